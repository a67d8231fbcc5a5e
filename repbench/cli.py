"""The ``repbench`` command line.

User errors (unknown names, bad suite files, unwritable stores, damaged files) print one line and
exit with code 2; a traceback means a bug in repbench or a plugin.
"""

from __future__ import annotations

import inspect
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Annotated, Optional

import typer

from repbench.errors import RepbenchError

app = typer.Typer(
    help="repbench: which learned state representation is good for control, and which "
    "representation metric predicts RL performance.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
task_app = typer.Typer(help="Inspect tasks.", no_args_is_help=True)
app.add_typer(task_app, name="task")

KINDS = ("tasks", "encoders", "metrics", "agents")

# str, not Path: typer turns "" into Path("."), and an empty --store/--out must be refused,
# not taken for the current folder
StoreOpt = Annotated[
    Optional[str],  # noqa: UP045 (typer needs Optional on 3.10)
    typer.Option("--store", help="Stage-store directory (env REPBENCH_STORE; default "
                 "~/.cache/repbench/store).", envvar="REPBENCH_STORE", show_default=False),
]
OutOpt = Annotated[
    Optional[str],  # noqa: UP045
    typer.Option("--out", help="Leaderboard folder (default: leaderboards/<suite>)."),
]


@app.command("list")
def list_plugins(
    kind: Annotated[Optional[str], typer.Argument(  # noqa: UP045
        help="tasks, encoders, metrics or agents (default: all four).")] = None,
) -> None:
    """List registered plugins with one-line descriptions."""
    from repbench.registry import REGISTRIES

    if kind is not None and kind not in REGISTRIES:
        raise RepbenchError(f"unknown plugin kind {kind!r}; choose one of {', '.join(KINDS)}")
    for k in [kind] if kind else list(KINDS):
        reg = REGISTRIES[k]
        typer.echo(f"{k}:")
        for name in reg.names():
            try:
                desc = reg.describe(name)
                sensing = getattr(reg.get(name), "sensing", None) if k == "tasks" else None
                if callable(sensing) and sensing():
                    desc += f" Sensors: {sensing()}."
            except RepbenchError as exc:
                desc = f"[cannot load: {exc}]"
            typer.echo(f"  {name:<22} {desc}")


@app.command()
def doctor() -> None:
    """Check the installation and say what to fix.

    Library versions, the rendering backend, a real 64×64 offscreen render, CPU/GPU.
    """
    from repbench.doctor import run_doctor

    ok = run_doctor(echo=typer.echo)
    raise typer.Exit(0 if ok else 1)


@app.command()
def run(
    suite: Annotated[str, typer.Option("--suite", "-s", help="smoke, quick, paper, or a "
                                       "suite TOML file.")] = "smoke",
    store: StoreOpt = None,
    out: OutOpt = None,
    executor: Annotated[str, typer.Option(help="local or ray.")] = "local",
    workers: Annotated[Optional[int], typer.Option(  # noqa: UP045
        help="Parallel workers for the local executor (default: CPU count).")] = None,
    ray_address: Annotated[Optional[str], typer.Option(  # noqa: UP045
        "--ray-address", help="Join this Ray cluster (e.g. 'auto'); otherwise start a local "
        "Ray instance.")] = None,
    no_rl: Annotated[bool, typer.Option(
        "--no-rl", help="Every stage but the encoders' RL: metrics first (e.g. to commit a "
        "return prediction before any RL record exists); rerun without it to add the RL.")
    ] = False,
    task: Annotated[Optional[list[str]], typer.Option(  # noqa: UP045
        "--task", help="Only this task of the suite (repeat for several; default: all). "
        "Leaderboards go to leaderboards/<suite>-<task> unless --out says otherwise.")] = None,
) -> None:
    """Run a suite and write its leaderboards.

    Datasets → encoders → latents → metrics → RL → correlations → leaderboards. Finished
    stages are reused from the store, so an interrupted run resumes.
    """
    from repbench.pipeline.runner import run_suite

    result = run_suite(suite, store=store, out=out, executor=executor, workers=workers,
                       ray_address=ray_address, no_rl=no_rl, tasks=task or None)
    typer.echo(f"leaderboards written to {result.out_dir}")
    if result.report.failed:
        raise typer.Exit(1)


@app.command()
def leaderboard(
    suite: Annotated[str, typer.Option("--suite", "-s", help="Suite whose results to "
                                       "collect.")] = "smoke",
    store: StoreOpt = None,
    out: OutOpt = None,
    records: Annotated[Optional[list[Path]], typer.Option(  # noqa: UP045
        "--records", help="Build from this folder of result records (e.g. "
        "leaderboards/smoke/records) instead of the store; repeat it for several (e.g. one "
        "per task).")] = None,
    longer: Annotated[Optional[Path], typer.Option(  # noqa: UP045
        "--longer", help="Leaderboard folder of the same task x agent trained for longer "
        "(e.g. leaderboards/quick/longer): adds the 10k-vs-longer rows to "
        "robustness.csv.")] = None,
    agent_run: Annotated[Optional[Path], typer.Option(  # noqa: UP045
        "--agent-run", help="Leaderboard folder of another agent on the same tasks and budget "
        "(e.g. leaderboards/quick/ddpg): adds the SAC-vs-DDPG rows to robustness.csv.")] = None,
    predictions: Annotated[Optional[list[Path]], typer.Option(  # noqa: UP045
        "--predictions", help="Folder of pre-registered predictions (<task id>.csv, e.g. "
        "leaderboards/quick/predictions); repeat it for several (e.g. also "
        "leaderboards/quick/predictions/zoo): scores them in robustness.csv.")] = None,
    copy_records: Annotated[bool, typer.Option(
        "--copy-records/--no-copy-records", help="Copy the --records into OUT/records (the "
        "default), or leave them where they are and name their folders in provenance.json: for "
        "a board built from another board's records, e.g. one task of quick.")] = True,
    scores: Annotated[Optional[list[Path]], typer.Option(  # noqa: UP045
        "--scores", help="Folder `repbench score-metric --out` wrote; repeat it for several: "
        "ranks the metrics scored there with the board's own in metrics.csv.")] = None,
) -> None:
    """Rebuild the leaderboards (CSV + HTML) from stored results without recomputing."""
    from repbench.pipeline.runner import rebuild_leaderboards

    for folder in records or []:
        if not folder.is_dir():
            raise RepbenchError(f"records folder {folder} does not exist")
    out_dir = rebuild_leaderboards(suite, store=store, out=out, records=records or None,
                                   longer=longer, agent_run=agent_run,
                                   predictions=predictions, copy_records=copy_records,
                                   scores=scores)
    typer.echo(f"leaderboards written to {out_dir}")


@app.command()
def evaluate(
    encoder: Annotated[str, typer.Argument(help="Encoder to evaluate: a registered name, or "
                                           "path/to/file.py:Class, or module:Class.")],
    suite: Annotated[str, typer.Option("--suite", "-s", help="Suite whose reference "
                                       "leaderboard to join.")] = "smoke",
    metrics_only: Annotated[bool, typer.Option(
        "--metrics-only", help="Skip RL: compute the metrics and predict the return from the "
        "reference calibration (minutes instead of hours).")] = False,
    reference: Annotated[Optional[list[Path]], typer.Option(  # noqa: UP045
        "--reference", help="Folder of reference records, repeat for several (default: the "
        "folders leaderboards/<suite>/reference.toml lists, else "
        "leaderboards/<suite>/records).")] = None,
    store: StoreOpt = None,
    out: Annotated[Optional[str], typer.Option(  # noqa: UP045
        "--out", help="Leaderboard folder (default: leaderboards/<suite>-<encoder>).")] = None,
    workers: Annotated[Optional[int], typer.Option(  # noqa: UP045
        help="Parallel workers (default: CPU count).")] = None,
    task: Annotated[Optional[list[str]], typer.Option(  # noqa: UP045
        "--task", help="Only this task of the suite (repeat for several; default: all of "
        "them, e.g. quick's PegInHole-v0, SurfacePress-v0 and Door-v0).")] = None,
    predictor: Annotated[Optional[list[str]], typer.Option(  # noqa: UP045
        "--predictor", help="With --metrics-only: predict the return from this metric only "
        "(repeat for several; default: the calibration picks among all of the suite's).")] = None,
) -> None:
    """Evaluate one encoder against a suite's reference records.

    Computes only its stages, merges them with the reference records, and writes a
    leaderboard with it highlighted.
    """
    from repbench.pipeline.evaluate import evaluate_encoder

    result = evaluate_encoder(encoder, suite, metrics_only=metrics_only, store=store,
                              out=out, reference=reference or None, workers=workers,
                              tasks=task or None, predictors=predictor or None)
    typer.echo(f"leaderboard written to {result.out_dir}")
    if result.report.failed:
        raise typer.Exit(1)


@app.command("score-metric")
def score_metric(
    metric: Annotated[str, typer.Argument(help="Metric to score: a registered name, or "
                                          "path/to/file.py:fn, or module:fn.")],
    suite: Annotated[str, typer.Option("--suite", "-s", help="Suite whose shipped latents "
                                       "and RL returns to score against.")] = "quick",
    task: Annotated[Optional[list[str]], typer.Option(  # noqa: UP045
        "--task", help="Only this task (repeat for several; default: every task with shipped "
        "latents).")] = None,
    out: Annotated[Optional[str], typer.Option(  # noqa: UP045
        "--out", help="Folder for its row, every metric's rows, its figure and scored.json, "
        "which `repbench leaderboard --scores` reads (default: "
        "leaderboards/<suite>-metric-<metric>).")] = None,
    reference: Annotated[Optional[list[Path]], typer.Option(  # noqa: UP045
        "--reference", help="Folder of reference records, repeat for several (default: the "
        "suite's, as for evaluate).")] = None,
    latents: Annotated[Optional[Path], typer.Option(  # noqa: UP045
        "--latents", help="Folder of shipped latents (default: "
        "leaderboards/<suite>/latents).")] = None,
    lower_is_better: Annotated[bool, typer.Option(
        "--lower-is-better/--higher-is-better", help="Direction of a plain function's value "
        "(a registered metric declares its own).")] = False,
    observable: Annotated[bool, typer.Option(
        "--observable", help="A plain function reads only what a real robot logs (no "
        "simulator state): its group on the board.")] = False,
    workers: Annotated[Optional[int], typer.Option(  # noqa: UP045
        help="Processes for a slow metric (default: CPU count).")] = None,
) -> None:
    """Score a metric against a suite's reference without training or RL.

    Computes the metric on every shipped latent set as a run would and ranks it with the
    reference's metrics against the reference's RL returns, beside the noise ceiling.
    """
    from repbench.pipeline.preflight import check_out_dir
    from repbench.pipeline.score_metric import score_metric as score
    from repbench.pipeline.suite import load_suite

    name = metric.rpartition(":")[2] if ":" in metric else metric
    out_dir = out if out is not None else str(
        Path("leaderboards") / f"{load_suite(suite).name}-metric-{name}")
    result = score(metric, suite, reference=reference or None, latents=latents,
                   tasks=task or None, workers=workers, out=check_out_dir(out_dir),
                   higher_is_better=not lower_is_better, observable=observable,
                   echo=typer.echo)
    for r in result.row.to_dict("records"):
        typer.echo(
            f"{r['task']} {r['agent']}: {result.metric} within-learned ρ "
            f"{r['spearman_learned']:.2f} [{r['spearman_learned_ci_low']:.2f}, "
            f"{r['spearman_learned_ci_high']:.2f}] over {r['n_learned']} encoders "
            f"(all {r['spearman_all']:.2f}), rank {r['rank']} of {r['n_metrics']}, Holm p "
            f"{r['spearman_learned_p_holm']:.3g}; noise ceiling {r['noise_ceiling']:.2f}, "
            f"{r['of_ceiling']:.0%} of it")
    typer.echo(f"scored in {result.seconds:.1f} s; written to {result.out_dir}")


@app.command("export-latents")
def export_latents(
    suite: Annotated[str, typer.Option("--suite", "-s", help="Suite whose latents to "
                                       "export.")] = "quick",
    store: StoreOpt = None,
    out: Annotated[Optional[str], typer.Option(  # noqa: UP045
        "--out", help="Latents folder (default: leaderboards/<suite>/latents).")] = None,
    task: Annotated[Optional[list[str]], typer.Option(  # noqa: UP045
        "--task", help="Only this task (repeat for several).")] = None,
    encoder: Annotated[Optional[list[str]], typer.Option(  # noqa: UP045
        "--encoder", help="Only this encoder (repeat for several).")] = None,
) -> None:
    """Export a suite's latents from the store into its shipped latents folder.

    Adds to (or replaces the same task and encoder in) what the folder holds; every file is
    checksummed in its manifest.json.
    """
    from repbench.pipeline.latents_export import export_latents as export
    from repbench.pipeline.preflight import check_out_dir
    from repbench.pipeline.suite import load_suite

    folder = out if out is not None else str(
        Path("leaderboards") / load_suite(suite).name / "latents")
    written = export(suite, store=store, out=check_out_dir(folder), tasks=task or None,
                     encoders=encoder or None)
    typer.echo(f"{len(written)} files written to {folder}")


@task_app.command("preview")
def task_preview(
    task: Annotated[str, typer.Argument(help="Registered task id, e.g. PegInHole-v0.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="PNG file to write.")] = Path(
        "preview.png"),
    frames: Annotated[int, typer.Option(help="Number of frames.")] = 24,
    seed: Annotated[int, typer.Option(help="Rollout seed.")] = 0,
) -> None:
    """Contact sheet of wrist-camera frames from one rollout, force magnitude beside each.

    At most 200 frames (--frames); an --out without an extension gets .png.
    """
    from repbench.preview import render_preview
    from repbench.registry import tasks

    path = render_preview(tasks.get(task)(), out, n_frames=frames, seed=seed)
    typer.echo(f"preview written to {path}")


def _unwrapped(doc: str) -> str:
    """A docstring as a command's help: its paragraphs kept, the lines of each joined, so the
    terminal wraps them at its width (typer's rich help kept every line break of the
    docstring: "a real 64×64 offscreen" / "render, CPU/GPU" at 80 columns)."""
    return "\n\n".join(" ".join(p.split()) for p in inspect.cleandoc(doc).split("\n\n"))


for _app in (app, task_app):
    for _info in _app.registered_commands:
        if _info.help is None and _info.callback is not None and _info.callback.__doc__:
            _info.help = _unwrapped(_info.callback.__doc__)


#: Exit code of a run stopped by Ctrl-C (128 + SIGINT) and by SIGTERM (128 + SIGTERM), as a
#: shell reports a process either signal ended.
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143
_terminated: list[int] = []  # SIGTERM received (by :func:`_on_sigterm`)


def _on_sigterm(signum: int, frame: object) -> None:
    """SIGTERM (``kill PID``, a scheduler's or container's stop) stops the command as Ctrl-C
    does: a KeyboardInterrupt in the main thread, so the same clean stop runs (running stages
    are not committed, pool workers are stopped, finished stages stay in the store). A second
    SIGTERM during that stop ends the process at once."""
    _terminated.append(signum)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> None:
    """Console entry point: user errors → one line on stderr, exit code 2; Ctrl-C and SIGTERM
    → one line, exit code 130 and 143."""
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGTERM) if in_main else None
    if in_main and previous in (signal.SIG_DFL, None):
        signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        _main(argv)
    finally:
        if in_main and previous in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _main(argv: list[str] | None) -> None:
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        app(args=argv, prog_name="repbench", standalone_mode=True)
    except RepbenchError as exc:
        typer.echo(f"repbench: error: {exc}", err=True)
        sys.exit(2)
    except OSError as exc:  # a full disk outside the store (leaderboards, figures): one line too
        from repbench.pipeline.diskfull import is_disk_full

        if not is_disk_full(exc):
            raise
        typer.echo(f"repbench: error: no space left on the disk ({exc}); free some space and "
                   "run the same command again", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        _interrupted(args)
    except SystemExit as exc:  # typer turns Ctrl-C inside a command into a silent Exit(130)
        if _caused_by_ctrl_c(exc):
            _interrupted(args)
        raise


#: What the one-line message of a Ctrl-C says after "repbench: interrupted", by command; the
#: commands that run stages keep what they finished in the store.
_INTERRUPTED = {
    "run": "finished stages are kept in the store — run the same command again to resume",
    "evaluate": "finished stages are kept in the store — run the same command again to resume",
    "task preview": "no preview was written — run the same command again",
}


def _interrupted(args: list[str]) -> None:
    words = [a for a in args if not a.startswith("-")][:2]
    command = " ".join(words[:2]) if words[:1] == ["task"] else " ".join(words[:1])
    note = _INTERRUPTED.get(command)
    typer.echo("repbench: interrupted" + (f"; {note}" if note else ""), err=True)
    sys.exit(EXIT_TERMINATED if _terminated else EXIT_INTERRUPTED)


def _caused_by_ctrl_c(exc: BaseException) -> bool:
    """True when a KeyboardInterrupt is among the causes or contexts of ``exc``."""
    seen: BaseException | None = exc
    for _ in range(10):
        if seen is None:
            return False
        if isinstance(seen, KeyboardInterrupt):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


if __name__ == "__main__":  # pragma: no cover
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    main()
