"""PegInHole-v0 dataset checksums: run before and after a refactor of ``tasks/``; they must match.

    python studies/task_learnability/peg_checksums.py [--out FILE] [--compare FILE]

Covers the random (backwards-exploration) dataset with the wrist camera, the held-out one
(``hole_sampling="uniform"``), physics only, and an on-policy dataset of a fixed scripted policy.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys

import numpy as np

import repbench  # noqa: F401  (MUJOCO_GL before mujoco)
from repbench_tasks.peg_in_hole import PegInHoleTask


def scripted(obs: dict) -> np.ndarray:
    """Descend on a fixed diagonal (no task knowledge): exercises on_policy collection."""
    t = float(obs["proprio"][14])
    return np.array([np.sin(10 * t), 0.3, -0.5], np.float32)


def _sums(ds) -> list[str]:
    """The arrays' checksum and a hash of the metadata without its timing."""
    meta = {k: v for k, v in ds.metadata.items()
            if k not in ("collection_seconds", "library_versions")}
    digest = hashlib.sha256(json.dumps(meta, sort_keys=True).encode()).hexdigest()
    return [ds.checksum(), digest]


def checksums() -> dict[str, list[str]]:
    out = {}
    out["random_camera"] = _sums(PegInHoleTask(horizon=100).collect(
        "random", n_episodes=3, steps_per_episode=40, seed=0, progress=False))
    out["heldout_uniform"] = _sums(PegInHoleTask(horizon=100, hole_sampling="uniform").collect(
        "random", n_episodes=2, steps_per_episode=30, seed=1000, progress=False))
    out["random_physics"] = _sums(PegInHoleTask(horizon=100, camera=False).collect(
        "random", n_episodes=4, steps_per_episode=100, seed=3, progress=False))
    out["on_policy_camera"] = _sums(PegInHoleTask(horizon=100).collect(
        "on_policy", n_episodes=2, steps_per_episode=30, seed=1, policy=scripted,
        progress=False))
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out")
    ap.add_argument("--compare")
    args = ap.parse_args()
    got = checksums()
    print(json.dumps(got, indent=1))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(got, f, indent=1)
    if args.compare:
        with open(args.compare) as f:
            want = json.load(f)
        bad = [k for k in want if want[k] != got.get(k)]
        print("IDENTICAL" if not bad else f"DIFFERENT: {bad}")
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
