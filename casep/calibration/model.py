"""Ground-test error models: declare -> ``setup()`` -> locked, as the flight models.

A :class:`CalibrationModel` is the sibling of :class:`casep.ErrorModel` for a ground test. It
declares coefficients exactly as a flight model does (the declaration machinery is
:class:`casep.ErrorModel`'s own, held inside: names, natural units, SI factors, typical
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

import casadi as ca
import numpy as np

from casep.model._model import ErrorModel, ModelDefinitionError, unknown_coefficient_message

__all__ = ["CalibrationModel", "READINGS", "SLOTS"]

#: Output slots: name -> the sensor triad.
SLOTS = {"accel_reading": "accelerometer", "gyro_reading": "gyro"}
#: What a model expects of the readings.
READINGS = ("raw", "si")
_AXES = "xyz"
# Deterministic probes (specific force m/s^2, angular rate rad/s) for the affine-in-omega check.
_F_PROBES = np.array([[0.0, 0.0, 9.8], [3.1, -7.7, 2.2], [-9.81, 0.4, -1.3]])
_W_PROBES = np.array([[0.0, 0.0, 0.0], [0.7, -1.9, 3.3], [-5.2, 0.1, 2.4]])


class CalibrationModel:
    """Error model of a ground calibration test (see the module notes).

    Parameters
    ----------
    name : str
        Model name, reported in results (e.g. ``"ferraris"``).
    description : str, optional
        One line shown in reports.
    readings : {"raw", "si"}
        ``"raw"``: the session's columns as recorded, in any unit; ``"si"``: readings in m/s^2 and
        rad/s (converted from the units the session states).
    flight_model : str, optional
        The flight model whose coefficient names and units this model's shared coefficients carry.

    Examples
    --------
    >>> import casadi as ca
    >>> m = CalibrationModel("toy", readings="si")
    >>> c = m.declare(Ka0x="mg", Ka1x="mg/g")
    >>> m.set_accel_reading(m.f + ca.vertcat(c.Ka0x + c.Ka1x * m.W[0], 0, 0))
    >>> m.setup().names
    ('Ka0x', 'Ka1x')
    """

    def __init__(self, name: str, description: str = "", *, readings: str = "raw",
                 flight_model: str | None = None) -> None:
        if readings not in READINGS:
            raise ValueError(f"`readings` must be one of {', '.join(READINGS)}, got {readings!r}")
        self._decl = ErrorModel(name, description)  # the declaration machinery of the flight models
        self.readings = readings
        self.flight_model = flight_model
        self._omega = ca.SX.sym("omega", 3)  # angular rate, sensor frame, rad/s
        self._outputs: dict[str, ca.SX | None] = dict.fromkeys(SLOTS)
        self._locked = False
        self._functions: dict[str, ca.Function] = {}
        self._columns: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------------ declare
    @property
    def name(self) -> str:
        return self._decl.name

    @name.setter
    def name(self, value: str) -> None:
        self._decl.name = value

    @property
    def description(self) -> str:
        return self._decl.description

    @property
    def f(self) -> ca.SX:
        """Specific force in the sensor frame, 3 x 1, m/s^2."""
        return self._decl.f

    @property
    def W(self) -> ca.SX:
        """Specific force in g (``f / G0``), 3 x 1."""
        return self._decl.W

    @property
    def omega(self) -> ca.SX:
        """Angular rate of the sensor frame, 3 x 1, rad/s."""
        return self._omega

    def coefficient(self, name: str, unit: str, **kw) -> ca.SX:
        """Declare one coefficient (as :meth:`casep.ErrorModel.coefficient`); returns ``symbol * si_factor``."""
        self._check_unlocked()
        if kw.get("per_flight"):
            raise ValueError(f"`{name}`: a ground test has no flights (per_flight is a flight-model option)")
        return self._decl.coefficient(name, unit, **kw)

    def declare(self, **units):
        """Declare several coefficients, ``Name="unit"`` or ``Name=("unit", scale)`` (as
        :meth:`casep.ErrorModel.declare`)."""
        self._check_unlocked()
        if "per_flight" in units:
            raise ValueError("a ground test has no flights (per_flight is a flight-model option)")
        return self._decl.declare(**units)

    def set_accel_reading(self, expr) -> None:
        """Set the accelerometer triad reading y_a(f, omega, D), 3 x 1."""
        self._set("accel_reading", expr)

    def set_gyro_reading(self, expr) -> None:
        """Set the gyro triad reading y_g(f, omega, D), 3 x 1."""
        self._set("gyro_reading", expr)

    def output(self, slot: str) -> ca.SX:
        """Current expression of an output (zeros if unset)."""
        if slot not in SLOTS:
            raise ValueError(f"unknown output `{slot}`; use one of {', '.join(SLOTS)}")
        e = self._outputs[slot]
        return ca.SX.zeros(3, 1) if e is None else e

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
        fl = flight._symbols
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
            ours.append(self._decl._symbols[j])
        return ca.substitute(expr, ca.vertcat(*fl, flight.f), ca.vertcat(*ours, self.f))

    def _set(self, slot: str, expr) -> None:
        self._check_unlocked()
        if not isinstance(expr, (ca.SX, ca.DM)):
            expr = ca.vertcat(*expr)
        expr = ca.SX(expr)
        if expr.shape != (3, 1):
            raise ValueError(f"`{slot}` must be 3 x 1 (x, y, z), got {expr.shape[0]} x {expr.shape[1]}")
        self._outputs[slot] = expr

    def _check_unlocked(self) -> None:
        if self._locked:
            raise RuntimeError(f"model `{self.name}` is locked after setup(). Use: declare every coefficient "
                               "and output before setup(), or build a new model")

    # ------------------------------------------------------------------- setup
    def setup(self) -> "CalibrationModel":
        """Check the declarations, split each output into known part and Jacobian, lock the model.

        Raises
        ------
        ModelDefinitionError
            Naming what is missing, a term not linear in the coefficients, a term not affine in
            omega, a foreign symbol, a coefficient used in no output or in both.
        """
        if self._locked:
            return self
        d = self._decl
        syms = d._symbols
        if not syms:
            raise ModelDefinitionError(f"model `{self.name}`: Missing: error coefficients. "
                                       "Use: model.declare(Ka0x='mg', ...) or model.coefficient(name, unit)")
        present = {k: v for k, v in self._outputs.items() if v is not None}
        if not present:
            raise ModelDefinitionError(f"model `{self.name}`: Missing: sensor readings. "
                                       "Use: model.set_accel_reading(...) and/or model.set_gyro_reading(...)")
        D = ca.vertcat(*syms)
        f, w = d.f, self._omega
        allowed = list(syms) + [f[i] for i in range(3)] + [w[i] for i in range(3)]
        used_by: dict[str, list[int]] = {}
        for slot, expr in present.items():
            foreign = [s for s in ca.symvar(expr) if not any(ca.is_equal(s, a) for a in allowed)]
            if foreign:
                raise ModelDefinitionError(
                    f"model `{self.name}`: `{slot}` uses symbol(s) {', '.join(f'`{s.name()}`' for s in foreign)} "
                    "that are not declared. Use: only the coefficients, model.f / model.W and model.omega")
            J = ca.jacobian(expr, D)  # exact d reading / dD, 3 x n, per natural unit
            for i in range(3):
                if ca.depends_on(J[i, :], D):
                    bad = [nm for nm, s in zip(d._names, syms) if ca.depends_on(J[i, :], s)]
                    raise ModelDefinitionError(
                        f"model `{self.name}`: `{slot}` component {_AXES[i]} is not linear in the coefficients "
                        f"(its derivative still depends on {', '.join(bad)}). Use: one coefficient per term")
            y0 = ca.substitute(expr, D, ca.SX.zeros(D.shape))  # the known part (ideal sensor)
            # Affine in omega: the second derivative with respect to omega vanishes (checked numerically
            # at probe points on the Jacobian of the whole output with respect to omega).
            dW = ca.jacobian(expr, w)
            fun = ca.Function("dW", [f, w, D], [dW])
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
            cols = sorted(set(J.sparsity().get_col()))
            for j in cols:
                used_by.setdefault(d._names[j], []).append(0 if slot == "accel_reading" else 1)
            self._functions[f"{slot}_known"] = ca.Function(f"{slot}_known", [f, w], [y0], ["f", "omega"], ["y0"])
            self._functions[f"{slot}_jacobian"] = ca.Function(f"{slot}_jacobian", [f, w], [ca.densify(J)],
                                                              ["f", "omega"], ["J"])
            # d reading / d f (3 x 3): how a wrong specific force (a tilted position) moves the reading
            self._functions[f"{slot}_df"] = ca.Function(f"{slot}_df", [f, w, D], [ca.densify(ca.jacobian(expr, f))],
                                                        ["f", "omega", "D"], ["dy_df"])
            self._columns[slot] = np.asarray(cols, dtype=np.intp)
        unused = [nm for nm in d._names if nm not in used_by]
        if unused:
            raise ModelDefinitionError(f"model `{self.name}`: coefficient(s) {', '.join(f'`{u}`' for u in unused)} "
                                       "declared but used in no reading. Use: add them to an equation or remove them")
        both = [nm for nm, v in used_by.items() if len(set(v)) > 1]
        if both:
            raise ModelDefinitionError(
                f"model `{self.name}`: coefficient(s) {', '.join(f'`{b}`' for b in both)} appear in both the "
                "accelerometer and the gyro readings. Use: a coefficient per sensor (each triad is its own "
                "regression with its own noise level)")
        self._locked = True
        return self

    # ------------------------------------------------------------- after setup
    def _require_setup(self) -> None:
        if not self._locked:
            raise RuntimeError(f"model `{self.name}` is not set up. Use: model.setup()")

    @property
    def is_setup(self) -> bool:
        return self._locked

    @property
    def names(self) -> tuple[str, ...]:
        """Coefficient names in model order."""
        return self._decl.names

    @property
    def units(self) -> tuple[str, ...]:
        """Natural unit of each coefficient."""
        return self._decl.units

    @property
    def scales(self) -> dict[str, float]:
        """Typical magnitude per coefficient (natural units), for those declared with one."""
        return self._decl.scales

    @property
    def n_coefficients(self) -> int:
        return self._decl.n_coefficients

    @property
    def si_factors(self) -> np.ndarray:
        """SI value of one natural unit, per coefficient (copy)."""
        return np.asarray(self._decl._factors, dtype=float)

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

    def index(self, name: str) -> int:
        """Position of coefficient `name` in the model order."""
        if name not in self.names:
            raise KeyError(unknown_coefficient_message(name, self.names, f"model `{self.name}`"))
        return self.names.index(name)

    def __repr__(self) -> str:
        return (f"CalibrationModel({self.name!r}, {self.n_coefficients} coefficients, readings {self.readings}, "
                f"{'set up' if self._locked else 'declaring'})")

