"""Everything the Monte Carlo knows about particular estimators, in one place.

The rest of :mod:`casep.montecarlo` sees a method only through :func:`parse_method` (the
spec language of ``--methods``: ``ols``, ``ridge:<lambda>``, ``wavelet+<method>``),
:func:`linear_maps` (the batched path) and :func:`solve_runs` (the per-run path). What they
ask of an estimator:

- its name in :data:`casep.estimators.registry.METHODS` and whether its estimate is a fixed
  linear function of the data at fixed options (``batched``), and then its linear map
  ``D = K y + b`` with the solver's std (:class:`casep.estimators.ols.LinearMap`);
- options written in the spec (``ridge:<lambda>`` is ridge with ``lam`` fixed, which makes it
  linear);
- the options the Monte Carlo supplies itself: ``map`` gets a prior (given, else the paper's
  demo prior) and the scenario's known sigma; ``bounded`` gets bounds (given, else the demo's);
- ``gls`` only: a chunk of runs on one trajectory shares one REML search of tau
  (:func:`casep.estimators.gls.estimate_tau_many`), and a task holds at most
  :data:`GLS_CHUNK` runs so that the lattice stays that of a small chunk;
- a solver through the registry (:func:`casep.estimators.registry.run_method`) or, with a
  noise model or a robust fit, through :func:`casep.workflows.solve.solve_problem`, returning an
  estimate and its std (None: the method reports none).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.estimators.registry import METHODS as _REGISTRY
from casep.simulation.paper import demo_bounds, demo_prior

__all__ = ["BATCHED", "GLS_CHUNK", "METHOD_HELP", "MethodSpec", "linear_maps", "parse_method", "solve_runs"]

#: Methods solved for all runs with one factorisation (their linear map).
BATCHED = tuple(k for k, m in _REGISTRY.items() if m.batched)
METHOD_HELP = ("ols, rls, rels, ridge (GCV), ridge:<lambda>, pcr, map, bounded, gls (REML tau), huber, and "
               "wavelet+<method> (de-noised first)")
#: Runs of a task that share one GLS REML lattice (:func:`casep.estimators.gls.estimate_tau_many`).
GLS_CHUNK = 16


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
        return not self.denoise and (self.name in BATCHED or (self.name == "ridge" and "lam" in self.options))

    @property
    def max_task_runs(self) -> int | None:
        """Most runs per task this method wants (None: no limit of its own)."""
        return GLS_CHUNK if self.name == "gls" else None


def parse_method(text: str) -> MethodSpec:
    """Read one method spec; ValueError naming it when unknown or its option is bad."""
    denoise = text.startswith("wavelet+")
    base = text.split("+", 1)[1] if denoise else text
    if base.startswith("ridge:"):
        try:
            lam = float(base.split(":", 1)[1])
        except ValueError:
            raise ValueError(f"method `{text}`: ridge:<lambda> needs a number") from None
        if not lam > 0:
            raise ValueError(f"method `{text}`: lambda must be > 0")
        return MethodSpec(text, "ridge", {"lam": lam}, denoise)
    if base not in _REGISTRY:
        raise ValueError(f"unknown method `{text}`. Use: {METHOD_HELP}")
    return MethodSpec(text, base, {}, denoise)


def linear_maps(S: np.ndarray, names: Sequence[str], sigma: float, methods: Sequence[str],
                prior: Mapping | None = None) -> dict[str, Any]:
    """The estimators' own linear maps (``D = K y + b``) of the batched `methods`, registry defaults.

    ``ols``, ``rls`` (no forgetting, the registry's p0 and weight), ``pcr`` (default
    truncation), ``map`` (at the scenario's sigma, as the per-run path gives it) and
    ``ridge:<lambda>``: see :class:`casep.estimators.ols.LinearMap`. `S` is the stacked
    ``(rows, n)`` regression matrix.
    """
    from casep.estimators.map import map_linear_map
    from casep.estimators.ols import ols_linear_map
    from casep.estimators.pcr import pcr_linear_map
    from casep.estimators.registry import OPTIONS
    from casep.estimators.ridge import ridge_linear_map
    from casep.estimators.rls import rls_linear_map

    build = {"ols": lambda: ols_linear_map(S),
             "rls": lambda: rls_linear_map(S, p0=OPTIONS["p0"].default, weight=OPTIONS["weight"].default),
             "pcr": lambda: pcr_linear_map(S),
             "map": lambda: map_linear_map(S, prior or demo_prior(names), sigma, names=names)}
    out: dict[str, Any] = {}
    for m in methods:
        spec = parse_method(m)
        out[m] = ridge_linear_map(S, spec.options["lam"]) if spec.name == "ridge" else build[spec.name]()
    return out


def solve_runs(spec: MethodSpec, ys: Sequence[np.ndarray], flights: Sequence[tuple[np.ndarray, np.ndarray]], *,
               names: Sequence[str], sigma: float, prior: Mapping | None = None, bounds: Mapping | None = None,
               noise: str = "white", robust: str | None = None, rows: Sequence[Any] | None = None,
               shared: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Each run of a chunk through the public solver: estimates and stds, ``(runs, n)`` each.

    `ys` are the runs' dv, `flights` their ``(S_V, t)``; `shared` the ``(S_V, t)`` all runs
    share (nominal campaigns: GLS then searches tau on one lattice for the chunk). `prior` and
    `bounds` are those of ``map`` and ``bounded`` (default: the paper's demo values); `noise`
    and `robust` the noise model and robust fit, with `rows` each run's rows prepared once for
    every method (:func:`casep.workflows.solve.prepare_rows`; None: white, the solver directly).
    The std is None when the method reports none.
    """
    runs = [_denoised(spec, y) for y in ys]
    if spec.name == "gls" and shared is not None:  # one REML lattice for the chunk
        from casep.estimators.gls import estimate_tau_many

        taus: list[float | str] = list(estimate_tau_many(shared[0], np.stack([y for y, _ in runs], axis=-1),
                                                         shared[1]))
    else:
        taus = ["auto"] * len(runs)
    outs = [_solve(spec, S, y, t, given, tau, names=names, sigma=sigma, prior=prior, bounds=bounds, noise=noise,
                   robust=robust, rows=rw)
            for (y, given), tau, (S, t), rw in zip(runs, taus, flights, rows or [None] * len(runs))]
    est = np.array([o[0] for o in outs])
    return est, None if outs[0][1] is None else np.array([o[1] for o in outs])


def _denoised(spec: MethodSpec, y: np.ndarray) -> tuple[np.ndarray, float | None]:
    """``wavelet+<m>``: the de-noised dv and its sigma, as casep separate does; else as given."""
    if not spec.denoise:
        return y, None
    from casep.analysis.denoise import denoise

    d = denoise(y)
    return d.dv, float(np.sqrt(np.mean(d.sigma**2)))


def _solve(spec: MethodSpec, S: np.ndarray, y: np.ndarray, t: np.ndarray, given: float | None, tau: float | str, *,
           names: Sequence[str], sigma: float, prior: Mapping | None, bounds: Mapping | None, noise: str,
           robust: str | None, rows: Any) -> tuple[np.ndarray, np.ndarray | None]:
    """One run: `given` is the sigma handed to the solver (None: estimated), `tau` GLS's."""
    from casep.estimators.registry import run_method

    method, opts = spec.name, dict(spec.options)
    if method == "map":
        opts, given = {"prior": prior or demo_prior(names)}, given or sigma  # MAP with the known sigma
    elif method == "bounded":
        opts = {"bounds": bounds or demo_bounds(names)}
    elif method == "gls":
        opts = {"tau": tau}
    if rows is not None:
        from casep.workflows.solve import solve_problem

        if method == "gls":  # its own tau; the glitches removed first when the run is robust
            r = solve_problem(rows.problem, "gls", opts, noise="gm", robust=robust, sigma=given).result
        else:
            r = solve_problem(rows.problem, method, opts, noise=noise, rows=rows, sigma=given,
                              check_white=False).result
        return r.estimate, r.std
    r = run_method(method, S, y, t, opts, names=names, sigma=given)  # the registry's solver and defaults
    return r.estimate, r.std
