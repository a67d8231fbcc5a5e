"""Issue 56, misuse of the robosuite tasks' environments: a step after ``close``, an infinite
action, ``horizon=True``. Each test failed on the code before its fix."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import repbench  # noqa: F401  (registers the gymnasium ids; sets MUJOCO_GL)
from repbench.errors import ConfigError, DataError, RepbenchError
from repbench.registry import tasks
from repbench.testing.toy_task import ToyReachTask

ROBOSUITE_TASKS = ["PegInHole-v0", "Door-v0", "SurfacePress-v0"]
ENV_CLASSES = {"PegInHole-v0": "PegInHoleEnv", "Door-v0": "DoorEnv",
               "SurfacePress-v0": "PressEnv"}


# -- 6. a closed environment --------------------------------------------------------------------

@pytest.mark.parametrize("task_id", ROBOSUITE_TASKS)
def test_step_after_close_says_the_environment_is_closed(task_id: str) -> None:
    """Before: AttributeError: 'NoneType' object has no attribute 'model'."""
    env = tasks.get(task_id)(camera=False).make_env().unwrapped
    env.reset(seed=0)
    env.close()
    owner = type(env).__name__
    for call, name in ((lambda: env.step(np.zeros(3)), "step"),
                       (lambda: env.reset(seed=0), "reset")):
        with pytest.raises(RepbenchError) as info:
            call()
        msg = str(info.value)
        assert isinstance(info.value, RuntimeError)
        assert isinstance(info.value, gymnasium.error.ClosedEnvironmentError)
        assert msg.startswith(f"{owner}.{name}: ") and "is closed" in msg, msg
        assert "make a new environment" in msg and "\n" not in msg, msg
    env.close()  # closing twice stays harmless


def test_step_after_close_through_gymnasium_make() -> None:
    env = gymnasium.make("repbench/PegInHole-v0", camera=False)
    env.reset(seed=0)
    env.close()
    with pytest.raises(RepbenchError, match=r"PegInHoleEnv\.step: .*is closed"):
        env.step(np.zeros(3, np.float32))


# -- 9. non-finite actions ----------------------------------------------------------------------

@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_is_refused(physics_env, bad: float) -> None:
    """Before: NaN was refused but an infinite action was clipped to 1 and executed."""
    physics_env.reset(seed=0)
    t = physics_env._t
    with pytest.raises(DataError, match=r"^PegInHoleEnv\.step: action must be finite, got ") \
            as info:
        physics_env.step(np.array([0.0, bad, 0.0]))
    assert isinstance(info.value, ValueError) and "\n" not in str(info.value)
    assert physics_env._t == t  # the step did not happen
    physics_env.step(np.array([0.0, 1e6, 0.0]))  # a large finite action is still clipped


# -- 7. booleans for integer parameters ---------------------------------------------------------

@pytest.mark.parametrize("task_id", ROBOSUITE_TASKS)
@pytest.mark.parametrize("param", ["horizon", "grid_size"])
def test_bool_for_an_integer_parameter_is_refused(task_id: str, param: str) -> None:
    """Before: PegInHole-v0 took horizon=True (and grid_size=True) as 1; ToyReach refuses."""
    with pytest.raises(ConfigError, match=f"^{task_id}: {param}=True must be an? ") as info:
        tasks.get(task_id)(**{param: True})
    assert "\n" not in str(info.value)


def test_toy_reach_refuses_a_bool_horizon_as_before() -> None:
    with pytest.raises(ConfigError, match="horizon=True must be a whole number"):
        ToyReachTask(horizon=True)


def test_integer_parameters_still_take_numpy_integers() -> None:
    task = tasks.get("PegInHole-v0")(horizon=np.int64(7), grid_size=np.int32(3))
    assert task.config().horizon == 7
