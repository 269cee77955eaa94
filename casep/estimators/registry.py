"""The estimator registry: every method's options, defaults, rules and capabilities in one table.

``casep separate`` (its option check and ``casep methods``) and :func:`casep.separate` read
this table, so an option the chosen method does not take is an error naming the option and
the method, instead of being silently ignored (``--method ols --lambda 5``).

Each :class:`Method` names its public solver, the options it takes (keywords of
:func:`casep.separate`, with the CLI flag, default and rule), and its capabilities:
``recursive`` (processes samples in time order, has an estimate history), ``needs_time``
(uses the sample times), ``batched`` (a fixed linear map of the data, solved for all runs at
once by ``casep montecarlo``) and ``std_kind`` (what its std mean: sampling, posterior or
conditional; see :data:`casep.estimators.result.STD_KINDS`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from casep.estimators.result import STD_KINDS

__all__ = ["Option", "Method", "OPTIONS", "METHODS", "check_method_options", "describe", "run_method"]


@dataclass(frozen=True)
class Option:
    """One method option: keyword of :func:`casep.separate`, CLI flag, default and rule."""

    name: str
    flag: str
    default: Any
    rule: str
    help: str


@dataclass(frozen=True)
class Method:
    """One estimator: its solver, options and capabilities."""

    name: str
    solver: str
    summary: str
    options: tuple[str, ...] = ()
    required: tuple[str, ...] = ()
    recursive: bool = False
    needs_time: bool = False
    batched: bool = False
    fixed: tuple[tuple[str, Any], ...] = ()  # solver keywords this method always sets

    @property
    def std_kind(self) -> str:
        """What the reported std mean (``sampling``, ``posterior`` or ``conditional``)."""
        return STD_KINDS.get(self.name, "sampling")


#: Method-specific options (``sigma`` and the de-noising options apply to every method).
OPTIONS: dict[str, Option] = {o.name: o for o in (
    Option("p0", "--p0", 1e6, "float in (0, 1e30]", "P0 = p0 I, natural units (a prior variance)"),
    Option("weight", "--weight", 1.0, "float in [1e-12, 1e12]", "measurement weight w (variance 1/w)"),
    Option("forgetting", "--forgetting", 1.0, "float in (0, 1]", "forgetting factor (stabilized)"),
    Option("noise_order", "--noise-order", 1, "int >= 1", "MA order of the noise model"),
    Option("lam", "--lambda", "gcv", "gcv | lcurve | float > 0", "ridge parameter on unit-norm columns, or its rule"),
    Option("bounds", "--bounds", None, "JSON file {name: [lo, hi] | value}", "box bounds and fixed values"),
    Option("prior", "--prior", None, "JSON file {name: {mean, std}}", "Gaussian prior per coefficient"),
    Option("n_components", "--components", None, "int >= 1", "principal components kept (default: CI <= 1000)"),
    Option("tau", "--tau", "auto", "auto | float in (0, 1e4] s", "Gauss-Markov correlation time (auto: REML)"),
)}

#: Every estimator, in the order of ``casep methods``.
METHODS: dict[str, Method] = {m.name: m for m in (
    Method("ols", "solve_ols", "least squares on the scaled QR reduction", batched=True),
    Method("rls", "solve_rls", "recursive least squares, paper Eq. (14), Bierman U-D",
           ("p0", "weight", "forgetting"), recursive=True, batched=True, fixed=(("noise_order", 0),)),
    Method("rels", "solve_rls", "recursive extended least squares (MA noise model)",
           ("p0", "weight", "forgetting", "noise_order"), recursive=True),
    Method("ridge", "solve_ridge", "ridge regression (GCV, L-curve or given lambda)", ("lam",)),
    Method("bounded", "solve_bounded", "box-bounded least squares (Clarabel + exact polish)", ("bounds",),
           required=("bounds",)),
    Method("pcr", "solve_pcr", "principal-component regression", ("n_components",), batched=True),
    Method("map", "solve_map", "maximum a posteriori with a Gaussian prior", ("prior",), required=("prior",),
           batched=True),
    Method("gls", "solve_gls", "least squares in Gauss-Markov noise (AR(1) whitening)", ("tau",),
           needs_time=True),
    Method("huber", "solve_huber", "robust (Huber) least squares by IRLS, outliers flagged"),
)}


def check_method_options(method: str, given: Mapping[str, Any]) -> None:
    """Refuse options that `method` does not take, and missing required ones.

    Parameters
    ----------
    method : str
        A key of :data:`METHODS`.
    given : mapping
        Option name (:data:`OPTIONS` key) -> value, for the options the caller set.

    Raises
    ------
    ValueError
        Naming the option (with its CLI flag), the method, and the methods that take it.
    """
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {', '.join(METHODS)}, got {method!r}")
    m = METHODS[method]
    for name in given:
        if name not in m.options:
            takers = [k for k, v in METHODS.items() if name in v.options]
            flag = OPTIONS[name].flag if name in OPTIONS else name
            raise ValueError(f"option {flag} (`{name}`) is not taken by method `{method}`; it is an option of "
                             f"{', '.join(takers) or 'no method'}. Use: --method {takers[0] if takers else '...'}, "
                             "or leave the option out")
    for name in m.required:
        if given.get(name) is None:
            raise ValueError(f"`{name}` is required for method `{method}`. Use: {OPTIONS[name].flag} "
                             f"{OPTIONS[name].rule}")


#: Where each solver lives (imported on first use, so that the registry imports no estimator).
_MODULES = {"solve_ols": "ols", "solve_rls": "rls", "solve_ridge": "ridge", "solve_bounded": "bounded",
            "solve_pcr": "pcr", "solve_map": "map", "solve_gls": "gls", "solve_huber": "huber"}


def solver(method: str):
    """The public solver function of a registered method."""
    import importlib

    name = METHODS[method].solver
    return getattr(importlib.import_module(f"casep.estimators.{_MODULES[name]}"), name)


def describe() -> list[dict[str, Any]]:
    """The registry as plain data (``casep methods --json``)."""
    out = []
    for m in METHODS.values():
        out.append({"name": m.name, "solver": f"casep.{m.solver}", "summary": m.summary,
                    "options": [{"name": o, "flag": OPTIONS[o].flag, "default": OPTIONS[o].default,
                                 "rule": OPTIONS[o].rule, "help": OPTIONS[o].help} for o in m.options],
                    "required": list(m.required), "recursive": m.recursive, "needs_time": m.needs_time,
                    "batched_in_montecarlo": m.batched, "std_kind": m.std_kind})
    return out


def run_method(method: str, S, y, t, options: Mapping[str, Any], **labels) -> Any:
    """Solve with a registered method: its public solver, its options, the labels.

    Parameters
    ----------
    method : str
        A key of :data:`METHODS`.
    S, y, t : array_like
        Regression ``(N, 3, n)``, velocity error ``(N, 3)`` and sample times ``(N,)``.
    options : mapping
        The method's options (keys of its :attr:`Method.options`; missing ones take the
        :data:`OPTIONS` default; required ones go to the solver positionally).
    **labels
        ``names``, ``units``, ``si_factors``, ``sigma`` and solver extras (e.g. PCR's
        ``max_condition_index``).

    Returns
    -------
    EstimateResult
    """
    check_method_options(method, {k: v for k, v in options.items() if v is not None})
    m = METHODS[method]
    args = [S, y] + ([t] if m.needs_time else []) + [options[r] for r in m.required]
    kw = {o: options.get(o, OPTIONS[o].default) for o in m.options if o not in m.required}
    kw = {k: v for k, v in kw.items() if v is not None}
    return solver(method)(*args, **kw, **dict(m.fixed), **labels)
