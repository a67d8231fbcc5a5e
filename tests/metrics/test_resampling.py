"""Episode resamples are paired across encoders: they depend on the metric's seed, not on how
much of its random stream the metric used before (that grows with the latent size)."""

from __future__ import annotations

import numpy as np

from repbench.metrics._common import episode_bootstrap_replicates, resampling_stream


def _episodes(n_episodes: int = 12, steps: int = 20) -> tuple[np.ndarray, np.ndarray]:
    episode = np.repeat(np.arange(n_episodes), steps)
    values = np.random.default_rng(3).normal(size=episode.size)
    return episode, values


def test_resamples_do_not_depend_on_draws_made_before() -> None:
    episode, values = _episodes()
    a, b = np.random.default_rng(7), np.random.default_rng(7)
    a.normal(size=16 * 123)  # e.g. jitter for a 16-D latent
    b.normal(size=64 * 123)  # and for a 64-D one
    ra = episode_bootstrap_replicates(lambda r: values[r].mean(), episode, a, 50)[2]
    rb = episode_bootstrap_replicates(lambda r: values[r].mean(), episode, b, 50)[2]
    assert ra == rb and len(ra) == 50


def test_resamples_follow_the_seed() -> None:
    episode, values = _episodes()
    r7 = episode_bootstrap_replicates(lambda r: values[r].mean(), episode,
                                      np.random.default_rng(7), 50)[2]
    r8 = episode_bootstrap_replicates(lambda r: values[r].mean(), episode,
                                      np.random.default_rng(8), 50)[2]
    assert r7 != r8


def test_resampling_stream_is_independent_of_its_parent() -> None:
    parent = np.random.default_rng(7)
    child = resampling_stream(np.random.default_rng(7))
    x, y = parent.normal(size=2000), child.normal(size=2000)
    assert abs(np.corrcoef(x, y)[0, 1]) < 0.1  # not the parent's stream replayed
    legacy = np.random.Generator(np.random.PCG64(7))  # its seed sequence is a SeedSequence too
    assert isinstance(resampling_stream(legacy), np.random.Generator)
