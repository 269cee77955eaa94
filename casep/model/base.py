"""The declaration machinery every symbolic model shares: declare -> ``setup()`` -> locked.

:class:`SymbolicModel` holds named error coefficients (CasADi symbols valued in each
coefficient's *natural* unit, :data:`casep.units.UNITS`) and the output expressions built from
them. A subclass says what is its own: its inputs (symbols), its output slots and their shape,
and :meth:`SymbolicModel._build`, which derives its exact Jacobians as named
:class:`casadi.Function` objects. The base gives the rest, the same for every model:

- coefficients (:meth:`~SymbolicModel.coefficient`, :meth:`~SymbolicModel.declare`) with their
  natural units, SI factors (the returned expression is ``symbol * si_factor``, so equations are
  written in SI and Jacobians come out per natural unit), typical magnitudes and descriptions;
- outputs (:meth:`~SymbolicModel.output`, ``_set_output``) checked for shape;
- the life cycle (as do-mpc's ``Model``): declaring after :meth:`~SymbolicModel.setup` and
  reading results before it are errors that say what to do ("... Use: model.setup()");
- the checks :meth:`~SymbolicModel.setup` runs, with errors of the form "Missing: ... Use: ...":
  a coefficient or an output missing, a foreign symbol, a coefficient used in no output, an
  output not linear in the coefficients (its Jacobian still depends on them), a coefficient-free
  term (an output that is not zero at ``D = 0``).

Subclasses: :class:`casep.ErrorModel` (platform flight errors), :class:`casep.TrackingModel`
(one station's measurement errors), :class:`casep.calibration.CalibrationModel` (ground-test
readings).
"""

from __future__ import annotations

import difflib
import keyword
import re
from types import SimpleNamespace
from typing import Any, Callable, ClassVar, Sequence

import casadi as ca
import numpy as np

from casep.units import G0
from casep.units import si_factor as _unit_si_factor

__all__ = ["SymbolicModel", "SpecificForceModel", "ModelDefinitionError", "unknown_coefficient_message",
           "suggest_names", "AXES"]

#: Axis letters of the rows of a 3 x 1 output.
AXES = "xyz"
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
# Characters typed for one another in coefficient names: letter O / digit 0, letter l or I / digit 1.
_CONFUSABLE = str.maketrans({"o": "0", "l": "1", "i": "1"})


class ModelDefinitionError(ValueError):
    """A model is declared inconsistently (raised by ``setup()`` of every symbolic model)."""


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


class SymbolicModel:
    """Coefficients, outputs and life cycle shared by the symbolic models (see the module notes).

    Parameters
    ----------
    name : str
        Model name, reported in results.
    description : str, optional
        One line shown in reports.
    """

    #: How errors name the model (``"model `platform36`: ..."``).
    KIND: ClassVar[str] = "model"
    #: How errors name the class (``"build() returned int, not casep.ErrorModel"``).
    PUBLIC_NAME: ClassVar[str] = "casep.SymbolicModel"
    #: Output slot names, in order.
    SLOTS: ClassVar[tuple[str, ...]] = ()
    #: Rows of each output (3: an x, y, z triad; 1: a scalar).
    ROWS: ClassVar[int] = 3
    #: "Use: ..." of the missing-coefficients and missing-outputs errors.
    DECLARE_USE: ClassVar[str] = "model.declare(Kg0x='deg/h', ...) or model.coefficient(name, unit)"
    OUTPUTS_USE: ClassVar[str] = "set at least one output"
    #: What the outputs are called in errors ("error outputs", "sensor readings").
    OUTPUTS_WHAT: ClassVar[str] = "error outputs"

    def __init__(self, name: str, description: str = "") -> None:
        if not isinstance(name, str) or not name.strip():
            raise TypeError("`name` must be a non-empty str")
        if not isinstance(description, str):
            raise TypeError("`description` must be a str")
        self.name = name
        self.description = description
        self._names: list[str] = []
        self._units: list[str] = []
        self._factors: list[float] = []
        self._descriptions: list[str] = []
        self._scales: dict[str, float | None] = {}
        self._symbols: list[ca.SX] = []
        self._outputs: dict[str, ca.SX | None] = dict.fromkeys(self.SLOTS)
        self._locked = False

    # ------------------------------------------------------------------ declare
    def coefficient(self, name: str, unit: str, *, si_factor: float | None = None, description: str = "",
                    scale: float | None = None) -> ca.SX:
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
            Typical magnitude in the natural unit (a spec-sheet value).

        Returns
        -------
        casadi.SX
            ``symbol * si_factor``: use it in the SI equations of the model.
        """
        self._check_unlocked()
        if not isinstance(name, str) or not _NAME_RE.match(name) or keyword.iskeyword(name):
            raise ValueError(f"coefficient name {name!r} is not a valid identifier")
        if name in self._names:
            raise ValueError(f"coefficient `{name}` is declared twice in {self.KIND} `{self.name}`")
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
        """Declare several coefficients at once, in the order given.

        Parameters
        ----------
        **units : str or (str, float)
            ``Name="unit"`` or ``Name=("unit", scale)`` with the typical magnitude `scale`
            (see :meth:`coefficient`), e.g. ``declare(Kg0x=("deg/h", 0.5), Kg1x="deg/h/g")``.

        Returns
        -------
        types.SimpleNamespace
            Attribute per coefficient holding its SI-valued expression.
        """
        return self._declare(units)

    def _declare(self, units: dict[str, str | tuple[str, float]], **options: Any) -> SimpleNamespace:
        """:meth:`declare` with `options` passed to every :meth:`coefficient` call."""
        def one(name: str, spec: str | tuple[str, float]) -> ca.SX:
            if isinstance(spec, tuple):
                if len(spec) != 2:
                    raise ValueError(f"`{name}` must be \"unit\" or (\"unit\", scale), got {spec!r}")
                return self.coefficient(name, spec[0], scale=spec[1], **options)
            return self.coefficient(name, spec, **options)

        return SimpleNamespace(**{n: one(n, u) for n, u in units.items()})

    def output(self, slot: str) -> ca.SX:
        """Current expression of an output slot (zeros if unset), e.g. to add a term to it."""
        if slot not in self.SLOTS:
            raise ValueError(f"unknown output `{slot}`; use one of {', '.join(self.SLOTS)}")
        expr = self._outputs[slot]
        return ca.SX.zeros(self.ROWS, 1) if expr is None else expr

    def _set_output(self, slot: str, expr: Any) -> None:
        """Store `expr` as output `slot`: a ROWS x 1 SX (a sequence of ROWS expressions, or a number
        for a scalar output)."""
        self._check_unlocked()
        label = self._label(slot)
        if self.ROWS == 1:
            if isinstance(expr, (int, float)) and not isinstance(expr, bool):
                expr = ca.SX(expr)
            if not isinstance(expr, (ca.SX, ca.DM)):
                raise TypeError(f"{label} must be a scalar casadi.SX expression, got {type(expr).__name__}")
        elif not isinstance(expr, (ca.SX, ca.DM)):
            if isinstance(expr, (str, bytes)) or not isinstance(expr, (Sequence, np.ndarray)):
                raise TypeError(f"{label} must be a 3 x 1 casadi.SX or a sequence of 3 expressions")
            expr = ca.vertcat(*expr)
        expr = ca.SX(expr)
        if expr.shape != (self.ROWS, 1):
            want = "a scalar" if self.ROWS == 1 else f"{self.ROWS} x 1 (x, y, z)"
            raise ValueError(f"{label} must be {want}, got {expr.shape[0]} x {expr.shape[1]}")
        self._outputs[slot] = expr

    def _label(self, slot: str) -> str:
        """How errors name output `slot`."""
        return f"`{slot}`"

    def _check_unlocked(self) -> None:
        if self._locked:
            raise RuntimeError(f"{self.KIND} `{self.name}` is locked after setup(). Use: declare every "
                               "coefficient and output before setup(), or build a new model")

    def _require_setup(self) -> None:
        if not self._locked:
            raise RuntimeError(f"{self.KIND} `{self.name}` is not set up. Use: model.setup()")

    # ------------------------------------------------------------------ setup
    def setup(self) -> Any:
        """Check the declarations, derive the exact Jacobians and lock the model.

        Returns
        -------
        The model itself, for chaining.

        Raises
        ------
        ModelDefinitionError
            Naming what is missing, the output that is not linear in the coefficients or has a
            coefficient-free term, a foreign symbol, or an unused coefficient.
        """
        if self._locked:
            return self
        where = f"{self.KIND} `{self.name}`"
        if not self._names:
            raise ModelDefinitionError(f"{where}: Missing: error coefficients. Use: {self.DECLARE_USE}")
        present = {k: v for k, v in self._outputs.items() if v is not None}
        if not present:
            raise ModelDefinitionError(f"{where}: Missing: {self.OUTPUTS_WHAT}. Use: {self.OUTPUTS_USE}")
        self._build(present)
        self._locked = True
        return self

    def _build(self, present: dict[str, ca.SX]) -> None:
        """Check the outputs set (`present`, slot -> expression) and build the functions (subclass)."""
        raise NotImplementedError

    # Checks used by the subclasses' _build, each raising ModelDefinitionError "... Use: ...".
    def _check_foreign(self, slot: str, expr: ca.SX, allowed: Sequence[ca.SX], use: str) -> None:
        """Every symbol of `expr` is a coefficient or one of `allowed` (the model's inputs)."""
        # known: one of the same nodes (``ca.is_equal`` at depth 0), by the nodes' hashes, each looked up once (an
        # expression among `allowed` is no symbol: it never equals one)
        known = {a.element_hash() for a in list(self._symbols) + list(allowed) if a.is_scalar() and a.is_symbolic()}
        foreign = [s for s in ca.symvar(expr) if s.element_hash() not in known]
        if foreign:
            names = ", ".join(f"`{s.name()}`" for s in foreign)
            raise ModelDefinitionError(f"{self.KIND} `{self.name}`: {self._label(slot)} uses symbol(s) {names} "
                                       f"that are not declared. Use: only {use}")

    def _check_used(self, used: Callable[[ca.SX], bool], where: str = "output",
                    use: str = "add them to an equation or remove them") -> None:
        """Every coefficient is one that `used(symbol)` says some output uses."""
        unused = [nm for nm, s in zip(self._names, self._symbols) if not used(s)]
        if unused:
            raise ModelDefinitionError(f"{self.KIND} `{self.name}`: coefficient(s) "
                                       f"{', '.join(f'`{u}`' for u in unused)} declared but used in no {where}. "
                                       f"Use: {use}")

    def _check_linear(self, J: ca.SX, D: ca.SX, row: Sequence[str]) -> None:
        """The Jacobian `J` = d outputs / dD no longer depends on `D`; `row[i]` names row i in errors."""
        for i in range(J.shape[0]):
            if ca.depends_on(J[i, :], D):
                bad = [nm for nm, s in zip(self._names, self._symbols) if ca.depends_on(J[i, :], s)]
                raise ModelDefinitionError(
                    f"{self.KIND} `{self.name}`: {row[i]} is not linear in the coefficients (its derivative "
                    f"still depends on {', '.join(bad)}). Use: one coefficient per term; declare a product "
                    "as its own coefficient")

    def _check_offset(self, value: np.ndarray, row: Sequence[str], at: str) -> None:
        """The outputs at ``D = 0`` (`value`, one probe point `at`) are zero: no coefficient-free term."""
        value = np.asarray(value, dtype=float).ravel()
        if np.any(value != 0.0):
            i = int(np.flatnonzero(value)[0])
            raise ModelDefinitionError(
                f"{self.KIND} `{self.name}`: {row[i]} has a term without a coefficient (value {value[i]:.6g} "
                f"at {at}). Use: multiply every term by exactly one coefficient")

    # ------------------------------------------------------------------ after setup
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
    def symbols(self) -> tuple[ca.SX, ...]:
        """The coefficient symbols (valued in natural units), model order."""
        return tuple(self._symbols)

    @property
    def scales(self) -> dict[str, float]:
        """Typical magnitude per coefficient, natural units, for those declared with one."""
        return {n: v for n, v in self._scales.items() if v is not None}

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
        return np.asarray(self._factors, dtype=float)

    def index(self, name: str) -> int:
        """Position of coefficient `name` in the model order."""
        try:
            return self._names.index(name)
        except ValueError:
            raise KeyError(unknown_coefficient_message(name, self._names, f"{self.KIND} `{self.name}`")) from None

    def __repr__(self) -> str:
        state = "set up" if self._locked else "declaring"
        return f"{type(self).__name__}({self.name!r}, {len(self._names)} coefficients, {state})"


class SpecificForceModel(SymbolicModel):
    """A :class:`SymbolicModel` whose equations take the specific force :attr:`f` (m/s^2, 3 x 1) and
    :attr:`W` = f / g0 (in g): the flight and the ground-test instrument models."""

    def __init__(self, name: str, description: str = "") -> None:
        super().__init__(name, description)
        self._f = ca.SX.sym("f", 3)  # specific force, m/s^2
        self._W = self._f / G0  # the same in g, as the error equations use it

    @property
    def f(self) -> ca.SX:
        """Specific force symbol, 3 x 1, m/s^2 (platform frame in flight, sensor frame on a stand)."""
        return self._f

    @property
    def W(self) -> ca.SX:
        """Specific force in g (``f / G0``), 3 x 1 expression."""
        return self._W
