"""The heading check of a navigation from the pad (casep.io.setup.heading_turn, heading_problem).

A rocket's horizontal velocity early in flight, built in local east-north-up axes at the range of the simulated
sounding rocket (67.89 N) and turned launch-inertial by casep.frames (pymap3d's geodetic conversions): the tracking
at the true azimuth, the navigation at the azimuth turned by a heading error ``e`` (an INS started ``e`` deg clockwise
of the truth flies its horizontal velocity ``e`` deg clockwise). The turn is found to its construction, a 90 deg error
is refused with the numbers, a 0.2 deg error under tracking errors of 3 m/s is not, and a near-vertical flight
(horizontal speed below the limit) is not judged.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from casep.frames import LaunchSite, geodetic_to_launch
from casep.io.setup import HEADING_MIN_SPEED, HEADING_TURN_LIMIT, heading_problem, heading_turn

SITE = LaunchSite(67.89, 21.10, 330.0, 30.0, 1000.0)


def _state(t: np.ndarray, azimuth_deg: float, speed: float, v_up: float = 80.0) -> tuple[np.ndarray, np.ndarray]:
    """Launch-inertial position and velocity of a vehicle over the site moving at `speed` m/s horizontally towards
    `azimuth_deg` (clockwise from north) and `v_up` m/s up (the position's horizontal drift is left out: a few
    km change the local axes by hundredths of a degree)."""
    az = math.radians(azimuth_deg)
    n = t.size
    return geodetic_to_launch(SITE, t, np.full(n, SITE.lat_deg), np.full(n, SITE.lon_deg),
                              SITE.h_m + v_up * (t - SITE.t0),
                              np.full(n, speed * math.sin(az)), np.full(n, speed * math.cos(az)), np.full(n, v_up))


@pytest.mark.parametrize("error", [0.2, 90.0, -45.0, 170.0])
def test_the_turn_is_the_heading_error(error):
    t = SITE.t0 + np.arange(10.0, 40.0, 0.1)
    r, v_trk = _state(t, 30.0, 25.0)
    _, v_tel = _state(t, 30.0 + error, 25.0)
    h = heading_turn(SITE, t, v_tel, v_trk, r)
    assert h["turn_deg"] == pytest.approx(error, abs=1e-6)
    assert h["rest_m_s"] < 1e-6 and h["epochs"] == t.size and h["speed_m_s"] == pytest.approx(25.0, rel=1e-9)
    assert h["misfit_m_s"] == pytest.approx(2 * 25.0 * abs(math.sin(math.radians(error) / 2)), rel=1e-9)


def test_a_90_degree_heading_error_is_refused_and_a_small_one_is_not():
    rng = np.random.default_rng(5)
    t = SITE.t0 + np.arange(27.5, 47.5, 0.1)
    r, v_trk = _state(t, 30.0, 25.0)
    noise = np.repeat(rng.normal(0.0, 3.0, (20, 3)), 10, axis=0)  # a 1 Hz solution with errors of 3 m/s
    for error, said in [(0.2, False), (90.0, True)]:
        _, v_tel = _state(t, 30.0 + error, 25.0)
        why = heading_problem(SITE, t, v_tel, v_trk + noise, r, "--heading 120 deg, of body axis y")
        assert (why is not None) == said, why
    assert why is not None
    for part in ("turned 9", "deg clockwise", "200 epochs", "--heading 120 deg, of body axis y", "deg off"):
        assert part in why, part
    h = heading_turn(SITE, t, v_tel, v_trk + noise, r)
    assert abs(h["turn_deg"] - 90.0) < 15 and h["turn_deg"] > HEADING_TURN_LIMIT


def test_no_judgement_without_horizontal_speed_or_before_the_launch():
    t = SITE.t0 + np.arange(10.0, 40.0, 0.1)
    r, v_trk = _state(t, 30.0, 0.9 * HEADING_MIN_SPEED)
    _, v_tel = _state(t, 120.0, 0.9 * HEADING_MIN_SPEED)
    assert heading_turn(SITE, t, v_tel, v_trk, r) is None
    r, v_trk = _state(t - 60.0, 30.0, 25.0)  # every epoch before the launch time
    _, v_tel = _state(t - 60.0, 120.0, 25.0)
    assert heading_problem(SITE, t - 60.0, v_tel, v_trk, r, "gyrocompassing") is None
