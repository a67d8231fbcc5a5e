"""Mutual information I(z; z°) between a representation and the true state, and kNN entropy.

What MI means here
------------------
For a deterministic, invertible encoder z = g(z°) of a continuous true state the mutual
information I(z; z°) is **infinite**: knowing z pins z° down exactly. Every finite number below is
finite only because of the estimator (the number of samples, k, the network and its training),
so raw MI estimates of different encoders are comparable only as a ranking made with one
estimator at one sample size. Three metrics are offered:

* ``mine`` — MINE (Belghazi et al. 2018), the paper's estimator and settings; the Donsker–Varadhan
  lower bound evaluated on **held-out episodes** (the training-batch value over-states MI).
* ``ksg`` — the Kraskov–Stögbauer–Grassberger estimator 1 on standardized inputs. At 16 + 16
  dimensions it is strongly biased low (it cannot resolve more than about ln N nats and its
  error grows with dimension); use it to rank, not as an absolute number.
* ``mi_noisy`` — a finite, comparable quantity: I(z̃; z°) with z̃ = standardize(z) + σ·ε,
  ε ~ N(0, I), for a fixed σ. Independent Gaussian noise of fixed size after per-dimension
  standardization makes the true value finite for every encoder (an invertible encoder no
  longer has infinite MI) and invariant to a rescaling of z, so encoders can be compared on
  one scale. For a linear Gaussian channel it has the closed form ½ ln det(I + R/σ²) (R the
  correlation matrix of z), which the tests check. It is estimated with KSG.

Helpers usable on their own: :func:`ksg_mi`, :func:`knn_entropy`, :func:`ksg_terms`,
:func:`gaussian_mi`, :func:`gaussian_entropy`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import digamma

from repbench.devices import torch_threads
from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import (
    check_params,
    drop_constant,
    episode_bootstrap_replicates,
    resolve_device,
    seed_from,
    standardize,
)

__all__ = [
    "gaussian_entropy",
    "gaussian_mi",
    "knn_entropy",
    "ksg",
    "ksg_mi",
    "ksg_terms",
    "mi_noisy",
    "mine",
]


# -- closed forms (for tests and documentation) -------------------------------------------------
def gaussian_mi(cov: np.ndarray, dx: int) -> float:
    """I(x; y) in nats for a joint Gaussian with covariance ``cov``; x is the first ``dx`` dims.

    ½ ln(det Σx det Σy / det Σ).
    """
    cov = np.asarray(cov, dtype=np.float64)
    _, ld = np.linalg.slogdet(cov)
    _, ldx = np.linalg.slogdet(cov[:dx, :dx])
    _, ldy = np.linalg.slogdet(cov[dx:, dx:])
    return 0.5 * (ldx + ldy - ld)


def gaussian_entropy(cov: np.ndarray) -> float:
    """Differential entropy in nats of N(·, cov): ½ ln((2πe)^d det Σ)."""
    cov = np.atleast_2d(np.asarray(cov, dtype=np.float64))
    _, ld = np.linalg.slogdet(cov)
    return 0.5 * (cov.shape[0] * math.log(2 * math.pi * math.e) + ld)


# -- kNN estimators ------------------------------------------------------------------------------
def _as_2d(x: Any, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise DataError(f"{name} must be 1-D or 2-D [samples, dims], got shape {x.shape}")
    if not np.isfinite(x).all():
        raise DataError(f"{name} has NaN/inf values; drop or fix those rows first")
    return x


def _jitter(x: np.ndarray, jitter: float, rng: np.random.Generator | None) -> np.ndarray:
    """Add tiny noise (relative to each column's scale) so that no two points coincide.

    kNN estimators assume continuous variables; exact ties (duplicated rows, discrete
    dimensions) make the k-th neighbour distance zero. As scikit-learn does, a relative noise
    of 1e-10 breaks the ties without changing any estimate measurably.
    """
    if jitter <= 0:
        return x
    rng = rng if rng is not None else np.random.default_rng(0)
    scale = np.maximum(np.abs(x).mean(axis=0), 1e-300)
    return x + jitter * scale * rng.standard_normal(x.shape)


def ksg_terms(x: Any, y: Any, k: int = 5, *, jitter: float = 1e-10,
              rng: np.random.Generator | None = None, workers: int = 1) -> np.ndarray:
    """Per-sample terms of the KSG estimator 1; their mean is Î(x; y) in nats.

    Term i is ψ(k) + ψ(N) − ψ(n_x(i) + 1) − ψ(n_y(i) + 1), where ε(i) is the max-norm distance
    from sample i to its k-th neighbour in the joint space and n_x(i) counts the samples with
    ‖x_j − x_i‖_∞ < ε(i) *strictly* (j ≠ i). The strict inequality is exact: the marginal
    kd-trees count points within radius ``nextafter(ε, 0)``, the largest float below ε, and the
    max-norm distances are computed exactly (no rounding) by the tree. All queries are
    vectorized (``scipy.spatial.cKDTree``).
    """
    x, y = _as_2d(x, "x"), _as_2d(y, "y")
    n = x.shape[0]
    if y.shape[0] != n:
        raise DataError(f"x has {n} rows but y has {y.shape[0]}; they must align")
    if not 1 <= k < n:
        raise DataError(f"KSG needs 1 <= k < number of samples; got k={k} with {n} samples")
    x, y = _jitter(x, jitter, rng), _jitter(y, jitter, rng)
    xy = np.hstack([x, y])
    dist, _ = cKDTree(xy).query(xy, k=k + 1, p=np.inf, workers=workers)
    eps = dist[:, -1]
    if (eps <= 0).any():
        raise DataError(
            f"{int((eps <= 0).sum())} samples have {k} exact duplicates; pass jitter > 0"
        )
    radius = np.nextafter(eps, 0)
    nx = cKDTree(x).query_ball_point(x, radius, p=np.inf, return_length=True, workers=workers)
    ny = cKDTree(y).query_ball_point(y, radius, p=np.inf, return_length=True, workers=workers)
    # query_ball_point counts the point itself: n_x + 1 = nx.
    return digamma(k) + digamma(n) - digamma(nx) - digamma(ny)


def ksg_mi(x: Any, y: Any, k: int = 5, *, jitter: float = 1e-10,
           rng: np.random.Generator | None = None, workers: int = 1) -> float:
    """KSG estimator 1 of I(x; y) in nats (Kraskov, Stögbauer & Grassberger 2004, eq. 8).

    ``x`` [N, dx] and ``y`` [N, dy] are used as given (standardize them first if their
    columns have different scales; the :func:`ksg` metric does). Not clipped at zero.
    """
    return float(np.mean(ksg_terms(x, y, k, jitter=jitter, rng=rng, workers=workers)))


def knn_entropy_terms(x: Any, k: int = 5, *, jitter: float = 1e-10,
                      rng: np.random.Generator | None = None, workers: int = 1) -> np.ndarray:
    """Per-sample terms of the Kozachenko–Leonenko entropy estimate; their mean is Ĥ(x)."""
    x = _as_2d(x, "x")
    n, d = x.shape
    if not 1 <= k < n:
        raise DataError(f"kNN entropy needs 1 <= k < number of samples; got k={k}, n={n}")
    x = _jitter(x, jitter, rng)
    dist, _ = cKDTree(x).query(x, k=k + 1, p=np.inf, workers=workers)
    r = dist[:, -1]
    if (r <= 0).any():
        raise DataError(f"{int((r <= 0).sum())} samples have {k} exact duplicates")
    return digamma(n) - digamma(k) + d * math.log(2.0) + d * np.log(r)


def knn_entropy(x: Any, k: int = 5, *, jitter: float = 1e-10,
                rng: np.random.Generator | None = None, workers: int = 1) -> float:
    """Kozachenko–Leonenko kNN estimate of the differential entropy H(x) in nats.

    Ĥ = ψ(N) − ψ(k) + d ln 2 + (d/N) Σ ln r_i with r_i the max-norm distance to the k-th
    neighbour (Kraskov et al. 2004, eq. 20 with the max norm; the estimator of the ``NPEET``
    implementation the paper used, in nats). Not standardized: H(cX) = H(X) + d ln c holds
    exactly for this estimator.
    """
    return float(np.mean(knn_entropy_terms(x, k, jitter=jitter, rng=rng, workers=workers)))


# -- shared preparation --------------------------------------------------------------------------
def _prepare(z: np.ndarray, z_true: np.ndarray, name: str
             ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Drop constant columns of both sides and standardize; raise if z_true has none left."""
    zv, dropped = drop_constant(z)
    ztv, dropped_true = drop_constant(z_true)
    notes: dict[str, Any] = {"dropped_constant_dims": dropped,
                             "dropped_constant_true_dims": dropped_true}
    if ztv.shape[1] == 0:
        raise DataError(f"{name}: every column of z_true is constant; nothing to measure")
    if zv.shape[1] == 0:
        return zv, standardize(ztv, f"{name} z_true"), notes
    return standardize(zv, f"{name} z"), standardize(ztv, f"{name} z_true"), notes


def _ksg_result(x: np.ndarray, y: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
                k: int, n_bootstrap: int, extras: dict[str, Any]) -> MetricResult:
    terms = ksg_terms(x, y, k, rng=rng)
    value = float(terms.mean())
    lo, hi, reps = episode_bootstrap_replicates(lambda rows: terms[rows].mean(), episode, rng,
                                                n_bootstrap)
    return MetricResult(value, True, lo, hi, extras={**extras, "k": k, "n_samples": len(x),
                                                     "bootstrap_replicates": reps})


# -- metrics -------------------------------------------------------------------------------------
def _check_ksg(*, k: int, **_: Any) -> None:
    """Range checks of :func:`ksg`'s parameters (the planner runs them too)."""
    check_params("ksg", k=(int(k) >= 1, f"must be >= 1, got {k}"))


@metric("ksg", higher_is_better=True, check=_check_ksg,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="KSG kNN estimate of I(z; z°) in nats on standardized inputs (ranking only)")
def ksg(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator, *,
        k: int = 5, n_bootstrap: int = 100) -> MetricResult:
    """KSG estimator 1 of I(z; z°) in nats, on per-dimension standardized z and z°.

    Strongly biased low at 16 + 16 dimensions (the estimate saturates far below the true,
    possibly infinite, MI of an invertible encoder); use it to rank encoders measured on the
    same dataset, not as an absolute number. Constant columns are dropped (they do not change
    any max-norm distance); a fully constant z scores 0 (no information). CI: percentile
    bootstrap over episodes of the per-sample KSG terms (neighbour counts held fixed;
    resampling rows would create duplicate points, which the estimator cannot handle).
    """
    _check_ksg(k=k)
    x, y, notes = _prepare(z, z_true, "ksg")
    if x.shape[1] == 0:
        return MetricResult(0.0, True, 0.0, 0.0, extras={**notes, "note": "z is constant"})
    return _ksg_result(x, y, episode, rng, int(k), n_bootstrap, notes)


def _check_mi_noisy(*, noise: float, k: int, **_: Any) -> None:
    """Range checks of :func:`mi_noisy`'s parameters (the planner runs them too)."""
    check_params("mi_noisy", noise=(float(noise) > 0, f"must be > 0, got {noise}"),
                 k=(int(k) >= 1, f"must be >= 1, got {k}"))


@metric("mi_noisy", higher_is_better=True, check=_check_mi_noisy,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="I(standardized z + σ·noise; z°) in nats: finite, comparable across encoders")
def mi_noisy(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
             *, noise: float = 0.5, k: int = 5, n_bootstrap: int = 100) -> MetricResult:
    """MI of a noisy channel: I(z̃; z°) with z̃ = standardize(z) + noise·ε, ε ~ N(0, I).

    For a deterministic invertible encoder I(z; z°) is infinite; with a fixed noise level after
    per-dimension standardization the MI is finite, invariant to rescaling z, and bounded by
    the channel capacity ½ Σ ln(1 + 1/σ²) per dimension, so it compares encoders on one scale:
    it rewards representations that spread the true state over many, well separated
    directions. Estimated with KSG (k=5) on z̃ and standardized z°; for a linear Gaussian
    channel the closed form is ½ ln det(I + R/σ²) with R the correlation matrix of z. The
    noise draw comes from ``rng`` (fixed seed → fixed value). Constant z columns are dropped;
    a fully constant z scores 0.
    """
    _check_mi_noisy(noise=noise, k=k)
    x, y, notes = _prepare(z, z_true, "mi_noisy")
    if x.shape[1] == 0:
        return MetricResult(0.0, True, 0.0, 0.0, extras={**notes, "note": "z is constant"})
    noise_rng = np.random.default_rng(seed_from(rng))  # own stream for the channel noise
    noisy = x + float(noise) * noise_rng.standard_normal(x.shape)
    capacity = 0.5 * x.shape[1] * math.log(1.0 + 1.0 / float(noise) ** 2)
    return _ksg_result(noisy, y, episode, rng, int(k), n_bootstrap,
                       {**notes, "noise": float(noise), "channel_capacity": capacity})


def _check_mine(*, hidden: int, learning_rate: float, batch_size: int, ema_decay: float,
                steps: int, test_fraction: float, eval_every: int, average_last: int,
                **_: Any) -> None:
    """Range checks of :func:`mine`'s parameters (the planner runs them too)."""
    check_params(
        "mine", hidden=(int(hidden) >= 1, "must be >= 1"),
        learning_rate=(float(learning_rate) > 0, "must be > 0"),
        batch_size=(int(batch_size) >= 2, "must be >= 2"),
        ema_decay=(0 < float(ema_decay) <= 1, "must be in (0, 1]"),
        steps=(int(steps) >= 1, "must be >= 1"), eval_every=(int(eval_every) >= 1, "must be >= 1"),
        average_last=(int(average_last) >= 1, "must be >= 1"),
        test_fraction=(0 < float(test_fraction) < 1, "must be in (0, 1)"),
    )


@metric("mine", higher_is_better=True, check=_check_mine,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="MINE estimate of I(z; z°) in nats on held-out episodes (paper's settings)")
def mine(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator, *,
         hidden: int = 64, learning_rate: float = 5e-5, batch_size: int = 128,
         ema_decay: float = 0.001, steps: int = 15000, test_fraction: float = 0.3,
         eval_every: int = 500, average_last: int = 5, n_marginal: int = 8,
         device: str = "auto", num_threads: int | None = 1, progress: bool = False,
         n_bootstrap: int = 100) -> MetricResult:
    """MINE (Belghazi et al. 2018) lower bound on I(z; z°), evaluated on held-out episodes.

    Paper settings: statistics network T(z, z°) of linear/ReLU layers with ``hidden`` = 64
    units (two hidden layers), Adam with learning rate 5e-5, batch 128, and the bias-corrected
    gradient of MINE whose denominator E[e^T] is a moving average with constant
    ``ema_decay`` = 0.001 (the weight of the newest batch). The moving average is itself
    bias-corrected (divided by 1 − (1 − ema_decay)^t, as Adam does) so that its start at zero
    does not distort the first ~1/ema_decay steps.

    Protocol: inputs are standardized with training statistics; whole episodes
    (``test_fraction``) are held out. Every ``eval_every`` steps the Donsker–Varadhan bound
    mean T(z, z°) − ln mean e^{T(z, z°')} is computed on *all* held-out samples, the marginal
    from ``n_marginal`` shuffles of z° within the held-out set. The reported value is the mean
    of the last ``average_last`` held-out evaluations (no early-stopping selection, which would
    bias it upwards). The training-batch estimate (EMA of the last 1000 steps' bounds) and the
    held-out curve are in extras. The default 15 000 steps reach the plateau of the held-out
    curve for n = 7500, 16 + 16 dimensions (measured: the held-out bound rises until ~12k
    steps, then fluctuates by ±0.1 nats) in about 30-60 s on one CPU core.

    CI: percentile bootstrap over held-out episodes of the final network's bound (training
    variance is not included). Constant columns are dropped; a fully constant z scores 0.
    On CPU the training runs with ``num_threads`` torch threads (default 1: the network is
    too small to gain from more, and extra threads slow it down on a busy machine); the
    previous setting is restored afterwards. ``None`` leaves torch's setting alone.
    """
    threads = num_threads if resolve_device(device) == "cpu" else None
    with torch_threads(threads):
        return _mine(z, z_true, episode, rng, hidden=hidden, learning_rate=learning_rate,
                     batch_size=batch_size, ema_decay=ema_decay, steps=steps,
                     test_fraction=test_fraction, eval_every=eval_every,
                     average_last=average_last, n_marginal=n_marginal, device=device,
                     progress=progress, n_bootstrap=n_bootstrap)


def _mine(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator, *,
          hidden: int, learning_rate: float, batch_size: int, ema_decay: float, steps: int,
          test_fraction: float, eval_every: int, average_last: int, n_marginal: int,
          device: str, progress: bool, n_bootstrap: int) -> MetricResult:
    import torch

    _check_mine(hidden=hidden, learning_rate=learning_rate, batch_size=batch_size,
                ema_decay=ema_decay, steps=steps, test_fraction=test_fraction,
                eval_every=eval_every, average_last=average_last)
    from repbench.dataset import episode_split

    zv, dropped = drop_constant(z)
    ztv, dropped_true = drop_constant(z_true)
    notes: dict[str, Any] = {"dropped_constant_dims": dropped,
                             "dropped_constant_true_dims": dropped_true}
    if ztv.shape[1] == 0:
        raise DataError("mine: every column of z_true is constant; nothing to measure")
    if zv.shape[1] == 0:
        return MetricResult(0.0, True, 0.0, 0.0, extras={**notes, "note": "z is constant"})
    train, test = episode_split(episode, test_fraction, seed_from(rng))
    if train.size < batch_size:
        raise DataError(f"mine: training split has {train.size} rows < batch_size {batch_size}; "
                        "collect more data or lower batch_size")
    # training-split statistics; a column constant on the training split is left unscaled
    mx, sx = zv[train].mean(0), zv[train].std(0)
    my, sy = ztv[train].mean(0), ztv[train].std(0)
    sx[sx == 0], sy[sy == 0] = 1.0, 1.0
    dev = torch.device(resolve_device(device))
    gen = torch.Generator().manual_seed(seed_from(rng))
    torch_seed = seed_from(rng)

    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(a, dtype=torch.float32, device=dev)

    x_tr, y_tr = tensor((zv[train] - mx) / sx), tensor((ztv[train] - my) / sy)
    x_te, y_te = tensor((zv[test] - mx) / sx), tensor((ztv[test] - my) / sy)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(torch_seed)
        net = torch.nn.Sequential(
            torch.nn.Linear(zv.shape[1] + ztv.shape[1], hidden), torch.nn.ReLU(),
            torch.nn.Linear(hidden, hidden), torch.nn.ReLU(), torch.nn.Linear(hidden, 1),
        ).to(dev)
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
    n_tr, n_te = x_tr.shape[0], x_te.shape[0]
    marg_perm = [torch.randperm(n_te, generator=gen).to(dev) for _ in range(n_marginal)]

    def held_out_terms() -> tuple[np.ndarray, np.ndarray]:
        """Per-sample T on joint pairs, and per-sample mean e^T over the marginal shuffles."""
        with torch.no_grad():
            t_joint = net(torch.cat([x_te, y_te], 1)).squeeze(1)
            t_marg = torch.stack([net(torch.cat([x_te, y_te[p]], 1)).squeeze(1)
                                  for p in marg_perm])
            # log-mean-exp per sample, in a numerically safe form
            lme = torch.logsumexp(t_marg, 0) - math.log(n_marginal)
        return t_joint.double().cpu().numpy(), lme.double().cpu().numpy()

    def dv(t_joint: np.ndarray, lme: np.ndarray) -> float:
        m = lme.max()
        return float(t_joint.mean() - (m + np.log(np.mean(np.exp(lme - m)))))

    from tqdm.auto import tqdm

    ema, train_bound = 0.0, float("nan")
    curve: list[tuple[int, float]] = []
    for step in tqdm(range(1, int(steps) + 1), disable=not progress, desc="mine"):
        idx = torch.randint(n_tr, (batch_size,), generator=gen).to(dev)
        idx_m = torch.randint(n_tr, (batch_size,), generator=gen).to(dev)
        xb = x_tr[idx]
        out = net(torch.cat([torch.cat([xb, xb]), torch.cat([y_tr[idx], y_tr[idx_m]])], 1))
        t, t_m = out.squeeze(1).split(batch_size)
        et = torch.exp(t_m).mean()
        ema = (1 - ema_decay) * ema + ema_decay * float(et.detach())
        ema_hat = ema / (1 - (1 - ema_decay) ** step)
        loss = -(t.mean() - et / ema_hat)  # gradient of the bias-corrected MINE objective
        if not torch.isfinite(loss):
            from repbench.errors import TrainingDivergedError

            raise TrainingDivergedError(f"mine: loss became {float(loss)} at step {step}; "
                                        "lower learning_rate")
        opt.zero_grad()
        loss.backward()
        opt.step()
        bound = float(t.mean().detach() - torch.log(et.detach()))
        train_bound = bound if step == 1 else 0.999 * train_bound + 0.001 * bound
        if step % eval_every == 0 or step == steps:
            curve.append((step, dv(*held_out_terms())))
    last = [v for _, v in curve[-int(average_last):]]
    value = float(np.mean(last))
    t_joint, lme = held_out_terms()
    lo, hi, reps = episode_bootstrap_replicates(lambda rows: dv(t_joint[rows], lme[rows]),
                                                episode[test], rng, n_bootstrap)
    shift = value - dv(t_joint, lme)  # interval for the averaged value, same width
    reps = [r + shift for r in reps]
    if lo is not None and hi is not None:
        lo, hi = lo + shift, hi + shift
    extras = {**notes, "steps": int(steps), "eval_every": int(eval_every),
              "average_last": len(last), "held_out_curve": curve,
              "train_bound_ema": train_bound, "n_train": int(n_tr), "n_test": int(n_te),
              "split": "whole episodes held out", "bootstrap_replicates": reps}
    return MetricResult(value, True, lo, hi, extras=extras)
