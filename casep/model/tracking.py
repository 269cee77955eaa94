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

import keyword
import os
import re
from types import SimpleNamespace

import casadi as ca
import numpy as np

from casep.model._model import ModelDefinitionError
from casep.units import si_factor as _unit_si_factor

__all__ = ["TrackingModel", "TRACKING_OUTPUTS", "GEOMETRY", "load_tracking_model", "build_tracking_model"]

#: Output slots: name -> SI unit. Rows of T in this order.
TRACKING_OUTPUTS: dict[str, str] = {"range": "m", "azimuth": "rad", "elevation": "rad", "range_rate": "m/s"}
#: Geometry inputs of the per-sample function, in order: name -> SI unit.
GEOMETRY: dict[str, str] = {"range": "m", "azimuth": "rad", "elevation": "rad", "range_rate": "m/s",
                            "azimuth_rate": "rad/s", "elevation_rate": "rad/s", "range_acceleration": "m/s^2",
                            "east": "m", "north": "m", "up": "m", "t": "s"}
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
# Deterministic geometry probes (SI, GEOMETRY order) used to look for coefficient-free terms.
_PROBES = np.array([[3.1e5, 0.7, 0.3, 1.2e3, 1e-3, -2e-3, 31.0, 1.9e5, 2.3e5, 9.1e4, 12.0],
                    [8.0e4, -2.1, 1.1, -3.0e2, -4e-3, 5e-3, -7.5, -6.0e4, 3.5e4, 3.9e4, 77.0],
                    [1.5e6, 3.0, 0.05, 2.5e3, 2e-4, 1e-4, 12.0, 1.0e5, -1.4e6, 1.2e5, 150.0]])


class TrackingModel:
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

    def __init__(self, name: str, description: str = "") -> None:
        if not isinstance(name, str) or not name.strip():
            raise TypeError("`name` must be a non-empty str")
        if not isinstance(description, str):
            raise TypeError("`description` must be a str")
        self.name = name
        self.description = description
        self._geo = {k: ca.SX.sym(k) for k in GEOMETRY}
        self._names: list[str] = []
        self._units: list[str] = []
        self._factors: list[float] = []
        self._descriptions: list[str] = []
        self._scales: dict[str, float | None] = {}
        self._symbols: list[ca.SX] = []
        self._outputs: dict[str, ca.SX | None] = dict.fromkeys(TRACKING_OUTPUTS)
        self._locked = False
        self._jac: ca.Function | None = None
        self._err: ca.Function | None = None

    # ------------------------------------------------------------------ geometry symbols
    @property
    def range(self) -> ca.SX:
        """Range rho from the station to the target, m."""
        return self._geo["range"]

    @property
    def azimuth(self) -> ca.SX:
        """Azimuth A, rad from north, clockwise (towards east)."""
        return self._geo["azimuth"]

    @property
    def elevation(self) -> ca.SX:
        """Elevation E above the local horizon (plane normal to the WGS84 normal), rad."""
        return self._geo["elevation"]

    @property
    def range_rate(self) -> ca.SX:
        """d rho / dt, m/s."""
        return self._geo["range_rate"]

    @property
    def azimuth_rate(self) -> ca.SX:
        """dA/dt, rad/s."""
        return self._geo["azimuth_rate"]

    @property
    def elevation_rate(self) -> ca.SX:
        """dE/dt, rad/s."""
        return self._geo["elevation_rate"]

    @property
    def range_acceleration(self) -> ca.SX:
        """d^2 rho / dt^2, m/s^2 (from the telemetered kinematic acceleration)."""
        return self._geo["range_acceleration"]

    @property
    def enu(self) -> ca.SX:
        """Target position in the station's east-north-up axes, m (3 x 1)."""
        return ca.vertcat(self._geo["east"], self._geo["north"], self._geo["up"])

    @property
    def t(self) -> ca.SX:
        """Time since the station's first sample, s."""
        return self._geo["t"]

    # ------------------------------------------------------------------ declare
    def coefficient(self, name: str, unit: str, *, si_factor: float | None = None, description: str = "",
                    scale: float | None = None) -> ca.SX:
        """Declare one error coefficient and return its SI-valued expression (``symbol * si_factor``).

        Parameters as :meth:`casep.ErrorModel.coefficient` (`unit` a key of
        :data:`casep.units.UNITS`, or give `si_factor`; `scale` a typical magnitude, natural unit).
        """
        self._check_unlocked()
        if not isinstance(name, str) or not _NAME_RE.match(name) or keyword.iskeyword(name):
            raise ValueError(f"coefficient name {name!r} is not a valid identifier")
        if name in self._names:
            raise ValueError(f"coefficient `{name}` is declared twice in tracking model `{self.name}`")
        if not isinstance(unit, str):
            raise TypeError(f"`unit` of `{name}` must be a str")
        if si_factor is None:
            factor = _unit_si_factor(unit)
        else:
            factor = float(si_factor)
            if not np.isfinite(factor) or factor <= 0.0:
                raise ValueError(f"`si_factor` of `{name}` must be finite and > 0, got {si_factor}")
        if scale is not None and (isinstance(scale, bool) or not isinstance(scale, (int, float))
                                  or not np.isfinite(scale) or scale <= 0):
            raise ValueError(f"`scale` of `{name}` must be a finite number > 0, got {scale!r}")
        sym = ca.SX.sym(name)  # valued in the natural unit
        self._names.append(name)
        self._units.append(unit)
        self._factors.append(factor)
        self._descriptions.append(description)
        self._scales[name] = None if scale is None else float(scale)
        self._symbols.append(sym)
        return sym * factor

    def declare(self, **units: str | tuple[str, float]) -> SimpleNamespace:
        """Declare several coefficients: ``Name="unit"`` or ``Name=("unit", scale)``, in order."""
        def one(name, spec):
            if isinstance(spec, tuple):
                if len(spec) != 2:
                    raise ValueError(f"`{name}` must be \"unit\" or (\"unit\", scale), got {spec!r}")
                return self.coefficient(name, spec[0], scale=spec[1])
            return self.coefficient(name, spec)

        return SimpleNamespace(**{n: one(n, u) for n, u in units.items()})

    def set_range_error(self, expr) -> None:
        """Measured minus true range, m (scalar)."""
        self._set("range", expr)

    def set_azimuth_error(self, expr) -> None:
        """Measured minus true azimuth, rad (scalar)."""
        self._set("azimuth", expr)

    def set_elevation_error(self, expr) -> None:
        """Measured minus true elevation, rad (scalar)."""
        self._set("elevation", expr)

    def set_range_rate_error(self, expr) -> None:
        """Measured minus true range rate, m/s (scalar)."""
        self._set("range_rate", expr)

    def output(self, slot: str) -> ca.SX:
        """Current expression of an output slot (0 if unset), e.g. to add a term to it."""
        if slot not in TRACKING_OUTPUTS:
            raise ValueError(f"unknown output `{slot}`; use one of {', '.join(TRACKING_OUTPUTS)}")
        expr = self._outputs[slot]
        return ca.SX(0) if expr is None else expr

    def _set(self, slot: str, expr) -> None:
        self._check_unlocked()
        if isinstance(expr, (int, float)) and not isinstance(expr, bool):
            expr = ca.SX(expr)
        if not isinstance(expr, (ca.SX, ca.DM)):
            raise TypeError(f"`{slot}` error must be a scalar casadi.SX expression, got {type(expr).__name__}")
        expr = ca.SX(expr)
        if expr.shape != (1, 1):
            raise ValueError(f"`{slot}` error must be a scalar, got {expr.shape[0]} x {expr.shape[1]}")
        self._outputs[slot] = expr

    def _check_unlocked(self) -> None:
        if self._locked:
            raise RuntimeError(f"tracking model `{self.name}` is locked after setup(). Use: declare every "
                               "coefficient and output before setup(), or build a new model")

    # ------------------------------------------------------------------ setup
    def setup(self) -> "TrackingModel":
        """Check the declarations, derive ``T = d(error)/d theta`` exactly and lock the model.

        Raises
        ------
        ModelDefinitionError
            Naming what is missing, the output that is not linear in the coefficients or has a
            coefficient-free term, a foreign symbol, or an unused coefficient.
        """
        if self._locked:
            return self
        if not self._names:
            raise ModelDefinitionError(f"tracking model `{self.name}`: Missing: error coefficients. "
                                       "Use: model.declare(range_bias='m', ...)")
        present = {k: v for k, v in self._outputs.items() if v is not None}
        if not present:
            raise ModelDefinitionError(f"tracking model `{self.name}`: Missing: error outputs. "
                                       "Use: model.set_range_error(...) and/or the azimuth/elevation ones")
        theta = ca.vertcat(*self._symbols)
        geo = ca.vertcat(*self._geo.values())
        everything = ca.vertcat(*present.values())
        allowed = list(self._symbols) + list(self._geo.values())
        for slot, expr in present.items():
            foreign = [s for s in ca.symvar(expr) if not any(ca.is_equal(s, a) for a in allowed)]
            if foreign:
                raise ModelDefinitionError(
                    f"tracking model `{self.name}`: `{slot}` error uses symbol(s) "
                    f"{', '.join(f'`{s.name()}`' for s in foreign)} that are not declared. Use: only the "
                    "coefficients and the geometry (model.range, .azimuth, .elevation, their rates, .enu, .t)")
        unused = [nm for nm, s in zip(self._names, self._symbols) if not ca.depends_on(everything, s)]
        if unused:
            raise ModelDefinitionError(f"tracking model `{self.name}`: coefficient(s) "
                                       f"{', '.join(f'`{u}`' for u in unused)} declared but used in no output. "
                                       "Use: add them to an error expression or remove them")
        out = ca.vertcat(*(self.output(s) for s in TRACKING_OUTPUTS))  # 4 x 1
        J = ca.jacobian(out, theta)  # exact d(error)/d theta, 4 x n, per natural unit
        for i, slot in enumerate(TRACKING_OUTPUTS):
            if ca.depends_on(J[i, :], theta):
                bad = [nm for nm, s in zip(self._names, self._symbols) if ca.depends_on(J[i, :], s)]
                raise ModelDefinitionError(
                    f"tracking model `{self.name}`: `{slot}` error is not linear in the coefficients (its "
                    f"derivative still depends on {', '.join(bad)}). Use: one coefficient per term")
        offset = ca.Function("offset", [geo], [ca.substitute(out, theta, ca.SX.zeros(theta.shape))])
        for probe in _PROBES:
            value = np.array(offset(probe)).ravel()
            if np.any(value != 0.0):
                i = int(np.flatnonzero(value)[0])
                raise ModelDefinitionError(
                    f"tracking model `{self.name}`: `{list(TRACKING_OUTPUTS)[i]}` error has a term without a "
                    f"coefficient (value {value[i]:.6g} at range {probe[0]:g} m). Use: multiply every term by "
                    "exactly one coefficient")
        self._jac = ca.Function("T", [geo], [ca.densify(J)], ["geometry"], ["T"])
        self._err = ca.Function("errors", [geo, theta], [out], ["geometry", "theta"], ["errors"])
        self._locked = True
        return self

    # ------------------------------------------------------------------ after setup
    def _require_setup(self) -> None:
        if not self._locked:
            raise RuntimeError(f"tracking model `{self.name}` is not set up. Use: model.setup()")

    @property
    def is_setup(self) -> bool:
        return self._locked

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._names)

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(self._units)

    @property
    def si_factors(self) -> np.ndarray:
        return np.asarray(self._factors, dtype=float)

    @property
    def n_coefficients(self) -> int:
        return len(self._names)

    @property
    def scales(self) -> dict[str, float]:
        """Declared typical magnitudes (natural units), where given."""
        return {k: v for k, v in self._scales.items() if v is not None}

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

    def __repr__(self) -> str:
        state = "set up" if self._locked else "open"
        return f"TrackingModel({self.name!r}, {self.n_coefficients} coefficients, {state})"


def build_tracking_model(model: str | os.PathLike) -> TrackingModel:
    """Run a tracking-model file's ``build()`` and return the model *unlocked* (to extend it)."""
    from casep.model.loader import find_model_file, run_model_file

    return run_model_file(find_model_file(model), TrackingModel)


def load_tracking_model(model: "str | os.PathLike | TrackingModel") -> TrackingModel:
    """A tracking model by name (``"radar_biases"``), model file or object, set up.

    Found like the instrument models (:func:`casep.model.loader.find_model_file`).
    """
    from casep.model.loader import ModelFileError, find_model_file, run_model_file

    if isinstance(model, TrackingModel):
        return model.setup()
    path = find_model_file(model)
    built = run_model_file(path, TrackingModel)
    try:
        return built.setup()
    except ModelDefinitionError as exc:
        raise ModelFileError(f"model file {path}: {exc}") from exc

