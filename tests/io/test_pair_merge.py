"""The tracking grid of a telemetry + tracking merge: no near-duplicate time tag of casep's making.

A tracking epoch a rounding away from a telemetry sample (7e-8 s: time stamps written with fewer
digits) is that sample; one between samples is inserted; two time tags that close in the user's own
files still get the plausibility check's warning.
"""

from __future__ import annotations

import warnings

import numpy as np

from casep.checks.plausibility import check_flight
from casep.checks.time_offset import GRAVITY_LAUNCH
from casep.exceptions import PlausibilityWarning
from casep.io.flight import DUPLICATE_STEP
from casep.io.pair import pair_flight

T0, RATE = 345600.0, 100.0  # GPS seconds of week, an IMU grid


def _pair(t_tel, t_trk):
    """A smooth motion seen by both: acceleration (1 + sin t, cos t, 0.1), v its integral plus a start speed."""
    def v(t):
        s = t - T0
        return np.column_stack([5.0 + s - np.cos(s), np.sin(s), 0.1 * s])

    a = np.column_stack([1.0 + np.sin(t_tel - T0), np.cos(t_tel - T0), np.full(t_tel.size, 0.1)])
    f = a - GRAVITY_LAUNCH  # specific force: the kinematic acceleration less gravity (the units check holds)
    return pair_flight(t_tel, f, v(t_tel), t_trk, v(t_trk), interpolation="linear")


def _near_duplicate_warnings(flight):
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        check_flight(flight)
    return [str(w.message) for w in rec
            if issubclass(w.category, PlausibilityWarning) and "near-duplicate" in str(w.message)]


def test_a_tracking_epoch_a_rounding_off_a_sample_is_that_sample():
    t_tel = T0 + np.arange(3000) / RATE
    on_grid = t_tel[50:2950:10] + 7e-8  # 10 Hz tracking, its stamps 7e-8 s off the IMU's
    between = t_tel[55:2950:200] + 0.0033  # and some epochs between samples
    t_trk = np.sort(np.concatenate([on_grid, between]))
    fl = _pair(t_tel, t_trk)
    assert fl.meta["inserted"] == between.size  # the on-grid epochs are samples, not new rows
    assert fl.n_samples == np.count_nonzero(t_tel <= t_trk[-1]) + between.size  # telemetry to the end of tracking
    assert np.abs(fl.t[fl.observed] - t_trk).max() <= 7e-8 + 1e-9  # each epoch on its own row
    assert np.min(np.diff(fl.t)) >= DUPLICATE_STEP * np.median(np.diff(fl.t))
    assert _near_duplicate_warnings(fl) == []


def test_near_duplicate_time_tags_of_the_files_still_warn():
    t_tel = T0 + np.arange(3000) / RATE
    t_trk = t_tel[50:2950:10] + 7e-8
    dup_tel = np.insert(t_tel, 1001, t_tel[1000] + 2e-7)  # the telemetry file's own near-duplicate
    msgs = _near_duplicate_warnings(_pair(dup_tel, t_trk))
    assert len(msgs) == 1 and "row 1002: time step 2e-07 s" in msgs[0]
    extra = np.array([t_tel[700] + 0.004, t_tel[700] + 0.004 + 2e-7])  # the tracking file's own pair, between samples
    msgs = _near_duplicate_warnings(_pair(t_tel, np.sort(np.concatenate([t_trk, extra]))))
    assert len(msgs) == 1 and "time step 2e-07 s" in msgs[0]


def test_a_navigation_not_trusted_on_every_tracked_row_is_bad_input(tmp_path, capsys):
    """``ins_valid`` 0 from before the first tracking epoch (an accelerometer clipped at lift-off, tracking from
    later): exit 2 naming the file, the column and the rows, no traceback and no result written."""
    from casep.cli import main
    from casep.io.files import write_table

    t = np.arange(0.0, 20.0, 0.1)
    z = np.zeros_like(t)
    write_table(tmp_path / "tel.csv", {"t": t, "f_x": z, "f_y": z - GRAVITY_LAUNCH[1], "f_z": z, "v_tel_x": z,
                                       "v_tel_y": z, "v_tel_z": z, "ins_valid": (t < 3.0).astype(float)})
    tt = np.arange(5.0, 20.0, 0.5)
    write_table(tmp_path / "trk.csv", {"t": tt, "v_trk_x": tt * 0, "v_trk_y": tt * 0, "v_trk_z": tt * 0})
    out = tmp_path / "res.json"
    code = main(["separate", str(tmp_path / "tel.csv"), "--tracking", str(tmp_path / "trk.csv"), "--json", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    assert "tel.csv" in err and "ins_valid" in err and "no tracked row is left" in err, err
    assert not out.exists()
