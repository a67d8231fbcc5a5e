"""Saturation check, part (1) of the pre-registration (studies/metric_search/preregistration.md).

Does ``task_cmi``'s kNN estimate (Frenzel–Pompe, k = 5) flatten out where the informative
encoders sit (1.1–1.3 nats on PegInHole-v0)? On synthetic jointly Gaussian data with the
reference's shapes and a known I(z; c | r), report ``task_cmi``'s and ``task_cmi_gc``'s estimates
against the truth: bias, and the slope of estimate vs truth (saturation = slope < 0.5 there).
Synthetic data only: nothing here reads a reference latent.

Shapes (as on quick's PegInHole-v0): z 16-D (quick's latent_dim); r the task's robot state
(``PegInHoleTask().robot_state``, read off the task below); the task state as wide as
``PegInHoleTask().task_state``, its first two columns complementary (the tip − hole offset in x,
y) and the others determined by r (as ``task_cmi``'s ``complementary_columns`` finds on the
reference); 8500 rows in 35 episodes (25 × 300 held-out exploration + 10 × 100 on-policy).

Data: r ~ N(0, Σ_r); the hidden part u ~ N(0, I₂); c = u + rB (B small: c's share unexplained
by r ≈ 0.9, as on the reference); z = uM + rG + ε, ε ~ N(0, I₁₆), the two rows of M orthogonal
with norm a (spread over all 16 dimensions). Then I(z; c | r) = ln(1 + a²) exactly (checked
against the covariance's closed form), so a = √(e^T − 1) gives truth T.

Variants: ``iid`` — every row independent; ``episodic`` — like the reference's trajectories,
u fixed within an episode (the hole) and r an AR(1) walk (ρ = 0.98) within it, per-row marginal
unchanged, so the same truth per row.

Run (about 5 minutes on 2 busy cores)::

    python studies/metric_search/saturation.py --out studies/metric_search/saturation.md
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from repbench.metrics.task_information import gaussian_cmi, task_cmi
from repbench.metrics.usable_information import task_cmi_gc

Z_DIM = 16
N_COMPLEMENTARY = 2
EPISODES = [(25, 300), (10, 100)]  # (episodes, steps): held-out exploration, on-policy
IID_TRUTHS = (0.0, 0.5, 1.0, 1.1, 1.2, 1.3, 1.4, 1.6, 2.0, 2.5, 3.0, 4.0, 5.0)
EPISODIC_TRUTHS = (0.5, 1.0, 1.1, 1.2, 1.3, 1.4, 2.0, 3.0, 5.0)


def reference_widths() -> tuple[int, int]:
    """(robot-state width, task-state width) of PegInHole-v0, read off the task itself."""
    from repbench_tasks.peg_in_hole import PegInHoleTask

    task = PegInHoleTask()
    obs = {"proprio": np.zeros((2, 20), np.float32), "true_state": np.zeros((2, 16), np.float32)}
    return task.robot_state(obs).shape[1], task.task_state(obs).shape[1]


def episode_ids() -> np.ndarray:
    ids, start = [], 0
    for n_ep, steps in EPISODES:
        ids.append(np.repeat(np.arange(start, start + n_ep), steps))
        start += n_ep
    return np.concatenate(ids)


def make_data(truth: float, dr: int, dtask: int, variant: str, seed: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """z [N, 16], robot state [N, dr], task state [N, dtask], episode [N], exact I(z; c | r)."""
    if dtask < N_COMPLEMENTARY or dr < 1:
        raise SystemExit(f"need a task state of >= {N_COMPLEMENTARY} columns and a robot state")
    rng = np.random.default_rng(seed)
    episode = episode_ids()
    n, dc = len(episode), N_COMPLEMENTARY
    a = math.sqrt(math.expm1(truth))
    root_r = rng.standard_normal((dr, dr)) / math.sqrt(dr) + np.eye(dr)  # r = η root_r
    b = 0.1 * rng.standard_normal((dr, dc))
    q = np.linalg.qr(rng.standard_normal((Z_DIM, Z_DIM)))[0][:, :dc]
    m = a * q.T  # [dc, 16], orthogonal rows of norm a
    g = rng.standard_normal((dr, Z_DIM))
    # (z, c, r) = (u, η, ε) @ lin: the exact covariance and truth
    lin = np.zeros((dc + dr + Z_DIM, Z_DIM + dc + dr))
    lin[:dc, :Z_DIM], lin[:dc, Z_DIM:Z_DIM + dc] = m, np.eye(dc)
    lin[dc:dc + dr, :Z_DIM] = root_r @ g
    lin[dc:dc + dr, Z_DIM:Z_DIM + dc] = root_r @ b
    lin[dc:dc + dr, Z_DIM + dc:] = root_r
    lin[dc + dr:, :Z_DIM] = np.eye(Z_DIM)
    exact = gaussian_cmi(lin.T @ lin, Z_DIM, dc)
    assert abs(exact - math.log1p(a * a)) < 1e-9, (exact, truth)
    if variant == "iid":
        u = rng.standard_normal((n, dc))
        eta = rng.standard_normal((n, dr))
    elif variant == "episodic":
        ids, first = np.unique(episode, return_index=True)
        u = rng.standard_normal((ids.size, dc))[np.searchsorted(ids, episode)]
        rho = 0.98
        shocks = rng.standard_normal((n, dr))
        eta = np.empty((n, dr))
        starts = set(first.tolist())
        for i in range(n):  # a stationary AR(1) walk per episode
            eta[i] = shocks[i] if i in starts else (
                rho * eta[i - 1] + math.sqrt(1 - rho * rho) * shocks[i])
    else:
        raise SystemExit(f"unknown variant {variant!r}; use iid or episodic")
    eps = rng.standard_normal((n, Z_DIM))
    v = np.hstack([u, eta, eps]) @ lin
    z, c, r = v[:, :Z_DIM], v[:, Z_DIM:Z_DIM + dc], v[:, Z_DIM + dc:]
    # the determined columns: functions of r (the tip's height over the hole, its velocity)
    determined = r[:, :dtask - dc] * 1.5 - 0.3
    return z, r, np.hstack([c, determined]), episode, exact


def slope(truths: list[float], values: list[float], lo: float, hi: float) -> float:
    """Least-squares slope of value on truth over the truths in [lo, hi]."""
    t = np.array(truths)
    keep = (t >= lo - 1e-9) & (t <= hi + 1e-9)
    if keep.sum() < 2:
        return float("nan")
    return float(np.polyfit(t[keep], np.array(values)[keep], 1)[0])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", help="write the Markdown table here")
    ap.add_argument("--seed", type=int, default=0, help="data seed (the metrics use seed 0)")
    ap.add_argument("--variants", default="iid,episodic")
    ap.add_argument("--robot-dim", type=int, default=None,
                    help="robot-state width (default: PegInHole-v0's)")
    args = ap.parse_args(argv)
    dr_task, dtask = reference_widths()
    dr = args.robot_dim or dr_task
    started = time.time()
    rows: list[dict[str, float | str]] = []
    for variant in args.variants.split(","):
        truths = IID_TRUTHS if variant == "iid" else EPISODIC_TRUTHS
        for truth in truths:
            z, r, task, episode, exact = make_data(truth, dr, dtask, variant, args.seed)
            t0 = time.time()
            knn = task_cmi(z, z, episode, 0, robot_state=r, task_state=task, n_bootstrap=0)
            t1 = time.time()
            gc = task_cmi_gc(z, z, episode, 0, robot_state=r, task_state=task, n_bootstrap=0)
            t2 = time.time()
            used = knn.extras["task_state_columns_used"]
            assert used == list(range(N_COMPLEMENTARY)), used
            rows.append({"variant": variant, "truth": exact, "task_cmi": knn.value,
                         "task_cmi_gc": gc.value, "s_knn": t1 - t0, "s_gc": t2 - t1})
            print(f"{variant:8s} truth {exact:5.2f}  task_cmi {knn.value:6.3f}  "
                  f"task_cmi_gc {gc.value:6.3f}  ({t1 - t0:.1f} s, {t2 - t1:.2f} s)",
                  flush=True)
    lines = [
        "# Saturation check (1): task_cmi and task_cmi_gc against a known I(z; c | r)",
        "",
        "Pre-registration part (1) (studies/metric_search/preregistration.md). Synthetic "
        "jointly Gaussian data only (no reference latent is read); the data model and variants "
        "are in `saturation.py`'s docstring.",
        "",
        f"Shapes: z {Z_DIM}-D, robot state r {dr}-D (PegInHole-v0's `robot_state`: "
        f"{dr_task}-D), task state {dtask}-D of which {N_COMPLEMENTARY} complementary (both "
        f"metrics keep exactly those), {len(episode_ids())} rows in "
        f"{len(np.unique(episode_ids()))} episodes. Metric seed 0, registered defaults "
        f"(task_cmi k = 5), no bootstrap. Data seed {args.seed}.",
        "",
        "Command: `python studies/metric_search/saturation.py "
        + " ".join(sys.argv[1:] if argv is None else argv) + "`",
        "",
        "| variant | true CMI (nats) | task_cmi | bias | task_cmi_gc | bias | "
        "task_cmi slope to next row | task_cmi_gc slope to next row |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for i, row in enumerate(rows):
        nxt = rows[i + 1] if i + 1 < len(rows) and rows[i + 1]["variant"] == row[
            "variant"] else None

        def local(key: str, row: dict = row, nxt: dict | None = nxt) -> str:
            if nxt is None:
                return ""
            return f"{(nxt[key] - row[key]) / (nxt['truth'] - row['truth']):.2f}"

        lines.append(
            f"| {row['variant']} | {row['truth']:.2f} | {row['task_cmi']:.3f} | "
            f"{row['task_cmi'] - row['truth']:+.3f} | {row['task_cmi_gc']:.3f} | "
            f"{row['task_cmi_gc'] - row['truth']:+.3f} | {local('task_cmi')} | "
            f"{local('task_cmi_gc')} |")
    lines += ["", "Slopes of estimate vs truth (least squares over the grid points in the "
              "window; saturation = slope < 0.5):", "",
              "| variant | window of true CMI | task_cmi slope | task_cmi mean bias | "
              "task_cmi_gc slope | task_cmi_gc mean bias |", "|---|---|---|---|---|---|"]
    for variant in args.variants.split(","):
        sub = [r_ for r_ in rows if r_["variant"] == variant]
        t = [float(r_["truth"]) for r_ in sub]
        for lo, hi in [(1.1, 1.3), (1.0, 1.4), (0.5, 2.0)]:
            inside = [r_ for r_ in sub if lo - 1e-9 <= float(r_["truth"]) <= hi + 1e-9]
            if len(inside) < 2:
                continue
            bias_k = np.mean([float(r_["task_cmi"]) - float(r_["truth"]) for r_ in inside])
            bias_g = np.mean([float(r_["task_cmi_gc"]) - float(r_["truth"]) for r_ in inside])
            lines.append(
                f"| {variant} | {lo}–{hi} nats ({len(inside)} points) | "
                f"{slope(t, [float(r_['task_cmi']) for r_ in sub], lo, hi):.2f} | "
                f"{bias_k:+.3f} | "
                f"{slope(t, [float(r_['task_cmi_gc']) for r_ in sub], lo, hi):.2f} | "
                f"{bias_g:+.3f} |")
    lines += ["", "Where `task_cmi`'s *estimate* is 1.1–1.3 nats (the informative encoders' "
              "values on PegInHole-v0): the true CMI there (linear interpolation on the grid) and "
              "`task_cmi`'s slope over the grid points that bracket it:", ""]
    for variant in args.variants.split(","):
        sub = [r_ for r_ in rows if r_["variant"] == variant]
        t = np.array([float(r_["truth"]) for r_ in sub])
        est = np.array([float(r_["task_cmi"]) for r_ in sub])
        if est.max() < 1.1:
            lines.append(f"- {variant}: `task_cmi` never reaches 1.1 (at most {est.max():.3f}, "
                         f"at true {t[est.argmax()]:.2f} nats).")
            continue
        first = int(np.argmax(est >= 1.1))
        last = int(np.argmax(est >= 1.3)) if (est >= 1.3).any() else len(est) - 1
        lo_i = max(first - 1, 0)
        at = [float(np.interp(v, est[lo_i:last + 1], t[lo_i:last + 1]))
              if est[lo_i] <= v <= est[last] else float("nan") for v in (1.1, 1.3)]
        sl = float(np.polyfit(t[lo_i:last + 1], est[lo_i:last + 1], 1)[0])
        lines.append(f"- {variant}: true CMI {at[0]:.2f}–{at[1]:.2f} nats; `task_cmi` slope "
                     f"{sl:.2f} over true {t[lo_i]:.2f}–{t[last]:.2f} nats.")
    knn_s = np.mean([float(r_["s_knn"]) for r_ in rows])
    gc_s = np.mean([float(r_["s_gc"]) for r_ in rows])
    lines += ["", f"Time per set: task_cmi {knn_s:.1f} s, task_cmi_gc {gc_s:.2f} s "
              f"(total {time.time() - started:.0f} s on this machine).", ""]
    text = "\n".join(lines)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
