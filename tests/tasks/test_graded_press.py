"""SurfacePress-v1 (issue 57's pilot candidate): conformance, the graded reward's known answers,
a privileged script solves it and a blind push does not, the wrist F/T tells contact from free
motion, and the wrist camera cannot see the spring's stiffness (what the pre-registration in
``studies/force_task_pilot/README.md`` says it cannot)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from repbench.errors import ConfigError
from repbench.registry import tasks
from repbench.testing import check_task
from repbench_tasks.graded_press import (
    GYM_ID,
    GradedPressConfig,
    GradedPressEnv,
    GradedPressTask,
    graded_press_reward,
)
from repbench_tasks.press_env import press_reward
from repbench_tasks.scripted import BlindPress, ForceFeedbackPress, PrivilegedPress

#: Corners and centre of the 5 x 5 (stiffness x rest height) grid: the softest and stiffest
#: springs at the lowest and highest plate.
CONFIGS = (0, 4, 12, 20, 24)


@pytest.fixture(scope="module")
def graded_env():
    e = GradedPressTask(camera=False).make_env()
    yield e.unwrapped
    e.close()


def rollout(env: GradedPressEnv, policy, reset: dict, steps: int = 60) -> tuple[float, bool]:
    if hasattr(policy, "reset"):
        policy.reset()
    obs, info = env.reset(**reset)
    ret, success = 0.0, False
    for _ in range(steps):
        obs, r, _, _, info = env.step(policy({**obs, "true_state": info["true_state"]}))
        ret += r
        success |= info["is_success"]
    return ret, success


# -- registration, configuration, conformance ------------------------------------------------
def test_registered_and_conformant() -> None:
    assert tasks.get("SurfacePress-v1") is GradedPressTask and GYM_ID in gym.registry
    check_task("SurfacePress-v1", n_steps=3, camera=False)
    task = GradedPressTask(reward_width=3.0, stiffness_range=[600, 4000])  # TOML gives lists
    assert task.config().reward_width == 3.0 and task.config().stiffness_range == (600, 4000)
    assert GradedPressTask(**task.get_params()).get_params() == task.get_params()


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"reward_width": 0.0}, "reward_width"),
    ({"reward_width": True}, "reward_width"),
    ({"force_tolerance": 20.0}, "force_tolerance"),  # v0's checks, named as v1's
])
def test_bad_args_raise_one_line_config_error_naming_v1(kwargs, field) -> None:
    with pytest.raises(ConfigError, match=field) as exc:
        GradedPressTask(**kwargs)
    assert "\n" not in str(exc.value) and str(exc.value).startswith("SurfacePress-v1: ")


# -- the reward ----------------------------------------------------------------------------------
def test_graded_reward_known_answers_and_v0_success() -> None:
    cfg = GradedPressConfig()
    at = np.zeros(3)
    assert graded_press_reward(15.0, at, 0, cfg) == (5.0, False)
    assert graded_press_reward(17.5, at, 0, cfg)[0] == pytest.approx(1 + 4 * np.exp(-0.25))
    assert graded_press_reward(7.5, at, 0, cfg)[0] == pytest.approx(1 + 4 * np.exp(-2.25))
    assert graded_press_reward(0.0, np.array([0.0, 0.0, 0.01]), 0, cfg)[0] == pytest.approx(
        1 - np.tanh(0.1))
    # graded in the error where v0 is flat: v0 pays 2.56 at 7.5 N off and 3 at the target
    v1 = [graded_press_reward(f, at, 0, cfg)[0] for f in (3.0, 7.5, 11.0, 13.0)]
    assert v1 == sorted(v1) and v1[-1] - v1[0] > 2.5
    # success (and its reward, 10) exactly as v0's, over the band's edges and the hold count
    for force in (12.4, 12.5, 15.0, 17.5, 17.6):
        for held in (9, 10, 11):
            s1 = graded_press_reward(force, at, held, cfg)
            s0 = press_reward(force, at, 0.0, held, cfg)
            assert s1[1] == s0[1] and (s1[0] == 10.0) == s0[1]


# -- known results of scripts (5 grid configurations: corners and centre) ---------------------
def test_privileged_and_force_feedback_solve_it_blind_push_does_not(
        graded_env: GradedPressEnv) -> None:
    """Over all 30 evaluation episodes (measured when the task was added): privileged 405
    return, 100 % success; force feedback 376, 100 %; best blind push 124, 17 %."""
    for policy in (PrivilegedPress(), ForceFeedbackPress()):
        results = [rollout(graded_env, policy, {"seed": 0, "options": {"config_index": i}})
                   for i in CONFIGS]
        assert all(s for _, s in results), (type(policy).__name__, results)
        assert np.mean([r for r, _ in results]) > 300, results
    blind = [rollout(graded_env, BlindPress(1.0, 14), {"seed": 0, "options": {"config_index": i}})
             for i in CONFIGS]
    assert sum(s for _, s in blind) <= 2 and np.mean([r for r, _ in blind]) < 250, blind


def test_ft_reads_free_motion_and_contact_apart(graded_env: GradedPressEnv) -> None:
    obs, info = graded_env.reset(seed=0, options={"start": "above", "config_index": 12})
    free = []
    for _ in range(3):
        obs, *_, info = graded_env.step(np.array([0.0, 0.0, 0.0]))
        free.append(np.linalg.norm(obs["ft"][:3]))
    assert not info["in_contact"] and max(free) < 1.0
    policy = ForceFeedbackPress()
    for _ in range(40):
        obs, *_, info = graded_env.step(policy({**obs, "true_state": info["true_state"]}))
    assert info["in_contact"] and obs["ft"][2] > 10.0
    assert abs(obs["ft"][2] - info["spring_force"]) < 1.0


def test_camera_cannot_see_the_stiffness() -> None:
    """Two episodes that differ only in the spring's stiffness (500 vs 5000 N/m, same rest
    height, same reset seed) give bit-identical wrist images until the pusher touches the
    plate; after the same open-loop push the wrist force differs by more than 10 N."""
    env = GradedPressTask().make_env().unwrapped  # with the wrist camera
    try:
        images, forces = [], []
        for k in (500.0, 5000.0):
            obs, _ = env.reset(seed=3, options={"stiffness": k, "rest_offset": 0.0})
            seen = [obs["image"]]
            for _ in range(4):  # descending, still above the plate (start 2-5 cm above it)
                obs, *_, info = env.step(np.array([0.0, 0.0, -1.0]))
                assert not info["in_contact"]
                seen.append(obs["image"])
            for _ in range(16):  # the same push into the plate
                obs, *_, info = env.step(np.array([0.0, 0.0, -1.0]))
            images.append(np.stack(seen))
            forces.append(float(obs["ft"][2]))
        assert images[0].any()
        np.testing.assert_array_equal(images[0], images[1])
        assert abs(forces[0] - forces[1]) > 10.0, forces
    finally:
        env.close()
