"""Usable information: what z tells about the task beyond the robot state, to a given learner.

The RL agent observes μ_z ⊕ robot state r; what it cannot read off r is the task's hidden part c,
the *complementary* task-state columns (:mod:`repbench.metrics.task_information`: for the
peg-in-hole the tip − hole offset in x and y). ``task_cmi`` measures I(z; c | r) with a kNN
estimator, which any invertible map of z leaves unchanged and which can saturate in many
dimensions. The four metrics here ask instead how much of that information a *given* family of
predictors can use, or estimate the CMI a second way:

* ``task_sdl`` — surplus description length (Whitney et al. 2020, "Evaluating representations
  by the complexity of learning low-loss predictors"): Σₙ max(0, L(n) − ε) over the training
  sizes n, L(n) the held-out loss of an MLP probe z ⊕ r → c trained on n rows (lower is better).
* ``task_eps_samples`` — ε-sample complexity (the same paper): log₂ of the smallest n with
  L(n) ≤ ε; log₂ of twice the largest n when none reaches it (lower is better).
* ``task_vinfo_linear`` — predictive V-information (Xu et al. 2020, "A theory of usable
  information under computational constraints") for the linear-Gaussian family, conditional on
  r: ½ Σ_k ln(σ²_{k|r} / σ²_{k|r,z}), held-out residual variances of ridge fits (nats).
* ``task_cmi_gc`` — Gaussian-copula CMI (Ince et al. 2017, "A statistical framework for
  neuroimaging data analysis based on mutual information estimated via a Gaussian copula"):
  every column's ranks mapped to a standard normal, then the Gaussian closed form of
  I(z; c | r) in nats; the check on ``task_cmi``'s kNN estimate (studies/metric_search).

The loss–data curve L(n) (:func:`loss_data_curve`): the rows of the training episodes in one
random order; the probe for size n is trained on the first n of them (nested subsets), a
scikit-learn ``MLPRegressor`` (``hidden`` ReLU layers, Adam at its default step size) for a fixed
number of gradient steps (``train_steps`` in batches of ``batch_size``, as Whitney et al.'s
library does: 4000 there, 1000 here to keep a set of 8500 rows to a few seconds), no early
stopping. L(n) = mean over c's columns of Σ(ĉ_k − c_k)² / Σ(c_k − c̄_k)² on the held-out
episodes (1 − R², targets standardized with the training episodes' statistics; c̄_k their
mean). One probe seed per size (the paper averages several).

Rows: every stored row, like ``task_cmi``. ``z_true`` is not used.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from typing import Any

import numpy as np
from scipy import stats

from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import (
    check_params,
    episode_bootstrap_replicates,
    seed_from,
)
from repbench.metrics.task_information import _prepare, gaussian_cmi, held_out_r2

__all__ = [
    "copula_normalize",
    "gaussian_copula_cmi",
    "loss_data_curve",
    "task_cmi_gc",
    "task_eps_samples",
    "task_sdl",
    "task_vinfo_linear",
]

#: Training sizes of the loss–data curve (the pre-registration's).
SIZES = (64, 128, 256, 512, 1024, 2048, 4096)


# -- the loss-data curve (task_sdl, task_eps_samples) ------------------------------------------

def _fit_predict_mlp(x_train: np.ndarray, y_train: np.ndarray, x_test: np.ndarray, *,
                     hidden: tuple[int, ...], train_steps: int, batch_size: int, seed: int
                     ) -> np.ndarray:
    """An MLP probe trained for ``train_steps`` Adam steps on (x_train, y_train); its
    predictions on x_test. Inputs standardized on x_train; no early stopping."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from threadpoolctl import threadpool_limits

    n = len(x_train)
    batch = min(int(batch_size), n)
    epochs = max(1, math.ceil(int(train_steps) / math.ceil(n / batch)))
    reg = MLPRegressor(hidden_layer_sizes=hidden, batch_size=batch, max_iter=epochs,
                       early_stopping=False, tol=0.0, n_iter_no_change=epochs + 1,
                       random_state=seed)
    pipe = make_pipeline(StandardScaler(), reg)
    # tiny matrices: one BLAS thread is faster and gives the same bits on every machine
    with warnings.catch_warnings(), threadpool_limits(limits=1):
        warnings.simplefilter("ignore", ConvergenceWarning)
        pipe.fit(x_train, y_train)
        return np.asarray(pipe.predict(x_test)).reshape(len(x_test), -1)


_CURVE_CACHE: dict[str, tuple[list[int], np.ndarray, np.ndarray]] = {}


def loss_data_curve(x: np.ndarray, y: np.ndarray, train: np.ndarray, test: np.ndarray,
                    sizes: tuple[int, ...], *, hidden: tuple[int, ...], train_steps: int,
                    batch_size: int, seed: int) -> tuple[list[int], np.ndarray, np.ndarray]:
    """Squared held-out errors of MLP probes ``x → y`` trained on n training rows, n in sizes.

    Returns ``(sizes used, err [n_sizes, n_test, K], dev [n_test, K])``: per held-out row and
    y column the squared error of size n's probe and the squared deviation from the training
    mean, y standardized with the ``train`` rows' statistics, so that
    ``(err[i][rows].sum(0) / dev[rows].sum(0)).mean()`` is L(n) on any set of held-out rows
    (:func:`curve_losses`). Sizes above the number of training rows are left out. The training
    rows are put in one random order (``seed``); size n trains on the first n (nested). The
    result of the last call is cached, so ``task_sdl`` and ``task_eps_samples`` on the same
    arrays train the probes once.
    """
    key = hashlib.sha256(b"".join([
        np.ascontiguousarray(a).tobytes() for a in (x, y, train, test)]) + repr(
        (x.shape, y.shape, tuple(sizes), tuple(hidden), train_steps, batch_size, seed)
    ).encode()).hexdigest()
    if key in _CURVE_CACHE:
        return _CURVE_CACHE[key]
    my, sy = y[train].mean(0), y[train].std(0)
    sy[sy == 0] = 1.0
    ys = (y - my) / sy
    order = np.random.default_rng(seed).permutation(train)
    used = [int(n) for n in sizes if n <= train.size]
    err = np.empty((len(used), test.size, y.shape[1]))
    for i, n in enumerate(used):
        rows = order[:n]
        if x.shape[1] == 0:
            pred = np.broadcast_to(ys[rows].mean(0), (test.size, y.shape[1]))
        else:
            pred = _fit_predict_mlp(x[rows], ys[rows], x[test], hidden=hidden,
                                    train_steps=train_steps, batch_size=batch_size, seed=seed)
        err[i] = (pred - ys[test]) ** 2
    dev = ys[test] ** 2
    _CURVE_CACHE.clear()
    _CURVE_CACHE[key] = (used, err, dev)
    return used, err, dev


def curve_losses(err: np.ndarray, dev: np.ndarray, rows: np.ndarray | None = None
                 ) -> np.ndarray:
    """L(n) per size: 1 − R² per y column on ``rows`` (all held-out rows by default), averaged
    over the columns (see :func:`loss_data_curve`)."""
    if rows is not None:
        err, dev = err[:, rows], dev[rows]
    return (err.sum(1) / np.maximum(dev.sum(0), 1e-300)).mean(1)


def surplus_description_length(losses: np.ndarray, epsilon: float) -> float:
    """Σₙ max(0, L(n) − ε) over the sizes of the curve (Whitney et al. 2020, on a grid)."""
    return float(np.maximum(np.asarray(losses) - epsilon, 0.0).sum())


def eps_sample_complexity(losses: np.ndarray, sizes: list[int], epsilon: float,
                          largest: int) -> float:
    """log₂ of the smallest size with L(n) ≤ ε; log₂(2 · ``largest``) when none reaches it."""
    hit = [n for n, loss in zip(sizes, losses, strict=True) if loss <= epsilon]
    return float(math.log2(hit[0] if hit else 2 * largest))


def _check_curve(name: str) -> Any:
    """Range checks of ``task_sdl``'s / ``task_eps_samples``' parameters."""
    def check(*, hidden: Any, sizes: Any, epsilon: float, train_steps: int, batch_size: int,
              test_fraction: float, **_: Any) -> None:
        sz = [int(n) for n in sizes]
        check_params(name,
                     hidden=(len(hidden) > 0 and all(int(h) >= 1 for h in hidden),
                             "must list layer sizes >= 1"),
                     sizes=(len(sz) > 0 and all(n >= 2 for n in sz) and sz == sorted(set(sz)),
                            f"must be increasing training sizes >= 2, got {list(sizes)}"),
                     epsilon=(float(epsilon) > 0, f"must be > 0, got {epsilon}"),
                     train_steps=(int(train_steps) >= 1, "must be >= 1"),
                     batch_size=(int(batch_size) >= 1, "must be >= 1"),
                     test_fraction=(0 < float(test_fraction) < 1, "must be in (0, 1)"))

    return check


def _curve_metric(name: str, z: np.ndarray, episode: np.ndarray, rng: np.random.Generator, *,
                  robot_state: np.ndarray | None, task_state: np.ndarray | None,
                  hidden: tuple[int, ...], sizes: tuple[int, ...], epsilon: float,
                  train_steps: int, batch_size: int, test_fraction: float,
                  determined_tol: float, n_bootstrap: int) -> MetricResult:
    """``task_sdl`` (``name`` = "task_sdl") or ``task_eps_samples`` from one loss–data curve."""
    from repbench.dataset import episode_split

    _check_curve(name)(hidden=hidden, sizes=sizes, epsilon=epsilon, train_steps=train_steps,
                       batch_size=batch_size, test_fraction=test_fraction)
    sizes = tuple(int(n) for n in sizes)
    hidden = tuple(int(h) for h in hidden)
    epsilon = float(epsilon)
    zv, rv, c, notes = _prepare(name, z, task_state, robot_state, determined_tol)
    sdl = name == "task_sdl"
    params = {"hidden": list(hidden), "sizes": list(sizes), "epsilon": epsilon,
              "train_steps": int(train_steps), "batch_size": int(batch_size)}
    if c.shape[1] == 0:  # nothing left to learn: every loss is 0
        value = 0.0 if sdl else math.log2(sizes[0])
        return MetricResult(value, False, value, value, extras={
            **notes, **params, "note": "robot state determines the task state"})
    train, test = episode_split(episode, test_fraction, seed_from(rng))
    seed = seed_from(rng)
    if train.size < sizes[0]:
        raise DataError(f"{name}: the training episodes have {train.size} rows, fewer than the "
                        f"smallest training size {sizes[0]}; collect more data or lower sizes")
    used, err, dev = loss_data_curve(np.hstack([zv, rv]), c, train, test, sizes, hidden=hidden,
                                     train_steps=int(train_steps), batch_size=int(batch_size),
                                     seed=seed)

    def statistic(rows: np.ndarray | None) -> float:
        losses = curve_losses(err, dev, rows)
        return (surplus_description_length(losses, epsilon) if sdl
                else eps_sample_complexity(losses, used, epsilon, sizes[-1]))

    losses = curve_losses(err, dev)
    value = statistic(None)
    lo, hi, reps = episode_bootstrap_replicates(statistic, episode[test], rng, n_bootstrap)
    if not math.isfinite(value):
        raise DataError(f"{name}: the loss is not finite; the held-out task state is constant")
    extras = {**notes, **params,
              "loss_data_curve": {"n": used, "loss": [float(v) for v in losses]},
              "sizes_skipped": [n for n in sizes if n not in used],
              "n_train": int(train.size), "n_test": int(test.size),
              "split": "whole episodes held out", "bootstrap_replicates": reps}
    return MetricResult(value, False, lo, hi, extras=extras)


@metric("task_sdl", higher_is_better=False, check=_check_curve("task_sdl"),
        description="Surplus description length (Whitney et al. 2020) of an MLP probe "
                    "z ⊕ robot state → task state, ε = 0.2")
def task_sdl(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
             *, robot_state: np.ndarray | None = None, task_state: np.ndarray | None = None,
             hidden: tuple[int, ...] = (64, 64), sizes: tuple[int, ...] = SIZES,
             epsilon: float = 0.2, train_steps: int = 1000, batch_size: int = 256,
             test_fraction: float = 0.3, determined_tol: float = 1e-6,
             n_bootstrap: int = 100) -> MetricResult:
    """Surplus description length SDL_ε = Σₙ max(0, L(n) − ε) (lower is better; 0: a probe
    reaches loss ε from 64 rows on).

    L(n): the held-out loss (1 − R², mean over the complementary task-state columns c) of an
    MLP probe from z ⊕ r trained on n rows of the training episodes, n in ``sizes``
    (module docstring, :func:`loss_data_curve`); 30 % of the episodes held out. Whitney et al.
    2020 sum over every n; this sums over the pre-registered grid 64 … 4096, so each term
    stands for a doubling of the data. Sizes above the number of training rows are left out
    (``extras["sizes_skipped"]``): compare values only across sets of the same size. CI:
    percentile bootstrap over held-out episodes (probes held fixed). Extras: the curve
    (``loss_data_curve``). ``z_true`` is not used.
    """
    return _curve_metric("task_sdl", z, episode, rng, robot_state=robot_state,
                         task_state=task_state, hidden=hidden, sizes=sizes, epsilon=epsilon,
                         train_steps=train_steps, batch_size=batch_size,
                         test_fraction=test_fraction, determined_tol=determined_tol,
                         n_bootstrap=n_bootstrap)


@metric("task_eps_samples", higher_is_better=False, check=_check_curve("task_eps_samples"),
        description="ε-sample complexity (Whitney et al. 2020), log2 rows an MLP probe z ⊕ "
                    "robot state → task state needs for loss ≤ 0.2")
def task_eps_samples(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                     rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                     task_state: np.ndarray | None = None, hidden: tuple[int, ...] = (64, 64),
                     sizes: tuple[int, ...] = SIZES, epsilon: float = 0.2,
                     train_steps: int = 1000, batch_size: int = 256, test_fraction: float = 0.3,
                     determined_tol: float = 1e-6, n_bootstrap: int = 100) -> MetricResult:
    """ε-sample complexity: log₂ of the smallest training size n with L(n) ≤ ε, or
    log₂(2 · max ``sizes``) (13 by default) when no size reaches it (lower is better).

    The same loss–data curve as :func:`task_sdl` (computed once when both run on the same
    arrays in one process). CI: percentile bootstrap over held-out episodes (probes held
    fixed). ``z_true`` is not used.
    """
    return _curve_metric("task_eps_samples", z, episode, rng, robot_state=robot_state,
                         task_state=task_state, hidden=hidden, sizes=sizes, epsilon=epsilon,
                         train_steps=train_steps, batch_size=batch_size,
                         test_fraction=test_fraction, determined_tol=determined_tol,
                         n_bootstrap=n_bootstrap)


# -- linear V-information ----------------------------------------------------------------------

def _check_vinfo(*, test_fraction: float, **_: Any) -> None:
    """Range checks of :func:`task_vinfo_linear`'s parameters."""
    check_params("task_vinfo_linear",
                 test_fraction=(0 < float(test_fraction) < 1, "must be in (0, 1)"))


@metric("task_vinfo_linear", higher_is_better=True, check=_check_vinfo,
        description="Linear conditional V-information (Xu et al. 2020) of the task state "
                    "from z given robot state, nats")
def task_vinfo_linear(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                      rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                      task_state: np.ndarray | None = None, test_fraction: float = 0.3,
                      determined_tol: float = 1e-6, n_bootstrap: int = 100) -> MetricResult:
    """I_V(z → c | r) = ½ Σ_k ln(σ²_{k|r} / σ²_{k|r,z}) in nats (higher is better; 0: a
    linear predictor gains nothing from z).

    V the linear-Gaussian predictive family: for each standardized complementary task-state
    column c_k a ridge fit (``RidgeCV``, α by leave-one-out over 1e-3 … 1e3, inputs
    standardized) from r alone and from r ⊕ z on the training episodes; σ² their mean squared
    errors on the held-out episodes (the Gaussian's optimal variance, so each term is the
    held-out drop in Gaussian log-loss, Xu et al. 2020). For jointly Gaussian data with
    columns of c independent given r and given (r, z) it equals I(z; c | r) (exactly Σ_k of
    the per-column CMIs). Held out, so it can be slightly negative when z only adds noise.
    A z with no varying column scores exactly 0. CI: percentile bootstrap over held-out
    episodes (fits held fixed). ``z_true`` is not used.
    """
    from repbench.dataset import episode_split

    _check_vinfo(test_fraction=test_fraction)
    zv, rv, c, notes = _prepare("task_vinfo_linear", z, task_state, robot_state,
                                determined_tol)
    if c.shape[1] == 0:
        return MetricResult(0.0, True, 0.0, 0.0,
                            extras={**notes, "note": "robot state determines the task state"})
    train, test = episode_split(episode, test_fraction, seed_from(rng))
    joint = np.hstack([zv, rv])
    err_r = np.empty((test.size, c.shape[1]))
    err_j = np.empty_like(err_r)
    for k in range(c.shape[1]):
        err_r[:, k], _ = held_out_r2(rv, c[:, [k]], train, test, model="ridge")
        if zv.shape[1] == 0:
            err_j[:, k] = err_r[:, k]
        else:
            err_j[:, k], _ = held_out_r2(joint, c[:, [k]], train, test, model="ridge")

    def vinfo(rows: np.ndarray) -> float:
        return float(0.5 * np.sum(np.log(err_r[rows].mean(0)
                                         / np.maximum(err_j[rows].mean(0), 1e-300))))

    all_rows = np.arange(test.size)
    value = vinfo(all_rows)
    if not math.isfinite(value):
        raise DataError("task_vinfo_linear: a residual variance is zero on the held-out "
                        "episodes; the held-out task state is constant")
    lo, hi, reps = episode_bootstrap_replicates(vinfo, episode[test], rng, n_bootstrap)
    per_dim = 0.5 * np.log(err_r.mean(0) / np.maximum(err_j.mean(0), 1e-300))
    extras = {**notes, "per_column": [float(v) for v in per_dim],
              "residual_variance_robot_only": [float(v) for v in err_r.mean(0)],
              "residual_variance_z_and_robot": [float(v) for v in err_j.mean(0)],
              "n_train": int(train.size), "n_test": int(test.size),
              "split": "whole episodes held out", "bootstrap_replicates": reps}
    return MetricResult(value, True, lo, hi, extras=extras)


# -- Gaussian-copula CMI -----------------------------------------------------------------------

def copula_normalize(x: np.ndarray) -> np.ndarray:
    """Each column's ranks (ties averaged) / (N + 1), mapped through the standard normal's
    inverse CDF (Ince et al. 2017's ``copnorm``): standard normal margins, the same copula."""
    x = np.asarray(x, dtype=np.float64)
    u = stats.rankdata(x, axis=0) / (x.shape[0] + 1)
    return np.asarray(stats.norm.ppf(u))


def gaussian_copula_cmi(x: np.ndarray, y: np.ndarray, w: np.ndarray, *, ridge: float = 1e-6
                        ) -> tuple[float, np.ndarray]:
    """Gaussian-copula estimate of I(x; y | w) in nats (Ince et al. 2017), and per-sample terms.

    Copula-normalize every column (:func:`copula_normalize`) of the arrays as given; Σ the
    sample covariance (divisor N) of the normalized columns with ``ridge`` added to its
    diagonal; the value is ½ ln(det Σ_xw det Σ_yw / (det Σ_w det Σ_xyw))
    (:func:`~repbench.metrics.task_information.gaussian_cmi`). Exact when the joint copula is
    Gaussian (any monotone map of each column of jointly Gaussian data); no finite-sample bias
    correction (about d_x·d_y / 2N nats). The terms are, per sample, the log-likelihood ratio
    ln p(y | x, w) − ln p(y | w) under the fitted Gaussian; their mean equals the value up to
    the ridge (exactly at ``ridge=0``).
    """
    x, y, w = (np.asarray(a, dtype=np.float64).reshape(len(a), -1) for a in (x, y, w))
    g = copula_normalize(np.hstack([x, y, w]))
    g -= g.mean(0)
    dx, dy = x.shape[1], y.shape[1]
    cov = np.atleast_2d(np.cov(g, rowvar=False, bias=True)) + ridge * np.eye(g.shape[1])
    value = gaussian_cmi(cov, dx, dy)
    iy = np.arange(dx, dx + dy)
    iw = np.arange(dx + dy, g.shape[1])

    def log_lik(given: np.ndarray) -> np.ndarray:
        """ln p(y | g[:, given]) per sample, up to the constant −(d_y/2) ln 2π."""
        s_yy = cov[np.ix_(iy, iy)]
        if given.size:
            s_gg, s_yg = cov[np.ix_(given, given)], cov[np.ix_(iy, given)]
            beta = np.linalg.solve(s_gg, s_yg.T)  # [d_given, d_y]
            resid = g[:, iy] - g[:, given] @ beta
            s_yy = s_yy - s_yg @ beta
        else:
            resid = g[:, iy]
        maha = np.einsum("ij,ij->i", resid, np.linalg.solve(s_yy, resid.T).T)
        return -0.5 * (np.linalg.slogdet(s_yy)[1] + maha)

    terms = log_lik(np.r_[np.arange(dx), iw]) - log_lik(iw)
    return value, terms


def _check_cmi_gc(*, ridge: float, **_: Any) -> None:
    """Range checks of :func:`task_cmi_gc`'s parameters."""
    check_params("task_cmi_gc", ridge=(float(ridge) >= 0, f"must be >= 0, got {ridge}"))


@metric("task_cmi_gc", higher_is_better=True, check=_check_cmi_gc,
        description="I(z; task state | robot state) in nats, Gaussian-copula estimate "
                    "(Ince et al. 2017)")
def task_cmi_gc(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                task_state: np.ndarray | None = None, ridge: float = 1e-6,
                determined_tol: float = 1e-6, n_bootstrap: int = 100) -> MetricResult:
    """Gaussian-copula conditional MI I(z; c | r) in nats (higher is better).

    The same c (complementary task-state columns) and r as ``task_cmi``, constant columns
    dropped; every column copula-normalized (ranks → standard normal), then
    ½ ln(det Σ_zr det Σ_cr / (det Σ_r det Σ_zcr)) with ``ridge`` on the covariance diagonal
    (:func:`gaussian_copula_cmi`). Invariant to a monotone map of each column; exact for
    Gaussian copulas, a parametric approximation otherwise. It does not saturate with the
    number of samples as a kNN estimate does, hence the check beside ``task_cmi``. z with no
    varying column, or no complementary column, scores 0. CI: percentile bootstrap over
    episodes of the mean per-sample log-likelihood ratio under the fitted Gaussian (fit held
    fixed, as ``task_cmi`` holds its neighbour counts), centred on the value.
    ``z_true`` is not used.
    """
    _check_cmi_gc(ridge=ridge)
    zv, rv, c, notes = _prepare("task_cmi_gc", z, task_state, robot_state, determined_tol)
    if zv.shape[1] == 0 or c.shape[1] == 0:
        why = "z is constant" if zv.shape[1] == 0 else "robot state determines the task state"
        return MetricResult(0.0, True, 0.0, 0.0, extras={**notes, "note": why})
    value, terms = gaussian_copula_cmi(zv, c, rv, ridge=float(ridge))
    shift = value - float(terms.mean())
    lo, hi, reps = episode_bootstrap_replicates(lambda rows: terms[rows].mean() + shift,
                                                episode, rng, n_bootstrap)
    return MetricResult(value, True, lo, hi,
                        extras={**notes, "ridge": float(ridge), "n_samples": len(zv),
                                "terms_mean_minus_value": -shift,
                                "bootstrap_replicates": reps})
