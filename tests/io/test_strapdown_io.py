"""Strapdown telemetry at the edge: f = C(q) fb, and the checks on q, fb, w (casep.io.strapdown)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import casep
import casep.io.strapdown as sd
from casep.io.files import write_table
from casep.io.flight import FlightDataError
from casep.io.strapdown import StrapdownWarning

RATE = 50.0


def motion(n: int = 1000):
    """A rolling, pitching body: exact attitude from a closed-form rotation (roll then a slow pitch).

    C(t) = Rz(theta(t)) Rx(phi(t)) with phi = 1.5 t, theta = 0.2 sin(0.3 t): body rate
    w = Rx(phi)^T (0, 0, theta_dot) + (phi_dot, 0, 0).
    """
    t = np.arange(n) / RATE
    phi, phi_dot = 1.5 * t, np.full(n, 1.5)
    theta, theta_dot = 0.2 * np.sin(0.3 * t), 0.06 * np.cos(0.3 * t)
    R = Rotation.from_euler("z", theta[:, None]) * Rotation.from_euler("x", phi[:, None])
    w = np.column_stack([phi_dot, np.sin(phi) * theta_dot, np.cos(phi) * theta_dot])
    fb = np.column_stack([30.0 + np.sin(t), 0.5 * np.cos(t), 0.2 * np.ones(n)])
    return t, R.as_quat(scalar_first=True), fb, w, R.as_matrix()


def write(path, t, q, fb, w, dv=None, **extra):
    cols = {"t": t, **{f"q_{a}": q[:, i] for i, a in enumerate("wxyz")},
            **{f"fb_{a}": fb[:, i] for i, a in enumerate("xyz")}, **{f"w_{a}": w[:, i] for i, a in enumerate("xyz")}}
    dv = np.zeros((t.size, 3)) if dv is None else dv
    cols.update({f"dv_{a}": dv[:, i] for i, a in enumerate("xyz")}, **extra)
    write_table(path, cols)
    return path


def test_force_is_the_rotated_body_force_and_sign_flips_are_accepted(tmp_path):
    t, q, fb, w, C = motion()
    flip = np.ones(t.size)
    flip[200:450] = -1.0  # q and -q: the same attitude
    fl = casep.read_flight(write(tmp_path / "sd.csv", t, q * flip[:, None], fb, w))
    assert fl.meta["force"] == "q, fb"
    assert np.allclose(fl.f, np.einsum("kij,kj->ki", C, fb), atol=1e-12)
    assert fl.meta["strapdown"]["sign_flips"] == 2
    qs = np.column_stack([fl.signals[f"q_{a}"] for a in "wxyz"])
    assert np.all(np.sum(qs[1:] * qs[:-1], axis=1) > 0)  # continuous after the flips are removed
    assert fl.meta["strapdown"]["rms_rate_error_rad_s"] < 1e-3 * fl.meta["strapdown"]["rms_rate_rad_s"]


def test_cli_separate_says_how_many_sign_flips_it_removed(tmp_path, capsys):
    from casep.cli import main

    t, q, fb, w, _ = motion(400)
    flip = np.ones(t.size)
    flip[100:250] = -1.0
    dv = 0.01 * np.random.default_rng(0).standard_normal((t.size, 3))
    path = write(tmp_path / "sd.csv", t, q * flip[:, None], fb, w, dv=dv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a flight of noise: only the line is asked about
        main(["separate", str(path), "--model", "strapdown12", "--noise", "white"])
    assert "attitude: 2 quaternion sign flip(s) (q and -q are the same attitude) removed" in capsys.readouterr().out


def test_non_unit_quaternion_names_columns_row_and_numbers(tmp_path):
    t, q, fb, w, _ = motion()
    q[36] *= 1.001
    q[500] *= 0.99
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, w))
    msg = str(exc.value)
    assert "columns `q_w`, `q_x`, `q_y`, `q_z`" in msg and "row 37" in msg and "1.001" in msg
    assert "2 of 1000 rows" in msg and "row 501" in msg and "0.99" in msg


def test_rates_in_degrees_per_second_are_refused(tmp_path):
    t, q, fb, w, _ = motion()
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, np.degrees(w)))
    msg = str(exc.value)
    assert "column `w_x`" in msg and "deg/s" in msg and "pi/180" in msg
    scale = float(msg.split("turns by ")[1].split(" times")[0])
    assert scale == pytest.approx(np.pi / 180, rel=1e-3)


@pytest.mark.parametrize("transform, what", [
    (lambda q: q[:, [1, 2, 3, 0]], "scalar last"),
    (lambda q: q * np.array([1.0, -1.0, -1.0, -1.0]), "navigation to body"),
])
def test_quaternions_of_another_convention_are_refused(tmp_path, transform, what):
    t, q, fb, w, _ = motion()
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(write(tmp_path / "sd.csv", t, transform(q), fb, w))
    msg = str(exc.value)
    assert f"look {what}" in msg and "columns `q_w`, `q_x`, `q_y`, `q_z`" in msg and "% off" in msg


def test_unexplained_disagreement_warns_with_its_size(tmp_path):
    t, q, fb, w, _ = motion()
    w_bad = w.copy()
    w_bad[:, 1] += 0.2  # 0.2 rad/s on the y gyro that the attitude never saw
    with pytest.warns(StrapdownWarning, match=r"disagrees with the integrated body rate .* deg/s RMS") as rec:
        casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, w_bad))
    size = float(str(rec[0].message).split(" by ")[1].split(" deg/s")[0])
    assert size == pytest.approx(np.degrees(0.2), rel=0.05)


def test_implausible_rate_peak_warns(tmp_path):
    """250 rad/s (40 rev/s) that the attitude does follow (1 kHz samples): the peak is suspicious (and a constant
    spin cannot tell a time skew of q against w: said too, tests/io/test_strapdown_skew.py)."""
    t = np.arange(200) / 1000.0
    q = Rotation.from_euler("x", 250.0 * t[:, None]).as_quat(scalar_first=True)
    w = np.column_stack([np.full(t.size, 250.0), np.zeros(t.size), np.zeros(t.size)])
    fb = np.column_stack([np.full(t.size, 30.0), np.zeros(t.size), np.zeros(t.size)])
    with pytest.warns(StrapdownWarning, match=r"peaks at 250 rad/s \(1\.432e\+04 deg/s.* row 1, .*deg/s"), \
            pytest.warns(StrapdownWarning, match="cannot tell whether they are on one time base"):
        fl = casep.read_flight(write(tmp_path / "spin.csv", t, q, fb, w))
    assert fl.meta["strapdown"]["rms_rate_error_rad_s"] < 1e-6 * 250


def test_f_columns_win_and_partial_strapdown_columns_are_named(tmp_path):
    t, q, fb, w, C = motion(200)
    f = np.einsum("kij,kj->ki", C, fb)
    fl = casep.read_flight(write(tmp_path / "both.csv", t, q, fb, w, f_x=f[:, 0], f_y=f[:, 1], f_z=f[:, 2]))
    assert fl.meta["force"] == "f" and "strapdown" in fl.meta  # the file's f, the strapdown columns checked
    with pytest.warns(StrapdownWarning, match=r"differ from C\(q\) fb .* by 1 m/s\^2 RMS") as rec:
        fl = casep.read_flight(write(tmp_path / "off.csv", t, q, fb, w, f_x=f[:, 0] + 1.0, f_y=f[:, 1], f_z=f[:, 2]))
    percent = float(str(rec[0].message).split("RMS (")[1].split(" %")[0])
    f_file = f + [1.0, 0.0, 0.0]
    assert percent == pytest.approx(100.0 / np.sqrt(np.mean(np.sum(f_file**2, axis=1))), rel=2e-3)  # of RMS |f|
    assert np.allclose(fl.f[:, 0], f[:, 0] + 1.0)  # the file's f is used
    cols = {"t": t, "q_w": q[:, 0], "q_x": q[:, 1], "q_y": q[:, 2], "q_z": q[:, 3],
            **{f"dv_{a}": np.zeros(t.size) for a in "xyz"}}
    write_table(tmp_path / "part.csv", cols)
    with pytest.raises(FlightDataError, match="column `fb_x`, header .*missing column"):
        casep.read_flight(tmp_path / "part.csv")


def _trapezoid_mismatch(t, q, w):
    """RMS |quaternion step - trapezoid of w| over the RMS trapezoid: what a second-order check would see."""
    from casep.rotations import quat_conjugate, quat_multiply, quat_to_rotvec

    rv = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:]))
    trap = 0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None]
    return float(np.sqrt(np.sum((rv - trap) ** 2) / np.sum(trap**2)))


@pytest.mark.parametrize("kind, reading, rounding", [
    ("rates", "samples of the body rate", 1e-9),
    ("increments", "each step's mean rate at its end", 1e-3),  # the first step's coning: no previous increment
])
def test_the_navigators_own_output_on_vibrating_data_passes(kind, reading, rounding):
    """casep's navigate output on 100 Hz data with vibration (a turn, 37 Hz vibration, gyro noise): no warning.

    The steps of its attitude are the coning-corrected fourth-order increments of the rates (or the
    angle increments, written as ``w = dtheta / step``); against a trapezoid of w they differ by more
    than the 5 % tolerance, so the check must compare the navigator's own increments.
    """
    from casep.frames import LaunchSite
    from casep.io.strapdown import RATE_TOL, check_strapdown
    from casep.navigation.imu import ImuData
    from casep.navigation.navigator import navigate_from

    rng = np.random.default_rng(11)
    t = np.arange(1500) / 100.0
    vib = np.sin(2 * np.pi * 37.0 * t + np.array([[0.0], [1.0], [2.0]])).T
    w = np.array([0.0, 0.02, 0.15]) + 0.4 * vib + 0.05 * rng.standard_normal((t.size, 3))
    f = np.array([0.5, 0.0, 9.8]) + 2.0 * vib[:, ::-1]
    imu = ImuData(t, w, f) if kind == "rates" else ImuData(t, w, f, kind=kind, dtheta=w * 0.01, dv=f * 0.01)
    nav = navigate_from(imu, LaunchSite(49.0, 8.0, 100.0, 0.0, 0.0), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3),
                        np.zeros(3))
    assert _trapezoid_mismatch(nav.t, nav.q, nav.w) > 2 * RATE_TOL  # a trapezoid check would warn
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, info = check_strapdown("nav.csv", nav.t, nav.q, nav.fb, nav.w)
    assert info["rate_reading"].startswith(reading)
    assert info["rms_rate_error_rad_s"] < rounding * info["rms_rate_rad_s"]  # like with like
    with pytest.raises(FlightDataError, match="look scalar last"):  # and the conventions are still caught
        check_strapdown("nav.csv", nav.t, nav.q[:, [1, 2, 3, 0]], nav.fb, nav.w)
    with pytest.raises(FlightDataError, match="looks like deg/s"):
        check_strapdown("nav.csv", nav.t, nav.q, nav.fb, np.degrees(nav.w))


def test_body_force_in_g_is_refused_naming_the_fb_columns_the_row_and_the_factor(tmp_path):
    """A dv-only strapdown file whose fb_* are in g (peak 3.2 g read as 3.2 m/s^2): before, a success with a
    warning; its accelerometers never read the g of rest or level flight, so it is refused as the velocity check of
    a file with v_tel_* refuses it."""
    t, q, fb, w, _ = motion()
    fl = casep.read_flight(write(tmp_path / "sd.csv", t, q, fb / 9.80665, w))  # about 3.2 g written in m/s^2
    from casep.checks.plausibility import check_flight

    norm = np.linalg.norm(fb, axis=1) / 9.80665
    k = int(np.argmax(norm))
    with pytest.raises(FlightDataError) as exc:
        check_flight(fl)
    msg = str(exc.value)
    assert exc.value.column == "fb_x, fb_y, fb_z" and exc.value.row == k + 1, msg
    assert f"peaks at {norm[k]:.4g} m/s^2" in msg and f"t = {t[k]:.6g} s" in msg and "multiply by 9.80665" in msg


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_specific_force_that_points_down_on_average_is_refused(tmp_path, sign):
    """A boost pitched 80 deg up at 3 g along the body's x axis: C(q) fb's time mean along the launch frame's
    vertical is about 2.95 g (g plus the vertical speed gained over the span). With fb_x negated (an accelerometer's
    sign) it is -2.95 g, which no vehicle reaches unless driven downward faster than it falls: refused, naming the
    fb columns and the numbers; the right sign reads."""
    from casep.checks.plausibility import check_flight

    n = 500
    t = np.arange(n) / RATE
    pitch = np.radians(80.0)
    q = np.tile([np.cos(pitch / 2), 0.0, 0.0, np.sin(pitch / 2)], (n, 1))  # body x turned 80 deg about z: up
    fb = np.column_stack([sign * 3.0 * 9.80665 * np.ones(n), np.zeros(n), np.zeros(n)])
    up = float(np.sin(pitch) * 3.0 * 9.80665)
    fl = casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, np.zeros((n, 3))))
    assert np.mean(fl.f[:, 1]) == pytest.approx(sign * up, rel=1e-12)
    if sign > 0:
        check_flight(fl)
        return
    with pytest.raises(FlightDataError) as exc:
        check_flight(fl)
    msg = str(exc.value)
    assert exc.value.column == "fb_x, fb_y, fb_z" and "points down on average" in msg, msg
    assert f"is {-up:.4g} m/s^2 ({-up / 9.80665:.3g} g) over t = 0 .. {t[-1]:.6g} s" in msg, msg


@pytest.mark.parametrize("what, scale", [("at rest, in m/s^2", None), ("a coast in vacuum, 0.05 g", 0.05 * 9.80665)])
def test_low_body_force_in_m_s2_is_not_refused(tmp_path, what, scale):
    """The rule's other side: an accelerometer at rest reads g (never refused), and a coast whose fb stays below 1
    m/s^2 is no g reading (read in g it would not reach 1 g): a warning, as before, not an error."""
    t, q, fb, w, _ = motion()
    fb = fb / np.linalg.norm(fb, axis=1)[:, None] * (9.80665 if scale is None else scale)
    fl = casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, w))
    from casep.checks.plausibility import check_flight

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_flight(fl)


def gain_in(msg: str) -> np.ndarray:
    """The gain ``G = [a b c; ...]`` of a refusal's message (``?`` as NaN)."""
    return np.array([[float(x.replace("?", "nan")) for x in row.split()]
                     for row in msg.split("G = [")[1].split("]")[0].split("; ")])


@pytest.mark.parametrize("wrong, what", [
    (lambda w: 3.0 * w, "times 3"),
    (lambda w: w * np.array([1.0, 1.0, -1.0]), "w_z negated"),
    (lambda w: w[:, [1, 0, 2]], "w_x and w_y swapped"),
    (lambda w: 1.1 * w, "times 1.1"),
])
def test_rates_the_attitude_did_not_integrate_are_refused(tmp_path, wrong, what):
    """The INS integrates its own measured rate, so a systematic gain between the quaternion steps and the file's
    rate is no sensor error the model could estimate: refused, naming the w columns, the gain and the worst row."""
    t, q, fb, w, _ = motion()
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, wrong(w)))
    msg = str(exc.value)
    assert "columns `w_x`, `w_y`, `w_z`" in msg and "deg/s RMS" in msg and "worst" in msg and "t = " in msg, what
    G = gain_in(msg)
    expected = {"times 3": np.eye(3) / 3, "w_z negated": np.diag([1.0, 1.0, -1.0]),
                "w_x and w_y swapped": np.eye(3)[[1, 0, 2]], "times 1.1": np.eye(3) / 1.1}[what]
    # a constant roll rate is the bias's twin: that column is undetermined ("?"); the others as made
    # (within the 1.5 % the slow pitch's coning leaves off the diagonal)
    turning = np.ptp(wrong(w), axis=0) > 1e-9
    assert np.all(np.isnan(G[:, ~turning])) and np.abs(G - expected)[:, turning].max() < 0.02


@pytest.mark.parametrize("k", [2, 3, -2])
def test_an_attitude_skewed_against_the_rate_is_named_as_a_skew(tmp_path, k):
    """q_* k samples late (or early) against w_* (20 ms at 50 Hz each) under a changing roll rate: the gain the skew
    makes looks like axes mixed (beyond GAIN_TOL; a 20 Hz roll: 14.6 % off-diagonal for one sample), but
    shifted back they agree: the refusal names the skew, its direction and milliseconds, not swapped axes. (One
    sample here stays within RATE_TOL and GAIN_TOL: read, as any disagreement that small.)"""
    t = np.arange(1000) / RATE  # motion()'s closed form with a roll rate that changes (a constant one hides a skew)
    phi, phi_dot = 1.5 * t + 2.0 * np.sin(1.3 * t), 1.5 + 2.6 * np.cos(1.3 * t)
    theta, theta_dot = 0.2 * np.sin(0.3 * t), 0.06 * np.cos(0.3 * t)
    q = (Rotation.from_euler("z", theta[:, None]) * Rotation.from_euler("x", phi[:, None])).as_quat(scalar_first=True)
    w = np.column_stack([phi_dot, np.sin(phi) * theta_dot, np.cos(phi) * theta_dot])
    fb = np.column_stack([30.0 + np.sin(t), 0.5 * np.cos(t), 0.2 * np.ones(t.size)])
    skewed = np.roll(q, k, axis=0)  # row i holds the attitude of row i - k: late by k samples
    sl = slice(abs(k), t.size - abs(k))  # the rows np.roll wrapped around left out
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(write(tmp_path / "sd.csv", t[sl], skewed[sl], fb[sl], w[sl]))
    msg = str(exc.value)
    when = "later" if k > 0 else "earlier"
    assert f"is {abs(k)} sample(s) ({20 * abs(k)} ms) {when} than the body rate" in msg, msg
    assert f"move q_* by {-20 * k:+d} ms" in msg and "columns `q_w`, `q_x`, `q_y`, `q_z`" in msg, msg


def test_a_small_compensation_gain_and_a_bias_stay_a_warning(tmp_path):
    """2 % scale and 0.1 rad/s bias on the file's rate (a calibration the INS applied before integrating):
    below GAIN_TOL, the warning with the numbers."""
    t, q, fb, w, _ = motion()
    with pytest.warns(StrapdownWarning, match=r"disagrees .* systematic part \(a gain\) is 2 %"):
        casep.read_flight(write(tmp_path / "sd.csv", t, q, fb, 1.02 * w + np.array([0.1, 0.0, 0.0])))


def gentle_noisy_flight(seconds: float = 40.0, noise: float = 0.005, seed: int = 9):
    """A gently turning vehicle at 100 Hz (peak ~2.6 deg/s): the attitude the navigator integrates from the smooth
    rate, and the rate written as instantaneous samples with white noise `noise` rad/s (a MEMS gyro's)."""
    from casep.rotations import quat_multiply, rotation_increments

    t = np.arange(int(seconds * 100) + 1) / 100.0
    w = 0.1 * np.column_stack([0.35 * np.sin(2 * np.pi * t / 25) + 0.1 * np.sin(2 * np.pi * t / 7),
                               0.25 * np.sin(2 * np.pi * t / 40) + 0.05, 0.12 * np.cos(2 * np.pi * t / 19)])
    steps = Rotation.from_rotvec(rotation_increments(t, w)).as_quat(scalar_first=True)
    q = np.empty((t.size, 4))
    q[0] = [1.0, 0.0, 0.0, 0.0]
    for k in range(1, t.size):
        q[k] = quat_multiply(q[k - 1], steps[k - 1])
    q /= np.linalg.norm(q, axis=1)[:, None]
    return t, q, w, w + noise * np.random.default_rng(seed).standard_normal(w.shape)


def test_noisy_rate_samples_of_a_gentle_flight_are_read_and_a_gain_with_that_noise_is_refused():
    """Noise in the written rate must not read as a gain (errors in variables would pull G towards 0 by ~15 % on
    the slowly turning z axis): G is the identity within its std, at most a warning; 1.1 times the rate with the
    same noise is still refused."""
    from casep.io.strapdown import check_strapdown

    t, q, w, noisy = gentle_noisy_flight()
    fb = np.tile([0.0, 0.0, 9.8], (t.size, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StrapdownWarning)  # the noise is a 20 % disagreement: a warning at most
        _, info = check_strapdown("sd.csv", t, q, fb, noisy)
    G = np.array(info["rate_gain"], dtype=float)
    assert info["systematic"] < 0.03 and np.nanmax(np.abs(G - np.eye(3))) < 0.03, G
    with pytest.raises(FlightDataError, match="not the rates the INS integrated") as exc:
        check_strapdown("sd.csv", t, q, fb, 1.1 * w + (noisy - w))
    G = gain_in(str(exc.value))
    assert np.abs(G - np.eye(3) / 1.1).max() < 0.03, G  # the quaternions turn by 1/1.1 of the rate


def kinematic_flight(seed: int = 11):
    """:func:`motion` with the velocity an INS integrates from it, ``v = v0 + int (C fb + g) dt`` (flat-Earth g,
    Simpson's rule on the 50 Hz samples, not the trapezoid of the check), plus 0.05 m/s of white noise, and
    tracking 0.1 m/s off it."""
    from scipy.integrate import cumulative_simpson

    from casep.gravity import GRAVITY_LAUNCH

    t, q, fb, w, C = motion()
    a = np.einsum("kij,kj->ki", C, fb) + GRAVITY_LAUNCH
    rng = np.random.default_rng(seed)
    v = np.array([150.0, 0.0, 0.0]) + cumulative_simpson(a, x=t, axis=0, initial=0.0)
    v_tel = v + rng.normal(scale=0.05, size=v.shape)
    return t, q, fb, w, v_tel, v_tel + 0.1 * rng.standard_normal(v.shape)


def write_tel(path, t, q, fb, w, v_tel, v_trk):
    cols = {"t": t, **{f"q_{a}": q[:, i] for i, a in enumerate("wxyz")},
            **{f"fb_{a}": fb[:, i] for i, a in enumerate("xyz")}, **{f"w_{a}": w[:, i] for i, a in enumerate("xyz")},
            **{f"v_tel_{a}": v_tel[:, i] for i, a in enumerate("xyz")},
            **{f"v_trk_{a}": v_trk[:, i] for i, a in enumerate("xyz")}}
    write_table(path, cols)
    return path


def test_the_velocity_is_checked_against_the_specific_force_naming_the_column(tmp_path):
    """d(v_tel)/dt = C(q) fb + g: the INS's own columns agree (median misfit below 0.05 m/s^2 per body axis); an
    80 mg bias in every fb column that the velocity does not hold (the largest MEMS bias) is said nothing of; 250 mg
    in fb_z is a warning with the size (2.45 m/s^2, found within the 0.05 m/s of velocity noise per 1 s window); fb
    in g and a 3 g offset in fb_y (the old checks saw neither: the peak of fb in g here is 3.1 g) are errors naming
    the columns and the size, g with its fix."""
    t, q, fb, w, v_tel, v_trk = kinematic_flight()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fl = casep.read_flight(write_tel(tmp_path / "ok.csv", t, q, fb, w, v_tel, v_trk))
    kin = fl.meta["strapdown"]["kinematics"]
    assert kin["windows"] == 19 and np.max(np.abs(kin["median_misfit_m_s2"])) < 0.05
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        casep.read_flight(write_tel(tmp_path / "mems.csv", t, q, fb + 0.08 * 9.80665, w, v_tel, v_trk))
    with pytest.warns(StrapdownWarning, match=r"median -?0\.0\d*, -?0\.0\d*, -2\.4\d m/s\^2 .*fb_z is off by "
                                              r"2\.4\d m/s\^2 \(2[45]\d mg\), beyond 160 mg in 19 of the windows"):
        casep.read_flight(write_tel(tmp_path / "b250.csv", t, q, fb + [0.0, 0.0, 0.25 * 9.80665], w, v_tel,
                                    v_trk))
    with pytest.raises(FlightDataError, match=r"columns `fb_x`, `fb_y`, `fb_z`: .*\(rows 1-951\); fb_x is off by "
                                              r"2\d\.\d m/s\^2 .*Read in g \(times 9\.80665\) fb fits.*"
                                              r"multiply by 9\.80665"):
        casep.read_flight(write_tel(tmp_path / "g.csv", t, q, fb / 9.80665, w, v_tel, v_trk))
    with pytest.raises(FlightDataError, match=r"column `fb_y`: .*median -?0\.0\d*, -29\.4, -?0\.0\d* m/s\^2 .*fb_y "
                                              r"is off by 29\.4 m/s\^2 \(3e\+03 mg\).*\(3 g: an offset of whole g in "
                                              r"fb_y\?\)"):
        casep.read_flight(write_tel(tmp_path / "y3g.csv", t, q, fb + [0.0, 3 * 9.80665, 0.0], w, v_tel, v_trk))


def test_t_in_ms_is_named_not_the_body_rate(tmp_path):
    """The closed-form rolling body (50 Hz, 20 s) with t in ms: the quaternions turn by 1/1000 of the rate
    integrated over steps of 20 "s"; main blamed w_* ("axes swapped, a sign, a factor?"). Read in ms (the
    telemetry's time-unit rule) they agree: an error naming column t, and the same file in s reads cleanly."""
    t, q, fb, w, _ = motion()
    with pytest.raises(FlightDataError, match=r"column `t`: t looks like ms, not s: median time step 20 s .* agree "
                                              r"within .*t is in ms \(divide by 1000\)") as exc:
        casep.read_flight(write(tmp_path / "ms.csv", 1e3 * t, q, fb, w))
    assert "not the rates the INS integrated" not in str(exc.value)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fl = casep.read_flight(write(tmp_path / "s.csv", t, q, fb, w))
    assert "lost_rows" not in fl.meta["strapdown"]


def test_t_in_ms_and_the_body_rate_in_deg_s_are_both_named(tmp_path):
    """The closed-form rolling body with t in ms and w_* in deg/s at once: the quaternions turn by (pi/180)/1000 of
    the rate integrated over the file's steps, which neither unit alone explains (main: "not the rates the INS
    integrated (axes swapped, a sign, a factor?)"). Read in both units they agree: one error naming t and w_*, each
    unit with its fix, and the gain against the product of the two factors."""
    t, q, fb, w, _ = motion()
    with pytest.raises(FlightDataError, match=r"columns `t`, `w_x`, `w_y`, `w_z`: t looks like ms, not s, and the body "
                                              r"rate \(w_x, w_y, w_z\) like deg/s, not rad/s") as exc:
        casep.read_flight(write(tmp_path / "msdeg.csv", 1e3 * t, q, fb, np.degrees(w)))
    said = str(exc.value)
    assert "0.001 (ms) x 0.017453 (deg/s) = 1.745e-05" in said, said
    assert "Give t in s (ms: divide by 1000) and w_x, w_y, w_z in rad/s (deg/s: multiply by pi/180)" in said, said
    assert "not the rates the INS integrated" not in said


def test_unit_factorisation_names_each_factor_of_a_gain():
    """The one rule: a gain is the product of at most one unit mistake per quantity, within 10 %: (pi/180)/1000
    (times 1.03) is ms and deg/s, pi/180 deg/s alone, g0/1000 ms and g; 1 (and 0.95) no mistake; 1e-6 and 1.2 pi/180
    none of the units offered (us is no unit of a 10 Hz record over 200 s)."""
    from casep.io.flight import time_unit_factors
    from casep.units import FORCE_UNIT_MISTAKES, G0, RATE_UNIT_MISTAKES, unit_factorisation

    time = time_unit_factors(100.0, 2e5)  # a 10 Hz record over 200 s, written in ms
    assert [u for u, _ in time] == ["ms (divide by 1000)"]
    groups = (time, RATE_UNIT_MISTAKES, FORCE_UNIT_MISTAKES)

    def named(gain):
        found = unit_factorisation(gain, groups)
        return None if found is None else [u.split(" (")[0] for u, _ in found]

    assert named(np.pi / 180 / 1000 * 1.03) == ["ms", "deg/s"]
    assert named(np.pi / 180) == ["deg/s"]
    assert named(G0 * 1e-3) == ["ms", "g"]
    assert named(1.0) == [] and named(0.95) == []
    assert named(1e-6) is None and named(np.pi / 180 * 1.2) is None


def test_t_in_ms_that_does_not_explain_the_disagreement_is_not_blamed():
    """t in ms and a body rate with two axes swapped: read in s they still disagree, so t is not named."""
    t, q, fb, w, _ = motion()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StrapdownWarning)
        try:
            sd.check_strapdown("sd.csv", 1e3 * t, q, fb, w[:, [0, 2, 1]])
        except FlightDataError as exc:
            assert "t looks like" not in str(exc)


@pytest.mark.parametrize("lost", [slice(300, 430), slice(500, 501), slice(1, 3)])
def test_lost_rows_are_named_and_left_out_of_the_comparison(lost):
    """Rows lost while the body rolls at 1.5 rad/s (130 rows: 3.9 rad turned in the gap, more than the half turn a
    quaternion step can show; one row; rows next to the first): the rate integrated over the gap is not what the
    attitude shows across it (the comparison with every step disagrees: main refused such files, blaming w_* or a
    skew between q and w). The gap is warned of with its rows, times and length,
    and the comparison without the steps across it agrees with the rate to rounding."""
    t, q, fb, w, _ = motion()
    keep = np.ones(t.size, bool)
    keep[lost] = False
    t, q, fb, w = t[keep], q[keep], fb[keep], w[keep]
    k = lost.start - 1  # 0-based row before the gap
    with pytest.warns(StrapdownWarning) as caught:
        _, info = sd.check_strapdown("sd.csv", t, q, fb, w)
    said = " | ".join(str(m.message) for m in caught)
    assert len(caught) == 1, said
    n = lost.stop - lost.start
    assert (f"column t: the telemetry lost rows: 1 gap(s) over 1.5 x the median step 0.02 s ({0.02 * (n + 1):.4g} s, "
            f"~{n} row(s) lost between rows {k + 1} and {k + 2}, t = {t[k]:.10g} .. {t[k + 1]:.10g} s, the body "
            "turning by") in said, said
    assert {k: v for k, v in info["lost_rows"][0].items() if k != "turn_rad"} == {
        "row_before": k + 1, "row_after": k + 2, "t_before": t[k], "t_after": t[k + 1], "length_s": t[k + 1] - t[k],
        "rows_lost": n}
    assert info["rms_rate_error_rad_s"] < 1e-4 * info["rms_rate_rad_s"]
    turn = info["lost_rows"][0]["turn_rad"]
    assert turn == pytest.approx(1.5 * 0.02 * (n + 1), rel=0.01)  # the roll rate 1.5 rad/s times the gap
    why = sd.lost_rows_problem(info)
    assert (why is not None) == (turn > sd.GAP_TURN_LIMIT) == (n > 100)  # 3.9 rad: S_V across it is not known
    if why is not None:
        said = (r"the telemetry lost rows while the body turned \(2\.62 s, ~130 row\(s\) lost between rows 300 and "
                r"301, t = 5\.98 \.\. 8\.6 s, the body turning by 22\d deg across it; beyond 44\.4 deg\)")
        assert re.search(said, why), why
        # a gap after the fit's last row (a clipped IMU's rows left out from its first clip) reaches no row of it
        assert sd.lost_rows_problem(info, last_used=t[k]) is None
        assert sd.lost_rows_problem(info, last_used=t[k + 1]) == why
    if n > 100:  # what the gap did to the comparison: it disagrees
        assert not sd._agrees(sd._rate_evidence(t, q, w))


def test_a_wrong_rate_with_lost_rows_is_refused_and_says_the_gap_was_left_out():
    t, q, fb, w, _ = motion()
    keep = np.r_[0:300, 400:t.size]
    said = (r"not the rates the INS integrated .*The telemetry lost rows \(2\.02 s, ~100 row\(s\) lost between rows "
            r"300 and 301.*left out of this comparison")
    with pytest.warns(StrapdownWarning, match="lost rows"), pytest.raises(FlightDataError, match=said):
        sd.check_strapdown("sd.csv", t[keep], q[keep], fb[keep], 1.1 * w[keep])
