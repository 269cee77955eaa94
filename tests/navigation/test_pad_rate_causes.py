"""The pad's Earth rate names the set-up mistake it determines (casep.navigation.alignment.pad_rate_causes): gyro
columns swapped, the latitude's sign, a heading off, with the numbers; nothing on a correct set-up, on MEMS gyros
(bias far beyond the Earth rate) or on the real MPU-9150 pads."""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from casep.exceptions import AlignmentWarning
from casep.frames import LaunchSite
from casep.gravity import normal_gravity_ecef
from casep.navigation.alignment import align

SITE = LaunchSite(28.5, -80.6, 10.0, 90.0, 0.0)  # a coastal launch site, azimuth 90 deg
#: A pad attitude (body -> launch triad: x east, y up, z south at azimuth 90): body x up, body z
#: horizontal at azimuth 180 deg, body y west (a rocket on its rail), tilted by a degree.
C_TB = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ \
    Rotation.from_euler("XY", [1.0, 0.5], degrees=True).as_matrix()
BIAS = np.radians(np.array([1.0, -0.6, 0.8]) / 3600.0)  # a tactical gyro: about 1.4 deg/h


def _heading_of(C_tb: np.ndarray, site: LaunchSite, i: int) -> float:
    v = C_tb[:, i]
    return (site.azimuth_deg + math.degrees(math.atan2(v[2], v[0]))) % 360.0


def _pad(rng, sigma_g: float = 1e-6, bias: np.ndarray = BIAS, n: int = 1000):
    g_t = SITE.C.T @ normal_gravity_ecef(SITE.r_site)
    t = np.arange(n) / 100.0
    w = np.tile(C_TB.T @ SITE.earth_rate + bias, (n, 1)) + sigma_g * rng.standard_normal((n, 3))
    f = np.tile(C_TB.T @ -g_t, (n, 1)) + 1e-3 * rng.standard_normal((n, 3))
    return t, w, f


def _said(t, w, f, site=SITE, heading=None) -> list[str]:
    heading = _heading_of(C_TB, SITE, 2) if heading is None else heading
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        align(t, w, f, (t[0], t[-1]), site, heading_deg=heading, heading_axis="z")
    return [str(r.message) for r in rec if issubclass(r.category, AlignmentWarning)]


def test_the_set_up_as_given_is_not_warned_about():
    assert _heading_of(C_TB, SITE, 2) == pytest.approx(180.0, abs=1.0) and C_TB[1, 0] > 0.999  # body x up
    assert _said(*_pad(np.random.default_rng(1))) == []


def test_swapped_gyro_columns_are_named_with_the_heading_they_mimic():
    """w_y, w_z swapped: body y and z are the horizontal axes, so the swap is a heading
    mirrored; both are named, the swap with the columns, with the bias each leaves against the one as given."""
    t, w, f = _pad(np.random.default_rng(2))
    said = _said(t, w[:, [0, 2, 1]], f)
    assert len(said) == 1
    assert "the gyro axes x, y, z read from w_x, w_z, w_y" in said[0] and "a heading of" in said[0]
    given = float(re.search(r"needs a gyro bias of ([0-9.]+) deg/h", said[0]).group(1))
    swapped = float(re.search(r"read from w_x, w_z, w_y: a bias of ([0-9.]+) deg/h", said[0]).group(1))
    assert swapped == pytest.approx(np.linalg.norm(BIAS[[0, 2, 1]]) / math.radians(1 / 3600), rel=0.05)
    assert given > 10.0 * swapped


def test_the_latitude_sign_is_named():
    t, w, f = _pad(np.random.default_rng(3))
    south = LaunchSite(-28.5, -80.6, 10.0, 90.0, 0.0)
    said = _said(t, w, f, site=south)
    assert len(said) == 1 and "a latitude of 28.5 deg (the sign of --launch-site's latitude: given -28.5)" in said[0]


@pytest.mark.parametrize("off", [90.0, -120.0])
def test_a_heading_off_is_named_with_the_gyrocompass_heading(off):
    """The given heading off by 90 or -120 deg: the heading the pad rate says is the true one within 6 deg (the
    bias, 1.4 deg/h against the 13.2 deg/h horizontal Earth rate, turns it by up to 6 deg)."""
    t, w, f = _pad(np.random.default_rng(4))
    true = _heading_of(C_TB, SITE, 2)
    said = _said(t, w, f, heading=(true + off) % 360.0)
    assert len(said) == 1
    found = float(re.search(r"a heading of ([0-9.]+) deg \(the gyrocompass heading", said[0]).group(1))
    assert abs((found - true + 180.0) % 360.0 - 180.0) < 6.0


def test_mems_gyros_and_noisy_pads_name_nothing():
    """A MEMS gyro (bias 1e-3 rad/s, 14 times the Earth rate: the pad cannot see the Earth rate) with its columns
    swapped, or a tactical gyro whose noise of the mean hides it (2e-3 rad/s per sample, 10 s: 6e-5 rad/s): no
    cause named (nothing the data determine)."""
    rng = np.random.default_rng(5)
    t, w, f = _pad(rng, bias=np.array([1e-3, -7e-4, 5e-4]))
    assert _said(t, w[:, [0, 2, 1]], f) == []
    t, w, f = _pad(rng, sigma_g=2e-3)
    assert _said(t, w[:, [0, 2, 1]], f) == []


@pytest.mark.parametrize("session", range(5))
def test_real_mpu9150_pads_name_nothing(session):
    """The five real MPU-9150 sessions (tests/data/mikoff_mpu9150; biases up to 1.3 deg/s), their first 6 s at
    rest, levelled with any heading: no warning names a set-up mistake."""
    a = np.loadtxt(Path(__file__).resolve().parents[1] / "data" / "mikoff_mpu9150" / f"imu{session}.log.gz")
    t = np.arange(len(a)) / 100.0
    flat = "xyz"[int(np.argmin(np.abs(a[:600, 0:3].mean(axis=0))))]  # the most horizontal axis
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        align(t[:600], a[:600, 3:6], a[:600, 0:3], (0.0, 5.99), LaunchSite(55.0, 83.0, 150.0, 0.0, 0.0),
              heading_deg=0.0, heading_axis=flat)
    assert not any("times as likely" in str(r.message) for r in rec)


def test_a_derivatives_alignment_skips_only_the_earth_rate_warning():
    """``judge_earth_rate=False`` (the perturbed means of a derivative, not a record as given): the same attitude as
    the alignment that judges the pad rate, without its warning; a record as given is judged whatever it says."""
    t, w, f = _pad(np.random.default_rng(2))
    w = w[:, [0, 2, 1]]  # swapped columns: warned about (test_swapped_gyro_columns_are_named_...)
    heading = _heading_of(C_TB, SITE, 2)
    runs = {}
    for as_given, judge in ((False, True), (False, False), (True, False)):
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            runs[as_given, judge] = align(t, w, f, (t[0], t[-1]), SITE, heading_deg=heading, heading_axis="z",
                                          as_given=as_given, judge_earth_rate=judge).C_tb
        said = [str(r.message) for r in rec if issubclass(r.category, AlignmentWarning)]
        assert len(said) == (0 if (not as_given and not judge) else 1), (as_given, judge, said)
    assert np.array_equal(runs[False, True], runs[False, False])
    assert np.array_equal(runs[False, True], runs[True, False])
