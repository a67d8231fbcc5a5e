"""Complementary task information: what z adds about the task beyond the robot state.

The RL agent observes μ_z ⊕ robot state (``Task.robot_state``). What it cannot read off the robot
state is the task's hidden part — for the peg-in-hole, where the hole is relative to the peg tip.
Two metrics measure how much of it z carries:

* ``task_cmi`` — the conditional mutual information I(z; c | r) in nats, r the robot state and c
  the *complementary* task-state columns (below), by the Frenzel–Pompe kNN estimator
  (:func:`knn_cmi`, a KSG-style estimator of CMI; tested against the Gaussian closed form
  :func:`gaussian_cmi`). Form-invariant like every MI: any invertible map of z scores the same.
* ``task_r2_gain`` — held-out (whole episodes) R² of predicting c from z ⊕ r minus the R² from r
  alone, both with the same MLP. 0: z adds nothing the robot state does not already give.

Complementary columns. ``Task.task_state`` (e.g. tip − hole offset and tip velocity) mixes what
the robot state already determines (the tip velocity, the tip height above the fixed table)
with what it does not (the planar offset to the hole). A column whose least-squares fit from
the robot state leaves a residual variance below ``determined_tol`` (relative) is determined by
r and is dropped (:func:`complementary_columns`); it carries no conditional information and,
being a deterministic function of r, would only break the kNN estimator's density assumptions.
For PegInHole-v0 with the 20-D proprio this keeps the tip − hole offset in x and y — equivalent,
given the tip position, to the hole's planar position, so I(z; c | r) = I(z; hole | r).

Rows: the metric stage computes both on every stored row (held-out backwards-exploration episodes
with off-grid holes, and on-policy episodes), never on the encoders' training data.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import digamma

from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import (
    check_params,
    drop_constant,
    episode_bootstrap_replicates,
    seed_from,
)
from repbench.metrics.mutual_information import _as_2d, _jitter

__all__ = [
    "complementary_columns",
    "gaussian_cmi",
    "knn_cmi",
    "knn_cmi_terms",
    "task_cmi",
    "task_r2_gain",
]


def gaussian_cmi(cov: np.ndarray, dx: int, dy: int) -> float:
    """I(x; y | w) in nats for a joint Gaussian over (x, y, w) with covariance ``cov``.

    x is the first ``dx`` dimensions, y the next ``dy``, w the rest:
    ½ ln(det Σ_xw det Σ_yw / (det Σ_w det Σ_xyw)).
    """
    cov = np.asarray(cov, dtype=np.float64)
    d = cov.shape[0]
    ix, iy, iw = np.arange(dx), np.arange(dx, dx + dy), np.arange(dx + dy, d)

    def ld(idx: np.ndarray) -> float:
        return 0.0 if idx.size == 0 else float(np.linalg.slogdet(cov[np.ix_(idx, idx)])[1])

    return 0.5 * (ld(np.r_[ix, iw]) + ld(np.r_[iy, iw]) - ld(iw) - ld(np.arange(d)))


def knn_cmi_terms(x: Any, y: Any, w: Any, k: int = 5, *, jitter: float = 1e-10,
                  rng: np.random.Generator | None = None, workers: int = 1) -> np.ndarray:
    """Per-sample terms of the Frenzel–Pompe estimator; their mean is Î(x; y | w) in nats.

    Frenzel & Pompe 2007 (eq. 3), the conditional form of KSG estimator 1: with ε(i) the
    max-norm distance from sample i to its k-th neighbour in the joint (x, y, w) space and
    n_xw(i), n_yw(i), n_w(i) the numbers of *other* samples strictly within ε(i) in those
    subspaces, term i is ψ(k) − ψ(n_xw + 1) − ψ(n_yw + 1) + ψ(n_w + 1). Strict counts as in
    :func:`~repbench.metrics.mutual_information.ksg_terms` (radius ``nextafter(ε, 0)``; the
    tree's count includes the point itself, which supplies the +1). Inputs are used as given:
    standardize columns of different scales first.
    """
    x, y, w = _as_2d(x, "x"), _as_2d(y, "y"), _as_2d(w, "w")
    n = x.shape[0]
    if y.shape[0] != n or w.shape[0] != n:
        raise DataError(f"x, y, w must have the same rows; got {n}, {y.shape[0]}, {w.shape[0]}")
    if not 1 <= k < n:
        raise DataError(f"kNN CMI needs 1 <= k < number of samples; got k={k} with {n}")
    x, y, w = (_jitter(a, jitter, rng) for a in (x, y, w))
    xyw = np.hstack([x, y, w])
    dist, _ = cKDTree(xyw).query(xyw, k=k + 1, p=np.inf, workers=workers)
    eps = dist[:, -1]
    if (eps <= 0).any():
        raise DataError(f"{int((eps <= 0).sum())} samples have {k} exact duplicates; "
                        "pass jitter > 0")
    radius = np.nextafter(eps, 0)

    def count(a: np.ndarray) -> np.ndarray:
        return cKDTree(a).query_ball_point(a, radius, p=np.inf, return_length=True,
                                           workers=workers)

    n_xw, n_yw = count(np.hstack([x, w])), count(np.hstack([y, w]))
    n_w = count(w) if w.shape[1] else np.full(n, n)
    return digamma(k) - digamma(n_xw) - digamma(n_yw) + digamma(n_w)


def knn_cmi(x: Any, y: Any, w: Any, k: int = 5, *, jitter: float = 1e-10,
            rng: np.random.Generator | None = None, workers: int = 1) -> float:
    """Frenzel–Pompe kNN estimate of I(x; y | w) in nats (not clipped at zero).

    With an empty ``w`` (zero columns) it equals KSG estimator 1 of I(x; y).
    """
    return float(np.mean(knn_cmi_terms(x, y, w, k, jitter=jitter, rng=rng, workers=workers)))


def complementary_columns(task_state: np.ndarray, robot_state: np.ndarray,
                          determined_tol: float = 1e-6) -> tuple[np.ndarray, list[float]]:
    """Mask of the task-state columns the robot state does *not* determine, and per column the
    residual variance share 1 − R² of a least-squares fit from ``[robot_state, 1]``.

    A column is determined when 1 − R² < ``determined_tol``; constant columns are not
    complementary either (nothing to know).
    """
    t = np.asarray(task_state, dtype=np.float64)
    design = np.hstack([np.asarray(robot_state, dtype=np.float64), np.ones((len(t), 1))])
    coef, *_ = np.linalg.lstsq(design, t, rcond=None)
    resid = ((t - design @ coef) ** 2).mean(0)
    var = t.var(0)
    share = np.where(var > 0, resid / np.where(var > 0, var, 1.0), 0.0)
    return (var > 0) & (share >= determined_tol), [float(v) for v in share]


def _standardize_cols(a: np.ndarray) -> np.ndarray:
    sd = a.std(0)
    return (a - a.mean(0)) / np.where(sd > 0, sd, 1.0)


def _prepare(name: str, z: np.ndarray, task_state: np.ndarray | None,
             robot_state: np.ndarray | None, determined_tol: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Varying columns of z and r, the complementary task-state columns c, and notes."""
    if task_state is None or robot_state is None:
        raise DataError(f"{name}: needs task_state= and robot_state= arrays (the latents stage "
                        "stores them; re-run it if the store predates them)")
    zv, dropped = drop_constant(z)
    rv, dropped_r = drop_constant(robot_state)
    keep, share = complementary_columns(task_state, rv, determined_tol)
    notes: dict[str, Any] = {
        "dropped_constant_dims": dropped, "dropped_constant_robot_dims": dropped_r,
        "task_state_columns_used": np.flatnonzero(keep).tolist(),
        "task_state_unexplained_share": share, "determined_tol": float(determined_tol),
    }
    return zv, rv, task_state[:, keep], notes


def _check_task_cmi(*, k: int, **_: Any) -> None:
    """Range checks of :func:`task_cmi`'s parameters (the planner runs them too)."""
    check_params("task_cmi", k=(int(k) >= 1, f"must be >= 1, got {k}"))


@metric("task_cmi", higher_is_better=True, check=_check_task_cmi,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="I(z; task state | robot state) in nats: kNN CMI (Frenzel–Pompe), ranking")
def task_cmi(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
             *, robot_state: np.ndarray | None = None, task_state: np.ndarray | None = None,
             k: int = 5, determined_tol: float = 1e-6, n_bootstrap: int = 100) -> MetricResult:
    """Conditional MI I(z; c | r): what z tells about the task beyond the robot state (nats).

    c are the complementary task-state columns (module docstring), r the robot state; z, c
    and r are standardized per column, constant columns dropped. Frenzel–Pompe kNN estimator
    (k = 5, max norm). Like KSG it is biased (towards 0) in many dimensions and an invertible
    encoder has infinite true CMI, so use it to rank encoders on one dataset. z with no varying
    column, or no complementary column, scores 0. CI: percentile bootstrap over episodes of the
    per-sample terms (neighbour counts held fixed). ``z_true`` is not used.
    """
    _check_task_cmi(k=k)
    zv, rv, c, notes = _prepare("task_cmi", z, task_state, robot_state, determined_tol)
    if zv.shape[1] == 0 or c.shape[1] == 0:
        why = "z is constant" if zv.shape[1] == 0 else "robot state determines the task state"
        return MetricResult(0.0, True, 0.0, 0.0, extras={**notes, "note": why})
    terms = knn_cmi_terms(_standardize_cols(zv), _standardize_cols(c), _standardize_cols(rv),
                          int(k), rng=rng)
    lo, hi, reps = episode_bootstrap_replicates(lambda rows: terms[rows].mean(), episode, rng,
                                                n_bootstrap)
    return MetricResult(float(terms.mean()), True, lo, hi,
                        extras={**notes, "k": int(k), "n_samples": len(zv),
                                "bootstrap_replicates": reps})


def held_out_r2(x: np.ndarray, y: np.ndarray, train: np.ndarray, test: np.ndarray, *,
                model: str, hidden: tuple[int, ...] = (64, 64), max_iter: int = 200,
                seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Fit ``x → y`` on ``train`` rows, predict ``test`` rows; y standardized with training
    statistics. Returns ``(per-row squared error, per-row squared deviation from the training
    mean)``, both summed over y's columns, so that 1 − Σerr/Σdev over any set of test rows is
    the out-of-sample R² on them.

    ``model``: ``"ridge"`` (scikit-learn ``RidgeCV``, α chosen by efficient leave-one-out over
    1e-3…1e3) or ``"mlp"`` (``MLPRegressor`` with ``hidden`` ReLU layers, Adam), both after a
    ``StandardScaler`` of x fit on the training rows. x with no columns predicts the training
    mean.
    """
    import warnings

    from sklearn.exceptions import ConvergenceWarning
    from sklearn.linear_model import RidgeCV
    from sklearn.neural_network import MLPRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    my, sy = y[train].mean(0), y[train].std(0)
    sy[sy == 0] = 1.0
    ys = (y - my) / sy
    if x.shape[1] == 0:
        pred = np.zeros((test.size, y.shape[1]))
    else:
        if model == "ridge":
            reg: Any = RidgeCV(alphas=np.logspace(-3, 3, 13))
        elif model == "mlp":
            reg = MLPRegressor(hidden_layer_sizes=tuple(hidden), max_iter=int(max_iter),
                               random_state=seed)
        else:
            raise DataError(f"held_out_r2: model must be 'ridge' or 'mlp', got {model!r}")
        pipe = make_pipeline(StandardScaler(), reg)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            pipe.fit(x[train], ys[train])
        pred = np.asarray(pipe.predict(x[test])).reshape(test.size, -1)
    err = ((pred - ys[test]) ** 2).sum(1)
    dev = (ys[test] ** 2).sum(1)
    return err, dev


def r2_of(err: np.ndarray, dev: np.ndarray) -> float:
    """Out-of-sample R² = 1 − Σerr / Σdev (see :func:`held_out_r2`)."""
    return float(1.0 - err.sum() / max(float(dev.sum()), 1e-300))


def _check_task_r2_gain(*, hidden: Any, test_fraction: float, max_iter: int, **_: Any
                        ) -> None:
    """Range checks of :func:`task_r2_gain`'s parameters (the planner runs them too)."""
    check_params("task_r2_gain",
                 test_fraction=(0 < float(test_fraction) < 1, "must be in (0, 1)"),
                 max_iter=(int(max_iter) >= 1, "must be >= 1"),
                 hidden=(all(int(h) >= 1 for h in hidden), "must list layer sizes >= 1"))


@metric("task_r2_gain", higher_is_better=True, check=_check_task_r2_gain,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="Held-out R² of the task state from z ⊕ robot state minus from robot state")
def task_r2_gain(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                 rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                 task_state: np.ndarray | None = None, hidden: tuple[int, ...] = (64, 64),
                 max_iter: int = 200, test_fraction: float = 0.3, determined_tol: float = 1e-6,
                 n_bootstrap: int = 100) -> MetricResult:
    """R²(c | z ⊕ r) − R²(c | r) on held-out episodes (higher is better; 0 = z adds nothing).

    c are the complementary task-state columns (module docstring; for the peg-in-hole the
    tip − hole offset in x, y), r the robot state. Both predictors are the same scikit-learn
    MLP (``hidden`` ReLU layers, Adam, ``max_iter`` epochs, inputs standardized), fit on the
    training episodes; R² is out-of-sample, pooled over c's standardized columns
    (:func:`held_out_r2`). A *nonlinear* probe: it asks whether the information is there in a
    form an MLP can use, between the form-invariant ``task_cmi`` and the linear
    ``task_probe``. A z with no varying column scores exactly 0 (the same MLP on the same
    inputs). The gain can exceed 1: on held-out episodes an MLP on the robot state alone can
    extrapolate worse than a constant (measured on PegInHole-v0: R² −0.68); that baseline is
    the same for every encoder of a run, so it shifts values without changing their ranking.
    CI: percentile bootstrap over held-out episodes of the difference (models held fixed).
    Extras: both R² values. ``z_true`` is not used.
    """
    from repbench.dataset import episode_split

    _check_task_r2_gain(hidden=hidden, test_fraction=test_fraction, max_iter=max_iter)
    zv, rv, c, notes = _prepare("task_r2_gain", z, task_state, robot_state, determined_tol)
    if c.shape[1] == 0:
        return MetricResult(0.0, True, 0.0, 0.0,
                            extras={**notes, "note": "robot state determines the task state"})
    train, test = episode_split(episode, test_fraction, seed_from(rng))
    seed = seed_from(rng)
    hidden = tuple(int(h) for h in hidden)
    err_r, dev = held_out_r2(rv, c, train, test, model="mlp", hidden=hidden,
                             max_iter=max_iter, seed=seed)
    err_j, _ = held_out_r2(np.hstack([zv, rv]), c, train, test, model="mlp", hidden=hidden,
                           max_iter=max_iter, seed=seed)
    def gain(rows: np.ndarray) -> float:
        return r2_of(err_j[rows], dev[rows]) - r2_of(err_r[rows], dev[rows])

    all_rows = np.arange(test.size)
    value = gain(all_rows)
    lo, hi, reps = episode_bootstrap_replicates(gain, episode[test], rng, n_bootstrap)
    extras = {**notes, "r2_z_and_robot": r2_of(err_j, dev), "r2_robot_only": r2_of(err_r, dev),
              "n_train": int(train.size), "n_test": int(test.size),
              "split": "whole episodes held out", "hidden": list(hidden),
              "max_iter": int(max_iter), "bootstrap_replicates": reps}
    if not math.isfinite(value):
        raise DataError("task_r2_gain: R² is not finite; the held-out task state is constant")
    return MetricResult(value, True, lo, hi, extras=extras)
