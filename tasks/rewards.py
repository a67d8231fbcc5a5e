"""The staged peg-in-hole reward of Lee et al. 2018 ("Making Sense of Vision and Touch"),
which the paper follows: reaching, alignment, insertion and completion.

With ``s`` the peg tip relative to the centre of the hole's opening (``s_z < 0`` inside):

* completion: ``10`` once the tip is within ``success_tolerance`` of the bottom;
* insertion (tip inside the hole: more than ``contact_tolerance`` below the opening and at
  most ``clearance + contact_tolerance`` off the axis in x and y, i.e. where only the opening
  lets the peg be): ``4 + 2 * depth / hole_depth`` in ``[4, 6)``;
* alignment (tip within ``eps_align`` of the axis, between ``contact_tolerance`` below and
  ``eps_height`` above the opening): ``2 - ||s_xy|| / eps_align`` in ``(1, 2]``;
* reaching otherwise: ``c_r - c_r / 2 * (tanh(lam ||s||) + tanh(lam ||s_xy||))`` in ``(0, 1]``.

Every stage pays more than any earlier one, so the reward increases along a successful insertion.

``contact_tolerance`` exists because contacts are soft: a peg pressed onto the top of a wall
sinks into it by a fraction of a millimetre. Counting any tip below the opening's plane as
"inside" paid the insertion reward (4 per step) for pressing on the rim, and SAC learned
exactly that instead of inserting.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RewardParams:
    """Constants of the staged reward (Lee et al. 2018 use the same structure)."""

    hole_depth: float
    clearance: float
    """Gap between the centred peg and each wall: how far off the axis a peg in the hole can be."""
    success_tolerance: float = 0.01
    contact_tolerance: float = 0.002
    """Allowance for soft-contact penetration and peg tilt (m); well above the ~0.3 mm a peg
    pressed on a wall top sinks in, well below the peg's width."""
    eps_align: float = 0.01
    eps_height: float = 0.02
    c_r: float = 1.0
    lam: float = 10.0


def stage_of(s: np.ndarray, p: RewardParams) -> tuple[str, float]:
    """The stage name (``reach``, ``align``, ``insert``, ``complete``) and the insertion depth."""
    s = np.asarray(s, dtype=np.float64)
    depth = -float(s[2])
    tol = p.contact_tolerance
    inside = depth > tol and bool(np.all(np.abs(s[:2]) <= p.clearance + tol))
    if inside and depth >= p.hole_depth - p.success_tolerance:
        return "complete", depth
    if inside:
        return "insert", depth
    if float(np.linalg.norm(s[:2])) < p.eps_align and -tol <= float(s[2]) < p.eps_height:
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
    if stage == "align":
        return 2.0 - float(np.linalg.norm(s[:2])) / p.eps_align, False
    return reach_reward(s, p.c_r, p.lam), False


def reach_reward(s: np.ndarray, c_r: float = 1.0, lam: float = 10.0) -> float:
    """The reach stage's reward ``c_r - c_r / 2 * (tanh(lam ||s||) + tanh(lam ||s_xy||))`` in
    ``(0, c_r]`` for the tip offset ``s`` (the peg-in-hole's; Door-v0's staged reach too)."""
    s = np.asarray(s, dtype=np.float64)
    d, dxy = float(np.linalg.norm(s)), float(np.linalg.norm(s[:2]))
    return float(c_r - c_r / 2 * (np.tanh(lam * d) + np.tanh(lam * dxy)))
