"""The ``paper`` scenario's trajectory at 100 Hz, stored: ``casep demo``'s flight without integrating it.

The demo flies the same vehicle at the same rate every time (its seed changes the tracking noise, not the
trajectory), and integrating it (:func:`~casep.simulation.trajectory.simulate_boost`: SciPy's DOP853, with
the ``scipy.integrate`` import) is most of the demo's time before its first figure. The integrated state at
the 19 501 sample times (position, velocity, mass; 7 x 19 501 doubles) is stored in
``data/paper_100hz.npz``, written by :func:`write_stored` from :func:`simulate_boost`; the specific force,
attitude and the rest are computed from it by the code :func:`simulate_boost` uses
(:func:`~casep.simulation.trajectory.sampled_trajectory`). With the stored states of the installed SciPy,
the trajectory is :func:`simulate_boost`'s bit for bit; ``tests/simulation/test_stored.py`` flies it again
and compares the states within 1e-9 of each column's largest value (DOP853 at rtol 1e-10).

Storage: the doubles' bit patterns as int64 differences from the previous sample, split into byte planes
and compressed (``np.savez_compressed``): 0.47 MB instead of 1.1 MB, restored exactly.

Regenerate after a change of the vehicle or of the simulator (the stored vehicle no longer matches: the demo
then integrates, as before):

    python -c "from casep.simulation.stored import write_stored; write_stored()"
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from casep.simulation.trajectory import BoostTrajectory, sampled_trajectory, simulate_boost
from casep.simulation.vehicle import Vehicle

__all__ = ["STORED_FILE", "STORED_RATE", "stored_trajectory", "write_stored", "encode_states", "decode_states"]

#: The stored trajectory: the ``paper`` scenario's vehicle at :data:`STORED_RATE`.
STORED_FILE = Path(__file__).with_name("data") / "paper_100hz.npz"
#: Its sample rate, Hz.
STORED_RATE = 100.0


def _vehicle_key(vehicle: Vehicle) -> str:
    return json.dumps(vehicle.to_dict(), sort_keys=True)


def encode_states(states: np.ndarray) -> np.ndarray:
    """(N, 7) doubles -> (7, 8, N) bytes: each column's bit patterns as int64 differences from the previous
    sample (smooth columns: small differences), split into byte planes (which compress well). Exact."""
    bits = np.ascontiguousarray(states, dtype=np.float64).view(np.int64)
    delta = np.diff(bits, axis=0, prepend=np.zeros((1, bits.shape[1]), dtype=np.int64))  # wraps, exactly
    return np.ascontiguousarray(delta.view(np.uint8).reshape(bits.shape[0], bits.shape[1], 8).transpose(1, 2, 0))


def decode_states(planes: np.ndarray) -> np.ndarray:
    """The inverse of :func:`encode_states`: the same doubles, bit for bit."""
    n = planes.shape[2]
    delta = np.ascontiguousarray(planes.transpose(2, 0, 1)).view(np.int64).reshape(n, planes.shape[0])
    return np.cumsum(delta, axis=0, dtype=np.int64).view(np.float64)  # int64 sums wrap as the differences did


def write_stored(path: str | os.PathLike = STORED_FILE, vehicle: Vehicle | None = None) -> Path:
    """Fly `vehicle` (default: the ``paper`` scenario's) at :data:`STORED_RATE` with :func:`simulate_boost`
    and store its integrated states at `path`."""
    from casep.simulation.scenarios import get_scenario

    vehicle = get_scenario("paper").vehicle if vehicle is None else vehicle
    traj = simulate_boost(vehicle, STORED_RATE)
    states = np.column_stack([traj.position, traj.velocity, traj.mass])
    path = Path(path)
    np.savez_compressed(path, planes=encode_states(states), aoa0=np.float64(traj._aoa0),
                        rate=np.float64(STORED_RATE), vehicle=np.array(_vehicle_key(vehicle)))
    return path


def stored_trajectory(vehicle: Vehicle, rate: float, path: str | os.PathLike = STORED_FILE
                      ) -> BoostTrajectory | None:
    """The stored trajectory of `vehicle` at `rate` Hz, or None when none is stored for them (another
    vehicle or rate, or no readable file): the caller then flies it (:func:`simulate_boost`).

    It holds its samples only: :meth:`BoostTrajectory.sample` and :meth:`~BoostTrajectory.kinematics`, which
    need the state between samples, refuse it (a tracking time offset or lever arm needs them).
    """
    if rate != STORED_RATE:
        return None
    try:
        with open(path, "rb") as fh, np.load(fh) as data:  # our handle: closed whatever np.load makes of it
            if str(data["vehicle"]) != _vehicle_key(vehicle) or float(data["rate"]) != rate:
                return None
            states, aoa0 = decode_states(data["planes"]), float(data["aoa0"])
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):  # no file, or not ours: fly it
        return None
    return sampled_trajectory(vehicle, rate, states, aoa0)
