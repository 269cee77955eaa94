"""Radar tracking errors in the same estimate (casep.radar, casep.model.tracking, casep.workflows.radar)."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import casadi as ca
import numpy as np
import pymap3d
import pytest
from conftest import dishonest_whitened, whitened_error

import casep
from casep.frames import LaunchSite, launch_to_ecef
from casep.model.error_model import ModelDefinitionError
from casep.model.loader import ModelFileError
from casep.model.tracking import TrackingModel, load_tracking_model
from casep.radar.geometry import RadarGeometry
from casep.radar.stations import RadarMeasurements, RadianAnglesWarning, Station, read_radar, read_station
from casep.simulation.radar import simulate_radar, write_radar_simulation
from casep.units import ARCSEC
from casep.workflows.radar import separate_radar

SITE = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)
#: elevation masks 10 deg below the horizon: the data of these tests keep the first samples, which a station's
#: default mask (the horizon) drops in the simulator (14 runs of the Monte Carlo below then gave tracking RMS z
#: 0.92 per coefficient; with the horizon mask, 14 runs on other noise draws gave 1.16: within their spread)
STATIONS = (Station("S1", 28.9, -80.0, 20.0, min_elevation_deg=-10.0),
            Station("S2", 28.1, -79.2, 15.0, min_elevation_deg=-10.0))
TRUTH = {"S1": {"range_bias": 5.0, "range_scale": 10.0, "azimuth_bias": 15.0, "elevation_bias": -20.0},
         "S2": {"range_bias": -3.0, "range_scale": -5.0, "azimuth_bias": -10.0, "elevation_bias": 12.0}}
NOISE = {"range": 3.0, "azimuth": 8.0, "elevation": 8.0}  # m, arcsec
SIGMA = {(s, ty): v * (ARCSEC if ty != "range" else 1.0) for s in ("S1", "S2") for ty, v in NOISE.items()}


@pytest.fixture(scope="module")
def clean():
    """A noise-free two-station flight at 20 Hz (telemetry and radar), station errors injected, no time bias."""
    return simulate_radar(STATIONS, SITE, seed=0, telemetry_rate=20, radar_rate=20, tracking_truth=TRUTH,
                          noise={"range": 0.0, "azimuth": 0.0, "elevation": 0.0})


@pytest.fixture(scope="module")
def clean_5hz():
    """The flight of :func:`clean` with radar at 5 Hz: a quarter of the rows (1.5 s of CPU a fit instead of 3.5)."""
    return simulate_radar(STATIONS, SITE, seed=0, telemetry_rate=20, radar_rate=5, tracking_truth=TRUTH,
                          noise={"range": 0.0, "azimuth": 0.0, "elevation": 0.0})


def _with_noise(sim, rng):
    """The same flight with fresh white noise of NOISE on every measurement (as simulate_radar adds it)."""
    out = []
    for m in sim.radars:
        n = m.t.size
        out.append(dataclasses.replace(m, range=m.range + rng.normal(0, NOISE["range"], n),
                                       azimuth=m.azimuth + rng.normal(0, NOISE["azimuth"] * ARCSEC, n),
                                       elevation=m.elevation + rng.normal(0, NOISE["elevation"] * ARCSEC, n)))
    return out


# ----------------------------------------------------------------------------- the tracking model
def test_tracking_model_lifecycle_and_checks():
    m = TrackingModel("t")
    c = m.declare(b="m", k=("ppm", 5.0))
    m.set_range_error(c.b + c.k * m.range)
    m.setup()
    assert m.names == ("b", "k") and m.units == ("m", "ppm") and m.scales == {"k": 5.0}
    with pytest.raises(RuntimeError, match="locked"):
        m.declare(x="m")
    bad = TrackingModel("nonlinear")
    c = bad.declare(b="m")
    bad.set_range_error(c.b * c.b)
    with pytest.raises(ModelDefinitionError, match="not linear"):
        bad.setup()
    free = TrackingModel("offset")
    c = free.declare(b="m")
    free.set_range_error(c.b + 0.01 * free.range)
    with pytest.raises(ModelDefinitionError, match="without a coefficient"):
        free.setup()
    unused = TrackingModel("unused")
    c = unused.declare(b="m", e="arcsec")
    unused.set_range_error(c.b)
    with pytest.raises(ModelDefinitionError, match="`e`.*used in no output"):
        unused.setup()
    foreign = TrackingModel("foreign")
    c = foreign.declare(b="m")
    foreign.set_range_error(c.b * ca.SX.sym("q"))
    with pytest.raises(ModelDefinitionError, match="`q`"):
        foreign.setup()


def test_radar_biases_T_against_finite_differences_and_closed_form():
    m = load_tracking_model("radar_biases")
    assert m.names == ("range_bias", "range_scale", "azimuth_bias", "elevation_bias", "time_bias")
    rng = np.random.default_rng(3)
    g = np.column_stack([rng.uniform(5e4, 5e5, 6), rng.uniform(-3, 3, 6), rng.uniform(0, 1.4, 6),
                         rng.uniform(-2e3, 2e3, 6), rng.uniform(-1e-2, 1e-2, 6), rng.uniform(-1e-2, 1e-2, 6),
                         rng.uniform(-50, 50, 6), rng.normal(0, 1e5, (6, 3)), rng.uniform(0, 200, 6)])
    T = m.jacobian(g)
    theta = rng.normal(0, 3, 5)
    h = 1e-3
    for j in range(5):  # central differences of the declared error expressions
        e = np.zeros(5)
        e[j] = h
        fd = (m.errors(g, theta + e) - m.errors(g, theta - e)) / (2 * h)
        np.testing.assert_allclose(T[:, :, j], fd, rtol=1e-9, atol=1e-18)
    # closed form of the conventions: (1 + s 1e-6) rho + b; A + a; E + e; tagged late by tau (ms)
    rho, rho_dot, a_dot, e_dot = g[:, 0], g[:, 3], g[:, 4], g[:, 5]
    np.testing.assert_allclose(T[:, 0, :], np.column_stack([np.ones(6), 1e-6 * rho, 0 * rho, 0 * rho,
                                                            -1e-3 * rho_dot]), rtol=1e-14)
    np.testing.assert_allclose(T[:, 1, 2], ARCSEC, rtol=1e-14)
    np.testing.assert_allclose(T[:, 2, 4], -1e-3 * e_dot, rtol=1e-14)
    np.testing.assert_allclose(T[:, 1, 4], -1e-3 * a_dot, rtol=1e-14)
    np.testing.assert_allclose(T[:, 3, :], np.column_stack([0 * rho, 1e-6 * rho_dot, 0 * rho, 0 * rho,
                                                            -1e-3 * g[:, 6]]), rtol=1e-14)


def test_radar_biases_is_a_tracking_model_not_an_instrument_model():
    with pytest.raises(ModelFileError, match="tracking model: use it with --tracking-model"):
        casep.load_model("radar_biases")
    with pytest.raises(ModelFileError, match="instrument model"):
        load_tracking_model("platform36")


# ----------------------------------------------------------------------------- geometry
def _random_states(rng, n=7):
    r = np.column_stack([rng.uniform(0, 4e5, n), rng.uniform(1e3, 2e5, n), rng.normal(0, 3e4, n)])
    v = rng.normal(0, 1.5e3, (n, 3))
    return rng.uniform(0, 250, n), r, v


def test_predicted_measurement_against_pymap3d():
    rng = np.random.default_rng(1)
    t, r, v = _random_states(rng)
    site = LaunchSite(28.5, -80.6, 3.0, 75.0, 12.5)
    for st in STATIONS:
        geo, _ = RadarGeometry(site, st).evaluate(t, r, v)
        r_e, v_e = launch_to_ecef(site, t, r, v)  # the frames module, then pymap3d's own aer
        az, el, rng_ = pymap3d.ecef2aer(r_e[:, 0], r_e[:, 1], r_e[:, 2], st.lat_deg, st.lon_deg, st.h_m)
        np.testing.assert_allclose(geo[:, 0], rng_, rtol=0, atol=1e-6)
        d_az = (np.radians(az) - geo[:, 1] + np.pi) % (2 * np.pi) - np.pi
        assert np.max(np.abs(d_az)) < 1e-9
        np.testing.assert_allclose(geo[:, 2], np.radians(el), rtol=0, atol=1e-9)
        # range rate: derivative of pymap3d's range along the ECEF motion (central difference in time)
        dt = 1e-3
        rp, _ = launch_to_ecef(site, t + dt, r + v * dt, v)
        rm, _ = launch_to_ecef(site, t - dt, r - v * dt, v)
        fd = (np.asarray(pymap3d.ecef2aer(*rp.T, st.lat_deg, st.lon_deg, st.h_m)[2])
              - np.asarray(pymap3d.ecef2aer(*rm.T, st.lat_deg, st.lon_deg, st.h_m)[2])) / (2 * dt)
        np.testing.assert_allclose(geo[:, 3], fd, rtol=0, atol=2e-4)


def test_range_acceleration_against_finite_differences():
    """d(range rate)/dt along a constant-acceleration motion, by central differences in time."""
    rng = np.random.default_rng(8)
    t, r, v = _random_states(rng)
    a = rng.normal(0, 30, r.shape)
    g = RadarGeometry(SITE, STATIONS[1])
    geo, _ = g.evaluate(t, r, v, a)
    h = 1e-3
    gp, _ = g.evaluate(t + h, r + v * h + 0.5 * a * h**2, v + a * h, a)
    gm, _ = g.evaluate(t - h, r - v * h + 0.5 * a * h**2, v - a * h, a)
    np.testing.assert_allclose(geo[:, 6], (gp[:, 3] - gm[:, 3]) / (2 * h), rtol=0, atol=2e-5)
    assert np.all(np.isnan(g.evaluate(t, r, v)[0][:, 6]))  # no acceleration given: no range acceleration


def test_H_against_finite_differences():
    rng = np.random.default_rng(2)
    t, r, v = _random_states(rng)
    g = RadarGeometry(SITE, STATIONS[0])
    _, H = g.evaluate(t, r, v)
    for j in range(6):
        h = 1e-2 if j < 3 else 1e-3
        e = np.zeros(6)
        e[j] = h
        gp, _ = g.evaluate(t, r + e[:3], v + e[3:])
        gm, _ = g.evaluate(t, r - e[:3], v - e[3:])
        d = gp[:, :4] - gm[:, :4]
        d[:, 1] = (d[:, 1] + np.pi) % (2 * np.pi) - np.pi
        fd = d / (2 * h)
        scale = np.array([1.0, 1e-5, 1e-5, 1e-2])  # m/m, rad/m, rad/m, (m/s)/m: magnitudes of the rows
        np.testing.assert_allclose(H[:, :, j] / scale, fd / scale, rtol=0, atol=1e-7)


# ----------------------------------------------------------------------------- separation
def _noise_free_errors(sim, radars):
    rr = separate_radar(sim.telemetry, radars, SITE, sim.model, sim.tracking, "ols",
                        sigma={k: v for k, v in SIGMA.items() if k[0] in {m.station.name for m in radars}},
                        diagnostics=False)
    names = rr.result.names
    truth = dict(zip(sim.model.names, sim.truth), dt_launch=0.0)  # the simulated launch time is the site's
    for m in radars:
        truth.update({f"{m.station.name}.{k}": sim.tracking_truth[m.station.name].get(k, 0.0)
                      for k in sim.tracking.names})
    x = np.array([truth[n] for n in names])
    return rr, (rr.result.estimate - x) / rr.result.std


def test_noise_free_two_stations_recovered_to_5e7_of_crlb(clean_5hz):
    """Radar at 5 Hz (0.6 s of CPU instead of 2.1; exact recovery needs no more rows): max |z| 1.6e-8 (3.3e-8 at
    20 Hz, whose std are half as large); the bound 5e-7, half the 20 Hz test's 1e-6, asks the same absolute error."""
    clean = clean_5hz
    rr, z = _noise_free_errors(clean, list(clean.radars))
    assert rr.result.success and np.all(np.isfinite(z))
    assert np.max(np.abs(z)) < 5e-7, dict(zip(rr.result.names, z))
    assert rr.result.names[-6:] == tuple(f"S2.{n}" for n in clean.tracking.names) + ("dt_launch",)


def test_noise_free_one_station_recovered_to_5e7_of_crlb(clean_5hz):
    """Radar at 5 Hz, the bound halved as in the two-station test: max |z| 1.5e-10 (4.1e-10 at 20 Hz)."""
    clean = clean_5hz
    rr, z = _noise_free_errors(clean, [clean.radars[0]])
    ok = np.isfinite(z)
    assert ok.sum() >= 30  # one station: what it identifies
    assert np.max(np.abs(z[ok])) < 5e-7


def test_time_bias_applied_exactly_is_recovered_to_first_order():
    """A 2 ms late time tag simulated exactly (state sampled at t - tau): the first-order term finds it
    within 0.5-1 % of its CRLB std (the second-order remainder tau^2 rho''/2), range rate included.

    Radar at 5 Hz (3.6 s of CPU instead of 9.2 at 20 Hz): max |z| 2.9e-4 without and 1.4e-3 with range rate
    (at 20 Hz, std half as large: 5.8e-4 and 2.7e-3); the bounds keep the margin of the 20 Hz test (17x and 7x).
    """
    tt = {"S1": {**TRUTH["S1"], "time_bias": 2.0}, "S2": {**TRUTH["S2"], "time_bias": -1.5}}
    sim = simulate_radar(STATIONS, SITE, seed=0, telemetry_rate=20, radar_rate=5, tracking_truth=tt,
                         noise={"range": 0.0, "azimuth": 0.0, "elevation": 0.0, "range_rate": 0.0}, range_rate=True)
    rr, z = _noise_free_errors(sim, [dataclasses.replace(m, range_rate=None) for m in sim.radars])
    assert np.max(np.abs(z)) < 5e-3, dict(zip(rr.result.names, z))
    # with range rate (the time bias through the range acceleration from the telemetry's a_*)
    sigma = {**SIGMA, **{(s, "range_rate"): 0.05 for s in ("S1", "S2")}}
    res = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, sigma=sigma,
                         diagnostics=False).result
    z = (res.estimate - sim.truth_vector()) / res.std
    assert np.max(np.abs(z)) < 1e-2, dict(zip(res.names, z))


@pytest.mark.montecarlo
def test_monte_carlo_z_and_coverage(clean_5hz):
    """Range noise 3 m, angle noise 8 arcsec, telemetry 20 Hz, radar 5 Hz, two stations; noise std estimated
    per station and type.

    4 seeded draws (reduced; ``benchmarks/bench_radar.py --mc 100`` runs more at 20 Hz), each draw's error
    whitened by its stated covariance (:func:`conftest.whitened_error`): all 44 coefficients together and the
    36 instrument terms alone honest by :func:`conftest.dishonest_whitened` with ``rms=None`` and false alarm
    1e-4 each. With an honest covariance ``sum w^2 ~ chi2`` on 176 and 144 values: RMS in [0.790, 1.221] and
    [0.769, 1.245] but with probability 0.5e-4, more than 3 of the 4 draws over their chi2 95 % point with
    probability 6e-6. Here RMS 0.91 and 0.88 (the first 4 of the 8 draws this test ran before with the fixed
    band [0.85, 1.15], where they gave 0.92 and 0.89); std 0.7x the stated ones give 1.30 and 1.26, both
    fail; 0.5x give 1.82 and 1.77, every draw over; 0.8x (1.14 and 1.10) passes, as it nearly did on the 8
    draws (1.155 against 1.15). The tracking terms alone (8 per draw) are in the joint check: their std 2x
    too small alone lifts its RMS to ~1.24.
    """
    clean = clean_5hz
    rng = np.random.default_rng(2026)
    truth = clean.truth_vector()
    nD = clean.model.n_coefficients
    w: dict[str, list] = {"all": [], "instrument": []}
    for _ in range(4):
        res = separate_radar(clean.telemetry, _with_noise(clean, rng), SITE, clean.model, clean.tracking, "ols",
                             diagnostics=False).result
        err = res.estimate - truth
        w["all"].append(whitened_error(err, res.covariance))
        w["instrument"].append(whitened_error(err[:nD], res.covariance[:nD, :nD]))
    bad = dishonest_whitened(w, rms=None, false_alarm=1e-4)
    assert not bad, bad


def test_velocity_and_measurement_domain_agree_on_a_bias_free_flight():
    """The same flight: dv = v_tel - v_trk (0.1 m/s noise) and the radar measurements (no station errors)."""
    sim = simulate_radar(STATIONS, SITE, seed=5, telemetry_rate=20, radar_rate=20)
    tel = sim.telemetry
    SV = casep.build_sv(sim.model, tel.t, tel.f)
    rng = np.random.default_rng(11)
    dv = SV @ sim.truth + rng.normal(0, 0.1, tel.v.shape)  # v_tel - (v + n)
    vel = casep.separate(casep.FlightData(tel.t, tel.f, dv), sim.model, "ols")
    rad = separate_radar(tel, sim.radars, SITE, sim.model, sim.tracking, "ols", diagnostics=False).result
    nD = sim.model.n_coefficients
    d = (vel.estimate - rad.estimate[:nD]) / np.hypot(vel.std, rad.std[:nD])
    assert np.max(np.abs(d)) < 4.0
    assert 0.5 < float(np.sqrt(np.mean(d**2))) < 1.5


def test_diagnostics_fixed_free_groups_and_station_gain(clean_5hz):
    """Radar at 5 Hz (0.4 s of CPU instead of 2.1): nothing here depends on the rate (free/fixed ratios >= 1.0035,
    S1's gain 2.14, the grouped bounds equal to the row-by-row ones to 5e-12, as at 20 Hz)."""
    clean = clean_5hz
    rr = separate_radar(clean.telemetry, list(clean.radars), SITE, clean.model, clean.tracking, "ols", sigma=SIGMA)
    d = rr.diagnostics
    inst = {r["name"]: r for r in d["instrument"]}
    assert set(inst) == set(clean.model.names)
    for r in inst.values():  # freeing parameters never improves a bound
        assert r["crlb_std_tracking_free"] >= r["crlb_std_tracking_fixed"] * (1 - 1e-9)
    assert set(d["station_gain"]) == {"S1", "S2"} and d["station_gain"]["S1"]["median_ratio"] > 1.0
    assert [r["name"] for r in d["tracking"]][:2] == ["S1.range_bias", "S1.range_scale"]
    assert "CRLB fixed" in rr.text()
    # the bounds come from the per-group reductions: the same as from every weighted row
    lin = rr.linearised
    full = np.sqrt(np.diag(casep.checks.diagnostics.crlb_covariance(lin.S * lin.weights[:, None], 1.0)))
    np.testing.assert_allclose([r["crlb_std_tracking_free"] for r in d["instrument"]], full[:36], rtol=1e-7)
    js = json.loads(json.dumps(rr.to_dict()))
    assert js["diagnostics"]["tracking_terms"][0] == "S1.range_bias" and js["radar"]["noise"][0]["source"] == "given"


def test_every_estimator_runs_on_the_joint_regression(clean_5hz):
    """Radar at 5 Hz (1 s of CPU a fit instead of 3.7): each method's S1.range_bias within 5 OLS std of 5 m."""
    clean = clean_5hz
    radars = _with_noise(clean, np.random.default_rng(4))
    opts = {"bounded": {"bounds": {"S1.range_bias": [-100, 100]}},
            "map": {"prior": {"S1.range_bias": {"mean": 0.0, "std": 50.0}}}}
    ols = separate_radar(clean.telemetry, radars, SITE, clean.model, clean.tracking, "ols", diagnostics=False).result
    for method in casep.estimators.registry.METHODS:
        if method == "gls":
            with pytest.raises(ValueError, match="several stations"):
                separate_radar(clean.telemetry, radars, SITE, clean.model, clean.tracking, method, diagnostics=False)
            res = separate_radar(clean.telemetry, radars[:1], SITE, clean.model, clean.tracking, method,
                                 diagnostics=False).result
            ref = separate_radar(clean.telemetry, radars[:1], SITE, clean.model, clean.tracking, "ols",
                                 diagnostics=False).result
        else:
            res = separate_radar(clean.telemetry, radars, SITE, clean.model, clean.tracking, method,
                                 options=opts.get(method), diagnostics=False).result
        assert res.success, (method, res.message)
        j = res.names.index("S1.range_bias")
        sd = (ref if method == "gls" else ols).std[j]  # one station alone knows the range bias to ~30 m
        assert abs(res.estimate[j] - 5.0) < 5 * sd, (method, res.estimate[j], sd)


# ----------------------------------------------------------------------------- inputs
def test_station_file_errors_name_file_and_field(tmp_path):
    p = tmp_path / "s.json"
    p.write_text(json.dumps({"name": "S1", "lat": 28.0, "h": 3.0}))
    with pytest.raises(ValueError, match=r"s\.json: field `lon`: missing"):
        read_station(p)
    p.write_text(json.dumps({"name": "S1", "lat": 128.0, "lon": 2.0, "h": 3.0}))
    with pytest.raises(ValueError, match=r"field `lat`"):
        read_station(p)
    p.write_text(json.dumps({"name": "S1", "lat": 0.497, "lon": -1.407, "h": 3.0}))
    with pytest.warns(RadianAnglesWarning, match=r"lat 0.497, lon -1.407 look like radians \(28.48 deg, -80.62 deg\)"):
        read_station(p)


def _write_radar(path, m: RadarMeasurements, *, degrees=True):
    f = np.degrees if degrees else (lambda a: a)
    casep.io.files.write_table(path, {"t": m.t, "range": m.range, "azimuth": f(m.azimuth),
                                      "elevation": f(m.elevation)})


def test_radians_in_the_measurement_file_warn_then_fail_on_the_first_sample(clean, tmp_path):
    m = clean.radars[0]
    _write_radar(tmp_path / "r.csv", m, degrees=False)
    with pytest.warns(RadianAnglesWarning, match="look like radians"):
        rad = read_radar(tmp_path / "r.csv", m.station)
    with pytest.raises(ValueError, match=r"station `S1`.*first measured azimuth.*angles not in degrees"):
        separate_radar(clean.telemetry, [rad], SITE, clean.model, clean.tracking, diagnostics=False)


def test_wrong_station_is_an_error_naming_it(clean):
    m = clean.radars[1]
    moved = dataclasses.replace(m, station=dataclasses.replace(m.station, lat_deg=m.station.lat_deg + 0.05))
    with pytest.raises(ValueError, match=r"station `S2`.*first measured range.*not a bias"):
        separate_radar(clean.telemetry, [clean.radars[0], moved], SITE, clean.model, clean.tracking)


def test_cli_simulate_separate_diagnose_impact(tmp_path, capsys):
    from casep.cli import main

    tel = tmp_path / "tel.csv"
    for s in STATIONS:
        (tmp_path / f"{s.name}.json").write_text(json.dumps({"name": s.name, "lat": s.lat_deg, "lon": s.lon_deg,
                                                             "h": s.h_m}))
    truth = tmp_path / "trk_truth.json"
    truth.write_text(json.dumps(TRUTH))
    # telemetry at 10 Hz, radar at 5 Hz (the docs' radar page runs the same): separate, diagnose and impact read a
    # quarter of the rows of 20 Hz and 20 Hz; the separation and its checks are the same code at any rate
    assert main(["simulate", "-o", str(tel), "--rate", "10", "--radar-rate", "5", "--rotating-earth", "--launch-site",
                 "28.5", "-80.6", "3", "90", "--radar-station", str(tmp_path / "S1.json"), "--radar-station",
                 str(tmp_path / "S2.json"), "--tracking-truth", str(truth)]) == 0
    out = capsys.readouterr().out
    assert "tel.S1.csv" in out
    side = json.loads((tmp_path / "tel.truth.json").read_text())
    assert side["tracking"]["S1"]["range_bias"] == 5.0
    args = ["separate", str(tel), "--radar", str(tmp_path / "tel.S1.json"), str(tmp_path / "tel.S1.csv"),
            "--radar", str(tmp_path / "tel.S2.json"), str(tmp_path / "tel.S2.csv"),
            "--launch-site", "28.5", "-80.6", "3", "90", "--launch-time", "0", "--json", str(tmp_path / "r.json")]
    assert main(args + ["--report", str(tmp_path / "r.html")]) == 0
    page = (tmp_path / "r.html").read_text()
    assert "Radar stations" in page and "S2.elevation_bias" in page and "CRLB free" in page
    out = capsys.readouterr().out
    assert "S1.range_bias" in out and "telemetered position: r_tel columns" in out
    res = json.loads((tmp_path / "r.json").read_text())
    j = res["names"].index("S2.elevation_bias")
    assert abs(res["estimates"][j] - 12.0) < 5 * res["std"][j]
    assert main(["diagnose", str(tel), *args[2:-2]]) == 0
    assert "CRLB free" in capsys.readouterr().out
    # the miss of the instrument terms only (tracking terms play no part)
    assert main(["impact", str(tel), "--result", str(tmp_path / "r.json"), "--model", "platform36",
                 "--json", str(tmp_path / "i.json")]) == 0
    imp = json.loads((tmp_path / "i.json").read_text())
    assert "S1.range_bias" not in json.dumps(imp) and "Ka0x" in json.dumps(imp)


def test_cli_bad_station_file_exit_2(tmp_path, capsys):
    from casep.cli import main

    (tmp_path / "S1.json").write_text(json.dumps({"name": "S1", "lon": 1.0, "h": 3.0}))
    (tmp_path / "S1.csv").write_text("t,range,azimuth,elevation\n0,1000,10,5\n")
    (tmp_path / "tel.csv").write_text("t,f_x,f_y,f_z,v_tel_x,v_tel_y,v_tel_z\n0,0,10,0,0,0,0\n1,0,10,0,0,1,0\n")
    code = main(["separate", str(tmp_path / "tel.csv"), "--radar", str(tmp_path / "S1.json"), str(tmp_path / "S1.csv"),
                 "--launch-site", "28.5", "-80.6", "3", "90", "--launch-time", "0"])
    assert code == 2
    err = capsys.readouterr().err
    assert "S1.json: field `lat`: missing" in err


def test_write_radar_simulation_round_trip(clean, tmp_path):
    files = write_radar_simulation(clean, tmp_path / "f.csv")
    assert {p.name for p in files} >= {"f.csv", "f.S1.json", "f.S1.csv", "f.truth.json"}
    st = read_station(tmp_path / "f.S1.json")
    m = read_radar(tmp_path / "f.S1.csv", st)
    np.testing.assert_allclose(m.range, clean.radars[0].range, rtol=1e-15)
    assert math.isclose(st.lat_deg, STATIONS[0].lat_deg)


def test_a_user_term_in_one_file(clean_5hz, tmp_path):
    """The guide's example: refraction and a survey offset added to radar_biases in a model file of its own
    (radar at 5 Hz: the fit only has to take the user's terms)."""
    clean = clean_5hz
    p = tmp_path / "my_radar.py"
    p.write_text('''
import casadi as ca
import casep

def build():
    m = casep.build_tracking_model("radar_biases")
    c = m.declare(refraction=("arcsec", 10.0), survey_up=("m", 2.0))
    m.set_elevation_error(m.output("elevation") + c.refraction * ca.cos(m.elevation) / ca.sin(m.elevation))
    m.set_range_error(m.output("range") - c.survey_up * m.enu[2] / m.range)
    return m
''')
    trk = load_tracking_model(str(p))
    assert trk.names[-2:] == ("refraction", "survey_up")
    g = np.array([[2e5, 0.3, 0.4, 100.0, 0.0, 0.0, 0.0, 1e5, 1.5e5, 7e4, 0.0]])
    T = trk.jacobian(g)
    assert math.isclose(T[0, 2, 5], ARCSEC * math.cos(0.4) / math.sin(0.4), rel_tol=1e-14)
    assert math.isclose(T[0, 0, 6], -7e4 / 2e5, rel_tol=1e-14)
    rr = separate_radar(clean.telemetry, list(clean.radars), SITE, clean.model, str(p), sigma=SIGMA, diagnostics=False)
    assert "S2.survey_up" in rr.result.names


def test_joint_result_as_prior_and_truth_for_design_and_montecarlo(clean_5hz):
    """A radar result as a prior (casep design --prior, casep montecarlo --truth-from-prior, separate --prior):
    the instrument block only, the station terms marginalised out (radar at 5 Hz: the prior is read from any
    result)."""
    clean = clean_5hz
    from casep.estimators.map import parse_prior, prior_from_result
    from casep.estimators.result import EstimateResult

    rr = separate_radar(clean.telemetry, _with_noise(clean, np.random.default_rng(9)), SITE, clean.model,
                        clean.tracking, sigma=SIGMA, diagnostics=False)
    res = EstimateResult.from_json(json.loads(json.dumps(rr.to_dict())))
    prior = prior_from_result(res)
    assert "S1.range_bias" not in prior and "Ka0x" in prior
    parse_prior(prior, clean.model.names, source="radar result")
    j = res.names.index("Ka0x")
    assert math.isclose(prior["Ka0x"]["std"], res.std[j], rel_tol=1e-12)


def test_cli_radar_options_without_radar_are_refused(tmp_path, capsys):
    from casep.cli import main

    assert main(["separate", str(tmp_path / "x.csv"), "--tracking-model", "radar_biases.py"]) == 2
    assert "--tracking-model is used only with --radar" in capsys.readouterr().err
    assert main(["simulate", "-o", str(tmp_path / "x.csv"), "--range-noise", "2"]) == 2
    assert "--range-noise is used only with --radar-station" in capsys.readouterr().err


def test_range_rate_rows_noise_free_and_recursive():
    """Range rate as a fourth measurement type: noise-free recovery, and RLS on the grouped rows (radar at 5 Hz:
    an exact recovery needs no more rows)."""
    sim = simulate_radar(STATIONS, SITE, seed=0, telemetry_rate=20, radar_rate=5, tracking_truth=TRUTH,
                         noise={"range": 0.0, "azimuth": 0.0, "elevation": 0.0, "range_rate": 0.0}, range_rate=True)
    assert sim.radars[0].types == ("range", "azimuth", "elevation", "range_rate")
    sigma = {**SIGMA, **{(s, "range_rate"): 0.05 for s in ("S1", "S2")}}
    truth = sim.truth_vector()
    ols = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, sigma=sigma,
                         diagnostics=False).result
    assert np.max(np.abs((ols.estimate - truth) / ols.std)) < 1e-6
    no_rr = separate_radar(sim.telemetry, [dataclasses.replace(m, range_rate=None) for m in sim.radars], SITE,
                           sim.model, sim.tracking, sigma=SIGMA, diagnostics=False).result
    j = ols.names.index("S1.range_scale")
    assert ols.std[j] < no_rr.std[j]  # range rate informs the scale factor
    rls = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking, "rls", sigma=sigma,
                         options={"p0": 1e20}, diagnostics=False).result
    assert np.max(np.abs((rls.estimate - truth) / ols.std)) < 1e-3


def test_telemetry_without_position_is_integrated_from_the_launch_point(clean_5hz, tmp_path):
    """Telemetry 20 Hz, radar 5 Hz (0.4 s of CPU for the fit instead of 1.5): the integration error is the
    telemetry's, the same in metres, and the std twice the 20 Hz ones, so max |z| 0.0095 (0.019 at 20 Hz) and the
    bound 0.1 (half the 20 Hz test's 0.2) asks the same absolute error."""
    from casep.radar.regression import read_telemetry

    clean = clean_5hz
    tel = clean.telemetry
    casep.io.files.write_table(tmp_path / "t.csv", {"t": tel.t, **{f"f_{a}": tel.f[:, i] for i, a in enumerate("xyz")},
                                                    **{f"v_tel_{a}": tel.v[:, i] for i, a in enumerate("xyz")}})
    got = read_telemetry(tmp_path / "t.csv", SITE)
    assert got.r_source == "v_tel integrated from the launch point"
    assert np.max(np.abs(got.r - tel.r)) < 0.5  # trapezoid of v at 20 Hz against the exact r + S_P D
    rr = separate_radar(got, list(clean.radars), SITE, clean.model, clean.tracking, sigma=SIGMA, diagnostics=False)
    assert rr.summary["telemetry_position"] == "v_tel integrated from the launch point"
    z = (rr.result.estimate - clean.truth_vector()) / rr.result.std
    assert np.max(np.abs(z)) < 0.1  # noise-free data: only the integration error of the position


def test_azimuth_across_north():
    """A station south of the track: the vehicle passes north of it (azimuth 359 -> 1 deg); residuals wrapped.
    Radar at 5 Hz (azimuths 359.7 and 0.8 deg either side of north; max |z| 7e-11, 1.7e-10 at 20 Hz), the bound
    half the 20 Hz test's 1e-6 (std twice as large)."""
    st = Station("S3", 28.3, -79.5, 5.0)
    sim = simulate_radar([st], SITE, seed=0, telemetry_rate=20, radar_rate=5,
                         tracking_truth={"S3": {"azimuth_bias": 30.0}},
                         noise={"range": 0.0, "azimuth": 0.0, "elevation": 0.0})
    az = np.degrees(sim.radars[0].azimuth)
    assert az.max() > 350 and az.min() < 10  # the file's azimuths jump across north
    rr = separate_radar(sim.telemetry, list(sim.radars), SITE, sim.model, sim.tracking,
                        sigma={("S3", "range"): 3.0, ("S3", "azimuth"): 8 * ARCSEC, ("S3", "elevation"): 8 * ARCSEC},
                        diagnostics=False)
    z = (rr.result.estimate - sim.truth_vector()) / rr.result.std
    assert np.max(np.abs(z[np.isfinite(z)])) < 5e-7


def test_noise_from_the_station_file(clean):
    st = read_station({"name": "S1", "lat": 28.9, "lon": -80.0, "h": 20.0, "sigma_range": 3.0, "sigma_angle": 8.0})
    assert st.sigma == {"range": 3.0, "azimuth": 8 * ARCSEC, "elevation": 8 * ARCSEC}
    radars = _with_noise(clean, np.random.default_rng(1))
    radars[0] = dataclasses.replace(radars[0], station=st)
    rr = separate_radar(clean.telemetry, radars, SITE, clean.model, clean.tracking, diagnostics=False)
    noise = {(g["station"], g["type"]): g for g in rr.summary["noise"]}
    assert noise[("S1", "range")]["source"] == "given" and noise[("S1", "range")]["sigma"] == 3.0
    assert noise[("S1", "azimuth")]["sigma"] == pytest.approx(8.0, rel=1e-12)
    assert noise[("S2", "range")]["source"].startswith("estimated")  # by REML under the noise model
    assert noise[("S2", "range")]["sigma"] == pytest.approx(3.0, rel=0.05)  # 3901 samples: 1.1 % std
    assert noise[("S2", "elevation")]["sigma"] == pytest.approx(8.0, rel=0.05)


def test_bad_noise_std_is_refused(clean):
    with pytest.raises(ValueError, match=r"noise std of S1.range must be a finite number > 0"):
        separate_radar(clean.telemetry, list(clean.radars), SITE, clean.model, clean.tracking,
                       sigma={("S1", "range"): 0.0})
    with pytest.raises(ValueError, match=r"noise given for S3.range, which is not a measurement group"):
        separate_radar(clean.telemetry, list(clean.radars), SITE, clean.model, clean.tracking,
                       sigma={("S3", "range"): 3.0})


def test_linearisation_that_does_not_settle_warns(clean):
    from casep.radar.regression import RadarConvergenceWarning, RadarRegression

    reg = RadarRegression(clean.telemetry, list(clean.radars), clean.model, clean.tracking, SITE)
    with pytest.warns(RadarConvergenceWarning, match=r"not settled in 1 Gauss-Newton steps \(last step 1\.4\d std"):
        lin = reg.solve(SIGMA, iterations=1)
    assert not lin.converged and re.search(r"last step 1\.4\d std", lin.convergence_message)
