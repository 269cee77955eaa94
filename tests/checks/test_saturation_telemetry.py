"""Strapdown telemetry whose gyro clipped (casep.checks.saturation.screen_saturation) and fits whose residuals are
a model error (casep.checks.plausibility.misfit_problem): never a plain success with a wrong answer.

The flights come from an independent strapdown simulation (``tests/conftest.py``: :func:`ins_telemetry`,
quaternions integrated at the midpoint rate, 8 steps per telemetry sample): the INS integrates its measured rates,
clipped at a full scale, and its measured body specific force, with body-frame errors of strapdown12's kind (bias
and scale factor per axis).
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
from conftest import DUR, TRK_RATE, ins_telemetry

import casep
from casep.exceptions import SaturationWarning
from casep.io.files import write_table
from casep.units import G0


def _files(tmp_path_factory, clip_dps: float):
    """The telemetry and tracking files of the shared INS simulation (``tests/conftest.py``: :func:`ins_telemetry`),
    the truth and the time of the first clipped sample."""
    tel, trk, D, held = ins_telemetry(clip_dps)
    d = tmp_path_factory.mktemp(f"clip{clip_dps:g}")
    write_table(d / "tel.csv", tel)
    write_table(d / "trk.csv", trk)
    return d / "tel.csv", d / "trk.csv", D, tel["t"][np.flatnonzero(held.any(axis=1))[0]]


@pytest.fixture(scope="module")
def clipped_at_125(tmp_path_factory):
    """Gyro clipped at the nominal +-125 deg/s range from t ~ 43 s."""
    return _files(tmp_path_factory, 125.0)


@pytest.fixture(scope="module")
def clipped_at_110(tmp_path_factory):
    """Gyro clipped at +-110 deg/s (no nominal range, nothing declared) from t ~ 36 s."""
    return _files(tmp_path_factory, 110.0)


def _separate(tel, trk):
    """casep.separate of the pair with strapdown12; the warnings it gave."""
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        res = casep.separate(casep.read_flight_pair(tel, trk), "strapdown12")
    return res, [str(w.message) for w in rec if issubclass(w.category, SaturationWarning)]


@pytest.fixture(scope="module")
def separated_125(clipped_at_125):
    """casep.separate of the pair clipped at 125 deg/s (:func:`_separate`)."""
    return _separate(*clipped_at_125[:2])


def test_clipped_gyro_in_telemetry_is_flagged_and_the_rest_left_out(clipped_at_125, separated_125):
    """w_x held at the nominal 125 deg/s: said (column, full scale, rows, times), the rows from the first clipped
    sample on left out (the INS attitude stays wrong after it), and the estimates within a few std of the truth."""
    tel, trk, D, first = clipped_at_125
    res, said = separated_125
    assert len(said) == 1 and "w_x at its maximum 125 deg/s (the nominal +-125 deg/s range)" in said[0]
    assert f"wrong from t = {first:.10g} s on" in said[0] and "rows " in said[0]
    n_before = int(np.sum(np.arange(0.0, DUR + 1e-9, 1 / TRK_RATE) < first - 1e-9))
    assert res.n_samples == n_before
    z = np.array([(res.estimate[i] - D[n]) / res.std[i] for i, n in enumerate(res.names)])
    assert res.success and np.max(np.abs(z)) < 4.0, dict(zip(res.names, z.round(2)))


def test_the_clipped_telemetry_iterates_along_what_its_tracking_determines(clipped_at_125, separated_125):
    """The rows before the clip are curved enough to iterate (the one pass's second order moves it by 1.2 std). The
    IMU noise measured on the telemetry's own second differences (gyro 3e-3 rad/s per sample on the rolling axis,
    3 times the noise written; the INS here integrated none of it) puts 1 declared magnitude or more in the std of
    every combination: leaving out by that std left all 12 at the prior, ``ba_x`` among them (0.0087 declared
    magnitudes by the tracking, 1.03 with the IMU's noise), and the stop rule then failed on its correction of 217
    tracking std. The passes leave out only what the tracking does not determine to the plausible size (the std
    the stop rule reads): the iteration converges, no combination left out has a tracking std below a declared
    magnitude, and every estimate is within 4 of its tracking-only std of the truth (and well within its std)."""
    from casep.workflows.imu_separate import SIGNIFICANT

    D = clipped_at_125[2]
    res, _ = separated_125
    it = res.diagnostics["iterations"]
    assert res.success and it["converged"] and res.diagnostics["linearisation"]["iterated"], res.message
    left = it["passes"][-1].get("left_out") or []
    assert len(left) < 6 and all(c["std"] > 1.0 and c["z"] < SIGNIFICANT for c in left), left
    stated = it["passes"][-1]["determined"]
    # the combinations whose std grow to the plausible size with the curvature of what the passes left out and the
    # consider terms are no longer stated (imu_separate._with_consider_stated): they are in the pass's record
    dropped = it["passes"][-1].get("widened_out") or []
    assert len(stated) + len(left) + len(dropped) == 12 and min(c["std_tracking_noise_only"] for c in stated) < 0.02
    trk_only = res.diagnostics["noise"]["imu"]["std_tracking_noise_only"]
    z = {n: (res.estimate[i] - D[n]) / trk_only[n] for i, n in enumerate(res.names)}
    assert max(abs(v) for v in z.values()) < 4.0, z


def test_a_fit_absorbing_an_undetected_clip_is_not_a_plain_success(clipped_at_110, tmp_path):
    """Clipped at 110 deg/s, the rail blurred by 1e-9 rad/s so no reading repeats and the screen cannot see it:
    nothing says saturation, but the residuals are hundreds of times the tracking noise and correlated after the
    noise model: failed, with the numbers."""
    from casep.estimators.registry import STATUS_MISFIT

    tel, trk, D, _ = clipped_at_110
    tab = np.genfromtxt(tel, delimiter=",", names=True)
    cols = {c: np.array(tab[c]) for c in tab.dtype.names}
    cols["w_x"] = cols["w_x"] + np.random.default_rng(1).normal(0.0, 1e-9, cols["w_x"].size)
    write_table(tmp_path / "blurred.csv", cols)
    res, said = _separate(tmp_path / "blurred.csv", trk)
    assert not said
    assert not res.success and res.status == STATUS_MISFIT
    assert "residual RMS at least 100 times the tracking's sample-to-sample noise" in res.message
    assert "x " in res.message and "m/s =" in res.message


def test_a_declared_gyro_range_finds_the_clip_in_telemetry(clipped_at_110, tmp_path, capsys):
    """``casep separate TEL --tracking TRK --gyr-range 110``: the declared full scale finds the clip the nominal
    ranges do not; the flight before it separates (a success, the estimates within a few std)."""
    from casep.cli import main

    tel, trk, D, first = clipped_at_110
    code = main(["separate", str(tel), "--tracking", str(trk), "--model", "strapdown12", "--gyr-range", "110",
                 "--json", str(tmp_path / "r.json")])
    cap = capsys.readouterr()
    err = cap.out + cap.err  # the command prints the warnings it recorded
    assert code == 0 and "w_x at its maximum 110 deg/s (the declared full scale" in err
    cut = float(err.split("wrong from t = ")[1].split(" s on")[0])
    assert first - 0.2 <= cut <= first  # 99 % of the declared range is at it (CLIP_MARGIN): a sample or two earlier
    import json

    doc = json.loads((tmp_path / "r.json").read_text())
    z = [(c["estimate"] - D[c["name"]]) / c["std"] for c in doc["coefficients"]]
    assert doc["success"] and max(abs(x) for x in z) < 4.0


def test_a_declared_gyro_range_the_telemetry_exceeds_is_refused(clipped_at_110, tmp_path, capsys):
    """The same telemetry (clipped at 110 deg/s) declared with ``--gyr-range 20``: a gyro clipped at 20 cannot read
    110, so the declared range is wrong: exit 2 naming the column, the reading and the option, nothing written (the
    raw-IMU path's rule, :func:`casep.checks.saturation.beyond_declared`)."""
    from casep.cli import main

    tel, trk, _, _ = clipped_at_110
    code = main(["separate", str(tel), "--tracking", str(trk), "--model", "strapdown12", "--gyr-range", "20",
                 "--json", str(tmp_path / "r.json")])
    err = capsys.readouterr().err
    assert code == 2 and not (tmp_path / "r.json").exists()
    assert "column `w_x`, row " in err and "the gyro reads up to 110.0" in err
    assert "5.5 times the declared full scale 20 deg/s (--gyr-range)" in err


def test_misfit_rule_needs_both_the_ratio_and_correlated_residuals():
    """misfit_problem on white dv of 0.05 m/s: a residual RMS 200 x that on a correlated axis is named; the
    same RMS on an axis the noise model whitened, or 50 x on a correlated one, is not."""
    from casep.checks.plausibility import MISFIT_RATIO, misfit_problem
    from casep.io.flight import FlightData

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 60.0, 0.1)
    fl = FlightData(t, np.tile([10.0, 20.0, 0.0], (t.size, 1)), rng.normal(0, 0.05, (t.size, 3)))
    big, small = 200 * 0.05, 0.5 * MISFIT_RATIO * 0.05
    why = misfit_problem(fl, {"x": big, "y": big, "z": small}, ("x", "z"))
    assert why is not None and "on 1 axis(es) (x 10 m/s = " in why
    assert misfit_problem(fl, {"x": big, "y": big, "z": big}, ()) is None
    # a robust fit's rejections in runs stand for the correlation, and are named in its place
    why = misfit_problem(fl, {"x": big, "y": big, "z": small}, ("x", "z"), runs=(30, 32, 3))
    assert why is not None and "the robust fit rejected 30 of its 32 rejected samples in 3 run(s)" in why
    assert "correlated after the noise model" not in why and "on 1 axis(es) (x 10 m/s = " in why


def test_misfit_advice_puts_missing_terms_before_units():
    """The misfit message says the model may lack terms (naming the richer shipped model) before anything else,
    and a unit mix-up only when a fitted scale is a unit factor (1 + sa = 1/9.81: g read as m/s^2)."""
    from casep.checks.plausibility import misfit_advice, misfit_problem, unit_factor
    from casep.io.flight import FlightData

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 60.0, 0.1)
    fl = FlightData(t, np.tile([10.0, 20.0, 0.0], (t.size, 1)), rng.normal(0, 0.05, (t.size, 3)))
    plain = misfit_advice("strapdown33", ["sa_x", "sg_x"], ["ppm", "ppm"], [300.0, -80.0])
    why = misfit_problem(fl, {"x": 10.0, "y": 0.0, "z": 0.0}, ("x",), advice=plain)
    assert why is not None and why.endswith(plain) and "unit" not in why
    assert plain.startswith("model strapdown33 may lack terms the data need: try strapdown42_extended")
    g = misfit_advice("strapdown12", ["sa_x"], ["ppm"], [(1.0 / 9.80665 - 1.0) * 1e6])
    assert g.startswith("model strapdown12 may lack terms the data need: try strapdown33 or strapdown42_extended")
    assert g.index("lack terms") < g.index("unit mix-up") and "9.81: g for m/s^2" in g
    assert unit_factor(1000.0 * 1.02) and unit_factor(1 / 3600.0) and not unit_factor(1.5) and not unit_factor(-57.3)


def test_a_clip_at_a_full_scale_nobody_declared_is_found_from_the_data(clipped_at_110):
    """w_x held at exactly 110 deg/s (no nominal range, none declared): the column's own extreme, repeated to all
    digits in a column that repeats nowhere else, is the full scale the data imply; said with the option that
    declares it, the rows from the first clip on left out, the estimates within a few std."""
    tel, trk, D, first = clipped_at_110
    res, said = _separate(tel, trk)
    assert len(said) == 1 and "w_x at its maximum 110 deg/s (a full scale +-110 deg/s implied" in said[0]
    assert "--gyr-range 110 declares it" in said[0] and f"wrong from t = {first:.10g} s on" in said[0]
    z = np.array([(res.estimate[i] - D[n]) / res.std[i] for i, n in enumerate(res.names)])
    assert res.success and np.max(np.abs(z)) < 4.0, dict(zip(res.names, z.round(2)))


def _screened(w: np.ndarray, rate: float = 100.0):
    """screen_saturation of a flight whose telemetry gyro reads `w` (N, 3), rad/s: the flight, the warnings."""
    from casep.checks.saturation import screen_saturation
    from casep.io.flight import FlightData

    t = np.arange(w.shape[0]) / rate
    fb = np.tile([0.0, G0, 0.0], (t.size, 1)) + np.sin(t)[:, None] * [0.3, 0.2, 0.1]
    sig = {**{f"w_{a}": w[:, i] for i, a in enumerate("xyz")}, **{f"fb_{a}": fb[:, i] for i, a in enumerate("xyz")}}
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        out = screen_saturation(FlightData(t, fb, np.zeros_like(fb), signals=sig))
    return out, [str(x.message) for x in rec if issubclass(x.category, SaturationWarning)]


def _smooth_rates(n: int) -> np.ndarray:
    """A noise-free turning flight's body rates at 100 Hz, rad/s (no value repeats)."""
    t = np.arange(n) / 100.0
    return np.column_stack([0.35 * np.sin(2 * np.pi * t / 25) + 0.1 * np.sin(2 * np.pi * t / 7),
                            0.25 * np.sin(2 * np.pi * t / 40) + 0.05, 0.12 * np.cos(2 * np.pi * t / 19)])


@pytest.mark.parametrize("dps, spike_at", [(24.0, None), (200.0, 90.0)])
def test_a_gyro_clipped_at_an_undeclared_non_nominal_range_is_flagged(dps, spike_at):
    """Smooth rates clipped at exactly +-24 deg/s for hundreds of rows, or a 0.6 s roll spike of 300 deg/s clipped
    at exactly 200 deg/s for about 30 rows near the end of the record: the column, the implied full scale, the rows
    and times are named, and the observed rows from the first clip on are left out."""
    w = _smooth_rates(10000)
    if spike_at is not None:
        x = (np.arange(10000) / 100.0 - spike_at) / 0.3
        w[:, 0] += np.where(np.abs(x) < 1, math.radians(300.0) * (1 - x * x) ** 2, 0.0)
    w = np.clip(w, -math.radians(dps), math.radians(dps))
    held = np.flatnonzero(np.abs(w[:, 0]) == math.radians(dps))
    assert held.size >= (300 if spike_at is None else 20)
    out, said = _screened(w)
    assert len(said) == 1 and f"(a full scale +-{dps:g} deg/s implied by identical readings" in said[0]
    assert f"--gyr-range {dps:g} declares it" in said[0] and f"rows {held[0] + 1}.." in said[0]
    assert f"t = {held[0] / 100.0:.10g}" in said[0] and "w_y" not in said[0] and "w_z" not in said[0]
    assert out.meta["saturation"]["from_s"] == pytest.approx(held[0] / 100.0, abs=1e-12)
    assert np.array_equal(out.observed, out.t < held[0] / 100.0)


def test_exact_repeats_of_a_legitimate_flight_are_not_a_clip():
    """Not flagged: a noise-free simulated flight on the pad at exactly 0, then turning, with a constant-rate
    segment at its extreme computed in floating point (repeated to all digits: the pad says the column holds
    values exactly); the pad alone; a noise-free record held at its extreme from its first sample on; a noisy
    vehicle holding a constant rate of 50 deg/s."""
    rng = np.random.default_rng(5)
    w = _smooth_rates(6000)
    w[:500] = 0.0  # the pad
    top = float(w[:, 0].max())
    w[3000:3400, 0] = top * np.cos(np.zeros(400))  # a coordinated turn at the column's maximum rate, held exactly
    assert np.sum(w[:, 0] == top) >= 400
    assert _screened(w)[1] == []
    assert _screened(np.zeros((2000, 3)))[1] == []
    w = _smooth_rates(6000)
    w[:500, 0] = w[:, 0].max() + 0.1  # held exactly from the first sample, at the column's extreme: a state, no clip
    assert _screened(w)[1] == []
    steady = np.full((3000, 3), [math.radians(50.0), 0.0, 0.0]) + rng.normal(0.0, 1e-3, (3000, 3))
    out, said = _screened(steady)
    assert said == [] and out.observed.all()


def test_a_robust_fit_on_a_model_error_is_not_a_plain_success(tmp_path):
    """A 0.6 s roll spike at t = 29 s of a 35 s flight clips w_x at 200 deg/s (blurred by 1e-9 rad/s: no screen
    sees it), so the INS attitude is wrong for the last 6 s. A Huber fit once rejected that stretch as runs of
    "glitches" and its weighted residuals passed the whiteness test on x and z, the axes of the misfit (a plain
    success before the misfit rule judged the runs). The robust filter now judges each innovation against the
    noise and the fit's own prediction variance, which the misfit inflates: nothing is rejected, the whiteness test
    sees the correlation on x and z, and the misfit rule fails the fit naming them (the rule's wording for runs:
    :func:`test_misfit_rule_needs_both_the_ratio_and_correlated_residuals`)."""
    from casep.estimators.registry import STATUS_MISFIT

    tel, trk, D, held = ins_telemetry(200.0, spike=(29.0, 300.0), dur=35.0)
    assert held.any() and tel["t"][np.flatnonzero(held.any(axis=1))[0]] > 28.5
    tel["w_x"] = tel["w_x"] + np.random.default_rng(1).normal(0.0, 1e-9, tel["w_x"].size)
    write_table(tmp_path / "tel.csv", tel)
    write_table(tmp_path / "trk.csv", trk)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        res = casep.separate(casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv"), "strapdown12",
                             robust="huber")
    assert not [w for w in rec if issubclass(w.category, SaturationWarning)]
    assert res.diagnostics["robust"]["rejected_count"] == 0
    assert {"x", "z"} <= set(res.diagnostics["whiteness"]["rejected"])
    assert not res.success and res.status == STATUS_MISFIT
    assert "correlated after the noise model" \
        in res.message and "(x " in res.message and ", z " in res.message


def test_misfit_rule_names_a_noise_model_as_slow_as_the_record():
    """White dv of 0.05 m/s over 60 s: residuals of 1.9 m/s (39 x the sample noise) that the noise model took for a
    Gauss-Markov noise of tau 40 s (2/3 of the record: it fits the signal) are named, with the axis, tau and ratio,
    though the whitened residuals pass (a dv_x/dv_z swap absorbed as tau 135-189
    s on a 184 s record). Honest correlated noise (tau 1.2 s), a slow noise whose residuals are near the sample
    noise (8 x), or one near the noise of the record's noisiest stretch (a quiet pad and a noisy flight: the simulated
    rocket's 0.035 against 1.7 m/s), is not named."""
    from casep.checks.plausibility import SLOW_NOISE_RATIO, SLOW_NOISE_SHARE, misfit_problem
    from casep.io.flight import FlightData

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 60.0, 0.1)
    fl = FlightData(t, np.tile([10.0, 20.0, 0.0], (t.size, 1)), rng.normal(0, 0.05, (t.size, 3)))
    span = t[-1] - t[0]

    def noise(tau):
        return {"axes": {a: {"model": "gauss-markov+white", "tau_s": tau} for a in "xyz"}}

    rms = {"x": 1.9, "y": 0.2, "z": 0.06}
    why = misfit_problem(fl, rms, (), noise=noise(40.0))
    assert why is not None and re.search(r"as slow as the record \(59\.9 s .* on 1 axis\(es\) \(x tau 40 s, residual "
                                         r"RMS 1\.9 m/s = 38\.7 x 0\.049 m/s\): .*the noise model fits the signal",
                                         why), why
    assert misfit_problem(fl, rms, (), noise=noise(1.2)) is None
    assert misfit_problem(fl, rms, (), noise=noise(0.99 * SLOW_NOISE_SHARE * span)) is None
    assert misfit_problem(fl, {"x": 0.8 * SLOW_NOISE_RATIO * 0.05, "y": 0.2, "z": 0.2}, (), noise=noise(40.0)) is None
    assert misfit_problem(fl, rms, ()) is None  # without the noise record: the rule of correlated residuals alone
    tt = np.concatenate([np.arange(0.0, 20.0, 0.1), np.arange(25.0, 60.0, 0.1)])  # a pause of 5 s: two stretches
    dv = np.where((tt < 22.0)[:, None], 1.0, 20.0) * rng.normal(0, 0.05, (tt.size, 3))  # 0.05, then 1 m/s
    noisy = FlightData(tt, np.tile([10.0, 20.0, 0.0], (tt.size, 1)), dv)
    assert misfit_problem(noisy, rms, (), noise=noise(40.0)) is None
    assert misfit_problem(noisy, {"x": 15.0, "y": 0.2, "z": 0.2}, (), noise=noise(40.0)) is not None
