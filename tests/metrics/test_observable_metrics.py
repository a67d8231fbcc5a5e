"""Known-answer tests of the observable metrics (repbench.metrics.observable).

Every case has its answer by construction: a spectrum set exactly (orthonormal columns scaled
and rotated), a linear system, a reward that telescopes to a known return-to-go.
"""

from __future__ import annotations

import numpy as np
import pytest

from repbench.errors import ConfigError, DataError
from repbench.metrics.observable import (
    alpha_req,
    covariance_spectrum,
    forward_r2,
    inverse_r2,
    nesum,
    rankme,
    rankme_of,
    return_to_go,
    reward_probe_gain,
    value_probe,
    value_probe_gain,
)
from repbench.registry import metrics

OBSERVABLE = ("rankme", "alpha_req", "nesum", "forward_r2", "inverse_r2", "value_probe",
              "value_probe_gain", "reward_probe_gain")
N_EP, STEPS = 40, 50


def _episodes(n_ep: int = N_EP, steps: int = STEPS) -> np.ndarray:
    return np.repeat(np.arange(n_ep), steps)


def _with_spectrum(lam: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    """[n, D] data whose sample covariance has exactly the eigenvalues ``lam``, randomly rotated."""
    rng = np.random.default_rng(seed)
    g = rng.standard_normal((n, lam.size))
    q, _ = np.linalg.qr(g - g.mean(0))  # orthonormal, centred columns
    rot, _ = np.linalg.qr(rng.standard_normal((lam.size, lam.size)))
    return (q * np.sqrt((n - 1) * lam)) @ rot.T + 3.0  # an offset: covariance ignores it


# --- registration ---------------------------------------------------------------------------

@pytest.mark.parametrize("name", OBSERVABLE)
def test_registered_as_observable(name: str) -> None:
    m = metrics.get(name)
    assert m.group == "observable" and m.higher_is_better
    assert "task_state" not in m.extra_inputs
    assert m.rows == ("on_policy" if name in ("value_probe", "value_probe_gain") else "all")


def test_preregistered_defaults() -> None:
    params = {n: {k: p.default for k, p in metrics.get(n).parameters.items()} for n in OBSERVABLE}
    assert params["rankme"]["eps"] == 1e-7
    for n in ("forward_r2", "inverse_r2", "value_probe", "value_probe_gain", "reward_probe_gain"):
        assert params[n]["test_fraction"] == 0.3
    assert params["value_probe"]["gamma"] == params["value_probe_gain"]["gamma"] == 0.99


# --- rankme ---------------------------------------------------------------------------------

def test_rankme_of_matches_its_formula() -> None:
    rng = np.random.default_rng(1)
    z = rng.standard_normal((300, 6)) * np.array([5, 3, 2, 1, 0.5, 0.1]) + 0.7
    s = np.linalg.svd(z, compute_uv=False)
    p = s / s.sum() + 1e-7
    assert rankme_of(z) == pytest.approx(float(np.exp(-(p * np.log(p)).sum())), rel=1e-9)


def test_rankme_isotropic_gaussian_is_its_dimension() -> None:
    ep = _episodes()
    z = np.random.default_rng(0).standard_normal((ep.size, 16))
    res = rankme(z, z, ep, 0, n_bootstrap=50)
    assert 15.9 < res.value <= 16.0
    assert res.ci_low <= res.value <= res.ci_high
    assert len(res.extras["bootstrap_replicates"]) == 50


@pytest.mark.parametrize("k", [1, 3, 7])
def test_rankme_of_rank_k_equal_singular_values_is_k(k: int) -> None:
    rng = np.random.default_rng(k)
    q, _ = np.linalg.qr(rng.standard_normal((500, k)))
    z = np.hstack([q * 4.0, np.zeros((500, 16 - k))]) @ np.linalg.qr(
        rng.standard_normal((16, 16)))[0]
    # k singular values equal, 16 − k zero: p = 1/k + ε (k times), ε (16 − k times)
    p = np.r_[np.full(k, 1.0 / k), np.zeros(16 - k)] + 1e-7
    value = rankme(z, z, _episodes(10, 50), 0, n_bootstrap=0).value
    assert value == pytest.approx(float(np.exp(-(p * np.log(p)).sum())), rel=1e-7)
    assert value == pytest.approx(k, abs=2e-4)  # the ε terms add ≈ k·(16 − k)·ε·ln(1/ε)


def test_rankme_uses_z_as_encoded_not_centred() -> None:
    z = np.zeros((200, 4))
    z[:, 0] = 5.0  # a constant direction is a singular value of the uncentred z
    z[:, 1] = np.random.default_rng(0).standard_normal(200)
    assert rankme(z, z, _episodes(10, 20), 0, n_bootstrap=0).value > 1.5


def test_rankme_of_zero_z_is_a_clear_error() -> None:
    ep = _episodes(10, 20)
    z = np.zeros((ep.size, 4))
    with pytest.raises(DataError, match="rankme: z is constant zero"):
        rankme(z, z, ep, 0)


def test_rankme_rejects_bad_eps() -> None:
    with pytest.raises(ConfigError, match="eps"):
        metrics.get("rankme").check_params({"eps": 0.0})


# --- alpha_req ------------------------------------------------------------------------------

@pytest.mark.parametrize("alpha", [0.5, 1.0, 2.0])
def test_alpha_req_power_law_spectrum(alpha: float) -> None:
    ep = _episodes()
    z = _with_spectrum(np.arange(1, 17, dtype=float) ** -alpha, ep.size)
    res = alpha_req(z, z, ep, 0, n_bootstrap=30)
    assert res.extras["alpha"] == pytest.approx(alpha, abs=1e-6)
    assert res.value == pytest.approx(-abs(alpha - 1.0), abs=1e-6)
    assert res.ci_low <= res.value <= res.ci_high


def test_alpha_req_drops_zero_eigenvalues() -> None:
    ep = _episodes()
    lam = np.r_[np.arange(1, 9, dtype=float) ** -1.0, np.zeros(8)]  # rank 8 in 16 dims
    z = _with_spectrum(lam, ep.size)
    res = alpha_req(z, z, ep, 0, n_bootstrap=0)
    assert res.extras["n_nonzero_eigenvalues"] == 8
    assert res.extras["alpha"] == pytest.approx(1.0, abs=1e-6)


def test_alpha_req_needs_two_directions() -> None:
    ep = _episodes(10, 20)
    z = np.outer(np.random.default_rng(0).standard_normal(ep.size), np.ones(4))  # rank 1
    with pytest.raises(DataError, match=r"alpha_req: .*at least 2"):
        alpha_req(z, z, ep, 0)


# --- nesum ----------------------------------------------------------------------------------

def test_nesum_identity_covariance_is_dimension() -> None:
    ep = _episodes()
    z = _with_spectrum(np.ones(16), ep.size)
    res = nesum(z, z, ep, 0, n_bootstrap=30)
    assert res.value == pytest.approx(16.0, rel=1e-9)
    assert res.ci_low <= res.value <= res.ci_high


def test_nesum_harmonic_spectrum() -> None:
    ep = _episodes()
    lam = 2.5 / np.arange(1, 17)  # Σ λ_i/λ_1 = the harmonic number H_16
    z = _with_spectrum(lam, ep.size)
    assert nesum(z, z, ep, 0, n_bootstrap=0).value == pytest.approx(
        float((1.0 / np.arange(1, 17)).sum()), rel=1e-9)


def test_nesum_constant_z_scores_zero() -> None:
    ep = _episodes(10, 20)
    z = np.ones((ep.size, 4))
    assert nesum(z, z, ep, 0, n_bootstrap=0).value == 0.0


def test_covariance_spectrum_is_sorted_and_positive() -> None:
    lam = covariance_spectrum(_with_spectrum(np.array([1.0, 4.0, 0.0, 2.0]), 400))
    assert lam == pytest.approx([4.0, 2.0, 1.0])


# --- forward_r2 and inverse_r2 -------------------------------------------------------------

def _linear_system(noise: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """z_{t+1} = A z_t + B a_t + noise, A stable, a_t ~ N(0, I); 8-D z, 3-D a."""
    rng = np.random.default_rng(seed)
    a_mat = 0.9 * np.linalg.qr(rng.standard_normal((8, 8)))[0]
    b_mat = rng.standard_normal((8, 3))
    z, a = np.zeros((N_EP * STEPS, 8)), rng.standard_normal((N_EP * STEPS, 3))
    for e in range(N_EP):
        zt = rng.standard_normal(8)
        for t in range(STEPS):
            i = e * STEPS + t
            z[i] = zt
            zt = a_mat @ zt + b_mat @ a[i] + noise * rng.standard_normal(8)
    return z, a, _episodes()


def test_forward_r2_linear_system_is_one() -> None:
    z, a, ep = _linear_system(noise=0.01)
    res = forward_r2(z, z, ep, 0, action=a, n_bootstrap=30)
    assert res.value > 0.999
    assert res.ci_low <= res.value <= res.ci_high
    assert res.extras["n_pairs"] == N_EP * (STEPS - 1)


def test_forward_r2_iid_noise_is_zero() -> None:
    ep = _episodes()
    rng = np.random.default_rng(3)
    z, a = rng.standard_normal((ep.size, 8)), rng.standard_normal((ep.size, 3))
    assert abs(forward_r2(z, z, ep, 0, action=a, n_bootstrap=0).value) <= 0.05


def test_forward_r2_pairs_do_not_straddle_episodes() -> None:
    # z_{t+1} = z_t + a_t inside episodes, a jump of 100 at every episode start: a pair across
    # an episode boundary would ruin the fit
    rng = np.random.default_rng(4)
    ep = _episodes()
    a = rng.standard_normal((ep.size, 4))
    z = np.zeros((ep.size, 4))
    for e in range(N_EP):
        rows = np.flatnonzero(ep == e)
        z[rows] = 100.0 * rng.standard_normal(4) + np.vstack(
            [np.zeros(4), np.cumsum(a[rows[:-1]], axis=0)])
    assert forward_r2(z, z, ep, 0, action=a, n_bootstrap=0).value > 0.999


def test_inverse_r2_action_is_the_step() -> None:
    rng = np.random.default_rng(5)
    ep = _episodes()
    a = rng.standard_normal((ep.size, 4))
    z = np.zeros((ep.size, 4))
    for e in range(N_EP):
        rows = np.flatnonzero(ep == e)
        z[rows] = rng.standard_normal(4) + np.vstack(
            [np.zeros(4), np.cumsum(a[rows[:-1]], axis=0)])  # a_t = z_{t+1} − z_t
    res = inverse_r2(z, z, ep, 0, action=a, n_bootstrap=30)
    assert res.value > 0.999
    assert res.ci_low <= res.value <= res.ci_high


def test_inverse_r2_unrelated_action_is_zero() -> None:
    z, _, ep = _linear_system(noise=0.01)
    a = np.random.default_rng(6).standard_normal((ep.size, 3))
    assert abs(inverse_r2(z, z, ep, 0, action=a, n_bootstrap=0).value) <= 0.05


# --- return-to-go and the value / reward probes ---------------------------------------------

def test_return_to_go_matches_a_loop() -> None:
    rng = np.random.default_rng(7)
    ep = np.repeat([3, 5, 9], [4, 1, 6])
    r = rng.standard_normal(ep.size)
    loop = [sum(0.99 ** (k - t) * r[k] for k in range(t, ep.size) if ep[k] == ep[t])
            for t in range(ep.size)]
    assert return_to_go(r, ep, 0.99) == pytest.approx(loop, abs=1e-12)


def _telescoping(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A latent s_t and a reward r_t = s_t − γ s_{t+1} (s = 0 after the last step): then the
    truncated return-to-go is exactly s_t. Returns (s [N, 1], reward [N], episode)."""
    rng = np.random.default_rng(seed)
    ep = _episodes()
    s = rng.standard_normal(ep.size)
    nxt = np.r_[s[1:], 0.0]
    nxt[np.r_[ep[1:] != ep[:-1], True]] = 0.0
    reward = s - 0.99 * nxt
    assert return_to_go(reward, ep, 0.99) == pytest.approx(s, abs=1e-9)
    return s[:, None], reward, ep


def test_value_probe_latent_that_sets_the_value_is_one() -> None:
    s, reward, ep = _telescoping()
    rng = np.random.default_rng(8)
    z = np.hstack([s, rng.standard_normal((ep.size, 7))]) @ np.linalg.qr(
        rng.standard_normal((8, 8)))[0]
    robot = rng.standard_normal((ep.size, 5))
    res = value_probe(z, z, ep, 0, robot_state=robot, reward=reward, n_bootstrap=30)
    assert res.value > 0.999
    assert res.ci_low <= res.value <= res.ci_high
    gain = value_probe_gain(z, z, ep, 0, robot_state=robot, reward=reward, n_bootstrap=30)
    assert gain.value > 0.99  # the robot state knows nothing of s
    assert gain.value == pytest.approx(res.value - res.extras["r2_robot_only"], abs=1e-12)


def test_value_probe_unrelated_latent_is_zero() -> None:
    _, reward, ep = _telescoping()
    rng = np.random.default_rng(9)
    z, robot = rng.standard_normal((ep.size, 16)), rng.standard_normal((ep.size, 5))
    assert abs(value_probe(z, z, ep, 0, robot_state=robot, reward=reward,
                           n_bootstrap=0).value) <= 0.05


def test_value_probe_gain_zero_when_z_adds_nothing_to_robot_state() -> None:
    s, reward, ep = _telescoping()
    rng = np.random.default_rng(10)
    robot = np.hstack([s, rng.standard_normal((ep.size, 4))])
    for z in (robot @ rng.standard_normal((5, 16)),  # a linear map of r
              rng.standard_normal((ep.size, 16))):  # noise
        res = value_probe_gain(z, z, ep, 0, robot_state=robot, reward=reward, n_bootstrap=30)
        assert abs(res.value) <= 0.02
        assert res.extras["r2_robot_only"] > 0.999
        assert res.ci_low <= res.value <= res.ci_high


def test_reward_probe_gain_known_answers() -> None:
    rng = np.random.default_rng(11)
    ep = _episodes()
    h, robot = rng.standard_normal((ep.size, 2)), rng.standard_normal((ep.size, 5))
    reward = h @ np.array([1.0, -2.0]) + robot[:, 0]
    z_h = np.hstack([h, rng.standard_normal((ep.size, 6))])  # z knows h, r does not
    res = reward_probe_gain(z_h, z_h, ep, 0, robot_state=robot, reward=reward, n_bootstrap=30)
    # R²(z ⊕ r) = 1, R²(r) = Var(r_0) / Var(reward) = 1/6
    assert res.value == pytest.approx(1.0 - 1.0 / 6.0, abs=0.03)
    assert res.ci_low <= res.value <= res.ci_high
    robot_h = np.hstack([robot, h])  # now the robot state knows h; z is a linear map of it
    z_r = robot_h @ rng.standard_normal((7, 16))
    assert abs(reward_probe_gain(z_r, z_r, ep, 0, robot_state=robot_h, reward=reward,
                                 n_bootstrap=0).value) <= 0.01


# --- what every observable metric shares ---------------------------------------------------

def _inputs() -> dict[str, np.ndarray]:
    s, reward, ep = _telescoping()
    rng = np.random.default_rng(12)
    z = np.hstack([s, rng.standard_normal((ep.size, 5))]).cumsum(0) / 10
    return {"z": z, "episode": ep, "reward": reward, "robot_state": rng.standard_normal(
        (ep.size, 3)), "action": rng.standard_normal((ep.size, 2))}


def _call(name: str, z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
          **arrays: np.ndarray) -> object:
    m = metrics.get(name)
    return m(z, z_true, episode, 0, n_bootstrap=10,
             **{k: v for k, v in arrays.items() if k in m.extra_inputs})


@pytest.mark.parametrize("name", OBSERVABLE)
def test_ignores_z_true_and_is_reproducible(name: str) -> None:
    d = _inputs()
    z, ep = d.pop("z"), d.pop("episode")
    a = _call(name, z, z, ep, **d)
    b = _call(name, z, np.random.default_rng(0).standard_normal((ep.size, 3)), ep, **d)
    assert (a.value, a.ci_low, a.ci_high) == (b.value, b.ci_low, b.ci_high)
    assert np.isfinite(a.value) and a.ci_low <= a.value <= a.ci_high
    assert a.extras["bootstrap_replicates"]
    none = metrics.get(name)(z, z, ep, 0, n_bootstrap=0,
                             **{k: v for k, v in d.items() if k in metrics.get(name).extra_inputs})
    assert none.ci_low is None and none.ci_high is None and none.value == a.value


PROBES = ("forward_r2", "inverse_r2", "value_probe", "value_probe_gain", "reward_probe_gain")


@pytest.mark.parametrize("name", PROBES)
def test_probes_need_two_episodes(name: str) -> None:
    d = _inputs()
    z, _ = d.pop("z"), d.pop("episode")
    with pytest.raises(DataError, match="at least 2 episodes") as info:
        _call(name, z, z, np.zeros(len(z), dtype=int), **d)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(("name", "missing"), [
    ("forward_r2", "action"), ("inverse_r2", "action"), ("value_probe", "reward"),
    ("value_probe_gain", "reward"), ("reward_probe_gain", "reward"),
    ("value_probe", "robot_state"), ("reward_probe_gain", "robot_state")])
def test_missing_array_is_a_one_line_error(name: str, missing: str) -> None:
    d = _inputs()
    z, ep = d.pop("z"), d.pop("episode")
    d.pop(missing)
    with pytest.raises(DataError, match=f"{name}: needs {missing}=") as info:
        _call(name, z, z, ep, **d)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name", ["value_probe", "value_probe_gain", "reward_probe_gain"])
def test_bad_reward_is_a_one_line_error(name: str) -> None:
    d = _inputs()
    z, ep = d.pop("z"), d.pop("episode")
    with pytest.raises(DataError, match="one number per row"):
        _call(name, z, z, ep, **{**d, "reward": np.ones((len(z), 2))})
    with pytest.raises(DataError, match="constant"):
        _call(name, z, z, ep, **{**d, "reward": np.zeros(len(z))})


def test_no_successive_steps_is_an_error() -> None:
    ep = np.arange(40)  # every episode one row long
    z = np.random.default_rng(0).standard_normal((40, 3))
    with pytest.raises(DataError, match="forward_r2: needs successive steps"):
        forward_r2(z, z, ep, 0, action=z)


@pytest.mark.parametrize("name", PROBES)
def test_probe_parameter_checks(name: str) -> None:
    with pytest.raises(ConfigError, match="test_fraction"):
        metrics.get(name).check_params({"test_fraction": 1.5})
