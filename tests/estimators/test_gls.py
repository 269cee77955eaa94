"""GLS for Gauss-Markov noise with REML tau (casep.estimators.gls)."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from conftest import dishonest_whitened, whitened_error

import casep
from casep.estimators.gls import estimate_tau


def test_known_tau_equals_dense_gls(rng):
    N, n, tau = 120, 4, 0.4
    t = np.cumsum(rng.uniform(0.05, 0.15, N))
    S = rng.standard_normal((N, 3, n))
    y = rng.standard_normal((N, 3))
    Si = np.linalg.inv(np.exp(-np.abs(t[:, None] - t[None, :]) / tau))  # Sigma / sigma^2 per axis
    F = sum(S[:, i].T @ Si @ S[:, i] for i in range(3))
    b = sum(S[:, i].T @ Si @ y[:, i] for i in range(3))
    x = np.linalg.solve(F, b)
    res = casep.solve_gls(S, y, t, tau=tau)
    np.testing.assert_allclose(res.estimate, x, rtol=1e-9)
    r = y - S @ x  # sigma^2 = r^T Sigma^-1 r / (m - n)
    s2 = sum(r[:, i] @ Si @ r[:, i] for i in range(3)) / (3 * N - n)
    np.testing.assert_allclose(res.covariance, s2 * np.linalg.inv(F), rtol=1e-8)
    np.testing.assert_allclose(res.residuals, r, atol=1e-12)


@pytest.mark.montecarlo
def test_reml_tau_and_honest_coverage(platform36):
    """paper-ar1 at 10 Hz, 8 seeded draws of Gauss-Markov noise (tau 1 s; reduced from 12,
    ``benchmarks/bench_gls_montecarlo.py`` runs more): REML's mean tau within 0.1 s of 1 s (its draw-to-draw
    std ~0.065 s: the mean's ~0.023 s, the bound 4.35 of it, false alarm 1.4e-5), the GLS error whitened by its
    stated covariance honest by :func:`conftest.dishonest_whitened` with ``rms=None`` and false alarm 1e-4 (288
    values: RMS in [0.835, 1.172] but with probability 0.5e-4, more than 4 of the 8 draws over their chi2 95 %
    point 1.5e-5), and OLS's white-noise covariance caught by the same check (RMS ~4.7, every draw over) and by its
    per-coefficient 95 % coverage (~0.25). On these draws GLS's RMS is 1.00 (12 draws: 1.01); its std 0.7x or 0.8x
    give 1.43 or 1.26, both fail."""
    from casep.simulation.noise import NoiseModel
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper-ar1", seed=0, rate=10.0)
    t = sim.flight.t
    S = casep.build_sv(platform36, t, sim.flight.f)
    clean = S @ sim.truth
    rng = np.random.default_rng(8)
    noise = NoiseModel("ar1", 0.1, tau=1.0)
    w: dict[str, list] = {"gls": [], "ols": []}
    taus, z_ols = [], []
    for _ in range(8):
        y = clean + noise.sample(t, rng)
        g = casep.solve_gls(S, y, t)
        taus.append(g.extras.tau)
        w["gls"].append(whitened_error(g.estimate - sim.truth, g.covariance))
        o = casep.solve_ols(S, y)
        w["ols"].append(whitened_error(o.estimate - sim.truth, o.covariance))
        z_ols.append((o.estimate - sim.truth) / o.std)
    assert abs(np.mean(taus) - 1.0) < 0.1
    bad = dishonest_whitened(w, rms=None, false_alarm=1e-4)
    assert list(bad) == ["ols"], bad  # white-noise std would mislead; the check sees it
    assert np.mean(np.abs(np.array(z_ols)) <= 1.96) < 0.6


def test_white_noise_gives_ols(paper_problem, platform36):
    S, y, _ = paper_problem
    t = np.arange(S.shape[0]) / 20.0
    assert estimate_tau(S, y, t) < 0.02  # the lower end: white in effect
    g = casep.solve_gls(S, y, t)
    o = casep.solve_ols(S, y)
    assert np.max(np.abs(g.estimate - o.estimate) / o.std) < 0.05
    np.testing.assert_allclose(g.std, o.std, rtol=0.05)


def test_separate_and_cli(tmp_path, capsys):
    from casep.cli import main

    assert main(["simulate", "--scenario", "paper-ar1", "--rate", "10", "-o", str(tmp_path / "f.csv")]) == 0
    out = tmp_path / "r.json"
    assert main(["separate", str(tmp_path / "f.csv"), "--method", "gls", "--json", str(out)]) == 0
    import json

    data = json.loads(out.read_text())
    assert data["method"] == "gls" and 0.7 < data["extras"]["tau"] < 1.4
    assert main(["separate", str(tmp_path / "f.csv"), "--method", "gls", "--tau", "2.5", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["settings"]["tau"] == 2.5


def test_bad_arguments(paper_problem):
    S, y, _ = paper_problem
    t = np.arange(S.shape[0]) / 20.0
    with pytest.raises(ValueError, match=r"option --tau \(`tau`\) must be finite and > 0"):
        casep.solve_gls(S, y, t, tau=-1.0)
    with pytest.raises(ValueError, match=r"option --tau \(`tau`\) must be a number > 0 or 'auto'"):
        casep.solve_gls(S, y, t, tau="ml")
    with pytest.raises(ValueError, match="`t` must have"):
        casep.solve_gls(S, y, t[:-1])


@functools.cache
def _paper_ar1_setup(rate):
    """paper-ar1's scenario, trajectory, S_V (read-only: shared by the tests of this process) and truth."""
    from casep.simulation.simulate import scenario_setup

    sc, traj, model, truth = scenario_setup("paper-ar1", rate)
    S = casep.build_sv(model, traj.t, traj.specific_force)
    S.setflags(write=False)
    return sc, traj, S, truth


def _paper_ar1_runs(k, seed=11, rate=10.0):
    sc, traj, S, truth = _paper_ar1_setup(rate)
    rng = np.random.default_rng(seed)
    Y = np.stack([S @ truth + sc.noise.sample(traj.t, rng) for _ in range(k)], axis=-1)
    return S, Y, traj.t


def test_batched_tau_matches_per_run_reml():
    """One REML lattice for 8 runs: tau within 2e-5 relative of a tight per-run search and 1e-3 of
    estimate_tau (whose search stops at 1e-4 in ln tau), with far fewer factorisations."""
    from unittest import mock

    from scipy.optimize import minimize_scalar

    from casep.estimators import gls

    S, Y, t = _paper_ar1_runs(8, rate=5.0)
    calls = []

    def counting(self, tau, share=0.0):
        calls.append(self.Y.shape[-1])
        return evaluate(self, tau, share)

    neg2, evaluate = gls._neg2_reml, gls._Reml.__call__
    with mock.patch.object(gls._Reml, "__call__", counting):
        taus = gls.estimate_tau_many(S, Y, t)
        n_batch = len(calls)
        per_run = [estimate_tau(S, Y[..., r], t) for r in range(Y.shape[-1])]
    assert n_batch < 0.5 * (len(calls) - n_batch)  # factorisations: shared lattice vs one search per run
    for r in range(Y.shape[-1]):
        tight = np.exp(minimize_scalar(lambda x, r=r: float(neg2(S, Y[..., r:r + 1], t, float(np.exp(x)))[0]),
                                       bounds=gls.tau_search_bounds(t), method="bounded", options={"xatol": 1e-10}).x)
        assert abs(taus[r] / tight - 1) < 2e-5, (r, taus[r], tight)
        assert abs(taus[r] / per_run[r] - 1) < 1e-3
    assert 0.7 < np.median(taus) < 1.4  # truth 1 s


def test_neg2_reml_columns_equal_single_runs():
    """Each column of the one-factorisation objective equals the objective of that run alone."""
    from casep.estimators.gls import _neg2_reml

    S, Y, t = _paper_ar1_runs(3, rate=5.0)
    many = _neg2_reml(S, Y, t, 0.8)
    one = [_neg2_reml(S, Y[..., r:r + 1], t, 0.8)[0] for r in range(3)]
    np.testing.assert_allclose(many, one, rtol=0, atol=1e-8)


def test_formed_objective_equals_the_qr_one_and_finds_the_same_noise():
    """_Reml (S factored once, a Gram matrix per evaluation) against _neg2_reml (a QR of the whole whitened
    matrix per evaluation): the same values to 1e-8 over the whole search box of (ln tau, white share), every
    run; and estimate_noise's (tau, white share) through either objective equal to 1e-7 relative, on
    Gauss-Markov data (share 0 kept) and on Gauss-Markov plus white data (the white part kept)."""
    from unittest import mock

    from casep.estimators import gls

    S, Y, t = _paper_ar1_runs(3, rate=5.0)
    reml = gls._Reml(S, Y, t)
    lo, hi = gls.tau_search_bounds(t)
    for x in np.linspace(lo, hi, 7):
        for w in (0.0, 1.0 / (1.0 + np.exp(12.0)), 0.1, 0.5, 1.0 / (1.0 + np.exp(-12.0))):
            np.testing.assert_allclose(reml(float(np.exp(x)), w), gls._neg2_reml(S, Y, t, float(np.exp(x)), w),
                                       rtol=0, atol=1e-8)
    rng = np.random.default_rng(5)
    y_white = Y[..., 0] + 0.1 * rng.standard_normal(Y[..., 0].shape)
    found = [gls.estimate_noise(S, y, t) for y in (Y[..., 0], y_white)]
    with mock.patch.object(gls._Reml, "__call__", lambda self, tau, share=0.0: gls._neg2_reml(self.S, self.Y, self.t,
                                                                                            tau, share)):
        reference = [gls.estimate_noise(S, y, t) for y in (Y[..., 0], y_white)]
    assert found[0][1] == reference[0][1] == 0.0 and found[1][1] > 0.1
    np.testing.assert_allclose(found, reference, rtol=1e-7, atol=0)


def test_rank_deficient_regression_uses_the_qr_objective():
    """A regression with two equal columns: the objective is _neg2_reml's own (its QR handles them); with a zero
    column, the formed one, equal to it."""
    from casep.estimators import gls

    S, Y, t = _paper_ar1_runs(1, rate=5.0)
    S2 = np.concatenate([S, S[:, :, :1]], axis=2)
    reml = gls._Reml(S2, Y, t)
    assert not reml.full
    np.testing.assert_array_equal(reml(0.8, 0.1), gls._neg2_reml(S2, Y, t, 0.8, 0.1))
    S0 = np.concatenate([S, np.zeros(S.shape[:2] + (1,))], axis=2)  # a zero column: dropped by both, p counts it
    reml = gls._Reml(S0, Y, t)
    assert reml.full
    for w in (0.0, 0.1):
        np.testing.assert_allclose(reml(0.8, w), gls._neg2_reml(S0, Y, t, 0.8, w), rtol=0, atol=1e-8)


def test_lattice_vertex_exact_for_polynomials():
    from casep.estimators.gls import _lattice_vertex

    u = np.arange(-3.0, 4.0)
    assert _lattice_vertex((u - 0.3) ** 2) == pytest.approx(0.3, abs=1e-12)  # parabola
    q = (u + 0.45) ** 2 + 0.05 * (u + 0.45) ** 4 + 1e-3 * u**6
    z = np.linspace(-1, 1, 200001)
    zq = z[np.argmin((z + 0.45) ** 2 + 0.05 * (z + 0.45) ** 4 + 1e-3 * z**6)]
    assert _lattice_vertex(q) == pytest.approx(zq, abs=1e-5)  # degree 6, exact through 7 points
    v = (u - 0.2) ** 2 + 0.1 * (u - 0.2) ** 3
    v[:2] = np.nan  # beyond an end of the interval: the cubic through the five left
    z3 = z[np.argmin((z - 0.2) ** 2 + 0.1 * (z - 0.2) ** 3)]
    assert _lattice_vertex(v) == pytest.approx(z3, abs=1e-5)
    v = (u + 1.0) ** 2
    v[:3] = np.nan  # the middle value is the interval's end
    assert _lattice_vertex(v) == 0.0
