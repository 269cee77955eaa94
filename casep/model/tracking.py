"""Symbolic tracking-system error model: declare -> ``setup()`` -> locked, one station's terms.

A :class:`TrackingModel` is the sibling of :class:`casep.model.ErrorModel` for the errors of a
radar station. The instrument model describes how the *platform* errs (its outputs are rates and
accelerations that S_V integrates); a tracking model describes how a *station's measurement*
errs, as a function of the measured geometry of that station at the same instant, so it has
other inputs and other outputs and is a class of its own, with the same life cycle, units and
error style:

- inputs (CasADi ``SX`` scalars, SI): :attr:`range` rho (m), :attr:`azimuth` A (rad, from
  north, clockwise), :attr:`elevation` E (rad, above the local horizon), their rates
  :attr:`range_rate`, :attr:`azimuth_rate`, :attr:`elevation_rate` (m/s, rad/s),
  :attr:`range_acceleration` (m/s^2), the
  station-ENU position of the target :attr:`enu` (m, 3 x 1) and :attr:`t` (s since the station's
  first sample);
- outputs (measured minus true, SI): :meth:`set_range_error` (m), :meth:`set_azimuth_error`,
  :meth:`set_elevation_error` (rad) and :meth:`set_range_rate_error` (m/s).

Every output must be linear in the coefficients with no coefficient-free term, so the error of
one station's measurements is ``T(geometry) theta`` with ``T`` (4 x n, rows range, azimuth,
elevation, range rate) derived exactly by CasADi at :meth:`TrackingModel.setup`. Coefficients are
valued in natural units (m, ppm, arcsec, ms, ...; :data:`casep.units.UNITS`) as in the
instrument models. In a separation every station has its own copy of the coefficients, named
``<station>.<term>`` (``S1.range_bias``).

Model files hold one ``build()`` returning a TrackingModel (``models/radar_biases.py``); they are
found like instrument model files (:mod:`casep.model.loader`) and loaded by
:func:`load_tracking_model`.
"""

from __future__ import annotations

import os

import casadi as ca
import numpy as np

from casep.model.base import SymbolicModel

__all__ = ["TrackingModel", "TRACKING_OUTPUTS", "GEOMETRY", "load_tracking_model", "build_tracking_model"]

#: Output slots: name -> SI unit. Rows of T in this order.
TRACKING_OUTPUTS: dict[str, str] = {"range": "m", "azimuth": "rad", "elevation": "rad", "range_rate": "m/s"}
#: Geometry inputs of the per-sample function, in order: name -> SI unit.
GEOMETRY: dict[str, str] = {"range": "m", "azimuth": "rad", "elevation": "rad", "range_rate": "m/s",
                            "azimuth_rate": "rad/s", "elevation_rate": "rad/s", "range_acceleration": "m/s^2",
                            "east": "m", "north": "m", "up": "m", "t": "s"}
# Deterministic geometry probes (SI, GEOMETRY order) used to look for coefficient-free terms.
_PROBES = np.array([[3.1e5, 0.7, 0.3, 1.2e3, 1e-3, -2e-3, 31.0, 1.9e5, 2.3e5, 9.1e4, 12.0],
                    [8.0e4, -2.1, 1.1, -3.0e2, -4e-3, 5e-3, -7.5, -6.0e4, 3.5e4, 3.9e4, 77.0],
                    [1.5e6, 3.0, 0.05, 2.5e3, 2e-4, 1e-4, 12.0, 1.0e5, -1.4e6, 1.2e5, 150.0]])


def _geometry(key: str, doc: str) -> property:
    """A read-only property returning the geometry input symbol `key`."""
    return property(lambda self: self._geo[key], doc=doc)


class TrackingModel(SymbolicModel):
    """Error model of one tracking station's measurements, declared with CasADi symbols.

    Parameters
    ----------
    name : str
        Model name (e.g. ``"radar_biases"``).
    description : str, optional

    Examples
    --------
    >>> m = TrackingModel("toy")
    >>> c = m.declare(range_bias="m")
    >>> m.set_range_error(c.range_bias)
    >>> m.setup().names
    ('range_bias',)
    """

    PUBLIC_NAME = "casep.TrackingModel"
    KIND = "tracking model"
    SLOTS = tuple(TRACKING_OUTPUTS)
    ROWS = 1
    DECLARE_USE = "model.declare(range_bias='m', ...)"
    OUTPUTS_USE = "model.set_range_error(...) and/or the azimuth/elevation ones"

    def __init__(self, name: str, description: str = "") -> None:
        super().__init__(name, description)
        self._geo = {k: ca.SX.sym(k) for k in GEOMETRY}
        self._jac: ca.Function | None = None
        self._err: ca.Function | None = None

    # ------------------------------------------------------------ geometry symbols (CasADi SX scalars, SI)
    range = _geometry("range", "Range rho from the station to the target, m.")
    azimuth = _geometry("azimuth", "Azimuth A, rad from north, clockwise (towards east).")
    elevation = _geometry("elevation", "Elevation E above the local horizon (plane normal to the WGS84 normal), rad.")
    range_rate = _geometry("range_rate", "d rho / dt, m/s.")
    azimuth_rate = _geometry("azimuth_rate", "dA/dt, rad/s.")
    elevation_rate = _geometry("elevation_rate", "dE/dt, rad/s.")
    range_acceleration = _geometry("range_acceleration",
                                   "d^2 rho / dt^2, m/s^2 (from the telemetered kinematic acceleration).")

    @property
    def enu(self) -> ca.SX:
        """Target position in the station's east-north-up axes, m (3 x 1)."""
        return ca.vertcat(self._geo["east"], self._geo["north"], self._geo["up"])

    t = _geometry("t", "Time since the station's first sample, s.")

    # ------------------------------------------------------------------ declare
    def set_range_error(self, expr) -> None:
        """Measured minus true range, m (scalar)."""
        self._set_output("range", expr)

    def set_azimuth_error(self, expr) -> None:
        """Measured minus true azimuth, rad (scalar)."""
        self._set_output("azimuth", expr)

    def set_elevation_error(self, expr) -> None:
        """Measured minus true elevation, rad (scalar)."""
        self._set_output("elevation", expr)

    def set_range_rate_error(self, expr) -> None:
        """Measured minus true range rate, m/s (scalar)."""
        self._set_output("range_rate", expr)

    def _label(self, slot: str) -> str:
        return f"`{slot}` error"

    # ------------------------------------------------------------------ setup
    def setup(self) -> "TrackingModel":
        """Check the declarations, derive ``T = d(error)/d theta`` exactly and lock the model.

        Raises
        ------
        ModelDefinitionError
            Naming what is missing, the output that is not linear in the coefficients or has a
            coefficient-free term, a foreign symbol, or an unused coefficient.
        """
        return super().setup()

    def _build(self, present: dict[str, ca.SX]) -> None:
        theta = ca.vertcat(*self._symbols)
        geo = ca.vertcat(*self._geo.values())
        everything = ca.vertcat(*present.values())
        for slot, expr in present.items():
            self._check_foreign(slot, expr, list(self._geo.values()), "the coefficients and the geometry "
                                "(model.range, .azimuth, .elevation, their rates, .enu, .t)")
        self._check_used(lambda s: bool(ca.depends_on(everything, s)),
                         use="add them to an error expression or remove them")
        out = ca.vertcat(*(self.output(s) for s in TRACKING_OUTPUTS))  # 4 x 1
        J = ca.jacobian(out, theta)  # exact d(error)/d theta, 4 x n, per natural unit
        rows = [f"`{s}` error" for s in TRACKING_OUTPUTS]
        self._check_linear(J, theta, rows)
        offset = ca.Function("offset", [geo], [ca.substitute(out, theta, ca.SX.zeros(theta.shape))])
        for probe in _PROBES:
            self._check_offset(np.array(offset(probe)), rows, f"range {probe[0]:g} m")
        self._jac = ca.Function("T", [geo], [ca.densify(J)], ["geometry"], ["T"])
        self._err = ca.Function("errors", [geo, theta], [out], ["geometry", "theta"], ["errors"])

    # ------------------------------------------------------------------ after setup
    @property
    def outputs(self) -> tuple[str, ...]:
        """Output slots the model sets."""
        return tuple(k for k, v in self._outputs.items() if v is not None)

    def jacobian(self, geometry: np.ndarray) -> np.ndarray:
        """``T`` at each sample: ``(N, 4, n)``, rows range (m), azimuth, elevation (rad), range rate (m/s).

        Parameters
        ----------
        geometry : (N, 11) array_like
            Columns in :data:`GEOMETRY` order (SI).
        """
        self._require_setup()
        g = np.atleast_2d(np.asarray(geometry, dtype=float))
        if g.ndim != 2 or g.shape[1] != len(GEOMETRY):
            raise ValueError(f"`geometry` must be (N, {len(GEOMETRY)}) ({', '.join(GEOMETRY)}), got {g.shape}")
        n = self.n_coefficients
        if g.shape[0] == 0:
            return np.zeros((0, 4, n))
        assert self._jac is not None  # built by setup()
        T = np.asarray(self._jac(g.T))  # (4, n N): one 4 x n block per sample, side by side
        return T.reshape(4, g.shape[0], n).transpose(1, 0, 2)

    def errors(self, geometry: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The error expressions themselves at each sample, ``(N, 4)`` SI (theta in natural units).

        Evaluated from the declared expressions, not from ``T``: what the finite-difference check
        of :meth:`jacobian` compares against.
        """
        self._require_setup()
        g = np.atleast_2d(np.asarray(geometry, dtype=float))
        th = np.asarray(theta, dtype=float).reshape(-1)
        if th.size != self.n_coefficients:
            raise ValueError(f"`theta` must have {self.n_coefficients} values, got {th.size}")
        assert self._err is not None  # built by setup()
        return np.asarray(self._err(g.T, th)).T


def build_tracking_model(model: str | os.PathLike) -> TrackingModel:
    """Run a tracking-model file's ``build()`` and return the model *unlocked* (to extend it)."""
    from casep.model.loader import find_model_file, run_model_file

    return run_model_file(find_model_file(model), TrackingModel)


def load_tracking_model(model: "str | os.PathLike | TrackingModel") -> TrackingModel:
    """A tracking model by name (``"radar_biases"``), model file or object, set up.

    Found like the instrument models (:func:`casep.model.loader.find_model_file`).
    """
    from casep.model.loader import find_model_file, load_model_file

    if isinstance(model, TrackingModel):
        return model.setup()
    return load_model_file(find_model_file(model), TrackingModel)
