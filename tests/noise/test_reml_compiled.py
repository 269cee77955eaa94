"""The compiled REML scale fit (:func:`casep._kernels.reml_scale_fit`, used where an axis has a white share) against
the fixed point's own equations on the stacked whitened rows, and against numpy's LAPACK kernels (``Reml.COMPILED =
False``: the reference path): the same scales and -2 l_R to the rounding, the same noise fits and the same estimate
and std under them to far below the searches' tolerance (5e-3 in ln tau)."""

from __future__ import annotations

import numpy as np
import pytest

from casep._kernels import reml_scale_fit
from casep.estimators.ols import solve_ols
from casep.noise.fit import Reml, estimable_basis
from casep.noise.model import whiten_series
from casep.regression.problem import Problem
from casep.regression.rows import prepare_rows
from casep.simulation.noise import ar1_noise


def _problem(seed: int, N: int = 240, n: int = 7) -> Problem:
    """Rows of n regressors at 5 Hz with Gauss-Markov (tau 1.5 s, 0.1) plus white (0.05) noise per axis."""
    rng = np.random.default_rng(seed)
    t = 0.2 * np.arange(N)
    S = rng.normal(size=(N, 3, n)) * np.linspace(0.5, 2.0, n)
    e = ar1_noise(t, 0.1, 1.5, rng) + 0.05 * rng.standard_normal((N, 3))
    return Problem.from_arrays(S, S @ rng.normal(size=n) + e, t)


POINTS = [((1.5, 0.8, 3.0), (0.3, 0.1, 0.6), None), ((0.2, 6.0, 1.0), (0.9, 0.02, 0.4), (1.0, 2.0, 0.5)),
          ((1.0, None, 2.0), (0.5, 0.0, 1e-4), (1.0, 0.7, 1.3))]


def _grams(reml: Reml, taus, shares):
    gs = [reml.gram(j, taus[j], shares[j]) for j in range(3)]
    return np.stack([g[0] for g in gs]), np.array([g[1] for g in gs])


def test_compiled_scale_fit_is_the_fixed_point_of_the_whitened_rows():
    """At the scales found, r_a^2 = RSS_a / (N - h_a) (r_x = 1) holds on the stacked whitened rows solved by lstsq
    (h_a the hat matrix's trace over axis a's rows), to the fixed point's tolerance (1e-7 in ln r); the value is
    -2 l_R computed from those rows (slogdet of the normal matrix)."""
    pb = _problem(1)
    reml = Reml(pb, estimable_basis(pb))
    N, p = reml.N, reml.p
    for taus, shares, start in POINTS:
        Ms, lds = _grams(reml, taus, shares)
        val, sc, ok = reml_scale_fit(Ms, np.ones(3) if start is None else np.array(start), N, p, lds)
        assert ok and np.isfinite(val) and sc[0] == 1.0
        W = [whiten_series(reml.Z[j], reml.t, taus[j], shares[j])[0] / sc[j] for j in range(3)]
        A = np.vstack([w[:, :p] for w in W])
        b = np.concatenate([w[:, p] for w in W])
        beta = np.linalg.lstsq(A, b, rcond=None)[0]
        r = b - A @ beta
        H = A @ np.linalg.solve(A.T @ A, A.T)
        rss = [float(np.sum(r[j * N:(j + 1) * N] ** 2)) * sc[j] ** 2 for j in range(3)]
        h = [float(np.trace(H[j * N:(j + 1) * N, j * N:(j + 1) * N])) for j in range(3)]
        r2 = np.array([rss[j] / (N - h[j]) for j in range(3)])
        np.testing.assert_allclose(np.sqrt(r2 / r2[0]), sc, rtol=1e-6)
        dense = (3 * N - p) * np.log(float(r @ r)) + np.linalg.slogdet(A.T @ A)[1] \
            + sum(N * np.log(sc[j] ** 2) + lds[j] for j in range(3))
        assert val == pytest.approx(dense, rel=1e-10)


def test_compiled_scale_fit_equals_numpys_kernels(monkeypatch):
    """The same steps as Reml's numpy path (LAPACK's Cholesky and inverse): scales to 1e-9, -2 l_R to 1e-12
    relative; a Gram that is not definite is no likelihood either way."""
    pb = _problem(2)
    reml = Reml(pb, estimable_basis(pb))
    for taus, shares, start in POINTS:
        Ms, lds = _grams(reml, taus, shares)
        val, sc, ok = reml_scale_fit(Ms, np.ones(3) if start is None else np.array(start), reml.N, reml.p, lds)
        monkeypatch.setattr(Reml, "COMPILED", False)
        ref_val, ref_sc = reml._fit_scales(taus, start, shares)
        monkeypatch.setattr(Reml, "COMPILED", True)
        assert ok and val == pytest.approx(ref_val, rel=1e-12)
        np.testing.assert_allclose(sc, ref_sc, rtol=1e-9)
        assert reml._fit_scales(taus, start, shares) == (val, sc)  # the path a search takes with a white share
    Ms, lds = _grams(reml, *POINTS[0][:2])
    Ms[:, :, 2] = Ms[:, 2, :] = 0.0  # a column of nothing: G singular
    val, _, ok = reml_scale_fit(Ms, np.ones(3), reml.N, reml.p, lds)
    assert not ok and val == np.inf
    with np.errstate(invalid="ignore"):  # as _fit_scales calls it
        ref = reml._scale_steps(np.ones(3), Ms.reshape(3, -1),
                                np.ascontiguousarray(Ms[:, :reml.p, :reml.p]).reshape(3, -1), Ms, Ms[:, reml.p, reml.p])
    assert not ref[1]


@pytest.mark.parametrize("kind", ["gmw", "auto"])
def test_noise_fit_and_the_fit_under_it_equal_numpys_kernels(kind, monkeypatch):
    """fit_noise and OLS on the rows whitened by it, compiled against numpy's kernels: tau and the white share to
    1e-5 relative (a rounding-level difference in a value can move a search's step: 500 times below its tolerance),
    the scales, sigma and the estimate and std under the model to 1e-6."""
    pb = _problem(9 if kind == "gmw" else 4, N=250, n=16)
    fits = {}
    for compiled in (True, False):
        monkeypatch.setattr(Reml, "COMPILED", compiled)
        rows = prepare_rows(pb, kind, robust="none")
        fits[compiled] = rows.noise, solve_ols(rows.solved)
    (nm, res), (ref, ref_res) = fits[True], fits[False]
    assert nm.axis_kinds() == ref.axis_kinds() and "gmw" in nm.axis_kinds()
    np.testing.assert_allclose(np.array(nm.tau, float), np.array(ref.tau, float), rtol=1e-5)
    np.testing.assert_allclose(nm.share, ref.share, rtol=1e-5)
    np.testing.assert_allclose(nm.scale, ref.scale, rtol=1e-6)
    assert nm.sigma == pytest.approx(ref.sigma, rel=1e-6)
    assert nm.extra["neg2_reml"] == pytest.approx(ref.extra["neg2_reml"], rel=1e-9)
    np.testing.assert_allclose(res.estimate, ref_res.estimate, rtol=1e-6, atol=1e-6 * np.abs(ref_res.std).min())
    np.testing.assert_allclose(res.std, ref_res.std, rtol=1e-6)
