"""Saturation check (2) of the pre-registration, on the reference: is ``task_cmi`` flat across
the informative encoders because its kNN estimator saturates?

``studies/metric_search/preregistration.md`` fixes it as "the Spearman ρ between ``task_cmi``
and ``task_cmi_gc`` over the encoders within one interval half-width of each other". Made
operational here, before this script first read a value (``task_cmi_gc``'s reference values
come from the committed selection's scores, ``results/scores/task_cmi_gc_values.csv``):

- *the encoders*: the selection's learned encoders (``selection.json``);
- *one interval half-width*: the median over them of
  (ci_high − ci_low) / 2 of their ``task_cmi`` records;
- *within it of each other*: the largest set of learned encoders whose ``task_cmi`` values fit in
  a window of that width (ties: the window of higher values — the informative end).

Printed beside it, descriptive (no verdict of its own): each estimator's within-window Spearman
ρ with mean SAC return. Reads committed files only.

Run::

    cd studies/metric_search && python saturation_reference.py --out saturation_reference.md
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "leaderboards" / "quick"
SCORES = Path(__file__).parent / "results" / "scores"


def densest_window(values: pd.Series, width: float) -> list[str]:
    """The largest set of ``values``' index whose values fit in ``[v, v + width]`` for some v
    (ties: the window of higher values)."""
    s = values.sort_values()
    best: list[str] = []
    for i, lo in enumerate(s.to_numpy()):
        inside = list(s.index[i:][s.to_numpy()[i:] <= lo + width])
        if len(inside) >= len(best):
            best = inside
    return best


def check(task: str = "PegInHole-v0") -> dict:
    """The check on ``task``: the window, and the three Spearman ρ."""
    learned = json.loads((SCORES.parent / "selection.json").read_text())["model_train"]["encoders"]
    enc = pd.read_csv(BOARD / "encoders.csv")
    enc = enc[enc["task"] == task].set_index("encoder").loc[learned]
    gc = pd.read_csv(SCORES / "task_cmi_gc_values.csv")
    gc = gc[gc["task"] == task].set_index("encoder")["value"]
    cmi = enc["task_cmi"]
    half = float(np.median((enc["task_cmi_ci_high"] - enc["task_cmi_ci_low"]) / 2))
    window = densest_window(cmi, half)

    def rho(a: pd.Series, b: pd.Series, on: Sequence[str]) -> float:
        return float(stats.spearmanr(a.loc[list(on)], b.loc[list(on)]).statistic)

    ret = enc["sac_return"]
    return {
        "task": task, "n_learned": len(learned), "half_width": half,
        "window": sorted(window), "window_range": [float(cmi[window].min()),
                                                   float(cmi[window].max())],
        "rho_cmi_gc_window": rho(cmi, gc, window), "rho_cmi_gc_learned": rho(cmi, gc, learned),
        "rho_return_window": {"task_cmi": rho(cmi, ret, window),
                              "task_cmi_gc": rho(gc, ret, window)},
        "rho_return_learned": {"task_cmi": rho(cmi, ret, learned),
                               "task_cmi_gc": rho(gc, ret, learned)},
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="PegInHole-v0")
    ap.add_argument("--out", default=None, help="write the result as Markdown here")
    args = ap.parse_args(argv)
    r = check(args.task)
    lo, hi = r["window_range"]
    text = "\n".join([
        f"# Saturation check (2) on the reference, {r['task']}", "",
        "Pre-registration part (2); the window made operational in "
        "`saturation_reference.py`'s docstring. Command: `cd studies/metric_search && python "
        "saturation_reference.py --out saturation_reference.md`.", "",
        f"- `task_cmi`'s median interval half-width over the {r['n_learned']} learned encoders: "
        f"{r['half_width']:.3f} nats.",
        f"- The densest window of that width holds **{len(r['window'])}** learned encoders, "
        f"`task_cmi` {lo:.2f}–{hi:.2f}: {', '.join(r['window'])}.",
        f"- Spearman ρ(`task_cmi`, `task_cmi_gc`): **{r['rho_cmi_gc_window']:.2f}** inside the "
        f"window, {r['rho_cmi_gc_learned']:.2f} over all learned encoders.",
        f"- Spearman ρ with mean SAC return inside the window: `task_cmi` "
        f"{r['rho_return_window']['task_cmi']:.2f}, `task_cmi_gc` "
        f"{r['rho_return_window']['task_cmi_gc']:.2f}; over all learned: "
        f"{r['rho_return_learned']['task_cmi']:.2f}, "
        f"{r['rho_return_learned']['task_cmi_gc']:.2f}.", ""])
    print(text)
    if args.out:
        Path(args.out).write_text(text)
        Path(args.out).with_suffix(".json").write_text(json.dumps(r, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
