"""Seed sweeps behind the tolerances of tests/metrics/test_task_metrics.py (not a test).

    python tests/metrics/measure/known_answers.py cmi        # Gaussian closed forms, seeds 0-9
    python tests/metrics/measure/known_answers.py order      # peg-like orderings, seeds 0-4
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/metrics, for _peg_like

from repbench.metrics.mutual_information import ksg_mi
from repbench.metrics.task_information import gaussian_cmi, knn_cmi

ONE_D = np.array([[1.0, 1.0, 0.0], [1.0, 1.5, 1.0], [1.0, 0.0, 0.0]])
FIVE_D = np.array([[0.8, 0.3, 1.0, 0.0, 0.0], [0.2, 0.9, 0.0, 1.0, 0.0],
                   [0.5, 0.0, 1.0, 0.4, 0.5], [1.0, 0.0, 0.0, 0.0, 0.0],
                   [0.0, 1.0, 0.0, 0.0, 0.0]])


def cmi() -> None:
    for name, lmat, dx, n in (("1/1/1", ONE_D, 1, 2000), ("2/1/2", FIVE_D, 2, 2000),
                              ("2/1/2", FIVE_D, 2, 3000)):
        true = gaussian_cmi(lmat @ lmat.T, dx, 1)
        errs = []
        for s in range(10):
            rng = np.random.default_rng(s)
            v = rng.standard_normal((n, lmat.shape[0])) @ lmat.T
            errs.append(knn_cmi(v[:, :dx], v[:, dx:dx + 1], v[:, dx + 1:], rng=rng) - true)
        print(f"{name} n={n} true {true:.3f}: error {min(errs):+.3f} .. {max(errs):+.3f}, "
              f"mean {np.mean(errs):+.3f}")
    est, mi = [], []
    for s in range(10):
        rng = np.random.default_rng(s)
        w = rng.standard_normal((3000, 2))
        x = w @ np.array([[1.0, 0.5], [0.2, 1.0]]) + rng.standard_normal((3000, 2))
        y = w[:, :1] + rng.standard_normal((3000, 1))
        est.append(knn_cmi(x, y, w, rng=rng))
        mi.append(ksg_mi(x, y))
    print(f"x ⊥ y | w: max |CMI| {np.max(np.abs(est)):.3f}, I(x; y) {np.mean(mi):.2f}")


def order() -> None:
    from _peg_like import peg_like

    from repbench.registry import metrics

    res: dict[tuple[str, str], list[float]] = {}
    for seed in range(5):
        d = peg_like(seed=seed)
        zt = np.hstack([d["robot_state"], d["hole"]])
        for m in ("task_cmi", "task_r2_gain", "task_probe", "action_probe"):
            fn = metrics.get(m)
            kw = {k: d[k] for k in fn.extra_inputs}
            for z in ("z_hole", "z_cubic", "z_tip", "z_random"):
                r = fn(d[z], zt, d["episode"], seed, n_bootstrap=0, **kw)
                res.setdefault((m, z), []).append(r.value)
    for (m, z), v in res.items():
        print(f"{m:13s} {z:9s} {min(v):+.3f} .. {max(v):+.3f}")


if __name__ == "__main__":
    {"cmi": cmi, "order": order}[sys.argv[1] if len(sys.argv) > 1 else "cmi"]()
