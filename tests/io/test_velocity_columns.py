"""Earth-fixed tracking whose velocity columns are in another order or of another sign than their names say
(casep.io.pair.check_velocity_columns): the tracked position's change, against the integrated velocity, names the
columns. Before the check, such a file failed only at the fit, as "a model error" naming no column.

Simulated rotating-Earth flights (casep.simulation.earth_fixed, the paper scenario) at an azimuth of 20 deg (the north
velocity about 2.7 times the east: at 45 deg the two are nearly equal, a swap changes little and is rightly not named),
geodetic tracking at 10 Hz, with 3 m of white noise added to each position axis (a GNSS fix's metres; the simulator
writes exact positions)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from casep.frames import LaunchSite
from casep.io.files import read_flight_pair
from casep.io.flight import FlightDataError
from casep.simulation.earth_fixed import write_earth_fixed_flight

SITE = LaunchSite(28.5, -80.6, 3.0, 20.0, 0.0)
#: metres of white noise per position axis added to the simulated (exact) tracked positions
POSITION_NOISE_M = 3.0


def _rewrite(path, frame: pd.DataFrame) -> None:
    header = [line for line in path.read_text().splitlines() if line.startswith("#")]
    with open(path, "w") as fh:
        fh.write("\n".join(header) + "\n")
        frame.to_csv(fh, index=False, float_format="%.12g")


@pytest.fixture(scope="module", params=[0, 1, 2])
def flight(request, tmp_path_factory):
    """A simulated pair with noisy positions: the telemetry path, the tracking path and its table."""
    d = tmp_path_factory.mktemp(f"cols{request.param}")
    fl = write_earth_fixed_flight(d / "tel.csv", SITE, frame="geodetic",
                                  seed=request.param, telemetry_rate=10.0, tracking_rate=10.0)
    trk = pd.read_csv(fl.tracking, comment="#")
    rng = np.random.default_rng(100 + request.param)
    m_per_deg = 111_320.0
    trk["lat"] += POSITION_NOISE_M * rng.standard_normal(len(trk)) / m_per_deg
    trk["lon"] += POSITION_NOISE_M * rng.standard_normal(len(trk)) / (m_per_deg * np.cos(np.radians(trk["lat"])))
    trk["h"] += POSITION_NOISE_M * rng.standard_normal(len(trk))
    _rewrite(fl.tracking, trk)
    return fl.telemetry, fl.tracking, trk


def _read(tel, trk_path):
    return read_flight_pair(tel, trk_path, tracking_frame="geodetic", site=SITE)


def test_right_columns_are_not_named(flight):
    tel, trk_path, _ = flight
    assert _read(tel, trk_path).n_observed > 100


@pytest.mark.parametrize("mutation, named", [
    ({"v_east": "v_north", "v_north": "v_east"}, "v_east the north velocity, v_north the east velocity"),
    ({"v_up": "-v_up"}, "v_up the negated up velocity"),
    ({"v_east": "v_north", "v_north": "v_east", "v_up": "-v_up"},
     "v_east the north velocity, v_north the east velocity, v_up the negated up velocity"),  # NED read as ENU
])
def test_swapped_or_negated_columns_are_named(flight, tmp_path, mutation, named):
    tel, _, trk = flight
    bad = trk.copy()
    for col, src in mutation.items():
        bad[col] = -trk[src[1:]] if src.startswith("-") else trk[src]
    path = tmp_path / "bad.tracking.csv"
    path.write_text("".join(line for line in flight[1].read_text().splitlines(True) if line.startswith("#")))
    with open(path, "a") as fh:
        bad.to_csv(fh, index=False, float_format="%.12g")
    with pytest.raises(FlightDataError) as err:
        _read(tel, path)
    msg = str(err.value)
    assert "do not follow the tracked position" in msg and named in msg, msg
    assert "times closer" in msg


def test_noise_that_hides_the_mistake_names_nothing():
    """A reading is named only where it explains the misfit (COLUMN_RATIO): velocities whose noise is as large as
    the difference a swap makes leave no reading 10 times closer (the unit test of the rule on arrays)."""
    from casep.io.pair import COLUMN_RATIO, velocity_column_misfit

    rng = np.random.default_rng(0)
    t = np.arange(0.0, 60.0, 0.1)
    v = np.column_stack([np.full(t.size, 1.0), np.full(t.size, -1.0), np.zeros(t.size)])
    r = np.cumsum(v * 0.1, axis=0) + 6.4e6
    noisy = v + 5.0 * rng.standard_normal(v.shape)
    swap = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1]], float)
    d, *_ = velocity_column_misfit(t, r, noisy, None, np.stack([np.eye(3), swap]))
    rms = np.sqrt(np.mean(d**2, axis=1))
    assert rms[0] < COLUMN_RATIO * rms[1]
    exact, *_ = velocity_column_misfit(t, r, v[:, [1, 0, 2]], None, np.stack([np.eye(3), swap]))
    assert np.sqrt(np.mean(exact[1] ** 2)) < 1e-6 < np.sqrt(np.mean(exact[0] ** 2))  # the swap read back: exact

