"""Plausibility and residual checks (casep.checks.plausibility): unit mistakes, impossible data, noise-free
data, outliers and a tracking time offset, through the API and the command line."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

import casep
from casep.checks.plausibility import check_flight
from casep.checks.time_offset import GRAVITY_LAUNCH, time_offset_test
from casep.cli import main
from casep.exceptions import (
    CasepWarning,
    IllConditionedWarning,
    MagnitudeWarning,
    NoiseFreeWarning,
    NoiseNotWhiteWarning,
    OutlierWarning,
    PlausibilityWarning,
    TimeOffsetWarning,
)
from casep.io.flight import FlightDataError
from casep.simulation.noise import NoiseModel
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import scenario_setup, simulate_flight, simulate_two_rate
from casep.simulation.synthetic import excitation_force, inject_errors
from casep.units import G0

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples" / "data").glob("*.csv"))


def _casep_warnings(fn, *args, **kwargs) -> list[warnings.WarningMessage]:
    """Call `fn` and return the CasepWarnings it raised other than ill-conditioning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args, **kwargs)
    return [w for w in caught if issubclass(w.category, CasepWarning)
            and not issubclass(w.category, IllConditionedWarning)]


@pytest.fixture(scope="module")
def paper20():
    """The paper scenario at 20 Hz, seed 1 (white noise 0.1 m/s)."""
    return simulate_flight("paper", seed=1, rate=20.0)


def _replace(flight: casep.FlightData, **kw) -> casep.FlightData:
    args = {"t": flight.t, "f": flight.f, "dv": flight.dv, "source": "mistake.csv"}
    args.update(kw)
    return casep.FlightData(**args)


# ----------------------------------------------------------------------- no false alarms


@pytest.mark.parametrize("scenario", ["paper", "paper-pitch", "paper-ar1"])
def test_simulator_flights_raise_no_check_warning(scenario):
    sim = simulate_flight(scenario, seed=4)
    assert _casep_warnings(casep.separate, sim.flight, sim.model, "ols") == []


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_files_raise_no_check_warning(path):
    assert _casep_warnings(casep.separate, path) == []


def test_synthetic_noisy_flight_raises_no_check_warning(platform36, truth36, rng):
    t = np.arange(0.0, 180.0, 0.05)
    f = excitation_force(t)
    fl = casep.FlightData(t, f, inject_errors(platform36, t, f, truth36, sigma=0.1, rng=rng))
    assert _casep_warnings(casep.separate, fl, platform36) == []


def test_noise_free_two_rate_pair_raises_no_check_warning(tmp_path):
    """Spline interpolation leaves a ripple at staging on noise-free data: structured and "significant", but at
    the pair's interpolation floor, so the one warning is the noise-free note (no outlier, offset or whiteness)."""
    quiet = dataclasses.replace(get_scenario("paper"), noise=NoiseModel("white", 0.0))
    simulate_two_rate(quiet, seed=0).write(tmp_path / "tel.csv", tmp_path / "trk.csv", apparent=True)
    fl = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
    assert [w.category for w in _casep_warnings(casep.separate, fl)] == [NoiseFreeWarning]


# ------------------------------------------------------------------------- unit mistakes


def test_force_in_g_warns_with_the_factor(paper20):
    fl = _replace(paper20.flight, f=paper20.flight.f / G0)
    with pytest.warns(PlausibilityWarning,
                      match=r"peak specific force .* 5\.24\d* m/s\^2 \(0\.534 g\).*multiply by 9\.80665"):
        check_flight(fl)


def test_a_peak_of_one_g_in_m_per_s2_is_said_at_rest_not_f_in_g(paper20):
    """An accelerometer at rest reads |f| = g, 9.805 m/s^2 (just under g0): f in g would read 1, so the hint is a
    record without lift-off, not 'multiply by 9.80665'."""
    f = paper20.flight.f
    fl = _replace(paper20.flight, f=f * (9.805 / np.max(np.linalg.norm(f, axis=1))))
    with pytest.warns(PlausibilityWarning) as rec:
        check_flight(fl)
    said = [str(w.message) for w in rec if "peak specific force" in str(w.message)]
    assert len(said) == 1 and "9.805 m/s^2" in said[0], said
    assert "at rest reads |f| = g" in said[0] and "multiply by 9.80665" not in said[0]


@pytest.mark.parametrize("factor, unit", [(1e3, "ms"), (1e6, "us")])
def test_time_in_ms_or_us_warns_with_the_unit(paper20, factor, unit):
    fl = _replace(paper20.flight, t=paper20.flight.t * factor)
    with pytest.warns(PlausibilityWarning) as rec:
        check_flight(fl)
    text = " | ".join(str(w.message) for w in rec)
    assert f"Is t in {unit} (divide by" in text and "median time step" in text
    assert "integrates to" in text  # int |f| dt: thousands of km/s


def test_dv_in_mm_per_s_warns(paper20):
    fl = _replace(paper20.flight, dv=paper20.flight.dv * 1e3)
    with pytest.warns(PlausibilityWarning,
                      match=r"column `dv_.`: sample-to-sample noise 1\d\d\.?\d* m/s.*mm/s \(divide by 1000\)"):
        check_flight(fl)


def test_dv_in_ft_per_s_is_not_detectable(paper20):
    """Documented limitation: ft/s scales signal and noise alike (3.28); t, f, dv cannot show it."""
    fl = _replace(paper20.flight, dv=paper20.flight.dv / 0.3048)
    assert _casep_warnings(check_flight, fl) == []


def test_force_in_mm_per_s2_is_an_error(paper20):
    fl = _replace(paper20.flight, f=paper20.flight.f * 1e4)
    with pytest.raises(FlightDataError, match=r"mistake\.csv: column `f_x`: peak specific force .* not a boost"):
        check_flight(fl)


def test_large_force_warns_cm(paper20):
    fl = _replace(paper20.flight, f=paper20.flight.f * 100.0)
    with pytest.warns(PlausibilityWarning) as rec:
        check_flight(fl)
    text = " | ".join(str(w.message) for w in rec)
    assert "(524.1 g), above the 100 g" in text and "Is it cm/s^2 (divide by 100)?" in text
    assert "integrates to 5.461e+05 m/s" in text


def test_zero_force_is_an_error(paper20):
    fl = _replace(paper20.flight, f=np.zeros_like(paper20.flight.f))
    with pytest.raises(FlightDataError, match=r"mistake\.csv: column `f_x`: the specific force .* zero in every row"):
        casep.separate(fl)


# ------------------------------------------------------------------------------- time steps


def test_picosecond_time_steps_are_an_error(paper20):
    fl = _replace(paper20.flight, t=np.arange(paper20.flight.n_samples) * 1e-12)
    with pytest.raises(FlightDataError, match=r"column `t`: median time step 1e-12 s \(1e\+12 Hz\)"):
        casep.separate(fl)


def test_near_duplicate_time_tag_warns(paper20):
    t = paper20.flight.t.copy()
    t[100] = t[99] + 1e-9
    with pytest.warns(PlausibilityWarning, match=r"column `t`, row 101: time step 1e-09 s"):
        check_flight(_replace(paper20.flight, t=t))


# ----------------------------------------------------------------------------- residuals


def test_noise_free_flight_warns_that_std_are_rounding(platform36, truth36):
    t = np.arange(0.0, 120.0, 0.1)
    f = excitation_force(t, duration=120.0)
    fl = casep.FlightData(t, f, inject_errors(platform36, t, f, truth36))
    with pytest.warns(NoiseFreeWarning, match=r"residual RMS .* rounding level .* std reflect rounding only"):
        casep.separate(fl, platform36)


def test_outlier_is_named_with_its_row_and_size(paper20):
    dv = paper20.flight.dv.copy()
    dv[1234, 0] += 1e4
    with pytest.warns(OutlierWarning) as rec, warnings.catch_warnings():  # the warning of a fit without the robust
        warnings.simplefilter("ignore", MagnitudeWarning)  # filter (the 1e4 m/s throws Ka1xz beyond 1e5 ug/g too)
        casep.separate(_replace(paper20.flight, dv=dv), paper20.model, robust="none")
    msg = next(str(w.message) for w in rec if w.category is OutlierWarning)
    assert "1 outlier(s)" in msg and "sample 1235 (t = 61.7 s) dv_x +1e+04 m/s" in msg
    z = float(msg.split("m/s = ")[1].split(" noise sigma")[0])
    assert 8e4 < z < 1.2e5  # 1e4 m/s against 0.1 m/s noise


def test_time_offset_statistic_matches_an_independent_lstsq(paper20, rng):
    """Coefficient and white-noise std of the a(t) column against numpy's lstsq on [S | a | j]."""
    fl = paper20.flight
    S = casep.build_sv(paper20.model, fl.t, fl.f)
    a = fl.f + GRAVITY_LAUNCH
    j = np.gradient(a, fl.t, axis=0)
    dt = 0.01
    y = (S @ paper20.truth + a * dt + 0.1 * rng.standard_normal(fl.dv.shape)).reshape(-1)
    A = np.column_stack([S.reshape(-1, S.shape[-1]), a.reshape(-1), j.reshape(-1)])
    c = np.linalg.norm(A, axis=0)
    coef, rss, *_ = np.linalg.lstsq(A / c, y, rcond=None)
    cov = rss[0] / (A.shape[0] - A.shape[1]) * np.linalg.inv((A / c).T @ (A / c)) / np.outer(c, c)
    r = (y - S.reshape(-1, S.shape[-1]) @ paper20.truth).reshape(-1, 3)
    test = time_offset_test(S, r, fl.t, fl.f)
    assert test.offset == pytest.approx(coef[-2] / c[-2], rel=1e-6)
    assert test.jerk == pytest.approx(coef[-1] / c[-1], rel=1e-6, abs=1e-9)
    assert 1.0 <= test.inflation < 1.2  # white noise: lag-1 correlation ~ 0
    assert test.offset_std == pytest.approx(np.sqrt(cov[-2, -2] * test.inflation), rel=1e-6)
    assert abs(test.offset - dt) < 4 * test.offset_std


def test_tracking_time_offset_20ms_warns_or_is_modelled(tmp_path):
    """20 ms late tracking (20 Hz: below one period) on a launch-frame pair: the model as given leaves residuals that
    track a(t), which the test names with the offset; by default (the caller decided nothing) the pair is then
    fitted with dt_trk, which recovers the offset, and the result says so (no warning left to act on). Telemetry
    25 Hz, tracking 10 Hz."""
    d = simulate_two_rate("paper", seed=3, time_offset=0.020, telemetry_rate=25.0, tracking_rate=10.0)
    d.write(tmp_path / "tel.csv", tmp_path / "trk.csv")
    fl = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
    with pytest.warns(TimeOffsetWarning, match=r"tracking time offset of (\d+\.?\d*) \+- ") as rec, \
            warnings.catch_warnings():
        warnings.simplefilter("ignore", NoiseNotWhiteWarning)  # the unmodelled offset leaves correlated residuals
        plain = casep.separate(fl, fit_time_offset=False)
    msg = next(str(w.message) for w in rec if w.category is TimeOffsetWarning)
    ms, std = float(msg.split("offset of ")[1].split(" +- ")[0]), float(msg.split(" +- ")[1].split(" ms")[0])
    assert abs(ms - 20.0) < 4 * std and std < 3.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = casep.separate(fl)
    assert not [w for w in caught if w.category is TimeOffsetWarning]
    j = list(res.names).index("dt_trk")
    assert abs(res.estimate[j] - 20.0) < 4 * res.std[j] and "tracking time offset modelled" in res.message
    assert res.settings["time_offset"].startswith("modelled")
    shared = [n for n in plain.names if n in res.names]
    ratio = np.median([res.std[res.names.index(n)] / plain.std[plain.names.index(n)] for n in shared])
    assert ratio < 0.7, ratio  # the offset no longer taken as correlated noise


def test_time_offset_false_alarm_rate_white_and_ar1():
    """50 seeded white-noise flights and 20 Gauss-Markov (tau 1 s) flights of the paper scenario at
    20 Hz, no offset. Measured: 0 of 50 and 0 of 20 fire (|t| > 5); the white-noise t-statistics
    have mean square ~1 (they are standard normal). Bound asserted: at most 1 of 50, 1 of 20."""
    sc, traj, model, truth = scenario_setup("paper", 20.0)
    S = casep.build_sv(model, traj.t, traj.specific_force)
    clean = S @ truth
    stats: dict[str, list] = {"white": [], "ar1": []}
    for kind, runs, noise in (("white", 50, sc.noise), ("ar1", 20, NoiseModel("ar1", 0.1, tau=1.0))):
        for seed in range(runs):
            dv = clean + noise.sample(traj.t, np.random.default_rng(seed))
            r = dv - S @ casep.solve_ols(S, dv).estimate
            test = time_offset_test(S, r, traj.t, traj.specific_force)
            stats[kind].append((test.offset_t, test.jerk_t))
    white, red = np.abs(stats["white"]), np.abs(stats["ar1"])
    assert np.sum(np.any(white > 5, axis=1)) <= 1 and np.sum(np.any(red > 5, axis=1)) <= 1
    assert 0.4 < np.mean(white[:, 0] ** 2) < 2.0  # calibrated, not merely conservative


# --------------------------------------------------------------------------- command line


def _write(tmp_path, fl: casep.FlightData, name: str) -> Path:
    p = tmp_path / name
    casep.write_flight(fl, p)
    return p


def test_cli_separate_prints_the_unit_warning(tmp_path, capsys, paper20):
    p = _write(tmp_path, _replace(paper20.flight, f=paper20.flight.f / G0), "in_g.csv")
    assert main(["separate", str(p)]) == 0
    err = capsys.readouterr().err  # the warnings on stderr, the table on stdout
    line = [s for s in err.splitlines() if s.startswith("warning: ") and "peak specific force" in s]
    assert len(line) == 1 and "multiply by 9.80665" in line[0] and str(p) in line[0]


def test_cli_diagnose_prints_the_unit_warning(tmp_path, capsys, paper20):
    p = _write(tmp_path, _replace(paper20.flight, t=paper20.flight.t * 1e3), "in_ms.csv")
    assert main(["diagnose", str(p), "--sigma", "0.1"]) == 0
    assert "warning: " in capsys.readouterr().err


def test_cli_impossible_flight_exit_2(tmp_path, capsys, paper20):
    p = _write(tmp_path, _replace(paper20.flight, f=np.zeros_like(paper20.flight.f)), "zero.csv")
    out = tmp_path / "r.json"
    assert main(["separate", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("casep: error: ") and err.count("\n") == 1 and str(p) in err and "f_x" in err
    assert not out.exists()


@pytest.mark.parametrize("factor, hint", [(1 / 0.3048, "ft/s"), (100.0, "cm/s"), (1e-3, "km/s"), (1.5, None)])
def test_velocity_columns_in_other_units_are_refused(tmp_path, factor, hint):
    """v_tel/v_trk in ft/s (or cm/s, km/s) while f is in m/s^2: the telemetered velocity change
    disagrees with int (f + g) dt by the unit factor (0.9986 in SI on the paper boost): refused, naming the
    file, the columns and the numbers (every estimate would be scaled by the factor); a ratio of 1.5, no
    unit's factor, is a warning."""
    from casep.io.files import write_table
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=1, telemetry_rate=20.0, tracking_rate=20.0)
    cols = {"t": d.t_tel, **{f"f_{a}": d.f[:, i] for i, a in enumerate("xyz")}}
    v_trk = np.column_stack([np.interp(d.t_tel, d.t_trk, d.v_trk[:, i]) for i in range(3)])
    good, bad = tmp_path / "si.csv", tmp_path / "bad.csv"
    for path, k in ((good, 1.0), (bad, factor)):
        write_table(path, {**cols, **{f"v_tel_{a}": k * d.v_tel[:, i] for i, a in enumerate("xyz")},
                           **{f"v_trk_{a}": k * v_trk[:, i] for i, a in enumerate("xyz")}})
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        check_flight(casep.read_flight(good))  # SI: silent
    if hint is None:
        with pytest.warns(PlausibilityWarning, match="ratio 1.5"):
            check_flight(casep.read_flight(bad))
        return
    with pytest.raises(FlightDataError, match=hint) as e, warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)  # cm/s: the dv scatter is named too
        check_flight(casep.read_flight(bad))
    assert e.value.source == str(bad) and e.value.column == "v_tel_x" and "ratio " in str(e.value)


def test_cli_pair_with_telemetry_in_km_per_s_exits_2(tmp_path, capsys):
    """A telemetry file in km/s beside tracking in m/s: no plain success but exit 2 naming the file, the column and
    the numbers, and nothing written."""
    from casep.io.files import write_table
    from casep.simulation.simulate import simulate_two_rate

    d = simulate_two_rate("paper", seed=1, telemetry_rate=10.0, tracking_rate=10.0)
    tel, trk, out = tmp_path / "tel_kms.csv", tmp_path / "trk.csv", tmp_path / "out.json"
    write_table(tel, {"t": d.t_tel, **{f"f_{a}": d.f[:, i] for i, a in enumerate("xyz")},
                      **{f"v_tel_{a}": 1e-3 * d.v_tel[:, i] for i, a in enumerate("xyz")}})
    write_table(trk, {"t": d.t_trk, **{f"v_trk_{a}": d.v_trk[:, i] for i, a in enumerate("xyz")}})
    assert main(["separate", str(tel), "--tracking", str(trk), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(tel) in err and "v_tel_x" in err and "km/s" in err and "ratio" in err
    assert not out.exists()


@pytest.mark.parametrize("factor, raises", [(3.28084, True), (1.0, False)])
def test_tracking_units_against_telemetry(factor, raises):
    """Tracking in ft/s beside telemetry in m/s: the units rule of v_tel against int (f + g), applied to v_trk
    against v_tel over the same times, refuses it naming the tracking file and its column."""
    from casep.checks.plausibility import check_flight
    from casep.checks.time_offset import GRAVITY_LAUNCH
    from casep.io.flight import FlightDataError
    from casep.io.pair import pair_flight

    t = np.arange(0.0, 60.0, 0.1)
    f = np.tile([30.0, 0.0, 0.0], (t.size, 1)) - GRAVITY_LAUNCH  # a = 30 m/s^2 along x
    v_tel = np.outer(t, [30.0, 0.0, 0.0]) + [0.0, 0.0, 0.0]
    t_trk = np.arange(0.05, 60.0, 0.5)
    v_trk = factor * np.outer(t_trk, [30.0, 0.0, 0.0])
    flight = pair_flight(t, f, v_tel, t_trk, v_trk, source="tel.csv + trk.csv",
                         meta={"telemetry": "tel.csv", "tracking": "trk.csv"})
    if raises:
        with pytest.raises(FlightDataError, match=r"trk\.csv.*v_trk_x.*ratio 3\.28.*ft/s"):
            check_flight(flight)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # not a boost of the plausible kinds: only the units rule counts here
            try:
                check_flight(flight)
            except FlightDataError as exc:
                assert "v_trk" not in str(exc)


@pytest.mark.parametrize("factor", [1.0, 3.28084])
def test_tracking_units_on_a_drifting_window(factor):
    """A car-like window: the vehicle's speed changes by 3 m/s over 30 s while the navigated (uncorrected MEMS)
    velocity drifts by 8 m/s (a tilt error, 0.27 m/s^2 across the track): the ratio of the velocity changes (0.35)
    is a drift, not a unit's factor, and the tracking is not refused; the same tracking in ft/s, a scaled copy of
    a telemetry that does not drift, is."""
    from casep.checks.time_offset import GRAVITY_LAUNCH
    from casep.io.pair import pair_flight

    t = np.arange(0.0, 30.0, 0.01)
    v_true = np.column_stack([10.0 + 3.0 * np.sin(np.pi * t / 60.0) ** 2, np.zeros_like(t), np.zeros_like(t)])
    drift = np.outer(t, [0.0, 0.27, 0.02]) if factor == 1.0 else 0.0 * v_true
    a = np.gradient(v_true + drift, t, axis=0)
    t_trk = np.arange(0.1, 30.0, 0.25)
    v_trk = factor * np.column_stack([np.interp(t_trk, t, v_true[:, i]) for i in range(3)])
    flight = pair_flight(t, a - GRAVITY_LAUNCH, v_true + drift, t_trk, v_trk, source="tel.csv + trk.csv",
                         meta={"telemetry": "tel.csv", "tracking": "trk.csv"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # not a boost: only the units rule counts here
        if factor == 1.0:
            check_flight(flight)  # ratio 0.35 before the scaled-copy test: refused as "the files disagree on units"
        else:
            with pytest.raises(FlightDataError, match=r"trk\.csv.*v_trk_x.*ratio 3\.28.*ft/s"):
                check_flight(flight)


@pytest.mark.parametrize("factor", [1.0, 3.28084])
def test_tracking_units_of_a_car_at_rest_then_driving_on_the_rotating_earth(factor):
    """Groves' car profile in miniature: 40 s at rest at 51 deg, then a drive north peaking at 20 m/s that ends at
    rest, tracked in ECEF and turned into the launch-inertial frame; the navigated telemetry drifts by 5 m/s (a tilt
    error growing as t^2). In that frame a vehicle at rest changes velocity by the Earth's rotation turning
    ``omega_E x r`` (2.6 m/s over 120 s at 51 deg: ``|omega_E x r_s| omega_E T``), which the units rule must not
    compare with the drift: both files relative to the pad, their changes a copy of the drive (scale 1 within the
    drift), no units warning (before, the last epoch's ratio: 0.42, a warning). The same tracking in ft/s (its ECEF
    velocity 3.28 times) is refused (before, it was not: the Earth's turn in both files hid the factor)."""
    from casep.frames import LaunchSite, ecef_to_launch
    from casep.io.pair import pair_flight

    site = LaunchSite(51.0, 0.0, 10.0, 0.0, 60.0)
    t = np.arange(0.0, 120.0, 0.02)
    speed = np.where(t > 40.0, 20.0 * np.sin(np.pi * (t - 40.0) / 80.0) ** 2, 0.0)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    lat = np.radians(site.lat_deg)
    north = np.array([-np.sin(lat), 0.0, np.cos(lat)])  # at longitude 0
    r_e, v_e = site.r_site + np.outer(s, north), np.outer(speed, north)
    v_l = ecef_to_launch(site, t, r_e, v_e)[1]
    pad = ecef_to_launch(site, t[[0, -1]], np.tile(site.r_site, (2, 1)), np.zeros((2, 3)))[1]
    assert np.linalg.norm(pad[1] - pad[0]) == pytest.approx(
        7.292115e-5**2 * np.linalg.norm(site.r_site[:2]) * 120.0, rel=1e-3)  # the pad's turn: 2.6 m/s
    v_tel = v_l + np.outer((t / 120.0) ** 2, [4.0, 3.0, 0.0])  # the drift: 5 m/s at the end
    k = slice(1, None, 10)
    v_trk = ecef_to_launch(site, t[k], r_e[k], factor * v_e[k])[1]
    flight = pair_flight(t, np.gradient(v_tel, t, axis=0) - GRAVITY_LAUNCH, v_tel, t[k], v_trk,
                         source="tel.csv + trk.csv", meta={"telemetry": "tel.csv", "tracking": "trk.csv",
                                                           "tracking_frame": {"frame": "ecef", "site": site.to_dict()}})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # not a boost: only the units rule counts here
        if factor == 1.0:
            check_flight(flight)
        else:
            # the scale over the flight's changes: the drift, uncorrelated with 3.28 times the drive, lowers it
            with pytest.raises(FlightDataError, match=r"trk\.csv.*v_trk_x.*ratio 2\.\d+ over the flight.*ft/s"):
                check_flight(flight)
    assert not any("units" in str(c.message) for c in caught), [str(c.message) for c in caught]


@pytest.mark.parametrize("column, match", [
    ("f", r"column `f_x`.*ratio 3\.2\d.* f_x, f_y, f_z are in g, multiply them by 9\.80665"),
    ("t", r"column `t`.*ratio 0\.001.*t is in ms, divide it by 1000")])
def test_force_in_g_or_time_in_ms_is_named_before_the_velocity(tmp_path, column, match):
    """f in g or t in ms break v_tel against int (f + g) dt as a velocity unit would (ratio 3.22: 'ft/s?'; 0.001:
    'km/s?'); read with f in m/s^2 or t in s the velocity agrees, so that column is named, not the velocity's."""
    from casep.checks.time_offset import GRAVITY_LAUNCH
    from casep.io.files import write_table

    t = np.arange(0.0, 60.0, 0.05)
    a = np.tile([30.0, 0.0, 0.0], (t.size, 1))  # 3 g along x
    f = (a - GRAVITY_LAUNCH) / (G0 if column == "f" else 1.0)
    path = tmp_path / "bad.csv"
    write_table(path, {"t": 1e3 * t if column == "t" else t, **{f"f_{c}": f[:, i] for i, c in enumerate("xyz")},
                       **{f"v_tel_{c}": (t * a[:, i]) for i, c in enumerate("xyz")},
                       **{f"v_trk_{c}": (t * a[:, i]) for i, c in enumerate("xyz")}})
    with pytest.raises(FlightDataError, match=match) as e, warnings.catch_warnings():
        warnings.simplefilter("ignore", PlausibilityWarning)  # the peak force or the time step is named too
        check_flight(casep.read_flight(path))
    assert e.value.column == ("f_x" if column == "f" else "t") and e.value.source == str(path)


def test_outliers_are_judged_by_their_own_stretchs_noise():
    """A pad of 101 epochs at 0.06 m/s, a 27 s pause, 14 flight epochs at 1.7 m/s: judged by one sigma (the pad's)
    every flight epoch was an outlier; each stretch by its own noise, none is, and a 40 m/s spike in the flight
    stretch still is (named by its sample and time)."""
    from casep.checks.plausibility import _check_outliers

    rng = np.random.default_rng(11)
    t = np.concatenate([np.arange(50.0, 60.05, 0.1), np.arange(87.0, 101.0, 1.0)])
    r = np.where((t < 80)[:, None], 0.06, 1.7) * rng.standard_normal((t.size, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error", OutlierWarning)
        _check_outliers(r, t, "f.csv")
    k = int(np.flatnonzero(t == 93.0)[0])
    r[k, 1] += 40.0
    with pytest.warns(OutlierWarning, match=r"f.csv: 1 outlier\(s\) in dv: sample 108 \(t = 93 s\) dv_y \+3\d\.\d m/s"):
        _check_outliers(r, t, "f.csv")
