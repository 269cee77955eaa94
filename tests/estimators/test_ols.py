"""Least squares on the scaled QR-reduced system (casep.estimators.ols, casep.regression.linalg)."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.simulation.synthetic import excitation_force, inject_errors


def test_noise_free_recovery_all_36(platform36, truth36, flight_tf):
    t, f = flight_tf
    S = casep.build_sv(platform36, t, f)
    res = casep.solve_ols(S, S @ truth36, names=platform36.names)
    assert res.status == 1 and res.rank == 36
    rel = np.abs(res.estimate - truth36) / np.abs(truth36)
    assert rel.max() <= 1e-6, dict(zip(platform36.names, rel))


def test_matches_independent_lstsq_and_covariance(rng):
    # Well-conditioned random problem: numpy's SVD lstsq and sigma^2 (S^T S)^-1.
    S = rng.standard_normal((300, 5)) * np.array([1e-3, 1.0, 1e4, 2.0, 5e-2])
    x = rng.standard_normal(5)
    y = S @ x + 0.1 * rng.standard_normal(300)
    res = casep.solve_ols(S, y)
    ref, rss, *_ = np.linalg.lstsq(S, y, rcond=None)
    # Column scales span 1e7: the unscaled reference itself is only good to ~1e-9.
    np.testing.assert_allclose(res.estimate, ref, rtol=1e-8)
    s2 = rss[0] / (300 - 5)
    np.testing.assert_allclose(res.sigma, np.sqrt(s2), rtol=1e-10)
    np.testing.assert_allclose(res.covariance, s2 * np.linalg.inv(S.T @ S), rtol=1e-8)
    np.testing.assert_allclose(res.residuals, y - S @ ref, atol=1e-9)  # |S_j| up to 1e4 * 17


def test_tsqr_blocks_equal_one_qr(rng):
    S = rng.standard_normal((1000, 6))
    y = rng.standard_normal(1000)
    a = casep.reduce_qr(S, y, block_rows=1000)
    b = casep.reduce_qr(S, y, block_rows=37)
    # R is unique up to row signs.
    sa, sb = np.sign(np.diag(a.R)), np.sign(np.diag(b.R))
    np.testing.assert_allclose(a.R * sa[:, None], b.R * sb[:, None], atol=1e-12)
    np.testing.assert_allclose(a.qty * sa, b.qty * sb, atol=1e-12)
    np.testing.assert_allclose(a.rho2, b.rho2, rtol=1e-10)


def test_zero_and_duplicate_columns_reported_others_estimated(rng):
    S = rng.standard_normal((400, 5))
    S[:, 1] = 0.0  # zero column
    S[:, 4] = 2.5 * S[:, 3]  # exact twin of column 3
    x = np.array([1.0, 7.0, -2.0, 0.5, 0.2])
    y = S @ x + 0.01 * rng.standard_normal(400)
    res = casep.solve_ols(S, y, names=["a", "b", "c", "d", "e"])
    assert res.status == 2 and res.success
    assert np.isnan(res.estimate[[1, 3, 4]]).all() and np.isnan(res.std[[1, 3, 4]]).all()
    assert "zero column" in res.reasons["b"]
    assert "exactly dependent on e" in res.reasons["d"] and "exactly dependent on d" in res.reasons["e"]
    # The identifiable ones equal OLS with the twin merged into one column.
    ref = np.linalg.lstsq(S[:, [0, 2, 3]], y, rcond=None)[0]
    np.testing.assert_allclose(res.estimate[[0, 2]], ref[:2], rtol=1e-10)
    rows = {r["name"]: r for r in res.coefficient_rows()}
    assert rows["b"]["estimate"] is None and rows["a"]["estimate"] is not None


def test_pitch_plane_flight_exactly_the_zero_columns(platform36, truth36):
    t = np.arange(0.0, 180.0, 0.05)
    f = excitation_force(t, cross_range=False)
    S = casep.build_sv(platform36, t, f)
    res = casep.solve_ols(S, S @ truth36, names=platform36.names)
    expected = {"Kg1xz", "Kg1yz", "Kg1z", "Kg2z", "Ka1xz", "Ka2xz", "Ka1yz", "Ka2yz",
                "Ka1z", "Ka2z", "Ka2zx", "Ka2zy"}
    assert set(res.diagnostics["unidentifiable"]) == expected
    assert all("zero column" in res.reasons[n] for n in expected)
    ok = res.identifiable
    np.testing.assert_allclose(res.estimate[ok], truth36[ok], rtol=1e-6)


@pytest.mark.montecarlo
def test_std_is_honest_monte_carlo(platform36, truth36, rng):
    """RMS of (estimate - truth) / std over seeded runs is near 1 for every coefficient."""
    t = np.arange(0.0, 60.0, 0.2)  # small flight: 300 samples
    f = excitation_force(t, duration=60.0)
    S = casep.build_sv(platform36, t, f)
    clean = S @ truth36
    runs = 200
    z = np.empty((runs, 36))
    for k in range(runs):
        res = casep.solve_ols(S, clean + 0.1 * rng.standard_normal(clean.shape))
        z[k] = (res.estimate - truth36) / res.std
    rms = np.sqrt(np.mean(z**2, axis=0))
    pooled = np.sqrt(np.mean(z**2))
    assert 0.85 <= pooled <= 1.15, pooled
    assert np.all((rms > 0.75) & (rms < 1.25)), rms
    assert abs(np.mean(z)) < 0.1  # unbiased


def test_bad_arguments(rng):
    S = rng.standard_normal((10, 2))
    with pytest.raises(ValueError, match="`y` has 9 values but `S` has 10 rows"):
        casep.solve_ols(S, np.zeros(9))
    with pytest.raises(ValueError, match="`names` has 1 entries"):
        casep.solve_ols(S, np.zeros(10), names=["a"])
    with pytest.raises(ValueError, match=r"option --sigma \(`sigma`\) must be finite and > 0"):
        casep.solve_ols(S, np.zeros(10), sigma=-1.0)
    with pytest.raises(ValueError, match="no degree of freedom"):
        casep.solve_ols(S[:2], np.zeros(2))
    with pytest.raises(ValueError, match="`y` is not finite at row 3"):
        y = np.zeros(10)
        y[3] = np.inf
        casep.solve_ols(S, y)


def test_inject_errors_requires_rng(platform36, truth36, flight_tf):
    t, f = flight_tf
    with pytest.raises(ValueError, match="`rng` is required"):
        inject_errors(platform36, t, f, truth36, sigma=0.1)


def test_platform39_phi0_aliasing_and_recovery(platform39, truth36, flight_tf, rng):
    """phi0 is exactly aliased with the antisymmetric accelerometer misalignments.

    f x (0, 0, phi) = (f_y phi, -f_x phi, 0) is the signature of Ka1xy * Wy - Ka1yx * Wx, so
    col(phi0z) = (arcsec / 1e-6) (col(Ka1xy) - col(Ka1yx)), and likewise for x and y. casep must
    report the nine as not separable; with the six misalignments known (ground calibration),
    phi0 is recovered.
    """
    from casep.units import ARCSEC

    t, f = flight_tf
    S = casep.build_sv(platform39, t, f)
    ix = platform39.index
    k = ARCSEC / 1e-6
    for phi, a, b in (("phi0z", "Ka1xy", "Ka1yx"), ("phi0y", "Ka1zx", "Ka1xz"), ("phi0x", "Ka1yz", "Ka1zy")):
        np.testing.assert_allclose(S[:, :, ix(phi)], k * (S[:, :, ix(a)] - S[:, :, ix(b)]),
                                   rtol=1e-12, atol=1e-12 * np.abs(S[:, :, ix(phi)]).max())
    D = np.concatenate([truth36, [30.0, -45.0, 15.0]])  # phi0 in arcsec
    res = casep.solve_ols(S, S @ D, names=platform39.names)
    aliased = {"Ka1xy", "Ka1yx", "Ka1zx", "Ka1xz", "Ka1yz", "Ka1zy", "phi0x", "phi0y", "phi0z"}
    assert res.status == 2 and set(res.diagnostics["unidentifiable"]) == aliased
    assert "Ka1xy" in res.reasons["phi0z"] and "Ka1yx" in res.reasons["phi0z"]
    ok = res.identifiable
    np.testing.assert_allclose(res.estimate[ok], D[ok], rtol=1e-6)
    # Misalignments known: move their contribution to the left-hand side, drop their columns.
    known = [ix(n) for n in ("Ka1xy", "Ka1yx", "Ka1zx", "Ka1xz", "Ka1yz", "Ka1zy")]
    free = [j for j in range(39) if j not in known]
    y = S @ D - S[:, :, known] @ D[known]
    fit = casep.solve_ols(S[:, :, free], y)
    assert fit.status == 1
    np.testing.assert_allclose(fit.estimate[-3:], D[36:], rtol=1e-6)
    noisy = casep.solve_ols(S[:, :, free], y + 0.1 * rng.standard_normal(y.shape))
    assert np.all(np.abs(noisy.estimate[-3:] - D[36:]) < 4 * noisy.std[-3:])


def _partner_problem(rng, eps: float, magnitudes: dict | None):
    """Columns a (a bias), b (a scale factor on f) and c = eps (alpha + beta f): c exactly dependent on a and b,
    excited only by eps (a misalignment times the instrument's own lateral error when eps is small)."""
    t = np.linspace(0.0, 100.0, 500)
    f = 1.0 + 0.5 * np.sin(0.1 * t)
    S = np.column_stack([t, t * f, eps * (0.3 * t + 0.7 * t * f)])
    x = np.array([0.8, -0.5, 0.6])
    y = S @ x + 0.05 * rng.standard_normal(t.size)
    pb = casep.Problem.from_arrays(S, y, names=["a", "b", "c"], units=["mg", "ppm", "arcsec"])
    if magnitudes is not None:
        pb.magnitudes = magnitudes
    return S, y, pb


def test_dependent_on_a_barely_excited_partner_is_the_least_size_solution_in_declared_magnitudes(rng):
    """With declared magnitudes s, a and b are reported with the least-squares solution of least size in units of s
    (numpy's minimum-norm lstsq on S diag(s), times s) and its covariance sigma^2 D (S D)^+ (S D)^+T D; c, which
    the data do not separate from a and b, stays without an estimate."""
    s = np.array([1.0, 2.0, 60.0])
    S, y, pb = _partner_problem(rng, 1e-8, {"a": 1.0, "b": 2.0, "c": 60.0})
    res = casep.solve_ols(pb)
    SD = S * s
    ref = np.linalg.lstsq(SD, y, rcond=1e-12)[0] * s
    sig2 = np.sum((y - S @ ref) ** 2) / (y.size - 2)
    Pp = np.linalg.pinv(SD, rcond=1e-12)
    cov = sig2 * (s[:, None] * (Pp @ Pp.T) * s[None, :])
    assert res.status == 2 and np.isnan(res.estimate[2])
    np.testing.assert_allclose(res.estimate[:2], ref[:2], rtol=1e-7)
    np.testing.assert_allclose(res.std[:2], np.sqrt(np.diag(cov))[:2], rtol=1e-7)
    np.testing.assert_allclose(res.covariance[:2, :2], cov[:2, :2], rtol=1e-6)
    assert res.reasons["a"].startswith("exactly dependent on")
    assert "within their declared magnitudes" in res.reasons["a"]
    assert "only their combination is determined" in res.reasons["c"]
    np.testing.assert_allclose(res.fitted_coefficients() @ S.T, S @ ref, rtol=1e-9)  # the same fitted values
    assert abs(res.estimate[0] - 0.8) < 4 * res.std[0] and abs(res.estimate[1] + 0.5) < 4 * res.std[1]


def test_dependent_on_a_well_excited_partner_or_without_magnitudes_stays_undetermined(rng):
    for eps, mags in ((1.0, {"a": 1.0, "b": 2.0, "c": 60.0}), (1e-8, None), (1e-8, {"a": 1.0, "b": 2.0})):
        res = casep.solve_ols(_partner_problem(rng, eps, mags)[2])
        assert np.isnan(res.estimate).all(), (eps, mags)
        assert all("only their combination is determined" in res.reasons[n] for n in "abc")
