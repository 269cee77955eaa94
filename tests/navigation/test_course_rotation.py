"""The heading from the tracked course (casep.navigation.alignment.course_rotation)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from casep.frames import geodetic_to_ecef
from casep.navigation.alignment import course_rotation


def test_course_rotation_recovers_a_heading_error():
    """A navigation turned by -psi about the vertical, with a constant velocity error: psi back to 1e-9 rad."""
    r0, _ = geodetic_to_ecef(np.array([40.1]), np.array([-105.1]), np.array([1600.0]), *np.zeros((3, 1)))
    up = r0[0] / np.linalg.norm(r0[0])  # near the normal; course_rotation uses the gravity's vertical
    t = np.arange(0.0, 20.0, 0.25)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    v = np.outer(3.0 * np.sin(0.3 * t) + t, north) + np.outer(0.5 * t, east)
    from casep.gravity import normal_gravity_ecef

    u = -normal_gravity_ecef(r0[0])
    u /= np.linalg.norm(u)
    psi = math.radians(-37.0)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    R = np.eye(3) - math.sin(psi) * K + (1 - math.cos(psi)) * K @ K  # rotation by -psi
    v_nav = v @ R.T + np.array([0.3, -0.2, 0.1])
    assert course_rotation(t, v_nav, t, v, r0[0]) == pytest.approx(psi, abs=1e-9)
    with pytest.raises(ValueError, match="no course"):
        course_rotation(t, np.zeros_like(v), t, np.zeros_like(v) + 2.0, r0[0])
