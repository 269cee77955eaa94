"""Gyro unit, rate and angle mistakes are refused with the numbers and the likely mistake named.

The turns of a session read in a physical gyro unit must integrate to about their declared angles
(:func:`casep.calibration.checks.check_turn_angles`). The cases run on imucal's real session
(``tests/data/imucal/example_ferraris_session.csv``: deg/s, 102.4 Hz, no ``t`` column), whose
turns integrate to 1.03, 0.98 and 1.00 times -360 deg.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from casep.calibration.checks import TURN_TOLERANCE, check_turn_angles
from casep.calibration.session import Session, ferraris_segment
from casep.cli import main

DATA = Path(__file__).resolve().parents[1] / "data" / "imucal"
SESSION = DATA / "example_ferraris_session.csv"
SEGMENTS = DATA / "example_ferraris_session_list.json"


def _x_rot_ratio(scale: float, rate: float = 102.4) -> float:
    """x_rot's gyro integral over the declared -360 deg, recomputed here with pandas (bias: the six static means)."""
    df = pd.read_csv(SESSION)
    static = [(540, 1271), (1620, 2361), (2814, 3298), (3740, 4152), (4522, 4975), (5376, 5983)]
    bias = np.mean([df["gyr_x"].iloc[a:b].mean() for a, b in static])
    return float((df["gyr_x"].iloc[6770:7093] - bias).sum() / rate) * scale / -360.0


def _calibrate(tmp_path, *args, session=SESSION):
    out = tmp_path / "cal.json"
    code = main(["calibrate", str(session), "--segments", str(SEGMENTS), "--acc-unit", "m/s^2", *args,
                 "--json", str(out)])
    return code, out


def test_the_right_units_pass(tmp_path, capsys):
    code, out = _calibrate(tmp_path, "--rate", "102.4", "--gyr-unit", "deg/s")
    assert code == 0 and out.exists()
    assert abs(_x_rot_ratio(1.0) - 1.0) < 0.05  # the real gyro's scale error: a few percent


def test_deg_per_s_declared_rad_per_s_is_refused(tmp_path, capsys):
    """Today's main: exit 0 with Sg_xx 5.8e7 ppm and Kg0x -1.2e5 deg/h (57 x the bias)."""
    code, out = _calibrate(tmp_path, "--rate", "102.4", "--gyr-unit", "rad/s", "--model", "platform36_ground")
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    ratio = _x_rot_ratio(180.0 / math.pi)
    assert ratio == pytest.approx(58.89, abs=0.01)  # the number the message gives, recomputed independently
    assert f"`x_rot` {ratio:.4g}" in err and "x the declared angle -360 deg" in err, err
    assert "read as rad/s at 102.4 Hz" in err and "the readings look like deg/s: --gyr-unit deg/s" in err, err


def test_deg_per_s_declared_deg_per_h_is_refused(tmp_path, capsys):
    code, out = _calibrate(tmp_path, "--rate", "102.4", "--gyr-unit", "deg/h")
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert f"`x_rot` {_x_rot_ratio(1.0 / 3600.0):.4g}" in err and "look like deg/s: --gyr-unit deg/s" in err, err


def test_a_wrong_rate_without_a_t_column_is_refused(tmp_path, capsys):
    """Today's main: exit 0 with the gyro scales halved (Sg_xx -4.9e5 ppm)."""
    code, out = _calibrate(tmp_path, "--rate", "204.8", "--gyr-unit", "deg/s", "--model", "platform36_ground")
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert f"`x_rot` {_x_rot_ratio(1.0, rate=204.8):.4g}" in err and "0.4912 x the declared angle -360 deg" in err
    assert "with no `t` column" in err and "--rate 204.8 Hz is probably wrong (about 102 Hz would give 1)" in err, err
    assert "the turns are about -180 deg, not -360" in err  # the other reading of a factor 2, also named


def test_with_a_t_column_a_factor_two_is_the_angle(tmp_path, capsys):
    """Two turns declared as one: the rate is the t column's, so only the angle is named."""
    df = pd.read_csv(SESSION)
    df.insert(0, "t", df["n_samples"] / 102.4)
    path = tmp_path / "with_t.csv"
    df.drop(columns="n_samples").to_csv(path, index=False)
    code, out = _calibrate(tmp_path, "--gyr-unit", "deg/s", "--angle", "-720", session=path)
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert "x the declared angle -720 deg" in err and "the turns are about -359 deg, not -720" in err, err
    assert "--rate" not in err


def _turn(scale: float = 1.0, kept: float = 1.0):
    """A noise-free session: 4 s level, then a -360 deg turn about z at 1 deg/s read with `scale` (t from the
    rate, 50 Hz); the turn segment holds its first `kept` fraction. The rectangle rule is exact on it."""
    rate, n = 50.0, 360 * 50
    gyr = np.zeros((n + 200, 3))
    gyr[200:, 2] = -1.0 * scale
    acc = np.tile([0.0, 0.0, 9.81], (n + 200, 1))
    ses = Session(t=np.arange(n + 200) / rate, acc=acc, gyr=gyr, rate=rate, acc_unit="m/s^2", gyr_unit="deg/s")
    return ses, [ferraris_segment("z_p", np.arange(0, 200)),
                 ferraris_segment("z_rot", np.arange(200, 200 + int(round(kept * n))))]


@pytest.mark.parametrize("scale", [1.0 + 0.8 * TURN_TOLERANCE, 1.0 - 0.8 * TURN_TOLERANCE,
                                   1.0 + 1.2 * TURN_TOLERANCE, -(1.0 + 1.2 * TURN_TOLERANCE)])
def test_the_tolerance_on_a_noise_free_turn(scale):
    """Read with scale k, the turn integrates to k x -360 deg exactly: refused beyond the tolerance."""
    ses, segs = _turn(scale)
    if abs(abs(scale) - 1.0) <= TURN_TOLERANCE:
        check_turn_angles(segs, ses)
    else:
        said = rf"integrates to {re.escape(f'{-360 * scale:+.6g}')} deg .* {scale:.4g} x the declared angle -360 deg"
        with pytest.raises(ValueError, match=said + rf".* the turns are about {re.escape(f'{-360 * scale:+.3g}')} deg"):
            check_turn_angles(segs, ses)


def test_a_segment_that_cuts_the_turn_is_refused():
    """A turn segment holding 60 % of its -360 deg turn integrates to 0.6 x its angle."""
    ses, segs = _turn(kept=0.6)
    with pytest.raises(ValueError, match=r"integrates to -216 deg .* 0\.6 x the declared angle -360 deg.*"
                                         r"about 30 Hz would give 1\); or the turns are about -216 deg, not -360 .*"
                                         r"or the segment boundaries cut the turns"):
        check_turn_angles(segs, ses)
