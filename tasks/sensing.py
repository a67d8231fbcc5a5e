"""Wrist force/torque processing: hand-and-peg weight removal and the low-pass filter.

MuJoCo's ``force``/``torque`` sensors on the gripper's ``ft_frame`` site report, in the site
frame, the wrench the arm applies to everything below the site (hand, fingers, peg). At rest in
free space that wrench just carries the weight: ``F = R^T m g_up`` and
``tau = R^T ((c - p) x m g_up)``, with ``m`` and ``c`` the subtree's mass and centre of mass and
``p`` the site position. Subtracting it leaves the contact (and small inertial) wrench.

The paper low-pass filters the force measurements without giving the filter; we use a
2nd-order Butterworth (``scipy.signal.butter``) at ``cutoff_hz`` run on the physics-rate samples.
"""

from __future__ import annotations

import numpy as np
from scipy import signal


def weight_wrench(rot: np.ndarray, com: np.ndarray, site_pos: np.ndarray, mass: float,
                  gravity: np.ndarray) -> np.ndarray:
    """The sensor reading [F, tau] (site frame) caused by the subtree's weight alone, at rest.

    Works on one sample (``rot`` [3, 3], ``com``/``site_pos`` [3] -> [6]) or a batch (``rot``
    [n, 3, 3], ``com``/``site_pos`` [n, 3] or [3] -> [n, 6]).
    """
    s = -mass * np.asarray(gravity, dtype=np.float64)  # force holding the subtree up (world)
    r = np.asarray(com, dtype=np.float64) - np.asarray(site_pos, dtype=np.float64)
    # r x s written out (np.cross is ~10x slower on 3-vectors)
    torque_world = np.stack((r[..., 1] * s[2] - r[..., 2] * s[1],
                             r[..., 2] * s[0] - r[..., 0] * s[2],
                             r[..., 0] * s[1] - r[..., 1] * s[0]), axis=-1)
    rot = np.asarray(rot, dtype=np.float64)
    # R^T v for each sample: sum over the rows of R
    force = np.einsum("...ji,j->...i", rot, s)
    torque = np.einsum("...ji,...j->...i", rot, torque_world)
    return np.concatenate((force, torque), axis=-1)


class LowPass:
    """Streaming 2nd-order Butterworth low-pass over 6-channel samples (state kept between
    chunks, so filtering chunk by chunk equals filtering the whole signal at once).

    The filter is linear, so for a chunk of ``n`` samples the new state and the last output are
    fixed linear maps of (state, chunk). They are read off ``scipy.signal.sosfilt`` once per
    chunk length (its response to unit states and unit impulses) and then applied as two small
    matrix products, which is ~10x cheaper than calling ``sosfilt`` every control step.
    """

    def __init__(self, cutoff_hz: float, sample_rate_hz: float, channels: int = 6) -> None:
        self.sos = signal.butter(2, cutoff_hz, btype="low", fs=sample_rate_hz, output="sos")
        self._zi_unit = signal.sosfilt_zi(self.sos)  # [sections, 2] for a unit step
        self.channels = channels
        self.zi: np.ndarray | None = None
        self.value = np.zeros(channels)
        self._maps: dict[int, np.ndarray] = {}

    def reset(self, x0: np.ndarray) -> None:
        """Start in steady state at ``x0`` (no start-up transient)."""
        x0 = np.asarray(x0, dtype=np.float64)
        self.zi = self._zi_unit[:, :, None] * x0[None, None, :]
        self.value = x0.copy()

    def _chunk_map(self, n: int) -> np.ndarray:
        """``M`` [S+1, S+n] with [new state; last output] = M @ [state; chunk] for each
        channel, S = 2 * sections."""
        if n not in self._maps:
            sections = self.sos.shape[0]
            size = 2 * sections + n
            basis = np.eye(size)
            out = np.empty((2 * sections + 1, size))
            for j in range(size):
                zi = basis[j, :2 * sections].reshape(sections, 2)
                y, zf = signal.sosfilt(self.sos, basis[j, 2 * sections:], zi=zi)
                out[:, j] = np.concatenate((zf.ravel(), [y[-1]]))
            self._maps[n] = out
        return self._maps[n]

    def __call__(self, chunk: np.ndarray) -> np.ndarray:
        """Filter ``chunk`` [n, channels]; return the last filtered sample."""
        chunk = np.asarray(chunk, dtype=np.float64)
        n = chunk.shape[0]
        if n == 0:
            return self.value
        if self.zi is None:
            self.reset(chunk[0])
        assert self.zi is not None
        sections = self.sos.shape[0]
        m = self._chunk_map(n)
        stacked = np.concatenate((self.zi.reshape(2 * sections, -1), chunk), axis=0)
        res = m @ stacked  # [2 * sections + 1, channels]
        self.zi = res[:2 * sections].reshape(sections, 2, -1)
        self.value = res[-1]
        return self.value
