"""Boost-phase trajectory physics sanity (casep.simulation.trajectory)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from casep.simulation.trajectory import (
    DEFAULT_VEHICLE,
    R_EARTH,
    Stage,
    Vehicle,
    YawManoeuvre,
    atmosphere,
    simulate_boost,
)
from casep.units import G0


@pytest.fixture(scope="module")
def traj():
    return simulate_boost(dataclasses.replace(DEFAULT_VEHICLE, yaw=YawManoeuvre()), 20.0)


def test_burnout_in_documented_range(traj):
    s = traj.summary()
    assert 170.0 <= s["duration_s"] <= 200.0
    assert 3000.0 <= s["burnout_speed_m_s"] <= 5000.0
    assert 100e3 <= s["burnout_altitude_m"] <= 300e3
    assert 20.0 <= s["burnout_flight_path_deg"] <= 30.0
    assert 5.0 <= s["max_specific_force_g"] <= 8.0


def test_specific_force_excludes_gravity(traj):
    # On the pad the accelerometers read thrust / mass (1.5-2 g), not thrust / mass - g (~0.8 g).
    f0 = traj.specific_force[0]
    expect = DEFAULT_VEHICLE.stages[0].thrust / DEFAULT_VEHICLE.liftoff_mass  # no drag at rest
    np.testing.assert_allclose(np.linalg.norm(f0), expect, rtol=1e-12)
    assert 1.5 * G0 <= np.linalg.norm(f0) <= 2.0 * G0
    assert f0[1] > 0.999 * np.linalg.norm(f0)  # vertical rise: along y (up)
    # Kinematics: dv/dt - f must be gravity (|g| ~ 9.2-9.8 m/s^2, pointing down), not zero.
    acc = np.gradient(traj.velocity, traj.t, axis=0)
    g = acc - traj.specific_force
    smooth = (traj.t > 20) & (traj.t < 90)
    gn = np.linalg.norm(g[smooth], axis=1)
    assert np.all((gn > 9.0) & (gn < 9.9))


def test_staging_shows_the_coast(traj):
    ev = traj.events
    coast = (traj.t > ev["stage1_burnout"] + 0.1) & (traj.t < ev["stage2_ignition"] - 0.1)
    assert coast.sum() >= 80  # 4.8 s at 20 Hz
    assert np.linalg.norm(traj.specific_force[coast], axis=1).max() < 0.05 * G0  # only drag
    before = (traj.t > ev["stage1_burnout"] - 3) & (traj.t < ev["stage1_burnout"] - 2)
    assert np.linalg.norm(traj.specific_force[before], axis=1).min() > 5.0 * G0  # peak just before tail-off
    assert np.all(np.diff(traj.mass) <= 1e-9)  # mass only decreases (burn and separation)
    assert traj.mass[coast][0] < traj.mass[before][-1] - DEFAULT_VEHICLE.stages[0].dry_mass + 1.0


def test_no_nan_and_yaw_gives_cross_range(traj):
    for a in (traj.position, traj.velocity, traj.specific_force, traj.mass, traj.altitude):
        assert np.all(np.isfinite(a))
    assert np.abs(traj.specific_force[:, 2]).max() > 0.02 * G0
    pitch = simulate_boost(DEFAULT_VEHICLE, 5.0)
    assert not np.any(pitch.specific_force[:, 2]) and not np.any(pitch.position[:, 2])


def test_dense_sampling_matches_grid(traj):
    pos, vel = traj.sample(traj.t[::37])
    np.testing.assert_allclose(vel, traj.velocity[::37], rtol=1e-12, atol=1e-9)
    with pytest.raises(ValueError, match="outside the flight"):
        traj.sample([traj.t[-1] + 1.0])


def test_standard_atmosphere_reference_values():
    # USSA-76 tables: sea level 1.2250 kg/m^3, 340.29 m/s; 11 and 20 km geopotential 0.36392 and
    # 0.088035; 50 km geometric 1.0269e-3.
    for h, rho_ref in ((0.0, 1.2250), (11_019.0, 0.36392), (20_063.0, 0.088035), (50_000.0, 1.0269e-3)):
        rho, _ = atmosphere(h)
        assert rho == pytest.approx(rho_ref, rel=2e-3)
    assert atmosphere(0.0)[1] == pytest.approx(340.29, rel=1e-4)
    assert atmosphere(150e3)[0] < 1e-8


def test_vehicle_validation():
    with pytest.raises(ValueError, match="stage 1 `thrust` must be finite and > 0"):
        Vehicle(1000.0, 1.0, (Stage(thrust=0.0, isp=200.0, burn=10.0, dry_mass=1.0),))
    with pytest.raises(ValueError, match="`liftoff_mass` must exceed"):
        Vehicle(10.0, 1.0, (Stage(thrust=1e3, isp=200.0, burn=10.0, dry_mass=20.0),))
    with pytest.raises(ValueError, match="`rate` must be finite and > 0"):
        simulate_boost(DEFAULT_VEHICLE, 0.0)
    assert R_EARTH == 6_371_000.0
