"""A clipped body rate in strapdown telemetry (casep.io.strapdown): said as a clip, never as axes or a sign.

The flights come from the independent strapdown simulation of ``tests/conftest.py`` (:func:`ins_telemetry`): a roll
whose rate grows past 100 deg/s, the written ``w_x`` clipped at +-100 deg/s. Where the INS integrated the measured rate
unclipped (its own gyro had the range; the logged channel did not), the attitude disagrees with the written rate
only at the clipped readings; the attitude check finds them with the saturation rule (:mod:`casep.fullscale`, the
one the saturation screen applies) and compares the rest.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import ins_telemetry

import casep
from casep.io.files import write_table
from casep.io.flight import FlightDataError
from casep.io.strapdown import StrapdownWarning


@pytest.fixture(scope="module")
def clipped_written_only(tmp_path_factory):
    """Telemetry whose ``w_x`` is clipped at 100 deg/s while the INS integrated the unclipped rate; the tracking;
    the held samples."""
    tel, trk, _, held = ins_telemetry(100.0, integrates_clip=False)
    d = tmp_path_factory.mktemp("clip_written")
    write_table(d / "trk.csv", trk)
    return tel, d / "trk.csv", held


def _read(tmp_path, tel, trk):
    write_table(tmp_path / "tel.csv", tel)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        fl = casep.read_flight_pair(tmp_path / "tel.csv", trk)
    return fl, [str(r.message) for r in rec if issubclass(r.category, StrapdownWarning)]


def test_a_clipped_rate_the_attitude_did_not_follow_is_said_as_a_clip(clipped_written_only, tmp_path):
    """Before, exit 2 with "G = [1.08 ? ?; ...] ... axes swapped, a sign, a factor?": the clip read as a gain. Now
    a warning naming the column, the value, the full scale, the rows and the times of the clip, with the agreement
    off it (a fraction of a per cent), and no word of axes; the file is read."""
    tel, trk, held = clipped_written_only
    fl, said = _read(tmp_path, tel, trk)
    rows = np.flatnonzero(held[:, 0])
    assert held[:, 1:].sum() == 0 and rows.size > 100
    assert len(said) == 1, said
    msg = said[0]
    assert "the gyro clipped: w_x held at its maximum 100 deg/s" in msg and "--gyr-range 100 declares it" in msg
    assert f"rows {rows[0] + 1}.." in msg and f"t = {tel['t'][rows[0]]:.10g} .. " in msg
    assert "w_x held at its minimum -100 deg/s" in msg and "disagrees with the integrated body rate" in msg
    agree = float(msg.split("they agree within ")[1].split(" %")[0])
    assert agree < 1.0 and "axes" not in msg and "G = [" not in msg
    assert fl.meta["strapdown"]["rate_clipped"][0].startswith("w_x held at its maximum 100 deg/s")
    # the saturation screen finds the same clip and leaves the rows from it on out, saying the INS's attitude
    # followed the motion (not "the INS integrated the full scale")
    from casep.checks.saturation import screen_saturation
    from casep.exceptions import SaturationWarning

    with pytest.warns(SaturationWarning) as rec:
        screened = screen_saturation(fl)
    msg = " ".join(str(r.message) for r in rec)
    assert "w_x at its maximum 100 deg/s" in msg and "The INS's attitude followed the motion there" in msg
    assert "integrated the full scale" not in msg
    assert screened.meta["saturation"]["from_s"] == pytest.approx(tel["t"][rows[0]], abs=1e-9)


@pytest.mark.parametrize("wrong, expected", [
    (lambda tel: {**tel, "w_x": tel["w_y"], "w_y": tel["w_x"]}, np.eye(3)[[1, 0, 2]]),
    (lambda tel: {**tel, "w_z": -tel["w_z"]}, np.diag([1.0, 1.0, -1.0])),
])
def test_rates_in_the_wrong_axes_are_refused_with_the_clip_left_out(clipped_written_only, tmp_path, wrong,
                                                                    expected):
    """The same clipped telemetry with its rate axes swapped, or an axis negated: still refused as rates the INS did
    not integrate, G as made (within 0.01 where determined) on the steps no clipped reading reaches, the worst row
    off the clip, and the message says the clip was left out of the comparison."""
    tel, trk, held = clipped_written_only
    with pytest.raises(FlightDataError) as exc:
        _read(tmp_path, wrong(dict(tel)), trk)
    msg = str(exc.value)
    assert "columns `w_x`, `w_y`, `w_z`" in msg and "axes swapped, a sign, a factor?" in msg
    clipped = "w_y" if expected[0, 1] else "w_x"
    assert f"The gyro also clipped ({clipped} held at its maximum 100 deg/s" in msg
    assert "left out of this comparison" in msg
    G = np.array([[float(x.replace("?", "nan")) for x in row.split()]
                  for row in msg.split("G = [")[1].split("]")[0].split("; ")])
    assert np.nanmax(np.abs(G - expected)) < 0.01
    worst = int(msg.split("at row ")[1].split(",")[0])  # the step into that row: rows worst - 2 .. worst + 1 reach it
    assert not held[max(worst - 3, 0):worst + 1].any()


def test_a_clipped_rate_the_ins_integrated_reads_without_a_word_from_the_attitude_check(tmp_path):
    """The INS integrated the clipped readings (its gyro clipped): attitude and rate agree, the attitude check says
    nothing (the saturation screen says the clip when the flight is separated)."""
    tel, trk, _, held = ins_telemetry(100.0, dur=40.0)
    assert held.any()
    write_table(tmp_path / "trk.csv", trk)
    fl, said = _read(tmp_path, tel, tmp_path / "trk.csv")
    assert not said and "rate_clipped" not in fl.meta["strapdown"]


def test_the_saturation_rule_is_one_function():
    """The attitude check, the telemetry's screen, calibration and navigation apply the one rule of casep.fullscale."""
    import casep.calibration.saturation as cal
    import casep.checks.saturation as chk
    import casep.fullscale as fs
    import casep.io.strapdown as sd
    import casep.navigation.imu as imu

    assert sd.held_full_scale is chk.held_full_scale is cal.held_full_scale is imu.held_full_scale \
        is fs.held_full_scale
