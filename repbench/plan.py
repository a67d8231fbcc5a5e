"""Turn a suite into the DAG of stages that answer it.

Per task::

    random dataset ─┬─▶ privileged SAC (oracle_task) ─▶ on-policy dataset ─┐
                    ├─▶ encoder e (for every e) ──────────────────────┼─▶ latents e ─▶ metric m
                    │                     └─▶ RL (agent a, seed s) ───┘
                    └─▶ true-state diagnostics (random + on-policy)

Keys depend only on configs and input keys, so the whole plan (and therefore where every result
lives in the store) is known before anything runs; ``repbench leaderboard`` uses that to collect
results without recomputing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from repbench.dataset import IMAGE
from repbench.errors import ConfigError
from repbench.registry import agents, encoders, metrics, tasks
from repbench.stages import (
    DATASET,
    DIAGNOSTICS,
    ENCODER,
    FULL_STATE,
    LATENTS,
    METRIC,
    RL,
    StageSpec,
    accepted_kwargs,
    check_kwargs,
    code_version,
    jsonable_config,
)
from repbench.suite import Suite

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


@dataclass
class Plan:
    suite: Suite
    tasks: list[TaskPlan]

    def stages(self) -> list[StageSpec]:
        """All stages in a dependency-respecting order, without duplicates."""
        out: dict[str, StageSpec] = {}
        for tp in self.tasks:
            seq: list[StageSpec | None] = [tp.random_dataset, tp.full_state, tp.on_policy_dataset,
                                           tp.diagnostics, *tp.encoders.values(),
                                           *tp.latents.values(), *tp.metrics.values(),
                                           *tp.rl.values()]
            for s in seq:
                if s is not None:
                    out.setdefault(f"{s.kind}/{s.key}", s)
        return list(out.values())


def _ref(spec: StageSpec) -> tuple[str, str]:
    return (spec.kind, spec.key)


def build_plan(suite: Suite) -> Plan:
    """Resolve every plugin and parameter of ``suite`` into stage specs (raises ConfigError on
    unknown plugins or parameters before anything runs)."""
    suite.check_plugins()
    plans = [_plan_task(suite, t) for t in suite.tasks]
    return Plan(suite, plans)


def _plan_privileged(suite: Suite, task_name: str, task_cls: type, task_cfg: dict[str, Any],
                     random_ds: StageSpec) -> StageSpec:
    """The privileged agent's stage (it collects the on-policy dataset)."""
    from repbench.rl.full_state import PRIVILEGED_AGENT_PARAMS
    from repbench.task import Task

    rl = suite.rl
    enc_cls = encoders.get(rl.privileged_encoder)
    if rl.privileged_encoder == "oracle_task" and (
            getattr(task_cls, "task_state", Task.task_state) is Task.task_state):
        raise ConfigError(
            f"suite {suite.source or suite.name}: task {task_name} defines no task_state, "
            f"which the privileged agent ({rl.privileged_encoder}) observes; implement "
            "Task.task_state or set rl.privileged_encoder = 'oracle'")
    sac_cls = agents.get(FULL_STATE_AGENT)
    # the suite's SAC settings (budget-related ones like learning_starts), then what the
    # privileged agent learns the task with, then the suite's explicit privileged settings
    params = {**suite.agent_params.get(FULL_STATE_AGENT, {}), **PRIVILEGED_AGENT_PARAMS,
              **rl.privileged_params}
    check_kwargs("rl.privileged_params", sac_cls, params)
    _check_budget(sac_cls, "rl.privileged_params", params, rl.full_state_train_steps)
    return StageSpec(FULL_STATE, jsonable_config({
        **task_cfg, "train_steps": rl.full_state_train_steps, "seed": suite.dataset.seed,
        "eval_episodes": rl.eval_episodes, "curve_points": rl.curve_points,
        "encoder": rl.privileged_encoder, "agent_params": params,
        "code": code_version(sac_cls), "encoder_code": code_version(enc_cls)}),
        inputs={"dataset": _ref(random_ds)}, label=f"{task_name} privileged SAC")


def _check_budget(agent_cls: type, owner: str, params: dict[str, Any], train_steps: int) -> None:
    """An RL budget the agent cannot learn in (e.g. below ``learning_starts``) fails now."""
    validate = getattr(agent_cls, "validate", None)
    if not callable(validate):
        return
    try:
        agent_cls(**params).validate(train_steps)
    except ConfigError as exc:
        raise ConfigError(f"{owner}: {exc}") from None


def _check_modalities(suite: Suite, task_name: str, task_params: dict[str, Any]) -> None:
    """An encoder that reads the image cannot run on a camera-less task."""
    if task_params.get("camera", True):
        return
    for enc_name in suite.encoders:
        if IMAGE in getattr(encoders.get(enc_name), "required_modalities", ()):
            raise ConfigError(
                f"suite {suite.source or suite.name}: encoder {enc_name!r} reads the wrist "
                f"image but task_params.{task_name} sets camera = false; drop the encoder or "
                "turn the camera on")


def _plan_task(suite: Suite, task_name: str) -> TaskPlan:
    task_cls = tasks.get(task_name)
    task_params = suite.task_params.get(task_name, {})
    check_kwargs(f"task_params.{task_name}", task_cls, task_params)
    task_cfg = {"task": task_name, "task_params": task_params, "code": code_version(task_cls)}
    ds = suite.dataset

    random_ds = StageSpec(DATASET, jsonable_config({
        **task_cfg, "kind": "random", "n_episodes": ds.random_episodes,
        "steps_per_episode": ds.random_steps, "seed": ds.seed}), label=f"{task_name} random data")
    dataset_inputs = {"random": _ref(random_ds)}

    full_state = on_policy = None
    if ds.on_policy_episodes > 0:
        full_state = _plan_privileged(suite, task_name, task_cls, task_cfg, random_ds)
        on_policy = StageSpec(DATASET, jsonable_config({
            **task_cfg, "kind": "on_policy", "n_episodes": ds.on_policy_episodes,
            "steps_per_episode": ds.on_policy_steps, "seed": ds.seed + 1}),
            inputs={"policy": _ref(full_state)}, label=f"{task_name} on-policy data")
        dataset_inputs["on_policy"] = _ref(on_policy)

    _check_modalities(suite, task_name, task_params)
    tp = TaskPlan(task_name, random_ds, on_policy, full_state,
                  StageSpec(DIAGNOSTICS, {"task": task_name}, inputs=dataset_inputs,
                            label=f"{task_name} true-state diagnostics"))

    training = suite.encoder_training.model_dump()
    for enc_name in suite.encoders:
        cls = encoders.get(enc_name)
        explicit = suite.encoder_params.get(enc_name, {})
        check_kwargs(f"encoder_params.{enc_name}", cls, explicit)
        params = {**accepted_kwargs(cls, training), **explicit}
        if "progress" in accepted_kwargs(cls, {"progress": True}):
            params["progress"] = False
        enc = StageSpec(ENCODER, jsonable_config({
            "encoder": enc_name, "params": params, "code": code_version(cls)}),
            inputs={"dataset": _ref(random_ds)}, label=f"{task_name} encoder {enc_name}")
        tp.encoders[enc_name] = enc
        lat = StageSpec(LATENTS, {"encoder": enc_name}, inputs={"encoder": _ref(enc),
                                                               **dataset_inputs},
                        label=f"{task_name} latents {enc_name}")
        tp.latents[enc_name] = lat
        for m in suite.metrics:
            fn = metrics.get(m)
            mparams = {"n_bootstrap": suite.metric_settings.bootstrap,
                       **suite.metric_params.get(m, {})}
            check_kwargs(f"metric_params.{m}", fn.fn if hasattr(fn, "fn") else fn, mparams)
            tp.metrics[(enc_name, m)] = StageSpec(METRIC, jsonable_config({
                "metric": m, "params": mparams, "seed": suite.metric_settings.seed,
                "code": code_version(fn)}), inputs={"latents": _ref(lat)},
                label=f"{task_name} {m} × {enc_name}")
        for a in suite.agents:
            agent_cls = agents.get(a)
            aparams: dict[str, Any] = dict(suite.agent_params.get(a, {}))
            check_kwargs(f"agent_params.{a}", agent_cls, aparams)
            _check_budget(agent_cls, a, aparams, suite.rl.train_steps)
            for seed in suite.seeds:
                tp.rl[(enc_name, a, seed)] = StageSpec(RL, jsonable_config({
                    **task_cfg, "agent": a, "agent_params": aparams,
                    "train_steps": suite.rl.train_steps, "eval_episodes": suite.rl.eval_episodes,
                    "curve_points": suite.rl.curve_points, "seed": seed,
                    "agent_code": code_version(agent_cls)}),
                    inputs={"encoder": _ref(enc)}, label=f"{task_name} {a} × {enc_name} s{seed}")
    return tp
