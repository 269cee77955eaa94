"""Model files that use more than the specific force: m.t, m.signal, set_velocity_error, per_flight.

References are independent of casep's S_V path: an ODE integration (scipy solve_ivp) of the
model equations, noise-free exact recovery, numpy least squares, finite differences of the
simulated attitude, and a seeded Monte Carlo against the Cramer-Rao bound.
"""

from __future__ import annotations

import dataclasses
import runpy
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from conftest import run_forked

import casep
from casep.io.flight import FlightDataError
from casep.simulation.noise import NoiseModel
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight
from casep.units import DEG_PER_HOUR, G0


def _casep(argv: list[str], cwd: Path | None = None) -> tuple[int, str, str]:
    """``python -m casep ARGV`` as the entry point in a forked child (:func:`conftest.run_forked`): ``(status, out,
    err)``, without a new interpreter's 1.2-1.5 s of CPU importing casep, NumPy, SciPy and CasADi."""
    from casep.cli import main

    return run_forked(lambda: main(argv), ["casep", *argv], cwd or Path.cwd())


def _lstsq(S: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares on unit-norm columns (numpy, not casep's estimators)."""
    A = S.reshape(-1, S.shape[-1])
    c = np.linalg.norm(A, axis=0)
    return np.linalg.lstsq(A / c, y.reshape(-1), rcond=None)[0] / c


def _noise_free(**kw):
    sc = dataclasses.replace(get_scenario("paper"), noise=NoiseModel("white", 0.0))
    return sc, simulate_flight(sc, seed=1, rate=20.0, **kw)


def _sv(sim):
    m, fl = sim.model, sim.flight
    return casep.build_sv(m, fl.t, fl.f, signals=fl.model_signals(m.signals, m.name))


# ------------------------------------------------------------------ model API
def test_signal_api_records_used_columns_and_per_flight():
    m = casep.ErrorModel("sig")
    c = m.declare(k1="mg")
    d = m.declare(dt="ms", per_flight=True)
    unused = m.signal("temp_unused")  # asked for, used in no output: not required
    assert m.signal("a_x") is m.signal("a_x")  # same name, same symbol
    m.set_accel_error(ca.vertcat(c.k1 * m.t, 0, 0))
    m.set_velocity_error(ca.vertcat(m.signal("a_x") * d.dt, 0, 0))
    m.setup()
    assert unused is not None and m.signals == ("a_x",)
    assert m.per_flight.tolist() == [False, True]
    assert m.numeric("velocity_columns").tolist() == [1]
    J = np.array(m.functions["dvelocity_error_dD"](np.zeros(3), 0.0, [3.0]))
    np.testing.assert_allclose(J, [[0.0, 3e-3], [0, 0], [0, 0]], rtol=1e-15)  # a_x * 1 ms, m/s per ms


@pytest.mark.parametrize("name, hint", [("t", "model.t"), ("f_x", "model.f"), ("dv_y", "observation")])
def test_signal_refuses_reserved_columns(name, hint):
    with pytest.raises(ValueError, match=hint):
        casep.ErrorModel("x").signal(name)


def test_initial_term_may_not_use_signals():
    m = casep.ErrorModel("x")
    c = m.declare(v="m/s")
    m.set_initial_velocity_error(ca.vertcat(c.v * m.signal("a_x"), 0, 0))
    with pytest.raises(casep.ModelDefinitionError, match="initial term is constant"):
        m.setup()


def test_velocity_error_must_be_linear_and_without_free_term():
    m = casep.ErrorModel("x")
    c = m.declare(v="m/s")
    m.set_velocity_error(ca.vertcat(c.v + m.signal("a_x"), 0, 0))  # a_x alone: no coefficient
    with pytest.raises(casep.ModelDefinitionError, match="term without a coefficient"):
        m.setup()
    m = casep.ErrorModel("y")
    c = m.declare(v="m/s")
    m.set_velocity_error(ca.vertcat(c.v * c.v * m.t, 0, 0))
    with pytest.raises(casep.ModelDefinitionError, match="not linear"):
        m.setup()


def test_velocity_error_locked_after_setup():
    m = casep.load_model("platform36_timeoffset")
    with pytest.raises(RuntimeError, match="locked"):
        m.set_velocity_error([0, 0, 0])


def test_models_verbose_lists_per_flight_and_signals():
    code, stdout, err = _casep(["models", "-v"])
    assert code == 0, err
    rows = {ln.split()[0]: ln for ln in stdout.splitlines() if ln.startswith("    ") and ln.split()}
    assert rows["dt_trk"].split()[1] == "ms" and rows["dt_trk"].rstrip().endswith("per flight")
    assert "signals: a_x, a_y, a_z" in stdout
    assert rows["Kg0x_dot"].split()[1] == "deg/h/s"


# ------------------------------------------- S_V against an ODE integration
def _force(t):
    return np.stack([3.0 * np.sin(0.5 * t), 10.0 + 0.2 * t, 2.0 * np.cos(0.3 * t)], -1)  # m/s^2


def _temp(t):
    return 20.0 + 5.0 * np.sin(0.2 * t)  # a "temperature" signal, degC


def _accel(t):
    return np.stack([np.cos(t), 0.5 * t, np.ones_like(t)], -1)  # an "a_*" signal, m/s^2


def test_sv_with_time_and_signals_matches_ode_integration():
    from scipy.integrate import solve_ivp

    m = casep.ErrorModel("odecheck")
    c = m.declare(Kg0x="deg/h", Kg0x_dot="deg/h/s", Kg1z="deg/h/g", Ka0y="mg", KaT="ug", dt_trk="ms")
    W = m.W
    m.set_gyro_drift(ca.vertcat(c.Kg0x + c.Kg0x_dot * m.t, 0, c.Kg1z * W[2]))
    m.set_accel_error(ca.vertcat(0, c.Ka0y + c.KaT * (m.signal("temp") - 20.0), 0))
    a = ca.vertcat(m.signal("a_x"), m.signal("a_y"), m.signal("a_z"))
    m.set_velocity_error(a * c.dt_trk)
    m.setup()
    D = np.array([0.5, 0.01, 0.2, -2.0, 300.0, 20.0])  # natural units
    # SI values, independently of casep: deg/h -> rad/s, mg -> m/s^2, ug -> m/s^2, ms -> s
    g0x, g0xd, g1z = D[0] * DEG_PER_HOUR, D[1] * DEG_PER_HOUR, D[2] * DEG_PER_HOUR
    a0y, kat, dt = D[3] * 1e-3 * G0, D[4] * 1e-6 * G0, D[5] * 1e-3
    t0 = 3.0  # flights need not start at 0: m.t is time since the first sample

    def rhs(t, x):
        f = _force(t)
        tau = t - t0
        phidot = np.array([g0x + g0xd * tau, 0.0, g1z * f[2] / G0])
        delta = np.array([0.0, a0y + kat * (_temp(t) - 20.0), 0.0])
        return np.concatenate([phidot, np.cross(f, x[:3]) + delta])  # dWdot = f x phi + Delta

    t = t0 + np.arange(0.0, 60.0, 0.005)
    sol = solve_ivp(rhs, (t[0], t[-1]), np.zeros(6), t_eval=t, method="DOP853", rtol=1e-12, atol=1e-14)
    dv_ode = sol.y[3:].T + _accel(t) * dt  # + the direct term, not integrated
    sig = {"temp": _temp(t), **{f"a_{ax}": _accel(t)[:, i] for i, ax in enumerate("xyz")}}
    dv = casep.build_sv(m, t, _force(t), signals=sig, chunk=1000) @ D
    scale = np.abs(dv_ode).max()
    assert np.abs(dv - dv_ode).max() / scale < 2e-6  # trapezoid O(dt^2) at 200 Hz
    # chunk boundaries change nothing
    dv2 = casep.build_sv(m, t, _force(t), signals=sig, chunk=333) @ D
    np.testing.assert_allclose(dv2, dv, rtol=0, atol=1e-12 * scale)


def test_drift_ramp_model_matches_ode():
    from scipy.integrate import solve_ivp

    m = casep.load_model("platform36_drift_ramp")
    D = np.zeros(m.n_coefficients)
    D[m.index("Kg0x_dot")] = 0.02  # deg/h per s
    t = np.arange(0.0, 40.0, 0.01)
    rate = 0.02 * DEG_PER_HOUR

    def rhs(tt, x):
        return np.concatenate([[rate * tt, 0.0, 0.0], np.cross(_force(tt), x[:3])])

    sol = solve_ivp(rhs, (0.0, 40.0), np.zeros(6), t_eval=t, method="DOP853", rtol=1e-12, atol=1e-16)
    dv = casep.build_sv(m, t, _force(t)) @ D
    assert np.abs(dv - sol.y[3:].T).max() / np.abs(sol.y[3:]).max() < 1e-5


# ----------------------------------------------------- noise-free recovery
def test_time_offset_20ms_recovered_exactly_from_model_equation():
    sc, sim = _noise_free(model="platform36_timeoffset", truth={**get_scenario("paper").truth, "dt_trk": 20.0})
    x = _lstsq(_sv(sim), sim.flight.dv)
    assert abs(x[-1] - 20.0) / 20.0 < 1e-6
    np.testing.assert_allclose(x, sim.truth, rtol=1e-4)


def test_time_offset_20ms_exact_injection_recovered_to_second_order():
    """Exact v_trk(t) = v(t - 20 ms): the first-order model leaves da/dt dt^2 / 2, measured 0.24 %."""
    sc, sim = _noise_free(model="platform36_timeoffset", truth={**get_scenario("paper").truth, "dt_trk": 0.0},
                          time_offset=0.02)
    x = _lstsq(_sv(sim), sim.flight.dv)
    assert abs(x[-1] - 20.0) / 20.0 < 5e-3
    # without the term the same data bias Ka0y by far more than the offset's own error
    p36 = casep.load_model("platform36")
    x36 = _lstsq(casep.build_sv(p36, sim.flight.t, sim.flight.f), sim.flight.dv)
    j = p36.index("Ka0y")
    assert abs(x36[j] - sim.truth[j]) > 10 * abs(x[j] - sim.truth[j])


def test_lever_arm_recovered_exactly():
    lever = [1.5, -0.4, 0.3]
    sc, sim = _noise_free(model="platform36_leverarm", truth=dict(get_scenario("paper").truth), lever_arm=lever)
    x = _lstsq(_sv(sim), sim.flight.dv)
    np.testing.assert_allclose(x[-3:], lever, rtol=1e-6)


def test_simulated_body_rate_is_the_derivative_of_the_attitude():
    from casep.simulation.trajectory import body_to_platform

    traj = get_scenario("paper")  # vehicle with the yaw manoeuvre: all three rates excited
    from casep.simulation.trajectory import simulate_boost

    tr = simulate_boost(traj.vehicle, 10.0)
    ts = np.array([5.0, 12.0, 40.0, 63.0, 81.0, 150.0])
    h = 1e-4
    kp, km, k0 = tr.kinematics(ts + h), tr.kinematics(ts - h), tr.kinematics(ts)
    C = [body_to_platform(k["attitude"][:, 0], k["attitude"][:, 1], k["attitude"][:, 2]) for k in (kp, km, k0)]
    Cdot = (C[0] - C[1]) / (2 * h)
    Om = np.einsum("kji,kjl->kil", C[2], Cdot)  # C^T Cdot = [omega_b x]
    omega = np.stack([Om[:, 2, 1], Om[:, 0, 2], Om[:, 1, 0]], -1)
    np.testing.assert_allclose(omega, k0["body_rate"], rtol=0, atol=1e-8)
    assert np.abs(k0["body_rate"]).max(0).min() > 0 or np.abs(k0["body_rate"][:, 2]).max() > 1e-3
    # kinematic acceleration = d v / dt
    np.testing.assert_allclose((kp["velocity"] - km["velocity"]) / (2 * h), k0["acceleration"], atol=1e-4)
    # at the sample times, kinematics() is what the trajectory stored
    k = tr.kinematics(tr.t[::97])
    np.testing.assert_allclose(k["body_rate"], tr.body_rate[::97], atol=1e-12)


def test_simulated_flight_columns_are_consistent():
    sim = simulate_flight("paper", seed=3, rate=10.0)
    s, fl = sim.flight.signals, sim.flight
    a = np.column_stack([s[f"a_{x}"] for x in "xyz"])
    v = np.column_stack([s[f"v_{x}"] for x in "xyz"])
    np.testing.assert_allclose(v + fl.dv, sim.trajectory.velocity + casep.build_sv(sim.model, fl.t, fl.f) @ sim.truth,
                               atol=1e-9)  # v_tel = v_trk + dv
    # a = f + gravity, gravity of the spherical Earth model
    r = sim.trajectory.position + [0.0, 6_371_000.0, 0.0]
    g = -3.986004418e14 * r / np.linalg.norm(r, axis=1)[:, None] ** 3
    np.testing.assert_allclose(a, fl.f + g, rtol=1e-12, atol=1e-9)


# ---------------------------------------------------------------- Monte Carlo
def test_time_offset_monte_carlo_unbiased_rms_at_crlb_and_coverage(rng):
    sc, sim = _noise_free(model="platform36_timeoffset", truth={**get_scenario("paper").truth, "dt_trk": 20.0})
    S = _sv(sim).reshape(-1, sim.model.n_coefficients)
    clean = sim.flight.dv.reshape(-1)
    sigma, runs = 0.1, 400
    c = np.linalg.norm(S, axis=0)
    Q, R = np.linalg.qr(S / c)
    Rinv = np.linalg.inv(R)
    crlb = sigma * np.linalg.norm(Rinv[-1]) / c[-1]  # sqrt of sigma^2 (S^T S)^-1, last entry
    Y = clean[:, None] + sigma * rng.standard_normal((clean.size, runs))
    X = (Rinv @ (Q.T @ Y)) / c[:, None]
    resid = Y - S @ X
    s_hat = np.sqrt((resid**2).sum(0) / (S.shape[0] - S.shape[1]))
    std = s_hat * np.linalg.norm(Rinv[-1]) / c[-1]
    err = X[-1] - 20.0
    assert abs(err.mean()) < 3.0 * crlb / np.sqrt(runs)
    assert abs(np.sqrt(np.mean(err**2)) / crlb - 1.0) < 0.10
    cover = np.mean(np.abs(err) <= 1.959964 * std)
    assert 0.90 <= cover <= 0.99
    assert 0.1 < crlb < 1.0  # ms at 0.1 m/s and 20 Hz: the offset is identifiable


# ------------------------------------------------------------------ bad input
def test_missing_signal_column_names_model_column_and_file(tmp_path):
    sim = simulate_flight("paper", seed=1, rate=5.0)
    path = tmp_path / "plain.csv"
    casep.io.files.write_table(path, {"t": sim.flight.t, **{f"f_{a}": sim.flight.f[:, i] for i, a in enumerate("xyz")},
                                      **{f"dv_{a}": sim.flight.dv[:, i] for i, a in enumerate("xyz")}})
    code, _, err = _casep(["separate", str(path), "--model", "platform36_leverarm"], tmp_path)
    assert code == 2
    err = err.strip()
    assert len(err.splitlines()) == 1
    assert "platform36_leverarm" in err and "missing column" in err and "`omega_x`" in err and str(path) in err
    with pytest.raises(ValueError, match="needs flight column"):
        casep.build_sv(casep.load_model("platform36_timeoffset"), sim.flight.t, sim.flight.f)


def test_nan_signal_names_the_row(tmp_path):
    sim = simulate_flight("paper", seed=1, rate=5.0)
    path = tmp_path / "f.csv"
    casep.write_flight(sim.flight, path)
    lines = path.read_text().splitlines()
    header = [i for i, ln in enumerate(lines) if ln.startswith("t,")][0]
    cols = lines[header].split(",")
    row = lines[header + 7].split(",")
    row[cols.index("a_y")] = "nan"
    lines[header + 7] = ",".join(row)
    path.write_text("\n".join(lines) + "\n")
    fl = casep.read_flight(path)  # read fine: platform36 does not use a_y
    assert np.isnan(fl.signals["a_y"][6])
    with pytest.raises(FlightDataError, match=r"column `a_y`, row 7.*platform36_timeoffset") as e:
        fl.model_signals(("a_x", "a_y"), "platform36_timeoffset")
    assert str(path) in str(e.value)
    code, _, err = _casep(["separate", str(path), "--model", "platform36_timeoffset"], tmp_path)
    assert code == 2 and "row 7" in err and "a_y" in err


def test_signals_round_trip_and_text_columns_ignored(tmp_path):
    sim = simulate_flight("paper", seed=2, rate=2.0)
    for name in ("f.csv", "f.parquet"):
        casep.write_flight(sim.flight, tmp_path / name)
        back = casep.read_flight(tmp_path / name)
        assert list(back.signals) == list(sim.flight.signals)
        for k, v in sim.flight.signals.items():
            np.testing.assert_array_equal(back.signals[k], v)
    text = tmp_path / "text.csv"
    text.write_text("t,f_x,f_y,f_z,dv_x,dv_y,dv_z,note,temp\n0,0,9,0,0,0,0,ok,20\n1,0,9,0,0,0,0,ok,21\n")
    fl = casep.read_flight(text)
    assert list(fl.signals) == ["temp"] and fl.signals["temp"].tolist() == [20.0, 21.0]


def test_simulate_cli_offset_and_lever_arm(tmp_path):
    import json

    out = tmp_path / "f.csv"
    code, _, err = _casep(["simulate", "--rate", "5", "--tracking-offset", "20", "--lever-arm", "1", "0", "0.5", "-o",
                           str(out)], tmp_path)
    assert code == 0, err
    truth = json.loads((tmp_path / "f.truth.json").read_text())
    assert truth["tracking"] == {"time_offset_ms": 20.0, "lever_arm_m": [1.0, 0.0, 0.5]}
    fl = casep.read_flight(out)
    assert {"a_x", "r_z", "v_y", "att_pitch", "omega_z"} <= set(fl.signals)
    code, _, err = _casep(["simulate", "--tracking-offset", "5000", "-o", str(tmp_path / "g.csv")], tmp_path)
    assert code == 2 and "--tracking-offset" in err


def test_two_rate_example_dt_trk_removes_the_ka0y_bias(tmp_path):
    example = str(Path(__file__).resolve().parents[2] / "examples" / "two_rate_workflow.py")
    code, out, err = run_forked(lambda: runpy.run_path(example, run_name="__main__"),
                                [example, "--quick", "--out", str(tmp_path)], tmp_path, path0=str(Path(example).parent),
                                timeout=600)
    assert code == 0, err
    assert "20 ms offset" in out and (tmp_path / "tracking.parquet").exists()  # the example's run (test_examples.py)
    line = next(ln for ln in out.splitlines() if ln.startswith("Ka0y"))
    before, after = (float(x) for x in line.split("bias/std ")[1].split(";")[0].split(" -> "))
    vs_ref = float(line.split("fitted - no offset ")[1].split()[0])
    assert before < -5.0  # unmodelled 20 ms: Ka0y many (honest, tracking-grid) std off
    assert abs(vs_ref) < 1.0  # dt_trk fitted: as if there were no offset
    dt = next(ln for ln in out.splitlines() if ln.startswith("dt_trk")).split()
    est, std = float(dt[2]), float(dt[4])
    assert abs(est - 20.0) < 4.0 * std


def test_model_signals_paper_example_runs(tmp_path):
    example = str(Path(__file__).resolve().parents[2] / "examples" / "model_signals_paper.py")
    code, out, err = run_forked(lambda: runpy.run_path(example, run_name="__main__"), [example, "--quick"], tmp_path,
                                path0=str(Path(example).parent), timeout=600)
    assert code == 0, err
    assert "dt_trk" in out and "VIF" in out and "lever arm (1.5, -0.4, 0.3) m: new terms [1.5, -0.4, 0.3]" in out
