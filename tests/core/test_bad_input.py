"""Bad input (issue 21, part B): one line naming the thing and the fix, exit code 2, before any
stage runs. Each test failed on the code before the fix. Nothing here renders robosuite or
trains: commands that get past the checks would run stages, and ``no_stage_runs`` makes that a
test failure at once."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import repbench
from repbench.cli import main
from repbench.errors import ConfigError, DataError, StoreError
from repbench.pipeline.preflight import check_ray_address
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite

from ..runner.tiny_toy_suite import tiny_toy_suite

ROOT = Path(__file__).resolve().parents[2]
TOY = tiny_toy_suite("toybad", ["oracle"])


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """Run the CLI in this process; assert exit code 2 and one line on stderr; return it."""
    with pytest.raises(SystemExit) as info:
        main(list(args))
    err = capsys.readouterr().err
    assert info.value.code == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith("repbench: error: "), err
    return err


@pytest.fixture
def no_stage_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any stage that starts fails the test (the checks must come first)."""
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("a stage ran before the bad input was noticed")

    monkeypatch.setattr("repbench.pipeline.runner.run_stages", refuse)
    monkeypatch.setattr("repbench.pipeline.evaluate.run_stages", refuse)


@pytest.fixture
def toy_suite(tmp_path: Path) -> Path:
    path = tmp_path / "toybad.toml"
    path.write_text(TOY)
    return path


@pytest.fixture
def closed_port() -> int:
    """A loopback port nobody listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def no_ray_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """No $RAY_ADDRESS, and Ray's temp folder (where `ray start` records the cluster) empty."""
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setenv("RAY_TMPDIR", str(tmp_path / "raytmp"))
    return tmp_path / "raytmp"


@pytest.fixture
def unwritable_dir(tmp_path: Path) -> Iterator[Path]:
    """A folder nobody can create files in (a read-only folder; as root, /sys)."""
    folder = tmp_path / "readonly"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        (folder / "probe").touch()
    except OSError:
        yield folder
    else:  # root ignores permissions
        (folder / "probe").unlink()
        if os.access("/sys", os.W_OK) and _can_create_in(Path("/sys")):
            pytest.skip("no unwritable folder on this machine")
        yield Path("/sys")
    finally:
        folder.chmod(0o700)


def _can_create_in(folder: Path) -> bool:
    try:
        (folder / ".repbench-test-probe").touch()
    except OSError:
        return False
    (folder / ".repbench-test-probe").unlink()
    return True


# -- the Ray address ----------------------------------------------------------------------------

def test_ray_address_that_does_not_answer_fails_in_seconds(tmp_path: Path, toy_suite: Path
                                                           ) -> None:
    """Before: ray.init waited more than 4 minutes (and rewrote 127.0.0.1)."""
    store = tmp_path / "s"
    out = subprocess.run(
        [sys.executable, "-m", "repbench.cli", "run", "--suite", str(toy_suite), "--store",
         str(store), "--executor", "ray", "--ray-address", "127.0.0.1:1"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert "--ray-address: no Ray cluster answers at 127.0.0.1:1" in out.stderr
    assert "ray start --head" in out.stderr
    assert not (store / "dataset").exists()


def test_ray_address_auto_without_a_cluster(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                            toy_suite: Path, no_ray_env: Path,
                                            no_stage_runs: None) -> None:
    """Before: a ConnectionError traceback from inside ray.init."""
    err = _cli(capsys, "run", "--suite", str(toy_suite), "--store", str(tmp_path / "s"),
               "--executor", "ray", "--ray-address", "auto")
    assert "--ray-address auto: no running Ray cluster found" in err
    assert str(no_ray_env / "ray" / "ray_current_cluster") in err


def test_ray_address_auto_finds_a_stale_cluster_file(no_ray_env: Path, closed_port: int) -> None:
    (no_ray_env / "ray").mkdir(parents=True)
    (no_ray_env / "ray" / "ray_current_cluster").write_text(f"127.0.0.1:{closed_port}\n")
    with pytest.raises(ConfigError, match=rf"auto \(found 127\.0\.0\.1:{closed_port} in .*"
                                          r"ray_current_cluster\): no Ray cluster answers"):
        check_ray_address("auto")


def test_ray_address_auto_uses_the_environment(no_ray_env: Path, closed_port: int,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAY_ADDRESS", f"127.0.0.1:{closed_port}")
    with pytest.raises(ConfigError, match=r"\$RAY_ADDRESS=127\.0\.0\.1:\d+\): no Ray cluster"):
        check_ray_address("auto")


@pytest.mark.parametrize("address", ["nonsense", "127.0.0.1", "127.0.0.1:99999", ":6379"])
def test_ray_address_that_is_not_host_port(address: str) -> None:
    with pytest.raises(ConfigError, match="is not a Ray address; use 'auto', 'local' or HOST:PORT"):
        check_ray_address(address)


def test_ray_address_that_answers_passes() -> None:
    """The check refuses only what does not answer: a listening loopback port passes."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        check_ray_address(f"127.0.0.1:{port}")
        check_ray_address(f"ray://127.0.0.1:{port}")
    check_ray_address("local")  # starts a new instance: nothing to reach


# -- the suite file -----------------------------------------------------------------------------

@pytest.mark.parametrize("old, new, needles", [
    ("train_steps = 60", 'train_steps = "60"',
     ["field 'rl.train_steps'", "got the string '60'", "unquoted"]),
    ("train_steps = 60", f"train_steps = {2**63 - 1}",
     ["field 'rl.train_steps'", "less than or equal to 1000000000"]),
    ("seeds = [0]", "seeds = [0, 0]", ["field 'seeds'", "listed more than once: [0]"]),
    ("seeds = [0]", "seeds = [-1]", ["field 'seeds.0'", "greater than or equal to 0"]),
])
def test_suite_values_refused_on_load(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                      old: str, new: str, needles: list[str],
                                      no_stage_runs: None) -> None:
    """Before: accepted ("60" became 60, seeds ran twice, -1 failed at the RL stage, 2**63-1
    steps was planned)."""
    path = tmp_path / "bad.toml"
    assert old in TOY
    path.write_text(TOY.replace(old, new, 1))
    with pytest.raises(ConfigError) as info:
        load_suite(path)
    for needle in needles:
        assert needle in str(info.value)
    err = _cli(capsys, "run", "--suite", str(path), "--store", str(tmp_path / "s"))
    assert str(path) in err and all(n in err for n in needles)
    assert not (tmp_path / "s" / "dataset").exists()


def test_builtin_suites_still_load_strictly() -> None:
    for name in ("smoke", "quick", "paper"):
        assert load_suite(name).rl.train_steps <= 10**9


def test_suite_file_that_is_not_utf8(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Before: a UnicodeDecodeError traceback."""
    path = tmp_path / "latin1.toml"
    path.write_bytes(TOY.replace('name = "toybad"', 'name = "café"').encode("latin-1"))
    err = _cli(capsys, "run", "--suite", str(path), "--store", str(tmp_path / "s"))
    assert f"suite file {path} is not UTF-8 text (byte 0xe9 on line 2); save it as UTF-8" in err


# -- --store and --out --------------------------------------------------------------------------

def test_empty_store_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                toy_suite: Path, no_stage_runs: None,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: --store '' made the current folder the store."""
    monkeypatch.chdir(tmp_path)
    err = _cli(capsys, "run", "--suite", str(toy_suite), "--store", "")
    assert "--store is empty; pass the store folder" in err
    assert not (tmp_path / ".tmp").exists()
    with pytest.raises(StoreError, match="--store is empty"):
        Store("")


def _out_cases(tmp_path: Path, unwritable: Path) -> dict[str, tuple[str, str]]:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    return {"file": (str(a_file), f"--out {a_file} is a file, not a folder"),
            "below a file": (str(a_file / "lb"), f"{a_file} is a file, so the folder cannot"),
            "unwritable": (str(unwritable / "lb"), f"cannot write in {unwritable}"),
            "empty": ("", "--out is empty")}


@pytest.mark.parametrize("case", ["file", "below a file", "unwritable", "empty"])
def test_run_checks_out_before_any_stage(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                         toy_suite: Path, unwritable_dir: Path, case: str,
                                         no_stage_runs: None) -> None:
    """Before: every stage ran, then writing the leaderboard failed with a traceback."""
    out, needle = _out_cases(tmp_path, unwritable_dir)[case]
    err = _cli(capsys, "run", "--suite", str(toy_suite), "--store", str(tmp_path / "s"),
               "--out", out, "--workers", "1")
    assert needle in err
    assert not (tmp_path / "s" / "dataset").exists()


@pytest.mark.parametrize("case", ["file", "unwritable"])
def test_evaluate_checks_out_before_any_stage(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                              unwritable_dir: Path, case: str,
                                              no_stage_runs: None) -> None:
    out, needle = _out_cases(tmp_path, unwritable_dir)[case]
    err = _cli(capsys, "evaluate", "pca", "--suite", "smoke", "--metrics-only", "--reference",
               str(ROOT / "leaderboards" / "smoke" / "records"), "--store", str(tmp_path / "s"),
               "--out", out, "--workers", "1")
    assert needle in err


def test_leaderboard_checks_out(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Before: a FileExistsError traceback after the tables were computed."""
    out, needle = _out_cases(tmp_path, tmp_path)["file"]
    err = _cli(capsys, "leaderboard", "--suite", "smoke", "--records",
               str(ROOT / "leaderboards" / "smoke" / "records"), "--out", out)
    assert needle in err


# -- repbench task preview ----------------------------------------------------------------------

@pytest.mark.parametrize("args, needle", [
    (["--frames", "0"], "--frames must be a whole number >= 1, got 0"),
    (["--frames", "-2"], "--frames must be a whole number >= 1, got -2"),
    (["--seed", "-1"], "--seed must be a whole number >= 0, got -1"),
    (["--out", "{tmp}/p.xyz"], "unknown image format '.xyz'; use one of"),
    (["--out", "{tmp}"], "is a folder; pass a file name"),
    (["--out", "{unwritable}/p.png"], "cannot write in {unwritable}"),
])
def test_task_preview_bad_arguments(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                    unwritable_dir: Path, args: list[str], needle: str,
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: a ValueError / PermissionError traceback (the last two after the rollout)."""
    from repbench.testing.toy_task import ToyReachTask

    def no_rollout(*a: object, **k: object) -> None:
        raise AssertionError("the rollout started before the bad argument was noticed")

    monkeypatch.setattr(ToyReachTask, "collect", no_rollout)
    monkeypatch.chdir(tmp_path)
    fill = {"tmp": str(tmp_path), "unwritable": str(unwritable_dir)}
    err = _cli(capsys, "task", "preview", "ToyReach-v0",
               *[a.format(**fill) for a in args])
    assert needle.format(**fill) in err
    assert not list(tmp_path.glob("*.png"))


def test_task_preview_good_arguments_still_work(capsys: pytest.CaptureFixture[str],
                                                tmp_path: Path) -> None:
    out = tmp_path / "new" / "p.png"  # a missing folder is created
    with pytest.raises(SystemExit) as info:
        main(["task", "preview", "ToyReach-v0", "--frames", "2", "--seed", "3", "--out",
              str(out)])
    assert info.value.code == 0, capsys.readouterr().err
    assert out.stat().st_size > 1000


# -- task parameters ----------------------------------------------------------------------------

_PEG = """
tasks = ["PegInHole-v0"]
encoders = ["oracle"]
metrics = ["ksg"]
[dataset]
on_policy_episodes = 0
"""


@pytest.mark.parametrize("text, needles", [
    (TOY.replace("horizon = 20", "horizon = 0"),
     ["task_params.'ToyReach-v0'", "ToyReach-v0: horizon=0 must be a whole number >= 1"]),
    (TOY.replace("horizon = 20", "max_speed = -0.1"),
     ["ToyReach-v0: max_speed=-0.1 must be a number > 0"]),
    (_PEG + '[task_params."PegInHole-v0"]\nclearance = "wide"\n',
     ["task_params.'PegInHole-v0'", "PegInHole-v0: clearance='wide' must be a number"]),
    (_PEG + '[task_params."PegInHole-v0"]\ncamera = "false"\n',
     ["PegInHole-v0: camera='false' must be true or false"]),
])
def test_task_parameters_refused_before_any_stage(capsys: pytest.CaptureFixture[str],
                                                  tmp_path: Path, text: str,
                                                  needles: list[str], no_stage_runs: None
                                                  ) -> None:
    """Before: ToyReach accepted horizon = 0 (and ran), PegInHole's clearance = "wide" gave a
    numpy message without the field's name, camera = "false" turned the camera on."""
    path = tmp_path / "bad.toml"
    path.write_text(text)
    err = _cli(capsys, "run", "--suite", str(path), "--store", str(tmp_path / "s"))
    assert str(path) in err and all(n in err for n in needles), err
    assert not (tmp_path / "s" / "dataset").exists()


# -- metric parameters --------------------------------------------------------------------------

@pytest.mark.parametrize("section, needles", [
    ("[metric_params.regression]\ntest_fraction = 2.0",
     ["field metric_params.regression", "'test_fraction' must be in (0, 1)"]),
    ('[metric_params.mine]\nhidden = "big"',
     ["field metric_params.mine", "parameter 'hidden' must be a whole number, got 'big'"]),
    ('[metric_params.regression]\nhidden = [64, "wide"]',
     ["parameter 'hidden' must be a list of whole numbers, got [64, 'wide']"]),
    ("[metric_params.ksg]\nk = 0", ["field metric_params.ksg", "'k' must be >= 1, got 0"]),
    ("[metric_params.ksg]\nkk = 3",
     ["field metric_params.ksg", "unknown parameter(s) ['kk']; valid: ['k', 'n_bootstrap']"]),
])
def test_metric_parameters_refused_before_any_stage(capsys: pytest.CaptureFixture[str],
                                                    tmp_path: Path, section: str,
                                                    needles: list[str], no_stage_runs: None
                                                    ) -> None:
    """Before: checked only when the metric ran (after datasets, encoders and latents), and the
    unknown-parameter message offered z, z_true, episode and rng as valid parameters."""
    path = tmp_path / "bad.toml"
    text = TOY.replace('metrics = ["ksg", "regression"]', 'metrics = ["ksg", "regression", "mine"]')
    path.write_text(text + section + "\n")
    err = _cli(capsys, "run", "--suite", str(path), "--store", str(tmp_path / "s"))
    assert str(path) in err and all(n in err for n in needles), err
    for internal in ("'z'", "'z_true'", "'episode'", "'rng'", "'robot_state'"):
        assert internal not in err
    assert not (tmp_path / "s" / "dataset").exists()


def test_metric_parameters_fit_every_builtin_default() -> None:
    """The check refuses no default (it would refuse every suite)."""
    from repbench.registry import metrics

    for name in metrics.names():
        metric = metrics.get(name)
        defaults = {k: p.default for k, p in metric.parameters.items()}
        metric.check_params(defaults)
        assert not {"z", "z_true", "episode", "rng"} & set(metric.parameters), name


# -- what a user encoder returns ----------------------------------------------------------------

class Broken(repbench.Encoder):
    """A user encoder that breaks the contract as ``mode`` says (``"ok"``: it does not)."""

    required_modalities = ("proprio",)
    #: overrides ``mode`` after loading (to break the latents stage, not the encoder stage)
    force_mode: ClassVar[str | None] = None

    def __init__(self, mode: str = "ok") -> None:
        self.mode = mode

    def fit(self, dataset: repbench.Dataset) -> Any:
        self.width_ = 3
        return None if self.mode == "fit_none" else self

    def encode(self, observations: Any) -> Any:
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"][:, :3].astype(np.float32)
        mode = self.force_mode or self.mode
        return {"ok": p, "width": np.hstack([p, p]), "short": p[1:], "1d": p[:, 0],
                "strings": p.astype(str), "nan": np.where(p > 0, np.nan, p),
                "list": p.tolist(), "fit_none": p}[mode]

    @property
    def latent_dim(self) -> int:
        return self.width_


@pytest.fixture(scope="module")
def broken_plan(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict]]:
    """A store with the toy random dataset, and the encoder/latents stages of ``Broken`` in
    every mode."""
    from repbench.pipeline.plan import build_plan
    from repbench.pipeline.stages import execute
    from repbench.registry import encoders

    encoders.register("broken_test_encoder", Broken, replace=True)
    folder = tmp_path_factory.mktemp("broken")
    modes = ["ok", "width", "short", "1d", "strings", "nan", "list", "fit_none"]
    text = TOY.replace('encoders = ["oracle"]', 'encoders = ["broken_test_encoder"]')
    stages = {}
    for mode in modes:
        path = folder / f"{mode}.toml"
        path.write_text(text + f'[encoder_params.broken_test_encoder]\nmode = "{mode}"\n')
        tp = build_plan(load_suite(path)).tasks[0]
        stages[mode] = (tp.encoders["broken_test_encoder"], tp.latents["broken_test_encoder"])
    root = str(folder / "store")
    execute(tp.random_dataset, root)
    yield root, stages
    encoders.unregister("broken_test_encoder")


_BROKEN = {
    "width": r"encode returned shape \(8, 6\) for 8 observations, expected \(8, 3\) "
             r"\(latent_dim = 3\); encode must return a float32 array \[N, latent_dim\]",
    "short": r"encode returned shape \(7, 3\) for 8 observations, expected \(8, 3\)",
    "1d": r"encode returned shape \(8,\) for 8 observations, expected \(8, 3\)",
    "strings": r"encode returned <U\d+ values, not numbers; encode must return a float32",
    "nan": r"encode returned NaN or infinite values in \d+ of 8 rows; check the encoder",
    "list": r"encode must return a numpy array, got list",
    "fit_none": r"fit must return self, returned None; end fit with `return self`",
}


@pytest.mark.parametrize("mode", sorted(_BROKEN))
def test_broken_encoder_stops_at_the_encoder_stage(broken_plan: tuple[str, dict], mode: str
                                                   ) -> None:
    """Before: a wrong-width latent reached the metrics (only RL failed); short rows, 1-D
    arrays and strings failed in numpy; fit returning None gave "'NoneType' object has no
    attribute 'save'"."""
    from repbench.pipeline.stages import ENCODER, execute

    root, stages = broken_plan
    encoder_stage, _ = stages[mode]
    with pytest.raises(DataError, match="^encoder 'broken_test_encoder' \\(Broken\\): "
                       + _BROKEN[mode]) as info:
        execute(encoder_stage, root)
    assert "\n" not in str(info.value)
    assert Store(root).get(ENCODER, encoder_stage.key) is None  # nothing stored


@pytest.mark.parametrize("mode", ["width", "short", "1d", "strings", "nan"])
def test_broken_encoder_stops_at_the_latents_stage(broken_plan: tuple[str, dict], mode: str,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """An encoder that passed its own stage but encodes the metric data wrongly: no latents
    are stored, so no metric of them can be published."""
    from repbench.pipeline.stages import LATENTS, execute

    root, stages = broken_plan
    encoder_stage, latents_stage = stages["ok"]
    execute(encoder_stage, root)
    monkeypatch.setattr(Broken, "force_mode", mode)
    message = _BROKEN[mode].replace("8", "60").replace(r"\(7, 3\)", r"\(59, 3\)")
    with pytest.raises(DataError, match="^encoder 'broken_test_encoder' \\(Broken\\): "
                       + message):
        execute(latents_stage, root)
    assert Store(root).get(LATENTS, latents_stage.key) is None


def test_good_encoder_passes_both_stages(broken_plan: tuple[str, dict]) -> None:
    from repbench.pipeline.stages import LATENTS, execute

    root, stages = broken_plan
    for stage in stages["ok"]:
        execute(stage, root)
    art = Store(root).get(LATENTS, stages["ok"][1].key)
    assert art is not None
    with np.load(art.file("latents.npz")) as f:
        assert f["z"].shape == (60, 3) and f["z"].dtype == np.float32


# -- a full disk --------------------------------------------------------------------------------

def test_full_disk_stops_the_run_with_one_message(capsys: pytest.CaptureFixture[str],
                                                  tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: each stage failed in turn with OSError ENOSPC, then the run went on to the
    leaderboard. Now the first full-disk error stops it: one message, exit code 2."""
    import errno

    from repbench.pipeline.store import ArtifactWriter

    attempts: list[str] = []

    def full(self: ArtifactWriter, obj: object, name: str = "result.json") -> Path:
        attempts.append(str(self.path))
        raise OSError(errno.ENOSPC, "No space left on device", str(self.path / name))

    monkeypatch.setattr(ArtifactWriter, "write_json", full)
    path = tmp_path / "two_roots.toml"  # the random and the held-out dataset need no input
    path.write_text(TOY.replace("on_policy_episodes = 0", "on_policy_episodes = 0\n"
                                "heldout_episodes = 2"))
    store = tmp_path / "s"
    with pytest.raises(SystemExit) as info:
        main(["run", "--suite", str(path), "--store", str(store), "--out", str(tmp_path / "lb"),
              "--workers", "1"])
    err = capsys.readouterr().err
    assert info.value.code == 2, err
    assert "Traceback" not in err and err.count("repbench: error:") == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"repbench: error: no space left on the disk of store {store} while "
                           "writing stage 'ToyReach-v0 random data'; the run stopped"), last
    assert "run the same command again: finished stages are kept" in last
    assert len(attempts) == 1  # no second stage tried
    assert not (tmp_path / "lb").exists()  # no leaderboard of a half run
    assert not list((store / ".tmp").iterdir())  # the partial artifact was removed


def test_full_disk_in_a_worker_stops_run_stages(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Pool and Ray workers hand the error back as data (marked fatal); run_stages stops."""
    from repbench.errors import DiskFullError
    from repbench.pipeline.executors import _execute_catching, run_stages
    from repbench.pipeline.stages import DATASET, StageSpec

    class Failing:
        capacity = 2

        def __init__(self) -> None:
            self.submitted: list[str] = []
            self.closed = False

        def submit(self, spec: StageSpec) -> str:
            self.submitted.append(spec.label)
            return spec.label

        def wait_any(self, handles: list[str]) -> list[tuple[str, dict[str, object]]]:
            return [(h, {"error": f"no space left ({h})", "fatal": True}) for h in handles[:1]]

        def shutdown(self) -> None:
            self.closed = True

        def abort(self) -> None:  # run_stages stops its executor at once on a fatal error
            self.closed = True

    specs = [StageSpec(DATASET, {"n": i}, label=f"d{i}") for i in range(4)]
    ex = Failing()
    with pytest.raises(DiskFullError, match=r"no space left \(d0\)"):
        run_stages(specs, Store(tmp_path / "s"), ex, progress=False, echo=lambda _: None)
    assert ex.closed and ex.submitted == ["d0", "d1"]  # capacity 2: nothing after the error

    def full(*args: object) -> dict[str, object]:
        raise DiskFullError("no space left on the disk of store x")

    monkeypatch.setattr("repbench.pipeline.executors.execute", full)
    assert _execute_catching(specs[0], str(tmp_path)) == {
        "error": "no space left on the disk of store x", "fatal": True}


def test_only_a_full_disk_is_fatal() -> None:
    import errno

    from repbench.errors import DiskFullError
    from repbench.pipeline.diskfull import is_disk_full, stop_when_full

    # other write errors stay what they are
    with pytest.raises(PermissionError), stop_when_full("stage x", "store y"):
        raise PermissionError(errno.EACCES, "Permission denied")
    with pytest.raises(DiskFullError, match="while writing stage x"), \
            stop_when_full("stage x", "store y"):
        try:
            raise OSError(errno.ENOSPC, "No space left on device")
        except OSError as exc:
            raise RuntimeError("file write failed") from exc  # as a library wraps it
    assert not is_disk_full(ValueError("x"))
