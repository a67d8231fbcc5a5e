"""The metric types: :class:`MetricResult` and :class:`Metric` (the registry's base for metrics).

Kept below :mod:`repbench.registry`; the ``@repbench.metric`` decorator that creates and
registers a :class:`Metric` is in :mod:`repbench.metric`. Write metrics as described there.

The metric API: pure functions of arrays returning a :class:`MetricResult`.

A metric is a function ``fn(z, z_true, episode, rng, **params) -> MetricResult`` where

* ``z`` — float ``[N, D]`` latents (μ_z), rows ordered by (episode, step);
* ``z_true`` — float ``[N, S]`` true state z°;
* ``episode`` — int ``[N]`` episode ids (consecutive rows of one episode are consecutive steps);
* ``rng`` — a ``numpy.random.Generator``; a fixed seed gives a reproducible value.

Register it with the decorator, which also validates inputs before the function runs::

    @repbench.metric("my_metric", higher_is_better=True, description="...")
    def my_metric(z, z_true, episode, rng, *, k=5) -> MetricResult: ...
"""

from __future__ import annotations

import functools
import inspect
import math
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from repbench.errors import ConfigError, DataError

#: Arrays beside (z, z_true, episode) that a metric can ask for by naming a keyword parameter
#: (see :mod:`repbench.metric`).
EXTRA_INPUTS = ("robot_state", "task_state", "action", "source", "reward")
#: Which rows of the stored latents a metric is computed on (see :mod:`repbench.metric`).
ROWS = ("all", "on_policy")
#: What a metric reads: ``observable`` — only what a real robot logs (z from its
#: observations, robot state, action, reward, episodes); ``privileged`` — the simulator's
#: state too (z°, the task state). See :mod:`repbench.metric`.
GROUPS = ("observable", "privileged")
#: The positional arguments every metric function takes; not parameters a suite can set.
ARRAY_ARGUMENTS = ("z", "z_true", "episode", "rng")


@dataclass(frozen=True)
class MetricResult:
    """One metric's value with its direction, uncertainty and details.

    Attributes:
        value: the scalar score.
        higher_is_better: direction, used by correlation and leaderboards.
        ci_low, ci_high: confidence interval (bootstrap or repeated seeds), when available.
        extras: JSON-serializable details: per-dimension values, curves, histograms.
    """

    value: float
    higher_is_better: bool
    ci_low: float | None = None
    ci_high: float | None = None
    extras: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "higher_is_better": self.higher_is_better,
                "ci_low": self.ci_low, "ci_high": self.ci_high, "extras": _jsonable(self.extras)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MetricResult:
        return cls(value=float(d["value"]), higher_is_better=bool(d["higher_is_better"]),
                   ci_low=d.get("ci_low"), ci_high=d.get("ci_high"),
                   extras=dict(d.get("extras") or {}))


class Metric:
    """A registered metric function with its direction, description and input checks."""

    def __init__(self, fn: Callable[..., MetricResult], name: str, higher_is_better: bool,
                 description: str = "", min_samples: int = 10, needs_episodes: bool = False,
                 version: int = 0, rows: str = "all",
                 check: Callable[..., None] | None = None, group: str = "privileged") -> None:
        if rows not in ROWS:
            raise ValueError(f"metric {name!r}: rows must be one of {ROWS}, got {rows!r}")
        if group not in GROUPS:
            raise ValueError(f"metric {name!r}: group must be one of {GROUPS}, got {group!r}")
        #: ``observable`` or ``privileged`` (:data:`GROUPS`)
        self.group = group
        self.fn = fn
        #: the metric's own range checks: called with every tunable parameter (defaults filled
        #: in) as keywords; raises ConfigError (:meth:`check_params`)
        self.check = check
        #: which rows of the stored latents the metric stage computes it on
        self.rows = rows
        #: declared version of what the metric computes (see :class:`repbench.Encoder.version`)
        self.version = int(version)
        self.name = name
        self.higher_is_better = higher_is_better
        self.description = description or (fn.__doc__ or "").strip().split("\n")[0]
        self.min_samples = min_samples
        self.needs_episodes = needs_episodes
        functools.update_wrapper(self, fn)
        self.__doc__ = fn.__doc__ or self.description

    def __call__(self, z: np.ndarray, z_true: np.ndarray, episode: np.ndarray | None = None,
                 rng: np.random.Generator | int | None = None, **params: Any) -> MetricResult:
        z, z_true, episode = check_metric_inputs(
            z, z_true, episode, name=self.name, min_samples=self.min_samples,
        )
        for key in self.extra_inputs:
            if key in params and params[key] is not None:
                params[key] = check_extra_input(params[key], key, len(z), name=self.name)
        if not isinstance(rng, np.random.Generator):
            rng = np.random.default_rng(0 if rng is None else rng)
        result = self.fn(z, z_true, episode, rng, **params)
        if not isinstance(result, MetricResult):
            raise TypeError(f"metric {self.name!r} returned {type(result)}, not MetricResult")
        if result.higher_is_better != self.higher_is_better:
            raise TypeError(f"metric {self.name!r} returned a result with the wrong direction")
        return result

    @property
    def label_free(self) -> bool:
        """Whether the metric reads nothing but z (observable, and no extra array but
        ``source``): a spectral score like RankMe. No ordering against the true state is
        expected of it (:func:`repbench.testing.check_metric`)."""
        return self.group == "observable" and not set(self.extra_inputs) - {"source"}

    @property
    def extra_inputs(self) -> tuple[str, ...]:
        """The names in :data:`EXTRA_INPUTS` that the function's signature accepts."""
        sig = inspect.signature(self.fn).parameters
        return tuple(k for k in EXTRA_INPUTS if k in sig)

    @property
    def parameters(self) -> dict[str, inspect.Parameter]:
        """The tunable parameters: the function's keyword parameters other than the arrays
        (:data:`ARRAY_ARGUMENTS`, :data:`EXTRA_INPUTS`), in signature order."""
        skip = {*ARRAY_ARGUMENTS, *EXTRA_INPUTS}
        return {n: p for n, p in inspect.signature(self.fn).parameters.items()
                if n not in skip and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}

    def check_params(self, params: Mapping[str, Any]) -> None:
        """Raise a one-line :class:`ConfigError` for parameters the metric would refuse.

        Without running the metric (the planner calls it, so a bad value fails before any
        stage): unknown names (the message lists the tunable parameters only), values whose
        type does not match the annotation (or, without one, the default's type), and whatever
        the metric's own ``check`` refuses.
        """
        known = self.parameters
        var_kw = any(p.kind == p.VAR_KEYWORD
                     for p in inspect.signature(self.fn).parameters.values())
        unknown = sorted(set(params) - set(known))
        if unknown and not var_kw:
            raise ConfigError(f"metric {self.name!r}: unknown parameter(s) {unknown}; valid: "
                              f"{list(known)}")
        try:
            hints = typing.get_type_hints(self.fn)
        except Exception:  # an annotation that does not resolve: fall back to the defaults
            hints = {}
        for key, value in params.items():
            if key not in known:
                continue
            hint = hints.get(key, _default_type(known[key].default))
            if not _fits(value, hint):
                raise ConfigError(f"metric {self.name!r}: parameter {key!r} must be "
                                  f"{_type_name(hint)}, got {value!r}")
        if self.check is not None:
            defaults = {k: p.default for k, p in known.items() if p.default is not p.empty}
            self.check(**{**defaults, **params})

    def __repr__(self) -> str:
        return f"<Metric {self.name} ({'higher' if self.higher_is_better else 'lower'} is better)>"


def _default_type(default: Any) -> Any:
    """The type a parameter without an annotation is checked against: its default's."""
    if default is inspect.Parameter.empty or default is None:
        return Any
    return type(default)


def _fits(value: Any, hint: Any) -> bool:
    """Whether ``value`` (as read from TOML) fits the type ``hint``; unknown hints fit."""
    if hint is Any:
        return True
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, a) for a in args)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, (bool, np.bool_))
    if isinstance(value, (bool, np.bool_)):
        return False  # True is an int to Python, not a number to a user
    if hint is int:
        return isinstance(value, (int, np.integer))
    if hint is float:
        return isinstance(value, (int, float, np.number)) and math.isfinite(float(value))
    if hint is str:
        return isinstance(value, str)
    if origin in (tuple, list, Sequence):
        if not isinstance(value, (list, tuple)):
            return False
        if origin is tuple and args and args[-1] is not Ellipsis:
            return len(value) == len(args) and all(
                _fits(v, a) for v, a in zip(value, args, strict=True))
        return all(_fits(v, args[0]) for v in value) if args else True
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True


def _type_name(hint: Any) -> str:
    names = {int: "a whole number", float: "a finite number", bool: "true or false",
             str: "a string", type(None): "none"}
    if hint in names:
        return names[hint]
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(hint))
    if typing.get_origin(hint) in (tuple, list, Sequence):
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        if len(set(args)) <= 1:
            inner = _type_name(args[0]).removeprefix("a ") if args else "value"
            return f"a list of {inner}s"
        return f"a list of {len(args)} values"
    return getattr(hint, "__name__", str(hint))


def check_metric_inputs(z: Any, z_true: Any, episode: Any = None, *, name: str = "metric",
                        min_samples: int = 10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate and convert metric inputs; raise DataError with a one-line message."""
    z = np.asarray(z, dtype=np.float64)
    z_true = np.asarray(z_true, dtype=np.float64)
    for label, arr in (("z", z), ("z_true", z_true)):
        if arr.ndim != 2:
            raise DataError(f"{name}: {label} must be 2-D [samples, dims], got shape {arr.shape}")
        if not np.isfinite(arr).all():
            bad = int((~np.isfinite(arr)).any(axis=1).sum())
            raise DataError(f"{name}: {label} has NaN/inf in {bad} rows; drop or fix them first")
    if z.shape[0] != z_true.shape[0]:
        raise DataError(
            f"{name}: z has {z.shape[0]} rows but z_true has {z_true.shape[0]}; they must align"
        )
    if z.shape[0] < min_samples:
        raise DataError(f"{name}: needs at least {min_samples} samples, got {z.shape[0]}")
    if episode is None:
        episode = np.zeros(z.shape[0], dtype=np.int64)
    episode = np.asarray(episode)
    if episode.shape != (z.shape[0],):
        raise DataError(f"{name}: episode must have shape ({z.shape[0]},), got {episode.shape}")
    return z, z_true, episode


def check_extra_input(value: Any, key: str, n: int, *, name: str = "metric") -> np.ndarray:
    """Validate one extra array (:data:`EXTRA_INPUTS`): aligned with z, finite, right rank."""
    arr = np.asarray(value)
    if key == "source":
        if arr.shape != (n,):
            raise DataError(f"{name}: source must have shape ({n},), got {arr.shape}")
        return arr
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] != n:
        raise DataError(f"{name}: {key} must be [{n}, dims] aligned with z, got shape "
                        f"{arr.shape}")
    if not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).any(axis=1).sum())
        raise DataError(f"{name}: {key} has NaN/inf in {bad} rows; drop or fix them first")
    return arr


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value
