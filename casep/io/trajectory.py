"""A trajectory file for the impact analysis: ``t``, ``f_*`` (or ``W_*``), ``r_*``, ``v_*``.

The impact point needs the burnout state (launch-inertial position and velocity, the columns
``r_x, r_y, r_z, v_x, v_y, v_z`` of the last row) and the specific force to integrate S_V; the
velocity error is not used, so a trajectory that was not flown may omit it.
"""

from __future__ import annotations

import os

import numpy as np

from casep.io.files import read_flight
from casep.io.flight import DV_COLUMNS, FlightData
from casep.io.locate import is_parquet
from casep.io.tables import VTEL_COLUMNS, Table, table_force

__all__ = ["read_trajectory"]


def read_trajectory(path: str | os.PathLike) -> FlightData:
    """A flight file for the impact analysis: ``t``, ``f_*`` (or ``W_*``), ``r_*``, ``v_*``.

    ``dv_*`` (or ``v_tel_*``/``v_trk_*``) may be absent: a trajectory that was not flown has
    none, a radar-tracked flight's telemetry has ``v_tel_*`` only, and the impact analysis does not
    use them (dv is then stored as zeros and
    ``meta["dv"]`` says ``"absent"``).
    """
    tab = Table(path)
    if tab.has(DV_COLUMNS) or (any(c in tab.columns for c in VTEL_COLUMNS) and "v_trk_x" in tab.columns):
        del tab
        return read_flight(path)
    tab.require(("t",))
    t = tab.time()
    f, force_from = table_force(tab, t)
    return FlightData(t, f, np.zeros((t.size, 3)), source=tab.src, signals=tab.signals(),
                      meta={"format": "parquet" if is_parquet(tab.path) else "csv", "force": force_from,
                            "dv": "absent"})
