"""Robust (Huber) least squares: casep.estimators.huber.solve_huber."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.exceptions import IllConditionedWarning


@pytest.fixture(scope="module")
def paper20():
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=1, rate=20.0)
    S = casep.build_sv(sim.model, sim.flight.t, sim.flight.f)
    return S, S @ sim.truth, sim.truth, sim.model


def _glitchy(clean, rng, share=0.02, size=3.0):
    """White 0.1 m/s noise plus `share` of the scalar rows carrying +-`size` m/s glitches."""
    y = clean + 0.1 * rng.standard_normal(clean.shape)
    hit = rng.random(clean.shape) < share
    return y + hit * size * rng.choice([-1.0, 1.0], size=clean.shape), hit


def _ols_and_huber(paper20, rng, **huber_options):
    S, clean, _, m = paper20
    y = clean + 0.1 * rng.standard_normal(clean.shape)
    with pytest.warns(IllConditionedWarning):
        ols = casep.solve_ols(S, y, names=m.names)
    with pytest.warns(IllConditionedWarning):
        hub = casep.solve_huber(S, y, names=m.names, **huber_options)
    return ols, hub


def test_huber_equals_ols_when_nothing_is_downweighted(paper20, rng):
    """c -> infinity: every weight is 1 and IRLS is least squares (to 1e-8 std)."""
    ols, hub = _ols_and_huber(paper20, rng, c=1e9)
    assert np.max(np.abs(hub.estimate - ols.estimate) / ols.std) < 1e-8
    np.testing.assert_allclose(hub.std, ols.std, rtol=1e-3)  # H1 factor -> 1 up to (m - p) / m


def test_huber_on_clean_data_is_close_to_ols(paper20, rng):
    """Default c = 1.345 on Gaussian noise: 95 % efficiency, so Huber - OLS ~ 0.23 std RMS."""
    ols, hub = _ols_and_huber(paper20, rng)
    z = (hub.estimate - ols.estimate) / ols.std
    assert np.sqrt(np.mean(z**2)) < 0.5 and hub.extras.outliers["count"] < 0.001 * ols.residuals.size


@pytest.mark.montecarlo
def test_huber_monte_carlo_with_glitches(paper20, rng):
    """2 % of samples with 3 m/s outliers. Huber's RMS error stays within 1.3x the
    clean-data CRLB (median over coefficients) where OLS is several times worse; its std cover
    ~95 %; every injected glitch is flagged and few clean rows are (30 seeded runs, 20 Hz)."""
    S, clean, truth, m = paper20
    crlb = casep.checks.diagnostics.crlb_covariance(S, 0.1)
    crlb = np.sqrt(np.diag(crlb))
    eh, eo, hits, flagged_ok, false_flags = [], [], [], 0, 0
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        for _ in range(30):
            y, hit = _glitchy(clean, rng)
            h = casep.solve_huber(S, y, names=m.names)
            o = casep.solve_ols(S, y, names=m.names)
            eh.append(h.estimate - truth)
            eo.append(o.estimate - truth)
            hits.append(np.abs(h.estimate - truth) <= 1.96 * h.std)
            u = np.abs(h.residuals.reshape(-1)) / h.extras.scale
            flagged = u > h.settings["flag"]
            flagged_ok += int(np.all(flagged[hit.reshape(-1)]))
            false_flags += int(np.sum(flagged & ~hit.reshape(-1)))
    ratio_h = np.sqrt(np.mean(np.array(eh) ** 2, axis=0)) / crlb
    ratio_o = np.sqrt(np.mean(np.array(eo) ** 2, axis=0)) / crlb
    assert np.median(ratio_h) <= 1.3, np.median(ratio_h)
    assert np.median(ratio_o) >= 3.0, np.median(ratio_o)
    assert 0.90 <= np.median(np.mean(hits, axis=0)) <= 0.99
    assert flagged_ok == 30  # all glitches flagged in every run
    assert false_flags < 30 * clean.size * 2e-4  # Gaussian P(|u| > 4) = 6e-5 per row


def test_irls_steps_on_one_basis_equal_the_qr_of_the_weighted_rows(paper20):
    """The IRLS steps on the orthonormal basis of S (huber._Basis) against a QR, rank analysis and SVD of the
    weighted rows at every step (the path a rank-deficient problem takes): the same estimate and std to 1e-9 of
    the std, scale and flagged sizes to 1e-9, iterations and flagged rows equal, for glitches of 3 and of
    300 m/s (weights down to ~5e-4); weights that could make the weighted rows lose rank at the rank threshold
    take the QR path."""
    from unittest import mock

    from casep.estimators import huber
    from casep.estimators._base import prepare

    S, clean, _, m = paper20
    rng = np.random.default_rng(40)
    for size in (3.0, 300.0):
        y, _ = _glitchy(clean, rng, size=size)
        with pytest.warns(IllConditionedWarning):
            fast = casep.solve_huber(S, y, names=m.names)
        with mock.patch.object(huber._Basis, "weighted", lambda self, w, b: None), pytest.warns(IllConditionedWarning):
            qr = casep.solve_huber(S, y, names=m.names)
        assert np.max(np.abs(fast.estimate - qr.estimate) / qr.std) < 1e-9
        np.testing.assert_allclose(fast.std, qr.std, rtol=1e-9)
        assert fast.extras.scale == pytest.approx(qr.extras.scale, rel=1e-9)
        assert fast.extras.iterations == qr.extras.iterations
        got, want = fast.extras.outliers, qr.extras.outliers
        assert got["count"] == want["count"] and len(got["largest"]) == len(want["largest"])
        for a, b in zip(got["largest"], want["largest"]):
            assert (a["sample"], a["axis"]) == (b["sample"], b["axis"])
            assert a["size_sigma"] == pytest.approx(b["size_sigma"], rel=1e-9)
    basis = huber._Basis(prepare(S, clean, None, None, None, None, None))
    w = np.ones(clean.size)
    assert basis.weighted(w, clean.reshape(-1)) is not None
    w[0] = 1e-12  # kappa(R) / min w far beyond the rank threshold
    assert basis.weighted(w, clean.reshape(-1)) is None


def test_huber_is_registered_and_validates(paper20):
    S, clean, truth, m = paper20
    from casep.estimators.registry import METHODS

    assert "huber" in METHODS and METHODS["huber"].std_kind == "sampling"
    with pytest.raises(ValueError, match=r"\(`c`\) must be"):
        casep.solve_huber(S, clean, c=-1.0)
