"""A wrong action shape passed to an environment's ``step`` is one line naming the expected
shape and what was passed (issue 45): before, numpy's "cannot reshape array of size 4 into
shape (3,)"."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.errors import DataError
from repbench.testing.toy_task import ToyReachTask


@pytest.mark.parametrize("action", [np.zeros(4), np.zeros((2, 3)), 0.5, [], [[0.1, 0.2]] * 3])
def test_wrong_action_shape_names_the_expected_shape(physics_env, action) -> None:
    physics_env.reset(seed=0)
    with pytest.raises(DataError) as info:
        physics_env.step(action)
    msg = str(info.value)
    assert "PegInHoleEnv.step" in msg and "expected shape (3,)" in msg
    assert f"got shape {np.shape(action)}" in msg and "\n" not in msg


@pytest.mark.parametrize("action", [np.zeros(3), np.zeros((1, 3)), [0.1, -0.2, 0.3]])
def test_right_action_shapes_still_step(physics_env, action) -> None:
    physics_env.reset(seed=0)
    physics_env.step(action)


def test_toy_env_wrong_action_shape() -> None:
    env = ToyReachTask(horizon=5).make_env().unwrapped
    env.reset(seed=0)
    with pytest.raises(DataError, match=r"ToyReachEnv\.step: .*expected shape \(2,\).*got "
                                        r"shape \(3,\)"):
        env.step(np.zeros(3))
    env.step(np.zeros(2))
