"""MAP with a Gaussian prior (casep.estimators.map)."""

from __future__ import annotations

import numpy as np
import pytest

import casep


def test_infinite_prior_std_equals_ols(paper_problem, platform36):
    S, y, _ = paper_problem
    ols = casep.solve_ols(S, y)
    res = casep.solve_map(S, y, {n: {"mean": 1.0, "std": float("inf")} for n in platform36.names},
                          names=platform36.names)
    assert np.max(np.abs(res.estimate - ols.estimate) / ols.std) < 1e-6
    np.testing.assert_allclose(res.std, ols.std, rtol=1e-7)


def test_prior_only_equals_the_prior(paper_problem, platform36):
    S, y, _ = paper_problem
    mu = np.linspace(-1, 1, 36)
    tau = np.linspace(0.1, 2, 36)
    prior = {n: {"mean": m, "std": t} for n, m, t in zip(platform36.names, mu, tau)}
    # Zero data: every column is zero, so only the prior speaks.
    res = casep.solve_map(np.zeros_like(S), y, prior, sigma=0.1, names=platform36.names)
    np.testing.assert_allclose(res.estimate, mu, rtol=1e-12)
    np.testing.assert_allclose(res.std, tau, rtol=1e-12)
    # Data of negligible weight: the same. (S, y) / 1e6 with sigma 1e3 is the data with sigma 1e9
    # (sigma itself is capped at 1e3 m/s, OPTION_RANGES).
    res = casep.solve_map(S * 1e-6, y * 1e-6, prior, sigma=1e3, names=platform36.names)
    np.testing.assert_allclose(res.estimate, mu, rtol=1e-6, atol=1e-9)


@pytest.mark.montecarlo
def test_posterior_std_matches_monte_carlo(platform36, rng):
    """Truth drawn from the prior each run: z = (estimate - truth) / std has RMS near 1."""
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=0, rate=10.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    tau = np.abs(sim.truth) * 2 + 1e-3
    prior = {n: {"mean": 0.0, "std": t} for n, t in zip(platform36.names, tau)}
    z = []
    for _ in range(150):
        truth = tau * rng.standard_normal(36)
        y = S @ truth + 0.1 * rng.standard_normal((S.shape[0], 3))
        res = casep.solve_map(S, y, prior, sigma=0.1, names=platform36.names)
        z.append((res.estimate - truth) / res.std)
    z = np.array(z)
    pooled = np.sqrt(np.mean(z**2))
    assert 0.9 < pooled < 1.1, pooled
    assert np.all(np.sqrt(np.mean(z**2, axis=0)) < 1.35)


def test_aliased_phi0_becomes_determined_with_a_misalignment_prior(platform39, truth36):
    from casep.simulation.synthetic import excitation_force

    t = np.arange(0.0, 180.0, 0.1)
    S = casep.build_sv(platform39, t, excitation_force(t))
    D = np.concatenate([truth36, [30.0, -45.0, 15.0]])
    prior = {n: {"mean": D[platform39.index(n)], "std": 1.0}
             for n in ("Ka1xy", "Ka1yx", "Ka1zx", "Ka1xz", "Ka1yz", "Ka1zy")}
    res = casep.solve_map(S, S @ D, prior, sigma=1e-6, names=platform39.names)
    assert res.status == 1
    np.testing.assert_allclose(res.estimate[36:], D[36:], rtol=1e-3)


def test_prior_errors(paper_problem, platform36):
    S, y, _ = paper_problem
    nm = platform36.names
    with pytest.raises(ValueError, match="unknown coefficient `Kq`"):
        casep.solve_map(S, y, {"Kq": {"mean": 0, "std": 1}}, names=nm)
    with pytest.raises(ValueError, match="`Kg0x` std must be > 0"):
        casep.solve_map(S, y, {"Kg0x": {"mean": 0, "std": -1}}, names=nm)
    with pytest.raises(ValueError, match="must be \\{\"mean\": m, \"std\": s\\}"):
        casep.solve_map(S, y, {"Kg0x": [0, 1]}, names=nm)


# --- prior names and values ---------------------------------------------------------

def test_parse_prior_unknown_name_suggests(platform36):
    from casep.estimators.map import parse_prior

    with pytest.raises(ValueError, match=r"`prior`: unknown coefficient `KaOy` \(did you mean `Ka0y`\?\)"):
        parse_prior({"KaOy": {"mean": 0, "std": 1}}, platform36.names)


@pytest.mark.parametrize("spec, expect", [
    ({"mean": 0.0, "std": float("nan")}, "std must be > 0"),
    ({"mean": 0.0, "std": 0.0}, "std must be > 0"),
    ({"mean": 0.0, "std": -1.0}, "std must be > 0"),
    ({"mean": 0.0, "std": 1e-320}, "std must be > 0"),   # 1 / std overflows: no usable precision
    ({"mean": float("inf"), "std": 1.0}, "mean must be finite"),
    ({"mean": float("nan"), "std": 1.0}, "mean must be finite"),
])
def test_parse_prior_rejects_bad_values_naming_the_coefficient(platform36, spec, expect):
    from casep.estimators.map import parse_prior

    with pytest.raises(ValueError, match=f"`Kg0x` {expect}"):
        parse_prior({"Kg0x": spec}, platform36.names)


def test_parse_prior_infinite_std_is_flat(platform36):
    from casep.estimators.map import parse_prior

    mu, tau = parse_prior({"Kg0x": {"mean": 1.0, "std": float("inf")}}, platform36.names)
    assert np.isinf(tau).all()
