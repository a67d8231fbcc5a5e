"""Metric plugins for the fault tests, installed for subprocesses through the
``repbench.metrics`` entry-point group (the path a third-party package takes), so that
spawned pool workers find them too.

Each computation appends one JSON line to ``$FAULTS_LOG`` (``start`` and ``end`` with the
metric, the process id and the thread settings), so a test can tell when a stage runs, in
which process, and how many times it was computed.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any

import numpy as np

from repbench.metric import MetricResult, metric


def _note(event: str, name: str, **extra: Any) -> None:
    path = os.environ.get("FAULTS_LOG")
    if not path:
        return
    with open(path, "a") as f:
        f.write(json.dumps({"event": event, "metric": name, "pid": os.getpid(), **extra}) + "\n")
        f.flush()


@metric("fault_mlp", higher_is_better=True, register=False, min_samples=2,
        description="Epochs a scikit-learn MLP trains for (all of them unless interrupted)")
def fault_mlp(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
              *, epochs: int = 4000, n_bootstrap: int = 0) -> MetricResult:
    """Fit an MLP for exactly ``epochs`` epochs; the value is the number of epochs it ran.

    scikit-learn's stochastic solvers catch KeyboardInterrupt and return the half-trained
    model, so an interrupted fit gives a value below ``epochs``. ``n_bootstrap`` (every
    suite passes it) is not used.
    """
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor

    _note("start", "fault_mlp")
    model = MLPRegressor(hidden_layer_sizes=(16,), max_iter=int(epochs), tol=0.0,
                         n_iter_no_change=int(epochs) + 1, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        model.fit(z, z_true)
    _note("end", "fault_mlp", n_iter=int(model.n_iter_))
    return MetricResult(value=float(model.n_iter_), higher_is_better=True)


@metric("fault_threads", higher_is_better=True, register=False, min_samples=2,
        description="The torch and BLAS/OpenMP thread counts a metric stage runs with")
def fault_threads(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                  rng: np.random.Generator, *, n_bootstrap: int = 0) -> MetricResult:
    """Value: torch intra-op threads; extras: the threadpoolctl pools and their threads."""
    import torch
    from threadpoolctl import threadpool_info

    pools = sorted({(p["user_api"], int(p["num_threads"])) for p in threadpool_info()})
    _note("start", "fault_threads")
    _note("end", "fault_threads")
    return MetricResult(value=float(torch.get_num_threads()), higher_is_better=True,
                        extras={"pools": [list(p) for p in pools]})
