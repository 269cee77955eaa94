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

import difflib
import keyword
import re
from types import SimpleNamespace
from typing import Sequence

import casadi as ca
import numpy as np

from casep.units import G0
from casep.units import si_factor as _unit_si_factor

__all__ = ["ErrorModel", "ModelDefinitionError", "OUTPUTS", "unknown_coefficient_message", "suggest_names"]

#: Output slots of a model: name -> (SI unit, setter name, may depend on f, t and signals?).
OUTPUTS: dict[str, tuple[str, str, bool]] = {
    "gyro_drift": ("rad/s", "set_gyro_drift", True),
    "accel_error": ("m/s^2", "set_accel_error", True),
    "initial_misalignment": ("rad", "set_initial_misalignment", False),
    "initial_velocity_error": ("m/s", "set_initial_velocity_error", False),
    "velocity_error": ("m/s", "set_velocity_error", True),
}

_AXES = "xyz"
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
# Deterministic specific-force probes (m/s^2) used to look for coefficient-free terms.
_PROBES = np.array([[0.0, 0.0, 0.0], [13.1, -7.3, 21.7], [-4.9, 55.2, 3.3], [71.0, 2.2, -38.5]])
_T_PROBES = np.array([0.0, 3.7, 41.3, 117.9])  # s, time since the first sample, at each probe
#: Flight columns a model may not use as signals: name -> what to use instead.
_NOT_SIGNALS = {"t": "model.t (time since the first sample, s)",
                **{f"f_{a}": "model.f / model.W (specific force)" for a in "xyz"},
                **{f"dv_{a}": "nothing: dv is the observation, not a regressor" for a in "xyz"}}


class ModelDefinitionError(ValueError):
    """An error model is declared inconsistently (raised by :meth:`ErrorModel.setup`)."""


# Characters typed for one another in coefficient names: letter O / digit 0, letter l or I / digit 1.
_CONFUSABLE = str.maketrans({"o": "0", "l": "1", "i": "1"})


def _fold(name: str) -> str:
    """Case- and look-alike-insensitive key of a name (``KaOy``, ``kaoy`` and ``Ka0y`` share one)."""
    return name.lower().translate(_CONFUSABLE)


def suggest_names(name: str, names: Sequence[str], n: int = 3) -> list[str]:
    """Names of `names` the user probably meant by `name`, best first (maybe none).

    Names equal to `name` up to case and the O/0, l/1, I/1 confusions come first; otherwise
    :func:`difflib.get_close_matches` (ratio >= 0.6) on the folded names.
    """
    folded: dict[str, str] = {}
    for nm in names:
        folded.setdefault(_fold(nm), nm)
    key = _fold(str(name))
    if key in folded:
        return [folded[key]]
    return [folded[k] for k in difflib.get_close_matches(key, list(folded), n=n, cutoff=0.6)]


def unknown_coefficient_message(name: str, names: Sequence[str], source: str) -> str:
    """One-line error for a coefficient name that `names` lacks, with a "did you mean".

    Parameters
    ----------
    name : str
        The name as the user gave it.
    names : sequence of str
        The model's coefficient names.
    source : str
        Where the name was read, e.g. ``"--prior p.json"`` or ``"model `platform36`"``.
    """
    close = suggest_names(name, names)
    hint = f" (did you mean {' or '.join(f'`{c}`' for c in close)}?)" if close else ""
    return f"{source}: unknown coefficient `{name}`{hint}; the model has {', '.join(names)}"


class ErrorModel:
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

    def __init__(self, name: str, description: str = "") -> None:
        if not isinstance(name, str) or not name.strip():
            raise TypeError("`name` must be a non-empty str")
        if not isinstance(description, str):
            raise TypeError("`description` must be a str")
        self.name = name
        self.description = description
        self._f = ca.SX.sym("f", 3)  # platform specific force, m/s^2
        self._W = self._f / G0  # the same in g, as the error equations use it
        self._t = ca.SX.sym("t")  # time since the flight's first sample, s
        self._signal_syms: dict[str, ca.SX] = {}  # flight column name -> symbol (file unit)
        self._per_flight: list[bool] = []
        self._names: list[str] = []
        self._units: list[str] = []
        self._factors: list[float] = []
        self._descriptions: list[str] = []
        self._scales: dict[str, float | None] = {}
        self._symbols: list[ca.SX] = []
        self._outputs: dict[str, ca.SX | None] = dict.fromkeys(OUTPUTS)
        self._locked = False
        self._functions: dict[str, ca.Function] = {}
        self._numeric: dict[str, np.ndarray] = {}
        self.source_file: str | None = None  # the model file, set by casep.model.loader
        self.source_doc: str = ""  # the model file's docstring, set by casep.model.loader

    # ------------------------------------------------------------------ declare
    @property
    def f(self) -> ca.SX:
        """Specific force symbol, 3 x 1, m/s^2 (platform frame)."""
        return self._f

    @property
    def W(self) -> ca.SX:
        """Specific force in g (``f / G0``), 3 x 1 expression."""
        return self._W

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
        """Declare one error coefficient and return its SI-valued expression.

        Parameters
        ----------
        name : str
            Identifier, unique in the model (e.g. ``"Kg0x"``).
        unit : str
            Natural unit used in reports and files (e.g. ``"deg/h"``); see
            :data:`casep.units.UNITS`.
        si_factor : float, optional
            SI value of one natural unit; required when `unit` is not a known unit.
        description : str, optional
            Free text for reports.
        scale : float, optional
            Typical magnitude in the natural unit (a spec-sheet value): the yardstick of the
            "weak" verdict of :func:`casep.analysis.diagnostics.diagnose` (CRLB std above it).
        per_flight : bool, optional
            Each flight has its own value (a time offset, an initial velocity error) when
            several flights are estimated together (:attr:`per_flight`).

        Returns
        -------
        casadi.SX
            ``symbol * si_factor``: use it in the SI equations of the model.
        """
        self._check_unlocked()
        if not isinstance(name, str) or not _NAME_RE.match(name) or keyword.iskeyword(name):
            raise ValueError(f"coefficient name {name!r} is not a valid identifier")
        if name in self._names:
            raise ValueError(f"coefficient `{name}` is declared twice in model `{self.name}`")
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
        if not isinstance(per_flight, (bool, np.bool_)):
            raise TypeError(f"`per_flight` of `{name}` must be a bool, got {per_flight!r}")
        sym = ca.SX.sym(name)  # valued in the natural unit
        self._names.append(name)
        self._units.append(unit)
        self._factors.append(factor)
        self._descriptions.append(description)
        self._scales[name] = None if scale is None else float(scale)
        self._symbols.append(sym)
        self._per_flight.append(bool(per_flight))
        return sym * factor

    def declare(self, per_flight: bool = False, **units: str | tuple[str, float]) -> SimpleNamespace:
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
        def one(name, spec):
            if isinstance(spec, tuple):
                if len(spec) != 2:
                    raise ValueError(f"`{name}` must be \"unit\" or (\"unit\", scale), got {spec!r}")
                return self.coefficient(name, spec[0], scale=spec[1], per_flight=per_flight)
            return self.coefficient(name, spec, per_flight=per_flight)

        return SimpleNamespace(**{n: one(n, u) for n, u in units.items()})

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
        if slot not in OUTPUTS:
            raise ValueError(f"unknown output `{slot}`; use one of {', '.join(OUTPUTS)}")
        expr = self._outputs[slot]
        return ca.SX.zeros(3, 1) if expr is None else expr

    def _set_output(self, slot: str, expr: ca.SX | Sequence) -> None:
        self._check_unlocked()
        if not isinstance(expr, (ca.SX, ca.DM)):
            if isinstance(expr, (str, bytes)) or not isinstance(expr, Sequence):
                raise TypeError(f"`{slot}` must be a 3 x 1 casadi.SX or a sequence of 3 expressions")
            expr = ca.vertcat(*expr)
        expr = ca.SX(expr)
        if expr.shape != (3, 1):
            raise ValueError(f"`{slot}` must be 3 x 1 (x, y, z), got {expr.shape[0]} x {expr.shape[1]}")
        self._outputs[slot] = expr

    def _check_unlocked(self) -> None:
        if self._locked:
            raise RuntimeError(
                f"model `{self.name}` is locked after setup(). Use: declare every coefficient "
                "and output before setup(), or build a new model"
            )

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
        if self._locked:
            return self
        if not self._names:
            raise ModelDefinitionError(
                f"model `{self.name}`: Missing: error coefficients. "
                "Use: model.declare(Kg0x='deg/h', ...) or model.coefficient(name, unit)"
            )
        present = {k: v for k, v in self._outputs.items() if v is not None}
        if not present:
            raise ModelDefinitionError(
                f"model `{self.name}`: Missing: error outputs. "
                "Use: model.set_gyro_drift(phidot) and/or model.set_accel_error(delta)"
            )
        D = ca.vertcat(*self._symbols)
        n = len(self._names)
        everything = ca.vertcat(*present.values())
        # Signals the outputs use, in the order first asked for: the columns a flight must carry.
        used = {k: v for k, v in self._signal_syms.items() if ca.depends_on(everything, v)}
        self._signals_used = tuple(used)
        sig = ca.vertcat(*used.values()) if used else ca.SX(0, 1)
        jac: dict[str, ca.SX] = {}
        for slot, expr in present.items():
            self._check_symbols(slot, expr)
            J = ca.jacobian(expr, D)  # exact dOutput/dD, 3 x n
            self._check_linear(slot, expr, J, D, sig)
            jac[slot] = J
        unused = [nm for nm, s in zip(self._names, self._symbols) if not ca.depends_on(everything, s)]
        if unused:
            raise ModelDefinitionError(
                f"model `{self.name}`: coefficient(s) {', '.join(f'`{u}`' for u in unused)} "
                "declared but used in no output. Use: add them to an equation or remove them"
            )
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
        gcols = sorted(set(Jg.sparsity().get_col()) | set(np.flatnonzero(np.any(phi0 != 0, 0))))
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
        self._locked = True
        return self

    def _check_symbols(self, slot: str, expr: ca.SX) -> None:
        inputs = [self._f[i] for i in range(3)] + [self._t] + list(self._signal_syms.values())
        allowed = list(self._symbols) + (inputs if OUTPUTS[slot][2] else [])
        foreign = [s for s in ca.symvar(expr) if not any(ca.is_equal(s, a) for a in allowed)]
        if foreign:
            names = ", ".join(f"`{s.name()}`" for s in foreign)
            what = ("the coefficients, model.f / model.W, model.t and model.signal(...)" if OUTPUTS[slot][2]
                    else "the coefficients (an initial term is constant: no f, t or signals)")
            raise ModelDefinitionError(
                f"model `{self.name}`: `{slot}` uses symbol(s) {names} that are not declared. "
                f"Use: only {what} (declare coefficients with model.coefficient)"
            )

    def _check_linear(self, slot: str, expr: ca.SX, J: ca.SX, D: ca.SX, sig: ca.SX) -> None:
        for i in range(3):
            if ca.depends_on(J[i, :], D):
                bad = [nm for nm, s in zip(self._names, self._symbols) if ca.depends_on(J[i, :], s)]
                raise ModelDefinitionError(
                    f"model `{self.name}`: `{slot}` component {_AXES[i]} is not linear in the "
                    f"coefficients (its derivative still depends on {', '.join(bad)}). "
                    "Use: one coefficient per term; declare a product as its own coefficient"
                )
        offset = ca.substitute(expr, D, ca.SX.zeros(D.shape))  # the coefficient-free part
        fun = ca.Function("offset", [self._f, self._t, sig], [offset])
        sig_probes = np.random.default_rng(20261122).uniform(-50.0, 50.0, (len(_PROBES), sig.shape[0]))
        for probe, t, s in zip(_PROBES, _T_PROBES, sig_probes):
            value = np.array(fun(probe, t, s)).ravel()
            if np.any(value != 0.0):
                i = int(np.flatnonzero(value)[0])
                at = f"f = {probe.tolist()} m/s^2" + (f", t = {t:g} s" if ca.depends_on(offset, self._t) else "")
                raise ModelDefinitionError(
                    f"model `{self.name}`: `{slot}` component {_AXES[i]} has a term without a "
                    f"coefficient (value {value[i]:.6g} at {at}). "
                    "Use: multiply every term by exactly one coefficient"
                )

    # ------------------------------------------------------------- after setup
    def _require_setup(self) -> None:
        if not self._locked:
            raise RuntimeError(f"model `{self.name}` is not set up. Use: model.setup()")

    @property
    def is_setup(self) -> bool:
        """True once :meth:`setup` has locked the model."""
        return self._locked

    @property
    def names(self) -> tuple[str, ...]:
        """Coefficient names in model order."""
        return tuple(self._names)

    @property
    def units(self) -> tuple[str, ...]:
        """Natural unit of each coefficient."""
        return tuple(self._units)

    @property
    def scales(self) -> dict[str, float]:
        """Typical magnitude per coefficient, natural units, for those declared with one."""
        return {n: v for n, v in self._scales.items() if v is not None}

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
    def descriptions(self) -> tuple[str, ...]:
        """Free-text description of each coefficient."""
        return tuple(self._descriptions)

    @property
    def n_coefficients(self) -> int:
        """Number of coefficients."""
        return len(self._names)

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

    def index(self, name: str) -> int:
        """Position of coefficient `name` in the model order."""
        try:
            return self._names.index(name)
        except ValueError:
            raise KeyError(unknown_coefficient_message(name, self._names, f"model `{self.name}`")) from None

    def to_si(self, values: np.ndarray) -> np.ndarray:
        """Convert coefficient values (last axis in model order) from natural units to SI."""
        return np.asarray(values, dtype=float) * self.si_factors

    def __repr__(self) -> str:
        state = "set up" if self._locked else "declaring"
        return f"ErrorModel({self.name!r}, {len(self._names)} coefficients, {state})"
