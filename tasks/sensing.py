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
    """The sensor reading [F, tau] (site frame) caused by the subtree's weight alone, at rest."""
    support = -mass * np.asarray(gravity, dtype=np.float64)  # force holding the subtree up
    torque_world = np.cross(np.asarray(com) - np.asarray(site_pos), support)
    return np.concatenate((rot.T @ support, rot.T @ torque_world))


class LowPass:
    """Streaming 2nd-order Butterworth low-pass over 6-channel samples (state kept between
    chunks, so filtering chunk by chunk equals filtering the whole signal at once)."""

    def __init__(self, cutoff_hz: float, sample_rate_hz: float, channels: int = 6) -> None:
        self.sos = signal.butter(2, cutoff_hz, btype="low", fs=sample_rate_hz, output="sos")
        self._zi_unit = signal.sosfilt_zi(self.sos)  # [sections, 2] for a unit step
        self.channels = channels
        self.zi: np.ndarray | None = None
        self.value = np.zeros(channels)

    def reset(self, x0: np.ndarray) -> None:
        """Start in steady state at ``x0`` (no start-up transient)."""
        x0 = np.asarray(x0, dtype=np.float64)
        self.zi = self._zi_unit[:, :, None] * x0[None, None, :]
        self.value = x0.copy()

    def __call__(self, chunk: np.ndarray) -> np.ndarray:
        """Filter ``chunk`` [n, channels]; return the last filtered sample."""
        chunk = np.asarray(chunk, dtype=np.float64)
        if chunk.shape[0] == 0:
            return self.value
        if self.zi is None:
            self.reset(chunk[0])
        out, self.zi = signal.sosfilt(self.sos, chunk, axis=0, zi=self.zi)
        self.value = out[-1]
        return self.value
