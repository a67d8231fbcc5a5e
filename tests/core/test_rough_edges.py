"""What a new user hits first: each mistake is one line on stderr with exit code 2."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from repbench.errors import ConfigError
from repbench.pipeline.plan import build_plan
from repbench.pipeline.runner import plan_identities
from repbench.pipeline.suite import load_suite

ROOT = Path(__file__).resolve().parents[2]

_SUITE = """
tasks = ["PegInHole-v0"]
encoders = ["oracle", "pca", "vae"]
metrics = ["ksg"]
agents = ["sac"]
[dataset]
random_episodes = 2
"""


def _repbench(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "repbench.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


def _one_line_exit_2(out: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert out.returncode == 2, out.stdout + out.stderr
    assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    for needle in needles:
        assert needle in out.stderr, out.stderr


def test_leaderboard_on_an_empty_store(tmp_path: Path) -> None:
    out = _repbench("leaderboard", "--suite", "smoke", "--store", str(tmp_path / "empty"),
                    "--out", str(tmp_path / "lb"))
    _one_line_exit_2(out, "no results of suite 'smoke'", "repbench run --suite smoke")
    assert not (tmp_path / "lb" / "encoders.csv").exists()


def test_evaluate_unknown_encoder(tmp_path: Path) -> None:
    out = _repbench("evaluate", "vea", "--suite", "smoke", "--store", str(tmp_path / "s"))
    _one_line_exit_2(out, "unknown encoder 'vea'; did you mean 'vae'")


def test_workers_below_one(tmp_path: Path) -> None:
    out = _repbench("run", "--suite", "smoke", "--workers", "0", "--store", str(tmp_path / "s"))
    _one_line_exit_2(out, "--workers must be at least 1, got 0")
    assert not (tmp_path / "s" / "dataset").exists()


@pytest.mark.parametrize("section, needle", [
    ('[task_params."PegInHole-v0"]\nclearance = -1', "task_params.'PegInHole-v0'"),
    ("[encoder_params.vae]\nepochs = -1", "encoder_params.vae"),
    ("[encoder_params.pca]\nlatent_dim = 0", "encoder_params.pca"),
    ("[agent_params.sac]\ntau = 2.0", "agent_params.sac"),
    ("[agent_params.sac]\nlearning_starts = 100000", "agent_params.sac"),
])
def test_plugin_parameters_fail_at_plan_time(tmp_path: Path, section: str, needle: str) -> None:
    suite = tmp_path / "bad.toml"
    suite.write_text(_SUITE + section + "\n")
    with pytest.raises(ConfigError, match=re.escape(needle)) as info:
        build_plan(load_suite(suite))
    assert str(suite) in str(info.value) and "\n" not in str(info.value)


def test_bad_task_parameter_on_the_command_line_runs_nothing(tmp_path: Path) -> None:
    suite = tmp_path / "bad.toml"
    suite.write_text(_SUITE + '[task_params."PegInHole-v0"]\nclearance = -1\n')
    out = _repbench("run", "--suite", str(suite), "--store", str(tmp_path / "s"))
    _one_line_exit_2(out, "task_params.'PegInHole-v0'", "clearance")
    assert not (tmp_path / "s" / "dataset").exists()


def test_a_user_suite_can_be_a_few_lines(tmp_path: Path) -> None:
    suite = tmp_path / "few.toml"
    suite.write_text(_SUITE)
    s = load_suite(suite)
    quick = load_suite("quick")
    assert s.name == "few" and s.dataset.random_episodes == 2
    assert s.dataset.random_steps == quick.dataset.random_steps  # documented defaults
    # quick pins its privileged agent to SB3 (its SAC runs on SBX); the rest are the defaults
    assert quick.rl.privileged_params == {"backend": "sb3"} and s.rl.privileged_params == {}
    assert s.rl.model_copy(update={"privileged_params": {"backend": "sb3"}}) == quick.rl
    assert s.encoder_training == quick.encoder_training
    assert s.seeds == quick.seeds
    build_plan(s)


def test_readme_installs_what_ci_installs_for_the_browser_test() -> None:
    readme = (ROOT / "README.md").read_text()
    block = next(b for b in re.findall(r"```bash\n(.*?)\n```", readme, re.S) if "pytest" in b)
    apt = next(line for line in block.splitlines() if "apt-get install" in line)
    ci = (ROOT / ".ci" / "run").read_text()
    ci_packages = set(re.search(r"apt-get install -y -qq \\\n\s*(.*?) >", ci, re.S)
                      .group(1).split())
    assert "chromium" in apt.split() and ci_packages <= set(apt.split())


def test_gym_ids_registered_on_import_repbench() -> None:
    code = textwrap.dedent("""
        import sys
        import gymnasium, repbench
        assert "robosuite" not in sys.modules and "repbench_tasks.peg_in_hole" not in sys.modules
        print(sorted(i for i in gymnasium.registry if i.startswith("repbench/")))
        env = gymnasium.make("repbench/ToyReach-v0", horizon=5)
        obs, info = env.reset(seed=0)
        print(sorted(obs), "true_state" in info)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    ids, obs = out.stdout.splitlines()
    assert "'repbench/PegInHole-v0'" in ids and "'repbench/ToyReach-v0'" in ids
    assert obs == "['ft', 'image', 'last_action', 'proprio'] True"
    readme = (ROOT / "README.md").read_text()
    assert 'gymnasium.make("repbench/PegInHole-v0"' in readme


def test_a_suite_on_fewer_of_its_tasks_is_a_valid_suite() -> None:
    """``evaluate --task PegInHole-v0`` on two-task quick: the copy drops the other task's
    per-task tables (a bare ``tasks`` update fails validation) and plans exactly quick's
    peg-in-hole stages."""
    quick = load_suite("quick")
    assert quick.tasks == ["PegInHole-v0", "SurfacePress-v0", "Door-v0"]
    with pytest.raises(ConfigError, match=r"'SurfacePress-v0' is not in tasks"):
        build_plan(quick.model_copy(update={"tasks": ["PegInHole-v0"]}))
    peg = quick.only_tasks(["PegInHole-v0"])
    assert peg.tasks == ["PegInHole-v0"] and "SurfacePress-v0" not in peg.task_rl
    assert "Door-v0" not in peg.task_rl
    assert peg.rl_for("PegInHole-v0") == quick.rl_for("PegInHole-v0")
    mine = plan_identities(peg)
    assert mine and mine < plan_identities(quick)
    others = quick.only_tasks(["SurfacePress-v0", "Door-v0"])
    assert plan_identities(others) == plan_identities(quick) - mine


@pytest.mark.parametrize(("task", "folder"), [("SurfacePress-v0", "surface_press"),
                                              ("Door-v0", "door")])
def test_quick_on_a_contact_rich_task_runs_the_stages_of_its_committed_suite(
        task: str, folder: str) -> None:
    """The records under ``leaderboards/quick/<task>/`` were made by that folder's
    ``suite_20k.toml``: its stages must be quick's stages on the task, so that the shipped
    records count as quick's and a run of quick reuses a store the task's suite filled. quick
    has more since the zoo joined it: exactly the zoo's stages on the task."""
    suite_file = ROOT / "leaderboards" / "quick" / folder / "suite_20k.toml"
    mine = plan_identities(load_suite("quick").only_tasks([task]))
    theirs = plan_identities(load_suite(suite_file))
    zoo = plan_identities(load_suite(ROOT / "leaderboards" / "quick" / "zoo" / "suite.toml")
                          .only_tasks([task]))
    assert theirs and theirs < mine and mine == theirs | zoo


def test_the_zoo_runs_quicks_stages_but_the_encoders() -> None:
    """The zoo (leaderboards/quick/zoo/suite.toml) is quick's settings on other encoders: its
    datasets, privileged agents and diagnostics are quick's own stages, so its encoders are
    scored on the reference's data and their records fold into quick's reference."""
    from repbench.pipeline.records import identity_key

    zoo = load_suite(ROOT / "leaderboards" / "quick" / "zoo" / "suite.toml")
    quick = load_suite("quick")
    assert {"mae", "vae_lowkl_ft_history", "r3m", "dino"} <= set(zoo.encoders)
    # since it was scored, the zoo is part of quick: every zoo stage is a stage of quick
    assert set(zoo.encoders) < set(quick.encoders)
    assert plan_identities(zoo) < plan_identities(quick)

    def shared(suite):
        return {identity_key(s.record) for s in build_plan(suite).stages()
                if s.record is not None and s.kind in ("dataset", "full_state_agent",
                                                       "diagnostics")}

    assert len(shared(zoo)) == 15 and shared(zoo) == shared(quick)
