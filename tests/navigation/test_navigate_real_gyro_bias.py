"""A real gyro bias on the pad: the MPU-9150 session whose z gyro reads 4.8 deg/s at rest (mikoff/imu-calib's
``imu3.log``, vendored in ``tests/data/mikoff_mpu9150`` with its MIT licence).

The pad-rate rule (:func:`casep.navigation.alignment.large_pad_rate`) was written from simulated records; here it
meets a real one. Independent reference: the authors' calibration of this session (``MIKOV_TABLE``, column #4),
which found the gyro biases from the turns between the poses, not from the first standstill: at rest the gyro reads
its bias plus the Earth rate (0.004 deg/s), so the pad's mean rate is the table's bias to within the standstill's
noise (0.9 deg/s per sample over 650 samples: 0.04 deg/s per axis) and the bias's own drift between the first pose
and the authors' fit (measured: 0.1 deg/s on the norm, 0.09 on y; the tolerance below is 0.2 deg/s).
"""

from __future__ import annotations

import gzip
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from casep.calibration.mikov import table_si
from casep.exceptions import AlignmentWarning, PlausibilityWarning
from casep.frames import LaunchSite
from casep.navigation import ImuData, check_imu, navigate

DATA = Path(__file__).resolve().parents[1] / "data" / "mikoff_mpu9150" / "imu3.log.gz"
SITE = LaunchSite(55.75, 37.62, 150.0, 0.0, 7.0)  # any site: the bench's is not given; the rule does not need it
PAD = (0.0, 6.5)  # s: the session's first standstill (the first turn starts at 7.0 s)
TOL_DEG_S = 0.2


def _first_pose_and_turn() -> ImuData:
    """The session's first 8.5 s at 100 Hz: the first standstill and the hand turn after it."""
    with gzip.open(DATA, "rt") as fh:
        d = np.loadtxt(fh, max_rows=850)
    t = np.arange(len(d)) / 100.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reader's noise/plausibility remarks on a hand-held record
        return check_imu(ImuData(t, d[:, 3:6], d[:, 0:3]))


def test_a_real_mpu9150_gyro_bias_is_named_refused_by_default_and_navigated_within_its_tolerance():
    bias = np.degrees(table_si("gyro", 3)[6:9])  # the authors' b_x, b_y, b_z of session #4, deg/s
    assert np.linalg.norm(bias) == pytest.approx(5.08, abs=0.01)
    imu = _first_pose_and_turn()
    with pytest.raises(ValueError, match=r"a gyro bias of (\d\.\d+) deg/s, or rates in deg/s") as err:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            navigate(imu, SITE, PAD, heading_deg=0.0)
    said = float(re.search(r"a gyro bias of (\d\.\d+) deg/s", str(err.value)).group(1))
    assert said == pytest.approx(float(np.linalg.norm(bias)), abs=TOL_DEG_S)
    assert "--gyro-bias-tolerance" in str(err.value)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = navigate(imu, SITE, PAD, heading_deg=0.0, gyro_bias_tolerance=math.radians(5.5))
    drift = [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)
             and "--gyro-bias-tolerance" in str(w.message)]
    assert len(drift) == 1, [str(w.message) for w in caught]
    m = re.search(r"attitude drifts by (\d\.\d+) deg/s, (\d\.\d+) deg/s of it tilting the vertical", drift[0])
    assert m, drift[0]
    assert float(m.group(1)) == pytest.approx(float(np.linalg.norm(bias)), abs=TOL_DEG_S)
    up = res.alignment.f_mean / np.linalg.norm(res.alignment.f_mean)  # the pad's vertical in body axes
    across = float(np.linalg.norm(bias - (bias @ up) * up))
    assert float(m.group(2)) == pytest.approx(across, abs=TOL_DEG_S)
    assert not any(issubclass(w.category, AlignmentWarning) and "deg/s" in str(w.message) and "units" in
                   str(w.message) for w in caught)
