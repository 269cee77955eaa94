"""The correlation time's profile likelihood (:func:`casep.noise.fit.tau_profile`): its weights, its points against
the fit they hold tau in, and a seeded coverage check of the interval it keeps."""

from __future__ import annotations

import numpy as np
import pytest

from casep.noise.fit import (
    PROFILE_LR,
    PROFILE_POINTS,
    Reml,
    estimable_basis,
    fit_noise,
    tau_kept,
    tau_profile,
    tau_search_bounds,
)
from casep.regression.problem import Problem
from casep.simulation.noise import ar1_noise


def _problem(seed: int, n: int = 100, tau: float = 1.0) -> Problem:
    """100 epochs at 5 Hz per axis, two regressors, Gauss-Markov (0.05 m/s, `tau`) plus white (0.03 m/s) noise."""
    rng = np.random.default_rng(seed)
    t = 0.2 * np.arange(n)
    S = np.stack([np.ones((n, 3)), np.tile((t - t.mean())[:, None], (1, 3))], axis=2)
    e = ar1_noise(t, 0.05, tau, rng) + 0.03 * rng.standard_normal((n, 3))
    return Problem.from_arrays(S, S @ np.array([0.3, -0.02]) + e, t)


def test_the_profile_points_are_the_fits_at_their_tau_weighted_by_their_likelihood():
    """Per axis: the kept points' tau on the grid (evenly in ln tau over the search interval), the others' at the
    Gauss-Markov plus white fit's; each point is ``fit_noise(problem, "gmw", tau=...)`` (its -2 l_R to 1e-9); the
    weights are ``exp(-(-2 l_R - min) / 2)`` summing to 1, every kept point within PROFILE_LR of the best; the free
    fit's -2 l_R at or below every point's (it is the minimum over tau too)."""
    pb = _problem(3)
    base, axes = tau_profile(pb)
    lo, hi = tau_search_bounds(pb.t)
    grid = np.exp(np.linspace(lo, hi, PROFILE_POINTS))
    assert base == fit_noise(pb, "gmw")
    for j, points in enumerate(axes):
        assert points and sum(w for w, _ in points) == pytest.approx(1.0, abs=1e-12)
        vals = []
        for _w, nm in points:
            assert np.min(np.abs(grid - nm.tau[j])) <= 1e-12 * nm.tau[j]
            assert all(nm.tau[k] == base.tau[k] for k in range(3) if k != j)
            again = fit_noise(pb, "gmw", tau=list(nm.tau))
            assert nm.extra["neg2_reml"] == pytest.approx(again.extra["neg2_reml"], abs=1e-9)
            assert base.extra["neg2_reml"] <= nm.extra["neg2_reml"] + 1e-6
            vals.append(nm.extra["neg2_reml"])
        d = np.array(vals) - min(vals)
        assert np.all(d < PROFILE_LR)
        np.testing.assert_allclose([w for w, _ in points], np.exp(-d / 2) / np.sum(np.exp(-d / 2)), rtol=1e-12)
        # tau_kept: the kept interval's ends, and whether it reaches the grid's top (the record length, 19.8 s)
        lo_j, hi_j, top_j = tau_kept(pb.t, (base, axes))[j]
        taus = [nm.tau[j] for _, nm in points]
        assert (lo_j, hi_j) == (min(taus), max(taus))
        assert top_j == (abs(hi_j - (pb.t[-1] - pb.t[0])) < 1e-9)


def test_a_reused_evaluator_gives_a_new_ones_numbers_and_another_problems_is_refused():
    """``fit_noise(..., reml=...)`` (tau_profile's points share one evaluator and its cached Gram matrices): the
    models equal (bit for bit) those of a fresh evaluator, in any order of the fits; another problem's is an error."""
    pb = _problem(5)
    reml = Reml(pb, estimable_basis(pb))
    for tau in ([0.5, 1.0, 2.0], [0.5, 1.0, 2.0], [3.0, 1.0, 2.0], None):
        assert fit_noise(pb, "gmw", tau=tau, reml=reml) == fit_noise(pb, "gmw", tau=tau)
    with pytest.raises(ValueError, match="`reml` is another problem's"):
        fit_noise(_problem(6), "gmw", reml=reml)


def test_the_kept_interval_holds_the_true_tau_about_as_often_as_its_level_says():
    """Seeded: 8 draws of 100 epochs per axis (24 axis profiles), truth tau 1 s. The grid point nearest the truth
    (0.89 s) is kept on at least 21 of the 24 axes (a 95 % interval: 22.8 expected; 23 here), where the plug-in
    REML tau is within a factor 1.5 of the truth on fewer than half (9 here)."""
    hold, plug = 0, 0
    lo, hi = tau_search_bounds(0.2 * np.arange(100))
    grid = np.exp(np.linspace(lo, hi, PROFILE_POINTS))
    near = grid[np.argmin(np.abs(np.log(grid)))]
    for seed in range(8):
        base, axes = tau_profile(_problem(100 + seed))
        for j, points in enumerate(axes):
            hold += any(abs(nm.tau[j] - near) < 1e-9 for _, nm in points)
            plug += 1 / 1.5 <= base.tau[j] <= 1.5
    assert hold >= 21, (hold, plug)
    assert plug < 12, (hold, plug)
