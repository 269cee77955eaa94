"""The parametrised attitude manoeuvre of ``casep design``.

A manoeuvre is a piecewise-linear attitude offset, pitch and/or yaw (deg), on a coarse grid of
knots over the powered flight, added to the scenario's attitude laws (the simulator's
:class:`casep.simulation.trajectory.AttitudeProfile`). The first knot is held at zero, so the
flight leaves the nominal attitude continuously there (before it: the nominal flight); after the
last knot (burnout) nothing is flown. The design variables are the offsets at the other knots.

Constraints (all on the offsets, i.e. relative to the nominal attitude):

- angle: ``|offset| <= max_angle`` at every knot (so everywhere: the offset is linear between knots);
- rate: ``|offset_{i+1} - offset_i| / (t_{i+1} - t_i) <= max_rate`` (the offset rate on each segment);
- lateral acceleration: the body axis turned by the offset through the angle ``gamma`` from the
  nominal one, the thrust and drag acceleration ``|f|`` gains a component ``|f| sin gamma``
  across the nominal body axis: ``|f| sin gamma <= max_lateral`` (g). Imposed conservatively on the
  knots (:func:`casep.design.optimize.knot_angle_limits`): each knot's offset size
  ``sqrt(d_pitch^2 + d_yaw^2)`` at most ``asin(max_lateral / max |f|)`` over its two segments, which bounds
  ``gamma`` everywhere on them (a box on the knot for one axis, a disc for both). At low ``|f|`` it
  does not bind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casep.simulation.trajectory import AttitudeProfile

__all__ = ["Maneuver", "AXES_OF", "interpolation_matrix"]

#: ``--maneuver`` choice -> attitude axes it moves.
AXES_OF = {"yaw": ("yaw",), "pitch": ("pitch",), "both": ("pitch", "yaw")}


def interpolation_matrix(knots: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``(len(t), len(knots))`` matrix B with ``offset(t) = B @ offset_at_knots`` (linear between
    knots, the first/last knot's value outside)."""
    knots, t = np.asarray(knots, dtype=float), np.asarray(t, dtype=float)
    B = np.zeros((t.size, knots.size))
    tc = np.clip(t, knots[0], knots[-1])
    i = np.clip(np.searchsorted(knots, tc, side="right") - 1, 0, knots.size - 2)
    u = (tc - knots[i]) / (knots[i + 1] - knots[i])
    rows = np.arange(t.size)
    B[rows, i] = 1.0 - u
    B[rows, i + 1] += u
    return B


@dataclass(frozen=True)
class Maneuver:
    """Knot layout of a designed manoeuvre.

    Parameters
    ----------
    kind : {"yaw", "pitch", "both"}
    knots : (m,) array_like
        Knot times, s, strictly increasing; the offset is held at zero at the first one.
    """

    kind: str
    knots: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.kind not in AXES_OF:
            raise ValueError(f"unknown maneuver `{self.kind}`: use one of {', '.join(AXES_OF)}")
        k = np.asarray(self.knots, dtype=float)
        if k.ndim != 1 or k.size < 2 or not np.all(np.isfinite(k)) or np.any(np.diff(k) <= 0):
            raise ValueError(f"`knots` must be two or more finite, strictly increasing times, got {self.knots!r}")
        object.__setattr__(self, "knots", tuple(float(x) for x in k))

    @property
    def axes(self) -> tuple[str, ...]:
        return AXES_OF[self.kind]

    @property
    def n_free(self) -> int:
        """Free knots per axis (all but the first, held at zero)."""
        return len(self.knots) - 1

    @property
    def n_variables(self) -> int:
        return self.n_free * len(self.axes)

    def split(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Design vector (deg) -> ``{"pitch": (m,), "yaw": (m,)}`` offsets at all knots (zeros for an axis not
        moved)."""
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.size != self.n_variables:
            raise ValueError(f"design vector must have {self.n_variables} values, got {x.size}")
        out = {"pitch": np.zeros(len(self.knots)), "yaw": np.zeros(len(self.knots))}
        for a, axis in enumerate(self.axes):
            out[axis][1:] = x[a * self.n_free:(a + 1) * self.n_free]
        return out

    def profile(self, x: np.ndarray, base_times=None, base_pitch=None) -> AttitudeProfile:
        """The simulator's attitude offsets for design vector `x` (deg); with the nominal flight's pitch
        (`base_times` s, `base_pitch` rad) flown open loop from the first knot on (see
        :class:`~casep.simulation.trajectory.AttitudeProfile`)."""
        s = self.split(x)
        return AttitudeProfile(times=self.knots, pitch=tuple(s["pitch"]), yaw=tuple(s["yaw"]),
                               base_times=None if base_times is None else tuple(base_times),
                               base_pitch=None if base_pitch is None else tuple(base_pitch))

    def rate_matrix(self) -> np.ndarray:
        """``(len(axes) * n_free, n_variables)``: offset rate (deg/s) on each segment, per axis."""
        h = np.diff(self.knots)
        m = self.n_free
        D = np.zeros((m, m))
        D[np.arange(m), np.arange(m)] = 1.0 / h
        D[np.arange(1, m), np.arange(m - 1)] = -1.0 / h[1:]  # first segment starts from the fixed zero
        out = np.zeros((m * len(self.axes), self.n_variables))
        for a in range(len(self.axes)):
            out[a * m:(a + 1) * m, a * m:(a + 1) * m] = D
        return out

    def to_dict(self, x: np.ndarray) -> dict:
        s = self.split(x)
        rates = {axis: (np.diff(s[axis]) / np.diff(self.knots)).tolist() for axis in ("pitch", "yaw")}
        return {"kind": self.kind, "parametrisation": "piecewise-linear offset added to the nominal attitude, "
                "zero at the first knot, held after the last",
                "knots_s": list(self.knots), "pitch_deg": s["pitch"].tolist(), "yaw_deg": s["yaw"].tolist(),
                "rate_pitch_deg_s": rates["pitch"], "rate_yaw_deg_s": rates["yaw"]}
