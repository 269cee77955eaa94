"""``navigate`` and ``casep navigate``: a stationary IMU on the pad, alignment, input checks, the CLI.

A stationary IMU senses ``f_b = -C_b^T g`` (the normal gravity at the pad) and ``w_b = C_b^T omega_E``.
Navigated in the launch-inertial frame and brought back to the Earth by
:func:`casep.frames.launch_to_ecef` (the conversion of the tracking chain) it must stay at rest:
this ties the mechanisation's gravitation and the frame's Earth rotation together (a centrifugal
term left out, or the Earth rate of the wrong sign, moves it by metres per second in a minute).
With sensor noise, it stays within the noise's own error growth: velocity random walk
``sigma_a sqrt(h t)``, the levelling error of the mean ``sigma_a / sqrt(n) t``, and the tilt random
walk under gravity ``g sigma_g sqrt(h) t^1.5 / sqrt(3)``.
"""

from __future__ import annotations

import json
import math
import re
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from casep.cli import main
from casep.exceptions import AlignmentWarning, GapWarning, PlausibilityWarning
from casep.frames import LaunchSite, launch_to_ecef
from casep.gravity import normal_gravity_ecef
from casep.io.flight import FlightDataError
from casep.navigation import TELEMETRY_COLUMNS, ImuData, check_imu, navigate, read_imu
from casep.navigation.alignment import EARTH_RATE_CHI2, SIGN_CHI2_CONSISTENT, align
from casep.rotations import quat_conjugate, quat_multiply

SITE = LaunchSite(67.89, 21.1, 330.0, 30.0, 100.0)  # a northern range, launch azimuth 30 deg, t0 = 100 s
C_TB = Rotation.from_euler("ZYX", [20.0, 5.0, -3.0], degrees=True).as_matrix()  # body -> launch triad


def _heading_of_x() -> float:
    x_t = C_TB[:, 0]
    return (SITE.azimuth_deg + math.degrees(math.atan2(x_t[2], x_t[0]))) % 360.0


def _stationary(rate: float, duration: float, rng=None, sigma_a: float = 0.0, sigma_g: float = 0.0,
                t_first: float = 0.0, C_tb: np.ndarray = C_TB):
    g_t = SITE.C.T @ normal_gravity_ecef(SITE.r_site)
    t = t_first + np.arange(0.0, duration, 1.0 / rate)
    n = len(t)
    w = np.tile(C_tb.T @ SITE.earth_rate, (n, 1))
    f = np.tile(C_tb.T @ -g_t, (n, 1))
    if rng is not None:
        w = w + rng.normal(scale=sigma_g, size=w.shape)
        f = f + rng.normal(scale=sigma_a, size=f.shape)
    return t, w, f


def test_a_stationary_imu_stays_at_rest_on_the_rotating_earth():
    t, w, f = _stationary(400.0, 300.0)
    res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    assert res.success and res.alignment.method == "heading"
    r_e, v_e = launch_to_ecef(SITE, res.t, res.r, res.v)  # the tracking chain's conversion
    assert np.abs(v_e).max() < 1e-5  # 5 min: rounding and the vertical channel only
    assert np.abs(r_e - SITE.r_site).max() < 1e-3
    # in the launch-inertial frame the pad moves with the Earth: omega_E x r (176 m/s here at 67.9 deg N)
    assert np.linalg.norm(res.v[0]) == pytest.approx(7.292115e-5 * np.hypot(*SITE.r_site[:2]), rel=1e-9)
    assert res.pad_drift() < 1e-7


def test_a_noisy_stationary_imu_drifts_by_its_noise_only(rng):
    rate, T, sa, sg = 200.0, 180.0, 0.02, 2e-4  # MEMS-like white noise per sample
    t, w, f = _stationary(rate, T, rng, sa, sg)
    res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 20.0), heading_deg=_heading_of_x())
    _, v_e = res.earth_relative()
    h, tau, n = 1.0 / rate, res.t - res.t[0], int(20.0 * rate)
    sigma = np.sqrt(sa ** 2 * h * tau + (sa / math.sqrt(n) * tau) ** 2 + 9.8 ** 2 * sg ** 2 * h * tau ** 3 / 3)
    z = np.linalg.norm(v_e, axis=1)[1:] / sigma[1:]
    assert z.max() < 5.0  # 3 components: |v| / sigma beyond 5 has probability < 1e-4
    assert np.abs(v_e[-1]).max() > 0.01 * sigma[-1]  # the noise did move it (the test could fail)


def test_gyrocompassing_finds_the_heading_and_says_how_well(rng):
    t, w, f = _stationary(100.0, 120.0)
    with pytest.warns(AlignmentWarning, match=r"gyrocompassing.*known to about"):
        res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 100.0))
    assert res.alignment.heading_deg == pytest.approx(_heading_of_x(), abs=1e-6)
    np.testing.assert_allclose(res.alignment.C_tb, C_TB, atol=1e-9)
    # a navigation-grade gyro noise: the heading within its stated uncertainty
    t, w, f = _stationary(100.0, 120.0, rng, 1e-3, 2e-6)
    with pytest.warns(AlignmentWarning, match="known to about") as rec:
        res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 100.0))
    std = res.alignment.heading_std_deg
    assert 0.01 < std < 10 and f"{std:.2g} deg" in str(rec[0].message)
    assert abs((res.alignment.heading_deg - _heading_of_x() + 180) % 360 - 180) < 4 * std
    # MEMS gyros cannot find north: an error asking for --heading
    t, w, f = _stationary(100.0, 120.0, rng, 1e-3, 0.01)
    w = w + np.radians([0.3, -0.2, 0.1])  # deg/s biases
    with pytest.raises(ValueError, match="cannot find north.*give --heading"):
        navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 100.0))


def _azimuth_of(C_tb: np.ndarray, i: int) -> float:
    a_t = C_tb[:, i]  # triad: x at the site azimuth, y up, z 90 deg clockwise of x
    return (SITE.azimuth_deg + math.degrees(math.atan2(a_t[2], a_t[0]))) % 360.0


def test_gyrocompassing_reports_the_azimuth_of_a_horizontal_axis(capsys):
    # body x 1 deg from the vertical (tilted towards body y), z horizontal; triad y is up
    C = (Rotation.from_euler("y", 35.0, degrees=True) * Rotation.from_euler("z", 89.0, degrees=True)).as_matrix()
    assert abs(C[1, 0]) > math.cos(math.radians(1.01)) and abs(C[1, 2]) < 1e-12
    t, w, f = _stationary(100.0, 30.0, C_tb=C)
    with pytest.warns(AlignmentWarning, match=r"body z at azimuth") as rec:
        res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 20.0))
    a = res.alignment
    assert a.heading_axis == "z" and a.to_dict()["heading_axis"] == "z"
    assert a.heading_deg == pytest.approx(_azimuth_of(C, 2), abs=1e-6)
    assert f"{a.heading_deg:.2f} deg" in str(rec[0].message)
    assert f"body z at {a.heading_deg:.2f} deg" in res.text()
    # the axis named is reported when its azimuth means something
    with pytest.warns(AlignmentWarning, match=r"body y at azimuth"):
        res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 20.0), heading_axis="y")
    assert res.alignment.heading_axis == "y"
    assert res.alignment.heading_deg == pytest.approx(_azimuth_of(C, 1), abs=1e-6)
    # fed back as --heading with that axis, it gives the same attitude
    again = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 20.0), heading_deg=res.alignment.heading_deg,
                     heading_axis="y")
    np.testing.assert_allclose(again.alignment.C_tb, C, atol=1e-9)


def test_alignment_refuses_what_is_not_at_rest_in_m_s2():
    t, w, f = _stationary(100.0, 30.0)
    with pytest.raises(ValueError, match=r"1\.00\d* m/s\^2 over 1001 samples.*look like they are in g \(\|f\| read so "
                                         r"is 9\.8\d* m/s\^2: multiply by 9\.80665\)") as e:
        navigate(check_imu(ImuData(t, w, f / 9.80665)), SITE, (0.0, 10.0), heading_deg=10.0)
    assert "--align 0 10" in str(e.value)
    with pytest.raises(ValueError, match="at least 2 samples") as e:
        navigate(check_imu(ImuData(t, w, f)), SITE, (50.0, 60.0), heading_deg=10.0)
    assert "in ms" not in str(e.value)
    with pytest.raises(ValueError, match=r"imu.csv: column t: median time step 10 s \(0\.1 Hz\), outside the "
                                         r"5 Hz-1e\+06 Hz an IMU samples at: is t in ms \(divide by 1000\)\?"):
        check_imu(ImuData(1e3 * t, w, f, source="imu.csv"))  # t of a 100 Hz IMU in ms, even with a window that fits
    with pytest.raises(ValueError, match=r"at least 2 samples.*median time step 10 s \(0\.1 Hz\).*is t in ms"):
        align(1e3 * t, w, f, (0.0, 9.0), SITE, heading_deg=10.0)  # the window's own hint, the same rule
    t, w, f = _stationary(100.0, 30.0, C_tb=Rotation.from_euler("YZX", [20.0, 1.0, -1.0], degrees=True).as_matrix())
    with pytest.raises(ValueError, match=r"y axis is 1\.\d+ deg from the vertical"):  # its azimuth fixes nothing
        navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 10.0), heading_deg=10.0, heading_axis="y")


def test_a_pad_accelerometer_bias_is_told_from_units_and_motion():
    """The mean pad |f| against the normal gravity: a 65 mg bias along the vertical (a consumer MEMS; the old rule,
    5 % of g, refused it) is a warning giving its size in mg and the levelling goes on, the pad check allowing the
    speed it drives, b T; 40 mg (within 5 % of g) and 20 mg across the vertical (|f| changes by 0.2 mg): nothing.
    150 mg is beyond the 80 mg default: an error giving the size and the option, which accepts it when raised. f in
    ft/s^2: an error naming the unit and its fix; a pad that moves by 0.3 g: an error saying it moved."""
    t, w, f = _stationary(100.0, 30.0, np.random.default_rng(5), sigma_a=1e-3, sigma_g=1e-5)
    up = f[0] / np.linalg.norm(f[0])
    across = np.cross(up, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = navigate(check_imu(ImuData(t, w, f + 0.065 * 9.80665 * up)), SITE, (0.0, 10.0), heading_deg=10.0)
    said = [str(c.message) for c in caught if c.category is AlignmentWarning]
    assert [m for m in said if re.search(r"\+65(\.\d)? mg\): an accelerometer bias of about 65(\.\d)? mg along the "
                                        r"vertical, within the 80 mg accelerometer bias accepted \(--accel-bias-"
                                        r"tolerance MG, the default, the largest of consumer MEMS\)", m)] == said, said
    assert res.alignment.g_pad == pytest.approx(9.8238, abs=1e-3) and res.pad_drift() < 0.065 * 9.80665 * 10.0 * 1.01
    assert _alignment_warnings(check_imu(ImuData(t, w, f + 0.020 * 9.80665 * across))) == []
    assert _alignment_warnings(check_imu(ImuData(t, w, f + 0.040 * 9.80665 * up)), check_pad=False) == []
    biased = check_imu(ImuData(t, w, f + 0.150 * 9.80665 * up))
    with pytest.raises(ValueError, match=r"\+150 mg\): not at rest on the pad in m/s\^2: steady within [0-9.]+ m/s\^2, "
                                         r"150 mg from gravity, beyond the 80 mg accelerometer bias accepted "
                                         r"\(--accel-bias-tolerance MG, the default, the largest of consumer MEMS\)"):
        navigate(biased, SITE, (0.0, 10.0), heading_deg=10.0)
    with pytest.warns(AlignmentWarning) as given:  # the user's tolerance said as the user's, not as consumer MEMS'
        navigate(biased, SITE, (0.0, 10.0), heading_deg=10.0, accel_bias_tolerance=0.2 * 9.80665)
    said = [str(c.message) for c in given if "bias of about 150 mg" in str(c.message)]
    assert len(said) == 1 and ("along the vertical, within the 200 mg accelerometer bias accepted "
                               "(--accel-bias-tolerance MG, given; the default 80 mg is the largest of consumer "
                               "MEMS)") in said[0], said
    with pytest.raises(ValueError, match=r"look like they are in ft/s\^2 \(\|f\| read so is 9\.8\d* m/s\^2: "
                                         r"multiply by 0\.3048\)"):
        navigate(check_imu(ImuData(t, w, f / 0.3048)), SITE, (0.0, 10.0), heading_deg=10.0)
    moving = f.copy()
    moving[500:700] += 0.3 * 9.80665 * up * 5.0  # 1.5 g for 2 s of the 10 s window: the mean is 0.3 g off
    with pytest.raises(ValueError, match=r"departs from its mean by up to [0-9.]+ m/s\^2 in the window: the vehicle "
                                         r"moved"):
        navigate(check_imu(ImuData(t, w, moving)), SITE, (0.0, 10.0), heading_deg=10.0)


def test_lost_samples_are_integrated_across_and_counted():
    t, w, f = _stationary(200.0, 60.0)
    keep = np.ones(len(t), bool)
    keep[3000:3015] = False  # 75 ms lost
    keep[6000:6003] = False
    with pytest.warns(GapWarning, match=r"2 gaps in t \(about 18 samples lost.*longest 0\.08 s"):
        imu = check_imu(ImuData(t[keep], w[keep], f[keep]))
    res = navigate(imu, SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    assert res.gaps == 2 and np.abs(res.earth_relative()[1]).max() < 1e-6


def test_a_gap_warning_gives_the_velocity_bound_s_parts_in_their_units():
    """The gap's velocity bound is the motion term plus the scatter's: the warning gives the scatter's part in m/s
    (the bound less the motion term) beside the samples' scatter in m/s^2, not an acceleration as a velocity."""
    t, w, f = _stationary(100.0, 30.0, np.random.default_rng(3), sigma_a=2e-3, sigma_g=1e-4)
    keep = (t < 20.0) | (t > 20.5)
    with pytest.warns(GapWarning) as rec:
        check_imu(ImuData(t[keep], w[keep], f[keep]))
    msg = str(rec[0].message)
    total, motion, rest, scatter = (float(re.search(p, msg).group(1)) for p in (
        r"known to about ([0-9.e+-]+) m/s only", r"s: ([0-9.e+-]+) m/s; the rest",
        r"the rest, ([0-9.e+-]+) m/s, from", r"about the bridge, ([0-9.e+-]+) m/s\^2 per sample"))
    assert rest == pytest.approx(total - motion, rel=0.02, abs=1e-3)
    assert scatter == pytest.approx(2e-3, rel=0.2)  # the noise the pad was given, per sample


def test_an_alignment_window_beyond_the_record_is_said():
    """``--align 0 9`` on a record of 2.5 s levels over what the record holds: said with the record's span and the
    window's; a window a sample beyond the record's end (round numbers) is not."""
    t, w, f = _stationary(800.0, 2.5)
    imu = check_imu(ImuData(t, w, f))
    with pytest.warns(AlignmentWarning, match=r"--align 0 9: .* holds 0 .. 2\.49\d* s, so the window's samples span "
                                              r"2\.49\d* s of the 9 s asked"):
        navigate(imu, SITE, (0.0, 9.0), heading_deg=_heading_of_x())
    with warnings.catch_warnings():
        warnings.simplefilter("error", AlignmentWarning)
        navigate(imu, SITE, (0.0, 2.5), heading_deg=_heading_of_x())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_long_gap_in_a_noisy_record_stays_within_what_the_warning_states(seed):
    """A pad IMU (gyro noise 1e-4 rad/s, accelerometer 2e-3 m/s^2, 100 Hz) loses 1 s: against the same record
    without the gap, the velocity just after it differs by less than the velocity the warning states, the
    attitude by less than its attitude, and at the end by less than both grown by the rate it states; the
    bounds are those of the noise, not absurdly wide. The cubic through the four nearest noisy samples
    gave 3e-3 rad and m/s over a minute."""
    t, w, f = _stationary(100.0, 40.0, np.random.default_rng(seed), sigma_a=2e-3, sigma_g=1e-4)
    keep = (t < 20.0) | (t > 21.0)
    full = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    with pytest.warns(GapWarning, match=r"1 gap in t \(about 10\d samples lost") as rec:
        imu = check_imu(ImuData(t[keep], w[keep], f[keep]))
    msg = str(rec[0].message)
    dv_bound, dth_bound, grow = (float(re.search(p, msg).group(1)) for p in (
        r"known to about ([0-9.e+-]+) m/s", r"to about ([0-9.e+-]+) rad", r"up to ([0-9.e+-]+) m/s per s"))
    res = navigate(imu, SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    i, j = np.searchsorted(full.t, res.t[2001]), 2001  # the first sample after the gap
    assert full.t[i] == res.t[j]
    assert np.linalg.norm(res.v[j] - full.v[i]) < dv_bound
    dq = quat_multiply(quat_conjugate(full.q[i]), res.q[j])
    assert 2.0 * np.linalg.norm(dq[1:]) < dth_bound
    assert np.linalg.norm(res.v[-1] - full.v[-1]) < dv_bound + grow * (res.t[-1] - res.t[j])
    assert dv_bound < 0.01 and dth_bound < 3e-4  # the noise's size (1e-4 rad/s over 1 s), not far beyond it


def test_rates_in_deg_s_are_caught():
    t = np.arange(0.0, 10.0, 0.01)
    w = np.zeros((len(t), 3))
    f = np.tile([0.0, 0.0, 9.8], (len(t), 1))
    w[500:, 0] = math.degrees(6.0)  # a 6 rad/s roll given in deg/s
    with pytest.raises(ValueError, match=r"w_\*, row 501: body rate 343.8 rad/s .*look like deg/s"):
        check_imu(ImuData(t, w, f))
    w[500:, 0] = 40.0
    with pytest.warns(PlausibilityWarning, match="2292 deg/s"):
        check_imu(ImuData(t, w, f))


def test_a_pad_record_in_deg_s_is_an_error_naming_columns_ratio_and_fix(tmp_path, capsys):
    # at rest the gyros read the Earth rate: in deg/s declared rad/s, 57.2958 times it, in its direction
    t, w, f = _stationary(100.0, 20.0)
    for increments, cols in ((False, "w_x, w_y, w_z"), (True, "dth_x, dth_y, dth_z")):
        _write_imu(tmp_path / "imu.csv", t, np.degrees(w), f, increments)
        with pytest.raises(ValueError) as e:
            navigate(read_imu(tmp_path / "imu.csv"), SITE, (0.0, 10.0))
        assert f"imu.csv, columns {cols}" in str(e.value)
        assert re.search(r"57\.\d\d times the Earth rate.*in deg/s; give them in rad/s", str(e.value))
    # the command: exit 2, the message on stderr, nothing written
    _write_imu(tmp_path / "imu.csv", t, np.degrees(w), f)
    site = [str(v) for v in (SITE.lat_deg, SITE.lon_deg, SITE.h_m, SITE.azimuth_deg)]
    out = tmp_path / "tel.csv"
    assert main(["navigate", str(tmp_path / "imu.csv"), "--launch-site", *site, "--launch-time", "100", "--align",
                 "0", "10", "--heading", "10", "--heading-axis", "y", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "columns w_x, w_y, w_z" in err and "57.30 times the Earth rate" in err and "rad/s" in err
    assert not out.exists()
    # the same rate in rad/s: the right solution
    _write_imu(tmp_path / "imu.csv", t, w, f)
    res = navigate(read_imu(tmp_path / "imu.csv"), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    assert res.pad_drift() < 1e-6


def test_a_pad_rate_near_57_times_the_earth_rate_is_judged_by_its_direction():
    t, _, f = _stationary(100.0, 20.0)
    up_t = -(SITE.C.T @ normal_gravity_ecef(SITE.r_site))
    up_t /= np.linalg.norm(up_t)
    north_t = SITE.earth_rate - (SITE.earth_rate @ up_t) * up_t
    # 57.3 times the Earth rate in magnitude, all of it horizontal: not the Earth rate in deg/s (58 % off it in body
    # axes), and a size a consumer MEMS bias has (860 deg/h): no deg/s finding; the pad check still sees the tilt
    w_t = math.degrees(1.0) * 7.292115e-5 * north_t / np.linalg.norm(north_t)
    w = np.tile(C_TB.T @ w_t, (len(t), 1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    assert not any("deg/s" in str(c.message) for c in caught), [str(c.message) for c in caught]
    assert any(c.category is AlignmentWarning and "speed reaches" in str(c.message) for c in caught)
    # 46 times the Earth rate in its direction: divided by 57.3, 19.7 % short of it, within the 20 % match of the
    # heading given: an error; gyrocompassed (the 5 % of the vertical and horizontal parts), 20 % off the Earth rate
    # is where a MEMS bias lands with a chance of 1.3 % at 68 deg latitude (above DEG_S_WARN_CHANCE): no deg/s
    # warning, and the gyrocompass refuses the record
    _, w, _ = _stationary(100.0, 20.0)
    with pytest.raises(ValueError, match=r"46\.00 times the Earth rate.*within 19\.7 % of the Earth rate"):
        navigate(check_imu(ImuData(t, 46.0 * w, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    with warnings.catch_warnings(record=True) as caught, pytest.raises(ValueError, match="cannot find north"):
        warnings.simplefilter("always")
        navigate(check_imu(ImuData(t, 46.0 * w, f)), SITE, (0.0, 10.0))
    assert not any("deg/s" in str(c.message) for c in caught), [str(c.message) for c in caught]


def test_a_consumer_mems_gyro_bias_is_no_deg_s_finding_and_deg_s_is_still_caught():
    """Gyros in rad/s with consumer MEMS biases (below casep.units.MEMS_GYRO_BIAS), the heading given: 400 deg/h in
    4 seeded directions (a pad rate 20 to 36 times the Earth rate, divided by 57.3 at least 37 % off the Earth rate
    in body axes, where a MEMS bias lands with a chance of 1 % or more), and 860 deg/h across the Earth rate (57 times
    it, the size the old rule took for deg/s; divided by 57.3, 141 % off it): no deg/s finding. The same record
    without the bias in deg/s: the error; with a 1 deg/h bias gyrocompassed, the warning
    (test_a_pad_record_in_deg_s_with_a_tactical_gyro_bias_is_an_error_with_the_heading_given)."""
    from casep.units import DEG_PER_HOUR, MEMS_GYRO_BIAS

    assert 860.0 * DEG_PER_HOUR < MEMS_GYRO_BIAS
    rng = np.random.default_rng(11)
    t, w, f = _stationary(100.0, 20.0, rng, 1e-3, 1e-5)
    earth = w.mean(axis=0) / np.linalg.norm(w.mean(axis=0))
    across = [np.cross(earth, a) for a in np.eye(3)]
    biases = [400.0 * e / np.linalg.norm(e) for e in rng.normal(size=(4, 3))] + \
        [860.0 * a / np.linalg.norm(a) for a in across if np.linalg.norm(a) > 0.3]
    assert len(biases) >= 6
    for b in biases:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            navigate(check_imu(ImuData(t, w + b * DEG_PER_HOUR, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x(),
                     check_pad=False)
        assert not any("deg/s" in str(c.message) for c in caught), [str(c.message) for c in caught]
    with pytest.raises(ValueError, match=r"the rates are in deg/s; give them in rad/s"):
        navigate(check_imu(ImuData(t, np.degrees(w), f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())


def test_a_pad_record_in_deg_s_with_a_tactical_gyro_bias_is_an_error_with_the_heading_given():
    # a 1 deg/h bias along the vertical is 6.7 % of the Earth rate: beyond the gyrocompassed 5 % (plus 3 std of
    # the mean's noise, 1e-6 rad/s per sample: 0.2 %), within the 20 % of the three-axis match the heading allows
    rng = np.random.default_rng(3)
    t, w, f = _stationary(100.0, 20.0, rng, 1e-3, 1e-6)
    up_b = f[0] / np.linalg.norm(f[0])
    bias = np.radians(1.0 / 3600.0) * up_b
    w_deg = np.degrees(w + bias)
    with pytest.raises(ValueError, match=r"the Earth rate the alignment puts in body axes.*within 6\.\d % of the "
                                         r"Earth rate; allowed 20\.\d %.*the rates are in deg/s"):
        navigate(check_imu(ImuData(t, w_deg, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    # gyrocompassed, only the vertical and horizontal parts: 6.7 % is beyond 5.2 %, a warning with the numbers
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            navigate(check_imu(ImuData(t, w_deg, f)), SITE, (0.0, 10.0))
        except ValueError as e:
            assert "in deg/s" not in str(e)
    assert any(re.search(r"deg/s given as rad/s \(57\.3 times; divided by 57\.2958 it differs from the Earth rate by "
                         r"7 % of it", str(c.message)) for c in caught)
    # the same gyros in rad/s: no deg/s finding
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        navigate(check_imu(ImuData(t, w + bias, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    assert not any("deg/s" in str(c.message) for c in caught)


def test_a_mems_bias_read_in_rad_s_near_57_times_the_earth_rate_is_no_error():
    # a MEMS gyro in rad/s biased by 0.17 deg/s (41 times the Earth rate, the real car drive's) in the direction
    # that comes closest to the Earth rate in deg/s: 28 % of the Earth rate off it, a warning at most
    t, w, f = _stationary(100.0, 20.0)
    e = w[0] / np.linalg.norm(w[0])
    w_mems = w + np.radians(0.17) * e
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        navigate(check_imu(ImuData(t, w_mems, f)), SITE, (0.0, 10.0), heading_deg=_heading_of_x())
    assert not any("the rates are in deg/s" in str(c.message) for c in caught)


def test_a_noisy_pad_in_deg_s_is_a_warning_giving_the_chance_of_a_mems_bias_there():
    # noise 1e-4 rad/s per sample, read 57.3 times larger: the match widens to 45 % of the Earth rate, where a
    # MEMS bias read in rad/s lands with a chance of 1.7 %: the pad cannot tell, a warning naming the chance
    rng = np.random.default_rng(4)
    t, w, f = _stationary(50.0, 10.0, rng, 1e-2, 1e-4)
    with pytest.warns(PlausibilityWarning, match=r"rates in deg/s\? The noise leaves the pad unable to tell.*"
                                                 r"chance of \d\.?\d* %.*Both readings: in rad/s, a gyro bias of "
                                                 r"[\d.]+ deg/s .*; in deg/s, the Earth rate within \d+ % of it"):
        navigate(check_imu(ImuData(t, np.degrees(w), f)), SITE, (0.0, 9.0), heading_deg=_heading_of_x())


def test_a_mems_bias_on_a_vibrating_pad_gets_no_deg_s_hint():
    # the real car drive's pad: a MEMS gyro in rad/s biased by 0.187 deg/s (45.6 times the Earth rate here), its
    # horizontal part turned from the Earth rate's by 90 deg about the vertical (the sizes kept), on a pad whose noise
    # of the mean (0.017 rad/s per sample) widens the deg/s match to 108 % of the Earth rate: a MEMS bias read in
    # rad/s lands in it with a chance of 39 %, beyond DEG_S_HINT_CHANCE, so no "rates in deg/s?" (it was said)
    from casep.navigation.alignment import DEG_S_HINT_CHANCE

    t, w, f = _stationary(50.0, 10.0, np.random.default_rng(4), 1e-2, 0.017)
    up_b = -f[0] / np.linalg.norm(f[0])
    e = w[0] / np.linalg.norm(w[0])
    d = (e @ up_b) * up_b + np.cross(up_b, e - (e @ up_b) * up_b)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        navigate(check_imu(ImuData(t, w + np.radians(0.187) * d / np.linalg.norm(d), f)), SITE, (0.0, 9.0),
                 heading_deg=_heading_of_x())
    assert not any("deg/s" in str(c.message) for c in caught), [str(c.message) for c in caught]
    assert DEG_S_HINT_CHANCE < 0.39


def test_a_flight_in_deg_s_the_earth_rate_cannot_tell_is_refused_by_the_pad_check(tmp_path, capsys):
    """A MEMS rail launch (examples/make_example_mems.py's errors, its roll slowed to 0.3 rad/s) with its rates in
    deg/s: 17 "rad/s" in flight, below every peak rule, and a pad rate of 2375 times the Earth rate, too far from it
    for the Earth-rate match to tell deg/s from a MEMS bias. As read, 0.17 rad/s is beyond the bias of any gyro that
    navigates and the pad solution drifts beyond what the sensors allow: navigate exits 2 naming the columns, the
    window's rows and the numbers, and writes nothing (so does ``separate --imu``, by the same rule); in rad/s it
    navigates, and the separation with the tracking
    (the default model, strapdown42_extended) succeeds."""
    import casep
    from casep.io.files import write_table
    from casep.model.strapdown import body_errors
    from casep.simulation.noise import white_noise
    from casep.simulation.strapdown import rail_launch

    site = LaunchSite(67.89, 21.10, 330.0, 30.0, 10.0)
    t = np.round(np.arange(0.0, 40.0, 0.05), 10)
    w, f = rail_launch(site, t, elevation_deg=80.0, boost_g=4.0, burn_s=20.0, coast_g=-0.2, roll=(0.3, 5.0))
    nav = navigate(check_imu(ImuData(t, w, f)), site, (0.0, 9.0), heading_deg=30.0)
    model = casep.load_model("strapdown15_axial")
    truth = dict(ba_x=20.0, ba_y=-15.0, ba_z=10.0, sa_x=5000.0, ma_yx=1500.0, ma_zx=-1000.0, bg_x=200.0,
                 bg_y=-150.0, bg_z=250.0, sg_x=3000.0, mg_yx=1000.0, mg_zx=-800.0, gg_xx=200.0, gg_yx=-100.0,
                 gg_zx=150.0)
    df, dw = body_errors(model, nav.q, f, w, t - t[0], np.array([truth[n] for n in model.names]))
    k = slice(None, None, 4)
    v = nav.v[k] + white_noise(t[k].size, 0.02, np.random.default_rng(1))
    write_table(tmp_path / "trk.csv", {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    setup = ["--launch-site", "67.89", "21.10", "330", "30", "--launch-time", "10", "--align", "0", "9", "--heading",
             "30"]
    for unit, scale in (("deg", math.degrees(1.0)), ("rad", 1.0)):
        write_table(tmp_path / f"imu_{unit}.csv", {"t": t, **{f"w_{a}": scale * (w + dw)[:, i] for i, a in
                                                             enumerate("xyz")},
                                                   **{f"fb_{a}": (f + df)[:, i] for i, a in enumerate("xyz")}})
    out = tmp_path / "tel_deg.csv"
    assert main(["navigate", str(tmp_path / "imu_deg.csv"), *setup, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(r"imu_deg\.csv: columns w_x, w_y, w_z, rows 1-181: mean body rate 0\.17\d* rad/s .* the "
                     r"navigated speed reaches [0-9.]+ m/s in it, above the [0-9.e+-]+ m/s its sensors allow.*a gyro "
                     r"bias of 9\.9\d deg/s, or rates in deg/s \(divided by 57\.2958 it is 0\.00\d+ rad/s.*beyond the "
                     r"0\.05 rad/s bias of any gyro that navigates", err), err
    assert not out.exists()
    # the separation from the raw record navigates it the same way and refuses it by the same rule, before any pass
    assert main(["separate", "--imu", str(tmp_path / "imu_deg.csv"), "--tracking", str(tmp_path / "trk.csv"),
                 *setup, "--json", str(tmp_path / "sep_deg.json")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"imu_deg\.csv: columns w_x, w_y, w_z, rows 1-181: mean body rate 0\.17\d* rad/s .*or rates in "
                     r"deg/s", err), err
    assert not (tmp_path / "sep_deg.json").exists()
    assert main(["navigate", str(tmp_path / "imu_rad.csv"), *setup, "-o", str(tmp_path / "tel_rad.csv")]) == 0
    assert main(["separate", str(tmp_path / "tel_rad.csv"), "--tracking", str(tmp_path / "trk.csv")]) == 0


def _biased_pad(bias: np.ndarray, turn: float = 0.0, scale: float = 1.0):
    """20 s at rest at SITE, 100 Hz, with a constant gyro bias `bias` (rad/s, body axes), then 1 s turning about
    body x at `turn` rad/s; the rates times `scale` (57.2958: deg/s)."""
    t, w, f = _stationary(100.0, 21.0)
    w = w + bias
    w[t >= 20.0, 0] += turn
    return check_imu(ImuData(t, scale * w, f))


def test_a_large_gyro_bias_is_navigated_within_its_tolerance_and_said_how_fast_the_attitude_drifts(tmp_path, capsys):
    """A gyro bias of 0.084 rad/s (the MPU-9150 #4 z gyro's 4.8 deg/s of mikoff/imu-calib's table), across the
    vertical, on a pad at rest, rates in rad/s: a pad rate beyond the 0.05 rad/s of any gyro that navigates,
    whose deg/s reading (0.084 deg/s) no Earth-rate match can tell from a bias, and a peak rate within 2000 deg/s.
    By default refused, saying both readings and the option; with --gyro-bias-tolerance 5 navigated, with a warning
    whose attitude drift is the bias (4.81 deg/s) and whose velocity error after 1 s is ``g b_h / 2``; both checked
    against the navigation itself (the angle turned in 1 s, the speed relative to the Earth)."""
    from casep.io.files import write_table

    _, _, f = _stationary(1.0, 1.0)
    across = np.cross(f[0], [1.0, 0.0, 0.0])
    b = 0.084 * across / np.linalg.norm(across)  # across the vertical: it tilts the levelling at its full size
    imu = _biased_pad(b)
    with pytest.raises(ValueError, match=r"a gyro bias of 4\.8\d deg/s, or rates in deg/s \(divided by 57\.2958 it is "
                                         r"0\.00147 rad/s, 20\.1 times the Earth rate.*the pad cannot tell.*beyond the "
                                         r"0\.05 rad/s bias of any gyro that navigates.*--gyro-bias-tolerance 4\.9 "):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            navigate(imu, SITE, (0.0, 5.0), heading_deg=_heading_of_x())
    with warnings.catch_warnings(), pytest.warns(PlausibilityWarning, match=r"a bias within the --gyro-bias-tolerance "
                                                 r"5 deg/s given: the navigation's attitude drifts by 4\.8\d deg/s, "
                                                 r"4\.8\d deg/s of it tilting the vertical"):
        warnings.simplefilter("ignore", AlignmentWarning)  # the pad check's: the speed the bias drives, said too
        res = navigate(imu, SITE, (0.0, 5.0), heading_deg=_heading_of_x(), gyro_bias_tolerance=math.radians(5.0))
    k = int(np.searchsorted(res.t, 1.0))
    turned = np.linalg.norm(Rotation.from_quat(quat_multiply(quat_conjugate(res.q[0]), res.q[k])[[1, 2, 3, 0]])
                            .as_rotvec())
    assert turned == pytest.approx(0.084, rel=2e-3)  # the bias over 1 s, the Earth rate 1e-3 of it
    up = res.alignment.f_mean / np.linalg.norm(res.alignment.f_mean)
    b_h = float(np.linalg.norm(b - (b @ up) * up))
    _, v_e = launch_to_ecef(SITE, res.t, res.r, res.v)
    assert np.linalg.norm(v_e[k]) == pytest.approx(9.82 * b_h / 2.0, rel=0.02)  # small angle: 4.8 deg, 0.1 %
    # the CLI's option, in deg/s, reaches the same rule
    write_table(tmp_path / "imu.csv", {"t": imu.t, **{f"w_{a}": imu.w[:, i] for i, a in enumerate("xyz")},
                                       **{f"fb_{a}": imu.f[:, i] for i, a in enumerate("xyz")}})
    h = f"{_heading_of_x():.6f}"
    setup = [str(tmp_path / "imu.csv"), "--launch-site", "67.89", "21.1", "330", "30", "--launch-time", "100",
             "--align", "0", "5", "--heading", h, "-o", str(tmp_path / "tel.csv")]
    assert main(["navigate", *setup]) == 2
    assert "--gyro-bias-tolerance 4.9 (deg/s) navigates with it" in capsys.readouterr().err
    assert main(["navigate", *setup, "--gyro-bias-tolerance", "5"]) == 0
    assert re.search(r"attitude drifts by 4\.8\d deg/s", capsys.readouterr().err)


def test_rates_in_deg_s_whose_peak_no_gyro_reads_are_refused_whatever_the_gyro_bias_tolerance():
    """A MEMS gyro (bias 0.003 rad/s, 620 deg/h) in deg/s turning at 2 rad/s: a pad rate of 0.17 "rad/s" as read, too
    far from the Earth rate for its match, but a peak of 115 "rad/s", beyond the 2000 deg/s of common gyros: deg/s,
    refused even with a 20 deg/s tolerance; the same record in rad/s navigates with no pad-rate warning."""
    b = np.array([0.002, -0.0015, 0.0015])
    deg = math.degrees(1.0)
    with pytest.raises(ValueError, match=r"the rates are in deg/s: the pad rate is beyond the 0\.05 rad/s bias of any "
                                         r"gyro that navigates and the record's peak rate 11\d\.\d rad/s"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            navigate(_biased_pad(b, 2.0, deg), SITE, (0.0, 5.0), heading_deg=_heading_of_x(),
                     gyro_bias_tolerance=math.radians(20.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        warnings.simplefilter("ignore", AlignmentWarning)
        assert navigate(_biased_pad(b, 2.0), SITE, (0.0, 5.0), heading_deg=_heading_of_x()).success


def _write_imu(path, t, w, f, increments=False):
    if increments:
        h = np.diff(t, prepend=t[0] - (t[1] - t[0]))[:, None]
        cols = {"t": t, **{f"dth_{a}": w[:, i] * h[:, 0] for i, a in enumerate("xyz")},
                **{f"dvb_{a}": f[:, i] * h[:, 0] for i, a in enumerate("xyz")}}
    else:
        cols = {"t": t, **{f"w_{a}": w[:, i] for i, a in enumerate("xyz")},
                **{f"fb_{a}": f[:, i] for i, a in enumerate("xyz")}}
    with open(path, "w") as fh:
        fh.write(",".join(cols) + "\n")
        np.savetxt(fh, np.column_stack(list(cols.values())), delimiter=",", fmt="%.17g")


def test_files_of_rates_and_of_increments_give_the_same_pad_solution(tmp_path):
    t, w, f = _stationary(100.0, 60.0, t_first=40.0)
    _write_imu(tmp_path / "r.csv", t, w, f)
    _write_imu(tmp_path / "d.csv", t, w, f, increments=True)
    a, b = read_imu(tmp_path / "r.csv"), read_imu(tmp_path / "d.csv")
    assert (a.kind, b.kind) == ("rates", "increments")
    ra = navigate(a, SITE, (45.0, 55.0), heading_deg=_heading_of_x())
    rb = navigate(b, SITE, (45.0, 55.0), heading_deg=_heading_of_x())
    assert ra.t[0] == pytest.approx(45.0)
    np.testing.assert_allclose(ra.v, rb.v, atol=1e-7)
    np.testing.assert_allclose(ra.q, rb.q, atol=1e-10)


def test_bad_imu_files_name_file_column_and_row(tmp_path):
    t, w, f = _stationary(100.0, 5.0)
    _write_imu(tmp_path / "imu.csv", t, w, f)
    text = (tmp_path / "imu.csv").read_text().splitlines()
    (tmp_path / "nocol.csv").write_text("\n".join([text[0].replace("fb_z", "fz")] + text[1:]))
    with pytest.raises(FlightDataError, match=r"nocol.csv.*fb_z.*missing column"):
        read_imu(tmp_path / "nocol.csv")
    (tmp_path / "back.csv").write_text("\n".join(text[:10] + [text[5]] + text[10:]))
    with pytest.raises(FlightDataError, match=r"back.csv.*column `t`, row 10.*does not increase"):
        read_imu(tmp_path / "back.csv")


def test_the_command_writes_the_strapdown_telemetry(tmp_path, capsys):
    t, w, f = _stationary(100.0, 30.0)
    _write_imu(tmp_path / "imu.csv", t, w, f)
    site = [str(v) for v in (SITE.lat_deg, SITE.lon_deg, SITE.h_m, SITE.azimuth_deg)]
    out = tmp_path / "tel.csv"
    args = ["navigate", str(tmp_path / "imu.csv"), "--launch-site", *site, "--launch-time", "100", "--align", "0",
            "10", "--heading", f"{_heading_of_x():.12f}", "-o", str(out), "--json", str(tmp_path / "nav.json")]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "pad check" in printed and "telemetry written to" in printed
    summary = json.loads((tmp_path / "nav.json").read_text())  # plain, finite data (the result protocol)
    assert summary["success"] and summary["alignment"]["method"] == "heading" and summary["pad_drift_m_s"] < 1e-6
    header = next(line for line in out.read_text().splitlines() if not line.startswith("#"))
    assert tuple(header.split(",")) == TELEMETRY_COLUMNS
    data = np.loadtxt(out, delimiter=",", comments="#", skiprows=1 + sum(1 for line in out.read_text().splitlines()
                                                                         if line.startswith("#")))
    q = data[:, 1:5]
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    _, v_e = launch_to_ecef(SITE, data[:, 0], data[:, 14:17], data[:, 11:14])
    assert np.abs(v_e).max() < 1e-6
    # bad input: exit 2, nothing written
    bad = tmp_path / "tel2.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["navigate", str(tmp_path / "imu.csv"), "--launch-site", *site, "--launch-time", "100",
                     "--align", "50", "60", "-o", str(bad)]) == 2
    assert not bad.exists()


def test_a_gravity_iteration_that_does_not_converge_is_a_failed_result():
    from casep.navigation.strapdown import MAX_PASSES, propagate_translation

    t = np.arange(0.0, 3.0, 0.01)
    _, _, passes = propagate_translation(t, np.zeros((len(t) - 1, 3)), np.zeros(3), np.zeros(3),
                                         lambda tt, r: -1e-3 * r - 9.8, max_passes=1)
    assert passes == 2  # the limit reached: one more than allowed
    t, w, f = _stationary(100.0, 20.0)
    # the heading given (10 deg) is not the pad's: its noise-free Earth rate names the one it is
    with pytest.warns(AlignmentWarning, match="given 10, off by") as rec:
        res = navigate(check_imu(ImuData(t, w, f)), SITE, (0.0, 10.0), heading_deg=10.0)
    found = float(re.search(r"a heading of ([0-9.]+) deg \(the gyrocompass", str(rec[0].message)).group(1))
    assert abs(found - _heading_of_x()) <= 1.0
    assert res.success and res.status == 0
    res.passes = MAX_PASSES + 1
    assert not res.success and res.status == 1 and "did not converge" in res.message


def _alignment_warnings(imu, **kw) -> list[str]:
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        navigate(imu, SITE, (0.0, 10.0), heading_deg=_heading_of_x(), **kw)
    return [str(r.message) for r in rec if r.category is AlignmentWarning]


def test_gyro_signs_against_the_accelerometers_are_told_by_the_earth_rate_when_the_grade_allows():
    """A navigation-grade pad (gyro noise 1e-6 rad/s at 100 Hz): gyro y, z negated, or the specific force given as
    +g down, is named (the signs that explain the pad rate, chi-square 0 against ~30); as given, nothing; a MEMS
    gyro (bias 1e-3 rad/s, 14 times the Earth rate) cannot tell the Earth rate: no sign is named."""
    t, w, f = _stationary(100.0, 20.0, np.random.default_rng(3), sigma_a=1e-4, sigma_g=1e-6)
    assert _alignment_warnings(check_imu(ImuData(t, w, f))) == []
    for ww, ff in ((w * [1, -1, -1], f), (w, -f)):
        try:
            said = [m for m in _alignment_warnings(check_imu(ImuData(t, ww, ff))) if "Earth rate the alignment" in m]
        except ValueError as exc:  # decisive: an error (test below)
            said, refused = [str(exc)], True
        else:
            refused = False
        assert len(said) == 1 and "with the signs of gyro" in said[0] and "+g down" in said[0]
        as_given = float(re.search(r"chi-square ([0-9.e+-]+) over", said[0]).group(1))
        flipped = float(re.search(r"changed it is ([0-9.e+-]+):", said[0]).group(1))
        assert as_given > EARTH_RATE_CHI2 / 2 and flipped + 9.0 < as_given  # +g down: about a tilted axis
        assert refused == (as_given > EARTH_RATE_CHI2 and flipped <= SIGN_CHI2_CONSISTENT), (as_given, flipped)
    mems = w + 1e-3
    assert not any("signs of gyro" in m for m in _alignment_warnings(check_imu(ImuData(t, mems * [1, -1, -1], f))))


def test_gyro_signs_the_earth_rate_decides_are_refused():
    """A navigation-grade pad (gyro noise 1e-7 rad/s at 100 Hz, 60 s) with gyro y, z negated: as given the pad rate
    is far beyond the Earth rate (chi-square > 16.3), with those signs within it: an error naming the columns to
    negate and both numbers, nothing navigated (a reviewer's aircraft record: exit 0 and 14 km underground)."""
    t, w, f = _stationary(100.0, 60.0, np.random.default_rng(5), sigma_a=1e-4, sigma_g=1e-7)
    with pytest.raises(ValueError, match=r"negate w_y, w_z") as exc:
        _alignment_warnings(check_imu(ImuData(t, w * [1, -1, -1], f)))
    as_given = float(re.search(r"chi-square ([0-9.e+-]+) over", str(exc.value)).group(1))
    flipped = float(re.search(r"changed it is ([0-9.e+-]+):", str(exc.value)).group(1))
    assert as_given > EARTH_RATE_CHI2 and flipped <= SIGN_CHI2_CONSISTENT
    assert _alignment_warnings(check_imu(ImuData(t, w, f))) == []  # as recorded: nothing


def test_a_gyro_bias_of_a_few_earth_rates_is_not_taken_for_a_sign():
    """A quiet pad (gyro noise 1e-7 rad/s) whose y gyro has a bias of -4 times its Earth-rate component (-46 deg/h, a
    MEMS gyro's ordinary size; the mean rate 2.4 Earth rates, under the 3 beyond which no test is made): as given the
    chi-square is 261, with gyro y negated 65, better by far but no fit (beyond 16.27). The warning named the sign
    flip; it now says that no sign fits, and the bias the signs as given need (the closed form ``w_mean - e``)."""
    from casep.navigation.alignment import gyro_bias_allowance

    t, w, f = _stationary(100.0, 60.0, np.random.default_rng(5), sigma_a=1e-4, sigma_g=1e-7)
    e = C_TB.T @ SITE.earth_rate
    beta = np.array([0.0, -4.0 * e[1], 0.0])
    as_given, flipped = (float(np.sum((S * (e + beta) - e) ** 2)) / gyro_bias_allowance(SITE) ** 2
                         for S in (np.ones(3), np.array([1.0, -1.0, 1.0])))
    assert as_given > flipped + 9.0 and flipped > EARTH_RATE_CHI2  # the flip is better, and fits no better than none
    said = [m for m in _alignment_warnings(check_imu(ImuData(t, w + beta, f))) if "Earth rate the alignment" in m]
    assert len(said) == 1 and "signs of gyro" not in said[0] and "no other sign per gyro axis" in said[0], said
    need = re.search(r"need ([-0-9.e+]+), ([-0-9.e+]+), ([-0-9.e+]+) deg/h", said[0])
    assert need and abs(float(need.group(2)) - np.degrees(beta[1]) * 3600) < 0.01 * abs(np.degrees(beta[1]) * 3600)


def test_a_pad_that_drifts_beyond_its_sensors_is_warned_about():
    """At rest with noise: no pad warning. A gyro bias of 0.02 rad/s (a consumer MEMS, under the 0.05 rad/s rate
    warning) tilts the levelled attitude: within the 10 s window the speed reaches about g b T^2 / 2 = 9.8 m/s,
    named with the allowance; the same without the check says nothing."""
    t, w, f = _stationary(100.0, 20.0, np.random.default_rng(4), sigma_a=2e-3, sigma_g=1e-4)
    assert _alignment_warnings(check_imu(ImuData(t, w, f))) == []
    said = _alignment_warnings(check_imu(ImuData(t, w + [0.02, 0.0, 0.0], f)))
    drift = float(re.search(r"speed reaches ([0-9.]+) m/s within the 10 s window", said[-1]).group(1))
    allowed = float(re.search(r"above the ([0-9.e+-]+) m/s its sensors allow", said[-1]).group(1))
    assert 3.0 < drift < 15.0 and allowed < 0.3
    assert "the vehicle need not have moved" in said[-1]  # the pad's own rate, 0.02 rad/s, explains it
    # the allowance is a north-finding gyro's; the pad's own rate is said as the multiple of it that it is
    allowance = float(re.search(r"a gyro bias of ([0-9.e+-]+) rad/s, the allowance of a gyro that finds north",
                                said[-1]).group(1))
    times = float(re.search(r"a gyro bias of that size, ([0-9.e+-]+) x that allowance", said[-1]).group(1))
    assert times == pytest.approx(0.02 / allowance, rel=0.05)
    assert _alignment_warnings(check_imu(ImuData(t, w + [0.02, 0.0, 0.0], f)), check_pad=False) == []


def test_a_pad_drift_its_own_rate_does_not_explain_says_the_vehicle_moved():
    """At rest, then a push of 0.05 m/s^2 along x for the window's second half (no rate): the speed reaches 0.25
    m/s, which neither the noise nor the pad's own horizontal rate explains: the vehicle moved."""
    t, w, f = _stationary(100.0, 20.0, np.random.default_rng(4), sigma_a=2e-4, sigma_g=1e-6)
    f = f + np.where((t[:, None] > 5.0) & (t[:, None] < 10.0), [0.05, 0.0, 0.0], 0.0)
    said = [m for m in _alignment_warnings(check_imu(ImuData(t, w, f))) if "declared at rest" in m]
    assert said and "the vehicle moved in the window" in said[-1] and "need not have moved" not in said[-1]


def test_the_lost_samples_warning_gives_the_longest_gaps_own_figures():
    """A 1 s gap where the specific force is steady and a 0.2 s gap across a step of 1 m/s^2: the figures after
    "the longest 1 s" are the 1 s gap's, and the 0.2 s gap, least known, is named with its own."""
    t, w, f = _stationary(100.0, 40.0)
    f = f + np.where(t[:, None] > 30.1, [1.0, 0.0, 0.0], 0.0)
    keep = ((t < 20.0) | (t > 21.0)) & ((t < 30.0) | (t > 30.2))
    with pytest.warns(GapWarning) as rec:
        check_imu(ImuData(t[keep], w[keep], f[keep]))
    msg = str(rec[0].message)
    longest, rest = msg.split("the longest 1.02 s after t = 19.99 s")[1].split("least known across the 0.22 s gap")
    assert "between the two sides of its 1.02 s" in longest and "its 0.22 s" in rest
    v_long = float(re.search(r"known to about ([0-9.e+-]+) m/s", longest).group(1))
    v_short = float(re.search(r"known to about ([0-9.e+-]+) m/s", rest).group(1))
    assert v_short > v_long
