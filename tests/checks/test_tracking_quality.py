"""The tracking screen: stale fixes, epochs the IMU rules out, a drifting clock, noise that changes between stretches.

The simulated rocket (:mod:`casep.simulation.rocket`) knows when its receiver repeated its fix, when it
reported wrong epochs and when it reacquired: the screen must leave out exactly those and keep the pad.
Clean pairs built here must come through untouched and unwarned (the suite turns warnings into errors).
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

from casep.checks.tracking_quality import (
    DRIFT_MIN_PPM,
    MAX_TERMS,
    NOISE_RATIO,
    clock_drift,
    combination_terms,
    determined_message,
    keep_screen,
    noise_problem,
    plausible_size,
    screen_tracking,
)
from casep.exceptions import GapWarning, PlausibilityWarning, SaturationWarning, TrackingQualityWarning
from casep.io.pair import pair_flight
from casep.simulation.rocket import QUICK_ROCKET, simulate_rocket


@pytest.fixture(scope="module")
def rocket(tmp_path_factory):
    """The quick rocket navigated (gyro range declared) and paired with its GNSS file, before the screen."""
    fl = simulate_rocket(3, QUICK_ROCKET)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GapWarning)
        warnings.simplefilter("ignore", PlausibilityWarning)
        warnings.simplefilter("ignore", SaturationWarning)
        _, flight = fl.navigated(tmp_path_factory.mktemp("rocket"))
    return fl, flight


def test_the_pair_reader_leaves_out_what_the_telemetry_marks_invalid(rocket):
    fl, flight = rocket
    first = fl.site.t0 + (fl.events["first_clipped"] - fl.site.t0) * (1 + 104e-6)  # the IMU's clock
    info = flight.meta["ins_invalid"]
    assert first - 0.1 < info["from_s"] <= first + 0.1 and info["rows_left_out"] > 0
    assert not flight.observed[flight.t >= info["from_s"]].any()


def test_stale_and_wrong_epochs_are_left_out_and_listed_the_pad_kept(rocket):
    fl, flight = rocket
    with pytest.warns(TrackingQualityWarning) as w:
        screened = screen_tracking(flight)
    said = " | ".join(str(m.message) for m in w)
    ev, t0 = fl.events, fl.site.t0
    t = flight.t
    before = flight.observed
    after = screened.observed
    gone = before & ~after
    # every epoch of the lock-lost span is a repeat while the rocket climbs: all gone, the fix they repeat kept
    in_stale = before & (t >= ev["stale"][0] - 1e-6) & (t <= ev["stale"][1] + 1e-6)
    assert in_stale.sum() == round(QUICK_ROCKET.stale_s * QUICK_ROCKET.gps_rate) and not after[in_stale].any()
    last_fix = before & (t > ev["stale"][0] - 0.15) & (t < ev["stale"][0] - 0.05)
    assert after[last_fix].all()
    # the wrong epochs: exactly those fail the physics check
    in_wrong = before & (t >= ev["wrong"][0] - 1e-6) & (t <= ev["wrong"][1] + 1e-6)
    assert not after[in_wrong].any()
    assert f"{round(QUICK_ROCKET.wrong_s * QUICK_ROCKET.gps_rate)} tracking epochs fail the physics check" in said
    n_pad = round(QUICK_ROCKET.pad_s * QUICK_ROCKET.gps_rate)
    first_wrong = n_pad + round((QUICK_ROCKET.lock_lost_s + QUICK_ROCKET.stale_s) * QUICK_ROCKET.gps_rate) + 1
    assert (f"rows {first_wrong}..{first_wrong + 9} of gps.parquet, t = {ev['wrong'][0]:.10g}..{ev['wrong'][1]:.10g} "
            "s (10)") in said
    # after reacquisition: one epoch per 1 Hz update kept (the lagged solution repeated in between is stale)
    reacq = after & (t >= ev["reacquired"])
    assert np.allclose(np.diff(t[reacq]), QUICK_ROCKET.gps_step_s, atol=1e-6)
    # the pad: every epoch kept (the zero-velocity check holds)
    pad = before & (t < t0)
    assert after[pad].all() and pad.sum() == round(QUICK_ROCKET.pad_s * QUICK_ROCKET.gps_rate)
    assert gone.sum() == screened.meta["tracking_screen"]["epochs"] - screened.meta["tracking_screen"]["kept"]
    assert "stale tracking epochs" in said and f"t = {ev['stale'][0]:.10g}..{ev['stale'][1]:.10g} s" in said
    # the reacquired stretch is far noisier than the pad: said, and the reason the separation fails
    why = noise_problem(screened)
    assert why is not None and "differs" in why
    pad_sd, reacq_sd = (x[3] for x in screened.meta["tracking_screen"]["stretches"])
    assert reacq_sd > NOISE_RATIO * pad_sd and 0.01 < pad_sd < 0.06  # the pad noise simulated: 0.03 m/s
    assert screen_tracking(screened) is screened  # once


def test_a_later_pass_keeps_the_first_screen_unsaid(rocket):
    """An iteration's later pass (the same tracking, the IMU corrected: dv changed by a drift of a few m/s) leaves
    out exactly the tracking rows the first pass's screen left out, without screening or warning again."""
    _, flight = rocket
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TrackingQualityWarning)
        screened = screen_tracking(flight)
    screen = screened.meta["tracking_screen"]
    assert len(screen["left_out_rows"]) == screen["epochs"] - screen["kept"] > 0
    later = dataclasses.replace(flight, dv=flight.dv + 0.1 * (flight.t - flight.t[0])[:, None])
    kept = keep_screen(later, screen)  # no warning: the suite turns one into an error
    assert np.array_equal(kept.observed, screened.observed)
    assert kept.meta["tracking_screen"] is screen and screen_tracking(kept) is kept
    assert keep_screen(later, None) is later


def _clean_pair(rng, repeats=(), glitch=None, at_rest=False, held=None, accel=20.0):
    t_tel = np.arange(0.0, 60.0, 0.01)
    acc = np.zeros((t_tel.size, 3)) if at_rest else np.column_stack(
        [5 * np.sin(0.3 * t_tel), accel + 0 * t_tel, 3 * np.cos(0.2 * t_tel)])
    v_tel = np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (acc[1:] + acc[:-1]) * 0.01, axis=0)])
    t_trk = np.arange(0.0, 60.0, 0.1)
    v_trk = np.column_stack([np.interp(t_trk, t_tel, v_tel[:, i]) for i in range(3)])
    v_trk += rng.normal(0, 0.05, v_trk.shape)
    for k in repeats:
        v_trk[k] = v_trk[k - 1]
    if held is not None:  # rows a..b-1 hold row a - 1's velocity with a jitter (m/s)
        a, b, jitter = held
        v_trk[a:b] = v_trk[a - 1] + rng.normal(0, jitter, (b - a, 3))
    if glitch is not None:
        v_trk[glitch] += 50.0
    signals = {f"a_{c}": acc[:, i] for i, c in enumerate("xyz")}
    return pair_flight(t_tel, acc, v_tel, t_trk, v_trk, signals=signals, source="pair",
                       meta={"tracking_repeats": np.asarray(repeats, dtype=int)})


def test_a_clean_pair_passes_untouched_and_a_glitch_goes_alone(rng):
    flight = _clean_pair(rng)
    screened = screen_tracking(flight)  # no warning: the suite makes one an error
    assert np.array_equal(screened.observed, flight.observed)
    assert screened.meta["tracking_screen"]["stale"] == [] and screened.meta["tracking_screen"]["rejected"] == []
    glitch = r"1 tracking epochs fail the physics check .* jumps up to 86\.\d.* t = 20 s \(1\)"
    with pytest.warns(TrackingQualityWarning, match=glitch):
        screened = screen_tracking(_clean_pair(rng, glitch=200))
    assert screened.n_observed == flight.n_observed - 1


def test_a_repeated_fix_is_stale_only_when_the_vehicle_moved(rng):
    stale = r"3 stale tracking epochs .* in 1 span\(s\): t = 30\.1\.\.30\.3 s \(3\)"
    with pytest.warns(TrackingQualityWarning, match=stale):
        screened = screen_tracking(_clean_pair(rng, repeats=(301, 302, 303)))
    assert screened.meta["tracking_screen"]["stale"] == [(30.1, 30.3, 3)]
    at_rest = _clean_pair(rng, repeats=(301, 302, 303), at_rest=True)
    assert np.array_equal(screen_tracking(at_rest).observed, at_rest.observed)  # at rest a repeat is right


def test_a_velocity_held_with_a_jitter_is_stale(rng):
    """A tracking velocity held over 2 s with 3 mm/s of jitter (no exact repeat for repeated_rows to find) while the
    telemetry accelerates at 2 g: its epochs are stale, left out and listed; held on the pad it is right."""
    stale = r"20 stale tracking epochs .* in 1 span\(s\): t = 30\.1\.\.32 s \(20\)"
    with pytest.warns(TrackingQualityWarning, match=stale):
        screened = screen_tracking(_clean_pair(rng, held=(301, 321, 0.003)))
    assert screened.meta["tracking_screen"]["stale"] == [(30.1, 32.0, 20)]
    assert not screened.observed[np.flatnonzero(screened.t >= 30.05)[:1]].any()
    at_rest = _clean_pair(rng, held=(301, 321, 0.003), at_rest=True)
    assert np.array_equal(screen_tracking(at_rest).observed, at_rest.observed)


def test_a_still_tracking_beside_a_drifting_ins_is_not_held():
    """A right tracking of a vehicle at rest (noise-free, constant) beside a MEMS INS drifting at 20 mg: the telemetry
    moves by 2 m/s over 10 s, within the instrument errors' allowance (JUMP_RATE per s), so nothing is held; the same
    tracking beside a 2 g boost is held from its second epoch on."""
    from casep.io.pair import held_epochs as _held

    t = np.arange(0.0, 10.0, 0.1)
    for accel, held in ((0.2, 0), (20.0, t.size - 1)):
        V = np.column_stack([accel * t, 0 * t, 0 * t])
        assert int(_held(t, V, V).sum()) == held  # dv = v_tel - v_trk = V: the tracking still


@pytest.mark.parametrize("accel", [20.0, 1.0, 0.1])
def test_an_honest_tracking_is_never_held(accel):
    """50 seeds of an honest 10 Hz tracking (0.05 m/s white noise) of a vehicle accelerating at 2 g, 0.1 g and
    0.01 g: no epoch is taken for a held velocity (none of 200 seeds each measured)."""
    flagged = 0
    for seed in range(50):
        flight = _clean_pair(np.random.default_rng(seed), accel=accel)
        flagged += int(flight.n_observed - screen_tracking(flight).n_observed)
    assert flagged == 0


def test_a_short_first_stretch_joined_to_the_pad_is_kept(rng):
    """Lock lost 2 s after the start: 21 right fixes, a second of fresh-looking wrong ones (+50 m/s), then a
    lagged solution (1 s late: dv = 20 m/s on y, consistent over 57 s). The right 2 s are shorter than
    MIN_SEGMENT_S, but their dv is 0 from the first sample on (the pad): kept, the wrong second alone left out
    (main left out the right 2 s too, and kept the lagged rest). The same 2 s off by 50 m/s join nothing: left out."""
    flight = _clean_pair(rng)
    t = flight.t
    obs = np.flatnonzero(flight.observed)
    a = np.column_stack([flight.signals[f"a_{c}"] for c in "xyz"])
    dv = flight.dv.copy()
    late = obs[t[obs] >= 3.0 - 1e-9]
    dv[late] += a[late] * 1.0  # v_trk(t) = v_tel(t - 1 s): dv = a 1 s
    wrong = obs[(t[obs] > 2.05) & (t[obs] < 2.95)]
    dv[wrong] += 50.0
    said = r"9 tracking epochs fail the physics check.* t = 2\.1\.\.2\.9 s \(9\)"
    with pytest.warns(TrackingQualityWarning, match=said):
        screened = screen_tracking(dataclasses.replace(flight, dv=dv))
    kept = screened.observed
    assert kept[obs[t[obs] <= 2.0 + 1e-9]].all() and not kept[wrong].any() and kept[late].all()
    dv[obs[t[obs] <= 2.0 + 1e-9]] += 50.0  # the first 2 s not at the pad's dv = 0: a short stretch like any
    said = r"30 tracking epochs fail the physics check.* t = 0\.\.2\.9 s \(30\)"
    with pytest.warns(TrackingQualityWarning, match=said):
        screened = screen_tracking(dataclasses.replace(flight, dv=dv))
    assert not screened.observed[obs[t[obs] < 2.95]].any() and screened.observed[late].all()


@pytest.mark.parametrize("ppm", [0.0, 500.0])
def test_the_clock_drift_is_measured_in_windows(rng, ppm):
    t = np.arange(0.0, 100.0, 0.1)
    a = np.column_stack([20 * np.sin(2 * np.pi * t / 7), 15 * np.cos(2 * np.pi * t / 5), 10 * np.sin(t / 3)])
    tau = 0.05 + ppm * 1e-6 * (t - 50.0)  # the tracking time tags late by tau(t)
    dv = a * tau[:, None] + 0.3 + 0.01 * t[:, None] + rng.normal(0, 0.02, a.shape)
    est, std = clock_drift(t, dv, a)
    assert abs(est - ppm) < 4 * std and std < DRIFT_MIN_PPM / 2
    assert math.isnan(clock_drift(t, dv, 0 * a)[0])  # no acceleration: no offset to see, not determined


def _gm_white(rng, n, dt, tau_c, s_gm, s_w):
    """(n, 3) Gauss-Markov (std `s_gm`, correlation time `tau_c`) plus white (std `s_w`) noise."""
    from scipy.signal import lfilter

    phi = math.exp(-dt / tau_c)
    e = rng.normal(0.0, s_gm * math.sqrt(1 - phi**2), (n, 3))
    e[0] = rng.normal(0.0, s_gm, 3)
    return lfilter([1.0], [1.0, -phi], e, axis=0) + rng.normal(0.0, s_w, (n, 3))


def test_the_clock_drift_std_holds_under_gauss_markov_noise():
    """Tracking noise correlated over 2 s, no drift: each window's offset std takes the residuals' AR(1)
    long-run factor, so the drift's z is about standard normal (60 seeded flights: RMS z 0.92; the white-residual
    std gave 1.36). benchmarks/mc_clock_drift.py: the false-alarm rate and a 104 ppm drift found."""
    t = np.arange(0.0, 300.0, 0.1)
    a = np.column_stack([3 * np.sin(2 * np.pi * t / 7), 2 * np.cos(2 * np.pi * t / 13), 4 * np.sin(2 * np.pi * t / 40)])
    z = []
    for seed in range(60):
        dv = a * 0.04 + _gm_white(np.random.default_rng(seed), t.size, 0.1, 2.0, 0.05, 0.0)
        est, std = clock_drift(t, dv, a)
        z.append(est / std)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.75 < rms < 1.15, rms  # RMS of 60 z: sampling std ~0.09


def test_the_drift_warning_says_the_offset_change_in_milliseconds():
    """ppm x 100 s = 1e-4 s = 0.1 ms per ppm: 500 ppm is 50 ms per 100 s."""
    from casep.checks.tracking_quality import TrackingScreen, _warn

    with pytest.warns(TrackingQualityWarning, match=r"drifts by 500 \+- 10 ppm \(50 ms per 100 s\)"):
        _warn("f.csv", TrackingScreen(drift_ppm=500.0, drift_std_ppm=10.0), "", "")


def test_the_imu_noise_effect_is_the_closed_form_random_walk():
    """At rest, level (f = g up), attitude fixed: the accelerometer's white noise (per-sample std sa, step h) is a
    velocity random walk, Var dv = sa^2 h t, on every axis; the gyro's tilts the platform by a random walk whose
    gravity component integrates to Var dv_h = g^2 sg^2 h t^3 / 3 on the horizontal axes, none vertically."""
    from casep.checks.tracking_quality import imu_noise_effect
    from casep.io.flight import FlightData

    rng = np.random.default_rng(11)
    h, sa, sg, g = 1 / 200, 0.002, 2e-3, 9.80665  # horizontally the tilt dominates (by 3000x at 10 s)
    t = np.arange(0.0, 10.5, h)
    n = t.size
    f = np.tile([0.0, 0.0, g], (n, 1))
    sig = {"q_w": np.ones(n), "q_x": np.zeros(n), "q_y": np.zeros(n), "q_z": np.zeros(n),
           **{f"fb_{a}": f[:, i] + rng.normal(0, sa, n) for i, a in enumerate("xyz")},
           **{f"w_{a}": rng.normal(0, sg, n) for a in "xyz"}}
    flight = FlightData(t, f, np.zeros((n, 3)), meta={"rows_index": np.full(n, -1)}, signals=sig)
    rows = np.array([5.0, 10.0])
    G = imu_noise_effect(flight, rows, np.eye(6))  # seen through the identity: G itself
    var = np.sum(G**2, axis=1).reshape(2, 3)
    closed = np.array([[sa**2 * h * T + g**2 * sg**2 * h * T**3 / 3] * 2 + [sa**2 * h * T] for T in rows])
    np.testing.assert_allclose(var, closed, rtol=0.15)  # the per-sample std measured from 2100 samples (MAD)
    # the laws whatever the measured std: t for the velocity walk, t^3 for the tilt's
    np.testing.assert_allclose(var[1, 2] / var[0, 2], 2.0, rtol=1e-3)
    np.testing.assert_allclose(var[1, :2] / var[0, :2], closed[1, :2] / closed[0, :2], rtol=0.01)
    assert imu_noise_effect(dataclasses.replace(flight, meta={}), rows, np.eye(6)) is None  # no IMU samples


def test_the_imu_noise_is_measured_beside_the_motion():
    """A 100 Hz record of a rolling, accelerating flight (rates of 1 rad/s swinging at 0.5 Hz, forces of 5 m/s^2 at
    0.3 Hz) with white noise of 1e-3 rad/s and 2e-3 m/s^2 per sample: the per-sample std measured within 10 % of
    the noise's (the second differences alone read 4-9 % high; the changes between consecutive samples read the
    motion's slope: 0.023 rad/s and 0.07 m/s^2 here); the same record noise-free reads below a thousandth of it
    (the least over difference orders 2-6; the second differences alone: 0.4 of it)."""
    from casep.checks.tracking_quality import imu_sample_noise
    from casep.io.flight import FlightData

    rng = np.random.default_rng(5)
    h, sg, sa = 0.01, 1e-3, 2e-3
    t = np.arange(0.0, 30.0, h)
    n = t.size
    motion = {**{f"w_{a}": np.sin(np.pi * t + k) for k, a in enumerate("xyz")},
              **{f"fb_{a}": 5.0 * np.cos(0.6 * np.pi * t + k) for k, a in enumerate("xyz")}}
    quat = {"q_w": np.ones(n), "q_x": np.zeros(n), "q_y": np.zeros(n), "q_z": np.zeros(n)}
    meta = {"rows_index": np.full(n, -1)}
    noisy = {c: x + rng.normal(0, sg if c[0] == "w" else sa, n) for c, x in motion.items()}
    s, step, _ = imu_sample_noise(FlightData(t, np.zeros((n, 3)), np.zeros((n, 3)), meta=meta,
                                             signals={**quat, **noisy}), t)
    assert step == pytest.approx(h) and s.shape == (6,)
    np.testing.assert_allclose(s, [sa] * 3 + [sg] * 3, rtol=0.10)
    clean, _, _ = imu_sample_noise(FlightData(t, np.zeros((n, 3)), np.zeros((n, 3)), meta=meta,
                                              signals={**quat, **motion}), t)
    assert np.all(clean < 1e-3 * np.array([sa] * 3 + [sg] * 3)), clean


def _fast_motion(rate: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]:
    """20 s of a fast manoeuvre at `rate` Hz (rates of 1 rad/s swinging at 2 Hz, forces of 5 m/s^2 at 3 Hz) and white
    noise of 1e-4 rad/s and 2e-3 m/s^2 per sample: ``(t, motion (n, 6), noise (n, 6), (s_acc, s_gyro))``."""
    h = 1.0 / rate
    t = np.arange(0.0, 20.0, h)
    k = np.arange(3)
    motion = np.column_stack([5.0 * np.cos(6 * np.pi * t[:, None] + k), np.sin(4 * np.pi * t[:, None] + k)])
    sa, sg = 2e-3, 1e-4
    noise = np.random.default_rng(seed).normal(0.0, 1.0, motion.shape) * np.array([sa] * 3 + [sg] * 3)
    return t, motion, noise, (sa, sg)


@pytest.mark.parametrize("rate", [100.0, 400.0])
def test_the_imu_noise_is_measured_beside_a_fast_motion(rate):
    """:func:`white_sample_std` on :func:`_fast_motion`: the white noise drawn is recovered within its sampling error
    (3 of :func:`white_std_error`, 4 % at 100 Hz), where the second differences alone read the manoeuvre (at 100 Hz
    0.0156 rad/s and 0.25 m/s^2 of it, 60-200 times the noise); the noise-free manoeuvre reads below a hundredth of
    the noise (its sixth differences: 1e-7 rad/s and 1e-5 m/s^2 at 100 Hz), at its rounding at 400 Hz."""
    from math import sqrt

    from casep.checks.tracking_quality import white_sample_std, white_std_error

    for seed in (1, 2):
        t, motion, noise, (sa, sg) = _fast_motion(rate, seed)
        drawn = np.array([sa] * 3 + [sg] * 3)
        got = white_sample_std(motion + noise)
        np.testing.assert_allclose(got, drawn, rtol=3 * white_std_error(t.size))
        d2 = np.diff(motion + noise, 2, axis=0)
        second = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) * 1.4826 / sqrt(6)
        assert np.all(second > 1.5 * drawn), second / drawn  # the test can fail: the old rule reads the motion
        assert np.all(white_sample_std(motion) < 1e-2 * drawn), white_sample_std(motion) / drawn


def test_the_imu_noise_is_taken_on_the_pad_where_the_record_counts_motion():
    """A 100 Hz record: 30 s at rest on the pad, then 60 s of a motion as rough as a noise up to the Nyquist frequency
    (seeded white "jitter" of 0.05 m/s^2 and 1e-3 rad/s, which the IMU measures correctly: no difference order tells
    it from noise), with sensor noise of 0.01 m/s^2 and 3e-5 rad/s per sample (a tactical IMU). With the pad's
    figure (:func:`pad_white_std`, ``meta[IMU_NOISE_PAD]``), :func:`imu_sample_noise` takes it on every column
    (:func:`imu_noise_on_pad`) and reads the sensor noise within its sampling error, where the record alone reads
    the jitter (2.8-16 times too large); noise-free, the pad reads its rounding, every column "not measured", far below
    the record's figure; a pad of white noise only keeps the differences' figure (the record's where both agree)."""
    from casep.checks.tracking_quality import (
        IMU_NOISE_COLUMNS,
        IMU_NOISE_PAD,
        imu_noise_on_pad,
        imu_sample_noise,
        pad_white_std,
        unresolved_noise,
        white_sample_std,
        white_std_error,
    )
    from casep.io.flight import FlightData

    rng = np.random.default_rng(7)
    h = 0.01
    t = np.arange(0.0, 90.0, h)
    n, pad = t.size, t <= 29.0
    level = np.array([0.0, 0.0, 9.81, 0.0, 0.0, 7e-5])
    jitter = np.where(pad[:, None], 0.0, rng.normal(0.0, 1.0, (n, 6)) * np.array([0.05] * 3 + [1e-3] * 3))
    drawn = np.array([0.01] * 3 + [3e-5] * 3)
    quat = {"q_w": np.ones(n), "q_x": np.zeros(n), "q_y": np.zeros(n), "q_z": np.zeros(n)}

    def flight(x, with_pad=True):
        meta: dict = {"rows_index": np.full(n, -1)}
        if with_pad:
            s, e = pad_white_std(x[pad], h)
            meta[IMU_NOISE_PAD] = {"std": s, "rel_error": e, "span": (0.0, 29.0)}
        sig = {**quat, **{c: x[:, i] for i, c in enumerate(IMU_NOISE_COLUMNS)}}
        return FlightData(t, np.zeros((n, 3)), np.zeros((n, 3)), meta=meta, signals=sig)

    noisy = level + jitter + rng.normal(0.0, 1.0, (n, 6)) * drawn
    s, _, i = imu_sample_noise(flight(noisy), t)
    np.testing.assert_allclose(s, drawn, rtol=3 * white_std_error(int(pad.sum())))
    assert imu_noise_on_pad(flight(noisy), t) == list(IMU_NOISE_COLUMNS)
    record = imu_sample_noise(flight(noisy, with_pad=False), t)[0]
    assert np.all(record > 2 * drawn), record / drawn
    clean = level + jitter
    fl = flight(clean)
    s, _, i = imu_sample_noise(fl, t)
    assert np.all(s < 1e-10 * imu_sample_noise(flight(clean, with_pad=False), t)[0]), s
    assert unresolved_noise(fl, s, i) == list(IMU_NOISE_COLUMNS)
    quiet = level + rng.normal(0.0, 1.0, (n, 6)) * drawn  # no motion: the record's figure, from more samples
    assert imu_noise_on_pad(flight(quiet), t) == []
    np.testing.assert_array_equal(imu_sample_noise(flight(quiet), t)[0], white_sample_std(quiet))
    s_pad, e_pad = pad_white_std(quiet[pad], h)
    np.testing.assert_array_equal(s_pad, white_sample_std(quiet[pad]))
    assert np.all(e_pad == white_std_error(int(pad.sum())))


def test_the_pad_takes_the_allan_deviation_under_an_engines_vibration():
    """:func:`pad_white_std` on 30 s at rest at 100 Hz with white noise of 1e-3 rad/s under a 0.02 rad/s vibration at
    43 Hz (an engine: motion the IMU measures correctly): the differences read the vibration (20x), the Allan
    deviation at 1 s does not, and is taken (its error said: :func:`allan_white_error`, 0.11 for 29 averaging
    times); within 3 of that error of the noise (seeds 1-3)."""
    from casep.checks.tracking_quality import allan_white_error, pad_white_std

    h, s = 0.01, 1e-3
    t = np.arange(0.0, 30.0, h)
    for seed in (1, 2, 3):
        rng = np.random.default_rng(seed)
        x = 0.02 * np.sin(2 * np.pi * 43.0 * t[:, None] + rng.uniform(0, 6, 6)) + rng.normal(0, s, (t.size, 6))
        got, err = pad_white_std(x, h)
        assert np.all(err == allan_white_error(t.size, h)) and 0.09 < err[0] < 0.13, err
        np.testing.assert_allclose(got, s, rtol=3 * err[0])


@pytest.mark.parametrize("grid", ["tracking", "telemetry"])
def test_the_imu_noise_is_measured_on_every_telemetry_sample_a_tracking_epoch_on_one_included(grid):
    """A pair whose 20 Hz tracking epochs fall on the 20 Hz telemetry's samples from 3 s on, after a quiet pad
    (constant rate and force, noise-free: a simulated IMU standing still), the flight's samples (rates and forces
    ramping) with white noise of 1e-4 rad/s and 2e-3 m/s^2: the noise is measured on all the telemetry's samples up to
    the last epoch (the same numbers as :func:`white_sample_std` of the file's columns, and within 10 % of the noise
    drawn). Before, the samples with a tracking epoch on them were left out as if inserted: only the pad's 60 were
    left and the noise read ~1e-16 (the IMU's random walks dropped out of the std, and the IMU noise's blocks
    integrated F across the 117 s without samples); on the telemetry grid no sample was the telemetry's own: no IMU
    noise at all."""
    from casep.checks.tracking_quality import imu_sample_noise, unresolved_noise, white_sample_std
    from casep.io.pair import pair_flight

    rng = np.random.default_rng(11)
    h, sg, sa = 0.05, 1e-4, 2e-3
    t_tel = np.round(np.arange(0.0, 120.0, h), 10)
    n = t_tel.size
    flying = t_tel >= 3.0
    cols = {**{f"w_{a}": np.where(flying, 0.1 * k + 0.01 * t_tel + rng.normal(0, sg, n), 1e-5)
               for k, a in enumerate("xyz")},
            **{f"fb_{a}": np.where(flying, 30.0 - 5 * k - 0.1 * t_tel + rng.normal(0, sa, n), 9.8 * (a == "z"))
               for k, a in enumerate("xyz")},
            "q_w": np.ones(n), "q_x": np.zeros(n), "q_y": np.zeros(n), "q_z": np.zeros(n)}
    f = np.column_stack([cols[f"fb_{a}"] for a in "xyz"])
    v_tel = np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (f[1:] + f[:-1]) * h, axis=0)])
    t_trk = t_tel[flying]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = pair_flight(t_tel, f, v_tel, t_trk, v_tel[flying], signals=cols, grid=grid, source="pair")
    got = imu_sample_noise(flight, flight.t[np.asarray(flight.observed)])
    assert got is not None
    s, step, i = got
    assert step == pytest.approx(h) and i.size == n
    np.testing.assert_array_equal(flight.t[i], t_tel)
    raw = np.column_stack([cols[f"{k}_{a}"] for k in ("fb", "w") for a in "xyz"])
    np.testing.assert_allclose(s, white_sample_std(raw), rtol=1e-9)
    np.testing.assert_allclose(s, [sa] * 3 + [sg] * 3, rtol=0.10)
    assert unresolved_noise(flight, s, i) == []


def test_a_noise_the_samples_do_not_show_is_not_measured():
    """A noise-free record (a turning, accelerating flight at 20 Hz, 60 % of it standing still first) reads a
    per-sample std at its values' rounding (the second differences at rest are zero, the MAD takes them): every column
    is said not measured, beside its noisy twin (2e-3 m/s^2, 1e-4 rad/s: none), and the report says so instead of
    "measured on the record"; one column quantised beside white noise it does not hide is measured."""
    from casep.checks.tracking_quality import IMU_NOISE_COLUMNS, imu_sample_noise, unresolved_noise
    from casep.io.flight import FlightData
    from casep.reporting.noise_text import imu_noise_line

    rng = np.random.default_rng(2)
    h = 0.05
    t = np.arange(0.0, 100.0, h)
    n = t.size
    move = t >= 60.0
    clean = {**{f"w_{a}": np.where(move, np.sin(0.5 * t + k), 7e-5) for k, a in enumerate("xyz")},
             **{f"fb_{a}": np.where(move, 20.0 * np.cos(0.2 * t + k), 9.8 * (a == "z")) for k, a in enumerate("xyz")}}
    quat = {"q_w": np.ones(n), "q_x": np.zeros(n), "q_y": np.zeros(n), "q_z": np.zeros(n)}
    meta = {"rows_index": np.full(n, -1)}

    def measured(cols):
        fl = FlightData(t, np.zeros((n, 3)), np.zeros((n, 3)), meta=meta, signals={**quat, **cols})
        s, _, i = imu_sample_noise(fl, t)
        return s, unresolved_noise(fl, s, i)

    s, unseen = measured(clean)
    assert np.all(s < 1e-12) and unseen == ["fb_x", "fb_y", "fb_z", "w_x", "w_y", "w_z"], (s, unseen)
    noisy = {c: x + rng.normal(0, 1e-4 if c[0] == "w" else 2e-3, n) for c, x in clean.items()}
    assert measured(noisy)[1] == []
    steps = {**noisy, "fb_x": np.round(noisy["fb_x"] / 1e-3) * 1e-3}  # a 1e-3 m/s^2 quantum under 2e-3 of noise
    assert measured(steps)[1] == []
    account = {"accelerometer_m_s2": list(s[:3]), "gyro_rad_s": list(s[3:]), "sample_step_s": h,
               "std_factor_max": 1.0, "std_factor_worst": "ba_x", "not_measured": unseen}
    line = imu_noise_line(account)
    assert line.startswith("IMU noise not measured") and "measured on the record" not in line, line
    line = imu_noise_line({**account, "not_measured": ["w_x"]})
    assert "not measured on w_x" in line, line
    pad = {**account, "on_pad": ["w_x", "w_y", "w_z"], "pad_span_s": (0.0, 29.0), "not_measured": []}
    line = imu_noise_line(pad)
    assert line.startswith("IMU noise (measured at rest on the pad 0..29 s for w_x, w_y, w_z, on the record else"), line
    line = imu_noise_line({**pad, "on_pad": list(IMU_NOISE_COLUMNS), "not_measured": unseen})
    assert line.startswith("IMU noise not measured (looked for at rest on the pad 0..29 s)"), line


@pytest.mark.parametrize("levelled", [False, True])
def test_the_imu_noise_state_is_the_imu_noise_effect(levelled):
    """The linear state of the IMU's white noise (:func:`imu_noise_states`) has the covariance ``G G^T`` of
    :func:`imu_noise_effect` at the epochs, to 1e-12, on a turning, accelerating record; with the levelling's start
    tilt (a window over the first 2 s, a levelling Jacobian of rank 2 as levelling alone gives) as well: the tilt
    acts from the first epoch on, before the window's noise has ended (the state's Gaussian bridge)."""

    from casep.checks.tracking_quality import imu_noise_effect, imu_noise_states

    flight, rows, levelling = _turning_rows(levelled)
    G = imu_noise_effect(flight, rows, np.eye(3 * rows.size), levelling)
    known = imu_noise_states(flight, rows, levelling)
    assert known.T.shape[1] == (15 if levelled else 9)
    np.testing.assert_allclose(known.dense(), G @ G.T, rtol=0, atol=1e-12 * np.abs(G @ G.T).max())


@pytest.mark.parametrize("levelled", [False, True])
def test_the_imu_bias_instability_state_is_its_effect(levelled):
    """The bias instability's six states (:func:`imu_noise_states` with a correlation time, scaled to ``(q_a, q_g)``)
    have the covariance ``G G^T`` of :func:`imu_noise_effect` with the instability's columns, to 1e-11, with and
    without the levelling's states beside them; the parts add linearly (twice ``q``: twice the instability's
    covariance)."""
    from casep.checks.tracking_quality import imu_noise_effect, imu_noise_states

    flight, rows, levelling = _turning_rows(levelled)
    q = (4e-4, 3e-6)  # (m/s^2)^2, (rad/s)^2: of the white noise's size over a block
    known = imu_noise_states(flight, rows, levelling, instability_tau=2.5)
    assert known.T.shape[1] == (21 if levelled else 15) and len(known.parts) == 2
    for k in (1.0, 2.0):
        G = imu_noise_effect(flight, rows, np.eye(3 * rows.size), levelling, (2.5, k * q[0], k * q[1]))
        np.testing.assert_allclose(known.scaled([k * q[0], k * q[1]]).dense(), G @ G.T, rtol=0,
                                   atol=1e-11 * np.abs(G @ G.T).max())
    white = imu_noise_effect(flight, rows, np.eye(3 * rows.size), levelling)
    np.testing.assert_allclose(known.scaled([0.0, 0.0]).dense(), white @ white.T, rtol=0,
                               atol=1e-12 * np.abs(white @ white.T).max())


def test_the_imu_bias_effect_is_a_gauss_markov_bias_summed_by_definition():
    """:func:`imu_bias_effect` against its definition formed densely: the blocks' biases with ``Cov(b_j, b_l) = q
    exp(-|t_j - t_l| / tau)`` (block mean times), each acting at the epochs after its block as ``C_j h n_j b_a`` and
    ``-(F_r - F_j) x C_j h n_j b_g``: ``E Cov_b E^T`` to 1e-10, at a correlation time of a block and of a record."""
    from casep.checks.tracking_quality import _imu_noise_blocks, imu_bias_effect

    rng = np.random.default_rng(8)
    flight = _turning_record(rng)
    rows = np.array([0.3, 1.3, 2.0, 3.3, 4.0, 5.5])
    terms = _imu_noise_blocks(flight, rows, None)
    B = terms.t_end.size
    for tau in (0.2, 6.0):
        E = np.zeros((3 * rows.size, B, 6))  # per unit bias of each block and axis
        for r, tr in enumerate(rows):
            after = np.flatnonzero(terms.t_end <= tr)
            dF = terms.F_rows[r] - terms.F_mid[after]
            E[3 * r:3 * r + 3, after, :3] = np.moveaxis(terms.unit[after], 0, 1)
            E[3 * r:3 * r + 3, after, 3:] = -np.moveaxis(np.cross(dF[:, :, None], terms.unit[after], axisa=1,
                                                                  axisb=1, axisc=1), 0, 1)
        corr = np.exp(-np.abs(np.subtract.outer(terms.t_mid, terms.t_mid)) / tau)
        for k, sl in enumerate((slice(0, 3), slice(3, 6))):
            want = np.einsum("ibx,bc,jcx->ij", E[:, :, sl], corr, E[:, :, sl])
            G = imu_bias_effect(flight, rows, np.eye(3 * rows.size), tau)[k]
            np.testing.assert_allclose(G @ G.T, want, rtol=0, atol=1e-10 * np.abs(want).max())


def test_the_imu_noise_effect_sums_each_epoch_once_in_any_order():
    """``weights @ G`` by the suffix sums of :func:`imu_noise_effect` against its definition summed epoch by epoch
    (each block's columns at every epoch after it: ``ga`` and ``-(F_r - F_mid) x gg``), the epochs out of time order,
    one before any block ends, one at a block's last sample, several weight rows: to 1e-12."""

    from casep.checks.tracking_quality import _imu_noise_blocks, imu_noise_effect

    rng = np.random.default_rng(8)
    flight = _turning_record(rng)
    rows = np.array([4.0, 0.02, 5.5, 1.3, 3.3, 2.0, 0.5])
    terms = _imu_noise_blocks(flight, rows, None)
    assert rows.min() < terms.t_end.min() and np.isin(terms.t_end, rows).any()
    W = rng.normal(size=(4, 3 * rows.size))
    ref = np.zeros((4, terms.t_end.size, 6))
    for r, tr in enumerate(rows):
        after = terms.t_end <= tr
        dF = terms.F_rows[r] - terms.F_mid[after]
        G_r = np.concatenate([terms.ga[after], -np.cross(dF[:, :, None], terms.gg[after], axisa=1, axisb=1,
                                                          axisc=1)], 2)
        ref[:, after] += np.einsum("ki,bij->kbj", W.reshape(4, rows.size, 3)[:, r], G_r)
    got = imu_noise_effect(flight, rows, W)
    np.testing.assert_allclose(got, ref.reshape(4, -1), rtol=0, atol=1e-12 * np.abs(ref).max())


def test_a_correlated_stretch_is_weighted_by_its_long_run_variance():
    """One offset seen by a quiet white stretch and by a stretch of Gauss-Markov noise whose epoch-to-epoch changes
    look quiet (lag-1 correlation 0.95: its mean is 28 times less certain than white noise of that scatter says).
    Seeded, 150 draws: the determined offset's z has RMS near 1 and 95 % coverage; with the stretches weighted
    by their scatter alone the correlated one would take most of the weight: RMS z 6.1 on these draws."""
    from casep.checks.tracking_quality import determined, stretch_noise
    from casep.regression.problem import Problem

    rng = np.random.default_rng(5)
    n, phi = 200, 0.95
    t = np.concatenate([np.arange(n) * 0.1, 30.0 + np.arange(n) * 0.1])
    S = np.zeros((2 * n, 3, 1))
    S[:, 0, 0] = 1.0
    z = []
    for _ in range(150):
        y = np.zeros((2 * n, 3))
        y[:, 1:] = rng.normal(0, 0.05, (2 * n, 2))
        y[:n, 0] = rng.normal(0, 0.05, n)
        e = np.empty(n)
        e[0] = rng.normal(0, 0.5)
        for k in range(1, n):
            e[k] = phi * e[k - 1] + rng.normal(0, 0.5 * math.sqrt(1 - phi**2))
        y[n:, 0] = e
        combos, _ = determined(Problem.from_arrays(S, y, t), stretch_noise(t, y), {"c0": 1.0})
        z.append(combos[0]["estimate"] / combos[0]["std"])
    z_arr = np.abs(np.asarray(z))
    rms = math.sqrt(np.mean(z_arr**2))
    assert 0.8 < rms < 1.2, rms
    assert 0.9 <= np.mean(z_arr < 1.959964) <= 1.0


def test_the_combinations_std_carry_the_consider_parameters_rows():
    """A consider parameter's rows (one std of it, N x 3) give each determined combination a variance beside its std
    (``consider_var``) the square of how far those rows, added to the data, move its estimate: checked by the fit
    itself, estimating again from the rows with the consider shift added (a shift inside the coefficients' columns,
    so the residuals and the stretches' weights stay as they were)."""
    from casep.checks.tracking_quality import determined, stretch_noise
    from casep.regression.problem import Problem

    rng = np.random.default_rng(3)
    n = 300
    t = np.arange(n) * 0.1
    S = rng.normal(0.0, 1.0, (n, 3, 2))
    y = rng.normal(0.0, 0.05, (n, 3))
    y[n // 2:] *= 4.0  # two stretches of different noise
    scales = {"c0": 2.0, "c1": 0.5}
    K = (0.03 * S[:, :, 0] + 0.01 * S[:, :, 1])[:, :, None]
    stretches = stretch_noise(t, y)
    plain, _ = determined(Problem.from_arrays(S, y, t), stretches, scales)
    wide, _ = determined(Problem.from_arrays(S, y, t), stretches, scales, consider=K)
    moved, _ = determined(Problem.from_arrays(S, y + K[:, :, 0], t), stretches, scales)
    assert len(plain) == len(wide) == len(moved) == 2
    for a, b, c in zip(plain, wide, moved):
        assert b["estimate"] == a["estimate"] and b["std"] == a["std"]  # what the record determines: its own
        assert b["consider_var"] == pytest.approx((c["estimate"] - a["estimate"]) ** 2, rel=1e-6)
        assert b["consider_var"] > 0.0


def test_stale_tracking_inside_a_one_file_flight_is_left_out(tmp_path, rng):
    """The tracking columns of a one-file flight (v_tel_* beside v_trk_*) are screened as a tracking file is: rows
    repeating a fix while the vehicle accelerates at 20 m/s^2 are left out and listed by file line; the same rows
    at rest (a repeat is right there) and the clean flight are left alone."""
    import casep
    from casep.checks.time_offset import GRAVITY_LAUNCH
    from casep.io.files import write_table

    t = np.arange(0.0, 20.0, 0.1)
    a = np.outer(np.where(t > 5.0, 20.0, 0.0), [1.0, 0.0, 0.0])  # at rest 0-5 s, then 20 m/s^2 along x
    v_tel = np.column_stack([np.concatenate([[0.0], np.cumsum(0.5 * (a[1:, 0] + a[:-1, 0]) * 0.1)]), 0 * t, 0 * t])
    v_trk = v_tel + rng.normal(0.0, 0.05, v_tel.shape)
    for rows, n_stale in ((slice(101, 121), 20), (slice(11, 31), 0), (slice(0, 0), 0)):
        trk = v_trk.copy()
        if rows.stop:
            trk[rows] = trk[rows.start - 1]  # the fix of the row before, repeated
        path = tmp_path / "one.csv"
        write_table(path, {"t": t, **{f"f_{c}": (a - GRAVITY_LAUNCH)[:, i] for i, c in enumerate("xyz")},
                           **{f"v_tel_{c}": v_tel[:, i] for i, c in enumerate("xyz")},
                           **{f"v_trk_{c}": trk[:, i] for i, c in enumerate("xyz")}})
        flight = casep.read_flight(path)
        if n_stale:
            stale = r"20 stale tracking epochs .* lines 103\.\.122 of one\.csv, t = 10\.1\.\.12 s \(20\)"
            with pytest.warns(TrackingQualityWarning, match=stale):
                screened = screen_tracking(flight)
            assert np.flatnonzero(~screened.observed).tolist() == list(range(101, 121))
        else:
            screened = screen_tracking(flight)  # no warning: the suite makes one an error
            assert screened.observed.all() and screened.meta["tracking_screen"]["stale"] == []


def test_a_combination_is_written_with_every_term_that_matters_at_the_plausible_size():
    """A term is written when it moves the combination by its std at the plausible size (``|w| size >= std``), the
    three largest always, at most MAX_TERMS; the text counts the others of weight 0.005 or more."""
    names = [f"c{j}" for j in range(12)]
    w = np.array([0.9, -0.4, 0.1, 0.05, 0.01, 0.004, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert plausible_size([{"estimate": -80.0}, {"estimate": 3.0}]) == 80.0
    assert plausible_size([{"estimate": 0.2}]) == 1.0  # never below the declared magnitude
    terms, more = combination_terms(names, w, std=0.5, size=10.0)  # |w| >= 0.05
    assert list(terms) == ["c0", "c1", "c2", "c3"] and terms["c1"] == -0.4 and more == 1  # 0.01 not written
    terms, more = combination_terms(names, w, std=0.5, size=1.0)  # none but the largest three
    assert list(terms) == ["c0", "c1", "c2"] and more == 2
    terms, more = combination_terms(names, np.full(12, 0.2), std=0.01, size=1.0)
    assert len(terms) == MAX_TERMS and more == 12 - MAX_TERMS
    text = determined_message("noise", [{"terms": terms, "more": more, "estimate": 1.0, "std": 0.1}], 1.0, 12, {})
    assert f"(+ {12 - MAX_TERMS} smaller terms) = 1 +- 0.1" in text


def _tilted_pair(ppm: float, seed: int = 3):
    """A pair (10 Hz, 300 s, a manoeuvring aircraft's acceleration) whose dv holds the tilt of a 100 deg/h gyro
    bias on each axis (``int f x (w t) dt``), a 40 ms tracking tag offset drifting by `ppm`, and white noise
    0.02 m/s; and the fit's residuals (least squares of the tilt columns, a constant and the offset column)."""
    from casep.io.flight import FlightData

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 300.0, 0.1)
    a = np.column_stack([3 * np.sin(2 * np.pi * t / 7), 2 * np.cos(2 * np.pi * t / 13), 4 * np.sin(2 * np.pi * t / 40)])
    f = a + np.array([0.0, 0.0, 9.81])

    def integral(x):
        return np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t)[:, None], axis=0)])

    cols = np.stack([integral(np.cross(f, np.eye(3)[k] * t[:, None])) for k in range(3)]
                    + [np.ones_like(a) * (np.arange(3) == j) for j in range(3)] + [a], axis=2)  # (n, 3, 7)
    dv = cols[:, :, :3] @ np.radians([100.0, -100.0, 100.0]) / 3600.0
    dv += a * (0.04 + ppm * 1e-6 * t)[:, None] + rng.normal(0.0, 0.02, a.shape)
    S = cols.reshape(-1, cols.shape[2])
    x, *_ = np.linalg.lstsq(S, dv.reshape(-1), rcond=None)
    fl = FlightData(t, f, dv, source="pair.csv", meta={"format": "pair"},
                    signals={f"a_{c}": a[:, i] for i, c in enumerate("xyz")})
    return fl, (dv.reshape(-1) - S @ x).reshape(dv.shape)


def test_the_clock_drift_is_measured_on_the_fits_residuals():
    """A gyro bias's tilt makes dv follow the specific force differently in each window: on the raw dv the
    windows' offsets scatter (std hundreds of ppm: a 104 ppm drift is lost); on the fit's residuals
    (fit_clock_drift) a 104 ppm drift is found within 4 std, warned and said as measured there, and none is
    warned without a drift. benchmarks/mc_clock_drift.py --instrument: the rates over 200 seeds."""
    from casep.checks.tracking_quality import fit_clock_drift

    fl, r = _tilted_pair(104.0)
    raw, raw_std = clock_drift(fl.t, fl.dv, np.column_stack([fl.signals[f"a_{c}"] for c in "xyz"]))
    assert raw_std > 104.0 / 4  # the raw dv cannot tell 104 ppm
    with pytest.warns(TrackingQualityWarning, match="on the fit's residuals"):
        est, std = fit_clock_drift(fl, r)
    assert abs(est - 104.0) < 4 * std and std < 104.0 / 4
    fl0, r0 = _tilted_pair(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TrackingQualityWarning)
        est0, std0 = fit_clock_drift(fl0, r0)
    assert abs(est0) < 4 * std0
    assert fit_clock_drift(dataclasses.replace(fl0, meta={}), r0) is None  # one file: one clock
    assert fit_clock_drift(fl0, r0[:-1]) is None  # residuals of other epochs


def _slow_manoeuvres(seed: int, ppm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, dv, a)``: 180 s at 10 Hz of an aircraft's slow manoeuvres (accelerations of periods 70-120 s, near a
    quadratic over a 30 s window), tags late by 40 ms + `ppm` 1e-6 t, Gauss-Markov (1 s, 0.05 m/s) + white 0.03."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 180.0, 0.1)
    ph = rng.uniform(0.0, 2 * np.pi, 3)
    a = np.column_stack([3 * np.sin(2 * np.pi * t / 70 + ph[0]), 2 * np.cos(2 * np.pi * t / 90 + ph[1]),
                         4 * np.sin(2 * np.pi * t / 120 + ph[2])])
    phi = math.exp(-0.1)
    gm = np.empty((t.size, 3))
    gm[0] = rng.normal(0.0, 0.05, 3)
    for k in range(1, t.size):
        gm[k] = phi * gm[k - 1] + rng.normal(0.0, 0.05 * math.sqrt(1 - phi**2), 3)
    return t, a * (0.040 + ppm * 1e-6 * t)[:, None] + gm + rng.normal(0.0, 0.03, (t.size, 3)), a


def test_on_residuals_the_windows_fit_no_trend_of_their_own():
    """Where the acceleration is near a quadratic over a window, a quadratic trend per axis takes most of a tau:
    the windows' offsets have std of ~760 ppm per the drift and a 300 ppm drift is lost; without trends (order 0,
    what fit_clock_drift uses on a fit's residuals, where no instrument error is left for a trend to take) the
    std are ~50 ppm and it is found within 4 std, 7 seeds of 8 or more beyond the alarm threshold (40 seeds: 33)."""
    runs = {o: np.array([clock_drift(*_slow_manoeuvres(s, 300.0), order=o) for s in range(8)]) for o in (2, 0)}
    assert np.median(runs[2][:, 1]) > 5 * np.median(runs[0][:, 1])
    est, std = runs[0][:, 0], runs[0][:, 1]
    assert np.sum(np.abs(est) > np.maximum(DRIFT_MIN_PPM, 4 * std)) >= 6
    assert np.all(np.abs(est - 300.0) < 4 * std)


def test_the_imu_noise_at_rest_ignores_vibration_near_nyquist():
    """White noise of 1e-3 rad/s per sample at 100 Hz under a vibration of 0.02 rad/s at 43 Hz (an engine): the
    second differences read the vibration as white noise (20x here), the Allan deviation at 1 s does not: its
    reading is within 25 % of the white noise's std (30 s: about 40 independent averages; seeds 1-3), and a
    flight carrying it under IMU_NOISE_AT_REST has it taken by imu_sample_noise instead of its own samples'."""
    from casep.checks.tracking_quality import IMU_NOISE_AT_REST, imu_sample_noise, rest_white_std, white_sample_std
    from casep.io.flight import FlightData

    h, s = 0.01, 1e-3
    t = np.arange(0.0, 30.0, h)
    n = t.size
    for seed in (1, 2, 3):
        rng = np.random.default_rng(seed)
        x = 0.02 * np.sin(2 * np.pi * 43.0 * t[:, None] + rng.uniform(0, 6, 2)) + rng.normal(0, s, (n, 2))
        assert np.all(white_sample_std(x) > 10 * s)
        np.testing.assert_allclose(rest_white_std(x, h), s, rtol=0.25)
    quat = {"q_w": np.ones(n), "q_x": np.zeros(n), "q_y": np.zeros(n), "q_z": np.zeros(n)}
    sig = {**quat, **{f"{k}_{a}": rng.normal(0, 1.0, n) for k in ("fb", "w") for a in "xyz"}}
    given = np.arange(1.0, 7.0) * 1e-3
    meta = {"rows_index": np.full(n, -1), IMU_NOISE_AT_REST: given}
    got, step, _ = imu_sample_noise(FlightData(t, np.zeros((n, 3)), np.zeros((n, 3)), meta=meta, signals=sig), t)
    assert step == pytest.approx(h)
    np.testing.assert_array_equal(got, given)


def test_rest_white_std_refuses_bad_input():
    from casep.checks.tracking_quality import rest_white_std

    with pytest.raises(ValueError, match="rest_white_std"):
        rest_white_std(np.zeros(50), 0.01)
    with pytest.raises(ValueError, match="rest_white_std"):
        rest_white_std(np.zeros((50, 3)), 0.0)


def test_a_clock_drift_not_measured_says_why_in_the_record():
    """A pad at rest (10 Hz, 50..60 s) and 14 epochs of a 1 Hz flight (87..100 s): of the 6 windows the drift is
    measured in, none has both 10 epochs and an acceleration that spreads (a pad's has none), so the drift is NaN;
    the record says why (the windows, their epochs and spreads), where before it held ``ppm: None`` alone; no
    warning (a short or quiet flight cannot show a drift). A flight of 300 s of manoeuvres at 10 Hz has its drift
    measured, and no ``why_not``."""
    from casep.checks.tracking_quality import DRIFT_MIN_ACCEL, clock_drift_record, clock_drift_unmeasured
    from casep.io.flight import FlightData

    t = np.concatenate([np.arange(50.0, 60.05, 0.1), np.arange(87.0, 100.5, 1.0)])
    a = np.zeros((t.size, 3))
    fly = t > 80
    a[fly, 2] = 30.0 * np.sin(t[fly] / 3.0)
    f = a + np.array([0.0, 0.0, 9.81])
    dv = np.random.default_rng(3).normal(0.0, 0.05, (t.size, 3))
    fl = FlightData(t, f, dv, source="pair.csv", meta={"format": "pair"},
                    signals={f"a_{c}": a[:, i] for i, c in enumerate("xyz")})
    with warnings.catch_warnings():
        warnings.simplefilter("error", TrackingQualityWarning)  # said in the record, not warned
        record = clock_drift_record(fl, dv)
    assert record["ppm"] is None and record["std_ppm"] is None
    why = record["why_not"]
    assert why == clock_drift_unmeasured(t, a)
    assert why.startswith("only 0 of the 6 windows") and f"less than {DRIFT_MIN_ACCEL:g} m/s^2" in why
    assert "fewer than 10 epochs" in why
    # measured: no reason, no warning of it
    fl2, r2 = _tilted_pair(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TrackingQualityWarning)
        record2 = clock_drift_record(fl2, r2)
    assert record2["ppm"] is not None and "why_not" not in record2
    assert clock_drift_unmeasured(fl2.t, np.column_stack([fl2.signals[f"a_{c}"] for c in "xyz"])) == ""


def _boost_coast(rng, ppm):
    """200 s at 10 Hz: 50 s of boost (thrust 30 -> 20 m/s^2 pitching over from vertical by 40 deg), then a coast
    (gravity and a decaying drag: the acceleration barely changes); the tracking time tags late by 30 ms + `ppm`
    x (t - 100 s); a fit's residuals: that offset's dv, a constant per axis and 0.02 m/s white noise."""
    t = np.arange(0.0, 200.0, 0.1)
    th = np.radians(90.0 - 40.0 * np.minimum(t, 50.0) / 50.0)
    thrust = np.where(t < 50.0, 30.0 - 0.2 * t, 0.0)
    drag = np.where(t < 50.0, 0.0, 0.5 * np.exp(-(t - 50.0) / 60.0))
    a = np.column_stack([(thrust - drag) * np.cos(th), (thrust - drag) * np.sin(th) - 9.80665, 0.1 * np.sin(t / 30)])
    tau = 0.03 + ppm * 1e-6 * (t - 100.0)
    return t, a * tau[:, None] + np.array([0.2, -0.1, 0.05]) + rng.normal(0.0, 0.02, a.shape), a


@pytest.mark.parametrize("ppm", [0.0, 100.0])
def test_a_coasting_rockets_drift_is_measured_over_the_whole_flight(ppm):
    """Only the boost's windows see an offset (2 of 6): the windows' line cannot be drawn, and on a fit's residuals
    (order 0) the whole flight is fitted at once, the coast's steady acceleration carrying the drift's ramp. Before:
    NaN (why_not: only 2 of the 6 windows see a time offset). The raw dv (order 2) keeps the windows' rule."""
    from casep.checks.tracking_quality import _drift_windows

    t, dv, a = _boost_coast(np.random.default_rng(3), ppm)
    assert sum(k is not None for *_, k in _drift_windows(t, a)) == 2
    est, std = clock_drift(t, dv, a, order=0)
    assert abs(est - ppm) < 4 * std and std < DRIFT_MIN_PPM / 4, (est, std)
    assert math.isnan(clock_drift(t, dv, a)[0])


@pytest.mark.parametrize("frame", ["ecef", "geodetic", "launch"])
def test_a_repeated_velocity_beside_fresh_positions_is_a_repeat(tmp_path, frame):
    """A receiver that holds its velocity while its positions go on (rows 5-8), or holds its position while its
    velocity goes on (rows 12-14): the velocity is what the separation compares, so the held velocity's rows are
    repeats for the screen (main: only rows whose position and velocity both repeat, and the held velocity became
    1855 "glitches"); the held position's are not."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS
    from casep.io.files import write_table
    from casep.io.pair import VTRK_COLUMNS, repeated_rows
    from casep.io.tables import Table

    n = 20
    t = 0.1 * np.arange(n)
    pos = np.column_stack([6.4e6 + 100.0 * t, 1e3 + 3.0 * t ** 2, 2e3 + t])
    vel = np.column_stack([100.0 + 0 * t, 6.0 * t, 1.0 + 0.5 * t])
    vel[5:9] = vel[4]
    pos[12:15] = pos[11]
    cols = {"launch": ((), VTRK_COLUMNS), "ecef": (ECEF_COLUMNS[1:4], ECEF_COLUMNS[4:]),
            "geodetic": (GEODETIC_COLUMNS[1:4], GEODETIC_COLUMNS[4:])}[frame]
    table = {"t": t, **{c: pos[:, i] for i, c in enumerate(cols[0])}, **{c: vel[:, i] for i, c in enumerate(cols[1])}}
    write_table(tmp_path / "trk.csv", table)
    assert repeated_rows(Table(tmp_path / "trk.csv"), frame).tolist() == [5, 6, 7, 8]
    # the held position's rows are the file's frozen positions (judged by their own rule), a launch file has none
    frozen = repeated_rows(Table(tmp_path / "trk.csv"), frame, part="position").tolist()
    assert frozen == ([] if frame == "launch" else [12, 13, 14])


def _earth_fixed_pair(tmp_path, speed: float, frozen: slice | None = None, frame: str = "ecef", drift: float = 0.0):
    """A vehicle at 51 deg N at rest on the rotating Earth (`speed` 0) or driving north-east from `speed` m/s over the
    ground, 0.05 m/s^2 faster each second (a straight ECEF line), 40 s: telemetry at 100 Hz (its launch-inertial
    velocity, noise-free), Earth-fixed tracking at 10 Hz, exact (at rest: a receiver's static hold, velocity exactly
    0 and one position), the rows `frozen` repeating the fix before them bit for bit; read as a pair (the set-up of
    the reviewer's pad: launch time 30 s). `drift`: the telemetry's velocity error grows by this many m/s per s
    along x (an INS not yet corrected)."""
    import casep
    from casep.frames import LaunchSite, ecef_to_geodetic, ecef_to_launch
    from casep.io.files import write_table

    site = LaunchSite(51.0, 0.0, 10.0, 0.0, 30.0)
    lat = np.radians(site.lat_deg)
    ne = np.array([-np.sin(lat), 1.0, np.cos(lat)]) / np.sqrt(2.0)  # north + east at longitude 0, unit
    t_tel, t_trk = np.arange(0.0, 40.0 + 1e-9, 0.01), np.arange(0.0, 40.0 + 1e-9, 0.1)
    acc = 0.05 if speed else 0.0  # m/s^2 along the track: no two fresh velocities alike

    def truth(t):  # ECEF position and velocity
        return site.r_site + (speed * t + 0.5 * acc * t**2)[:, None] * ne, (speed + acc * t)[:, None] * ne

    v_tel = ecef_to_launch(site, t_tel, *truth(t_tel))[1] + np.outer(drift * t_tel, [1.0, 0.0, 0.0])
    r_e, v_e = truth(t_trk)
    if frozen is not None:
        r_e[frozen], v_e[frozen] = r_e[frozen.start - 1], v_e[frozen.start - 1]
    a = np.gradient(v_tel, t_tel, axis=0)
    write_table(tmp_path / "tel.csv", {"t": t_tel, **{f"f_{c}": a[:, i] for i, c in enumerate("xyz")},
                                       **{f"v_tel_{c}": v_tel[:, i] for i, c in enumerate("xyz")}})
    if frame == "ecef":
        trk = {f"r_ecef_{c}": r_e[:, i] for i, c in enumerate("xyz")} | {
            f"v_ecef_{c}": v_e[:, i] for i, c in enumerate("xyz")}
    else:
        trk = dict(zip(("lat", "lon", "h", "v_east", "v_north", "v_up"), ecef_to_geodetic(r_e, v_e)))
    write_table(tmp_path / "trk.csv", {"t": t_trk, **trk})
    return casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv", tracking_frame=frame, site=site)


def test_a_static_hold_on_the_pad_is_not_stale(tmp_path):
    """A receiver at rest on the pad holding its fix (Earth-fixed velocity exactly 0, one position, 400 repeats over
    40 s): the Earth's rotation carries pad and telemetry alike (0.02 m/s^2 in the launch-inertial frame at 51 deg,
    the 0.5 m/s of the velocity rule reached after 24 s when Earth-fixed tracking was compared with the inertial
    telemetry): every epoch kept, none left out of the time alignment either, nothing said."""
    fl = _earth_fixed_pair(tmp_path, 0.0)
    assert len(fl.meta["tracking_repeats"]) == len(fl.meta["tracking_frozen"]) == 400
    screened = screen_tracking(fl)  # no warning: the suite makes one an error
    assert screened.meta["tracking_screen"]["stale"] == [] and np.array_equal(screened.observed, fl.observed)
    assert "stale_left_out" not in fl.meta["time_alignment"]


def test_a_static_hold_inside_the_levelling_window_is_a_fix_however_the_ins_drifts(tmp_path):
    """The static hold of the pad with an INS not yet corrected (its velocity 0.03 m/s further off each second: a
    first pass's drift, 1.2 m/s in 40 s): judged against the first fix, the drift reads as motion (0.5 m/s after
    17 s); where the navigation was levelled (the vehicle at rest by its premise: rest_window_s, the --align window
    0..39 s) every repeat is a fix, so only the epochs after it are judged, from the fix at 39 s: all kept."""
    fl = _earth_fixed_pair(tmp_path, 0.0, drift=0.03)
    with pytest.warns(TrackingQualityWarning, match=r"stale tracking epochs .* t = 16\.\d\.\.40 s"):
        screen_tracking(fl)
    at_rest = dataclasses.replace(fl, meta={**fl.meta, "rest_window_s": [0.0, 39.0]})
    screened = screen_tracking(at_rest)  # no warning: the suite makes one an error
    assert screened.meta["tracking_screen"]["stale"] == [] and np.array_equal(screened.observed, fl.observed)


@pytest.mark.parametrize("frame", ["ecef", "geodetic"])
def test_a_frozen_position_is_stale_from_its_first_repeat(tmp_path, frame):
    """A receiver at 21 m/s over the ground repeating its fix of t = 20 s bit for bit (position and velocity) over
    t = 20.1 .. 23 s: the velocity barely changes (the velocity rule's 0.5 m/s is not reached in the 3 s), but the
    position is 2 m behind the vehicle at the first repeat (beyond 1 m + 0.5 m/s x 0.1 s): all 30 repeats left out
    and listed, the fix itself kept, and the time alignment judges the same epochs."""
    fl = _earth_fixed_pair(tmp_path, 20.0, frozen=slice(201, 231), frame=frame)
    stale = r"30 stale tracking epochs .* in 1 span\(s\): lines 203\.\.232 of trk\.csv, t = 20\.1\.\.23 s \(30\)"
    with pytest.warns(TrackingQualityWarning, match=stale):
        screened = screen_tracking(fl)
    assert screened.meta["tracking_screen"]["left_out_rows"] == list(range(201, 231))
    assert fl.meta["time_alignment"]["stale_left_out"] == 30


def _turning_rows(levelled: bool):
    """The turning record (:func:`_turning_record`, seed 3), nine uneven epochs and, `levelled`, a levelling window over
    the first 2 s with a Jacobian of rank 2 (as levelling alone gives): (flight, rows, levelling or None)."""
    rng = np.random.default_rng(3)
    flight = _turning_record(rng)
    rows = np.array([0.5, 1.0, 1.3, 1.7, 2.0, 3.1, 3.3, 4.0, 5.5])
    L = 0.01 * rng.normal(size=(3, 3))
    L[:, 2] = 0.0
    return flight, rows, ((0.0, 2.0), L) if levelled else None


def _turning_record(rng):
    """A turning, accelerating strapdown record (6 s at 20 Hz) with noisy body force and rate, no tracking rows."""
    from scipy.spatial.transform import Rotation

    from casep.io.flight import FlightData

    t = np.arange(0.0, 6.0, 0.05)
    n = t.size
    q = Rotation.from_rotvec(np.column_stack([0.3 * t, 0.1 * np.sin(t), 0.05 * t])).as_quat()  # x y z w
    f = np.column_stack([np.sin(t), 9.8 + 2 * t, np.cos(2 * t)])
    sig = {"q_w": q[:, 3], "q_x": q[:, 0], "q_y": q[:, 1], "q_z": q[:, 2],
           **{f"fb_{a}": f[:, i] + rng.normal(0, 0.05, n) for i, a in enumerate("xyz")},
           **{f"w_{a}": rng.normal(0, 2e-3, n) for a in "xyz"}}
    return FlightData(t, f, np.zeros((n, 3)), meta={"rows_index": np.full(n, -1)}, signals=sig)


def test_the_screen_summary_counts_the_epochs_of_every_span():
    """The summary's counts are the spans' epochs summed (the warnings' rule), its spans the flagged runs
    (:func:`casep._kernels.runs`) with a run at either end of the record."""
    from casep.checks.tracking_quality import _spans, screen_summary

    t = np.arange(12) * 0.5
    flagged = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1, 0, 1, 1], dtype=bool)
    spans = _spans(t, flagged)
    assert spans == [(0.0, 0.5, 2), (2.0, 2.0, 1), (3.0, 4.0, 3), (5.0, 5.5, 2)]
    said = screen_summary({"epochs": 12, "kept": 4, "stale": spans, "rejected": [(9.0, 9.0, 1)]}, top=2)
    assert said.startswith("the tracking screen left out 8 of its 12 epochs (stale (repeated fixes) 8 in 4 spans: "
                           "t = 0..0.5 s (2), t = 2..2 s (1) and 2 more; rejected by the physics check 1 in 1 span:")
