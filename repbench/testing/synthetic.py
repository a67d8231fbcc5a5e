"""A small synthetic dataset in the task schema, for tests of encoders, metrics, agents, runners.

It mimics the peg-in-hole data without a simulator: a 2-D end effector does a smooth random walk
(with a pull towards the hole in every other episode, so some episodes succeed); a wrist camera
sees the hole as a dark disk displaced by ``hole − position``; the wrist force/torque sensor
spikes near the hole; proprioception is the end-effector position and velocity plus noise.

True state z° (S = 6): ``[x, y, vx, vy, hole_x, hole_y]``; proprio (P = 4): ``[x, y, vx, vy]``
plus noise; action and last action (A = 2): velocity commands. Deterministic in ``seed``;
4 × 30 steps take a few milliseconds.
"""

from __future__ import annotations

import numpy as np

from repbench.dataset import FT, IMAGE, LAST_ACTION, PROPRIO, Dataset
from repbench.errors import DataError

#: Distance (in state units) below which a step counts as a success.
SUCCESS_RADIUS = 0.12
_PIXELS_PER_UNIT = 20.0  # at 64 px; scaled with image_size
_HOLE_RADIUS = 7.0  # px at 64 px


def synthetic_dataset(n_episodes: int = 4, steps: int = 30, seed: int = 0,
                      image_size: int = 64) -> Dataset:
    """A deterministic dataset with the task's schema (see the module docstring).

    Args:
        n_episodes: number of episodes (each with its own hole position).
        steps: steps per episode.
        seed: seed of everything random.
        image_size: height and width of the square ``image`` modality.
    """
    if n_episodes < 1 or steps < 2:
        raise DataError(f"synthetic_dataset needs n_episodes >= 1 and steps >= 2, "
                        f"got n_episodes={n_episodes}, steps={steps}")
    if image_size < 8:
        raise DataError(f"synthetic_dataset needs image_size >= 8, got {image_size}")
    rng = np.random.default_rng(seed)
    e, t = n_episodes, steps
    hole = rng.uniform(-0.5, 0.5, size=(e, 2))
    pos = np.empty((e, t, 2))
    vel = np.empty((e, t, 2))
    act = np.empty((e, t, 2))
    pos[:, 0] = rng.uniform(-0.8, 0.8, size=(e, 2))
    vel[:, 0] = 0.0
    pull = np.where(np.arange(e) % 2 == 0, 0.35, 0.0)[:, None]  # every other episode seeks
    noise = rng.normal(0.0, 0.5, size=(e, t, 2))
    a_prev = np.zeros((e, 2))
    for n in range(t):
        a = 0.7 * a_prev + 0.3 * noise[:, n] + pull * (hole - pos[:, n]) / 0.1 * 0.1
        a = np.clip(a, -1.0, 1.0)
        act[:, n] = a
        a_prev = a
        if n + 1 < t:
            vel[:, n + 1] = 0.6 * vel[:, n] + 0.4 * a * 0.1
            pos[:, n + 1] = np.clip(pos[:, n] + vel[:, n + 1], -1.0, 1.0)
    last_act = np.concatenate([np.zeros((e, 1, 2)), act[:, :-1]], axis=1)
    hole_t = np.broadcast_to(hole[:, None, :], (e, t, 2))
    true_state = np.concatenate([pos, vel, hole_t], axis=-1).reshape(e * t, 6)

    rel = (hole_t - pos).reshape(e * t, 2)
    dist = np.linalg.norm(rel, axis=1)
    success = dist < SUCCESS_RADIUS
    reward = -dist

    # Force/torque: contact spike near the hole plus a drag term along the velocity.
    v = vel.reshape(e * t, 2)
    contact = 25.0 * np.exp(-((dist / 0.15) ** 2))
    ft = np.zeros((e * t, 6))
    ft[:, 0:2] = -3.0 * v / 0.1 + contact[:, None] * rel
    ft[:, 2] = contact
    ft[:, 3:5] = 0.3 * contact[:, None] * rel[:, ::-1]
    ft[:, 5] = 0.05 * contact
    ft += rng.normal(0.0, 0.2, size=ft.shape)

    proprio = true_state[:, :4] + rng.normal(0.0, 0.01, size=(e * t, 4))
    images = _render(rel, pos.reshape(e * t, 2), image_size)

    episode = np.repeat(np.arange(e, dtype=np.int64), t)
    step = np.tile(np.arange(t, dtype=np.int64), e)
    return Dataset(
        observations={
            IMAGE: images,
            FT: ft.astype(np.float32),
            PROPRIO: proprio.astype(np.float32),
            LAST_ACTION: last_act.reshape(e * t, 2).astype(np.float32),
        },
        action=act.reshape(e * t, 2).astype(np.float32),
        true_state=true_state.astype(np.float32),
        reward=reward.astype(np.float32),
        success=success,
        episode=episode,
        step=step,
        # z° is laid out as ToyReach-v0's, so task-frame encoders and metrics can read it
        metadata={"task": "ToyReach-v0", "synthetic": True, "seed": seed, "n_episodes": n_episodes,
                  "steps": steps, "image_size": image_size},
    )


def _render(rel: np.ndarray, pos: np.ndarray, size: int) -> np.ndarray:
    """Wrist-camera images: a dark hole disk at ``rel`` on a floor whose shade follows ``pos``."""
    scale = size / 64.0
    ax = np.arange(size, dtype=np.float32)
    centre = size / 2.0 - 0.5
    cx = (centre + rel[:, 0] * _PIXELS_PER_UNIT * scale).astype(np.float32)
    cy = (centre - rel[:, 1] * _PIXELS_PER_UNIT * scale).astype(np.float32)
    d2 = (ax[None, None, :] - cx[:, None, None]) ** 2 + (ax[None, :, None] - cy[:, None, None]) ** 2
    r = _HOLE_RADIUS * scale
    hole = 1.0 / (1.0 + np.exp(np.clip((np.sqrt(d2) - r) * 1.5, -30, 30)))  # soft disk [N,H,W]
    # Floor: a faint stripe pattern that slides with the end effector (parallax cue).
    stripes = 0.5 + 0.5 * np.sin(
        (ax[None, None, :] / scale + pos[:, 0, None, None] * 40.0) * 0.25
    ).astype(np.float32)
    floor = np.array([150.0, 140.0, 120.0], np.float32)
    img = floor[None, None, None, :] + 25.0 * stripes[..., None]
    ring = np.array([40.0, 40.0, 60.0], np.float32)
    img = img * (1.0 - hole[..., None]) + ring[None, None, None, :] * hole[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)
