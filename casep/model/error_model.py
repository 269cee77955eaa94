"""Symbolic instrumentation error model: declare -> ``setup()`` -> locked.

An :class:`ErrorModel` holds named error coefficients (CasADi symbols, one per coefficient,
valued in the coefficient's *natural* unit) and up to five output expressions built from them,
from the platform specific force ``f``, from the time since the first sample ``t`` and from
any numeric flight column (a *signal*, :meth:`ErrorModel.signal`):

=========================== ========= =============================================
output                      SI unit   role in the velocity error
=========================== ========= =============================================
``gyro_drift`` phidot(f, D)  rad/s     platform drift rate, integrated to phi(t)
``accel_error`` Delta(f, D)  m/s^2     accelerometer error, enters dWdot directly
``initial_misalignment``     rad       phi(t0) = phi0(D), constant
``initial_velocity_error``   m/s       dv(t0) = dv0(D), constant
``velocity_error`` dv_d(.., D) m/s       added to dv directly, not integrated
=========================== ========= =============================================

The velocity error these generate (``docs/reference/model.md``) is::

    phi(t)   = phi0 + int_{t0}^{t} phidot dt
    dWdot(t) = [f x] phi + Delta          [f x] = [[0, -fz, fy], [fz, 0, -fx], [-fy, fx, 0]]
    dv(t)    = dv0 + int_{t0}^{t} dWdot dt + dv_d(t)

Every output must be linear in the coefficients with no coefficient-free term, so
``dv(t) = S_V(t) D``. :meth:`ErrorModel.setup` checks that, derives the Jacobians of the
outputs with respect to ``D`` exactly (CasADi algorithmic differentiation) and stores them as
named :class:`casadi.Function` objects; :mod:`casep.model.sv` integrates them into S_V.

Because each symbol is valued in natural units and :meth:`ErrorModel.coefficient` returns
``symbol * si_factor``, the equations are written in SI and the Jacobians (hence S_V) come
out per natural unit of each coefficient.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Sequence

import casadi as ca
import numpy as np

from casep.model.base import (
    AXES,
    ModelDefinitionError,
    SpecificForceModel,
    suggest_names,
    unknown_coefficient_message,
)

__all__ = ["ErrorModel", "ModelDefinitionError", "OUTPUTS", "unknown_coefficient_message", "suggest_names"]

#: Output slots of a model: name -> (SI unit, setter name, may depend on f, t and signals?).
OUTPUTS: dict[str, tuple[str, str, bool]] = {
    "gyro_drift": ("rad/s", "set_gyro_drift", True),
    "accel_error": ("m/s^2", "set_accel_error", True),
    "initial_misalignment": ("rad", "set_initial_misalignment", False),
    "initial_velocity_error": ("m/s", "set_initial_velocity_error", False),
    "velocity_error": ("m/s", "set_velocity_error", True),
}

# Deterministic specific-force probes (m/s^2) used to look for coefficient-free terms.
_PROBES = np.array([[0.0, 0.0, 0.0], [13.1, -7.3, 21.7], [-4.9, 55.2, 3.3], [71.0, 2.2, -38.5]])
_T_PROBES = np.array([0.0, 3.7, 41.3, 117.9])  # s, time since the first sample, at each probe
#: Flight columns a model may not use as signals: name -> what to use instead.
_NOT_SIGNALS = {"t": "model.t (time since the first sample, s)",
                **{f"f_{a}": "model.f / model.W (specific force)" for a in "xyz"},
                **{f"dv_{a}": "nothing: dv is the observation, not a regressor" for a in "xyz"}}


class ErrorModel(SpecificForceModel):
    """Instrumentation error model declared with CasADi symbols.

    Parameters
    ----------
    name : str
        Model name, reported in results (e.g. ``"platform36"``).
    description : str, optional
        One line shown in reports.

    Notes
    -----
    Life cycle (as do-mpc's ``Model``): declare coefficients and outputs, call
    :meth:`setup`, after which the model is locked and its Jacobian functions exist.
    Inside the equations the specific force is available as :attr:`f` (m/s^2) and
    :attr:`W` = f / g0 (in g), both 3 x 1 CasADi ``SX`` column vectors; the time since the
    flight's first sample as :attr:`t` (s) and any other numeric flight column by
    :meth:`signal` (in the file's unit). The model records the columns it uses
    (:attr:`signals`).

    Examples
    --------
    >>> import casadi as ca
    >>> m = ErrorModel("toy")
    >>> c = m.declare(Ka0x="mg", Ka1x="mg/g")
    >>> m.set_accel_error(ca.vertcat(c.Ka0x + c.Ka1x * m.W[0], 0, 0))
    >>> m.setup().names
    ('Ka0x', 'Ka1x')
    """

    PUBLIC_NAME = "casep.ErrorModel"
    SLOTS = tuple(OUTPUTS)
    DECLARE_USE = "model.declare(Kg0x='deg/h', ...) or model.coefficient(name, unit)"
    OUTPUTS_USE = "model.set_gyro_drift(phidot) and/or model.set_accel_error(delta)"

    def __init__(self, name: str, description: str = "") -> None:
        super().__init__(name, description)
        self._t = ca.SX.sym("t")  # time since the flight's first sample, s
        self._signal_syms: dict[str, ca.SX] = {}  # flight column name -> symbol (file unit)
        self._signals_used: tuple[str, ...] = ()
        self._per_flight: list[bool] = []
        self._functions: dict[str, ca.Function] = {}
        self._numeric: dict[str, np.ndarray] = {}
        self.source_file: str | None = None  # the model file, set by casep.model.loader
        self.source_doc: str = ""  # the model file's docstring, set by casep.model.loader
        self.source_sha256: str | None = None  # SHA-256 of the model file, set by casep.model.loader

    # ------------------------------------------------------------------ declare
    @property
    def t(self) -> ca.SX:
        """Time since the flight's first sample, s (scalar symbol)."""
        return self._t

    def signal(self, name: str) -> ca.SX:
        """A numeric flight column as a scalar symbol, in the file's unit (e.g. ``"a_x"``, m/s^2).

        The same name gives the same symbol. A flight used with the model must carry every
        column the model's outputs use (:attr:`signals`).
        """
        self._check_unlocked()
        if not isinstance(name, str) or not name or name != name.strip() or "," in name:
            raise ValueError(f"signal name must be a flight column name (non-empty str without spaces at "
                             f"the ends or commas), got {name!r}")
        if name in _NOT_SIGNALS:
            raise ValueError(f"model `{self.name}`: column `{name}` is not a signal. Use: {_NOT_SIGNALS[name]}")
        if name not in self._signal_syms:
            self._signal_syms[name] = ca.SX.sym(f"signal:{name}")
        return self._signal_syms[name]

    def coefficient(
        self, name: str, unit: str, *, si_factor: float | None = None, description: str = "",
        scale: float | None = None, per_flight: bool = False,
    ) -> ca.SX:
        """Declare one error coefficient and return its SI-valued expression ``symbol * si_factor``.

        `name`, `unit`, `si_factor`, `description` and `scale` as
        :meth:`casep.model.base.SymbolicModel.coefficient`; `scale` is the yardstick of the "weak"
        verdict of :func:`casep.checks.diagnostics.diagnose` (CRLB std above it).

        Parameters
        ----------
        per_flight : bool, optional
            Each flight has its own value (a time offset, an initial velocity error) when
            several flights are estimated together (:attr:`per_flight`).

        Returns
        -------
        casadi.SX
            ``symbol * si_factor``: use it in the SI equations of the model.
        """
        if not isinstance(per_flight, (bool, np.bool_)):
            raise TypeError(f"`per_flight` of `{name}` must be a bool, got {per_flight!r}")
        expr = super().coefficient(name, unit, si_factor=si_factor, description=description, scale=scale)
        self._per_flight.append(bool(per_flight))
        return expr

    # per_flight is this model's own option; the base's declare takes unit specifications only
    def declare(self, per_flight: bool = False, **units: str | tuple[str, float]) -> SimpleNamespace:  # type: ignore[override]
        """Declare several coefficients at once, in the order given.

        Parameters
        ----------
        **units : str or (str, float)
            ``Name="unit"`` or ``Name=("unit", scale)`` with the typical magnitude `scale`
            (see :meth:`coefficient`), e.g. ``declare(Kg0x=("deg/h", 0.5), Kg1x="deg/h/g")``.
        per_flight : bool, optional
            These coefficients are per flight (see :meth:`coefficient`), e.g.
            ``declare(dt_trk="ms", per_flight=True)``.

        Returns
        -------
        types.SimpleNamespace
            Attribute per coefficient holding its SI-valued expression.
        """
        return self._declare(units, per_flight=per_flight)

    def set_gyro_drift(self, phidot: ca.SX | Sequence) -> None:
        """Set the platform drift rate phidot(f, D), rad/s, 3 x 1 (x, y, z)."""
        self._set_output("gyro_drift", phidot)

    def set_accel_error(self, delta: ca.SX | Sequence) -> None:
        """Set the accelerometer error Delta(f, D), m/s^2, 3 x 1 (x, y, z)."""
        self._set_output("accel_error", delta)

    def set_initial_misalignment(self, phi0: ca.SX | Sequence) -> None:
        """Set the platform misalignment at t0, phi0(D), rad, 3 x 1; independent of f."""
        self._set_output("initial_misalignment", phi0)

    def set_initial_velocity_error(self, dv0: ca.SX | Sequence) -> None:
        """Set the velocity error at t0, dv0(D), m/s, 3 x 1; independent of f."""
        self._set_output("initial_velocity_error", dv0)

    def set_velocity_error(self, dv_d: ca.SX | Sequence) -> None:
        """Set a velocity error added to dv directly, without integration, m/s, 3 x 1.

        May use ``f``, ``t`` and signals; e.g. a tracking time offset ``a(t) * dt_trk`` or a
        tracking-antenna lever arm. Linear in the coefficients like every output.
        """
        self._set_output("velocity_error", dv_d)

    def output(self, slot: str) -> ca.SX:
        """Current expression of an output slot (zeros if unset), e.g. to add a term to it.

        Parameters
        ----------
        slot : {"gyro_drift", "accel_error", "initial_misalignment", "initial_velocity_error", "velocity_error"}
        """
        return super().output(slot)

    # ------------------------------------------------------------------- setup
    def setup(self) -> "ErrorModel":
        """Check the declarations, derive the Jacobians and lock the model.

        Returns
        -------
        ErrorModel
            ``self``, for chaining.

        Raises
        ------
        ModelDefinitionError
            Naming what is missing, the output component that is not linear in the
            coefficients, a coefficient-free term, a foreign symbol, or an unused
            coefficient.
        """
        return super().setup()

    def _build(self, present: dict[str, ca.SX]) -> None:
        D = ca.vertcat(*self._symbols)
        n = len(self._names)
        everything = ca.vertcat(*present.values())
        # Signals the outputs use, in the order first asked for: the columns a flight must carry.
        used = {k: v for k, v in self._signal_syms.items() if ca.depends_on(everything, v)}
        self._signals_used = tuple(used)
        sig = ca.vertcat(*used.values()) if used else ca.SX(0, 1)
        jac: dict[str, ca.SX] = {}
        inputs = [self._f[i] for i in range(3)] + [self._t] + list(self._signal_syms.values())
        for slot, expr in present.items():
            varying = OUTPUTS[slot][2]  # may use f, t and signals
            self._check_foreign(slot, expr, inputs if varying else [],
                                ("the coefficients, model.f / model.W, model.t and model.signal(...)" if varying
                                 else "the coefficients (an initial term is constant: no f, t or signals)")
                                + " (declare coefficients with model.coefficient)")
            J = ca.jacobian(expr, D)  # exact dOutput/dD, 3 x n
            self._check_linear(J, D, [f"`{slot}` component {a}" for a in AXES])
            self._check_no_offset(slot, expr, D, sig)
            jac[slot] = J
        self._check_used(lambda s: bool(ca.depends_on(everything, s)))
        zero = ca.SX(3, n)
        Jg = jac.get("gyro_drift", zero)
        Ja = jac.get("accel_error", zero)
        Jphi0 = jac.get("initial_misalignment", zero)
        Jv0 = jac.get("initial_velocity_error", zero)
        Jd = jac.get("velocity_error", zero)
        # Inputs of the per-sample functions: f, plus t and the signals when the model uses them.
        uses_t = bool(ca.depends_on(everything, self._t))
        ins = [self._f] + ([self._t] if uses_t or used else []) + ([sig] if used else [])
        names = ["f", "t", "signals"][:len(ins)]
        self._functions = {"dphi0_dD": ca.Function("dphi0_dD", [], [Jphi0], [], ["dphi0_dD"]),
                           "ddv0_dD": ca.Function("ddv0_dD", [], [Jv0], [], ["ddv0_dD"])}
        for fname, J, slot in (("dphidot_dD", Jg, "gyro_drift"), ("dDelta_dD", Ja, "accel_error"),
                               ("dvelocity_error_dD", Jd, "velocity_error")):
            value = self.output(slot)  # zeros if unset
            out = {"gyro_drift": "phidot", "accel_error": "Delta"}.get(slot, slot)
            self._functions[fname] = ca.Function(fname, ins, [J], names, [fname])
            self._functions[out] = ca.Function(out, ins + [D], [value], names + ["D"], [out])
        phi0 = np.array(ca.DM(ca.densify(ca.evalf(Jphi0)))).reshape(3, n)
        dv0 = np.array(ca.DM(ca.densify(ca.evalf(Jv0)))).reshape(3, n)
        # Columns touched by the gyro part (through phi), the accelerometer part and the direct term.
        gcols = sorted({int(c) for c in Jg.sparsity().get_col()}
                       | {int(c) for c in np.flatnonzero(np.any(phi0 != 0, 0))})
        acols = sorted(set(Ja.sparsity().get_col()))
        vcols = sorted(set(Jd.sparsity().get_col()))
        # Per-sample kernel for the S_V build, transposed so that a chunk of C samples
        # lands in numpy as (C, 3, n_cols) C-order arrays; dense, because a buffer is
        # filled with the nonzeros of the output sparsity only. Inputs f, t (always) and
        # the signal vector (when the model uses signals).
        self._functions["sv_rates"] = ca.Function(
            "sv_rates", [self._f, self._t] + ([sig] if used else []),
            [ca.densify(Jg[:, gcols].T), ca.densify(Ja[:, acols].T), ca.densify(Jd[:, vcols].T)],
            ["f", "t"] + (["signals"] if used else []), ["dphidot_dD_T", "dDelta_dD_T", "dvelocity_error_dD_T"]
        )
        self._numeric = {
            "phi0": phi0,
            "dv0": dv0,
            "gyro_columns": np.asarray(gcols, dtype=np.intp),
            "accel_columns": np.asarray(acols, dtype=np.intp),
            "velocity_columns": np.asarray(vcols, dtype=np.intp),
            "si_factors": np.asarray(self._factors, dtype=float),
        }

    def _check_no_offset(self, slot: str, expr: ca.SX, D: ca.SX, sig: ca.SX) -> None:
        """`expr` is zero at D = 0 for every probe of f, t and the signals."""
        offset = ca.substitute(expr, D, ca.SX.zeros(D.shape))  # the coefficient-free part
        fun = ca.Function("offset", [self._f, self._t, sig], [offset])
        sig_probes = np.random.default_rng(20261122).uniform(-50.0, 50.0, (len(_PROBES), sig.shape[0]))
        for probe, t, s in zip(_PROBES, _T_PROBES, sig_probes):
            at = f"f = {probe.tolist()} m/s^2" + (f", t = {t:g} s" if ca.depends_on(offset, self._t) else "")
            self._check_offset(np.array(fun(probe, t, s)), [f"`{slot}` component {a}" for a in AXES], at)

    # ------------------------------------------------------------- after setup
    @property
    def signals(self) -> tuple[str, ...]:
        """Flight columns the outputs use (:meth:`signal`), in the order first asked for; known after setup."""
        self._require_setup()
        return self._signals_used

    @property
    def per_flight(self) -> np.ndarray:
        """Bool per coefficient (model order): True for a per-flight coefficient (copy)."""
        return np.array(self._per_flight, dtype=bool)

    @property
    def si_factors(self) -> np.ndarray:
        """SI value of one natural unit, per coefficient (copy)."""
        self._require_setup()
        return self._numeric["si_factors"].copy()

    @property
    def functions(self) -> dict[str, ca.Function]:
        """Named CasADi functions built by :meth:`setup`.

        ``dphidot_dD(f)``, ``dDelta_dD(f)`` and ``dvelocity_error_dD(f)``: 3 x n Jacobians of
        the drift rate, the accelerometer error and the direct velocity error at specific force
        ``f`` (m/s^2), per natural unit; a model that uses ``t`` or signals takes
        ``(f, t, signals)`` (t in s since the first sample, signals in :attr:`signals` order).
        ``dphi0_dD()`` and ``ddv0_dD()``: constant 3 x n Jacobians of the initial terms.
        ``phidot(..., D)``, ``Delta(..., D)`` and ``velocity_error(..., D)``: the outputs
        themselves (SI) for ``D`` in natural units. ``sv_rates(f, t[, signals])``: the
        transposed, column-restricted Jacobians used by :func:`casep.model.sv.build_sv`.
        """
        self._require_setup()
        return dict(self._functions)

    def numeric(self, key: str) -> np.ndarray:
        """Constant arrays derived by :meth:`setup` (copy).

        Keys: ``phi0`` and ``dv0`` (3 x n Jacobians of the initial terms), ``gyro_columns``
        , ``accel_columns`` and ``velocity_columns`` (indices of the coefficients reached
        through phi, through Delta and through the direct velocity error), ``si_factors``.
        """
        self._require_setup()
        if key not in self._numeric:
            raise KeyError(f"unknown key `{key}`; use one of {sorted(self._numeric)}")
        return self._numeric[key].copy()

    def to_si(self, values: np.ndarray) -> np.ndarray:
        """Convert coefficient values (last axis in model order) from natural units to SI."""
        return np.asarray(values, dtype=float) * self.si_factors
