"""Joint-embedding encoders (the zoo): each loss against a loop-by-loop transcription of its
paper's formula and its known answers, the momentum target, training, bad parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import repbench
from repbench.dataset import Dataset
from repbench.errors import ConfigError
from repbench_encoders.joint_embedding import (
    JointEmbeddingEncoder,
    barlow_twins_loss,
    byol_loss,
    dino_loss,
    nt_xent,
    vicreg_loss,
)

FAST = {"batch_size": 16, "progress": False}


def _randn(*shape: int, seed: int = 0) -> torch.Tensor:
    return torch.randn(*shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


# -- the losses against direct transcriptions ----------------------------------------------------
def _nt_xent_loops(z1: torch.Tensor, z2: torch.Tensor, tau: float) -> float:
    """SimCLR's eq. (1), ℓ(i, j) = −log exp(sim(z_i, z_j)/τ) / Σ_{k≠i} exp(sim(z_i, z_k)/τ),
    averaged over the 2N (i, j) orderings."""
    z = torch.cat([z1, z2])
    n = z1.shape[0]
    total = 0.0
    for i in range(2 * n):
        j = (i + n) % (2 * n)
        sims = [float(torch.dot(z[i], z[k]) / (z[i].norm() * z[k].norm())) / tau
                for k in range(2 * n)]
        denominator = sum(math.exp(s) for k, s in enumerate(sims) if k != i)
        total += -(sims[j] - math.log(denominator))
    return total / (2 * n)


def test_nt_xent_matches_the_formula_and_its_bounds() -> None:
    z1, z2 = _randn(6, 5, seed=1), _randn(6, 5, seed=2)
    assert float(nt_xent(z1, z2, 0.5)) == pytest.approx(_nt_xent_loops(z1, z2, 0.5), rel=1e-9)
    # every view identical: all 2N − 1 candidates tie, the loss is ln(2N − 1)
    same = torch.ones(8, 3, dtype=torch.float64)
    assert float(nt_xent(same, same, 0.1)) == pytest.approx(math.log(15), rel=1e-9)
    # partners equal and orthogonal to the rest, a sharp temperature: the loss goes to 0
    eye = torch.eye(8, dtype=torch.float64)
    assert float(nt_xent(eye, eye.clone(), 0.01)) < 1e-6


def test_byol_loss_known_answers() -> None:
    z = _randn(10, 4, seed=3)
    assert float(byol_loss(z, 3.0 * z)) == pytest.approx(0.0, abs=1e-12)  # scale-free
    assert float(byol_loss(z, -z)) == pytest.approx(4.0, rel=1e-12)
    p = _randn(10, 4, seed=4).requires_grad_()
    t = _randn(10, 4, seed=5).requires_grad_()
    byol_loss(p, t).backward()
    assert p.grad is not None and t.grad is None  # the target carries no gradient


def test_dino_loss_is_the_cross_entropy_of_the_sharpened_centred_teacher() -> None:
    s, t = _randn(7, 9, seed=6), _randn(7, 9, seed=7)
    center = _randn(9, seed=8) * 0.1
    expected = 0.0
    for b in range(7):
        pt = torch.softmax((t[b] - center) / 0.04, 0)
        expected += -float((pt * torch.log_softmax(s[b] / 0.1, 0)).sum())
    assert float(dino_loss(s, t, center, 0.1, 0.04)) == pytest.approx(expected / 7, rel=1e-9)
    # a uniform teacher: the loss is ln K when the student is uniform too
    flat = torch.zeros(3, 9, dtype=torch.float64)
    assert float(dino_loss(flat, flat, torch.zeros(9, dtype=torch.float64), 0.1, 0.04)) == \
        pytest.approx(math.log(9), rel=1e-12)


def test_vicreg_terms_match_the_paper() -> None:
    z1, z2 = _randn(50, 4, seed=9) * 0.5, _randn(50, 4, seed=10) * 2.0
    terms = vicreg_loss(z1, z2)
    assert float(terms["invariance"]) == pytest.approx(float(((z1 - z2) ** 2).mean()), rel=1e-12)
    variance = covariance = 0.0
    for z in (z1, z2):
        x = z.numpy()
        std = np.sqrt(x.var(0, ddof=1) + 1e-4)
        variance += np.maximum(0.0, 1 - std).mean() / 2
        cov = np.cov(x, rowvar=False)
        covariance += (cov ** 2).sum() - (np.diag(cov) ** 2).sum()
    covariance /= 4
    assert float(terms["variance"]) == pytest.approx(variance, rel=1e-9)
    assert float(terms["covariance"]) == pytest.approx(covariance, rel=1e-9)
    assert float(terms["loss"]) == pytest.approx(
        25 * float(terms["invariance"]) + 25 * variance + covariance, rel=1e-9)
    # a collapsed embedding: no spread, so the hinge is ~1 (σ = √1e-4), no covariance
    flat = torch.zeros(20, 4, dtype=torch.float64)
    collapsed = vicreg_loss(flat, flat)
    assert float(collapsed["variance"]) == pytest.approx(0.99, rel=1e-9)
    assert float(collapsed["covariance"]) == 0.0 and float(collapsed["invariance"]) == 0.0


def test_barlow_twins_is_zero_at_the_identity_and_counts_correlations() -> None:
    # whitened, identical views: centred orthogonal columns of norm √N, so C = I exactly
    centred = _randn(64, 4, seed=11)
    q, _ = torch.linalg.qr(centred - centred.mean(0))
    white = q * math.sqrt(64)
    assert float(barlow_twins_loss(white, white, 0.5)) == pytest.approx(0.0, abs=1e-8)
    # one view the negative of the other: every diagonal entry is −1, so (1 − (−1))² per dim
    z = _randn(200, 3, seed=12)
    assert float(barlow_twins_loss(z, -z, 0.0)) == pytest.approx(3 * 4.0, rel=1e-4)
    # loop transcription
    z1, z2 = _randn(30, 3, seed=13), _randn(30, 3, seed=14)
    a = (z1 - z1.mean(0)) / z1.std(0, unbiased=False)
    b = (z2 - z2.mean(0)) / z2.std(0, unbiased=False)
    expected = 0.0
    for i in range(3):
        for j in range(3):
            cij = float(sum(a[n, i] * b[n, j] for n in range(30)) / 30)
            expected += (1 - cij) ** 2 if i == j else 0.02 * cij ** 2
    assert float(barlow_twins_loss(z1, z2, 0.02, eps=0.0)) == pytest.approx(expected, rel=1e-9)


# -- the encoders ---------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "max_ratio"), [
    ("simclr", 0.75), ("byol", 0.3), ("dino", 0.9), ("vicreg", 0.92), ("barlow_twins", 0.75),
    ("spr", 0.5)])
def test_training_lowers_the_objective(name: str, max_ratio: float,
                                       small_dataset: Dataset) -> None:
    """Last over first epoch's objective, measured (one torch thread, 6 epochs, BatchNorm
    heads): simclr 2.21 -> 1.52 (0.68), byol 1.72 -> 0.37 (0.22), dino 3.58 -> 2.92 (0.82; ln 64
    = 4.16 is a uniform teacher, the collapse the LayerNorm heads fell into), vicreg 18.4 ->
    15.8 (0.86; its variance hinge floors it on 16-row batches), barlow_twins 24.3 -> 15.7
    (0.65), spr 1.76 -> 0.74 (0.42). An objective that does not train stays near 1."""
    enc = repbench.encoders.get(name)(epochs=6, **FAST).fit(small_dataset)
    curve = [h["train"]["objective"] for h in enc.history_]
    assert curve[-1] < max_ratio * curve[0], curve
    if name == "dino":
        assert curve[-1] < math.log(64) - 0.5, curve
    # the latent did not collapse to a point
    assert enc.history_[-1]["train"]["embedding_std"] > 0.05


def test_the_momentum_target_follows_the_online_network(tiny_dataset: Dataset) -> None:
    enc = JointEmbeddingEncoder(method="byol", epochs=1, momentum=0.5, **FAST).fit(tiny_dataset)
    net = enc.net_
    online = torch.cat([p.flatten() for p in net.trunk.parameters()])
    target = torch.cat([p.flatten() for p in net.target["trunk"].parameters()])
    assert not torch.equal(online, target)  # it lags ...
    assert all(not p.requires_grad for p in net.target.parameters())
    before = target.clone()
    net.update_target(0.0)  # ... and momentum 0 copies the online weights
    after = torch.cat([p.flatten() for p in net.target["trunk"].parameters()])
    assert torch.equal(after, online) and not torch.equal(after, before)
    simclr = JointEmbeddingEncoder(method="simclr", epochs=1, **FAST).fit(tiny_dataset)
    assert simclr.net_.target is None


def test_the_trained_weights_survive_a_save_and_load(tiny_dataset: Dataset, tmp_path) -> None:
    enc = repbench.encoders.get("dino")(epochs=1, **FAST).fit(tiny_dataset)
    enc.save(tmp_path / "dino")
    back = repbench.Encoder.load(tmp_path / "dino")
    obs = tiny_dataset.obs()
    np.testing.assert_array_equal(back.encode(obs), enc.encode(obs))


@pytest.mark.parametrize(("params", "message"), [
    ({"method": "mocov9"}, "method must be one of"),
    ({"temperature": 0.0}, "temperature must be > 0"),
    ({"momentum": 1.0}, r"momentum must be in \[0, 1\)"),
    ({"projector_dim": 1}, "projector_dim must be an integer >= 2"),
    ({"off_diagonal_weight": -1.0}, "off_diagonal_weight must be a finite number >= 0"),
])
def test_bad_parameters_are_one_line_errors(params: dict, message: str,
                                            tiny_dataset: Dataset) -> None:
    with pytest.raises(ConfigError, match=message):
        JointEmbeddingEncoder(**params, **FAST).fit(tiny_dataset)


def test_an_epochs_last_batch_of_one_row_trains(tiny_dataset: Dataset) -> None:
    """BatchNorm heads need two rows; 24 rows in batches of 23 leave one."""
    enc = JointEmbeddingEncoder(method="byol", epochs=1, batch_size=23,
                                progress=False).fit(tiny_dataset)
    assert np.isfinite(enc.history_[0]["train"]["objective"])
