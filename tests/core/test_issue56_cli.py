"""Issue 56, bad input and faults at the command line: a plugin calling ``sys.exit``, ``task
preview``'s limits, interrupt and rendering messages, suite-file nits (a byte-order mark, the
name "."), the store folder a refusal leaves behind, and ``repbench --help``. Each test failed on
the code before its fix."""

from __future__ import annotations

import codecs
import itertools
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from repbench.cli import main
from repbench.errors import RepbenchError
from repbench.pipeline.suite import load_suite

from ..runner.tiny_toy_suite import tiny_toy_suite
from .test_bad_input import _cli

TOY = tiny_toy_suite("toy56", ["oracle"])

_QUITTER = textwrap.dedent('''
    import sys

    import numpy as np
    import repbench


    class Quitter(repbench.Encoder):
        """Calls sys.exit(3) in fit, as a careless script does."""

        def __init__(self, latent_dim: int = 3):
            self.latent_dim_ = latent_dim

        def fit(self, dataset):
            sys.exit(3)

        def encode(self, observations):
            return np.zeros((len(observations["image"]), self.latent_dim_), np.float32)

        @property
        def latent_dim(self):
            return self.latent_dim_
''')


def _suite(tmp_path: Path, text: str = TOY, name: str = "toy56") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


# -- 1. sys.exit inside a plugin ----------------------------------------------------------------

def test_sys_exit_in_an_encoders_fit_is_a_failed_stage(capsys: pytest.CaptureFixture[str],
                                                       tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: ``repbench run --workers 1`` ended with exit code 3 and no output at all."""
    from repbench.registry import encoders

    monkeypatch.chdir(tmp_path)
    (tmp_path / "quitter.py").write_text(_QUITTER)
    suite = _suite(tmp_path, tiny_toy_suite("toy56", ["oracle", "quitter.py:Quitter"]))
    try:
        with pytest.raises(SystemExit) as info:
            main(["run", "--suite", str(suite), "--store", str(tmp_path / "s"), "--out",
                  str(tmp_path / "lb"), "--workers", "1"])
    finally:
        encoders.unregister("quitter.py:Quitter")
    out, err = capsys.readouterr()
    assert info.value.code == 1, out + err  # failed stages, like any other failure
    assert "failed stages" in out and "leaderboards written to" in out, out
    line = next(s for s in out.splitlines() if "sys.exit" in s)
    assert "ToyReach-v0" in line and "quitter.py:Quitter" in line, line
    assert "the encoder's fit called sys.exit(3)" in line, line
    assert (tmp_path / "lb" / "encoders.csv").is_file()  # the run went on: oracle's board
    assert "oracle" in (tmp_path / "lb" / "encoders.csv").read_text()


def test_sys_exit_in_a_stage_raises_a_repbench_error(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The stage itself turns the SystemExit into an error (any executor reports it)."""
    from repbench.pipeline.plan import build_plan
    from repbench.pipeline.stages import ENCODER, execute
    from repbench.pipeline.store import Store
    from repbench.registry import encoders

    monkeypatch.chdir(tmp_path)
    (tmp_path / "quitter.py").write_text(_QUITTER)
    suite = _suite(tmp_path, tiny_toy_suite("toy56", ["quitter.py:Quitter"]))
    try:
        tp = build_plan(load_suite(suite)).tasks[0]
        root = str(tmp_path / "s")
        execute(tp.random_dataset, root)
        stage = tp.encoders["quitter.py:Quitter"]
        with pytest.raises(RepbenchError) as info:
            execute(stage, root)
    finally:
        encoders.unregister("quitter.py:Quitter")
    msg = str(info.value)
    assert "\n" not in msg and (stage.label or "") in msg
    assert "the encoder's fit called sys.exit(3)" in msg
    assert Store(root).get(ENCODER, stage.key) is None  # nothing committed


# -- 2. task preview: frame limit, Ctrl-C, a bad MUJOCO_GL ---------------------------------------

@pytest.mark.parametrize("frames", ["100000000", "201"])
def test_task_preview_refuses_absurd_frame_counts(capsys: pytest.CaptureFixture[str],
                                                  tmp_path: Path, frames: str,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: --frames 100000000 started a rollout of 400 million steps."""
    from repbench.testing.toy_task import ToyReachTask

    def no_rollout(*a: object, **k: object) -> None:
        raise AssertionError("the rollout started before the bad argument was noticed")

    monkeypatch.setattr(ToyReachTask, "collect", no_rollout)
    err = _cli(capsys, "task", "preview", "ToyReach-v0", "--frames", frames, "--out",
               str(tmp_path / "p.png"))
    assert f"--frames must be a whole number in [1, 200], got {frames}" in err


def test_task_preview_takes_the_largest_frame_count(tmp_path: Path) -> None:
    from repbench.preview import MAX_PREVIEW_FRAMES, _check_preview_args

    assert MAX_PREVIEW_FRAMES == 200
    _check_preview_args(tmp_path / "p.png", MAX_PREVIEW_FRAMES, 0, None)  # no error


def test_task_preview_ctrl_c_says_what_it_stopped(capsys: pytest.CaptureFixture[str],
                                                  tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: "interrupted; finished stages are kept in the store": preview has neither."""
    from repbench.testing.toy_task import ToyReachTask

    def ctrl_c(*a: object, **k: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(ToyReachTask, "collect", ctrl_c)
    with pytest.raises(SystemExit) as info:
        main(["task", "preview", "ToyReach-v0", "--out", str(tmp_path / "p.png")])
    err = capsys.readouterr().err
    assert info.value.code == 130, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert "interrupted" in err and "no preview was written" in err, err
    assert "stage" not in err and "store" not in err, err


def test_run_ctrl_c_still_names_the_store(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    def ctrl_c(*a: object, **k: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("repbench.pipeline.runner.run_stages", ctrl_c)
    with pytest.raises(SystemExit) as info:
        main(["run", "--suite", str(_suite(tmp_path)), "--store", str(tmp_path / "s"),
              "--out", str(tmp_path / "lb"), "--workers", "1"])
    err = capsys.readouterr().err
    assert info.value.code == 130
    assert "interrupted; finished stages are kept in the store" in err


def test_task_preview_with_a_bad_mujoco_gl_explains_it(tmp_path: Path) -> None:
    """Before: a 71-line traceback ending in "invalid value for environment variable
    MUJOCO_GL"; ``run`` and ``doctor`` explain it."""
    env = {**os.environ, "MUJOCO_GL": "bogus"}
    env.pop("PYOPENGL_PLATFORM", None)
    out = subprocess.run([sys.executable, "-m", "repbench.cli", "task", "preview",
                          "PegInHole-v0", "--frames", "1", "--out", str(tmp_path / "p.png")],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert out.returncode == 2, out.stdout + out.stderr
    err = out.stderr
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "MUJOCO_GL: bogus" in err and "MUJOCO_GL=egl" in err and "repbench doctor" in err
    assert not (tmp_path / "p.png").exists()


# -- 3. and 4. suite files ----------------------------------------------------------------------

def test_suite_file_with_a_byte_order_mark_loads(tmp_path: Path) -> None:
    """Before: "not valid TOML (Invalid statement (at line 1, column 1))", the mark unnamed
    (Windows Notepad saves UTF-8 with one)."""
    path = tmp_path / "bom.toml"
    path.write_bytes(codecs.BOM_UTF8 + TOY.encode("utf-8"))
    suite = load_suite(path)
    assert suite.name == "toy56" and suite.tasks == ["ToyReach-v0"]


def test_suite_file_with_a_bom_and_bad_bytes_names_the_right_line(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "bomlatin1.toml"
    path.write_bytes(codecs.BOM_UTF8
                     + TOY.replace('name = "toy56"', 'name = "café"').encode("latin-1"))
    err = _cli(capsys, "run", "--suite", str(path), "--store", str(tmp_path / "s"))
    assert f"suite file {path} is not UTF-8 text (byte 0xe9 on line 2); save it as UTF-8" in err


@pytest.mark.parametrize("name", [".", "...", "a\\\\b", ".hidden"])
def test_suite_name_dot_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                   name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: name = "." wrote its board into leaderboards/ itself (".hidden": into a hidden
    folder)."""
    from repbench.pipeline.runner import default_out_dir

    monkeypatch.chdir(tmp_path)
    suite = _suite(tmp_path, TOY.replace('name = "toy56"', f'name = "{name}"'))
    err = _cli(capsys, "run", "--suite", str(suite), "--store", str(tmp_path / "s"),
               "--workers", "1")
    assert "field 'name'" in err and "must be a folder name" in err, err
    assert not (tmp_path / "leaderboards").exists()
    with pytest.raises(RepbenchError, match="suite name"):
        default_out_dir(".", [])


# -- 5. task preview --out without an extension -------------------------------------------------

def test_task_preview_reports_the_file_it_wrote(capsys: pytest.CaptureFixture[str],
                                                tmp_path: Path) -> None:
    """Before: "preview written to prev/noext" while matplotlib wrote prev/noext.png."""
    out = tmp_path / "prev" / "noext"
    with pytest.raises(SystemExit) as info:
        main(["task", "preview", "ToyReach-v0", "--frames", "2", "--out", str(out)])
    stdout, err = capsys.readouterr()
    assert info.value.code == 0, err
    assert stdout.strip() == f"preview written to {out}.png", stdout
    assert Path(f"{out}.png").is_file() and not out.exists()


# -- 8. repbench --help -------------------------------------------------------------------------

def _commands() -> dict[str, object]:
    import typer

    from repbench.cli import app

    group = typer.main.get_command(app)
    found = {}
    for name, cmd in group.commands.items():  # type: ignore[attr-defined]
        found[name] = cmd
        for sub, subcmd in getattr(cmd, "commands", {}).items():
            found[f"{name} {sub}"] = subcmd
    return found


def test_every_command_has_a_one_line_short_help() -> None:
    """Before: the command list kept the docstrings' line breaks, so "doctor" read "... a real
    64×64 offscreen" / "render, CPU/GPU, ..." over two lines, cut mid-sentence."""
    for name, cmd in _commands().items():
        short = cmd.short_help or (cmd.help or "").split("\n\n")[0]  # type: ignore[attr-defined]
        short = textwrap.dedent(short).strip()
        assert short and "\n" not in short, (name, short)
        assert short.endswith("."), (name, short)


def test_command_help_keeps_no_line_breaks_of_the_docstring() -> None:
    """Before: ``repbench run --help`` at 80 columns read "... leaderboards. Finished" /
    "stages are reused ...": each docstring line break stayed a line break."""
    for name, cmd in _commands().items():
        for paragraph in (cmd.help or "").split("\n\n"):  # type: ignore[attr-defined]
            assert "\n" not in paragraph.strip(), (name, paragraph)


def test_help_lists_each_command_in_whole_sentences() -> None:
    """The command list at 80 columns: a description goes on to its next row only where its
    next word did not fit (rich's wrapping), never at a line break of the docstring."""
    env = {**os.environ, "COLUMNS": "80", "TERM": "dumb"}
    out = subprocess.run([sys.executable, "-m", "repbench.cli", "--help"], capture_output=True,
                         text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    panel = out.stdout.split("Commands")[1].splitlines()[1:]
    rows = [line[1:-1] for line in panel if line.startswith("│")]
    start = rows[0].index("List registered")  # where the description column starts
    width = len(rows[0]) - start
    for before, row in itertools.pairwise(rows):
        if row[:start].strip():  # the next command
            continue
        text, word = before[start:].rstrip(), row[start:].split()[0]
        assert len(text) + 1 + len(word) > width - 2, (text, word)


# -- 10. no empty store folder left by a refusal ------------------------------------------------

def _bad_params(tmp_path: Path) -> Path:
    return _suite(tmp_path, TOY.replace("horizon = 20", "horizon = 0"), "badparams")


@pytest.mark.parametrize("case", ["bad task parameter", "unknown executor", "nested store"])
def test_a_refused_run_leaves_no_store_folder(capsys: pytest.CaptureFixture[str],
                                              tmp_path: Path, case: str) -> None:
    """Before: ``repbench run --suite bad.toml --store /tmp/newstore`` created /tmp/newstore
    (with its .tmp folder), then refused the suite."""
    store = tmp_path / ("a/b/newstore" if case == "nested store" else "newstore")
    args = ["run", "--suite", str(_bad_params(tmp_path) if case != "unknown executor"
                                  else _suite(tmp_path)),
            "--store", str(store), "--out", str(tmp_path / "lb"), "--workers", "1"]
    if case == "unknown executor":
        args += ["--executor", "bogus"]
    _cli(capsys, *args)
    assert not store.exists()
    assert not (tmp_path / "a").exists()


def test_a_refusal_from_python_leaves_no_store_folder(tmp_path: Path) -> None:
    """Before: the clean-up lived in the command line only; ``run_suite`` and
    ``evaluate_encoder`` called from Python left the empty store folder they made."""
    from repbench.errors import RepbenchError
    from repbench.pipeline.evaluate import evaluate_encoder
    from repbench.pipeline.runner import run_suite

    store = tmp_path / "a" / "newstore"
    with pytest.raises(RepbenchError):
        run_suite(_bad_params(tmp_path), store=store, out=tmp_path / "lb", workers=1)
    assert not (tmp_path / "a").exists()
    with pytest.raises(RepbenchError):
        evaluate_encoder("random", _suite(tmp_path), store=str(store), out=tmp_path / "ev",
                         reference=tmp_path / "no-such-records", workers=1)
    assert not (tmp_path / "a").exists()


def test_a_refusal_keeps_a_store_that_was_there(capsys: pytest.CaptureFixture[str],
                                                tmp_path: Path) -> None:
    store = tmp_path / "oldstore"
    (store / ".tmp").mkdir(parents=True)
    _cli(capsys, "run", "--suite", str(_bad_params(tmp_path)), "--store", str(store))
    assert (store / ".tmp").is_dir()


def test_a_refused_leaderboard_leaves_no_store_folder(capsys: pytest.CaptureFixture[str],
                                                      tmp_path: Path) -> None:
    store = tmp_path / "empty"
    _cli(capsys, "leaderboard", "--suite", "smoke", "--store", str(store), "--out",
         str(tmp_path / "lb"))
    assert not store.exists()
