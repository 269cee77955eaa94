"""FlightData validation and the sample-count check (casep.flight)."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.flight import FlightDataError, check_enough_samples, min_samples


def test_flightdata_validates_arrays():
    with pytest.raises(FlightDataError, match=r"column `f_y`, row 2: value nan is not finite"):
        casep.FlightData([0.0, 1.0], [[0, 0, 0], [0, np.nan, 0]], np.zeros((2, 3)))
    with pytest.raises(FlightDataError, match="`dv` must have shape"):
        casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((3, 3)))
    fl = casep.FlightData([0.0, 1.0], np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        fl.t[0] = 5.0  # read-only


def test_enough_samples_rule():
    assert min_samples(36) == 14 and min_samples(39) == 15
    fl = casep.FlightData(np.arange(13.0), np.zeros((13, 3)), np.zeros((13, 3)), source="s.csv")
    with pytest.raises(FlightDataError, match="s.csv: column `t`, row 13: 13 samples are too few for model `m`"):
        check_enough_samples(fl, 36, "m")
    check_enough_samples(casep.FlightData(np.arange(14.0), np.zeros((14, 3)), np.zeros((14, 3))), 36, "m")
