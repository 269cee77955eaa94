"""The simulated sounding rocket has the faults it claims, where and when its events say."""

from __future__ import annotations

import math

import numpy as np
import pytest

from casep.simulation.rocket import QUICK_ROCKET, simulate_rocket


@pytest.fixture(scope="module")
def fl():
    return simulate_rocket(7, QUICK_ROCKET)


def test_the_rocket_is_seeded(fl):
    again = simulate_rocket(7, QUICK_ROCKET)
    for k in fl.imu:
        assert np.array_equal(fl.imu[k], again.imu[k])
    assert not np.array_equal(fl.gps["v_ecef_x"], simulate_rocket(8, QUICK_ROCKET).gps["v_ecef_x"])


def test_the_imu_loses_packets_clips_and_runs_fast(fl):
    sp, t0 = QUICK_ROCKET, fl.site.t0
    t = fl.imu["t"]
    step = np.diff(t)
    big = step > 1.5 / sp.rate
    assert big.sum() == sp.gaps + 1
    k = int(np.argmax(step))  # the burnout gap
    assert 0.075 <= step[k] <= 0.075 + 2.0 / sp.rate and t[k] < t0 + sp.burn_s < t[k + 1]
    # the flight computer's clock: 104 ppm fast against GPS time, the two agreeing at lift-off
    assert t[0] - t0 == pytest.approx(-sp.pad_s * (1 + sp.clock_ppm * 1e-6), abs=1e-9)
    assert np.abs(fl.imu["w_y"]).max() == pytest.approx(math.radians(sp.gyr_range_dps), rel=1e-15)
    assert fl.events["first_clipped"] > t0 + sp.tumble_start_s


def test_the_gnss_repeats_then_lies_then_lags(fl):
    sp, t0, ev = QUICK_ROCKET, fl.site.t0, fl.events
    t = fl.gps["t"]
    state = np.column_stack([fl.gps[c] for c in fl.gps if c != "t"])
    stale = (t >= ev["stale"][0] - 1e-6) & (t <= ev["stale"][1] + 1e-6)
    last = np.flatnonzero(t < ev["stale"][0] - 1e-6)[-1]
    assert stale.sum() == round(sp.stale_s * sp.gps_rate) and (state[stale] == state[last]).all()
    wrong = (t >= ev["wrong"][0] - 1e-6) & (t <= ev["wrong"][1] + 1e-6)
    speed = np.linalg.norm(state[wrong, 3:], axis=1)
    assert np.all(np.abs(speed - sp.wrong_speed) < 0.5)
    after = t >= ev["reacquired"] - 1e-6
    changes = np.flatnonzero(np.any(np.diff(state[after], axis=0) != 0, axis=1)) + 1
    assert np.allclose(np.diff(t[after][changes]), sp.gps_step_s)  # a new solution once a second
    assert ev["reacquired"] - t0 == pytest.approx(sp.lock_lost_s + sp.stale_s + sp.wrong_s)
