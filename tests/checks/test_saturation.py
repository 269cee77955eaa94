"""Readings held at a full scale (:mod:`casep.checks.saturation`): one rule, so calibration and navigation flag
the same clipped record the same way; the command lines take the full scales in one form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from casep.calibration.saturation import declared_range, saturated_runs
from casep.checks.saturation import CLIP_MARGIN, CLIP_RUN, held_full_scale, held_mask
from casep.cli import main
from casep.navigation.imu import clipped_samples
from casep.units import G0

FS_DPS, FS_G = 2000.0, 16.0


def _runs_of(flag: np.ndarray, n: int) -> np.ndarray:
    """Independent of the module: each True of `flag` kept when it lies in a run of `n` or more (plain loop)."""
    out = np.zeros_like(flag)
    k = 0
    while k < flag.size:
        if flag[k]:
            e = k
            while e < flag.size and flag[e]:
                e += 1
            out[k:e] = e - k >= n
            k = e
        else:
            k += 1
    return out


@pytest.fixture(scope="module")
def record():
    """A gyro (rad/s) clipped at +-2000 deg/s in a 2500 deg/s swing, and an accelerometer (m/s^2) clipped at 16 g in
    a 20 g thrust, with noise before the clip (a converter holds its rail exactly); the readings before the clip."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 4.0, 1 / 200)
    w = np.column_stack([np.radians(2500.0) * np.sin(np.pi * t), np.radians(1500.0) * np.sin(np.pi * t / 4),
                         np.zeros_like(t)]) + np.radians(0.5) * rng.standard_normal((t.size, 3))
    thrust = np.clip(20.0 * np.sin(np.pi * (t - 1.0) / 2), 0.0, None) * ((t > 1.0) & (t < 3.0))
    f = np.column_stack([G0 * (1.0 + thrust), np.zeros_like(t), -G0 * np.ones_like(t)]) \
        + 0.01 * rng.standard_normal((t.size, 3))
    fs_w, fs_f = math.radians(FS_DPS), FS_G * G0
    return np.clip(w, -fs_w, fs_w), np.clip(f, -fs_f, fs_f), w, f


@pytest.mark.parametrize("declared", [False, True])
def test_calibration_and_navigation_flag_the_same_clipped_record_the_same_way(record, declared):
    w, f, w_true, f_true = record
    fs_w, fs_f = (math.radians(FS_DPS), FS_G * G0) if declared else (None, None)
    nav_w, nav_f = clipped_samples(w, fs_w, "gyro"), clipped_samples(f, fs_f, "accelerometer")
    # calibration reads the same record in deg/s and g, the declared full scales through its own declared_range
    cal_w = held_mask(saturated_runs(np.degrees(w), "gyro", "deg/s", declared_range(fs_w, "deg/s", "gyro")), w.shape)
    cal_f = held_mask(saturated_runs(f / G0, "accelerometer", "g", declared_range(fs_f, "g", "accelerometer")),
                      f.shape)
    np.testing.assert_array_equal(nav_w, cal_w)
    np.testing.assert_array_equal(nav_f, cal_f)
    # and what they flag is what the clip did: a run of CLIP_RUN or more readings beyond it (declared: within
    # CLIP_MARGIN of it, the samples just before the clip too)
    for x_true, fs, mask in ((w_true, math.radians(FS_DPS), nav_w), (f_true, FS_G * G0, nav_f)):
        level = (1 - CLIP_MARGIN) * fs if declared else fs
        expect = np.column_stack([_runs_of(x_true[:, j] >= level, CLIP_RUN) | _runs_of(x_true[:, j] <= -level, CLIP_RUN)
                                  for j in range(3)])
        np.testing.assert_array_equal(mask, expect)
        assert mask[:, 0].sum() > 20 and not mask[:, 1:].any()


def test_the_declared_margin_and_the_run():
    F = 10.0
    x = np.zeros((40, 1))
    x[5:8, 0] = (1 - CLIP_MARGIN) * F + 1e-9  # three readings just inside the margin: held at full scale
    x[15:17, 0] = F  # two at it: too short a run
    x[25:30, 0] = -(1 - 1.5 * CLIP_MARGIN) * F  # five outside the margin: no full scale
    found = held_full_scale(x, "gyro", declared=F)
    assert [(h.side, h.runs) for h in found] == [("maximum", [(5, 8)])]
    assert "the declared full scale 10" in found[0].why


def _fake(monkeypatch, module, name):
    seen = {}

    def fake(*args, **kw):
        seen.update(kw)
        raise ValueError("stopped by the test")

    monkeypatch.setattr(module, name, fake)
    return seen


@pytest.mark.parametrize("command", ["calibrate", "navigate", "separate"])
def test_one_definition_of_the_range_flags_checked_in_the_one_form(tmp_path, capsys, command):
    args = {"calibrate": ["calibrate", "s.csv", "--segments", "auto", "--json", "c.json"],
            "navigate": ["navigate", "imu.csv", "--launch-site", "0", "0", "0", "0", "--launch-time", "0", "--align",
                         "0", "1", "-o", "tel.csv"],
            "separate": ["separate", "--imu", "imu.csv"]}[command]
    assert main([*args, "--gyr-range", "-2"]) == 2
    assert "option --gyr-range (`gyr_range`) must be a finite number > 0 (deg/s), got '-2'" in capsys.readouterr().err
    assert main([*args, "--acc-range", "inf"]) == 2
    assert "option --acc-range (`acc_range`) must be a finite number > 0 (g), got 'inf'" in capsys.readouterr().err


def test_navigate_and_separate_imu_pass_the_full_scales_in_si(tmp_path, capsys, monkeypatch):
    import casep.navigation.imu
    import casep.workflows.imu_separate

    for name in ("imu.csv", "trk.csv"):
        (tmp_path / name).write_text("t\n0\n")
    site = ["--launch-site", "0", "0", "0", "0", "--launch-time", "0", "--align", "0", "1"]
    ranges = ["--gyr-range", "2000", "--acc-range", "16"]
    want = {"gyr_range": pytest.approx(math.radians(2000.0), rel=1e-15), "acc_range": pytest.approx(16 * G0, rel=1e-15)}
    seen = _fake(monkeypatch, casep.navigation.imu, "read_imu")
    assert main(["navigate", str(tmp_path / "imu.csv"), *site, *ranges, "-o", str(tmp_path / "tel.csv")]) == 2
    assert seen == want
    seen = _fake(monkeypatch, casep.workflows.imu_separate, "separate_imu")
    assert main(["separate", "--imu", str(tmp_path / "imu.csv"), "--tracking", str(tmp_path / "trk.csv"), *site,
                 *ranges]) == 2
    assert {k: seen[k] for k in want} == want
    assert "stopped by the test" in capsys.readouterr().err
    assert main(["separate", str(tmp_path / "imu.csv"), str(tmp_path / "trk.csv"), "--gyr-range", "2000"]) == 2
    assert "--gyr-range is used with --imu IMU.csv or one strapdown telemetry file, not with 2 flights" in \
        capsys.readouterr().err


def test_separate_imu_refuses_ranges_for_a_record_already_read():
    from casep.frames import LaunchSite
    from casep.navigation import ImuData
    from casep.workflows.imu_separate import separate_imu

    t = np.arange(0.0, 1.0, 0.1)
    imu = ImuData(t, np.zeros((t.size, 3)), np.zeros((t.size, 3)))
    with pytest.raises(ValueError, match=r"`gyr_range`, `acc_range`: give them to casep.navigation.read_imu"):
        separate_imu(imu, "trk.csv", LaunchSite(0.0, 0.0, 0.0, 0.0, 0.0), (0.0, 1.0), gyr_range=1.0)


def test_a_gyro_held_at_a_nominal_range_for_most_of_the_record_is_found():
    """A noisy gyro that sits on its 125 deg/s rail for 87 % of the record: its median is the rail, which
    says nothing against clipping for a gyro (an accelerometer's median at 1 g does); the noise is judged
    off the rail. A static accelerometer at 1 g that never clips is still not flagged."""
    rng = np.random.default_rng(0)
    fs = np.radians(125.0)
    w = np.column_stack([np.linspace(0.0, 3.0 * fs, 1000), np.zeros(1000), np.zeros(1000)])
    w += 1e-4 * rng.standard_normal(w.shape)
    w[:, 0] = np.minimum(w[:, 0], fs)
    found = held_full_scale(w, "gyro")
    assert len(found) == 1 and found[0].axis == 0 and found[0].side == "maximum"
    assert sum(b - a for a, b in found[0].runs) == int(np.sum(w[:, 0] == fs)) > 600
    acc = np.full((1000, 3), [0.0, 0.0, 9.80665]) + 2e-3 * rng.standard_normal((1000, 3))
    acc[:, 2] = np.round(acc[:, 2], 2)  # quantised: the 1 g maximum repeats, and is no rail
    assert held_full_scale(acc, "accelerometer") == []
