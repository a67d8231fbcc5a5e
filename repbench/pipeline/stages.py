"""The stages of a suite, each a pure function of its config and its inputs' artifacts.

A :class:`StageSpec` names a stage kind, its JSON config and the keys of the artifacts it reads.
:func:`execute` runs one spec inside any worker (a local process, a Ray task) and writes its
artifact to the store; it is a no-op when the artifact already exists, so re-running a plan
redoes nothing that finished.
"""

from __future__ import annotations

import contextlib
import json
import signal
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np

from repbench.dataset import Dataset
from repbench.devices import torch_threads as limit_threads
from repbench.errors import RepbenchError
from repbench.latent_metrics import compute_on_latents, metric_rows  # noqa: F401 (tests import it here)
from repbench.pipeline.diskfull import stop_when_full
from repbench.pipeline.records import RECORD_FILE, make_record, write_record
from repbench.pipeline.store import Store, file_sha256, stage_key
from repbench.registry import agents, encoders, metrics, tasks

DATASET, FULL_STATE, ENCODER, LATENTS, METRIC, RL, DIAGNOSTICS = (
    "dataset", "full_state_agent", "encoder", "latents", "metric", "rl", "diagnostics",
)


@dataclass(frozen=True)
class StageSpec:
    """One stage to run: ``kind``, its ``config``, and named input stage keys."""

    kind: str
    config: Mapping[str, Any]
    inputs: Mapping[str, tuple[str, str]] = field(default_factory=dict)  # name → (kind, key)
    label: str = ""
    #: What the stage computes, for its result record (:mod:`repbench.pipeline.records`): task,
    #: data, plugins with versions and parameters, seed. Not part of the key (the config is).
    record: Mapping[str, Any] | None = field(default=None, compare=False)
    #: Stages of one group take about as long as each other (the same metric on one task; RL of
    #: one agent and budget on one task, with or without rendering): the progress line's time
    #: left estimates a stage from its group first (:class:`~repbench.pipeline.executors.
    #: StageTimes`). Not part of the key.
    cost_group: str = field(default="", compare=False)

    @property
    def key(self) -> str:
        return stage_key(self.kind, self.config, sorted(k for _, k in self.inputs.values()))

    @property
    def deps(self) -> list[tuple[str, str]]:
        return list(self.inputs.values())


# -- stage implementations ---------------------------------------------------------------------

def _load_dataset(store: Store, key: str) -> Dataset:
    art = store.get(DATASET, key)
    if art is None:
        raise RuntimeError(f"input dataset {key} is missing from the store")
    return Dataset.load(art.file("dataset.npz"))


def _make_task(cfg: Mapping[str, Any]) -> Any:
    return tasks.get(cfg["task"])(**cfg.get("task_params", {}))


def _run_dataset(spec: StageSpec, store: Store, w: Any) -> None:
    cfg = spec.config
    task = _make_task(cfg)
    policy = None
    if cfg["kind"] == "on_policy":
        from repbench.encoder import Encoder
        from repbench.rl.full_state import load_policy

        art = store.get(FULL_STATE, spec.inputs["policy"][1])
        assert art is not None
        policy = load_policy(art.file("model.zip"), task,
                             Encoder.load(art.file("privileged_encoder.pt")))
    ds = task.collect(cfg["kind"], n_episodes=cfg["n_episodes"],
                      steps_per_episode=cfg["steps_per_episode"], seed=cfg["seed"],
                      policy=policy, progress=False)
    ds.save(w.file("dataset.npz"))
    w.write_json({"n_steps": len(ds), "n_episodes": ds.n_episodes, "checksum": ds.checksum(),
                  "success_rate": float(ds.success.mean()),
                  **{k: ds.metadata[k] for k in ("success_share", "contact_share")
                     if k in ds.metadata},
                  "metadata": ds.metadata})


def _run_full_state(spec: StageSpec, store: Store, w: Any) -> None:
    from repbench.rl.full_state import (
        fitted_privileged_encoder,
        save_policy,
        train_full_state_agent,
    )

    cfg = spec.config
    task = _make_task(cfg)
    dataset = _load_dataset(store, spec.inputs["dataset"][1])
    encoder = fitted_privileged_encoder(task, dataset, cfg["seed"], cfg["encoder"])
    policy, result = train_full_state_agent(
        task, train_steps=cfg["train_steps"], seed=cfg["seed"], encoder=encoder,
        eval_episodes=cfg["eval_episodes"], curve_points=cfg["curve_points"], progress=False,
        **cfg["agent_params"])
    save_policy(policy.model, w.file("model.zip"))
    policy.encoder.save(w.file("privileged_encoder.pt"))
    w.write_json(result.to_dict())


#: Rows of the training data the encoder stage encodes to check the fitted encoder's output.
CHECK_ROWS = 8


def _encoder_label(name: str, enc: Any) -> str:
    return f"encoder {name!r} ({type(enc).__name__})"


def _run_encoder(spec: StageSpec, store: Store, w: Any) -> None:
    from repbench.encoder import check_fit_result, check_latent_dim, check_latents

    cfg = spec.config
    cls = encoders.get(cfg["encoder"])
    dataset = _load_dataset(store, spec.inputs["dataset"][1])
    start = time.time()
    enc = cls(**cfg["params"])
    fitted = enc.fit(dataset)
    fit_time = time.time() - start
    # the conformance kit's checks, so a broken encoder stops here, not in the metrics or RL
    who = _encoder_label(cfg["encoder"], enc)
    check_fit_result(enc, fitted, who)
    dim = check_latent_dim(enc, who)
    enc.save(w.file("encoder.pt"))  # before encoding: the stored encoder is the one fit made
    n = min(len(dataset), CHECK_ROWS)
    check_latents(enc.encode(dataset.obs(slice(0, n))), n, dim, who, float32=False)
    w.write_json({"latent_dim": dim, "fit_time_s": fit_time,
                  "params": enc.get_params(), "family": str(getattr(cls, "family", "learned")),
                  **_save_fit_history(enc, cfg["encoder"], w)})
    figure = getattr(enc, "save_reconstruction_figure", None)
    if callable(figure):
        try:
            figure(dataset, w.file("reconstructions.png"))
        except Exception as exc:  # a figure must never lose a trained encoder
            w.extra_meta["figure_error"] = str(exc)


def _save_fit_history(enc: Any, name: str, w: Any) -> dict[str, Any]:
    """Store an encoder's per-epoch loss history (``history_``: dicts with ``epoch``, ``train``
    and ``heldout`` term dicts) as ``fit_history.json`` and ``loss_curves.png``; return a
    summary (epochs run, best epoch, held-out loss there) for the encoder's record."""
    history = getattr(enc, "history_", None)
    if not history or not all(isinstance(h, dict) and "train" in h for h in history):
        return {}
    w.file("fit_history.json").write_text(json.dumps(history))
    best = int(getattr(enc, "best_epoch_", len(history)) or len(history))
    heldout = history[best - 1].get("heldout", {}) if 0 < best <= len(history) else {}
    try:
        from repbench.report.figures import loss_curves

        loss_curves(history, w.file("loss_curves.png"), title=f"{name}: loss per epoch",
                    best_epoch=best)
    except Exception as exc:  # a figure must never lose a trained encoder
        w.extra_meta["loss_figure_error"] = str(exc)
    return {"epochs_run": len(history), "best_epoch": best,
            "heldout_loss": heldout.get("loss"), "train_loss": history[best - 1]["train"].get(
                "loss") if 0 < best <= len(history) else None}


def _run_latents(spec: StageSpec, store: Store, w: Any) -> None:
    """Encode the metric datasets; store z with the arrays metrics may ask for.

    ``latents.npz`` holds ``z``, ``z_true``, ``episode``, ``step``, ``source`` (index into
    ``source_names``: which dataset a row came from), ``action`` (the dataset's actions; on the
    on-policy dataset the privileged agent's), ``reward`` (the reward each action received),
    ``robot_state`` (``Task.robot_state``: what the agent sees beside z) and ``task_state``
    (``Task.task_state``; absent for a task without one).
    """
    from repbench.encoder import Encoder, check_latent_dim, check_latents

    enc_art = store.get(ENCODER, spec.inputs["encoder"][1])
    assert enc_art is not None
    enc = Encoder.load(enc_art.file("encoder.pt"))
    who = _encoder_label(spec.config["encoder"], enc)
    dim = check_latent_dim(enc, who)
    parts = [(name, _load_dataset(store, key)) for name, (kind, key) in sorted(spec.inputs.items())
             if kind == DATASET]
    data = Dataset.concatenate([d for _, d in parts])
    source = np.concatenate([np.full(len(d), i) for i, (_, d) in enumerate(parts)])
    batch = 256
    # every batch checked (shape [rows, latent_dim], real numbers, finite) before it is stored:
    # a latent of the wrong width must never reach a metric
    z = np.concatenate([
        check_latents(enc.encode(data.obs(slice(i, i + batch))), min(batch, len(data) - i), dim,
                      who, float32=False)
        for i in range(0, len(data), batch)])
    arrays: dict[str, np.ndarray] = {
        "z": z.astype(np.float32), "z_true": data.true_state, "episode": data.episode,
        "step": data.step, "source": source, "source_names": np.array([n for n, _ in parts]),
        "action": data.action, "reward": np.asarray(data.reward, dtype=np.float32)}
    notes: dict[str, Any] = {}
    if "task" in spec.config:
        task = _make_task(spec.config["task"])
        arrays["robot_state"] = np.asarray(task.robot_state(data.obs()), dtype=np.float32)
        try:
            arrays["task_state"] = np.asarray(task.task_state(data.obs()), dtype=np.float32)
        except NotImplementedError as exc:
            notes["task_state"] = str(exc)
    np.savez_compressed(w.file("latents.npz"), **arrays)
    w.write_json({"sources": [n for n, _ in parts], "n": len(data), "latent_dim": dim,
                  "arrays": sorted(arrays), **notes})


def _run_metric(spec: StageSpec, store: Store, w: Any) -> None:
    cfg = spec.config
    art = store.get(LATENTS, spec.inputs["latents"][1])
    assert art is not None
    fn = metrics.get(cfg["metric"])
    with np.load(art.file("latents.npz")) as f:
        arrays = {k: f[k] for k in f.files}
    arrays.setdefault("source_names", np.array(art.read_json().get("sources", [])))
    w.write_json(compute_on_latents(
        fn, arrays, seed=cfg["seed"], params=cfg["params"], rows=cfg.get("rows"),
        who=f"metric {cfg['metric']!r} of encoder {_encoder_of(spec)!r}"))


def _encoder_of(spec: StageSpec) -> str:
    """The name of the encoder a metric stage scores (from its record, else its label)."""
    enc = (spec.record or {}).get("encoder") or {}
    return str(enc.get("name") or spec.label.rpartition(" × ")[2] or "?")


def _run_rl(spec: StageSpec, store: Store, w: Any) -> None:
    from repbench.encoder import Encoder

    cfg = spec.config
    task = _make_task(cfg)
    enc_art = store.get(ENCODER, spec.inputs["encoder"][1])
    assert enc_art is not None
    encoder = Encoder.load(enc_art.file("encoder.pt"))
    agent = agents.get(cfg["agent"])(**cfg["agent_params"])
    result = agent.train(task, encoder, train_steps=cfg["train_steps"], seed=cfg["seed"],
                         eval_episodes=cfg["eval_episodes"], curve_points=cfg["curve_points"],
                         progress=False)
    w.write_json(result.to_dict())


def _run_diagnostics(spec: StageSpec, store: Store, w: Any) -> None:
    from repbench.metrics.diagnostics import true_state_differences

    out = {}
    for name, (_, key) in sorted(spec.inputs.items()):
        ds = _load_dataset(store, key)
        out[name] = true_state_differences(ds.true_state, ds.episode)
    w.write_json(out)


_IMPLEMENTATIONS: dict[str, Callable[[StageSpec, Store, Any], None]] = {
    DATASET: _run_dataset, FULL_STATE: _run_full_state, ENCODER: _run_encoder,
    LATENTS: _run_latents, METRIC: _run_metric, RL: _run_rl, DIAGNOSTICS: _run_diagnostics,
}


#: Threads every stage runs with (torch intra-op *and* the BLAS/OpenMP pools), whatever the
#: executor: the in-process executor, a pool worker and a Ray task sum in the same order, so a
#: stage's value depends on its key alone, never on ``--workers`` or on what runs beside it.
STAGE_THREADS = 1


def execute(spec: StageSpec, store_root: str) -> dict[str, Any]:
    """Run ``spec`` unless its artifact exists; return a small status record.

    The stage runs with :data:`STAGE_THREADS` torch and BLAS/OpenMP threads on every executor
    (the previous settings come back afterwards).
    """
    with limit_threads(STAGE_THREADS, blas=True):
        return _execute(spec, store_root)


@contextlib.contextmanager
def interrupts_recorded() -> Iterator[list[int]]:
    """Inside the block Ctrl-C (SIGINT) raises KeyboardInterrupt as usual *and* is recorded in
    the list the block receives, so a stage is known to be interrupted even when a library
    swallowed the exception and carried on (scikit-learn's MLP ``fit`` catches it and returns
    a half-trained model). SIGTERM is recorded the same way where a handler for it is installed
    (the command line's, which raises KeyboardInterrupt as Ctrl-C does; the handler still
    runs). The previous handlers come back afterwards.

    Nothing is installed outside the main thread (Python allows handlers only there) or where
    SIGINT is ignored (pool workers: their parent stops them, :mod:`repbench.pipeline.executors`).
    """
    seen: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield seen
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is signal.SIG_IGN:
        yield seen
        return
    previous_term = signal.getsignal(signal.SIGTERM)

    def record(signum: int, frame: Any) -> None:
        seen.append(signum)
        raise KeyboardInterrupt

    def record_term(signum: int, frame: Any) -> None:
        seen.append(signum)
        previous_term(signum, frame)  # type: ignore[operator]
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, record)
    if callable(previous_term):  # SIG_DFL ends the process: nothing is committed anyway
        signal.signal(signal.SIGTERM, record_term)
    try:
        with warnings.catch_warnings():
            # the interrupt is handled here (the stage is not committed, the command line says
            # so in one line): scikit-learn's note that it swallowed one is noise on top
            warnings.filterwarnings("ignore", message="Training interrupted by user")
            yield seen
    finally:
        signal.signal(signal.SIGINT, previous)
        if callable(previous_term):
            signal.signal(signal.SIGTERM, previous_term)


def _execute(spec: StageSpec, store_root: str) -> dict[str, Any]:
    store = Store(store_root)
    key = spec.key
    start = time.time()
    if store.get(spec.kind, key) is not None:
        return {"key": key, "status": "cached", "seconds": 0.0}
    with store.lock(spec.kind, key):  # another run computing this stage: wait for it
        if store.get(spec.kind, key) is not None:  # ... and reuse what it computed
            return {"key": key, "status": "cached", "seconds": 0.0,
                    "waited_s": round(time.time() - start, 1)}
        return _compute(spec, store)


def _compute(spec: StageSpec, store: Store) -> dict[str, Any]:
    key = spec.key
    start = time.time()
    # an artifact is committed only if its stage ran to the end without a Ctrl-C, whatever
    # the plugin did with the KeyboardInterrupt: raising inside ``store.write`` discards it
    with interrupts_recorded() as interrupted, \
            stop_when_full(f"stage {spec.label or spec.kind!r}", f"store {store.root}"), \
            store.write(spec.kind, key, config=spec.config,
                        inputs=[k for _, k in spec.inputs.values()],
                        seeds={k: v for k, v in spec.config.items() if "seed" in k}) as writer:
        writer.extra_meta["label"] = spec.label
        if spec.cost_group:  # a later run's time-left estimate reads it (StageTimes)
            writer.extra_meta["cost_group"] = spec.cost_group
        cpu = time.process_time()
        try:
            _IMPLEMENTATIONS[spec.kind](spec, store, writer)
        except SystemExit as exc:  # a plugin's sys.exit: this stage failed, the run goes on
            if interrupted:
                raise KeyboardInterrupt(f"stage {spec.label or key} was interrupted") from None
            raise PluginExitError(_exit_message(spec, exc)) from None
        if spec.record is not None:
            _write_record(spec, store, writer, time.time() - start, time.process_time() - cpu)
        if interrupted:
            raise KeyboardInterrupt(f"stage {spec.label or key} was interrupted")
    return {"key": key, "status": "done", "seconds": time.time() - start}


#: The plugin a stage kind calls (the name :func:`_exit_message` gives it).
_PLUGIN_OF = {DATASET: "task", FULL_STATE: "agent", ENCODER: "encoder", LATENTS: "encoder",
              METRIC: "metric", RL: "agent", DIAGNOSTICS: "metric"}


class PluginExitError(RepbenchError):
    """Plugin code called ``sys.exit`` (raised ``SystemExit``) inside a stage: the stage fails
    like any other; without this the whole run would end, silently, with the plugin's code."""


def _exit_message(spec: StageSpec, exc: SystemExit) -> str:
    """One line: the stage, which plugin function called ``sys.exit`` with what, and the fix."""
    plugin = _PLUGIN_OF.get(spec.kind, "plugin")
    frame = _plugin_frame(exc)
    if frame is None:
        who = f"the {plugin}"
    elif frame.f_code.co_name == "<module>":
        who = f"the {plugin}'s file {Path(frame.f_code.co_filename).name}, on import,"
    else:
        who = f"the {plugin}'s {frame.f_code.co_name}"
    return (f"stage {spec.label or spec.kind + '/' + spec.key}: {who} called "
            f"sys.exit({exc.code!r}); a plugin must raise an exception instead of exiting the "
            "process")


def _plugin_frame(exc: BaseException) -> FrameType | None:
    """The first frame of ``exc``'s traceback below this module's last one that is not
    repbench's own code (nor Python's import machinery): the plugin function that exited."""
    frames = []
    tb = exc.__traceback__
    while tb is not None:
        frames.append(tb.tb_frame)
        tb = tb.tb_next
    here = [i for i, f in enumerate(frames) if f.f_code.co_filename == __file__]
    package = Path(__file__).resolve().parents[1]
    for frame in frames[(here[-1] + 1 if here else 0):]:
        name = frame.f_code.co_filename
        if name.startswith("<") or Path(name).resolve().is_relative_to(package):
            continue
        return frame
    return None


def _write_record(spec: StageSpec, store: Store, w: Any, wall_s: float, cpu_s: float) -> None:
    """The stage's self-describing result record (:mod:`repbench.pipeline.records`), in its
    artifact."""
    assert spec.record is not None
    result = w.file("result.json")
    values = json.loads(result.read_text()) if result.is_file() else {}
    if spec.kind == ENCODER:
        files = {stem: f"{stem}.png" for stem in ("reconstructions", "loss_curves")
                 if w.file(f"{stem}.png").is_file()}
        if files:
            values["files"] = files
    checksums = {}
    for name, key in sorted(spec.record.get("data_stages", {}).items()):
        if (art := store.get(DATASET, key, verify=False)) is not None:
            checksums[name] = art.read_json().get("checksum")
    if spec.kind == DATASET:
        checksums[spec.record.get("data", {}).get("name", "dataset")] = values.get("checksum")
    record = make_record(spec.record, values, data_checksums=checksums,
                         stage={"kind": spec.kind, "key": spec.key, "label": spec.label,
                                "inputs": sorted(k for _, k in spec.inputs.values())},
                         timings={"wall_time_s": round(wall_s, 3), "cpu_time_s": round(cpu_s, 3)},
                         encoder_weights=_encoder_weights(spec, store, w))
    write_record(record, w.file(RECORD_FILE))


def _encoder_weights(spec: StageSpec, store: Store, w: Any) -> str | None:
    """SHA-256 of the trained encoder file a stage's result was computed from: its own
    ``encoder.pt`` for an encoder stage, its input encoder's for latents and RL, the encoder
    behind its latents for a metric; None for stages without an encoder. The stage key cannot
    tell two trainings of one encoder apart (training is not bit-reproducible across CPUs), the
    weights can (:func:`repbench.pipeline.records.mixed_encoder_weights`)."""
    if spec.kind == ENCODER:
        own = w.file("encoder.pt")
        return file_sha256(own) if own.is_file() else None
    keys = [key for kind, key in spec.inputs.values() if kind == ENCODER]
    for kind, key in spec.inputs.values():
        if kind == LATENTS and (latents := store.get(LATENTS, key, verify=False)) is not None:
            keys += [k for k in latents.meta.get("inputs", [])
                     if store.artifact_dir(ENCODER, k).is_dir()]
    for key in keys:
        if (enc := store.get(ENCODER, key, verify=False)) is not None:
            return enc.meta.get("files", {}).get("encoder.pt")
    return None
