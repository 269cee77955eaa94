"""Ground calibration: fixes from a review of `casep calibrate` (position error on six positions, time
gaps in a turn, rate against the t column, units, SI readings of the wrong unit)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from casep import calibrate
from casep.calibration import load_calibration_model
from casep.calibration.calibrate import PositionMisfitWarning
from casep.calibration.simulate import ferraris_design, simulate_session

# a platform36 truth of typical magnitudes (the six positions cannot separate the cross-quadratic terms: 0)
PLATFORM = dict(Kg0x=2.0, Kg1x=1.0, Kg0y=-3.0, Kg0z=1.5, Ka0x=-2, Ka1x=0.5, Ka1xy=50, Ka1xz=50, Ka2x=5, Ka0y=-2,
                Ka1y=0.5, Ka1yz=50, Ka1yx=50, Ka2y=5, Ka0z=1, Ka1z=0.5, Ka1zx=50, Ka1zy=50, Ka2z=5,
                Sg_xx=300.0, Sg_yy=-200.0, Sg_zz=100.0)


@pytest.fixture(scope="module")
def platform_ground():
    return load_calibration_model("platform36_ground")


@pytest.fixture(scope="module")
def ferraris():
    return load_calibration_model("ferraris")


def _quiet(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PositionMisfitWarning)
        return fn(*a, **k)


# ------------------------------------------------------------------ D1: position error on six positions
def test_six_positions_estimate_the_position_error_with_the_rank_not_the_columns(platform_ground):
    """18 accelerometer rows, 21 columns but rank 15: 3 degrees of freedom estimate the position error.
    Tilts of 0.5 deg rms: the estimate is near 0.5 deg over a few seeds (chi2 with 3 dof each), never 0."""
    est = []
    for seed in range(4):
        ses, segs = simulate_session(platform_ground, PLATFORM, ferraris_design(200, 200), rate=100.0,
                                     noise=(2e-3, 1e-4), position_error_deg=0.5, seed=seed)
        cal = _quiet(calibrate, ses, segs, platform_ground)
        d = cal.sensors["accelerometer"].diagnostics
        assert d["position_error_dof"] == 3
        est.append(d["position_error_deg"])
    assert min(est) > 0.05, est
    # pooled over 4 sessions: 12 dof, chi2_12 / 12 in (0.30, 2.0) with probability > 0.99
    pooled = float(np.sqrt(np.mean(np.square(est))))
    assert 0.5 * np.sqrt(0.30) < pooled < 0.5 * np.sqrt(2.0), est
    assert "3 degrees of freedom" in cal.report()
