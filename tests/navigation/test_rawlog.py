"""Raw IMU logs as they come: lost packets integrated across (with what they leave unknown), clipped samples marked.

The reference is the same record without the gap: across a gap the navigation takes the rate and the
specific force linear, so where they are linear (a coast at constant rate) nothing is lost, and where
the specific force changes (a motor's tail-off) the velocity error stays within the ``|f_b - f_a| h / 2``
the warning states (any path between the two samples fits the data).
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings

import numpy as np
import pytest

from casep.cli import main
from casep.exceptions import AlignmentWarning, GapWarning, PlausibilityWarning, SaturationWarning
from casep.navigation import ImuData, check_imu, navigate
from casep.simulation.rocket import QUICK_ROCKET, RocketSpec, simulate_rocket

EXACT = RocketSpec(rate=400.0, pad_s=4.0, flight_s=10.0, burn_s=3.0, gaps=0, burnout_gap_s=0.0, acc_bias_mg=0.0,
                   acc_scale_ppm=0.0, gyr_bias_dph=0.0, gyr_scale_ppm=0.0, acc_noise=0.0, gyr_noise=0.0,
                   tumble_start_s=1e3, clock_ppm=0.0, stale_s=1.0, heading_error_deg=0.0)


def _imu(cols: dict, keep=None, **kw) -> ImuData:
    keep = slice(None) if keep is None else keep
    return check_imu(ImuData(cols["t"][keep], np.column_stack([cols[f"w_{a}"] for a in "xyz"])[keep],
                             np.column_stack([cols[f"fb_{a}"] for a in "xyz"])[keep], source="imu.csv"), **kw)


_FLIGHTS: dict = {}


def _exact(tail_off: float):
    """The error-free record with a motor tail-off of `tail_off` s, and its navigation without a gap (cached)."""
    if tail_off not in _FLIGHTS:
        fl = simulate_rocket(0, dataclasses.replace(EXACT, tail_off_s=tail_off))
        _FLIGHTS[tail_off] = fl, navigate(_imu(fl.imu), fl.site, fl.align_window, heading_deg=fl.events["heading_deg"],
                                          heading_axis="z")
    return _FLIGHTS[tail_off]


@pytest.mark.parametrize("start, tail_off, kind", [(6.0, 0.3, "coast"), (2.9625, 0.3, "tail-off"),
                                                   (2.93, 0.005, "cut-off")])
def test_a_gap_costs_what_its_missing_samples_leave_unknown(start, tail_off, kind):
    fl, full = _exact(tail_off)
    t = fl.imu["t"] - fl.site.t0
    keep = ~((t > start) & (t < start + 0.075))
    gap = r"1 gap in t \(about \d+ samples lost.*longest 0\.0[78]\d* s after t = 30000"
    with pytest.warns(GapWarning, match=gap) as w:
        imu = _imu(fl.imu, keep)
    bound = float(re.search(r"known to about ([0-9.e+-]+) m/s", str(w[0].message)).group(1))
    res = navigate(imu, fl.site, fl.align_window, heading_deg=fl.events["heading_deg"], heading_axis="z")
    err = np.linalg.norm(res.v[-1] - full.v[-1])
    assert err <= bound
    if kind == "coast":  # rate constant, specific force smooth: the cubic loses nothing that matters
        assert err < 1e-3 and bound < 0.05
    elif kind == "tail-off":  # a smooth tail-off the cubic follows: far less than the bound
        assert err < 0.1 * bound and bound > 0.05
    else:  # the thrust cut off late in the gap: where, the samples do not say; the loss is of the bound's size
        assert 0.3 * bound < err and bound > 1.0


@pytest.fixture(scope="module")
def clipped_record():
    return simulate_rocket(3, QUICK_ROCKET)


def test_clipped_gyro_samples_are_named_and_the_rest_of_the_flight_marked(clipped_record, tmp_path):
    fl = clipped_record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GapWarning)  # the rates within the declared range: no PlausibilityWarning
        with pytest.warns(SaturationWarning, match=r"imu\.csv: the IMU clipped: w_y: \d+ samples at full scale \(the "
                                                   r"declared 2000 deg/s\), its maximum 34\.9066 rad/s = 2000 deg/s, "
                                                   r"rows \d+\.\.\d+, t = 3000\d\d\.\d+") as w:
            imu = _imu(fl.imu, gyr_range=math.radians(2000.0))
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always", AlignmentWarning)
            res = navigate(imu, fl.site, fl.align_window, heading_deg=fl.events["heading_deg"], heading_axis="z")
    # the pad speed, 0.337 m/s over the 7 s window, is its vertical accelerometer bias's b T (|f| - g = 0.048 m/s^2,
    # 4.9 mg): the levelling cannot cancel it, and the pad check allows it (no "speed reaches")
    assert not [r for r in rec if "speed reaches" in str(r.message)]
    vertical_bias = np.linalg.norm(res.alignment.f_mean) - res.alignment.g_pad
    assert res.pad_drift() == pytest.approx(vertical_bias * 7.0, rel=0.05)
    first = fl.site.t0 + (fl.events["first_clipped"] - fl.site.t0) * (1 + 104e-6)  # the IMU clock runs fast
    k = int(np.argmin(res.valid))
    assert first - 0.05 < res.t[k] <= first + 1e-9  # within 1 % of the full scale: the samples just before count
    assert res.valid[:k].all() and not res.valid[k:].any()
    assert any(f"wrong from t = {res.t[k]:.10g} s" in str(m.message) for m in w if m.category is SaturationWarning)
    cols = res.columns()
    assert "ins_valid" in cols and cols["ins_valid"][k - 1] == 1.0 and cols["ins_valid"][-1] == 0.0
    assert "clipped" in res.text() and res.to_dict()["invalid_from_s"] == pytest.approx(res.t[k])


def test_clipping_without_a_declared_range_is_a_run_at_a_nominal_range(clipped_record):
    fl = clipped_record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GapWarning)
        warnings.simplefilter("ignore", PlausibilityWarning)
        with pytest.warns(SaturationWarning, match=r"w_y: \d+ samples at full scale \(the nominal \+-2000 deg/s "
                                                   r"range\), its (maximum|minimum) -?34\.9066 rad/s = -?2000 deg/s"):
            imu = _imu(fl.imu)
    assert imu.clipped is not None and imu.clipped[-1]
    # a quantised peak repeated 3 times at 1500 deg/s is no full scale: nothing clipped, no warning
    t = np.arange(0.0, 2.0, 0.01)
    w = np.zeros((t.size, 3))
    w[:, 0] = np.minimum(np.radians(1500.0), np.radians(3000.0) * np.sin(np.pi * t / 2))
    w[:, 0] = np.round(w[:, 0], 2)
    f = np.tile([0.0, 0.0, -9.8], (t.size, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SaturationWarning)
        assert check_imu(ImuData(t, w, f)).clipped is None


def test_a_full_scale_must_be_positive():
    t = np.arange(0.0, 1.0, 0.01)
    with pytest.raises(ValueError, match=r"option --gyr-range \(`gyr_range`\) must be a finite number > 0 \(rad/s\), "
                                         r"got -1\.0"):
        check_imu(ImuData(t, np.zeros((t.size, 3)), np.zeros((t.size, 3))), gyr_range=-1.0)


def test_the_command_takes_the_gyro_range_and_writes_ins_valid(clipped_record, tmp_path, capsys):
    fl = clipped_record
    fl.write(tmp_path / "imu.parquet", tmp_path / "gps.parquet")
    s = fl.site
    out = tmp_path / "tel.parquet"
    a, b = fl.align_window
    args = ["navigate", str(tmp_path / "imu.parquet"), "--launch-site", str(s.lat_deg), str(s.lon_deg), str(s.h_m),
            str(s.azimuth_deg), "--launch-time", str(s.t0), "--align", str(a), str(b), "--heading",
            str(fl.events["heading_deg"]), "--heading-axis", "z", "--gyr-range", "2000", "-o", str(out)]
    assert main(args) == 0
    text = capsys.readouterr()
    assert "ins_valid = 0" in text.out and "the IMU clipped" in text.out + text.err
    import pandas as pd

    assert pd.read_parquet(out).columns[-1] == "ins_valid"
