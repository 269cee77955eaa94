"""casep design: manoeuvre parametrisation, exact gradients, a closed-form optimum, the
designed flight reaching the predicted CRLB, constraints as flown, the command line.

Small on purpose: coarse design grids (1-2 Hz), flights at 5 Hz, few knots, one or two starts.
"""

from __future__ import annotations

import dataclasses
import json

import casadi as ca
import numpy as np
import pytest

import casep
from casep.cli import main
from casep.design.maneuver import Maneuver, interpolation_matrix
from casep.design.objective import DesignProblem, fisher_information, objective_value
from casep.design.optimize import design
from casep.model.loader import load_model
from casep.model.sv import build_sv
from casep.simulation.scenarios import get_scenario
from casep.simulation.trajectory import AttitudeProfile, simulate_boost


@pytest.fixture(scope="module")
def coarse():
    sc = get_scenario("paper")
    return sc, simulate_boost(sc.vehicle, 1.0)


def _one_coefficient_model():
    """Accelerometer z scale factor only: its S_V column is (1e-6 / G0 per ug/g) int f_z dt."""
    m = casep.ErrorModel("onez", "z scale factor only")
    c = m.declare(Kaz=("ug/g", 50.0))
    m.set_accel_error(ca.vertcat(0, 0, c.Kaz * m.W[2]))
    return m.setup()


def test_interpolation_matrix_and_profile_agree():
    knots = np.array([10.0, 20.0, 40.0])
    t = np.array([0.0, 10.0, 15.0, 30.0, 40.0, 50.0])
    B = interpolation_matrix(knots, t)
    v = np.array([0.0, 2.0, -4.0])
    prof = AttitudeProfile(tuple(knots), (0.0, 0.0, 0.0), tuple(v))
    np.testing.assert_allclose(B @ v, [np.degrees(prof.offsets(x)[1]) for x in t], atol=1e-12)
    mv = Maneuver("both", tuple(knots))
    x = np.array([1.0, 2.0, 3.0, -1.0])  # pitch knots 2, 3 then yaw knots 2, 3
    s = mv.split(x)
    np.testing.assert_allclose(s["pitch"], [0, 1, 2])
    np.testing.assert_allclose(s["yaw"], [0, 3, -1])
    np.testing.assert_allclose(mv.rate_matrix() @ x, [0.1, 0.05, 0.3, -0.2])
    with pytest.raises(ValueError, match="unknown maneuver"):
        Maneuver("roll", (0.0, 1.0))


def test_gradient_matches_finite_differences(coarse):
    sc, tr = coarse
    model = load_model("platform36")
    scales = np.array([model.scales[n] for n in model.names])
    G = np.random.default_rng(3).standard_normal((2, model.n_coefficients)) * 1e3 / scales
    mv = Maneuver("both", tuple(np.linspace(16.0, 195.0, 4)))
    dp = DesignProblem(model, tr.t, tr.attitude, tr.specific_force, mv, rate=100.0, sigma=0.1, scales=scales,
                       miss_sensitivity=G)
    x0 = np.array([1.0, -2.0, 3.0, 2.5, -1.5, 0.5])
    for kind in ("A", "D", "miss"):
        J = dp.objective_expr(kind)
        fg = ca.Function("fg", [dp.x], [J, ca.gradient(J, dp.x)])
        grad = np.array(fg(x0)[1]).ravel()
        h = 1e-2  # deg; smaller steps drown in the objective's round-off (about 1e-11 absolute)
        fd = np.array([(float(fg(x0 + h * e)[0]) - float(fg(x0 - h * e)[0])) / (2 * h) for e in np.eye(x0.size)])
        np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-8 * np.max(np.abs(fd)))
        # the reported value is the numpy twin's on the same information
        F = np.array(dp.fisher(x0))
        assert dp.value(kind, x0) == pytest.approx(objective_value(kind, F, scales, None, G), rel=1e-9)


def test_design_fisher_matches_sv_of_the_rotated_force(coarse):
    """The symbolic chain is the model's S_V: same numbers as build_sv on the rotated specific force."""
    sc, tr = coarse
    model = load_model("platform36")
    scales = np.array([model.scales[n] for n in model.names])
    mv = Maneuver("both", tuple(np.linspace(16.0, 195.0, 5)))
    dp = DesignProblem(model, tr.t, tr.attitude, tr.specific_force, mv, rate=1.0, sigma=1.0, scales=scales)
    x = np.array([2.0, -3.0, 1.0, 4.0, -1.0, 2.0, 3.0, -4.0])
    off = mv.split(x)
    B = interpolation_matrix(mv.knots, tr.t)
    th = tr.attitude[:, 0] + np.radians(B @ off["pitch"])
    ps = tr.attitude[:, 1] + np.radians(B @ off["yaw"])
    e0 = np.column_stack([np.cos(tr.attitude[:, 1]) * np.cos(tr.attitude[:, 0]),
                          np.cos(tr.attitude[:, 1]) * np.sin(tr.attitude[:, 0]), np.sin(tr.attitude[:, 1])])
    a = np.einsum("ki,ki->k", tr.specific_force, e0)
    f = a[:, None] * np.column_stack([np.cos(ps) * np.cos(th), np.cos(ps) * np.sin(th), np.sin(ps)])
    S = build_sv(model, tr.t, f)
    S_sym = np.array(dp.sv(x)).reshape(3, model.n_coefficients, -1)  # component, coefficient, time
    np.testing.assert_allclose(S_sym.transpose(2, 0, 1), S, rtol=1e-10, atol=1e-12 * np.abs(S).max())
    w = np.full(tr.t.size, 1.0)
    w[[0, -1]] = 0.5  # trapezoid weights of the design's sum (uniform 1 s grid)
    F = np.einsum("k,kin,kim->nm", w, S, S)
    np.testing.assert_allclose(np.array(dp.fisher(x)), F, rtol=1e-9, atol=1e-12 * np.abs(F).max())
    assert fisher_information(S, 1.0) == pytest.approx(F + 0.5 * (np.einsum("in,im->nm", S[0], S[0])
                                                                  + np.einsum("in,im->nm", S[-1], S[-1])))


def test_single_coefficient_optimum_is_at_the_angle_bound():
    """Closed form: in a pitch-plane flight (f_z = 0) the only coefficient, the z scale factor, sees
    f_z = a sin(psi): its information sum_k (int a sin psi dt)^2 grows with |psi| everywhere, so the
    optimum holds every free knot at the same bound, +-max_angle."""
    model = _one_coefficient_model()
    res = design("paper-pitch", model=model, maneuver="yaw", objective="A", max_angle=3.0, max_rate=10.0,
                 max_lateral=10.0, knots=4, design_rate=1.0, rate=5.0, starts=2, seed=1, verify=False)
    assert res.solver["success"], res.solver
    np.testing.assert_allclose(np.abs(res.x), 3.0, atol=1e-5)
    assert len(set(np.sign(res.x))) == 1
    assert np.isnan(res.crlb_before[0])  # f_z = 0 in the nominal flight: not identifiable at all
    assert np.isfinite(res.crlb_after[0]) and res.after < res.before


@pytest.fixture(scope="module")
def designed():
    return design("paper", maneuver="yaw", objective="A", max_angle=10.0, max_rate=1.0, max_lateral=0.3, knots=5,
                  design_rate=2.0, rate=5.0, starts=1, max_iter=60)


def test_designed_flight_reaches_the_predicted_crlb(designed):
    """Monte Carlo (reduced): OLS on the re-simulated designed flight over many noise draws has the RMS
    that the design predicted, for the coefficients the design improves."""
    res = designed
    sc = res.scenario
    model = load_model(sc.model)
    traj = simulate_boost(sc.vehicle, sc.rate)
    S = build_sv(model, traj.t, traj.specific_force).reshape(-1, model.n_coefficients)
    c = np.linalg.norm(S, axis=0)
    Q, R = np.linalg.qr(S / c)
    rng = np.random.default_rng(7)
    runs = 1000
    noise = sc.noise.sigma * rng.standard_normal((S.shape[0], runs))
    err = np.linalg.solve(R, Q.T @ noise) / c[:, None]  # OLS estimate minus truth, natural units
    rms = np.sqrt(np.mean(err**2, axis=1))
    improved = np.isfinite(res.predicted_after) & (res.predicted_after < 0.8 * res.predicted_before)
    assert improved.sum() >= 5
    ratio = rms[improved] / res.predicted_after[improved]
    assert np.all((ratio > 0.85) & (ratio < 1.15)), dict(zip(np.array(res.names)[improved], ratio))
    np.testing.assert_allclose(res.crlb_after, res.predicted_after, rtol=0.1)  # exact vs design model


def test_design_result_follows_the_result_protocol(designed):
    """to_dict() is plain data with finite numbers or nulls; success, status and message follow the
    optimiser's return status; the old names warn."""
    from casep.results import Result

    res = designed
    assert isinstance(res, Result)
    d = res.to_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert res.success == bool(res.solver["success"]) and res.status == (0 if res.success else 1)
    assert res.solver["return_status"] in res.message
    with pytest.warns(DeprecationWarning, match="to_json"):
        assert res.to_json() == d
    with pytest.warns(DeprecationWarning, match="table"):
        assert res.table() == res.crlb_table()
    assert res.crlb_table() in res.text()
    stuck = dataclasses.replace(res, solver={**res.solver, "success": False, "return_status": "Maximum_Iterations"})
    assert not stuck.success and stuck.status == 1 and "did not converge" in stuck.message


def test_constraints_hold_on_the_simulated_flight(designed, tmp_path):
    from casep.simulation.simulate import simulate_flight

    res = designed
    lim = res.constraints
    flown = lim["flown"]
    assert flown["max_yaw_offset_deg"] <= lim["max_angle_deg"] * (1 + 1e-6)
    assert flown["max_yaw_rate_deg_s"] <= lim["max_rate_deg_s"] * (1 + 1e-3)
    assert flown["max_lateral_g"] <= lim["max_lateral_g"] * 1.03
    assert lim["design"]["max_lateral_g"] <= lim["max_lateral_g"] * (1 + 1e-6)
    assert lim["design"]["max_lateral_g"] > 0.8 * lim["max_lateral_g"]  # the lateral limit binds here
    # the flight file that -o writes: its attitude columns, against the nominal flight's
    sim = simulate_flight(res.scenario, seed=0)
    nom = simulate_flight(dataclasses.replace(res.scenario, vehicle=dataclasses.replace(res.scenario.vehicle,
                                                                                       attitude=None)), seed=0)
    d = np.degrees(sim.flight.signals["att_yaw"] - nom.flight.signals["att_yaw"])
    assert np.max(np.abs(d)) <= lim["max_angle_deg"] * (1 + 1e-6)
    rate = np.diff(d) / np.diff(sim.flight.t)
    assert np.max(np.abs(rate)) <= lim["max_rate_deg_s"] * (1 + 1e-6)


def test_simulator_without_profile_is_unchanged():
    sc = get_scenario("paper")
    a = simulate_boost(sc.vehicle, 2.0)
    b = simulate_boost(dataclasses.replace(sc.vehicle, attitude=AttitudeProfile((20.0, 100.0), (0.0, 0.0),
                                                                                 (0.0, 0.0))), 2.0)
    np.testing.assert_allclose(b.specific_force, a.specific_force, rtol=1e-7, atol=1e-7)
    with pytest.raises(ValueError, match="strictly increasing"):
        AttitudeProfile((1.0, 1.0), (0.0, 0.0), (0.0, 0.0))


def test_cli_design_json_and_flight(tmp_path, capsys):
    out, flight = tmp_path / "d.json", tmp_path / "designed.csv"
    prior = tmp_path / "prior.json"
    prior.write_text(json.dumps({"Kg0z": {"mean": 0.0, "std": 0.5}, "Ka1z": {"mean": 0.0, "std": 0.5}}))
    status = main(["design", "--rate", "5", "--knots", "4", "--starts", "1", "--max-angle", "8", "--prior", str(prior),
                   "--json", str(out), "-o", str(flight), "--figure", str(tmp_path / "d.png")])
    text = capsys.readouterr().out
    assert status in (0, 1) and "A-optimal yaw manoeuvre" in text
    doc = json.loads(out.read_text())
    for key in ("objective", "before", "after", "maneuver", "crlb_before", "crlb_after", "constraints"):
        assert key in doc
    assert doc["objective"] == "A" and doc["constraints"]["max_angle_deg"] == 8.0
    assert doc["bound"].startswith("Bayesian") and set(doc["crlb_after"]) == set(load_model("platform36").names)
    assert doc["solver"]["return_status"] and isinstance(doc["solver"]["success"], bool)
    assert doc["after"] <= doc["before"]
    f = casep.read_flight(flight)
    assert f.n_samples == 976 and (tmp_path / "designed.truth.json").exists()
    assert (tmp_path / "d.png").stat().st_size > 0


@pytest.mark.parametrize("argv, message", [
    (["--objective", "E"], "option --objective (`objective`) must be "),
    (["--max-angle=-3"], "--max-angle must be > 0"),
    (["--max-rate", "0"], "--max-rate must be > 0"),
    (["--maneuver", "roll"], "option --maneuver (`maneuver`) must be yaw | pitch | both, got 'roll'"),
])
def test_cli_bad_input_exits_2(argv, message, capsys):
    try:
        status = main(["design", *argv])
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_api_bad_input():
    with pytest.raises(ValueError, match="unknown objective `E`"):
        design("paper", objective="E")
    with pytest.raises(ValueError, match=r"option --max-angle \(`max_angle`\) must be a number > 0"):
        design("paper", max_angle=-1.0)


def test_example_runs(tmp_path):
    """``python examples/maneuver_design.py --quick`` in a forked child (:func:`conftest.run_forked`: no new
    interpreter importing casep, NumPy, SciPy and CasADi again)."""
    import runpy
    from pathlib import Path

    from conftest import run_forked

    script = str(Path(__file__).resolve().parents[2] / "examples" / "maneuver_design.py")
    code, out, err = run_forked(lambda: runpy.run_path(script, run_name="__main__"),
                                [script, "--quick", "--out", str(tmp_path)], tmp_path, path0=str(Path(script).parent),
                                timeout=600)
    assert code == 0, err[-2000:]
    assert "max 10.0 deg: A" in out and (tmp_path / "maneuver_design.png").exists()
    assert "reported std / design CRLB in [1.0000, 1.0000]" in out


def test_a_objective_over_a_subset(coarse):
    sc, tr = coarse
    model = load_model("platform36")
    scales = np.array([model.scales[n] for n in model.names])
    w = np.zeros(model.n_coefficients)
    w[[model.index("Kg0z"), model.index("Ka1z")]] = 1.0
    mv = Maneuver("yaw", tuple(np.linspace(16.0, 195.0, 3)))
    dp = DesignProblem(model, tr.t, tr.attitude, tr.specific_force, mv, rate=100.0, sigma=0.1, scales=scales,
                       weights=w)
    x = np.array([3.0, -2.0])
    F = np.array(dp.fisher(x))
    M = F * np.outer(scales, scales) + 1e-2 * np.eye(model.n_coefficients)
    C = np.linalg.inv(M)
    assert dp.value("A", x) == pytest.approx(C[model.index("Kg0z"), model.index("Kg0z")]
                                             + C[model.index("Ka1z"), model.index("Ka1z")], rel=1e-8)
    with pytest.raises(ValueError, match="Kg0q"):
        design("paper", coefficients=["Kg0q"])


def test_cli_reports_what_the_design_costs(tmp_path, capsys):
    """Fresh-eyes review: the console says where the designed flight burns out, which bounds get
    worse, and the JSON's before/after are the re-simulated values (the design model's under
    `predicted`), with the regularisation recorded when there is no prior."""
    import json

    from casep.cli import main

    out = tmp_path / "d.json"
    assert main(["design", "--maneuver", "yaw", "--max-angle", "5", "--knots", "4", "--starts", "1", "--rate", "5",
                 "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "the designed flight burns out elsewhere" in text and "crossrange" in text
    d = json.loads(out.read_text())
    assert d["objective_source"] == "re-simulated flights"
    assert d["before"] == pytest.approx(d["verification"]["before"]) \
        and d["after"] == pytest.approx(d["verification"]["after"])
    assert "before" in d["predicted"] and d["regularisation"]["information"] > 0
    ratio = {n: d["crlb_after"][n] / d["crlb_before"][n] for n in d["crlb_before"]
             if d["crlb_before"][n] and d["crlb_after"][n]}
    worse = [n for n, r in ratio.items() if r > 1.05]
    assert (("worse after the design" in text) == bool(worse)) and all(n in text for n in worse)
