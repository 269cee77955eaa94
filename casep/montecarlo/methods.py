"""How the Monte Carlo runs an estimator: only through its :class:`~casep.estimators.registry.Method`.

The rest of :mod:`casep.montecarlo` sees a method only through :func:`parse_method` (the
spec language of ``--methods``: ``<method>``, ``<method>:<number>`` (the method's first option
fixed, e.g. ``ridge:<lambda>``), ``<method>:<option>=<value>[:...]`` (any option),
``wavelet+<method>``), :func:`linear_maps` (the batched path)
and :func:`solve_runs` (the per-run path). What they ask of a method (its ``Method`` fields):

- ``batched`` and ``linear_map``: a batched method, or one with a linear map whose spec fixes
  its options to numbers (``ridge:<lambda>``), is solved for all runs with one factorisation,
  ``D = K y + b`` with the solver's std (:class:`casep.estimators.ols.LinearMap`);
- ``required``: the options the Monte Carlo supplies itself, given or else the paper's demo
  values (``prior``, ``bounds``); a method that requires a prior weighs the data at the
  scenario's known sigma;
- ``shared_options`` and ``max_runs_per_task``: options that the runs of a chunk on one
  trajectory share (GLS: one REML search of tau), and the most runs one task holds;
- ``own_noise_model``: with a noise model or a robust fit, a method that fits its own
  (GLS) gets the rows before whitening, the others the rows prepared once for every method
  (:func:`casep.workflows.solve.solve_problem`); otherwise the registry's solver
  (:func:`casep.estimators.registry.run_method`). Each returns an estimate and its std (None:
  the method reports none).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.estimators.registry import METHODS as _REGISTRY
from casep.estimators.registry import CoefficientTable, Interval
from casep.simulation.paper import demo_bounds, demo_prior

__all__ = ["BATCHED", "METHOD_HELP", "MethodSpec", "linear_maps", "parse_method", "solve_runs"]

#: Methods solved for all runs with one factorisation (their linear map).
BATCHED = tuple(k for k, m in _REGISTRY.items() if m.batched)
METHOD_HELP = ("ols, rls, rels, ridge (GCV), ridge:<lambda>, pcr, map, bounded, gls (REML tau), huber; "
               "<method>:<option>=<value>[:<option>=<value>] (any option of the method); and "
               "wavelet+<method> (de-noised first)")


@dataclass(frozen=True)
class MethodSpec:
    """One entry of ``methods``: ``text`` as given, the registry ``name``, the ``options`` the
    spec fixes, and ``denoise`` (``wavelet+``: the dv is de-noised first)."""

    text: str
    name: str
    options: Mapping[str, Any] = field(default_factory=dict)
    denoise: bool = False

    @property
    def linear(self) -> bool:
        """The estimate is a fixed linear map of the data (solved batched when allowed)."""
        m = _REGISTRY[self.name]
        if self.denoise or (m.linear_map is None and not m.batched):
            return False
        if not self.options:
            return m.batched
        # a linear map honours the method's first option (ridge's lambda, RLS's p0) as a number; other
        # options (RLS's forgetting) it does not take: those specs run per run, through the solver
        first = m.option_specs[0].name
        return set(self.options) == {first} and isinstance(self.options[first], (int, float))

    @property
    def max_task_runs(self) -> int | None:
        """Most runs per task this method wants (None: no limit of its own)."""
        return _REGISTRY[self.name].max_runs_per_task


def parse_method(text: str) -> MethodSpec:
    """Read one method spec; ValueError naming it (and the option) when unknown or an option is bad.

    Forms: ``<method>``; ``<method>:<number>`` (its first numeric option, e.g. ``ridge:1e-4``);
    ``<method>:<option>=<value>[:<option>=<value>...]`` (any option, by its keyword or its
    ``casep separate`` flag without dashes: ``rls:p0=1e6:forgetting=0.999``, ``ridge:lambda=0.1``);
    ``wavelet+`` before any of them. Each value is read and checked by the option's own rules and
    the set by the method's validator (:func:`casep.estimators.registry.check_method_options`), so
    a spec fails as ``casep separate --method <method> --<option> <value>`` would. The file options
    (``prior``, ``bounds``) come from ``--prior``/``--bounds``, not from a spec.
    """
    from casep.estimators.registry import check_method_options

    denoise = text.startswith("wavelet+")
    base = text.split("+", 1)[1] if denoise else text
    name, _, rest = base.partition(":")
    if name not in _REGISTRY:
        raise ValueError(f"unknown method `{text}`. Use: {_known()}")
    if not rest:
        return MethodSpec(text, name, {}, denoise)
    m = _REGISTRY[name]
    if "=" not in rest:
        options = [_first_number(text, m, rest)]
    else:
        options = [_option(text, m, item) for item in rest.split(":")]
    given = dict(options)
    if len(given) != len(options):
        raise ValueError(f"method `{text}`: an option is given twice")
    try:
        check_method_options(name, given)
    except ValueError as exc:
        raise ValueError(f"method `{text}`: {exc}") from None
    return MethodSpec(text, name, given, denoise)


def _first_number(text: str, m: Any, value: str) -> tuple[str, Any]:
    """``<method>:<number>``: the method's first option, when it takes a number."""
    numeric = [(o, r) for o in m.option_specs[:1] for r in o.rules if isinstance(r, Interval)]
    if not numeric:
        raise ValueError(f"method `{text}`: `{m.name}` takes no number. Use: {_known()}")
    (option, rule), label = numeric[0], numeric[0][0].flag.lstrip("-")
    try:
        number = rule.parse(value)
    except ValueError:
        raise ValueError(f"method `{text}`: {m.name}:<{label}> needs a number") from None
    if not rule.accepts(number):
        raise ValueError(f"method `{text}`: {label} must be {str(rule).removeprefix(rule.kind.__name__ + ' ')}")
    return option.name, number


def _option(text: str, m: Any, item: str) -> tuple[str, Any]:
    """One ``<option>=<value>`` of a spec: the option (by keyword or flag) and its value, read by its rules."""
    key, eq, value = item.partition("=")
    key = key.strip()
    found = [o for o in m.option_specs if key in (o.name, o.flag.lstrip("-"), o.flag.lstrip("-").replace("-", "_"))]
    takes = ", ".join(f"{o.name} ({o.flag})" for o in m.option_specs) or "none"
    if not eq or not key or not found:
        raise ValueError(f"method `{text}`: `{item}` is not an option of `{m.name}` (<option>=<value>; "
                         f"its options: {takes})")
    o = found[0]
    if any(isinstance(r, CoefficientTable) for r in o.rules):
        raise ValueError(f"method `{text}`: option `{o.name}` is a file: give it with {o.flag} FILE")
    try:
        return o.name, o.parse(value.strip())
    except ValueError:
        raise ValueError(f"method `{text}`: option `{o.name}` ({o.flag}) of method `{m.name}` must be {o.rule}, "
                         f"got {value.strip()!r}") from None


def _known() -> str:
    """The methods registered now (a method registered at run time included), and the spec forms."""
    return (f"{', '.join(_REGISTRY)}; <method>:<number> (its first option, e.g. ridge:<lambda>); "
            "<method>:<option>=<value>[:<option>=<value>] (e.g. rls:p0=1e6:forgetting=0.999); wavelet+<method>")


def _supplied(spec: MethodSpec, names: Sequence[str], prior: Mapping | None,
              bounds: Mapping | None) -> dict[str, Any]:
    """The spec's options and the required ones the Monte Carlo supplies (given, else the demo's)."""
    offer = {"prior": lambda: prior or demo_prior(names), "bounds": lambda: bounds or demo_bounds(names)}
    return {**spec.options, **{k: offer[k]() for k in _REGISTRY[spec.name].required}}


def linear_maps(S: np.ndarray, names: Sequence[str], sigma: float, methods: Sequence[str],
                prior: Mapping | None = None) -> dict[str, Any]:
    """The estimators' own linear maps (``D = K y + b``) of the linear `methods`, registry defaults.

    Each is the method's ``linear_map`` (:class:`casep.estimators.ols.LinearMap`) at the
    options of its spec, a prior (given, else the demo's) weighed at the scenario's `sigma`.
    `S` is the stacked ``(rows, n)`` regression matrix.
    """
    out: dict[str, Any] = {}
    for text in methods:
        spec = parse_method(text)
        build = _REGISTRY[spec.name].linear_map
        assert build is not None, f"{text} is not linear"  # the caller asks for the linear specs only
        out[text] = build(S, names=names, sigma=sigma, **_supplied(spec, names, prior, None))
    return out


def solve_runs(spec: MethodSpec, ys: Sequence[np.ndarray], flights: Sequence[tuple[np.ndarray, np.ndarray]], *,
               names: Sequence[str], sigma: float, prior: Mapping | None = None, bounds: Mapping | None = None,
               noise: str = "white", robust: str | None = None, rows: Sequence[Any] | None = None,
               shared: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Each run of a chunk through the public solver: estimates and stds, ``(runs, n)`` each.

    `ys` are the runs' dv, `flights` their ``(S_V, t)``; `shared` the ``(S_V, t)`` all runs
    share (nominal campaigns: the method's ``shared_options``, e.g. GLS's one REML lattice for
    the chunk). `prior` and `bounds` are those the methods require (default: the paper's demo
    values); `noise` and `robust` the noise model and robust fit, with `rows` each run's rows
    prepared once for every method (:func:`casep.workflows.solve.prepare_rows`; None: white,
    the solver directly). The std is None when the method reports none.
    """
    m = _REGISTRY[spec.name]
    runs = [_denoised(spec, y) for y in ys]
    per_run: list[dict[str, Any]] = [{} for _ in runs]
    if m.shared_options is not None and shared is not None:
        per_run = m.shared_options(shared[0], np.stack([y for y, _ in runs], axis=-1), shared[1])
    base = _supplied(spec, names, prior, bounds)
    outs = [_solve(spec, S, y, t, given, {**base, **extra}, sigma=sigma, names=names, noise=noise, robust=robust,
                   rows=rw)
            for (y, given), extra, (S, t), rw in zip(runs, per_run, flights,
                                                     # de-noised dv: white, as casep separate fits it
                                                     rows if rows is not None and not spec.denoise
                                                     else [None] * len(runs))]
    est = np.array([o[0] for o in outs])
    return est, None if outs[0][1] is None else np.array([o[1] for o in outs])


def _denoised(spec: MethodSpec, y: np.ndarray) -> tuple[np.ndarray, float | None]:
    """``wavelet+<m>``: the de-noised dv and its sigma, as casep separate does; else as given."""
    if not spec.denoise:
        return y, None
    from casep.noise.denoise import denoise

    d = denoise(y)
    return d.dv, float(np.sqrt(np.mean(d.sigma**2)))


def _solve(spec: MethodSpec, S: np.ndarray, y: np.ndarray, t: np.ndarray, given: float | None,
           opts: Mapping[str, Any], *, sigma: float, names: Sequence[str], noise: str, robust: str | None,
           rows: Any) -> tuple[np.ndarray, np.ndarray | None]:
    """One run: `given` is the sigma handed to the solver (None: estimated)."""
    from casep.estimators.registry import run_method

    m = _REGISTRY[spec.name]
    if "prior" in m.required:
        given = given or sigma  # a prior weighs the data at the known sigma
    if rows is not None:
        from casep.workflows.solve import solve_problem

        if m.own_noise_model is not None:  # it fits its own noise model; the glitches removed first when robust
            r = solve_problem(rows.problem, m.name, opts, noise="gm", robust=robust, sigma=given).result
        else:
            r = solve_problem(rows.problem, m.name, opts, noise=noise, rows=rows, sigma=given,
                              check_white=False).result
        return r.estimate, r.std
    r = run_method(m.name, S, y, t, opts, names=names, sigma=given)  # the registry's solver and defaults
    return r.estimate, r.std
