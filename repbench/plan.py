"""Turn a suite into the DAG of stages that answer it.

Per task::

    random dataset ─┬─▶ full-state SAC (oracle) ─▶ on-policy dataset ─┐
                    ├─▶ encoder e (for every e) ──────────────────────┼─▶ latents e ─▶ metric m
                    │                     └─▶ RL (agent a, seed s)    │
                    └─▶ true-state diagnostics (random + on-policy)   │
    held-out dataset (own seed, off-grid holes) ──────────────────────┘

The latents (and so every metric) come from the held-out and on-policy datasets, which no encoder
trains on; without a held-out dataset (``dataset.heldout_episodes = 0``) they come from the
random (training) and on-policy datasets, as before.

Keys depend only on configs and input keys, so the whole plan (and therefore where every result
lives in the store) is known before anything runs; ``repbench leaderboard`` uses that to collect
results without recomputing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

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
    task_cfg = {"task": task_name, "task_params": task_params, "code": code_version(task_cls)}
    ds = suite.dataset

    random_ds = StageSpec(DATASET, jsonable_config({
        **task_cfg, "kind": "random", "n_episodes": ds.random_episodes,
        "steps_per_episode": ds.random_steps, "seed": ds.seed}), label=f"{task_name} random data")
    dataset_inputs = {"random": _ref(random_ds)}

    full_state = on_policy = None
    if ds.on_policy_episodes > 0:
        sac_cls = agents.get(FULL_STATE_AGENT)
        sac_params = suite.agent_params.get(FULL_STATE_AGENT, {})
        full_state = StageSpec(FULL_STATE, jsonable_config({
            **task_cfg, "train_steps": suite.rl.full_state_train_steps, "seed": ds.seed,
            "eval_episodes": suite.rl.eval_episodes, "agent_params": sac_params,
            "code": code_version(sac_cls)}), inputs={"dataset": _ref(random_ds)},
            label=f"{task_name} full-state SAC")
        on_policy = StageSpec(DATASET, jsonable_config({
            **task_cfg, "kind": "on_policy", "n_episodes": ds.on_policy_episodes,
            "steps_per_episode": ds.on_policy_steps, "seed": ds.seed + 1}),
            inputs={"policy": _ref(full_state)}, label=f"{task_name} on-policy data")
        dataset_inputs["on_policy"] = _ref(on_policy)

    tp = TaskPlan(task_name, random_ds, on_policy, full_state,
                  StageSpec(DIAGNOSTICS, {"task": task_name}, inputs=dataset_inputs,
                            label=f"{task_name} true-state diagnostics"))
    metric_inputs = dict(dataset_inputs)
    if ds.heldout_episodes > 0:
        heldout_params = {**task_params, **suite.heldout_task_params.get(task_name, {})}
        check_kwargs(f"heldout_task_params.{task_name}", task_cls, heldout_params)
        tp.heldout_dataset = StageSpec(DATASET, jsonable_config({
            **task_cfg, "task_params": heldout_params, "kind": "random",
            "n_episodes": ds.heldout_episodes,
            "steps_per_episode": ds.heldout_steps or ds.random_steps, "seed": ds.heldout_seed}),
            label=f"{task_name} held-out data")
        metric_inputs = {"heldout": _ref(tp.heldout_dataset)}
        if on_policy is not None:
            metric_inputs["on_policy"] = _ref(on_policy)

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
        lat = StageSpec(LATENTS, jsonable_config({"encoder": enc_name, "task": task_cfg}),
                        inputs={"encoder": _ref(enc), **metric_inputs},
                        label=f"{task_name} latents {enc_name}")
        tp.latents[enc_name] = lat
        for m in suite.metrics:
            fn = metrics.get(m)
            mparams = {"n_bootstrap": suite.metric_settings.bootstrap,
                       **suite.metric_params.get(m, {})}
            check_kwargs(f"metric_params.{m}", fn.fn if hasattr(fn, "fn") else fn, mparams)
            tp.metrics[(enc_name, m)] = StageSpec(METRIC, jsonable_config({
                "metric": m, "params": mparams, "seed": suite.metric_settings.seed,
                "rows": getattr(fn, "rows", "all"), "code": code_version(fn)}),
                inputs={"latents": _ref(lat)},
                label=f"{task_name} {m} × {enc_name}")
        for a in suite.agents:
            agent_cls = agents.get(a)
            aparams: dict[str, Any] = dict(suite.agent_params.get(a, {}))
            check_kwargs(f"agent_params.{a}", agent_cls, aparams)
            for seed in suite.seeds:
                tp.rl[(enc_name, a, seed)] = StageSpec(RL, jsonable_config({
                    **task_cfg, "agent": a, "agent_params": aparams,
                    "train_steps": suite.rl.train_steps, "eval_episodes": suite.rl.eval_episodes,
                    "curve_points": suite.rl.curve_points, "seed": seed,
                    "agent_code": code_version(agent_cls)}),
                    inputs={"encoder": _ref(enc)}, label=f"{task_name} {a} × {enc_name} s{seed}")
    return tp
