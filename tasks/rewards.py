"""The staged peg-in-hole reward of Lee et al. 2018 ("Making Sense of Vision and Touch"),
which the paper follows: reaching, alignment, insertion and completion.

With ``s`` the peg tip relative to the centre of the hole's opening (``s_z < 0`` inside):

* completion: ``10`` once the tip is within ``success_tolerance`` of the bottom;
* insertion (tip inside the hole): ``4 + 2 * depth / hole_depth`` in ``[4, 6)``;
* alignment (tip within ``eps_align`` of the axis and less than ``eps_height`` above the
  opening): ``2 - ||s_xy|| / eps_align`` in ``(1, 2]``;
* reaching otherwise: ``c_r - c_r / 2 * (tanh(lam ||s||) + tanh(lam ||s_xy||))`` in ``(0, 1]``.

Every stage pays more than any earlier one, so the reward increases along a successful insertion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RewardParams:
    """Constants of the staged reward (Lee et al. 2018 use the same structure)."""

    hole_depth: float
    inner_half: float
    """Half-width of the opening (peg half-width + clearance)."""
    success_tolerance: float = 0.01
    eps_align: float = 0.01
    eps_height: float = 0.02
    c_r: float = 1.0
    lam: float = 10.0


def stage_of(s: np.ndarray, p: RewardParams) -> tuple[str, float]:
    """The stage name (``reach``, ``align``, ``insert``, ``complete``) and the insertion depth."""
    s = np.asarray(s, dtype=np.float64)
    depth = -float(s[2])
    inside = depth > 0 and bool(np.all(np.abs(s[:2]) <= p.inner_half + 1e-3))
    if inside and depth >= p.hole_depth - p.success_tolerance:
        return "complete", depth
    if inside:
        return "insert", depth
    if float(np.linalg.norm(s[:2])) < p.eps_align and -1e-3 <= float(s[2]) < p.eps_height:
        return "align", depth
    return "reach", depth


def staged_reward(s: np.ndarray, p: RewardParams) -> tuple[float, bool]:
    """Reward and success flag for the tip offset ``s`` (tip minus centre of the opening)."""
    stage, depth = stage_of(s, p)
    s = np.asarray(s, dtype=np.float64)
    if stage == "complete":
        return 10.0, True
    if stage == "insert":
        return 4.0 + 2.0 * min(depth / p.hole_depth, 1.0), False
    dxy = float(np.linalg.norm(s[:2]))
    if stage == "align":
        return 2.0 - dxy / p.eps_align, False
    d = float(np.linalg.norm(s))
    return p.c_r - p.c_r / 2 * (np.tanh(p.lam * d) + np.tanh(p.lam * dxy)), False
