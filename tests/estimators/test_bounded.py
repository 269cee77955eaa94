"""Bounded least squares (casep.estimators.bounded): box, KKT, no-active equals OLS, fixed values."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.estimators.bounded import parse_bounds


@pytest.fixture(scope="module")
def small(platform36, truth36):
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=3, rate=10.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    return S, np.array(sim.flight.dv), platform36.names


def _kkt(res, S, y, lo, hi, fixed):
    """Gradient of ||y - S x||^2 per coefficient in scaled coordinates: sign checks."""
    S2 = S.reshape(-1, S.shape[-1])
    c = np.linalg.norm(S2, axis=0)
    g = (S2 / c).T @ (S2 @ res.estimate - y.reshape(-1))  # d/dz of 0.5 ||r||^2
    gn = g / np.linalg.norm(y)
    act = res.extras.active_bounds
    names = res.names
    for j, nm in enumerate(names):
        kind = act.get(nm)
        if kind is None:
            assert abs(gn[j]) < 1e-6, (nm, gn[j])
        elif kind == "lower":
            assert gn[j] > -1e-6, (nm, gn[j])
        elif kind == "upper":
            assert gn[j] < 1e-6, (nm, gn[j])


def test_solution_in_box_and_kkt(small, truth36):
    S, y, names = small
    box = {n: [v - 2 * abs(v), v + 2 * abs(v)] for n, v in zip(names, truth36)}
    res = casep.solve_bounded(S, y, box, names=names)
    lo, hi, fixed = parse_bounds(box, names)
    assert np.all(res.estimate >= lo - 1e-12) and np.all(res.estimate <= hi + 1e-12)
    assert len(res.extras.active_bounds) > 0  # 0.1 m/s noise pushes many to the box
    _kkt(res, S, y, lo, hi, fixed)
    for nm in res.extras.active_bounds:
        j = names.index(nm)
        assert res.std[j] != res.std[j] and "bound" in res.reasons[nm]  # std NaN, reason given


def test_equals_ols_when_no_bound_is_active(small):
    S, y, names = small
    ols = casep.solve_ols(S, y, names=names)
    box = {n: [e - 100 * s, e + 100 * s] for n, e, s in zip(names, ols.estimate, ols.std)}
    res = casep.solve_bounded(S, y, box, names=names)
    assert res.extras.active_bounds == {}
    assert np.max(np.abs(res.estimate - ols.estimate) / ols.std) < 1e-4
    np.testing.assert_allclose(res.std, ols.std, rtol=1e-4)


def test_fixed_coefficients_stay_fixed_and_rest_is_conditional_ols(small):
    S, y, names = small
    res = casep.solve_bounded(S, y, {"Kg0x": 0.5, "Ka1xz": [50.0, 50.0]}, names=names)
    j, k = names.index("Kg0x"), names.index("Ka1xz")
    assert res.estimate[j] == 0.5 and res.estimate[k] == 50.0
    assert res.extras.active_bounds == {"Kg0x": "fixed", "Ka1xz": "fixed"}
    free = [i for i in range(36) if i not in (j, k)]
    S2 = S.reshape(-1, 36)
    ref = casep.solve_ols(S2[:, free], y.reshape(-1) - S2[:, [j, k]] @ np.array([0.5, 50.0]))
    assert np.max(np.abs(res.estimate[free] - ref.estimate) / ref.std) < 1e-4
    np.testing.assert_allclose(res.std[free], ref.std, rtol=1e-4)


def test_parse_errors(small):
    S, y, names = small
    with pytest.raises(ValueError, match="unknown coefficient `Kxx`"):
        casep.solve_bounded(S, y, {"Kxx": [0, 1]}, names=names)
    with pytest.raises(ValueError, match=r"`Kg0x` has lo > hi \(2 > 1\)"):
        casep.solve_bounded(S, y, {"Kg0x": [2, 1]}, names=names)
    with pytest.raises(ValueError, match="must be \\[lo, hi\\] or a number"):
        casep.solve_bounded(S, y, {"Kg0x": "wide"}, names=names)
    lo, hi, fixed = parse_bounds({"Kg0x": [None, 3.0]}, names)
    assert lo[0] == -np.inf and hi[0] == 3.0 and not fixed[0]


def test_message_and_table_state_active_set_and_conditional_std(small, truth36):
    S, y, names = small
    box = {n: [v - 2 * abs(v), v + 2 * abs(v)] for n, v in zip(names, truth36)}
    box["Kg0x"] = 0.5  # one fixed
    res = casep.solve_bounded(S, y, box, names=names)
    kinds = list(res.extras.active_bounds.values())
    n_lo, n_hi = kinds.count("lower"), kinds.count("upper")
    assert kinds.count("fixed") == 1 and n_lo + n_hi > 0
    n_free = 36 - len(kinds)
    assert res.diagnostics["active_set"] == {"at_lower": n_lo, "at_upper": n_hi, "fixed": 1, "free": n_free,
                                             "undetermined": 0}
    assert int(np.sum(np.isfinite(res.std))) == n_free  # std only for the free ones
    assert "all 36 coefficients estimated" not in res.message
    assert res.message.startswith(f"{n_lo + n_hi} of 36 coefficients at a bound ({n_lo} lower, {n_hi} upper), "
                                  f"1 fixed, {n_free} free")
    assert "conditional on this active set (understated" in res.message
    assert res.std_kind == "conditional" and res.to_dict()["std_kind"] == "conditional"
    table = res.text()
    assert res.message in table.splitlines()
    assert (f"active set {n_lo} at lower, {n_hi} at upper bound, 1 fixed, {n_free} free" in table
            and "std conditional on the active set (understated)" in table)


def test_no_active_bound_says_so(small):
    S, y, names = small
    ols = casep.solve_ols(S, y, names=names)
    box = {n: [e - 100 * s, e + 100 * s] for n, e, s in zip(names, ols.estimate, ols.std)}
    res = casep.solve_bounded(S, y, box, names=names)
    assert res.message.startswith("0 of 36 coefficients at a bound (0 lower, 0 upper), 0 fixed, 36 free")
    assert "no bound active" in res.message and res.std_kind == "sampling"


def test_narrow_interval_counts_each_coefficient_once(paper_problem, platform36):
    """A box narrower than the activity tolerance is 'at' both ends: it counts once (as lower, the
    value it takes), so the counts add up to n (review: '39 of 36 at a bound')."""
    import warnings

    S, y, truth = paper_problem
    bounds = {n: [v, v + 1e-12 * (1 + abs(v))] for n, v in zip(platform36.names, truth)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = casep.solve_bounded(S, y, bounds, names=platform36.names)
    c = res.diagnostics["active_set"]
    assert c["at_lower"] + c["at_upper"] + c["fixed"] + c["free"] + c["undetermined"] <= 36
    assert f"{c['at_lower'] + c['at_upper']} of 36" in res.message and "of 36 coefficients at a bound" in res.message


def test_active_set_is_clarabels_optimum(small, truth36, monkeypatch):
    """The active-set solution against the cvxpy + Clarabel path it stands in front of (forced by making
    the active-set method give up): the same active set, so, polished, the same numbers."""
    import casep.estimators.bounded as bounded

    S, y, names = small
    box = {n: [v - 2 * abs(v), v + 2 * abs(v)] for n, v in zip(names, truth36)}
    box["Kg0x"] = 0.5
    mine = casep.solve_bounded(S, y, box, names=names)
    monkeypatch.setattr(bounded, "_active_set", lambda *a: None)
    ref = casep.solve_bounded(S, y, box, names=names)
    assert mine.settings["solver"] == "active set" and ref.settings["solver"] == "cvxpy+clarabel"
    assert mine.diagnostics["polished"] and ref.diagnostics["polished"]
    assert mine.extras.active_bounds == ref.extras.active_bounds and len(ref.extras.active_bounds) > 3
    np.testing.assert_allclose(mine.estimate, ref.estimate, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(mine.std, ref.std, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("seed", range(6))
def test_active_set_on_random_boxes_is_the_qp_optimum(seed):
    """Random well-posed boxes (some sides open, one coordinate fixed): the active-set point is feasible, meets
    the KKT conditions and equals cvxpy + Clarabel's optimum to its accuracy."""
    import cvxpy as cp

    from casep.estimators.bounded import _active_set

    rng = np.random.default_rng(seed)
    n = 10
    R = np.triu(rng.normal(size=(n, n))) + 3.0 * np.eye(n)
    q = 3.0 * rng.normal(size=n)
    lo, hi = -rng.uniform(0.1, 1.0, n), rng.uniform(0.1, 1.0, n)
    lo[0], hi[1] = -np.inf, np.inf
    fixed = np.zeros(n, dtype=bool)
    fixed[2] = True
    hi[2] = lo[2]
    z = _active_set(R, q, lo, hi, fixed, 1e-12)
    assert z is not None and np.all(z >= lo) and np.all(z <= hi) and z[2] == lo[2]
    g = R.T @ (R @ z - q)
    on_lo, on_hi = (z == lo) & ~fixed, (z == hi) & ~fixed
    free = ~(on_lo | on_hi | fixed)
    assert np.all(np.abs(g[free]) < 1e-10) and np.all(g[on_lo] > -1e-10) and np.all(g[on_hi] < 1e-10)
    assert on_lo.any() or on_hi.any()
    x = cp.Variable(n)
    cons = [x[3:] >= lo[3:], x[0] <= hi[0], x[1] >= lo[1], x[2] == lo[2], x[3:] <= hi[3:]]
    cp.Problem(cp.Minimize(cp.sum_squares(R @ x - q)), cons).solve(solver=cp.CLARABEL)
    np.testing.assert_allclose(z, x.value, atol=1e-6)
