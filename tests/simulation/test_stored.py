"""The stored paper trajectory (casep.simulation.stored): the demo's flight without integrating it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight
from casep.simulation.stored import STORED_FILE, decode_states, encode_states, stored_trajectory
from casep.simulation.trajectory import simulate_boost

#: States compared to this fraction of each column's largest value. DOP853 at rtol 1e-10 does not give the
#: same bits on every machine: the boost amplifies rounding, and SciPy 1.17 on another CPU than the one that
#: stored the file differs from it by up to 8e-8 (position; velocity 4e-8, the rest <= 1e-8). A vehicle
#: change does not hide under 1e-6: a first-stage thrust 1e-5 higher moves position and velocity by 8e-5 and
#: 1.3e-4 of their largest values, and the test below fails it.
TOLERANCE = 1e-6

ARRAYS = ("t", "position", "velocity", "mass", "altitude", "specific_force", "acceleration", "attitude",
          "body_rate")


@pytest.fixture(scope="module")
def flown():
    """The paper vehicle flown at 100 Hz now, and the stored trajectory."""
    vehicle = get_scenario("paper").vehicle
    stored = stored_trajectory(vehicle, 100.0)
    assert stored is not None, f"no stored trajectory for the paper vehicle in {STORED_FILE}: regenerate it"
    return simulate_boost(vehicle, 100.0), stored


def test_the_stored_trajectory_is_the_one_flown_now(flown):
    """Every sampled array of the stored trajectory against simulate_boost's, within TOLERANCE of its
    largest value (a vehicle or simulator change that the stored file misses fails here)."""
    fresh, stored = flown
    for name in ARRAYS:
        assert _worst(fresh, stored, name) <= TOLERANCE, name
    assert stored.events == fresh.events
    assert stored.summary()["burnout_speed_m_s"] == pytest.approx(fresh.summary()["burnout_speed_m_s"], rel=TOLERANCE)


def _worst(a, b, name: str) -> float:
    """The largest difference of array `name` between trajectories `a` and `b`, in its column's largest value."""
    x, y = getattr(a, name), getattr(b, name)
    assert x.shape == y.shape, name
    return float(np.max(np.abs(x - y) / np.maximum(np.max(np.abs(x), axis=0), 1e-300)))


def test_the_tolerance_sees_a_small_vehicle_change(flown):
    """A first-stage thrust 1e-5 higher is far outside TOLERANCE (what the comparison above would miss
    otherwise)."""
    _, stored = flown
    vehicle = get_scenario("paper").vehicle
    stages = (dataclasses.replace(vehicle.stages[0], thrust=vehicle.stages[0].thrust * (1 + 1e-5)),
              *vehicle.stages[1:])
    changed = simulate_boost(dataclasses.replace(vehicle, stages=stages), 100.0)
    assert _worst(changed, stored, "velocity") > 30 * TOLERANCE


def test_a_flight_on_the_stored_trajectory_is_the_simulated_one(flown):
    """simulate_flight(trajectory=stored): dv, f and the signals of the flight simulated from scratch."""
    fresh, stored = flown
    a = simulate_flight("paper", seed=3, rate=100.0, trajectory=fresh)
    b = simulate_flight("paper", seed=3, rate=100.0, trajectory=stored)
    for x, y in ((a.flight.dv, b.flight.dv), (a.flight.f, b.flight.f)):
        np.testing.assert_allclose(y, x, rtol=0, atol=TOLERANCE * np.max(np.abs(x)))
    assert set(a.flight.signals) == set(b.flight.signals)
    with pytest.raises(ValueError, match="no state between them"):  # an offset needs the dense output
        simulate_flight("paper", seed=3, rate=100.0, trajectory=stored, time_offset=0.01)
    with pytest.raises(ValueError, match="not scenario `paper`'s vehicle flown at 50 Hz"):
        simulate_flight("paper", seed=3, rate=50.0, trajectory=stored)


def test_none_stored_for_another_rate_vehicle_or_file(tmp_path):
    vehicle = get_scenario("paper").vehicle
    assert stored_trajectory(vehicle, 50.0) is None
    assert stored_trajectory(dataclasses.replace(vehicle, area=2.5), 100.0) is None
    assert stored_trajectory(vehicle, 100.0, path=tmp_path / "missing.npz") is None
    (tmp_path / "bad.npz").write_bytes(b"not a zip file")
    assert stored_trajectory(vehicle, 100.0, path=tmp_path / "bad.npz") is None
    (tmp_path / "cut.npz").write_bytes(STORED_FILE.read_bytes()[:1000])  # a truncated copy
    assert stored_trajectory(vehicle, 100.0, path=tmp_path / "cut.npz") is None


def test_the_encoding_is_exact(rng):
    x = rng.standard_normal((257, 7)) * 10.0 ** rng.integers(-300, 300, (257, 7))
    x[3, 2], x[5, 0], x[7, 6], x[9, 1] = np.nan, np.inf, -np.inf, -0.0  # every bit pattern comes back
    back = decode_states(encode_states(x))
    assert back.view(np.int64).tobytes() == x.view(np.int64).tobytes()
