"""Turn a suite into the DAG of stages that answer it.

Per task::

    random dataset ─┬─▶ privileged SAC (oracle_task) ─▶ on-policy dataset ─┐
                    ├─▶ encoder e (for every e) ──────────────────────┼─▶ latents e ─▶ metric m
                    │                     └─▶ RL (agent a, seed s)    │
                    └─▶ true-state diagnostics (random + on-policy)   │
    held-out dataset (own seed, off-grid holes) ──────────────────────┘

The latents (and so every metric) come from the held-out and on-policy datasets, which no encoder
trains on; without a held-out dataset (``dataset.heldout_episodes = 0``) they come from the
random (training) and on-policy datasets, as before.

Keys depend only on configs and input keys, so the whole plan (and therefore where every result
lives in the store) is known before anything runs. A plugin enters a key through its name, its
parameters and its declared ``version`` (class attribute, default 0), never its source code: see
:mod:`repbench.pipeline.records` for the rule. Every stage also carries the context of its result
record (``StageSpec.record``); ``repbench leaderboard`` selects stored records by their identity.
"""

from __future__ import annotations

import inspect
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from repbench.dataset import IMAGE
from repbench.errors import ConfigError, RepbenchError
from repbench.pipeline.records import plugin_part, plugin_version
from repbench.pipeline.stages import (
    DATASET,
    DIAGNOSTICS,
    ENCODER,
    FULL_STATE,
    LATENTS,
    METRIC,
    RL,
    StageSpec,
)
from repbench.pipeline.suite import Suite
from repbench.references import source_digest
from repbench.registry import agents, encoders, metrics, tasks
from repbench.rl.full_state import PRIVILEGED_AGENT_PARAMS

FULL_STATE_AGENT = "sac"


@dataclass
class TaskPlan:
    """The stages of one task, indexed for the leaderboard."""

    task: str
    random_dataset: StageSpec
    on_policy_dataset: StageSpec | None
    full_state: StageSpec | None
    diagnostics: StageSpec
    encoders: dict[str, StageSpec] = field(default_factory=dict)
    latents: dict[str, StageSpec] = field(default_factory=dict)
    metrics: dict[tuple[str, str], StageSpec] = field(default_factory=dict)  # (enc, metric)
    rl: dict[tuple[str, str, int], StageSpec] = field(default_factory=dict)  # (enc, agent, seed)
    heldout_dataset: StageSpec | None = None


@dataclass
class Plan:
    suite: Suite
    tasks: list[TaskPlan]

    def stages(self) -> list[StageSpec]:
        """All stages in a dependency-respecting order, without duplicates."""
        out: dict[str, StageSpec] = {}
        for tp in self.tasks:
            seq: list[StageSpec | None] = [
                tp.random_dataset, tp.full_state, tp.on_policy_dataset, tp.heldout_dataset,
                tp.diagnostics, *tp.encoders.values(), *tp.latents.values(),
                *tp.metrics.values(), *tp.rl.values()]
            for s in seq:
                if s is not None:
                    out.setdefault(f"{s.kind}/{s.key}", s)
        return list(out.values())


# -- planning helpers ---------------------------------------------------------------------------

def accepted_kwargs(factory: Callable[..., Any], params: Mapping[str, Any]) -> dict[str, Any]:
    """The subset of ``params`` that ``factory``'s signature accepts."""
    sig = inspect.signature(factory)
    if any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values()):
        return dict(params)
    return {k: v for k, v in params.items() if k in sig.parameters}


def check_kwargs(owner: str, factory: Callable[..., Any], params: Mapping[str, Any]) -> None:
    """Raise ConfigError if ``params`` has keys ``factory`` does not accept."""
    unknown = set(params) - set(accepted_kwargs(factory, params))
    if unknown:
        valid = [p for p in inspect.signature(factory).parameters if p not in ("self",)]
        raise ConfigError(f"{owner}: unknown parameter(s) {sorted(unknown)}; valid: {valid}")


def jsonable_config(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """Round-trip through JSON so configs hash identically wherever they were built."""
    return json.loads(json.dumps(cfg, sort_keys=True))


def construct_checked(suite: Suite, field_name: str, factory: Callable[..., Any],
                      params: Mapping[str, Any], validate: Callable[[Any], None] | None = None
                      ) -> Any:
    """Build a plugin from its suite parameters now, so a bad value fails at plan time.

    Constructors store and check hyperparameters only (scikit-learn style), so this is cheap.
    A :class:`ConfigError` (or ``TypeError``/``ValueError``) from the constructor or from
    ``validate(obj)`` becomes one ConfigError naming the suite file and the field.
    """
    try:
        obj = factory(**params)
        if validate is not None:
            validate(obj)
    except (RepbenchError, TypeError, ValueError) as exc:
        raise ConfigError(f"suite {suite.source or suite.name}, field {field_name}: {exc}"
                          ) from None
    return obj


def _ref(spec: StageSpec) -> tuple[str, str]:
    return (spec.kind, spec.key)


def build_plan(suite: Suite) -> Plan:
    """Resolve every plugin and parameter of ``suite`` into stage specs (raises ConfigError on
    unknown plugins or parameters before anything runs)."""
    suite.check_plugins()
    plans = [_plan_task(suite, t) for t in suite.tasks]
    return Plan(suite, plans)


def _plan_task(suite: Suite, task_name: str) -> TaskPlan:
    task_cls = tasks.get(task_name)
    task_params = suite.task_params.get(task_name, {})
    check_kwargs(f"task_params.{task_name}", task_cls, task_params)
    construct_checked(suite, f"task_params.{task_name!r}", task_cls, task_params)
    task_cfg = {"task": task_name, "task_params": task_params,
                "task_version": plugin_version(task_cls)}
    task_part = plugin_part(task_name, task_cls, task_params)
    ds = suite.dataset_for(task_name)
    _check_on_policy_metrics(suite, task_name, ds.on_policy_episodes)
    rl = suite.rl_for(task_name)
    random_data = {"episodes": ds.random_episodes, "steps": ds.random_steps, "seed": ds.seed}
    data: dict[str, Any] = {"random": random_data, "on_policy": None, "full_state": None}

    random_ds = StageSpec(DATASET, jsonable_config({
        **task_cfg, "kind": "random", "n_episodes": ds.random_episodes,
        "steps_per_episode": ds.random_steps, "seed": ds.seed}), label=f"{task_name} random data",
        record=_context("dataset", task_part, data={"name": "random", **random_data}))
    dataset_inputs = {"random": _ref(random_ds)}
    data_stages = {"random": random_ds.key}

    full_state = on_policy = None
    if ds.on_policy_episodes > 0:
        sac_cls = agents.get(FULL_STATE_AGENT)
        _check_privileged(suite, task_name, task_cls, rl.privileged_encoder)
        priv_cls = encoders.get(rl.privileged_encoder)
        # the suite's SAC settings (budget-related ones like learning_starts), then what the
        # privileged agent learns the task with, then the suite's explicit privileged settings
        sac_params = {**suite.agent_params.get(FULL_STATE_AGENT, {}),
                      **PRIVILEGED_AGENT_PARAMS, **rl.privileged_params}
        field_name = f"rl.privileged_params (over agent_params.{FULL_STATE_AGENT})"
        check_kwargs(field_name, sac_cls, sac_params)
        construct_checked(suite, field_name, sac_cls, sac_params,
                          _agent_validator(rl.full_state_train_steps))
        sac_part = plugin_part(FULL_STATE_AGENT, sac_cls, sac_params)
        full_budget = {"train_steps": rl.full_state_train_steps,
                       "eval_episodes": rl.eval_episodes, "curve_points": rl.curve_points}
        full_state = StageSpec(FULL_STATE, jsonable_config({
            **task_cfg, **full_budget, "seed": ds.seed, "agent_params": sac_params,
            "encoder": rl.privileged_encoder, "encoder_version": plugin_version(priv_cls),
            "agent_version": plugin_version(sac_cls)}), inputs={"dataset": _ref(random_ds)},
            label=f"{task_name} privileged SAC",
            record=_context("full_state_agent", task_part, data={"random": random_data},
                            agent=sac_part, seed=ds.seed, budget=full_budget))
        data["full_state"] = {"agent": FULL_STATE_AGENT, "params": sac_part["params"],
                              "encoder": rl.privileged_encoder, **full_budget, "seed": ds.seed}
        data["on_policy"] = {"episodes": ds.on_policy_episodes, "steps": ds.on_policy_steps,
                             "seed": ds.seed + 1}
        on_policy = StageSpec(DATASET, jsonable_config({
            **task_cfg, "kind": "on_policy", "n_episodes": ds.on_policy_episodes,
            "steps_per_episode": ds.on_policy_steps, "seed": ds.seed + 1}),
            inputs={"policy": _ref(full_state)}, label=f"{task_name} on-policy data",
            record=_context("dataset", task_part, data={
                "name": "on_policy", **data["on_policy"], "full_state": data["full_state"],
                "random": random_data}))
        dataset_inputs["on_policy"] = _ref(on_policy)
        data_stages["on_policy"] = on_policy.key

    _check_modalities(suite, task_name, task_params)
    tp = TaskPlan(task_name, random_ds, on_policy, full_state,
                  StageSpec(DIAGNOSTICS, {"task": task_name}, inputs=dataset_inputs,
                            label=f"{task_name} true-state diagnostics",
                            record=_context("diagnostics", task_part, data=data,
                                            data_stages=data_stages)))
    # what the latents (and so the metrics) are computed on: held-out + on-policy when the suite
    # has a held-out dataset, else the random (training) + on-policy data
    metric_inputs, metric_data, metric_stages = dict(dataset_inputs), data, data_stages
    if ds.heldout_episodes > 0:
        heldout_params = {**task_params, **suite.heldout_task_params.get(task_name, {})}
        check_kwargs(f"heldout_task_params.{task_name}", task_cls, heldout_params)
        construct_checked(suite, f"heldout_task_params.{task_name!r}", task_cls, heldout_params)
        heldout_data = {"episodes": ds.heldout_episodes,
                        "steps": ds.heldout_steps or ds.random_steps, "seed": ds.heldout_seed,
                        "task_params": heldout_params}
        tp.heldout_dataset = StageSpec(DATASET, jsonable_config({
            **task_cfg, "task_params": heldout_params, "kind": "random",
            "n_episodes": ds.heldout_episodes,
            "steps_per_episode": ds.heldout_steps or ds.random_steps, "seed": ds.heldout_seed}),
            label=f"{task_name} held-out data",
            record=_context("dataset", task_part, data={"name": "heldout", **heldout_data}))
        metric_inputs = {"heldout": _ref(tp.heldout_dataset)}
        metric_data = {**data, "heldout": heldout_data}
        metric_stages = {"heldout": tp.heldout_dataset.key}
        if on_policy is not None:
            metric_inputs["on_policy"] = _ref(on_policy)
            metric_stages["on_policy"] = on_policy.key

    metric_params = {m: _metric_params(suite, m) for m in suite.metrics}
    training = suite.encoder_training.model_dump()
    for enc_name in suite.encoders:
        cls = encoders.get(enc_name)
        explicit = suite.encoder_params.get(enc_name, {})
        check_kwargs(f"encoder_params.{enc_name}", cls, explicit)
        params = {**accepted_kwargs(cls, training), **explicit}
        if "progress" in accepted_kwargs(cls, {"progress": True}):
            params["progress"] = False
        construct_checked(suite, f"encoder_params.{enc_name}", cls, params,
                          lambda e: e.check_params())
        enc_part = plugin_part(enc_name, cls, params)
        source = source_digest(cls)  # an encoder from a plain file: its content is in the key
        enc = StageSpec(ENCODER, jsonable_config({
            "encoder": enc_name, "params": params, "version": plugin_version(cls),
            **({"source_sha256": source} if source else {})}),
            inputs={"dataset": _ref(random_ds)}, label=f"{task_name} encoder {enc_name}",
            record=_context("encoder", task_part, data={"random": random_data},
                            encoder=enc_part, data_stages={"random": random_ds.key}))
        tp.encoders[enc_name] = enc
        lat = StageSpec(LATENTS, jsonable_config({"encoder": enc_name, "task": task_cfg}),
                        inputs={"encoder": _ref(enc), **metric_inputs},
                        label=f"{task_name} latents {enc_name}",
                        record=_context("latents", task_part, data=metric_data,
                                        encoder=enc_part, data_stages=metric_stages))
        tp.latents[enc_name] = lat
        for m in suite.metrics:
            fn, mparams = metrics.get(m), metric_params[m]
            tp.metrics[(enc_name, m)] = StageSpec(METRIC, jsonable_config({
                "metric": m, "params": mparams, "seed": suite.metric_settings.seed,
                "rows": getattr(fn, "rows", "all"), "version": plugin_version(fn)}),
                inputs={"latents": _ref(lat)}, label=f"{task_name} {m} × {enc_name}",
                cost_group=f"{task_name} {m}",
                record=_context("metric", task_part, data=metric_data, encoder=enc_part,
                                metric=plugin_part(m, fn, mparams),
                                seed=suite.metric_settings.seed, data_stages=metric_stages))
        renders = "image" if IMAGE in getattr(cls, "required_modalities", ()) else "no image"
        for a in suite.agents:
            agent_cls = agents.get(a)
            aparams: dict[str, Any] = dict(suite.agent_params.get(a, {}))
            check_kwargs(f"agent_params.{a}", agent_cls, aparams)
            construct_checked(suite, f"agent_params.{a}", agent_cls, aparams,
                              _agent_validator(rl.train_steps))
            agent_part = plugin_part(a, agent_cls, aparams)
            budget = {"train_steps": rl.train_steps, "eval_episodes": rl.eval_episodes,
                      "curve_points": rl.curve_points}
            for seed in suite.seeds:
                tp.rl[(enc_name, a, seed)] = StageSpec(RL, jsonable_config({
                    **task_cfg, "agent": a, "agent_params": aparams,
                    "train_steps": rl.train_steps, "eval_episodes": rl.eval_episodes,
                    "curve_points": rl.curve_points, "seed": seed,
                    "agent_version": plugin_version(agent_cls)}),
                    inputs={"encoder": _ref(enc)}, label=f"{task_name} {a} × {enc_name} s{seed}",
                    cost_group=f"{task_name} {a} {rl.train_steps} steps, {renders}",
                    record=_context("rl", task_part, data={"random": random_data},
                                    encoder=enc_part, agent=agent_part, seed=seed,
                                    budget=budget, data_stages={"random": random_ds.key}))
    return tp


def _metric_params(suite: Suite, name: str) -> dict[str, Any]:
    """The parameters metric ``name`` runs with, checked now (names, types, the metric's own
    range checks: :meth:`repbench.metric.Metric.check_params`), not when the metric runs."""
    fn = metrics.get(name)
    params = {"n_bootstrap": suite.metric_settings.bootstrap, **suite.metric_params.get(name, {})}
    if not callable(getattr(fn, "check_params", None)):  # not a Metric: check the names only
        check_kwargs(f"metric_params.{name}", fn, params)
        return params
    try:
        fn.check_params(params)
    except (RepbenchError, TypeError, ValueError) as exc:
        raise ConfigError(f"suite {suite.source or suite.name}, field metric_params.{name}: "
                          f"{exc}") from None
    return params


def _check_on_policy_metrics(suite: Suite, task_name: str, on_policy_episodes: int) -> None:
    """A metric declared ``rows="on_policy"`` (the expert-action probe, smoothness) is computed
    on the on-policy data only; a task without any cannot have it (the metric stage would
    refuse it too, :func:`repbench.latent_metrics.metric_rows`)."""
    if on_policy_episodes > 0:
        return
    needy = [m for m in suite.metrics if getattr(metrics.get(m), "rows", "all") == "on_policy"]
    if needy:
        override = suite.task_dataset.get(task_name)
        where = (f"task_dataset.{task_name}" if override is not None
                 and "on_policy_episodes" in override.model_fields_set else "dataset")
        raise ConfigError(
            f"suite {suite.source or suite.name}: {', '.join(map(repr, needy))} "
            f"{'is' if len(needy) == 1 else 'are'} computed on on-policy data, but "
            f"{where}.on_policy_episodes = 0 for {task_name}; collect some (e.g. 10) or drop "
            f"{'it' if len(needy) == 1 else 'them'} from metrics")


def _check_privileged(suite: Suite, task_name: str, task_cls: type,
                      privileged_encoder: str) -> None:
    """The privileged agent's ``oracle_task`` needs the task's task-frame state."""
    from repbench.task import Task

    if privileged_encoder == "oracle_task" and (
            getattr(task_cls, "task_state", Task.task_state) is Task.task_state):
        raise ConfigError(
            f"suite {suite.source or suite.name}: task {task_name} defines no task_state, "
            f"which the privileged agent ({privileged_encoder}) observes; implement "
            "Task.task_state or set rl.privileged_encoder = 'oracle'")


def _check_modalities(suite: Suite, task_name: str, task_params: Mapping[str, Any]) -> None:
    """An encoder that reads the image cannot run on a camera-less task."""
    if task_params.get("camera", True):
        return
    for enc_name in suite.encoders:
        if IMAGE in getattr(encoders.get(enc_name), "required_modalities", ()):
            raise ConfigError(
                f"suite {suite.source or suite.name}: encoder {enc_name!r} reads the wrist "
                f"image but task_params.{task_name} sets camera = false; drop the encoder or "
                "turn the camera on")


def _agent_validator(train_steps: int) -> Callable[[Any], None]:
    def validate(agent: Any) -> None:
        check = getattr(agent, "validate", None)
        if callable(check):
            check(train_steps)

    return validate


def _context(kind: str, task: dict[str, Any], **parts: Any) -> dict[str, Any]:
    """The record context of a stage (:mod:`repbench.pipeline.records`), JSON-clean."""
    return jsonable_config({"kind": kind, "task": task, **parts})
