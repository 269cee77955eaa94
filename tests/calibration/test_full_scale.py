"""``casep calibrate --segments auto --acc-range G --gyr-range DPS``: the declared full scale, checked, used by the
saturation checks, and compared with the full scale raw counts imply."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from casep.calibration.handsim import simulate_hand_session
from casep.calibration.handturned import calibrate_multiposition
from casep.calibration.saturation import (
    FullScaleWarning,
    SaturationWarning,
    check_gyro_saturation,
    declared_range,
)
from casep.calibration.session import Session
from casep.cli import main

G = 9.80665


def _run(args, out, capsys):
    rc = main(["calibrate", *args, "--segments", "auto", "--json", str(out)])
    std = capsys.readouterr()
    return rc, std.out, std.err


@pytest.fixture(scope="module")
def hand():
    return simulate_hand_session(16, seed=43)


@pytest.mark.parametrize("flag, value, unit", [("--acc-range", "-2", "g"), ("--gyr-range", "nan", "deg/s"),
                                               ("--acc-range", "abc", "g"), ("--gyr-range", "0", "deg/s")])
def test_a_bad_full_scale_is_refused_in_the_one_option_form(tmp_path, capsys, flag, value, unit):
    p = tmp_path / "s.txt"
    np.savetxt(p, np.zeros((10, 6)))
    out = tmp_path / "c.json"
    rc, _, err = _run([str(p), "--rate", "100", flag, value], out, capsys)
    key = flag[2:].replace("-", "_")
    assert rc == 2 and not out.exists()
    assert f"option {flag} (`{key}`) must be a finite number > 0 ({unit}), got '{value}'" in err, err


def test_the_api_refuses_it_in_the_same_form(hand):
    ses = Session(t=np.arange(len(hand.acc)) / hand.rate, acc=hand.acc, gyr=hand.gyr, rate=hand.rate,
                  acc_unit="m/s^2", gyr_unit="rad/s")
    with pytest.raises(ValueError, match=r"option --gyr-range \(`gyr_full_scale`\) must be a finite number > 0 "
                                         r"\(rad/s\), got -1\.0"):
        calibrate_multiposition(ses, gyr_full_scale=-1.0)


def test_the_labelled_path_refuses_the_flags(tmp_path, capsys):
    p = tmp_path / "s.csv"
    p.write_text("acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n" + "0,0,0,0,0,0\n" * 5)
    rc, _, err = main(["calibrate", str(p), "--rate", "100", "--segments", str(p), "--acc-range", "2", "--json",
                       str(tmp_path / "c.json")]), None, capsys.readouterr().err
    assert rc == 2 and "--acc-range: used by model multiposition" in err, err
    # the drift priors too: the labelled path's biases have no drift model to take them
    rc = main(["calibrate", str(p), "--rate", "100", "--segments", str(p), "--gyr-drift", "10,100", "--json",
               str(tmp_path / "c.json")])
    assert rc == 2 and "--gyr-drift: used by model multiposition" in capsys.readouterr().err


def test_a_declared_gyro_range_off_the_nominal_ones_is_saturation(tmp_path, capsys):
    # a +-200 deg/s gyro written in deg/s (no nominal range); fast turns hold +-200: without the flag the column's
    # extreme, repeated to all digits where nothing else repeats, is the full scale the data imply
    h = simulate_hand_session(16, seed=24, motion_s=(0.8, 1.0), angle_deg=(140.0, 170.0))
    gyr = np.clip(np.degrees(h.gyr), -200.0, 200.0)
    moving = [(a, b) for a, b in zip(np.flatnonzero(np.diff(np.r_[0, h.moving.astype(int)]) == 1),
                                     np.flatnonzero(np.diff(np.r_[h.moving.astype(int), 0]) == -1) + 1)]
    with pytest.warns(SaturationWarning, match=r"a full scale \+-200 deg/s implied by identical readings.*"
                                               r"--gyr-range 200 declares it"):
        assert check_gyro_saturation(gyr, moving, "deg/s", "s")
    with pytest.warns(SaturationWarning, match=r"the declared full scale -?200"):
        assert check_gyro_saturation(gyr, moving, "deg/s", "s", declared_range(math.radians(200), "deg/s", "gyro"))
    p = tmp_path / "clip.txt"
    np.savetxt(p, np.column_stack([h.acc, gyr]), fmt="%.10g")
    rc, _, err = _run([str(p), "--rate", "100", "--acc-unit", "m/s^2", "--gyr-unit", "deg/s", "--gyr-range", "200"],
                      tmp_path / "b.json", capsys)
    assert rc == 1 and re.search(r"gyro [xyz]: \d+ samples at its (maximum 200|minimum -200) \(the declared full "
                                 r"scale -?200\)", err), err[-2000:]  # a warning: on stderr


@pytest.mark.parametrize("gyr_range, warned", [("500", False), ("250", True)])
def test_raw_counts_compare_the_implied_full_scale_with_the_declared_one(tmp_path, capsys, hand, gyr_range, warned):
    # a +-2 g / +-500 deg/s part in 16-bit counts: declared right, the lines say "x the declared"; declared
    # +-250 deg/s, the counts imply twice that: warned with both numbers
    raw = np.clip(np.column_stack([np.round(hand.acc / (G / 16384.0)), np.round(hand.gyr / math.radians(1 / 65.536))])
                  + 32768, 0, 65535)
    p = tmp_path / "raw.txt"
    np.savetxt(p, raw, fmt="%d")
    rc, out, err = _run([str(p), "--rate", "100", "--acc-range", "2", "--gyr-range", gyr_range],
                        tmp_path / "c.json", capsys)
    assert rc == 0, err
    m = re.search(r"gyro raw counts: full scale \+-([\d.]+) deg/s over \+-32768 counts \(a 16-bit converter\), "
                  rf"([\d.]+) x the declared \+-{gyr_range} deg/s", out)
    assert m and abs(float(m.group(1)) / 500.0 - 1) < 0.015, out
    assert re.search(r"accelerometer raw counts: .* x the declared \+-2 g", out)
    said = re.search(rf"the gyro's raw counts imply a full scale of \+-{m.group(1)} deg/s over \+-32768 counts "
                     rf"\(a 16-bit converter\), {m.group(2)} x the declared \+-{gyr_range} deg/s: a wrong declared "
                     r"range or a wrong --rate", out + err)
    assert bool(said) == warned, out[-1500:] + err
    assert (abs(float(m.group(2)) - 2.0) < 0.03) == warned


def test_the_warning_class_is_a_casep_warning():
    from casep.exceptions import CasepWarning

    assert issubclass(FullScaleWarning, CasepWarning)


def test_the_converter_zero_is_mid_scale_only_for_unsigned_counts():
    # a signed 16-bit sensor with offsets of ~500 counts (readings below zero) is not a 10-bit unsigned one
    from casep.calibration.saturation import converter

    signed = np.array([[500.0, -16000.0, 16900.0], [-300.0, 700.0, -200.0]])
    assert converter(np.array([500.0, 520.0, -480.0]), signed) == (16, 0.0)
    assert converter(np.array([2100.0, 2000.0, 1990.0]), np.array([[1000.0, 3000.0, 2048.0]])) == (12, 2048.0)
    assert converter(np.array([32900.0, 32700.0, 32800.0]), np.array([[16400.0, 49000.0, 32768.0]])) == (16, 32768.0)
    assert converter(np.array([3.0, -2.0, 1.0]), np.array([[70000.0, 0.0, -5.0]])) == (18, 0.0)


def _first_beyond(x: np.ndarray, limit: float) -> tuple[int, int]:
    """The first column of `x` with a reading beyond `limit` in magnitude, and that reading's index."""
    j = next(j for j in range(x.shape[1]) if np.any(np.abs(x[:, j]) > limit))
    return j, int(np.flatnonzero(np.abs(x[:, j]) > limit)[0])


def test_a_declared_gyro_range_the_session_exceeds_is_refused(tmp_path, capsys):
    """The +-200 deg/s session declared ``--gyr-range 20``: a gyro clipped at 20 deg/s cannot read 200, so the
    declared range is wrong: exit 2 naming the column, the file's row, the time, the largest reading and the ratio,
    nothing written (the raw-IMU and telemetry paths' rule, :func:`casep.fullscale.beyond_declared`)."""
    h = simulate_hand_session(16, seed=24, motion_s=(0.8, 1.0), angle_deg=(140.0, 170.0))
    gyr = np.clip(np.degrees(h.gyr), -200.0, 200.0)
    p = tmp_path / "clip.txt"
    np.savetxt(p, np.column_stack([h.acc, gyr]), fmt="%.10g")
    out = tmp_path / "c.json"
    rc, _, err = _run([str(p), "--rate", "100", "--acc-unit", "m/s^2", "--gyr-unit", "deg/s", "--gyr-range", "20"],
                      out, capsys)
    j, i = _first_beyond(gyr, 30.0)  # DECLARED_EXCEEDED (1.5) times 20 deg/s
    top = np.abs(gyr[:, j]).max()
    assert rc == 2 and not out.exists()
    assert f"{p}: column `w{'xyz'[j]}`, row {i + 1} (t = {i / 100:.10g} s): the gyro reads up to {top:.6g} deg/s, " \
           f"{top / 20:.3g} times the declared full scale 20 deg/s (--gyr-range)" in err, err


def test_a_declared_accelerometer_range_a_csv_session_exceeds_is_refused(tmp_path, capsys):
    """A CSV session in g (header, time column) declared ``--acc-range 0.5``: the static poses read 1 g, twice the
    declared range: exit 2 naming the column, the file's line (the header is line 1) and the time; the API's
    Session refuses it alike, with its own column names."""
    h = simulate_hand_session(16, seed=43)
    acc = h.acc / G
    p = tmp_path / "s.csv"
    t = np.arange(len(acc)) / h.rate
    cols = np.column_stack([t, acc, h.gyr])
    np.savetxt(p, cols, delimiter=",", fmt="%.10g", comments="",
               header="t,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z")
    out = tmp_path / "c.json"
    rc, _, err = _run([str(p), "--acc-unit", "g", "--gyr-unit", "rad/s", "--acc-range", "0.5"], out, capsys)
    j, i = _first_beyond(acc, 0.75)
    top = np.abs(acc[:, j]).max()
    said = (f"the accelerometer reads up to {top:.6g} g, {top / 0.5:.3g} times the declared full scale 0.5 g "
            "(--acc-range)")
    assert rc == 2 and not out.exists()
    assert f"{p}: column `acc_{'xyz'[j]}`, row {i + 2} (t = {t[i]:.10g} s): {said}" in err, err
    ses = Session(t=t, acc=h.acc, gyr=h.gyr, rate=h.rate, acc_unit="m/s^2", gyr_unit="rad/s")
    with pytest.raises(ValueError, match=re.escape(f"column `acc_{'xyz'[j]}`, row {i + 2}")):
        calibrate_multiposition(ses, acc_full_scale=0.5 * G)
