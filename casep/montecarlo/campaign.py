"""The campaign: ``run_montecarlo`` checks its inputs, cuts the work into stages and tasks, runs
them on an engine, keeps them in the store and joins them into a :class:`MonteCarloResult`.

Stages: without dispersions the batched linear methods together, then each per-run method;
with dispersions one stage of all methods, so each run's trajectory is simulated and its S_V
built once. A stage is cut into tasks (:func:`casep.montecarlo.tasks.chunks`) that run in this
process or on Dask (:mod:`casep.montecarlo.engines`); with ``out`` each finished task is
written at once and a rerun reads it back (:mod:`casep.montecarlo.store`).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Mapping, Sequence
from contextlib import ExitStack
from typing import Any

import numpy as np

from casep.estimators.bounded import parse_bounds
from casep.estimators.map import parse_prior
from casep.estimators.spec import NoiseSpec
from casep.model.sv import build_sv
from casep.montecarlo.engines import DaskEngine, InProcess
from casep.montecarlo.inputs import check_options, check_truth_prior, own_trajectory
from casep.montecarlo.methods import MethodSpec, fit_spec
from casep.montecarlo.progress import Progress, progress_mode
from casep.montecarlo.result import MonteCarloResult
from casep.montecarlo.store import Store
from casep.montecarlo.tasks import Context, chunks, per_run_noise, reported_crlb
from casep.simulation.scenarios import Scenario
from casep.simulation.simulate import scenario_setup, sv_inputs

__all__ = ["run_montecarlo"]


def run_montecarlo(
    scenario: str | Scenario = "paper",
    *,
    runs: int = 100,
    methods: Sequence[str] = ("ols", "rls", "rels"),
    seed: int = 0,
    rate: float | None = None,
    workers: int | None = None,
    progress: bool | None = None,
    batched: bool = True,
    prior: Mapping | None = None,
    bounds: Mapping | None = None,
    scheduler: str | None = None,
    dispersions: Mapping | None = None,
    truth_prior: Mapping | None = None,
    out: str | os.PathLike | None = None,
    dask: bool | None = None,
    flight: Any = None,
    truth: Mapping | None = None,
    noise: str = NoiseSpec.kind,
    tau: Any = None,
    robust: str | None = NoiseSpec.robust,
) -> MonteCarloResult:
    """Run `runs` noise draws of a scenario through each method.

    Parameters
    ----------
    scenario : str or Scenario
    runs : int
    methods : sequence of str
        See :data:`casep.montecarlo.METHOD_HELP`.
    seed : int
        Root of the per-run seed sequences (see :func:`casep.montecarlo.tasks.run_seq`).
    rate : float, optional
        Sample rate, Hz (default: the scenario's).
    workers : int, optional
        Dask worker processes of the LocalCluster (one thread each; default: the cores this process
        may use, its CPU affinity). 1 runs the tasks in this process.
    progress : bool, optional
        Progress on stderr: True, a bar on a terminal and a plain line with the ETA every 5 s
        otherwise; False, none; default: the bar on a terminal only.
    batched : bool, optional
        Use the one-factorisation path for the linear methods (False: per run, for checks).
    prior, bounds : mapping, optional
        The prior of ``map`` (``{name: {"mean": m, "std": s}}``) and the bounds of ``bounded``
        (``{name: [lo, hi] | value}``), natural units, as ``casep separate --prior/--bounds``
        take them. Default: the paper's demo values (:func:`casep.simulation.paper.demo_prior`,
        :func:`casep.simulation.paper.demo_bounds`), or `truth_prior` for ``map`` when given.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) to run the tasks on.
    dispersions : mapping, optional
        Vehicle and launch dispersions (:mod:`casep.simulation.dispersions`): each run flies
        its own trajectory.
    truth_prior : mapping, optional
        ``{name: {"mean": m, "std": s}}``: each run draws its true coefficients from it
        (coefficients not in it keep the scenario's value).
    out : path, optional
        Folder for per-run results (``runs.parquet/``, one part per task), ``settings.json``,
        ``state.json`` and ``summary.json``; a rerun with the same settings resumes (finished
        tasks are read back, not rerun); other settings are refused.
    dask : bool, optional
        Force (True) or forbid (False) Dask; default: Dask when `scheduler` is given or
        `workers` > 1 and there is per-run work (a per-run method or dispersions).
    flight : FlightData or path, optional
        One's own trajectory instead of the scenario's: its times and specific force (every sample)
        give S_V; each run adds noise to ``S_V D_true``. Needs `truth`; not with `dispersions`.
    truth : mapping, optional
        With `flight`: the true coefficients, ``{name: value}`` in natural units, or a truth file of
        ``casep simulate`` (``{"model", "coefficients", "noise"}``: its model and noise are used).
        Without a noise there, white noise of the flight's own least-squares residual std. Its
        ``model`` is an :class:`~casep.ErrorModel` or the name of a model shipped with casep: a name
        read from a file never runs a model file.
    noise, tau, robust : optional
        The noise model every method assumes and the robust fit, as :func:`casep.separate` takes
        them, with its defaults (``"auto"``, ``"auto"``: each run as ``casep separate`` would fit
        it, every method per run through :func:`casep.estimators.solve.fit`). ``"white"``
        without a robust fit (robust ``"auto"`` or None) runs the methods as they are, the linear
        ones batched (fast; the std then assume white noise). The scenario's tracking gaps remove
        rows in every case.
    """
    asked = {"noise": noise, "tau": tau, "robust": robust}  # as given (recorded with the campaign)
    runs, seed, specs, n_workers, noise_spec = check_options(runs, seed, methods, workers, noise, tau, robust)
    noisy = per_run_noise(noise_spec)
    linear = [s for s in specs if batched and not noisy and s.linear]
    other = [s for s in specs if s not in linear]
    ctx, own, units = _context(scenario, rate, seed, flight, truth, prior, bounds, truth_prior, dispersions,
                               noise=noise_spec, other=other, linear=tuple(s.text for s in linear))
    # stages: (linear, per-run) methods; nominal: the linear maps together, then each per-run
    # method; dispersed: all in one stage (each run's trajectory is simulated once)
    stages: list[tuple[list[MethodSpec], list[MethodSpec]]]
    if ctx.dispersions is None:
        stages = ([(linear, [])] if linear else []) + [([], [s]) for s in other]
    else:
        stages = [(linear, other)]
    chunks_ = [chunks(a + b, runs) for a, b in stages]
    store = None
    if out is not None:
        settings = {"scenario": ctx.scenario.name, "rate": ctx.scenario.rate, "runs": runs, "seed": seed,
                    "methods": [s.text for s in specs], **({"flight": own["record"]} if own is not None else {}),
                    "batched": bool(batched), "prior": ctx.prior, "bounds": bounds, "dispersions": ctx.dispersions,
                    "truth_from_prior": truth_prior, "tasks": [len(c) for c in chunks_]}
        if noisy:  # (absent for the default, so campaigns written before stay resumable)
            settings["noise"] = {**asked, "robust": None if robust == "none" else robust}
        store = Store(out, json.loads(json.dumps(settings)))
    groups = [[s.text for s in a + b] for a, b in stages]
    bar = Progress(runs, [",".join(g) for g in groups], progress_mode(progress))
    results: list[dict[int, dict]] = [{} for _ in stages]
    if store is not None:
        for si, g in enumerate(groups):
            for ti in range(len(chunks_[si])):
                r = store.load(si, ti, g, ctx.names)
                if r is not None:
                    results[si][ti] = r
    n_tasks = sum(len(c) for c in chunks_)
    resumed = sum(len(r) for r in results)
    pending = n_tasks - resumed
    per_run_work = ctx.dispersions is not None or bool(other)
    use_dask = dask if dask is not None else bool(scheduler) or (n_workers > 1 and per_run_work and pending > 1)
    secs: dict[str, float] = {}
    with ExitStack() as stack:
        stack.callback(bar.close)
        engine = DaskEngine(stack, n_workers, scheduler) if use_dask and pending else InProcess()
        for si, (lin, per_run) in enumerate(stages):
            t0 = time.perf_counter()
            done = sum(len(r["runs"]) for r in results[si].values())
            if done:
                bar(done)
            jobs = [((si, ti), (lin, per_run, list(c))) for ti, c in enumerate(chunks_[si]) if ti not in results[si]]
            for (si_, ti), part in engine.run(ctx, jobs):
                if store is not None:
                    store.save(si_, ti, groups[si], ctx.names, part)
                results[si][ti] = part
                bar(len(part["runs"]))
            for m in groups[si]:
                secs[m] = (time.perf_counter() - t0) / len(groups[si])
            if si + 1 < len(stages):
                bar.next_stage()
    res = _result(ctx, [s.text for s in specs], units, groups, [[r[ti] for ti in range(len(c))]
                                                               for r, c in zip(results, chunks_)],
                  secs=secs, runs=runs, resumed=resumed, tasks=n_tasks)
    if store is not None:
        res.write_json(store.dir / "summary.json")
    return res


def _context(scenario: str | Scenario, rate: float | None, seed: int, flight: Any, truth: Mapping | None,
             prior: Mapping | None, bounds: Mapping | None, truth_prior: Mapping | None,
             dispersions: Mapping | None, *, noise: NoiseSpec | None = None, other: Sequence[MethodSpec] = (),
             linear: tuple[str, ...] = ()) -> tuple[Context, dict[str, Any] | None, tuple[str, ...]]:
    """The campaign's context (inputs checked, the nominal S_V and CRLB built, the fit request of each
    per-run method in `other` built once under the noise request `noise`), the own-trajectory record
    (None: the scenario's) and the coefficients' units."""
    own = None
    if flight is not None or truth is not None:
        if flight is None or truth is None:
            raise ValueError("`flight` and `truth` go together: a Monte Carlo on one's own trajectory needs both")
        if dispersions is not None:
            raise ValueError("`dispersions` fly the scenario's vehicle; with `flight` the trajectory is given")
        own = own_trajectory(scenario, flight, truth)
        sc, model, truth_v = own["scenario"], own["model"], own["truth"]
        traj: Any = None
    else:
        sc, traj, model, truth_v = scenario_setup(scenario, rate)
    names = model.names
    if prior is None and truth_prior is not None:
        prior = truth_prior  # MAP with the prior the truths are drawn from: Bayesian coverage
    if prior is not None:
        parse_prior(prior, names)  # checked once, before any run
    if bounds is not None:
        parse_bounds(bounds, names)
    tp = None
    if truth_prior is not None:
        if "correlation" in truth_prior and "correlation" not in names:
            raise ValueError("`truth_prior`: a correlation entry is not supported (marginal means and stds only)")
        tp = parse_prior(truth_prior, names, "`truth_prior`")
        check_truth_prior(tp, model, "`truth_prior`")
    if dispersions is not None:
        from casep.simulation.dispersions import parse_dispersions

        dispersions = parse_dispersions(dispersions, len(sc.vehicle.stages), "`dispersions`", vehicle=sc.vehicle)
    sigma = sc.noise.sigma
    tau = sc.noise.tau if sc.noise.kind == "ar1" else None  # the scenario's, for the CRLB
    S = t = crlb = None
    if dispersions is None:  # every run shares the trajectory
        if own is None:  # the scenario's force and signal columns (a strapdown scenario: its q_*, fb_*, w_*)
            t_all, (f_all, sig) = traj.t, sv_inputs(sc, traj, model, truth_v)
        else:
            t_all, f_all, sig = own["t"], own["f"], own["signals"]
        keep = sc.noise.keep_mask(t_all)  # tracking gaps: no rows there
        t = t_all[keep]
        S = build_sv(model, t_all, f_all, signals=sig)[keep]
        crlb = reported_crlb(S, t, sigma, tau, names, model.scales)
    fits = {}
    for spec in other:  # each method's fit request, checked here, before any run
        try:
            fits[spec.text] = fit_spec(spec, names, noise or NoiseSpec("white", robust=None), sigma=sigma, prior=prior,
                                       bounds=bounds)
        except ValueError as exc:
            raise ValueError(f"method `{spec.text}`: {exc}") from None
    ctx = Context(scenario=sc, names=names, sigma=sigma, tau=tau, seed=seed, truth=truth_v, prior=prior,
                  bounds=bounds, truth_prior=tp, dispersions=dispersions, S=S, t=t, crlb=crlb, noise=noise, fits=fits,
                  linear=linear, magnitudes=dict(model.scales))
    return ctx, own, model.units


def _result(ctx: Context, methods: list[str], units: tuple[str, ...], groups: list[list[str]],
            parts: list[list[dict[str, Any]]], *, secs: dict[str, float], runs: int, resumed: int,
            tasks: int) -> MonteCarloResult:
    """The stages' task results (`parts`, in run order) joined into the campaign's result."""
    est: dict[str, np.ndarray] = {}
    std: dict[str, np.ndarray | None] = {}
    for group, ps in zip(groups, parts):
        for m in group:
            est[m] = np.concatenate([p["est"][m] for p in ps])
            std[m] = None if ps[0]["std"][m] is None else np.concatenate([p["std"][m] for p in ps])
    first = parts[0]
    truths = np.concatenate([p["truth"] for p in first])
    crlbs = np.concatenate([p["crlb"] for p in first])
    draws = {k: np.concatenate([p["draws"][k] for p in first]) for k in (first[0].get("draws") or {})} if first else {}
    with np.errstate(invalid="ignore"):
        crlb_std: Any = ctx.crlb if ctx.dispersions is None else np.sqrt(np.mean(crlbs**2, axis=0))  # RMS over the runs
    tp = ctx.truth_prior
    centre = ctx.truth if tp is None else np.where(np.isfinite(tp[1]), tp[0], ctx.truth)
    return MonteCarloResult(scenario=ctx.scenario.name, runs=runs, seed=ctx.seed, rate=float(ctx.scenario.rate),
                            names=ctx.names, units=units, truth=centre, crlb_std=crlb_std,
                            estimates={m: est[m] for m in methods}, stds={m: std[m] for m in methods},
                            seconds=secs, truths=truths if tp is not None else None,
                            dispersions=tuple(ctx.dispersions) if ctx.dispersions else (), resumed=resumed,
                            tasks=tasks, draws=draws,
                            noise={"simulated": {**ctx.scenario.noise.to_dict(), "text": ctx.scenario.noise.describe()},
                                   "fit": _fit_record(ctx.noise)}, magnitudes=dict(ctx.magnitudes))


def _fit_record(noise: NoiseSpec | None) -> dict[str, Any]:
    """The noise model the campaign's methods assumed (None: white, no robust fit), as the result records it."""
    ns = noise if noise is not None else NoiseSpec("white", robust=None)
    return {"noise": ns.kind, "tau": ns.tau, "robust": ns.robust}
