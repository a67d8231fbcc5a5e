"""Suite files: built-ins load, bad files give errors naming the file and the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from repbench.errors import ConfigError
from repbench.pipeline.suite import BUILTIN_SUITES, load_suite

_VALID = """
name = "mine"
tasks = ["PegInHole-v0"]
encoders = ["oracle", "random"]
metrics = ["ksg"]
agents = ["sac"]
seeds = [0]
[dataset]
random_episodes = 2
random_steps = 10
on_policy_episodes = 0
on_policy_steps = 10
[encoder_training]
epochs = 1
[rl]
train_steps = 100
eval_episodes = 1
full_state_train_steps = 100
"""


@pytest.mark.parametrize("name", BUILTIN_SUITES)
def test_builtin_suites_load_and_name_registered_plugins(name: str) -> None:
    suite = load_suite(name)
    assert suite.name == name
    suite.check_plugins()


def test_paper_suite_carries_the_papers_numbers() -> None:
    s = load_suite("paper")
    assert s.dataset.random_episodes * s.dataset.random_steps == 7500
    assert s.encoder_training.latent_dim == 16
    assert s.rl.train_steps == 150_000 and len(s.seeds) == 10
    assert s.metric_params["mine"] == {"hidden": 64, "learning_rate": 5e-5, "batch_size": 128,
                                       "ema_decay": 0.001}
    sac, ddpg = s.agent_params["sac"], s.agent_params["ddpg"]
    assert sac["buffer_size"] == 3_000_000 and sac["batch_size"] == 256 and sac["tau"] == 0.005
    assert ddpg["action_noise"] == 0.25 and len(s.encoders) == 15  # the 14 + oracle_task


def test_user_suite_file(tmp_path: Path) -> None:
    p = tmp_path / "mine.toml"
    p.write_text(_VALID)
    s = load_suite(p)
    assert s.encoders == ["oracle", "random"] and s.source == str(p)


@pytest.mark.parametrize("change, field", [
    (("random_steps = 10", "random_stpes = 10"), "dataset.random_stpes"),  # misspelled key
    (("epochs = 1", 'epochs = "many"'), "encoder_training.epochs"),  # wrong type
    (("random_episodes = 2", "random_episodes = -3"), "dataset.random_episodes"),  # negative
    (('seeds = [0]', 'seeds = []'), "seeds"),
    (("[encoder_training]", '[task_dataset."PegInHole-v0"]\non_policy_stpes = 5\n'
      "[encoder_training]"), "task_dataset.PegInHole-v0.on_policy_stpes"),
    (("[encoder_training]", '[task_dataset."PegInHole-v0"]\non_policy_steps = 0\n'
      "[encoder_training]"), "task_dataset.PegInHole-v0.on_policy_steps"),
    (("[encoder_training]", '[task_rl."PegInHole-v0"]\ntrain_stpes = 5\n[encoder_training]'),
     "task_rl.PegInHole-v0.train_stpes"),
])
def test_bad_suite_names_file_and_field(tmp_path: Path, change: tuple[str, str],
                                        field: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(_VALID.replace(*change))
    with pytest.raises(ConfigError) as info:
        load_suite(p)
    msg = str(info.value)
    assert str(p) in msg and f"field '{field}'" in msg
    assert "\n" not in msg


def test_missing_suite_file() -> None:
    with pytest.raises(ConfigError, match="neither a built-in suite"):
        load_suite("no/such/suite.toml")


def test_unknown_plugin_in_suite(tmp_path: Path) -> None:
    p = tmp_path / "typo.toml"
    p.write_text(_VALID.replace('"random"]', '"vea"]'))
    with pytest.raises(ConfigError, match="unknown encoder 'vea'; did you mean 'vae'"):
        load_suite(p).check_plugins()


def test_not_toml(tmp_path: Path) -> None:
    p = tmp_path / "broken.toml"
    p.write_text("tasks = [")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_suite(p)


def test_task_dataset_and_task_rl_override_for_that_task_only(tmp_path: Path) -> None:
    from repbench.pipeline.plan import build_plan

    p = tmp_path / "two.toml"
    p.write_text(_VALID.replace('tasks = ["PegInHole-v0"]',
                                'tasks = ["PegInHole-v0", "ToyReach-v0"]')
                 .replace("[encoder_training]",
                          '[task_dataset."ToyReach-v0"]\nrandom_steps = 7\n'
                          '[task_rl."ToyReach-v0"]\ntrain_steps = 3000\n[encoder_training]')
                 .replace("train_steps = 100\n", "train_steps = 2000\n"))
    s = load_suite(p)
    assert s.dataset_for("ToyReach-v0").random_steps == 7
    assert s.dataset_for("PegInHole-v0") == s.dataset and s.rl_for("PegInHole-v0") == s.rl
    assert s.rl_for("ToyReach-v0").train_steps == 3000
    assert s.rl_for("ToyReach-v0").eval_episodes == s.rl.eval_episodes
    stages = build_plan(s).stages()
    steps = {st.config["task"]: st.config["steps_per_episode"] for st in stages
             if st.kind == "dataset" and st.config.get("kind") == "random"}
    assert steps == {"PegInHole-v0": 10, "ToyReach-v0": 7}
    budgets = {st.config["task"]: st.config["train_steps"] for st in stages if st.kind == "rl"}
    assert budgets == {"PegInHole-v0": 2000, "ToyReach-v0": 3000}
    with pytest.raises(ConfigError, match="'task_dataset': 'Nope-v0' is not in tasks"):
        bad = tmp_path / "bad.toml"
        bad.write_text(_VALID.replace("[encoder_training]", '[task_dataset."Nope-v0"]\n'
                                      "random_steps = 7\n[encoder_training]"))
        load_suite(bad).check_plugins()
