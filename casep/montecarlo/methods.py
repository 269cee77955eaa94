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
- ``own_noise_model``: a method that fits its own (GLS) keeps it whatever the campaign's noise.

Every per-run method is a fit request built once for the campaign (:func:`fit_spec`), each run solved
through the one entry point :func:`casep.estimators.solve.fit`, on the rows prepared once per run for
every method (:func:`casep.estimators.solve.rows_for`) when the campaign fits a noise model or a robust
fit. Each returns an estimate and its std (None: the method reports none).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.estimators.registry import METHODS as _REGISTRY
from casep.estimators.registry import CoefficientTable, Interval
from casep.simulation.paper import demo_bounds, demo_prior

__all__ = ["BATCHED", "METHOD_HELP", "MethodSpec", "fit_spec", "linear_maps", "parse_method", "solve_runs"]

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
                prior: Mapping | None = None, magnitudes: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The estimators' own linear maps (``D = K y + b``) of the linear `methods`, registry defaults.

    Each is the method's ``linear_map`` (:class:`casep.estimators.ols.LinearMap`) at the
    options of its spec, a prior (given, else the demo's) weighed at the scenario's `sigma`, and
    with the model's declared `magnitudes` reporting exactly dependent coefficients as the solver's
    result does (:meth:`~casep.estimators.ols.LinearMap.up_to_partners`).
    `S` is the stacked ``(rows, n)`` regression matrix.
    """
    out: dict[str, Any] = {}
    for text in methods:
        spec = parse_method(text)
        build = _REGISTRY[spec.name].linear_map
        assert build is not None, f"{text} is not linear"  # the caller asks for the linear specs only
        lm = build(S, names=names, sigma=sigma, **_supplied(spec, names, prior, None))
        out[text] = lm.up_to_partners(S, names, magnitudes, sigma) if magnitudes else lm
    return out


def fit_spec(spec: MethodSpec, names: Sequence[str], noise: Any, *, sigma: float, prior: Mapping | None = None,
             bounds: Mapping | None = None) -> Any:
    """The fit request (:class:`~casep.estimators.spec.FitSpec`) of one method of a campaign, built once.

    Its options are the spec's and the required ones the campaign supplies (`prior`, `bounds`: given,
    else the paper's demo values); a method that requires a prior weighs the data at the scenario's
    known `sigma`; `noise` is the campaign's :class:`~casep.estimators.spec.NoiseSpec`, de-noised first
    for ``wavelet+<method>`` (then white, as ``casep separate --denoise wavelet`` fits it). A method with
    its own noise model (GLS) keeps it: the campaign's "white" is the other methods' assumption.
    """
    import dataclasses

    from casep.estimators.spec import FitSpec

    m = _REGISTRY[spec.name]
    if spec.denoise:
        noise = dataclasses.replace(noise, denoise="wavelet")
    elif m.own_noise_model is not None and noise.kind == "white":
        noise = dataclasses.replace(noise, kind="auto")
    return FitSpec(spec.name, _supplied(spec, names, prior, bounds), sigma if "prior" in m.required else None, noise)


def solve_runs(spec: Any, ys: Sequence[np.ndarray], flights: Sequence[tuple[np.ndarray, np.ndarray]], *,
               names: Sequence[str], rows: Sequence[Any] | None = None,
               shared: tuple[np.ndarray, np.ndarray] | None = None,
               magnitudes: Mapping[str, float] | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Each run of a chunk through the one entry point :func:`casep.estimators.solve.fit`: estimates and stds,
    ``(runs, n)`` each.

    `spec` is the method's fit request (:func:`fit_spec`), `ys` the runs' dv, `flights` their
    ``(S_V, t)``; `rows` each run's rows prepared once for every method
    (:func:`casep.estimators.solve.rows_for`; None: prepared here, per method); `shared` the ``(S_V, t)``
    all runs share (nominal campaigns: the method's ``shared_options``, e.g. GLS's one REML lattice
    for the chunk); `magnitudes` the model's declared ones (the problem's, as ``casep separate``'s). The std
    is None when the method reports none. The residual checks are left out (a campaign judges its runs by
    their numbers).
    """
    import dataclasses

    from casep.estimators.solve import fit
    from casep.regression.problem import Problem

    m = _REGISTRY[spec.method]
    per_run: list[dict[str, Any]] = [{} for _ in ys]
    if m.shared_options is not None and shared is not None:
        per_run = m.shared_options(shared[0], np.stack(list(ys), axis=-1), shared[1])
    if rows is None or spec.noise.denoise is not None:  # de-noised dv: the rows of the raw dv are not its
        rows = [None] * len(ys)
    outs = []
    for y, extra, (S, t), rw in zip(ys, per_run, flights, rows):
        problem = rw.problem if rw is not None else Problem.from_arrays(S, y, t, names=names, magnitudes=magnitudes)
        run_spec = dataclasses.replace(spec, options={**spec.options, **extra}) if extra else spec
        r = fit(problem, run_spec, rows=rw, checks=False)
        outs.append((r.estimate, r.std))
    est = np.array([o[0] for o in outs])
    return est, None if outs[0][1] is None else np.array([o[1] for o in outs])
