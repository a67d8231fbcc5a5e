"""The peg-in-hole environment: gymnasium conformance, rigid grasp, force/torque, rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv

from repbench_tasks.collection import BackwardsExplorer
from repbench_tasks.env import PROPRIO_DIM, TRUE_STATE_DIM, PegInHoleEnv
from repbench_tasks.peg_in_hole import GYM_ID, PegInHoleTask
from repbench_tasks.rendering import WristRenderer, unseen_geom_ids


def test_env_checker_passes(env: PegInHoleEnv) -> None:
    check_env(env, skip_render_check=True)


def test_spaces_and_info(env: PegInHoleEnv) -> None:
    obs, info = env.reset(seed=0)
    assert obs["image"].shape == (64, 64, 3) and obs["image"].dtype == np.uint8
    assert obs["ft"].shape == (6,) and obs["proprio"].shape == (PROPRIO_DIM,)
    assert obs["last_action"].shape == (3,)
    assert info["true_state"].shape == (TRUE_STATE_DIM,) and info["true_state"].dtype == np.float32
    np.testing.assert_allclose(info["true_state"][-2:], env.hole_xy)
    assert env.observation_space.contains(obs)
    obs, _, _, _, info = env.step(np.array([0.5, -0.5, 0.2], np.float32))
    np.testing.assert_array_equal(obs["last_action"], np.array([0.5, -0.5, 0.2], np.float32))
    assert "is_success" in info and "true_state" in info


def test_gym_id_registered() -> None:
    assert GYM_ID in gym.registry
    e = gym.make(GYM_ID, camera=False, horizon=3)
    try:
        e.reset(seed=0)
        truncated = False
        for _ in range(3):
            *_, truncated, _ = e.step(e.action_space.sample())
        assert truncated, "episodes must truncate at horizon"
    finally:
        e.close()


def test_reset_is_deterministic_whatever_came_before(physics_env: PegInHoleEnv) -> None:
    def rollout() -> np.ndarray:
        _, info = physics_env.reset(seed=7)
        states = [info["true_state"]]
        for a in np.linspace(-1, 1, 15).reshape(5, 3):
            states.append(physics_env.step(a)[4]["true_state"])
        return np.stack(states)

    first = rollout()
    physics_env.reset(seed=3, options={"start": "inserted"})
    for _ in range(10):
        physics_env.step(np.array([1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(rollout(), first)


def test_fast_substeps_equal_robosuites_own_control_path(physics_env: PegInHoleEnv) -> None:
    """repbench's control path (no per-substep checks, no history buffers) computes exactly
    robosuite's torques: the same rollout bit for bit."""
    sim = physics_env.sim
    actions = np.random.default_rng(2).uniform(-1, 1, (12, 3))

    def rollout() -> tuple[np.ndarray, np.ndarray]:
        physics_env.reset(seed=9, options={"start": "inserted"})
        obs = [physics_env.step(a)[0] for a in actions]
        return np.stack([o["proprio"] for o in obs]), np.stack([o["ft"] for o in obs])

    fast = rollout()

    def robosuite_path(action, policy_step=False):
        ManipulationEnv._pre_action(sim, action, policy_step)
        sim._record_ft()

    sim._pre_action = robosuite_path
    try:
        reference = rollout()
    finally:
        del sim._pre_action
    np.testing.assert_array_equal(fast[0], reference[0])
    np.testing.assert_array_equal(fast[1], reference[1])


def test_inserted_start_is_success_and_above_is_not(physics_env: PegInHoleEnv) -> None:
    _, info = physics_env.reset(seed=0, options={"start": "inserted", "hole_index": 24})
    assert info["is_success"]
    np.testing.assert_allclose(physics_env.hole_xy, [0.08, 0.08])
    _, info = physics_env.reset(seed=0, options={"start": "above"})
    assert not info["is_success"] and physics_env.tip_offset()[2] > 0.015


def test_peg_stays_in_hand_through_300_steps_with_contact(physics_env: PegInHoleEnv) -> None:
    physics_env.reset(seed=1, options={"start": "inserted", "hole_index": 6})
    explorer = BackwardsExplorer(np.random.default_rng(0))
    contact, worst_slip, worst_tilt = 0, 0.0, 0.0
    for i in range(300):
        # phases: explore out of the hole, then press down hard on whatever is below
        a = explorer(physics_env.tip_offset()) if i % 60 < 45 else np.array([0.0, 0.0, -1.0])
        _, _, _, _, info = physics_env.step(a)
        contact += info["in_contact"]
        worst_slip = max(worst_slip, physics_env.peg_in_hand_offset())
        axis = physics_env.data.site_xmat[physics_env.sim.eef_site_id].reshape(3, 3)[:, 2]
        worst_tilt = max(worst_tilt, float(np.degrees(np.arccos(np.clip(-axis[2], -1, 1)))))
    assert contact >= 50, f"only {contact} of 300 steps in contact"
    assert worst_slip < 1e-9, f"peg moved {worst_slip} m in the hand"
    assert worst_tilt < 3.0, f"peg tilted {worst_tilt:.2f} degrees: orientation not held"


def test_ft_near_zero_in_free_space_tens_of_newtons_in_contact(physics_env: PegInHoleEnv) -> None:
    physics_env.reset(seed=2, options={"start": "above", "hole_index": 12})
    for _ in range(3):
        physics_env.step(np.array([0.0, 0.0, 0.3]))  # move up, away from everything
    free = []
    for _ in range(10):
        obs, *_, info = physics_env.step(np.zeros(3))
        assert not info["in_contact"]
        free.append(np.linalg.norm(obs["ft"][:3]))
    assert max(free) < 1.0, f"free-space force {max(free):.2f} N (weight not removed?)"
    # press the peg tip onto the top of a wall: tens of newtons
    physics_env.reset(seed=2, options={"hole_xy": (0.0, 0.0), "start": "inserted"})
    for _ in range(4):
        physics_env.step(np.array([0.0, 0.0, 1.0]))  # tip ~4 cm above the opening
    wall_top = physics_env.config.peg_half_width + physics_env.config.clearance + 0.01
    for _ in range(20):
        if abs(physics_env.tip_offset()[0] - wall_top) < 0.002:
            break
        physics_env.step(np.array([np.clip((wall_top - physics_env.tip_offset()[0]) / 0.02,
                                           -1, 1), 0.0, 0.0]))
    pressed = []
    for _ in range(15):
        obs, *_, info = physics_env.step(np.array([0.0, 0.0, -1.0]))
        pressed.append(np.linalg.norm(obs["ft"][:3]))
    assert info["in_contact"]
    assert 10.0 < np.median(pressed[-5:]) < 200.0, f"contact force {pressed[-5:]}"


def test_scripted_policy_inserts_the_peg(physics_env: PegInHoleEnv) -> None:
    """The clearance is resolvable: a straight-down insertion from above succeeds."""
    physics_env.reset(seed=4, options={"start": "above"})
    rewards, success = [], False
    for _ in range(60):
        off = physics_env.tip_offset()
        a = np.zeros(3)
        if np.linalg.norm(off[:2]) > 0.001:
            a[:2] = np.clip(-off[:2] / 0.02, -1, 1)
        else:
            a[2] = -0.5
        _, r, _, _, info = physics_env.step(a)
        rewards.append(r)
        if info["is_success"]:
            success = True
            break
    assert success, f"no insertion; final offset {physics_env.tip_offset()}"
    assert rewards[-1] == 10.0 and max(rewards[:-1]) < 10.0


def test_pressing_down_on_the_rim_pays_no_insertion_reward(physics_env: PegInHoleEnv) -> None:
    """The exploit SAC found: push the peg down hard on the hole's edge. Soft contacts let the
    tip sink a fraction of a millimetre below the opening's plane; that is not "inside"."""
    physics_env.reset(seed=4, options={"start": "above"})
    target = np.array([-0.014, -0.002])  # on the rim; the peg slides to the edge and sticks
    rewards, heights = [], []
    for i in range(60):
        off = physics_env.tip_offset()
        a = np.zeros(3)
        a[:2] = np.clip((target - off[:2]) / 0.02, -1, 1)
        a[2] = -1.0 if i > 10 else 0.0
        _, r, _, _, info = physics_env.step(a)
        rewards.append(r)
        heights.append(physics_env.tip_offset()[2])
        assert not info["is_success"]
    # measured: the tip sinks 0.2 mm below the opening (the old rule paid 4/step for 40 steps)
    assert -0.002 < min(heights) < 0.0, f"lowest tip height {min(heights)}"
    assert max(rewards) < 4.0 and max(rewards[20:]) > 1.0  # aligned above, never inserted


def test_wrist_image_upright_and_culled_geoms_never_seen(env: PegInHoleEnv) -> None:
    renderer: WristRenderer = env._renderer
    hidden = set(unseen_geom_ids(env.model).tolist())
    peg = np.flatnonzero(env.model.geom_bodyid == env.sim.peg_body_id)
    env.reset(seed=5)
    explorer = BackwardsExplorer(np.random.default_rng(1), noise=1.0)
    for i in range(30):
        env.step(explorer(env.tip_offset()) if i % 2 else np.array([0.0, 0.0, -1.0]))
        seg = renderer.render_segmentation()
        seen = set(np.unique(seg).tolist())
        assert not (seen & hidden), f"culled geoms visible: {seen & hidden}"
        rows = np.nonzero(np.isin(seg, peg))[0]
        assert rows.size > 0 and rows.mean() > 32, "peg should be in the lower half (upright)"


def test_default_rendering_shows_the_same_picture(task: PegInHoleTask, env: PegInHoleEnv) -> None:
    default = task.make_env(fast_render=False).unwrapped
    try:
        for seed in (0, 1):
            a, _ = env.reset(seed=seed)
            b, _ = default.reset(seed=seed)
            for _ in range(3):
                a = env.step(np.array([0.2, -0.1, -0.3]))[0]
                b = default.step(np.array([0.2, -0.1, -0.3]))[0]
            np.testing.assert_array_equal(a["proprio"], b["proprio"])
            diff = np.abs(a["image"].astype(int) - b["image"].astype(int))
            # only anti-aliased edges differ (MSAA off): a few grey levels on average
            assert diff.mean() < 6.0, f"mean image difference {diff.mean():.2f}"
            assert np.median(diff) <= 2
    finally:
        default.close()


def test_camera_off_gives_zero_images(physics_env: PegInHoleEnv) -> None:
    obs, _ = physics_env.reset(seed=0)
    assert not obs["image"].any()


def test_task_state_is_the_tip_offset_and_velocity(env: PegInHoleEnv) -> None:
    task = PegInHoleTask()
    obs, info = env.reset(seed=3)
    for _ in range(3):
        obs, _, _, _, info = env.step(np.array([0.1, 0.2, -0.3], np.float32))
    batch = {k: np.asarray(v)[None] for k, v in obs.items()}
    batch["true_state"] = info["true_state"][None]
    state = task.task_state(batch)
    assert state.shape == (1, 6) and state.dtype == np.float32
    np.testing.assert_allclose(state[0, :3], env.tip_offset(), atol=1e-5)
    np.testing.assert_allclose(state[0, 3:], obs["proprio"][17:20])


def test_task_state_names_missing_modality() -> None:
    import pytest

    from repbench.errors import DataError

    with pytest.raises(DataError, match="true_state"):
        PegInHoleTask().task_state({"proprio": np.zeros((2, 20), np.float32)})
