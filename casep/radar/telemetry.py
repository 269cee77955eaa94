"""Telemetry for a radar separation: :class:`Telemetry`, :func:`read_telemetry`, and its
interpolation to the radar times.

Telemetry quantities are carried to each station's times by cubic Hermite interpolation (position
with velocity as its derivative, S_P with S_V, :func:`hermite`), velocity and S_V linearly
(:func:`interp_linear`); at radar times that are telemetry times this is exact.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.frames import LaunchSite

__all__ = ["Telemetry", "read_telemetry", "integrate_position", "hermite", "interp_linear", "PAD_SPEED"]

#: Telemetry speed relative to the pad above which its first sample is not on the pad, m/s.
PAD_SPEED = 5.0


@dataclass(frozen=True)
class Telemetry:
    """Telemetered navigation of a flight: times, specific force, velocity and position (launch-inertial).

    Attributes
    ----------
    t, f, v, r : ndarray
        s; m/s^2 (N, 3); m/s (N, 3); m (N, 3).
    r_source : str
        ``"r_tel columns"`` or ``"v_tel integrated from the launch point"``.
    signals : dict
        Other numeric columns (for model files that use signals).
    source : str
    """

    t: np.ndarray
    f: np.ndarray
    v: np.ndarray
    r: np.ndarray
    r_source: str
    signals: dict = field(default_factory=dict)
    source: str = "<memory>"


def integrate_position(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Position from the launch point (r(t_0) = 0) by the trapezoid rule on the velocity."""
    return cumulative_trapezoid(v, t)


def read_telemetry(path: str | os.PathLike, site: LaunchSite | None = None) -> Telemetry:
    """A telemetry file for the radar separation: ``t``, ``f_*`` or ``W_*``, ``v_tel_*``, optional ``r_tel_*``.

    Without ``r_tel_*`` the position is ``v_tel`` integrated from the launch point (the origin of
    the launch-inertial frame); that needs the first sample on the pad: with `site`, a first
    ``v_tel`` more than 5 m/s from the pad's inertial velocity (the Earth's rotation) is refused.
    """
    from casep.io.tables import VTEL_COLUMNS, Table, table_force

    tab = Table(path)
    tab.require(("t",) + VTEL_COLUMNS, ". A radar separation needs the telemetered velocity v_tel_x/y/z (m/s, "
                                       "launch-inertial) and optionally the position r_tel_x/y/z (m)")
    t = tab.time()
    f, _ = table_force(tab, t)
    v = tab.vectors(VTEL_COLUMNS)
    rcols = ("r_tel_x", "r_tel_y", "r_tel_z")
    if tab.has(rcols):
        r, how = tab.vectors(rcols), "r_tel columns"
    else:
        if any(c in tab.columns for c in rcols):
            tab.require(rcols, ". Give all three r_tel_x/y/z or none (then v_tel is integrated)")
        if site is not None:
            pad = np.cross(site.earth_rate, -site.earth_centre)  # inertial velocity of the launch point
            off = float(np.linalg.norm(v[0] - pad))
            if off > PAD_SPEED:
                ratio = float(np.linalg.norm(pad)) / max(float(np.linalg.norm(v[0])), 1e-300)
                unit = (f" Or v_tel in km/s: the pad's inertial speed {np.linalg.norm(pad):.4g} m/s is {ratio:.4g} "
                        f"times the first |v_tel| {np.linalg.norm(v[0]):.4g}" if 300 < ratio < 3000 else "")
                raise tab.error(f"no r_tel_x/y/z columns, and the first v_tel is {off:.4g} m/s from the pad's "
                                "velocity: the telemetry starts in flight, so its position cannot be integrated from "
                                "the launch point. Give r_tel_x, r_tel_y, r_tel_z (m, launch-inertial)." + unit,
                                "v_tel_x" if unit else "r_tel_x", "header")
        r, how = integrate_position(t, v), "v_tel integrated from the launch point"
    sig = {k: val for k, val in tab.signals().items() if k not in rcols}
    return Telemetry(t, f, v, r, how, sig, tab.src)


def hermite(t: np.ndarray, y: np.ndarray, dy: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of `y` (derivative `dy`) at `tq`, along axis 0 (exact at the nodes)."""
    k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    h = (t[k + 1] - t[k])
    s = (tq - t[k]) / h
    shape = (-1,) + (1,) * (y.ndim - 1)
    s, h = s.reshape(shape), h.reshape(shape)
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s  # Hermite basis on [0, 1]
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    return h00 * y[k] + h10 * h * dy[k] + h01 * y[k + 1] + h11 * h * dy[k + 1]


def interp_linear(t: np.ndarray, y: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Linear interpolation of `y` at `tq` along axis 0 (exact at the nodes)."""
    k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    w = ((tq - t[k]) / (t[k + 1] - t[k])).reshape((-1,) + (1,) * (y.ndim - 1))
    return (1 - w) * y[k] + w * y[k + 1]
