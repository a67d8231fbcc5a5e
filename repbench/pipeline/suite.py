"""Suites: which tasks × encoders × metrics × agents × seeds, with sizes and budgets.

A suite is a TOML file. ``smoke``, ``quick`` and ``paper`` ship inside the package
(``repbench/suites/``); any other path is read as a user's suite file. Files are validated on
load; an error names the file and the field.

Every section and every size has a documented default (the ``quick`` suite's sizes), so a user's
suite file needs only what differs::

    tasks = ["PegInHole-v0"]
    encoders = ["oracle", "my_encoder"]
    metrics = ["ksg", "regression"]
    [dataset]
    random_episodes = 10      # everything else as in the defaults below

Defaults: ``agents = ["sac"]``, ``seeds = [0, 1, 2]``; ``[dataset]`` 25 × 300 random steps,
10 × 100 on-policy steps, seed 0; ``[encoder_training]`` latent_dim 16, 3 epochs, batch 64,
seed 0; ``[rl]`` 6000 train steps, 10 evaluation episodes, 5 curve points, 20 000 steps for the
full-state agent; ``[metric_settings]`` 100 bootstrap resamples (at least
:data:`MIN_BOOTSTRAP`), seed 0.

Values are checked strictly, as TOML writes them: ``train_steps = "60"`` (a string) is refused,
not converted; RL seeds are distinct and non-negative; step budgets are at most
:data:`MAX_TRAIN_STEPS`.
"""

from __future__ import annotations

import codecs
import re
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    NonNegativeInt,
    PositiveInt,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)

from repbench import _toml as toml
from repbench.errors import ConfigError

BUILTIN_SUITES = ("smoke", "quick", "paper")
#: Upper bound of an RL step budget (``rl.train_steps``, ``rl.full_state_train_steps``): 10⁹
#: steps is years of SAC on one machine; a larger value is a typo.
MAX_TRAIN_STEPS = 10**9
#: A suite's name is a folder name (its board goes to ``leaderboards/<name>``): letters, digits,
#: ``_``, ``-`` and ``.``, with no ``..`` (which would climb out of ``leaderboards/``) and not
#: ``.`` alone (which is ``leaderboards/`` itself).
SUITE_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
#: The fewest bootstrap resamples a metric's 95 % interval may come from (``[metric_settings]
#: bootstrap``, a metric's ``n_bootstrap``): the smoke suite's 20. The percentile interval of B
#: resamples leaves out its own value when at most one resample falls on one side of it: for a
#: symmetric spread a chance of at most 2 (B + 1) / 2^B, 2 % at B = 10, 4·10⁻⁵ at B = 20; B = 1
#: gives the interval [x, x] of its one resample.
MIN_BOOTSTRAP = 20


def check_bootstrap(n: int, key: str = "", allow_none: bool = False) -> int:
    """``n`` if it is enough bootstrap resamples (:data:`MIN_BOOTSTRAP`; with ``allow_none``
    also 0, no interval), else ValueError (naming ``key`` and ``n`` when given a key)."""
    if n >= MIN_BOOTSTRAP or (allow_none and n == 0):
        return n
    zero = " (or 0 for no interval)" if allow_none else ""
    raise ValueError(f"{f'{key} = {n}: ' if key else ''}too few bootstrap resamples for a 95 % "
                     "interval (it would often leave out its own value); use at least "
                     f"{MIN_BOOTSTRAP}{zero}, e.g. 100 as quick does")


def check_suite_name(name: str) -> str:
    """``name`` if it is a valid suite name (:data:`SUITE_NAME`), else ValueError saying why."""
    if not SUITE_NAME.match(name) or ".." in name or name.startswith("."):
        raise ValueError(f"suite name {name!r} must be a folder name: letters, digits, '_', '-' "
                         "and '.', not starting with '.' (a hidden folder) and without '..' (its "
                         "board goes to leaderboards/<name>); "
                         "rename it, e.g. name = \"my_suite\"")
    return name


class _Strict(BaseModel):
    # strict: a TOML file has real types; "60" for an int is a mistake, not something to coerce
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class DatasetConfig(_Strict):
    """Sizes of the encoder-training datasets."""

    random_episodes: PositiveInt = Field(default=25, description="backwards-exploration "
                                         "episodes (one per hole position in the paper: 25)")
    random_steps: PositiveInt = Field(default=300, description="steps per random episode "
                                                               "(paper: 300)")
    on_policy_episodes: int = Field(default=10, ge=0,
                                    description="episodes by the full-state agent")
    on_policy_steps: PositiveInt = Field(default=100, description="steps per on-policy episode")
    seed: int = Field(default=0, description="collection seed")
    heldout_episodes: int = Field(default=0, ge=0, description=(
        "episodes of a separate backwards-exploration dataset the metrics are computed on "
        "(with the on-policy data), never seen by the encoders; 0: metrics use the random "
        "(training) and on-policy data"))
    heldout_steps: PositiveInt | None = Field(default=None, description=(
        "steps per held-out episode (default: random_steps)"))
    heldout_seed: int = Field(default=1000, description="collection seed of the held-out data")


def _optional(annotation: Any, metadata: list[Any]) -> Any:
    """``annotation`` with its constraints (``metadata``: Gt(0) ...), or None."""
    return (Annotated[(annotation, *metadata)] if metadata else annotation) | None


def _override_model(config: type[BaseModel]) -> type[BaseModel]:
    """A model of any subset of ``config``'s fields (each optional, with its constraints): a
    per-task table that overrides the suite-wide one; an unknown field or a bad value fails at
    load, naming the field."""
    return create_model(
        f"{config.__name__}Override", __base__=_Strict,
        **{name: (_optional(f.annotation, f.metadata), None)
           for name, f in config.model_fields.items()})


def _overridden(config: Any, override: BaseModel | None) -> Any:
    """``config`` with the fields ``override`` sets, validated as a whole."""
    if override is None:
        return config
    return type(config).model_validate({**config.model_dump(),
                                        **override.model_dump(exclude_unset=True)})


#: ``[task_dataset.<task>]``: any fields of :class:`DatasetConfig`, overriding ``[dataset]``.
DatasetOverride = _override_model(DatasetConfig)

class EncoderTrainingConfig(_Strict):
    """Shared encoder-training settings (per-encoder overrides in ``encoder_params``)."""

    latent_dim: PositiveInt = Field(default=16, description="latent size D (paper: 16)")
    epochs: PositiveInt = Field(default=10, description="maximum training epochs over the random "
                                "dataset (early stopping may end training sooner)")
    patience: int = Field(default=3, ge=0, description="stop after this many epochs without a "
                                                       "held-out improvement (0: train all epochs)")
    validation_fraction: float = Field(default=0.2, ge=0.0, lt=1.0,
                                       description="share of whole episodes held out for the "
                                                   "held-out loss curve and early stopping")
    batch_size: PositiveInt = Field(default=64, description="minibatch size")
    seed: int = Field(default=0, description="encoder initialisation/training seed")

    @model_validator(mode="after")
    def _early_stopping_needs_heldout(self) -> EncoderTrainingConfig:
        if self.patience > 0 and self.validation_fraction == 0:
            raise ValueError("patience > 0 (early stopping) needs validation_fraction > 0")
        return self


class RLConfig(_Strict):
    """Downstream-RL budgets."""

    train_steps: PositiveInt = Field(default=10000, le=MAX_TRAIN_STEPS, description=(
        "environment steps per training run (paper: 150k; at most 10⁹)"))
    eval_episodes: PositiveInt = Field(default=30, description="fixed evaluation episodes "
                                                               "(paper: 20k steps)")
    curve_points: PositiveInt = Field(default=5, description="learning-curve evaluations")
    full_state_train_steps: PositiveInt = Field(default=20000, le=MAX_TRAIN_STEPS, description=(
        "steps for the privileged SAC agent that collects the on-policy dataset (at most 10⁹)"))
    privileged_encoder: str = Field(default="oracle_task", description="what the privileged "
                                    "agent observes beside the robot state")
    privileged_params: dict[str, Any] = Field(
        default_factory=dict, description="SAC parameters of the privileged agent, over "
        "repbench.rl.full_state.PRIVILEGED_AGENT_PARAMS")


#: ``[task_rl.<task>]``: any fields of :class:`RLConfig`, overriding ``[rl]`` (e.g. a longer
#: ``train_steps`` for a harder task).
RLOverride = _override_model(RLConfig)


class MetricsConfig(_Strict):
    """Which data the metrics are computed on."""

    bootstrap: PositiveInt = Field(default=100, description=(
        f"bootstrap resamples for CIs (at least {MIN_BOOTSTRAP})"))
    seed: int = Field(default=0, description="metric seed")

    @field_validator("bootstrap")
    @classmethod
    def _enough_resamples(cls, v: int) -> int:
        return check_bootstrap(v)


#: The suite tables keyed by task name (``[task_params.<task>]`` ...): each names only listed tasks.
PER_TASK_FIELDS = ("task_params", "heldout_task_params", "task_dataset", "task_rl")


class Suite(_Strict):
    """A validated suite file."""

    name: str
    description: str = ""
    tasks: list[str] = Field(min_length=1)
    encoders: list[str] = Field(min_length=1)
    metrics: list[str] = Field(min_length=1)
    agents: list[str] = Field(default=["sac"], min_length=1)
    seeds: list[NonNegativeInt] = Field(default=[0, 1, 2], min_length=1,
                                        description="RL seeds (distinct, >= 0)")
    dataset: DatasetConfig = DatasetConfig()
    encoder_training: EncoderTrainingConfig = EncoderTrainingConfig()
    rl: RLConfig = RLConfig()
    metric_settings: MetricsConfig = MetricsConfig()
    task_params: dict[str, dict[str, Any]] = Field(default_factory=dict)
    heldout_task_params: dict[str, dict[str, Any]] = Field(default_factory=dict, description=(
        "task parameters overriding task_params for the held-out dataset only (PegInHole-v0: "
        "hole_sampling = 'uniform' puts its holes off the training grid)"))
    task_dataset: dict[str, DatasetOverride] = Field(default_factory=dict, description=(
        "fields of [dataset] overridden for one task (e.g. on_policy_steps = its horizon)"))
    task_rl: dict[str, RLOverride] = Field(default_factory=dict, description=(
        "fields of [rl] overridden for one task (e.g. its train_steps)"))
    encoder_params: dict[str, dict[str, Any]] = Field(default_factory=dict)
    metric_params: dict[str, dict[str, Any]] = Field(default_factory=dict)
    agent_params: dict[str, dict[str, Any]] = Field(default_factory=dict)
    source: str = Field(default="", exclude=True, description="file the suite was read from")

    def dataset_for(self, task: str) -> DatasetConfig:
        """``[dataset]`` with ``task_dataset.<task>``'s fields overriding it."""
        return _overridden(self.dataset, self.task_dataset.get(task))

    def rl_for(self, task: str) -> RLConfig:
        """``[rl]`` with ``task_rl.<task>``'s fields overriding it."""
        return _overridden(self.rl, self.task_rl.get(task))

    def only_tasks(self, tasks: Sequence[str]) -> Suite:
        """This suite on ``tasks`` (a subset of its own, in the order given), with the per-task
        tables of the other tasks left out, so that the copy is a valid suite of its own."""
        keep = list(tasks)
        return self.model_copy(update={"tasks": keep, **{
            name: {t: v for t, v in getattr(self, name).items() if t in keep}
            for name in PER_TASK_FIELDS}})

    @field_validator("name")
    @classmethod
    def _folder_name(cls, v: str) -> str:
        return check_suite_name(v)

    @field_validator("metric_params")
    @classmethod
    def _enough_metric_resamples(cls, v: dict[str, dict[str, Any]]
                                 ) -> dict[str, dict[str, Any]]:
        for name, params in v.items():
            n = params.get("n_bootstrap")
            if isinstance(n, int) and not isinstance(n, bool):
                check_bootstrap(n, f"metric_params.{name}.n_bootstrap", allow_none=True)
        return v

    @field_validator("tasks", "encoders", "metrics", "agents", "seeds")
    @classmethod
    def _unique(cls, v: list[Any]) -> list[Any]:
        dupes = sorted({x for x in v if v.count(x) > 1})
        if dupes:
            raise ValueError(f"listed more than once: {dupes}")
        return v

    def check_plugins(self) -> None:
        """Check every named plugin is registered (reads entry points; imports nothing heavy) and
        every plugin given by reference (``file.py:Class``, ``module:Class``) imports."""
        from repbench.references import is_reference
        from repbench.registry import REGISTRIES

        for field_name in ("tasks", "encoders", "metrics", "agents"):
            reg = REGISTRIES[field_name]
            for name in getattr(self, field_name):
                if is_reference(name):
                    reg.get(name)  # a bad reference fails here, in one line naming it
                elif name not in reg:
                    raise ConfigError(f"suite {self.source or self.name}, field "
                                      f"{field_name!r}: {reg._unknown_message(name)}")
        for field_name, kind in (*((name, "tasks") for name in PER_TASK_FIELDS),
                                 ("encoder_params", "encoders"),
                                 ("metric_params", "metrics"), ("agent_params", "agents")):
            listed = set(getattr(self, kind))
            for name in getattr(self, field_name):
                if name not in listed:
                    raise ConfigError(
                        f"suite {self.source or self.name}, field {field_name!r}: {name!r} is "
                        f"not in {kind} {sorted(listed)}; remove it or add it there"
                    )


def load_suite(name_or_path: str | Path) -> Suite:
    """Load a built-in suite by name (``smoke``) or a suite file by path."""
    text, source = _read_suite_text(name_or_path)
    try:
        data = toml.loads(text)
    except toml.TOMLDecodeError as exc:
        raise ConfigError(f"suite file {source}: not valid TOML ({exc})") from None
    data.setdefault("name", Path(source).stem)
    try:
        suite = Suite.model_validate({**data, "source": source})
    except ValidationError as exc:
        raise ConfigError(f"suite file {source}: {_first_error(exc)}") from None
    return suite


def _read_suite_text(name_or_path: str | Path) -> tuple[str, str]:
    name = str(name_or_path)
    if name in BUILTIN_SUITES:
        ref = resources.files("repbench.suites") / f"{name}.toml"
        return ref.read_text(), f"<built-in suite {name}>"
    path = Path(name).expanduser()
    if not path.is_file():
        raise ConfigError(
            f"suite {name!r} is neither a built-in suite ({', '.join(BUILTIN_SUITES)}) nor an "
            "existing file; check the name or path"
        )
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"suite file {path} cannot be read ({exc.strerror or exc}); check its "
                          "permissions") from None
    if raw.startswith(codecs.BOM_UTF8):  # Windows editors (Notepad) save UTF-8 with one
        raw = raw[len(codecs.BOM_UTF8):]
    try:
        return raw.decode("utf-8"), str(path)
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ConfigError(f"suite file {path} is not UTF-8 text (byte {raw[exc.start]:#04x} on "
                          f"line {line}); save it as UTF-8") from None


def _first_error(exc: ValidationError) -> str:
    errors = exc.errors()
    parts = []
    for err in errors[:3]:
        loc = ".".join(str(p) for p in err["loc"])
        msg = err["msg"]
        if err["type"] == "extra_forbidden":
            msg = "unknown key (misspelled?)"
        elif err["type"].endswith("_type") and isinstance(err.get("input"), str):
            msg += f", got the string {err['input']!r} (write numbers and booleans unquoted)"
        elif isinstance(err.get("input"), (bool, int, float)):
            msg += f", got {err['input']!r}"
        parts.append(f"field {loc!r}: {msg}")
    more = f" (and {len(errors) - 3} more)" if len(errors) > 3 else ""
    return "; ".join(parts) + more
