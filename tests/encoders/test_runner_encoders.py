"""The encoder stage end to end on the toy task: early-stopping settings from the suite, the
history and loss figure in the artifact, the figure on the leaderboard page."""

from __future__ import annotations

import json
from pathlib import Path

from repbench.pipeline.plan import build_plan
from repbench.pipeline.runner import run_suite
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite

SUITE = """
name = "toy_encoders"
tasks = ["ToyReach-v0"]
encoders = ["vae_lowkl", "time_contrastive"]
metrics = ["ksg"]
agents = ["sac"]
seeds = [0]
[dataset]
random_episodes = 4
random_steps = 12
on_policy_episodes = 0
on_policy_steps = 12
[encoder_training]
latent_dim = 4
epochs = 3
patience = 1
validation_fraction = 0.5
batch_size = 16
[rl]
train_steps = 60
eval_episodes = 1
curve_points = 1
full_state_train_steps = 60
[metric_settings]
bootstrap = 20
[task_params."ToyReach-v0"]
horizon = 12
[agent_params.sac]
learning_starts = 30
batch_size = 16
"""


def test_encoder_stage_stores_curves_and_the_page_shows_them(tmp_path: Path) -> None:
    suite_file = tmp_path / "toy.toml"
    suite_file.write_text(SUITE)
    res = run_suite(suite_file, store=tmp_path / "store", out=tmp_path / "lb", workers=1,
                    progress=False)
    assert not res.report.failed, res.report.failed
    plan = build_plan(load_suite(suite_file))
    store = Store(tmp_path / "store")
    html = (tmp_path / "lb" / "index.html").read_text()
    for name, spec in plan.tasks[0].encoders.items():
        assert spec.config["params"]["patience"] == 1
        art = store.get(spec.kind, spec.key)
        info = art.read_json()
        history = json.loads(art.file("fit_history.json").read_text())
        assert info["epochs_run"] == len(history) <= 3
        assert info["heldout_loss"] == history[info["best_epoch"] - 1]["heldout"]["loss"]
        assert art.file("loss_curves.png").is_file()
        assert f"Training curves: {name}" in html
