"""Ground-test error models: declare -> ``setup()`` -> locked, as the flight models.

A :class:`CalibrationModel` is the sibling of :class:`casep.ErrorModel` for a ground test. It
declares coefficients exactly as a flight model does (the declaration machinery of both is
:class:`casep.model.base.SymbolicModel`: names, natural units, SI factors, typical
magnitudes and the "did you mean" messages are the same), but its outputs are the *readings* of
the two sensor triads on a test stand rather than the flight's drift rate and velocity error:

=================== ================================================================
output              meaning
=================== ================================================================
``accel_reading``   accelerometer triad reading y_a(f, omega, D), 3 x 1
``gyro_reading``    gyro triad reading y_g(f, omega, D), 3 x 1
=================== ================================================================

Inputs of the equations: the specific force in the sensor frame :attr:`f` (m/s^2; :attr:`W` =
f / g0 in g) and the angular rate in the sensor frame :attr:`omega` (rad/s). Each output is
``y = y0(f, omega) + J(f, omega) D``: :meth:`setup` splits it exactly (CasADi) into the known
part ``y0`` (an ideal sensor: ``f`` for an accelerometer read in m/s^2, 0 for raw counts) and the
Jacobian ``J`` per natural unit, and checks that

- every output is linear in the coefficients (``J`` does not depend on ``D``);
- every output is affine in ``omega`` (a rotation segment knows only the angle, the integral of
  omega, so only terms linear in omega can be integrated exactly);
- every declared coefficient appears in exactly one output (the accelerometer and the gyro
  are estimated as two regressions, each with its own noise level).

``readings="raw"`` models take the session's columns as they are (any unit: the coefficients
carry it); ``readings="si"`` models take readings converted to m/s^2 and rad/s (the session
states its units). ``flight_model`` names the flight model whose coefficients this model shares
(same names, same units): a ground result of it is a flight prior without re-typing.
"""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import casadi as ca
import numpy as np

from casep.model.base import AXES, ModelDefinitionError, SpecificForceModel
from casep.model.error_model import ErrorModel

__all__ = ["CalibrationModel", "READINGS", "SLOTS", "calibration_model_dirs", "calibration_models",
           "load_calibration_model"]

#: Output slots: name -> the sensor triad.
SLOTS = {"accel_reading": "accelerometer", "gyro_reading": "gyro"}
#: What a model expects of the readings.
READINGS = ("raw", "si")
# Deterministic probes (specific force m/s^2, angular rate rad/s) for the affine-in-omega check.
_F_PROBES = np.array([[0.0, 0.0, 9.8], [3.1, -7.7, 2.2], [-9.81, 0.4, -1.3]])
_W_PROBES = np.array([[0.0, 0.0, 0.0], [0.7, -1.9, 3.3], [-5.2, 0.1, 2.4]])


class CalibrationModel(SpecificForceModel):
    """Error model of a ground calibration test (see the module notes).

    Parameters
    ----------
    name, description : str
        As :class:`casep.ErrorModel` (e.g. ``"ferraris"``).
    readings : {"raw", "si"}
        ``"raw"``: the session's columns as recorded, in any unit; ``"si"``: readings in m/s^2 and
        rad/s (converted from the units the session states).
    flight_model : str, optional
        The flight model whose coefficient names and units this model's shared coefficients carry.

    Examples
    --------
    A gyro triad with a bias on x, reading rad/s:

    >>> m = CalibrationModel("toy", readings="si")
    >>> c = m.declare(Kg0x="deg/h")
    >>> w = m.omega
    >>> m.set_gyro_reading([w[0] + c.Kg0x, w[1], w[2]])
    >>> m.setup().slots
    ('gyro_reading',)
    """

    PUBLIC_NAME = "casep.calibration.CalibrationModel"
    SLOTS = tuple(SLOTS)
    DECLARE_USE = "model.declare(Ka0x='mg', ...) or model.coefficient(name, unit)"
    OUTPUTS_WHAT = "sensor readings"
    OUTPUTS_USE = "model.set_accel_reading(...) and/or model.set_gyro_reading(...)"

    def __init__(self, name: str, description: str = "", *, readings: str = "raw",
                 flight_model: str | None = None) -> None:
        if readings not in READINGS:
            raise ValueError(f"`readings` must be one of {', '.join(READINGS)}, got {readings!r}")
        super().__init__(name, description)
        self.readings = readings
        self.flight_model = flight_model
        self._omega = ca.SX.sym("omega", 3)  # angular rate, sensor frame, rad/s
        self._functions: dict[str, ca.Function] = {}
        self._columns: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------------ declare
    @property
    def omega(self) -> ca.SX:
        """Angular rate of the sensor frame, 3 x 1, rad/s."""
        return self._omega

    def coefficient(self, name: str, unit: str, *, per_flight: bool = False, **kw: Any) -> ca.SX:
        """Declare one coefficient (as :meth:`casep.ErrorModel.coefficient`); returns ``symbol * si_factor``."""
        self._check_unlocked()
        if per_flight:
            raise ValueError(f"`{name}`: a ground test has no flights (per_flight is a flight-model option)")
        return super().coefficient(name, unit, **kw)

    def declare(self, **units: Any) -> SimpleNamespace:
        """Declare several coefficients, ``Name="unit"`` or ``Name=("unit", scale)`` (as
        :meth:`casep.ErrorModel.declare`)."""
        self._check_unlocked()
        if "per_flight" in units:
            raise ValueError("a ground test has no flights (per_flight is a flight-model option)")
        return super().declare(**units)

    def set_accel_reading(self, expr) -> None:
        """Set the accelerometer triad reading y_a(f, omega, D), 3 x 1."""
        self._set_output("accel_reading", expr)

    def set_gyro_reading(self, expr) -> None:
        """Set the gyro triad reading y_g(f, omega, D), 3 x 1."""
        self._set_output("gyro_reading", expr)

    def flight_output(self, flight: ErrorModel, slot: str) -> ca.SX:
        """Output `slot` of a flight model (``"gyro_drift"`` or ``"accel_error"``) in this model's symbols.

        Every coefficient the flight output uses must be declared here under the same name and
        unit (so the ground result carries the flight model's names and units); the flight's
        specific force becomes the stand's :attr:`f`. The equations are the flight model's own,
        not re-typed.
        """
        self._check_unlocked()
        if slot not in ("gyro_drift", "accel_error"):
            raise ValueError(f"`slot` must be gyro_drift or accel_error, got {slot!r}")
        expr = flight.output(slot)
        fl = flight.symbols
        ours = []
        for name, unit, s in zip(flight.names, flight.units, fl):
            if not ca.depends_on(expr, s):
                ours.append(s)  # not in this output: left as it is (substituted by itself)
                continue
            if name not in self.names:
                raise ModelDefinitionError(f"model `{self.name}`: Missing: `{name}` ({unit}) of flight model "
                                           f"`{flight.name}`. Use: model.coefficient({name!r}, {unit!r})")
            j = self.names.index(name)
            if self.units[j] != unit:
                raise ModelDefinitionError(f"model `{self.name}`: `{name}` is declared in {self.units[j]}, flight "
                                           f"model `{flight.name}` has it in {unit}. Use: the flight model's unit")
            ours.append(self._symbols[j])
        return ca.substitute(expr, ca.vertcat(*fl, flight.f), ca.vertcat(*ours, self.f))

    # ------------------------------------------------------------------- setup
    def setup(self) -> "CalibrationModel":
        """Check the declarations, split each output into known part and Jacobian, lock the model.

        Raises
        ------
        ModelDefinitionError
            Naming what is missing, a term not linear in the coefficients, a term not affine in
            omega, a foreign symbol, a coefficient used in no output or in both.
        """
        return super().setup()

    def _build(self, present: dict[str, ca.SX]) -> None:
        D = ca.vertcat(*self._symbols)
        f, w = self._f, self._omega
        inputs = [f[i] for i in range(3)] + [w[i] for i in range(3)]
        used_by: dict[str, list[int]] = {}
        for slot, expr in present.items():
            self._check_foreign(slot, expr, inputs, "the coefficients, model.f / model.W and model.omega")
            J = ca.jacobian(expr, D)  # exact d reading / dD, 3 x n, per natural unit
            self._check_linear(J, D, [f"`{slot}` component {a}" for a in AXES])
            y0 = ca.substitute(expr, D, ca.SX.zeros(D.shape))  # the known part (ideal sensor)
            self._check_affine_in_omega(slot, expr, D)
            cols = sorted(set(J.sparsity().get_col()))
            for j in cols:
                used_by.setdefault(self._names[j], []).append(0 if slot == "accel_reading" else 1)
            self._functions[f"{slot}_known"] = ca.Function(f"{slot}_known", [f, w], [y0], ["f", "omega"], ["y0"])
            self._functions[f"{slot}_jacobian"] = ca.Function(f"{slot}_jacobian", [f, w], [ca.densify(J)],
                                                              ["f", "omega"], ["J"])
            # d reading / d f (3 x 3): how a wrong specific force (a tilted position) moves the reading
            self._functions[f"{slot}_df"] = ca.Function(f"{slot}_df", [f, w, D], [ca.densify(ca.jacobian(expr, f))],
                                                        ["f", "omega", "D"], ["dy_df"])
            self._columns[slot] = np.asarray(cols, dtype=np.intp)
        # a coefficient's symbol carries its name
        self._check_used(lambda sym: bool(sym.name() in used_by), where="reading")
        both = [nm for nm, v in used_by.items() if len(set(v)) > 1]
        if both:
            raise ModelDefinitionError(
                f"model `{self.name}`: coefficient(s) {', '.join(f'`{b}`' for b in both)} appear in both the "
                "accelerometer and the gyro readings. Use: a coefficient per sensor (each triad is its own "
                "regression with its own noise level)")

    def _check_affine_in_omega(self, slot: str, expr: ca.SX, D: ca.SX) -> None:
        """`expr` is affine in omega: its Jacobian with respect to omega is the same at every probe rate
        (the second derivative vanishes; checked numerically at probe points)."""
        dW = ca.jacobian(expr, self._omega)
        fun = ca.Function("dW", [self._f, self._omega, D], [dW])
        rng = np.random.default_rng(20261124)
        Dp = rng.uniform(-1.0, 1.0, D.shape[0])
        for fp in _F_PROBES:
            ref = np.array(fun(fp, _W_PROBES[0], Dp))
            for wp in _W_PROBES[1:]:
                if not np.allclose(np.array(fun(fp, wp, Dp)), ref, rtol=1e-12, atol=1e-12):
                    raise ModelDefinitionError(
                        f"model `{self.name}`: `{slot}` is not affine in model.omega (a term in omega^2 or "
                        "omega times a coefficient's own omega-dependence). Use: terms linear in omega only "
                        "(a rotation segment determines only the integral of omega, the angle)")

    # ------------------------------------------------------------- after setup
    @property
    def slots(self) -> tuple[str, ...]:
        """The outputs the model sets, in :data:`SLOTS` order (known after setup)."""
        self._require_setup()
        return tuple(s for s in SLOTS if s in self._columns)

    def columns(self, slot: str) -> np.ndarray:
        """Indices (model order) of the coefficients in output `slot` (copy)."""
        self._require_setup()
        if slot not in self._columns:
            raise KeyError(f"model `{self.name}` sets no `{slot}`; it sets {', '.join(self._columns)}")
        return self._columns[slot].copy()

    @property
    def functions(self) -> dict:
        """``<slot>_known(f, omega)`` (the reading of an ideal sensor), ``<slot>_jacobian(f, omega)``
        (3 x n, per natural unit) and ``<slot>_df(f, omega, D)`` (3 x 3) for each output set."""
        self._require_setup()
        return dict(self._functions)

    def known(self, slot: str, f: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """The known part y0 of `slot` at specific force `f` (m/s^2) and rate `omega` (rad/s), (3,)."""
        return np.array(self.functions[f"{slot}_known"](f, omega)).ravel()

    def jacobian(self, slot: str, f: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """d reading / dD of `slot` at `f` (m/s^2) and `omega` (rad/s), (3, n) per natural unit."""
        return np.array(self.functions[f"{slot}_jacobian"](f, omega)).reshape(3, self.n_coefficients)

    def reading_df(self, slot: str, f: np.ndarray, omega: np.ndarray, D: np.ndarray) -> np.ndarray:
        """d reading / d f of `slot` at `f`, `omega` and coefficients `D` (natural units), (3, 3)."""
        return np.array(self.functions[f"{slot}_df"](f, omega, D)).reshape(3, 3)

    def __repr__(self) -> str:
        return (f"CalibrationModel({self.name!r}, {self.n_coefficients} coefficients, readings {self.readings}, "
                f"{'set up' if self._locked else 'declaring'})")



# ------------------------------------------------------------------ model files
def calibration_model_dirs() -> list[Path]:
    """Folders searched for a calibration model by name: ``calibration/`` under each model folder."""
    from casep.model.loader import model_dirs

    return [d / "calibration" for d in model_dirs() if (d / "calibration").is_dir()]


def calibration_models() -> list[str]:
    """Names of the calibration models found (``ferraris``, ``platform36_ground``, ...)."""
    from casep.model.loader import model_names

    return model_names(calibration_model_dirs())


def load_calibration_model(model: str | os.PathLike | CalibrationModel) -> CalibrationModel:
    """A calibration model by name (``models/calibration/NAME.py``), path or object, set up.

    Model files are loaded as the flight models' (:func:`casep.model.loader.run_model_file`: one
    ``build()``, errors of one line naming the file and the line).
    """
    from casep.model.loader import find_model_file, load_model_file

    if isinstance(model, CalibrationModel):
        return model.setup()
    path = find_model_file(model, calibration_model_dirs(), what="calibration model",
                           use="a path to a .py file whose build() returns a casep.calibration.CalibrationModel")
    return load_model_file(path, CalibrationModel)
