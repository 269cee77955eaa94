"""The impact miss of an estimate (casep.impact, `casep impact`); format: docs/reference/file-formats.md "Impact JSON".

Each computed quantity is checked against an independent route: the closed-form Kepler impact
against an adaptive integration with a ground event, the CasADi Jacobian against central finite
differences, S_P against Simpson integration of S_V on a 10x finer grid (and exactly for a
constant force), the linear miss against the nonlinear propagation, and the predicted miss std
against a seeded Monte Carlo of batched OLS estimates.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import casep
from casep.cli import main
from casep.impact.ballistic import (
    EARTH_CENTRE,
    BallisticError,
    ground_coordinates,
    impact,
    impact_jacobian,
    impact_point,
    impact_point_ode,
)
from casep.impact.miss import STATE_COLUMNS, cumulative_sp, impact_analysis, position_sensitivity
from casep.simulation.trajectory import MU_EARTH, R_EARTH


@pytest.fixture(scope="module")
def paper_sim():
    """The paper scenario at 10 Hz (seed 1): flight with r_*, v_*, and its true coefficients."""
    from casep.simulation.simulate import simulate_flight

    return simulate_flight("paper", seed=1, rate=10.0)


@pytest.fixture(scope="module")
def paper_ols(paper_sim):
    """OLS result of the paper flight (covariance in natural units, BKW groups in diagnostics)."""
    problem = casep.Problem.from_flight(paper_sim.flight, paper_sim.model)
    return casep.solve_ols(problem)


def _burnout(sim):
    tr = sim.trajectory
    return tr.position[-1].copy(), tr.velocity[-1].copy()


def _states(sim, rng, k=6):
    """Burnout state of the paper trajectory and `k` random variations (speed, direction, height)."""
    r0, v0 = _burnout(sim)
    out = [(r0, v0)]
    for _ in range(k):
        r = r0 + rng.normal(0.0, [50e3, 30e3, 50e3])
        v = v0 * rng.uniform(0.7, 1.2) + rng.normal(0.0, 300.0, 3)
        out.append((r, v))
    out.append((r0, v0 * np.array([1.0, -1.0, 1.0])))  # descending at burnout
    return out


# ----------------------------------------------------------------------------- ballistic flight
def test_closed_form_impact_matches_integration(paper_sim, rng):
    """Kepler closed form (CasADi) vs DOP853 with an event at |r - c| = R_E (rtol 1e-12): < 1 mm."""
    worst = 0.0
    for r, v in _states(paper_sim, rng):
        p = impact_point(r, v)
        q, tof = impact_point_ode(r, v, rtol=1e-12)
        assert tof > 0
        assert abs(np.linalg.norm(p - EARTH_CENTRE) - R_EARTH) < 1e-6
        worst = max(worst, float(np.linalg.norm(p - q)))
        np.testing.assert_allclose(impact(r, v), ground_coordinates(p), rtol=0, atol=1e-6)
    assert worst < 1e-3, worst


def test_downrange_crossrange_definition():
    """downrange = R_E atan2(u_x, u_y), crossrange = R_E asin(u_z) (launch point u0 = (0, 1, 0))."""
    ang = 0.3
    p = EARTH_CENTRE + R_EARTH * np.array([np.sin(ang) * np.cos(0.1), np.cos(ang) * np.cos(0.1), np.sin(0.1)])
    d, c = ground_coordinates(p)
    assert d == pytest.approx(R_EARTH * np.arctan2(np.sin(ang), np.cos(ang)), rel=1e-12)
    assert c == pytest.approx(R_EARTH * 0.1, rel=1e-12)


def test_jacobian_matches_central_differences(paper_sim, rng):
    """Exact 2 x 6 Jacobian (CasADi AD of the closed form) vs central differences (h = 1 m, 1 mm/s)."""
    for r, v in _states(paper_sim, rng, k=3):
        J = impact_jacobian(r, v)
        x = np.concatenate([r, v])
        Jfd = np.empty((2, 6))
        for k in range(6):
            h = 1.0 if k < 3 else 1e-3
            e = np.zeros(6)
            e[k] = h
            Jfd[:, k] = (np.array(impact(*np.split(x + e, 2))) - np.array(impact(*np.split(x - e, 2)))) / (2 * h)
        # position columns (m/m) and velocity columns (m per m/s) each to 1e-6 of their scale
        for cols in (slice(0, 3), slice(3, 6)):
            scale = np.abs(J[:, cols]).max()
            np.testing.assert_allclose(J[:, cols], Jfd[:, cols], rtol=0, atol=1e-6 * scale)


def test_no_impact_is_refused():
    r = np.array([0.0, 300e3, 0.0])
    v_circ = np.sqrt(MU_EARTH / (R_EARTH + 300e3))
    with pytest.raises(BallisticError, match="does not meet the Earth"):
        impact(r, np.array([v_circ * 1.01, 0.0, 0.0]))  # orbit: perigee above the surface
    with pytest.raises(BallisticError, match="escape"):
        impact(r, np.array([0.0, 12e3, 0.0]))
    with pytest.raises(BallisticError, match="below the Earth's surface"):
        impact(np.array([0.0, -10.0, 0.0]), np.array([100.0, 100.0, 0.0]))


# ----------------------------------------------------------------------------- S_P
def test_sp_matches_fine_simpson_integration(platform36):
    """S_P(t_b) by casep (trapezoid, 10 Hz, blocks) vs Simpson on S_V built at 100 Hz: rel < 1e-4."""
    from scipy.integrate import simpson

    from casep.simulation.synthetic import excitation_force

    T = 120.0
    t = np.linspace(0.0, T, 1201)  # 10 Hz
    tf = np.linspace(0.0, T, 12001)  # 100 Hz
    fl = casep.FlightData(t, excitation_force(t, duration=T), np.zeros((t.size, 3)))
    sp, sv = position_sensitivity(platform36, fl)
    S_fine = casep.build_sv(platform36, tf, excitation_force(tf, duration=T))
    ref = simpson(S_fine, x=tf, axis=0)  # int_0^T S_V dt
    scale = np.abs(ref).max(axis=0)  # per coefficient
    assert np.all(np.abs(sp - ref) <= 1e-4 * scale + 1e-12), np.max(np.abs(sp - ref) / scale)
    np.testing.assert_allclose(sv, S_fine[-1], rtol=0, atol=1e-4 * np.abs(S_fine[-1]).max())


def test_sp_blocks_equal_cumulative_and_exact_for_constant_force(platform36):
    """Block-wise S_P (block boundaries crossed) equals the cumulative trapezoid; for a constant force
    the accelerometer-bias columns are S_V = k t, so S_P(t_b) = S_V(t_b) t_b / 2 exactly."""
    t = np.cumsum(np.r_[0.0, np.full(5000, 0.01) + 0.002 * np.sin(np.arange(5000))])  # non-uniform
    f = np.tile([3.0, 25.0, -1.0], (t.size, 1))
    fl = casep.FlightData(t, f, np.zeros((t.size, 3)))
    sp, sv = position_sensitivity(platform36, fl, rows=2048)  # three blocks
    S = casep.build_sv(platform36, t, f)
    np.testing.assert_allclose(sp, cumulative_sp(S, t)[-1], rtol=1e-12, atol=1e-14)
    assert np.all(cumulative_sp(S, t)[0] == 0.0)
    bias = [platform36.names.index(n) for n in ("Ka0x", "Ka0y", "Ka0z")]
    np.testing.assert_allclose(sp[:, bias], sv[:, bias] * (t[-1] - t[0]) / 2, rtol=1e-12, atol=1e-15)


# ----------------------------------------------------------------------------- the miss
def test_linear_miss_matches_nonlinear_for_paper_truth(paper_sim, paper_ols):
    """Linear prediction -J dx_b vs impact(x_b - dx_b) - impact(x_b) with the paper's true D: < 1 %."""
    res = dataclasses.replace(paper_ols, estimate=paper_sim.truth.copy())
    a = impact_analysis(paper_sim.flight, res)
    rel = np.abs(a.miss - a.nonlinear) / np.abs(a.nonlinear)
    assert np.all(rel < 0.01), rel
    assert np.all(np.abs(a.nonlinear) > 100.0)  # a real miss (km class), not a trivial zero
    # linear miss = sum of contributions = G D, and G = -J [S_P; S_V]
    np.testing.assert_allclose(a.miss, a.sensitivity @ paper_sim.truth, rtol=1e-12)
    np.testing.assert_allclose(a.sensitivity, -a.jacobian @ np.vstack([a.sp, a.sv]), rtol=1e-12)
    np.testing.assert_allclose(a.miss, np.nansum(a.contributions, axis=1), rtol=1e-12)
    # burnout = last sample's r_*, v_*
    assert a.t_b == paper_sim.flight.t[-1]
    np.testing.assert_array_equal(a.r_b, [paper_sim.flight.signals[c][-1] for c in STATE_COLUMNS[:3]])


@pytest.mark.montecarlo
def test_predicted_miss_std_matches_monte_carlo(paper_sim, paper_ols, rng):
    """std of the predicted miss (G Cov G^T of one OLS result) vs the RMS of predicted - true miss
    over seeded noise draws, OLS batched on one S_V: ratio in [0.85, 1.15] per axis."""
    a = impact_analysis(paper_sim.flight, paper_ols)
    fl, D = paper_sim.flight, paper_sim.truth
    S = casep.build_sv(paper_sim.model, fl.t, fl.f).reshape(-1, D.size)  # (3N, n) stacked
    c = np.linalg.norm(S, axis=0)
    Q, R = np.linalg.qr(S / c)  # OLS on unit-norm columns, all draws at once
    runs, sigma = 400, paper_sim.scenario.noise.sigma
    Y = (S @ D)[:, None] + sigma * rng.standard_normal((S.shape[0], runs))
    D_hat = np.linalg.solve(R, Q.T @ Y) / c[:, None]  # (n, runs)
    truth = dataclasses.replace(paper_ols, estimate=D.copy())
    true_miss = impact_analysis(fl, truth).nonlinear  # what the true errors do
    err = a.sensitivity @ D_hat - true_miss[:, None]  # predicted - true
    rms = np.sqrt(np.mean(err**2, axis=1))
    ratio = a.std / rms
    assert np.all((ratio > 0.85) & (ratio < 1.15)), (ratio, a.std, rms)


def test_model_mismatch_names_both(paper_sim, paper_ols):
    with pytest.raises(ValueError, match="model `platform36`, not of model `platform39_misalignment`"):
        impact_analysis(paper_sim.flight, paper_ols, model="platform39_misalignment")


def test_null_estimates_contribute_nothing(tmp_path):
    """A pitch-plane flight: 12 zero columns, null estimates; their contributions are null (listed),
    their sensitivities still reported; the miss sums the others; the JSON has no NaN."""
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper-pitch", seed=2, rate=5.0)
    res = casep.solve_ols(casep.Problem.from_flight(sim.flight, sim.model))
    assert (~res.identifiable).sum() == 12
    a = impact_analysis(sim.flight, res)
    d = json.loads(json.dumps(a.to_dict(), allow_nan=False))
    rows = {r["name"]: r for r in d["contributions"]}
    missing = [n for n, ok in zip(res.names, res.identifiable) if not ok]
    assert sorted(d["no_estimate"]) == sorted(missing)
    for n in missing:
        assert rows[n]["downrange"] is None and rows[n]["crossrange"] is None and "no estimate" in rows[n]["note"]
    sens = {r["name"]: r for r in d["sensitivity"]}
    assert all(sens[n]["downrange"] is not None for n in missing)
    ok = res.identifiable
    np.testing.assert_allclose(a.miss, a.sensitivity[:, ok] @ res.estimate[ok], rtol=1e-12)
    assert np.all(np.isfinite(a.std))


def test_impact_analysis_follows_the_result_protocol(paper_sim, paper_ols):
    from casep.results import Result

    a = impact_analysis(paper_sim.flight, paper_ols)
    assert isinstance(a, Result)
    d = json.loads(json.dumps(a.to_dict(), allow_nan=False))
    with pytest.warns(DeprecationWarning, match="to_json"):  # the old name: an alias, for one release
        assert d == json.loads(json.dumps(a.to_json(), allow_nan=False))
    assert d["miss"]["downrange"] == pytest.approx(a.miss[0], rel=1e-12)
    with pytest.warns(DeprecationWarning, match="table"):
        assert a.text() == a.table() and a.text(top=3) == a.table(3)
    assert a.success and a.status == 0 and "impact" in a.message
    assert f"downrange {a.miss[0]:.4g}" in a.text()
    assert len(a.text(top=3).splitlines()) < len(a.text().splitlines())


def test_groups_from_diagnostics_and_correlation_fallback(paper_sim, paper_ols):
    a = impact_analysis(paper_sim.flight, paper_ols)
    assert [list(g.names) for g in a.groups] == [g for g in paper_ols.diagnostics["groups"]]
    for g in a.groups:
        idx = [a.names.index(n) for n in g.names]
        np.testing.assert_allclose(g.contribution, np.nansum(a.contributions[:, idx], axis=1), rtol=1e-12)
    no_groups = dataclasses.replace(paper_ols, diagnostics={k: v for k, v in paper_ols.diagnostics.items()
                                                           if k != "groups"})
    b = impact_analysis(paper_sim.flight, no_groups)
    assert "|rho| > 0.9" in b.group_source and b.groups
    C = paper_ols.covariance
    for g in b.groups:  # every member strongly correlated with another member
        idx = [b.names.index(n) for n in g.names]
        rho = C[np.ix_(idx, idx)] / np.sqrt(np.outer(np.diag(C)[idx], np.diag(C)[idx]))
        assert np.all((np.abs(rho) - np.eye(len(idx))).max(axis=1) > 0.9)


def test_per_flight_coefficients_zero_unless_given(paper_sim, paper_ols):
    """A several-flight result holds the shared coefficients: a per-flight one (dt_trk) is 0 unless given."""
    d = paper_ols.to_dict()
    d["model"] = "platform36_timeoffset"
    d["flights"] = [{"file": "a.csv", "n_samples": 1, "sigma": 0.1, "coefficients": []}]
    a = impact_analysis(paper_sim.flight, d)
    j = a.names.index("dt_trk")
    assert a.coefficient_status[j] == "per-flight" and a.contributions[0, j] == 0.0
    b = impact_analysis(paper_sim.flight, d, per_flight={"dt_trk": 2.0})
    np.testing.assert_allclose(b.contributions[:, j], 2.0 * b.sensitivity[:, j])
    np.testing.assert_allclose(b.miss - a.miss, 2.0 * b.sensitivity[:, j], rtol=0, atol=1e-9)
    # dt_trk moves the state along its own ballistic arc, (dr, dv) = (v_b, g_b) dt (after tail-off f = 0):
    # the impact point does not move (m per ms: tiny against S_P's 4 m per ms times J's ~1 m/m)
    assert np.all(np.abs(b.sensitivity[:, j]) < 1e-3) and np.linalg.norm(b.sp[:, j]) > 1.0
    np.testing.assert_allclose(a.cov, b.cov)  # a given value has no uncertainty
    with pytest.raises(ValueError, match="not a per-flight coefficient"):
        impact_analysis(paper_sim.flight, d, per_flight={"Kg0x": 1.0})


# ----------------------------------------------------------------------------- command line
@pytest.fixture(scope="module")
def files(tmp_path_factory, paper_sim, paper_ols):
    from casep.simulation.simulate import write_simulation

    d = tmp_path_factory.mktemp("impact")
    write_simulation(paper_sim, d / "flight.csv")
    (d / "result.json").write_text(json.dumps(paper_ols.to_dict()))
    return d


def test_cli_writes_spec_json_and_figures(files, tmp_path, capsys):
    out, figs = tmp_path / "impact.json", tmp_path / "figs"
    assert main(["impact", str(files / "flight.csv"), "--result", str(files / "result.json"), "--json", str(out),
                 "--figures", str(figs)]) == 0
    text = capsys.readouterr().out
    assert "predicted miss (linear)" in text and "nonlinear miss" in text and "Kg0x" in text
    d = json.loads(out.read_text())
    assert set(d["burnout"]) == {"t", "r", "v"} and len(d["burnout"]["r"]) == 3 and len(d["burnout"]["v"]) == 3
    assert {"downrange", "crossrange"} <= set(d["nominal_impact"])
    n = len(casep.load_model("platform36").names)
    assert len(d["sensitivity"]) == n
    for s in d["sensitivity"]:
        assert {"name", "unit", "dr", "dv", "downrange", "crossrange"} <= set(s)
        assert len(s["dr"]) == 3 and len(s["dv"]) == 3
    m = d["miss"]
    assert {"downrange", "crossrange", "std_downrange", "std_crossrange", "cov", "nonlinear"} <= set(m)
    assert np.array(m["cov"]).shape == (2, 2) and set(m["nonlinear"]) == {"downrange", "crossrange"}
    assert m["std_downrange"] == pytest.approx(np.sqrt(m["cov"][0][0]))
    assert len(d["contributions"]) == n
    total = np.sum([[c["downrange"], c["crossrange"]] for c in d["contributions"]], axis=0)
    np.testing.assert_allclose(total, [m["downrange"], m["crossrange"]], rtol=1e-9)
    assert sorted(p.name for p in figs.iterdir()) == ["impact_ellipse.png", "miss_budget.png"]


def test_cli_trajectory_predicts_another_flight(files, tmp_path, paper_ols, capsys):
    """--trajectory OTHER.csv (no dv columns): the result's D and Cov on OTHER's S_V and burnout."""
    from casep.io.files import write_table
    from casep.simulation.simulate import simulate_flight

    other = simulate_flight("paper-azimuth", seed=5, rate=10.0)
    fl = other.flight
    cols = {"t": fl.t, **{f"f_{a}": fl.f[:, i] for i, a in enumerate("xyz")},
            **{c: fl.signals[c] for c in STATE_COLUMNS}}
    write_table(tmp_path / "other.csv", cols)
    out = tmp_path / "o.json"
    assert main(["impact", str(files / "flight.csv"), "--result", str(files / "result.json"),
                 "--trajectory", str(tmp_path / "other.csv"), "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["trajectory"].endswith("other.csv")
    np.testing.assert_allclose(d["burnout"]["r"], [fl.signals[c][-1] for c in STATE_COLUMNS[:3]])
    a = impact_analysis(fl, paper_ols)  # same numbers through the API on the other flight
    assert d["miss"]["downrange"] == pytest.approx(a.miss[0], rel=1e-9)
    assert d["miss"]["std_crossrange"] == pytest.approx(a.std[1], rel=1e-9)
    # the prediction is honest: the true miss of the other flight lies within 4 std of it
    true = impact_analysis(fl, dataclasses.replace(paper_ols, estimate=other.truth.copy())).nonlinear
    assert np.all(np.abs(a.miss - true) < 4 * a.std), (a.miss, true, a.std)


def test_cli_flight_without_state_columns_exit_2(tmp_path, paper_sim, files, capsys):
    fl = paper_sim.flight
    bare = casep.FlightData(fl.t, fl.f, fl.dv, signals={"a_x": fl.signals["a_x"]})
    p = tmp_path / "bare.csv"
    casep.write_flight(bare, p)
    assert main(["impact", str(p), "--result", str(files / "result.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "bare.csv" in err
    for c in STATE_COLUMNS:
        assert c in err


def test_cli_result_of_another_model_exit_2(files, capsys):
    assert main(["impact", str(files / "flight.csv"), "--result", str(files / "result.json"),
                 "--model", "platform39_misalignment"]) == 2
    err = capsys.readouterr().err
    assert "platform36" in err and "platform39_misalignment" in err


def test_cli_not_a_result_exit_2(files, tmp_path, capsys):
    p = tmp_path / "x.json"
    p.write_text('{"a": 1}')
    assert main(["impact", str(files / "flight.csv"), "--result", str(p)]) == 2
    assert "not a result: missing field `coefficients`" in capsys.readouterr().err


def test_lazy_names():
    import casep.impact as ci

    for name in ci.__all__:
        assert getattr(ci, name) is not None
    assert casep.impact_analysis is impact_analysis
