"""Bad input (issue 45, part 2): sizes, names, shapes and paths a person can get wrong, each
refused with one line naming the thing and the fix, exit code 2, before any stage runs. Each test
failed on the code before its fix."""

from __future__ import annotations

from pathlib import Path

import pytest

from repbench.errors import ConfigError
from repbench.pipeline.preflight import check_dataset_sizes, dataset_bytes_per_step
from repbench.pipeline.store import Store

from ..runner.tiny_toy_suite import tiny_toy_suite
from .test_bad_input import _cli

TOY = tiny_toy_suite("toylimits", ["oracle"])


@pytest.fixture
def no_stage_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any stage that starts fails the test (the checks must come first)."""
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("a stage ran before the bad input was noticed")

    monkeypatch.setattr("repbench.pipeline.runner.run_stages", refuse)
    monkeypatch.setattr("repbench.pipeline.evaluate.run_stages", refuse)


def _suite(tmp_path: Path, text: str = TOY, name: str = "toylimits") -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


# -- dataset sizes ------------------------------------------------------------------------------

def test_huge_dataset_is_refused_by_what_it_needs(capsys: pytest.CaptureFixture[str],
                                                  tmp_path: Path, no_stage_runs: None) -> None:
    """Before: accepted; collection died at ~10 GB with a MemoryError that named nothing."""
    suite = _suite(tmp_path, TOY.replace("random_episodes = 3", "random_episodes = 10000000"))
    err = _cli(capsys, "run", "--suite", str(suite), "--store", str(tmp_path / "s"),
               "--out", str(tmp_path / "lb"), "--workers", "1")
    assert "dataset.random_episodes = 10000000" in err
    assert " GB" in err and "memory" in err
    assert not (tmp_path / "s" / "dataset").exists()


def test_per_task_override_is_named(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                    no_stage_runs: None) -> None:
    suite = _suite(tmp_path, TOY + '[task_dataset."ToyReach-v0"]\nrandom_steps = 100000000\n')
    err = _cli(capsys, "run", "--suite", str(suite), "--store", str(tmp_path / "s"),
               "--out", str(tmp_path / "lb"), "--workers", "1")
    assert ("dataset.random_episodes = 3 and task_dataset.ToyReach-v0.random_steps = 100000000"
            in err)


def test_dataset_larger_than_the_free_disk_is_refused(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from repbench.pipeline import preflight
    from repbench.pipeline.plan import build_plan
    from repbench.pipeline.suite import load_suite

    plan = build_plan(load_suite(_suite(tmp_path)))
    store = Store(tmp_path / "s")
    check_dataset_sizes(plan, store)  # the tiny suite fits
    monkeypatch.setattr(preflight, "_free_disk_bytes", lambda path: 1000)
    with pytest.raises(ConfigError, match=r"dataset\.random_episodes = 3.*disk of the store"):
        check_dataset_sizes(plan, store)
    monkeypatch.setattr(preflight, "_available_memory_bytes", lambda: 1000)
    with pytest.raises(ConfigError, match=r"dataset\.random_episodes = 3.*memory"):
        check_dataset_sizes(plan, store)


def test_bytes_per_step_counts_the_image() -> None:
    assert 64 * 64 * 3 < dataset_bytes_per_step(64) < 64 * 64 * 3 + 1024
    assert dataset_bytes_per_step(128) > 4 * 64 * 64 * 3


def test_builtin_suites_pass_the_size_check(tmp_path: Path) -> None:
    from repbench.pipeline.plan import build_plan
    from repbench.pipeline.suite import load_suite

    for name in ("smoke", "quick", "paper"):
        check_dataset_sizes(build_plan(load_suite(name)), Store(tmp_path / "s"))


# -- suite names --------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["../../x", "..", "a/b", "x..y", "", "with space", "/abs"])
def test_suite_name_that_is_no_folder_name_is_refused(capsys: pytest.CaptureFixture[str],
                                                      tmp_path: Path, name: str,
                                                      no_stage_runs: None,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: name = "../../x" wrote its board to ../../x, outside leaderboards/."""
    monkeypatch.chdir(tmp_path)
    suite = _suite(tmp_path, TOY.replace('name = "toylimits"', f"name = {name!r}"))
    err = _cli(capsys, "run", "--suite", str(suite), "--store", str(tmp_path / "s"),
               "--workers", "1")
    assert "field 'name'" in err and "letters, digits" in err
    assert not list(tmp_path.parent.glob("x")) and not (tmp_path / "leaderboards").exists()


def test_good_suite_names_load(tmp_path: Path) -> None:
    from repbench.pipeline.suite import load_suite

    for name in ("quick", "my_suite-2.v1"):
        path = _suite(tmp_path, TOY.replace('name = "toylimits"', f"name = {name!r}"))
        assert load_suite(path).name == name


def test_default_out_dir_stays_inside_leaderboards() -> None:
    from repbench.pipeline.runner import default_out_dir

    root = Path("leaderboards").resolve()
    for tasks in ([], ["ToyReach-v0"], ["../../evil.py:Task"], ["/etc/x.py:T"]):
        out = default_out_dir("quick", tasks).resolve()
        assert out.parent == root, out
    with pytest.raises(ConfigError, match="suite name"):
        default_out_dir("../../x")


# -- worker counts ------------------------------------------------------------------------------

class _Stop(Exception):
    pass


def _usable_cpus() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


@pytest.mark.parametrize("command", ["run", "evaluate"])
def test_workers_beyond_the_cpus_are_capped_with_a_warning(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        command: str) -> None:
    """Before: --workers 1000 started a pool of 1000 spawned processes on a 2-core machine."""
    asked: list[int | None] = []

    def executor(kind: str, root: str, workers: int | None = None, *args: object) -> None:
        asked.append(workers)
        raise _Stop

    monkeypatch.setattr("repbench.pipeline.runner.make_executor", executor)
    monkeypatch.setattr("repbench.pipeline.evaluate.make_executor", executor)
    from repbench.pipeline.evaluate import evaluate_encoder
    from repbench.pipeline.runner import run_suite

    with pytest.raises(_Stop):
        if command == "run":
            run_suite(_suite(tmp_path), store=tmp_path / "s", out=tmp_path / "lb",
                      workers=1000, progress=False)
        else:
            evaluate_encoder("pca", "smoke", metrics_only=True, store=tmp_path / "s",
                             out=tmp_path / "lb", workers=1000, progress=False,
                             reference=Path(__file__).resolve().parents[2] / "leaderboards"
                             / "smoke" / "records")
    assert asked == [_usable_cpus()]
    err = capsys.readouterr().err
    [line] = [x for x in err.splitlines() if "--workers" in x]
    assert f"--workers 1000 is more than the {_usable_cpus()} CPUs" in line
    assert f"using {_usable_cpus()}" in line


def test_workers_within_the_cpus_are_kept(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    asked: list[int | None] = []

    def executor(kind: str, root: str, workers: int | None = None, *args: object) -> None:
        asked.append(workers)
        raise _Stop

    monkeypatch.setattr("repbench.pipeline.runner.make_executor", executor)
    from repbench.pipeline.runner import run_suite

    with pytest.raises(_Stop):
        run_suite(_suite(tmp_path), store=tmp_path / "s", out=tmp_path / "lb", workers=1,
                  progress=False)
    assert asked == [1] and "--workers" not in capsys.readouterr().err
