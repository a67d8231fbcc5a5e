"""Door-v0: configuration errors, environment contract, the hinge geometry, rewards, the
configuration grid and the known results of the scripted controllers (locating the ring solves
it; an open-loop script recorded on one configuration does not solve the others)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from repbench.errors import ConfigError, DataError
from repbench.testing import check_task
from repbench_tasks.door import CONFIG, GYM_ID, TASK_STATE_DIM, DoorTask
from repbench_tasks.door_env import (
    ENGAGE_DEPTH,
    OFF_GRID_DISTANCE,
    RING_HALF,
    TRUE_STATE_DIM,
    Z_SHIFT,
    Z_YAW,
    DoorConfig,
    DoorEnv,
    door_reward,
)
from repbench_tasks.scripted import PrivilegedDoor, ReplayDoor
from repbench_tasks.sim import ROD_RADIUS


@pytest.fixture(scope="module")
def door_task() -> DoorTask:
    return DoorTask(camera=False)


@pytest.fixture(scope="module")
def door_env(door_task: DoorTask):
    e = door_task.make_env()
    yield e.unwrapped
    e.close()


def rollout(env: DoorEnv, policy, reset: dict) -> tuple[float, bool, np.ndarray]:
    if hasattr(policy, "reset"):
        policy.reset()
    obs, info = env.reset(seed=reset["seed"], options=reset["options"])
    ret, success, actions = 0.0, False, []
    for _ in range(env.config.horizon):
        a = policy({**obs, "true_state": info["true_state"]})
        actions.append(a)
        obs, r, _, _, info = env.step(a)
        ret += r
        success |= info["is_success"]
    return ret, success, np.array(actions)


# -- configuration -----------------------------------------------------------------------------
@pytest.mark.parametrize(("field", "value", "match"), [
    ("horizon", 0, "horizon=0 must be a positive integer"),
    ("shift_range", (-0.2, 0.0), "shift_range"),
    ("yaw_range", (0.0, 1.0), "yaw_range"),
    ("config_sampling", "uniform", "config_sampling"),
    ("success_angle", 2.0, "success_angle"),
    ("action_scale", "big", "action_scale='big' must be a number"),
    ("physics_dt", 0.003, "physics_dt"),
    ("reach_reward", "sparse", r"reach_reward='sparse' must be one of \('distance', 'staged'\)"),
])
def test_bad_config_names_the_field(field: str, value, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        DoorTask(**{field: value})


def test_grid_is_shift_by_yaw() -> None:
    grid = DoorConfig().grid_configs()
    assert grid.shape == (25, 2)
    np.testing.assert_allclose(np.unique(grid[:, 0]), [-0.08, -0.04, 0, 0.04, 0.08])
    np.testing.assert_allclose(np.unique(grid[:, 1]), [-0.25, -0.125, 0, 0.125, 0.25])


def test_random_data_cycle_the_grid_and_off_grid_data_leave_it() -> None:
    grid = DoorConfig().grid_configs()
    ds = DoorTask(camera=False).collect("random", n_episodes=3, steps_per_episode=4, seed=0,
                                        progress=False)
    np.testing.assert_allclose(ds.true_state[::4, CONFIG], grid[:3], atol=1e-6)
    assert ds.metadata["task"] == "Door-v0"
    held = DoorTask(camera=False, config_sampling="off_grid").collect(
        "random", n_episodes=6, steps_per_episode=2, seed=1000, progress=False)
    lo, hi = DoorConfig().config_box()
    x = held.true_state[::2, CONFIG].astype(np.float64)
    dist = np.linalg.norm((x[:, None] - grid[None]) / (hi - lo), axis=-1).min(1)
    assert (dist >= OFF_GRID_DISTANCE - 1e-6).all(), dist


def test_evaluation_resets_cover_the_grid_then_leave_it(door_task: DoorTask) -> None:
    resets = door_task.evaluation_resets(30)
    assert [r["options"]["config_index"] for r in resets[:25]] == list(range(25))
    assert resets == door_task.evaluation_resets(30)
    assert len({r["seed"] for r in resets}) == 30
    with pytest.raises(ConfigError, match="positive int"):
        door_task.evaluation_resets(0)


# -- the environment ---------------------------------------------------------------------------
def test_env_checker_and_conformance() -> None:
    env = DoorTask().make_env().unwrapped  # with the wrist camera
    try:
        check_env(env, skip_render_check=True)
        obs, info = env.reset(seed=0)
        assert obs["image"].shape == (64, 64, 3) and obs["image"].any()
        assert info["true_state"].shape == (TRUE_STATE_DIM,)
    finally:
        env.close()
    check_task("Door-v0", n_steps=3, camera=False)


def test_gym_id_truncates_at_horizon() -> None:
    assert GYM_ID in gym.registry
    e = gym.make(GYM_ID, camera=False, horizon=3)
    try:
        e.reset(seed=0)
        assert [e.step(e.action_space.sample())[3] for _ in range(3)] == [False, False, True]
    finally:
        e.close()


def test_true_state_holds_the_configuration(door_env: DoorEnv) -> None:
    _, info = door_env.reset(seed=1, options={"shift": 0.013, "yaw": -0.1})
    z = info["true_state"]
    assert z.dtype == np.float32 and z.shape == (18,)
    np.testing.assert_allclose([z[Z_SHIFT], z[Z_YAW]], [0.013, -0.1], rtol=1e-5)
    with pytest.raises(ValueError, match="outside"):
        door_env.reset(seed=1, options={"yaw": 0.4})
    with pytest.raises(ValueError, match="config_index"):
        door_env.reset(seed=1, options={"config_index": 25})


def test_ring_geometry_matches_the_simulation(door_env: DoorEnv) -> None:
    """The analytic engagement point (task_state, the scripts) is where the ring is."""
    for idx in (0, 12, 24):
        door_env.reset(seed=0, options={"start": "engaged", "config_index": idx})
        m, d = door_env.model, door_env.data
        walls = [m.geom(f"door_ring_{w}").id for w in ("front", "back", "left", "right")]
        centre = d.geom_xpos[walls].mean(0)
        np.testing.assert_allclose(centre[:2], door_env.engage_point()[:2], atol=1e-6)
        assert door_env.engaged()


def test_door_only_opens_by_pulling(door_env: DoorEnv) -> None:
    door_env.reset(seed=0, options={"start": "engaged", "config_index": 12})
    for _ in range(10):  # push away from the robot: the stop holds it shut
        door_env.step(np.array([1.0, 0.0, 0.0]))
    assert door_env.door_angle() < 0.01


def test_reset_is_deterministic_whatever_came_before(door_env: DoorEnv) -> None:
    def run() -> np.ndarray:
        _, info = door_env.reset(seed=7)
        out = [info["true_state"]]
        for a in np.linspace(-1, 1, 18).reshape(6, 3):
            out.append(door_env.step(a)[4]["true_state"])
        return np.stack(out)

    first = run()
    door_env.reset(seed=3, options={"start": "engaged", "config_index": 24})
    for _ in range(5):
        door_env.step(np.array([-1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(run(), first)


def test_task_state_known_answer(door_task: DoorTask, door_env: DoorEnv) -> None:
    obs, info = door_env.reset(seed=0, options={"config_index": 7})
    batch = {k: np.asarray(v)[None] for k, v in obs.items()}
    batch["true_state"] = info["true_state"][None]
    s = door_task.task_state(batch)
    assert s.shape == (1, TASK_STATE_DIM) and s.dtype == np.float32
    np.testing.assert_allclose(s[0, :3], door_env.tip_offset(), atol=1e-5)
    np.testing.assert_allclose(s[0, 5:7], door_env.pull_direction(), atol=1e-6)
    with pytest.raises(DataError, match="true_state"):
        door_task.task_state({"proprio": np.zeros((2, 20), np.float32)})


# -- reward ------------------------------------------------------------------------------------
def test_reward_stages_increase_towards_an_open_door() -> None:
    """The distance reward's stages (the staged reach's are in the next test)."""
    cfg = DoorConfig(reach_reward="distance")
    far = door_reward(np.array([0.05, 0.0, 0.1]), 0.0, False, cfg)
    near = door_reward(np.array([0.0, 0.0, 0.01]), 0.0, False, cfg)
    hooked = door_reward(np.zeros(3), 0.0, True, cfg)
    opening = door_reward(np.zeros(3), 0.2, True, cfg)
    pushed = door_reward(np.array([0.1, 0, 0]), 0.2, False, cfg)
    done = door_reward(np.zeros(3), 0.3, True, cfg)
    assert 0 < far[0] < near[0] <= 1 < hooked[0] == 2 < opening[0] < 8 < done[0] == 10
    assert pushed[0] < 1 and done[1] and not opening[1]


def test_staged_reach_pays_more_over_the_ring_than_beside_it() -> None:
    """The distance reward's trap, and the staged reward that removes it: a tip resting on the
    door's top 1.5 cm beside the ring's mouth against one hovering 1.5 cm over it (offsets from
    the engagement point, which lies ENGAGE_DEPTH below the mouth)."""
    beside = np.array([0.015, 0.0, ENGAGE_DEPTH])
    over = np.array([0.0, 0.0, ENGAGE_DEPTH + 0.015])
    distance, staged = DoorConfig(reach_reward="distance"), DoorConfig(reach_reward="staged")
    assert door_reward(beside, 0.0, False, distance)[0] > door_reward(over, 0.0, False, distance)[0]
    # known values: reach 1 - (tanh(10 |s|) + tanh(10 d_xy)) / 2, alignment 1.5 - d_xy / 0.02
    assert door_reward(beside, 0.0, False, staged)[0] == pytest.approx(1 - np.tanh(0.15))
    assert door_reward(over, 0.0, False, staged)[0] == pytest.approx(1.5)
    at_mouth = np.array([0.005, 0.0, ENGAGE_DEPTH])
    assert door_reward(at_mouth, 0.0, False, staged)[0] == pytest.approx(1.25)
    far = door_reward(np.array([0.05, 0.0, 0.1]), 0.0, False, staged)[0]
    hooked = door_reward(np.zeros(3), 0.0, True, staged)[0]
    stages = [far, door_reward(beside, 0.0, False, staged)[0], 1.0,
              door_reward(at_mouth, 0.0, False, staged)[0],
              door_reward(over, 0.0, False, staged)[0], hooked]
    assert stages[0] > 0 and stages == sorted(set(stages)) and hooked == 2



def test_door_v0_is_the_variant_that_passed_its_confirmation() -> None:
    """Door-v0 version 1 is the staged reach reward with a 10 mm ring: privileged SAC reached
    100 % on six of six seeds with it (leaderboards/quick/door/levers/staged_ring10mm.toml); the
    5 mm ring and the distance reward each left a seed short of 90 %."""
    assert DoorConfig().reach_reward == DoorTask().reach_reward == "staged"
    clearance = RING_HALF - ROD_RADIUS
    assert clearance == pytest.approx(0.010)
    assert DoorTask.version == 1

# -- known results of the scripted controllers ---------------------------------------------------
@pytest.mark.slow
def test_privileged_script_opens_every_evaluation_door(door_task: DoorTask,
                                                       door_env: DoorEnv) -> None:
    results = [rollout(door_env, PrivilegedDoor(), r) for r in door_task.evaluation_resets(30)]
    assert all(s for _, s, _ in results), [s for _, s, _ in results]


def test_privileged_script_and_a_replay(door_task: DoorTask, door_env: DoorEnv) -> None:
    """The privileged script opens the door; its actions recorded on the centre configuration
    and replayed open-loop open it there but not on the grid's corners."""
    resets = door_task.evaluation_resets(25)
    _, success, actions = rollout(door_env, PrivilegedDoor(), resets[12])
    assert success
    replay = ReplayDoor(actions)
    assert rollout(door_env, replay, resets[12])[1]
    assert not any(rollout(door_env, replay, resets[i])[1] for i in (0, 4, 20, 24))
