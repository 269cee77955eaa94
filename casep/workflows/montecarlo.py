"""Seeded Monte Carlo of the estimators against the Cramer-Rao bound, on Dask.

Run k draws its tracking noise from ``default_rng(SeedSequence(seed, spawn_key=(k,)))`` (=
``SeedSequence(seed).spawn(runs)[k]``), its dispersed vehicle (``--dispersions``) from spawn key
``(k, 0)`` and its true coefficients (``--truth-from-prior``) from ``(k, 1)``: a run's numbers
depend on the seed and k only, not on how runs are grouped into tasks or which worker runs them.

Work is cut into **tasks** (chunks of runs whose size depends on `runs` only) in **stages**:
without dispersions the linear methods together, then each per-run method; with dispersions
one stage of all methods, so each run's trajectory is simulated and its S_V built once. Tasks
run in this process (``workers=1``), on a Dask LocalCluster of single-threaded worker
processes, or on a running cluster (``scheduler``). Methods whose estimate is a fixed linear
function of the data (``ols``, ``rls`` with no forgetting, ``ridge:<lambda>``, ``pcr``, ``map``
with the scenario's sigma) apply the estimator's own linear map ``D = K y + b``
(:func:`casep.estimators.ols.ols_linear_map` and its siblings, tested equal to the solvers) to
all runs of a task that share a trajectory at once (nominal: the whole task, the maps built
once per worker; dispersed: run by run). The others (``rels``, ``ridge`` with GCV, ``bounded``,
``gls``, ``wavelet+<method>``) call the public solver per run; GLS shares one REML lattice per
task (nominal). Both paths report the same numbers as the solvers (tested).

``out``: each finished task's runs are written as one Parquet part of ``runs.parquet/``
(columns run, method, coefficient, estimate, std, true, crlb_std), beside ``settings.json``,
``state.json`` (finished parts) and ``summary.json``; a rerun with the same settings reads the
finished parts back and runs only the rest, so its summary is that of an uninterrupted run.

Statistics per method and coefficient (natural units): ``bias`` = mean error, ``rms``,
``crlb_std`` (white: sigma^2 (S^T S)^-1; Gauss-Markov scenarios: the GLS bound; dispersed:
the RMS over the runs of each run's bound), ``efficiency`` = crlb_std / rms, ``coverage95`` =
share of runs with ``|error| <= 1.96 std`` among the runs that report a std for that
coefficient (bounded least squares reports none on a bound; null when the method gives none).
With a truth prior each run's error is against its own drawn truth and ``true`` is the prior
mean.
"""

from __future__ import annotations

import csv
import json
import multiprocessing
import os
import signal
import sys
import threading
import time
import uuid
import warnings
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from casep.analysis.diagnostics import crlb_covariance
from casep.estimators.bounded import parse_bounds
from casep.estimators.map import parse_prior
from casep.estimators.registry import METHODS as _REGISTRY
from casep.exceptions import IllConditionedWarning
from casep.io._atomic import atomic_open
from casep.model.sv import build_sv
from casep.simulation.paper import demo_bounds, demo_prior
from casep.simulation.scenarios import Scenario
from casep.simulation.simulate import scenario_setup

__all__ = ["MonteCarloResult", "run_montecarlo", "METHOD_HELP", "BATCHED", "Terminated", "sigterm_raises"]

#: Methods solved for all runs with one factorisation.
BATCHED = tuple(k for k, m in _REGISTRY.items() if m.batched)
METHOD_HELP = ("ols, rls, rels, ridge (GCV), ridge:<lambda>, pcr, map, bounded, gls (REML tau), huber, and "
               "wavelet+<method> (de-noised first)")
_BLOCK = 128  # runs per block of right-hand sides
_GLS_CHUNK = 16  # runs sharing one REML lattice (casep.estimators.gls.estimate_tau_many)


def _noise(scenario: Scenario, t: np.ndarray, seq: np.random.SeedSequence) -> np.ndarray:
    return scenario.noise.sample(t, np.random.default_rng(seq))


def _check_method(m: str) -> str:
    base = m.split("+", 1)[1] if m.startswith("wavelet+") else m
    if base.startswith("ridge:"):
        try:
            lam = float(base.split(":", 1)[1])
        except ValueError:
            raise ValueError(f"method `{m}`: ridge:<lambda> needs a number") from None
        if not lam > 0:
            raise ValueError(f"method `{m}`: lambda must be > 0")
    elif base not in _REGISTRY:
        raise ValueError(f"unknown method `{m}`. Use: {METHOD_HELP}")
    return m


# --------------------------------------------------------------------------- per-run path
def _denoised(method: str, y: np.ndarray) -> tuple[str, np.ndarray, float | None]:
    """``wavelet+<m>``: the de-noised dv and its sigma, as casep separate does; else as given."""
    if not method.startswith("wavelet+"):
        return method, y, None
    from casep.analysis.denoise import denoise

    d = denoise(y)
    return method.split("+", 1)[1], d.dv, float(np.sqrt(np.mean(d.sigma**2)))


def _solve(method: str, S: np.ndarray, y: np.ndarray, names, sigma: float, t: np.ndarray,
           given: float | None = None, tau: float | str = "auto", *, prior: Mapping | None = None,
           bounds: Mapping | None = None, noise: str = "white", noise_tau=None,
           robust: str | None = None, rows=None) -> tuple[np.ndarray, np.ndarray | None]:
    """One run of a (de-noised) method through the public solvers: estimate and reported std.

    `given` is the sigma handed to the solver (None: estimated), `tau` the GLS correlation time,
    `prior` and `bounds` those of ``map`` and ``bounded`` (default: the paper's demo values);
    `noise`, `noise_tau` and `robust` the noise model and robust fit
    (:func:`casep.workflows.solve.solve_problem`; white and not robust: the solver directly);
    `rows` the run's rows prepared once for every method (:func:`casep.workflows.solve.prepare_rows`).
    """
    from casep.estimators.registry import run_method

    opts: dict[str, Any] = {}
    if method.startswith("ridge:"):
        method, opts = "ridge", {"lam": float(method.split(":", 1)[1])}
    elif method == "map":
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


# ------------------------------------------------------------------------------ tasks
def _run_seq(seed: int, k: int, stream: int | None = None) -> np.random.SeedSequence:
    """Run k's seed sequence: noise ``(k,)`` (= ``SeedSequence(seed).spawn(runs)[k]``), dispersion
    ``(k, 0)``, true coefficients ``(k, 1)``: a run's numbers depend on the seed and k only."""
    return np.random.SeedSequence(seed, spawn_key=(k,) if stream is None else (k, stream))


@dataclass(frozen=True)
class _Context:
    """What every task needs (scattered once to the workers)."""

    token: str
    scenario: Scenario
    names: tuple[str, ...]
    sigma: float
    tau: float | None
    seed: int
    truth: np.ndarray  # nominal (the scenario's)
    prior: Mapping | None = None
    bounds: Mapping | None = None
    truth_prior: tuple[np.ndarray, np.ndarray] | None = None  # mean, std (inf: not drawn)
    dispersions: Mapping | None = None
    S: np.ndarray | None = None  # nominal trajectory's tracked rows (None when dispersed)
    t: np.ndarray | None = None
    crlb: np.ndarray | None = None
    noise: str = "white"  # the noise model the methods assume (casep.analysis.noise)
    noise_tau: Any = None
    robust: str | None = None


_CACHE: dict[str, Any] = {}  # per process: the linear maps of the current campaign


@lru_cache(maxsize=4)
def _model(name: str):
    from casep.model.loader import load_model

    return load_model(name)


def _flight(ctx: _Context, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Run k's S_V, times, true coefficients and CRLB std (nominal or dispersed)."""
    truth = ctx.truth
    if ctx.truth_prior is not None:
        mu, sd = ctx.truth_prior
        fin = np.isfinite(sd)
        truth = truth.copy()
        truth[fin] = mu[fin] + sd[fin] * np.random.default_rng(_run_seq(ctx.seed, k, 1)).standard_normal(fin.sum())
    if ctx.dispersions is None:
        return ctx.S, ctx.t, truth, ctx.crlb, {}
    from casep.simulation.dispersions import disperse_vehicle, draw_dispersion
    from casep.simulation.trajectory import simulate_boost

    values = draw_dispersion(ctx.dispersions, np.random.default_rng(_run_seq(ctx.seed, k, 0)))
    try:
        traj = simulate_boost(disperse_vehicle(ctx.scenario.vehicle, values), ctx.scenario.rate)
    except (ValueError, RuntimeError) as exc:  # a draw the vehicle cannot fly: say which run and which values
        drawn = ", ".join(f"{n} {v:.6g}" for n, v in values.items())
        raise ValueError(f"run {k}: the dispersed vehicle ({drawn}) cannot be flown: {exc}. Narrow the "
                         "--dispersions (the same seed draws the same values again)") from None
    keep = ctx.scenario.noise.keep_mask(traj.t)  # tracking gaps: no rows there
    S = build_sv(_model(ctx.scenario.model), traj.t, traj.specific_force)[keep]
    t = traj.t[keep]
    crlb = np.sqrt(np.diag(crlb_covariance(S, ctx.sigma, t=t if ctx.tau else None, tau=ctx.tau)))
    return S, t, truth, crlb, values


def _task(ctx: _Context, linear: Sequence[str], other: Sequence[str], runs: Sequence[int]) -> dict[str, Any]:
    """Runs `runs` of the `linear` methods (their linear maps) and the `other` (per-run) methods.

    Linear methods are applied to all runs sharing a trajectory at once (the whole task when
    nominal, run by run when dispersed). Returns run ids, true coefficients, CRLB std and per
    method the estimates and stds, ``(len(runs), n)`` each (std None: the method gives none).
    """
    from threadpoolctl import threadpool_limits

    from casep.estimators.gls import estimate_tau_many

    n = len(ctx.names)
    with threadpool_limits(limits=1), warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        flights = [_flight(ctx, k) for k in runs]
        ys = [S @ tr + _noise(ctx.scenario, t, _run_seq(ctx.seed, k)) for k, (S, t, tr, *_) in zip(runs, flights)]
        est: dict[str, np.ndarray] = {}
        std: dict[str, np.ndarray | None] = {}
        if linear:
            if ctx.dispersions is None:  # one trajectory: every run of the task in one product
                if _CACHE.get("token") != ctx.token:
                    _CACHE.clear()
                    _CACHE.update(token=ctx.token, maps=_linear_maps(ctx.S.reshape(-1, ctx.S.shape[-1]), ctx.names,
                                                                     ctx.sigma, linear, ctx.prior))
                groups = [(_CACHE["maps"], ctx.S, list(range(len(runs))))]
            else:
                groups = [(_linear_maps(S.reshape(-1, S.shape[-1]), ctx.names, ctx.sigma, linear, ctx.prior), S, [j])
                          for j, (S, *_rest) in enumerate(flights)]
            for m in linear:
                est[m], std[m] = np.empty((len(runs), n)), np.empty((len(runs), n))
            for maps, S, idx in groups:
                S2 = S.reshape(-1, S.shape[-1])
                Y = np.stack([ys[j].reshape(-1) for j in idx], axis=-1)
                for m, lm in maps.items():
                    X, sd = lm.apply(S2, Y)  # D = K y + b and the solver's std
                    est[m][idx], std[m][idx] = X.T, sd.T
        rows = [None] * len(runs)
        if ctx.noise != "white" or ctx.robust not in (None, "auto"):  # each run's noise model, weights: every method
            from casep.analysis.problem import Problem
            from casep.workflows.solve import prepare_rows

            rows = [prepare_rows(Problem.from_arrays(S, y, t, names=ctx.names), ctx.noise, ctx.noise_tau, ctx.robust)
                    for y, (S, t, *_) in zip(ys, flights)]
        for method in other:
            runs_d = [_denoised(method, y) for y in ys]
            if runs_d[0][0] == "gls" and ctx.dispersions is None:  # one REML lattice for the task
                taus = estimate_tau_many(ctx.S, np.stack([y for _, y, _ in runs_d], axis=-1), ctx.t)
            else:
                taus = ["auto"] * len(runs_d)
            outs = [_solve(m, S, y, ctx.names, ctx.sigma, t, given, tau, prior=ctx.prior, bounds=ctx.bounds,
                           noise=ctx.noise, noise_tau=ctx.noise_tau, robust=ctx.robust, rows=rw)
                    for (m, y, given), tau, (S, t, *_), rw in zip(runs_d, taus, flights, rows)]
            est[method] = np.array([o[0] for o in outs])
            std[method] = None if outs[0][1] is None else np.array([o[1] for o in outs])
    draws = {name: np.array([f[4][name] for f in flights]) for name in (flights[0][4] if flights else {})}
    return {"runs": np.asarray(runs, dtype=np.int64), "truth": np.array([f[2] for f in flights]),
            "crlb": np.array([f[3] for f in flights]), "est": est, "std": std, "draws": draws}


def _task_size(method: str, runs: int) -> int:
    """Runs per task: a function of `runs` only, so the numbers do not depend on the workers.

    GLS: <= 16 runs sharing one REML lattice; others: about 16 tasks, at most 128 runs each.
    """
    if method.split("+")[-1] == "gls":
        return -(-runs // -(-runs // _GLS_CHUNK))  # <= _GLS_CHUNK, as even as possible
    return max(1, min(_BLOCK, -(-runs // 16)))


def _chunks(methods: Sequence[str], runs: int) -> list[range]:
    size = min(_task_size(m, runs) for m in methods)
    return [range(k, min(k + size, runs)) for k in range(0, runs, size)]


# -------------------------------------------------------------------------- execution
class _InProcess:
    """Tasks run here, in order (``workers=1``)."""

    def run(self, ctx, jobs):
        for key, args in jobs:
            yield key, _task(ctx, *args)


@contextmanager
def _deferred_signals():
    """Within: SIGINT and SIGTERM are held, then re-raised to the handlers of before (main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    old = {s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        if got:
            signal.raise_signal(got[0])


class _Dask:
    """Tasks on a Dask cluster: a LocalCluster of `workers` single-threaded processes, or `scheduler`.

    The local workers ignore SIGINT (:mod:`casep.workflows._dask_worker`: Ctrl-C reaches the
    whole process group; this process handles it and closes the cluster) and have one BLAS thread (Dask's pre-spawn
    environment sets OMP/MKL/OPENBLAS_NUM_THREADS=1; each task also limits it by threadpoolctl,
    which covers remote workers). They end with this process, even on SIGKILL (Dask's nanny
    pipe).
    """

    def __init__(self, stack: ExitStack, workers: int, scheduler: str | None) -> None:
        import logging

        import dask
        from distributed import Client, LocalCluster

        # An interrupted cluster's closing can leave asyncio tasks failed on closed comms; asyncio
        # logs them ("Task exception was never retrieved") on stderr: not ours to show.
        aio = logging.getLogger("asyncio")
        stack.callback(aio.setLevel, aio.level)
        aio.setLevel(logging.CRITICAL)
        if scheduler:
            try:
                self.client = stack.enter_context(Client(scheduler, timeout="20s"))
            except OSError as exc:  # unreachable: say which option
                raise ValueError(f"--scheduler {scheduler}: no Dask scheduler answers there ({exc})") from None
        else:
            # dashboard_address ":0": the scheduler's HTTP server (no dashboard without bokeh) on a
            # free port; None still binds 8787 and warns when another cluster holds it
            # Forked workers inherit casep, NumPy, SciPy and numba's compiled kernels already loaded
            # here; spawned ones import and compile them again (measured: ~3 s of CPU per worker).
            # Python >= 3.12 deprecates fork in a threaded process: spawn there.
            fork = "fork" in multiprocessing.get_all_start_methods() and sys.version_info < (3, 12)
            with _deferred_signals(), dask.config.set(
                    {"distributed.worker.multiprocessing-method": "fork" if fork else "spawn"}):
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=logging.CRITICAL,
                                       preload=["casep.workflows._dask_worker"])
                stack.enter_context(cluster)
                self.client = stack.enter_context(Client(cluster))
        self.ctx_future = None

    def run(self, ctx, jobs):
        from distributed import as_completed

        if self.ctx_future is None:
            self.ctx_future = self.client.scatter(ctx, broadcast=True, hash=False)
        futures = {self.client.submit(_task, self.ctx_future, *args, pure=False): key for key, args in jobs}
        try:
            for fut in as_completed(futures):
                yield futures[fut], fut.result()
        finally:
            self.client.cancel(list(futures))


# ------------------------------------------------------------------------------ store
_PART = "part-s{stage:02d}-t{task:05d}.parquet"


def _settings_diff(old: Any, new: Any, path: str = "") -> str:
    """What differs between two settings, down to the innermost key (``dispersions.launch_azimuth_deg.high:
    2 there, 3 now``), values cut at 80 characters."""
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        keys = [k for k in dict.fromkeys([*old, *new]) if old.get(k) != new.get(k)]
        return "; ".join(_settings_diff(old.get(k), new.get(k), f"{path}.{k}" if path else str(k)) for k in keys)
    return f"{path}: {json.dumps(old)[:80]} there, {json.dumps(new)[:80]} now"


class _Store:
    """``--out DIR``: settings.json, runs.parquet/ (one part per finished task), state.json, summary.json."""

    def __init__(self, out: str | os.PathLike, settings: dict) -> None:
        self.dir = Path(out)
        self.parts = self.dir / "runs.parquet"
        sfile = self.dir / "settings.json"
        if sfile.exists():
            old = json.loads(sfile.read_text(encoding="utf-8"))
            if old != settings:
                raise ValueError(f"--out {self.dir}: holds a campaign with other settings "
                                 f"({_settings_diff(old, settings)});"
                                 " use another folder, or the same settings to resume")
        else:
            self.dir.mkdir(parents=True, exist_ok=True)
            with atomic_open(sfile) as fh:
                fh.write(json.dumps(settings, indent=2) + "\n")
        self.parts.mkdir(exist_ok=True)
        self.finished: list[str] = []

    def load(self, stage: int, task: int, methods: Sequence[str], names: Sequence[str]) -> dict | None:
        """A finished task's results, read back from its part (None: not finished)."""
        import pyarrow.parquet as pq

        path = self.parts / _PART.format(stage=stage, task=task)
        if not path.exists():
            return None
        tab = pq.read_table(path)
        n = len(names)
        runs_col = tab.column("run").to_numpy()
        m = len(runs_col) // (n * len(methods))
        res: dict[str, Any] = {"runs": runs_col[: m * n: n].astype(np.int64), "est": {}, "std": {}}
        res["truth"] = tab.column("true").to_numpy()[: m * n].reshape(m, n)
        res["crlb"] = tab.column("crlb_std").to_numpy()[: m * n].reshape(m, n)
        res["draws"] = {c.removeprefix("draw_"): tab.column(c).to_numpy()[: m * n: n] for c in tab.column_names
                        if c.startswith("draw_")}
        for i, meth in enumerate(methods):
            sl = slice(i * m * n, (i + 1) * m * n)
            res["est"][meth] = tab.column("estimate").to_numpy()[sl].reshape(m, n)
            sd = tab.column("std").slice(sl.start, m * n)
            res["std"][meth] = None if sd.null_count == m * n else sd.to_numpy(zero_copy_only=False).reshape(m, n)
        self.finished.append(path.name)
        return res

    def save(self, stage: int, task: int, methods: Sequence[str], names: Sequence[str], res: dict) -> None:
        """Write a task's part atomically (temporary name, then renamed), then state.json."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        m, n = len(res["runs"]), len(names)
        k = len(methods)
        est = np.concatenate([res["est"][meth].reshape(-1) for meth in methods])
        sds = [pa.nulls(m * n, pa.float64()) if res["std"][meth] is None else pa.array(res["std"][meth].reshape(-1))
               for meth in methods]
        tab = pa.table({
            "run": np.tile(np.repeat(res["runs"], n), k),
            "method": pa.array(np.repeat(np.array(methods, dtype=object), m * n).tolist(), pa.string()),
            "coefficient": pa.array(np.tile(np.array(names, dtype=object), m * k).tolist(), pa.string()),
            "estimate": est,
            "std": pa.concat_arrays(sds),
            "true": np.tile(res["truth"].reshape(-1), k),
            "crlb_std": np.tile(res["crlb"].reshape(-1), k),
            # each run's dispersion draws (natural units of casep.simulation.dispersions), on every row of the run
            **{f"draw_{p}": np.tile(np.repeat(np.asarray(v, dtype=float), n), k)
               for p, v in res.get("draws", {}).items()},
        })
        name = _PART.format(stage=stage, task=task)
        tmp = self.parts / f".{name}.tmp"
        pq.write_table(tab, tmp)
        os.replace(tmp, self.parts / name)
        self.finished.append(name)
        with atomic_open(self.dir / "state.json") as fh:
            fh.write(json.dumps({"finished_tasks": sorted(self.finished)}, indent=1) + "\n")

# ---------------------------------------------------------------------------- batched path
def _linear_maps(S: np.ndarray, names, sigma: float, methods: Sequence[str], prior: Mapping | None = None) -> dict:
    """The estimators' own linear maps (``D = K y + b``) of the batched methods, registry defaults.

    ``ols``, ``rls`` (no forgetting, the registry's p0 and weight), ``pcr`` (default
    truncation), ``map`` (at the scenario's sigma, as the per-run path gives it) and
    ``ridge:<lambda>``: see :class:`casep.estimators.ols.LinearMap`.
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
    return {m: ridge_linear_map(S, float(m.split(":", 1)[1])) if m.startswith("ridge:") else build[m]()
            for m in methods}


# ---------------------------------------------------------------------------------- result
@dataclass(frozen=True)
class MonteCarloResult:
    """Per-method, per-coefficient Monte Carlo statistics (see module notes)."""

    scenario: str
    runs: int
    seed: int
    names: tuple[str, ...]
    units: tuple[str, ...]
    truth: np.ndarray
    crlb_std: np.ndarray
    estimates: dict[str, np.ndarray]  # method -> (runs, n)
    stds: dict[str, np.ndarray | None]
    seconds: dict[str, float] = field(default_factory=dict)
    truths: np.ndarray | None = None  # (runs, n) when each run drew its own (truth from a prior)
    dispersions: tuple[str, ...] = ()  # the dispersed vehicle/launch parameters (crlb_std: RMS over the runs)
    rate: float | None = None  # sample rate of the simulated flights, Hz
    resumed: int = 0  # tasks read back from --out (a resumed campaign) ...
    tasks: int = 0  # ... of this many
    draws: dict[str, np.ndarray] = field(default_factory=dict)  # dispersion parameter -> (runs,) drawn values

    def stats(self, method: str) -> dict[str, np.ndarray]:
        """bias, rms, efficiency, coverage95 arrays of one method (NaN where undefined)."""
        E = self.estimates[method] - (self.truth if self.truths is None else self.truths)
        with np.errstate(invalid="ignore", divide="ignore"):
            bias = np.mean(E, axis=0)
            rms = np.sqrt(np.mean(E**2, axis=0))
            eff = self.crlb_std / rms
            sd = self.stds.get(method)
            if sd is None:
                cov = np.full(E.shape[1], np.nan)
            else:  # over the runs that report an interval (bounded: not on a bound)
                has = np.isfinite(sd) & np.isfinite(E)
                hit = (np.abs(E) <= 1.96 * np.where(has, sd, 0.0)) & has
                cov = np.where(has.any(axis=0), hit.sum(axis=0) / np.maximum(has.sum(axis=0), 1), np.nan)
        return {"bias": bias, "rms": rms, "efficiency": eff, "coverage95": cov}

    def to_dict(self) -> dict[str, Any]:
        """The Monte Carlo JSON of ``docs/reference/file-formats.md``."""
        def f(v):
            return float(v) if np.isfinite(v) else None

        methods = {}
        for meth in self.estimates:
            st = self.stats(meth)
            methods[meth] = {"seconds": self.seconds.get(meth), "coefficients": [
                {"name": n, "unit": u, "true": float(tr), "bias": f(st["bias"][j]), "rms": f(st["rms"][j]),
                 "crlb_std": f(self.crlb_std[j]), "efficiency": f(st["efficiency"][j]),
                 "coverage95": f(st["coverage95"][j])}
                for j, (n, u, tr) in enumerate(zip(self.names, self.units, self.truth))]}
        out: dict[str, Any] = {"scenario": self.scenario, "runs": self.runs, "seed": self.seed}
        if self.rate is not None:
            out["rate_hz"] = float(self.rate)
        if self.truths is not None:
            out["truth_from_prior"] = True  # "true": the prior mean; errors against each run's own draw
        if self.dispersions:
            out["dispersions"] = list(self.dispersions)
        out["methods"] = methods
        return out

    def write_json(self, path) -> None:
        with atomic_open(path) as fh:
            fh.write(json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n")

    def write_csv(self, path) -> None:
        with atomic_open(path) as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(["method", "name", "unit", "true", "bias", "rms", "crlb_std", "efficiency", "coverage95"])
            for meth, d in self.to_dict()["methods"].items():
                for row in d["coefficients"]:
                    w.writerow([meth] + ["" if row[k] is None else row[k] for k in
                                         ("name", "unit", "true", "bias", "rms", "crlb_std", "efficiency",
                                          "coverage95")])

    def summary(self) -> str:
        """One line per method: median efficiency and coverage over the coefficients."""
        lines = [f"{'method':<18} {'median RMS/CRLB':>15} {'median efficiency':>17} {'median coverage95':>17}"
                 f" {'seconds':>8}"]
        for meth in self.estimates:
            st = self.stats(meth)
            ratio = 1.0 / st["efficiency"]
            cov = st["coverage95"]
            cov_s = f"{np.nanmedian(cov):.3f}" if np.any(np.isfinite(cov)) else "-"
            lines.append(f"{meth:<18} {np.nanmedian(ratio):>15.3f} {np.nanmedian(st['efficiency']):>17.3f} "
                         f"{cov_s:>17} {self.seconds.get(meth, float('nan')):>8.2f}")
        return "\n".join(lines)


class _Progress:
    """Progress of the Monte Carlo on stderr, counted in runs of the current stage.

    A stage is one per-run method, or all batched linear methods together (one pass over the
    runs). ``mode`` "bar": a bar redrawn in place (terminals); "lines": a plain line every
    `every` seconds and one at the end (logs, pipes); None: silent.
    """

    def __init__(self, runs: int, stages: Sequence[str], mode: str | None, every: float = 5.0) -> None:
        self.runs, self.stages, self.mode, self.every = runs, list(stages), mode, every
        self.stage, self.done = 0, 0
        self.t0 = self.last = time.monotonic()
        self.drawn = False

    def next_stage(self) -> None:
        self.stage, self.done = self.stage + 1, 0

    def __call__(self, k: int) -> None:
        self.done += k
        now = time.monotonic()
        if self.mode == "bar":
            self._write("\r" + self._bar() + self._text(now, short=True))
            self.drawn = True
        elif self.mode == "lines" and (now - self.last >= self.every or self._finished()):
            self._write(f"montecarlo: {self._text(now)}\n")
            self.last = now
        if self.mode == "bar" and self._finished():
            self.close()

    def close(self) -> None:
        """End the bar's line (also on interruption)."""
        if self.drawn:
            self._write("\n")
            self.drawn = False

    def _finished(self) -> bool:
        return self.stage == len(self.stages) - 1 and self.done >= self.runs

    def _bar(self, width: int = 24) -> str:
        fill = int(width * self.done / max(self.runs, 1))
        return f"[{'#' * fill}{'.' * (width - fill)}] "

    def _text(self, now: float, short: bool = False) -> str:
        frac = (self.stage * self.runs + self.done) / (len(self.stages) * self.runs)  # share of all work
        el = now - self.t0
        eta = f"ETA {el * (1 - frac) / frac:.0f} s" if frac > 0 else "ETA -"
        which = f"{self.stages[self.stage]} {self.done}/{self.runs} runs"
        if len(self.stages) > 1:
            which += f" (method {self.stage + 1} of {len(self.stages)}"
            which += ")" if short else f", {100 * frac:.0f} % of all)"
        else:
            which += "" if short else f" ({100 * frac:.0f} %)"
        return f"{which}, {el:.0f} s elapsed, {eta}" + ("  " if short else "")

    @staticmethod
    def _write(text: str) -> None:
        sys.stderr.write(text)
        sys.stderr.flush()


def _progress_mode(progress: bool | None) -> str | None:
    tty = sys.stderr.isatty()
    if progress is None:
        return "bar" if tty else None
    return ("bar" if tty else "lines") if progress else None


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
    flight=None,
    truth: Mapping | None = None,
    noise: str = "white",
    tau=None,
    robust: str | None = "auto",
) -> MonteCarloResult:
    """Run `runs` noise draws of a scenario through each method.

    Parameters
    ----------
    scenario : str or Scenario
    runs : int
    methods : sequence of str
        See :data:`METHOD_HELP`.
    seed : int
        Root of the per-run seed sequences (see :func:`_run_seq`).
    rate : float, optional
        Sample rate, Hz (default: the scenario's).
    workers : int, optional
        Dask worker processes of the LocalCluster (one thread each; default: all cores). 1 runs
        the tasks in this process.
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
        Without a noise there, white noise of the flight's own least-squares residual std.
    noise, tau, robust : optional
        The noise model every method assumes and the robust fit, as :func:`casep.separate` takes
        them (default ``"white"``, not robust: the methods as they are, the linear ones batched;
        otherwise every method runs per run through :func:`casep.workflows.solve.solve_problem`).
        The scenario's tracking gaps remove rows in every case.
    """
    from casep.analysis.noise import check_noise_kind
    from casep.analysis.rows import ROBUST_CHOICES

    check_noise_kind(noise)
    noise_tau = tau  # (`tau` below is the scenario's, for the CRLB)
    if (noise != "white" or robust not in (None, "auto", "none")) and any(m.startswith("wavelet+") for m in methods):
        raise ValueError("wavelet+<method> de-noises dv: it does not combine with `noise` other than 'white' or "
                         "with `robust`")
    if robust is not None and robust not in ROBUST_CHOICES:
        raise ValueError(f"`robust` must be one of {', '.join(ROBUST_CHOICES)} or None, got {robust!r}")
    if tau is not None and noise != "gm":
        raise ValueError(f"`tau` given with noise {noise!r}: a given correlation time means noise 'gm'")
    robust = None if robust == "none" else robust
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise ValueError(f"`runs` must be an int >= 1, got {runs!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"`seed` must be an int >= 0, got {seed!r}")
    runs, seed = int(runs), int(seed)
    methods = [_check_method(m) for m in methods]
    if not methods:
        raise ValueError("`methods` is empty")
    if len(set(methods)) != len(methods):
        raise ValueError(f"`methods` names a method twice: {', '.join(methods)}")
    own = None
    if flight is not None or truth is not None:
        if flight is None or truth is None:
            raise ValueError("`flight` and `truth` go together: a Monte Carlo on one's own trajectory needs both")
        if dispersions is not None:
            raise ValueError("`dispersions` fly the scenario's vehicle; with `flight` the trajectory is given")
        own = _own_trajectory(scenario, flight, truth)
        sc, model, truth = own["scenario"], own["model"], own["truth"]
        traj = None
    else:
        sc, traj, model, truth = scenario_setup(scenario, rate)
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
        _check_truth_prior(tp, model, "`truth_prior`")
    if dispersions is not None:
        from casep.simulation.dispersions import parse_dispersions

        dispersions = parse_dispersions(dispersions, len(sc.vehicle.stages), "`dispersions`", vehicle=sc.vehicle)
    sigma = sc.noise.sigma
    tau = sc.noise.tau if sc.noise.kind == "ar1" else None
    S = t = crlb = None
    if dispersions is None:  # every run shares the trajectory
        t_all = traj.t if own is None else own["t"]
        keep = sc.noise.keep_mask(t_all)  # tracking gaps: no rows there
        t = t_all[keep]
        S = build_sv(model, t_all, traj.specific_force if own is None else own["f"])[keep]
        crlb = np.sqrt(np.diag(crlb_covariance(S, sigma, t=t if tau else None, tau=tau)))
    ctx = _Context(token=uuid.uuid4().hex, scenario=sc, names=names, sigma=sigma, tau=tau, seed=seed, truth=truth,
                   prior=prior, bounds=bounds, truth_prior=tp, dispersions=dispersions, S=S, t=t, crlb=crlb,
                   noise=noise, noise_tau=noise_tau, robust=robust)
    per_run_noise = noise != "white" or robust not in (None, "auto")
    lin = [m for m in methods if batched and not per_run_noise and (m in BATCHED or m.startswith("ridge:"))]
    other = [m for m in methods if m not in lin]
    # stages: (linear, per-run) methods; nominal: the linear maps together, then each per-run
    # method; dispersed: all in one stage (each run's trajectory is simulated once)
    if dispersions is None:
        stages = ([(lin, [])] if lin else []) + [([], [m]) for m in other]
    else:
        stages = [(lin, other)]
    chunks = [_chunks(a + b, runs) for a, b in stages]
    store = None
    if out is not None:
        settings = {"scenario": sc.name, "rate": sc.rate, "runs": runs, "seed": seed, "methods": methods,
                    **({"flight": own["record"]} if own is not None else {}),
                    "batched": bool(batched), "prior": prior, "bounds": bounds, "dispersions": dispersions,
                    "truth_from_prior": truth_prior, "tasks": [len(c) for c in chunks]}
        if per_run_noise:  # (absent for the default, so campaigns written before stay resumable)
            settings["noise"] = {"noise": noise, "tau": noise_tau, "robust": robust}
        store = _Store(out, json.loads(json.dumps(settings)))
    n_workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if n_workers < 1:
        raise ValueError(f"`workers` must be >= 1, got {workers!r}")
    groups = [a + b for a, b in stages]
    bar = _Progress(runs, [",".join(g) for g in groups], _progress_mode(progress))
    results: list[dict[int, dict]] = [{} for _ in stages]
    if store is not None:
        for si, g in enumerate(groups):
            for ti in range(len(chunks[si])):
                r = store.load(si, ti, g, names)
                if r is not None:
                    results[si][ti] = r
    n_tasks = sum(len(c) for c in chunks)
    resumed = sum(len(r) for r in results)
    pending = n_tasks - resumed
    per_run_work = dispersions is not None or bool(other)
    use_dask = dask if dask is not None else bool(scheduler) or (n_workers > 1 and per_run_work and pending > 1)
    secs: dict[str, float] = {}
    with ExitStack() as stack:
        stack.callback(bar.close)
        engine = _Dask(stack, n_workers, scheduler) if use_dask and pending else _InProcess()
        for si, (linear, per_run) in enumerate(stages):
            group = groups[si]
            t0 = time.perf_counter()
            done = sum(len(r["runs"]) for r in results[si].values())
            if done:
                bar(done)
            jobs = [((si, ti), (linear, per_run, list(c))) for ti, c in enumerate(chunks[si]) if ti not in results[si]]
            for (si_, ti), res in engine.run(ctx, jobs):
                if store is not None:
                    store.save(si_, ti, group, names, res)
                results[si][ti] = res
                bar(len(res["runs"]))
            for m in group:
                secs[m] = (time.perf_counter() - t0) / len(group)
            if si + 1 < len(stages):
                bar.next_stage()
    est: dict[str, np.ndarray] = {}
    std: dict[str, np.ndarray | None] = {}
    for si, group in enumerate(groups):
        parts = [results[si][ti] for ti in range(len(chunks[si]))]
        for m in group:
            est[m] = np.concatenate([p["est"][m] for p in parts])
            std[m] = None if parts[0]["std"][m] is None else np.concatenate([p["std"][m] for p in parts])
    first = [results[0][ti] for ti in range(len(chunks[0]))]
    truths = np.concatenate([p["truth"] for p in first])
    crlbs = np.concatenate([p["crlb"] for p in first])
    draws = {k: np.concatenate([p["draws"][k] for p in first]) for k in (first[0].get("draws") or {})} if first else {}
    with np.errstate(invalid="ignore"):
        crlb_std = crlb if dispersions is None else np.sqrt(np.mean(crlbs**2, axis=0))  # RMS over the runs
    centre = truth if tp is None else np.where(np.isfinite(tp[1]), tp[0], truth)
    res = MonteCarloResult(scenario=sc.name, runs=runs, seed=seed, rate=float(sc.rate), names=names, units=model.units,
                           truth=centre, crlb_std=crlb_std, estimates={m: est[m] for m in methods},
                           stds={m: std[m] for m in methods}, seconds=secs,
                           truths=truths if tp is not None else None,
                           dispersions=tuple(dispersions) if dispersions else (), resumed=resumed, tasks=n_tasks,
                           draws=draws)
    if store is not None:
        res.write_json(store.dir / "summary.json")
    return res

class Terminated(BaseException):
    """SIGTERM received (see :func:`sigterm_raises`); like KeyboardInterrupt, not an Exception."""


@contextmanager
def sigterm_raises():
    """Within: SIGTERM raises :class:`Terminated` in the main thread (elsewhere a no-op).

    So that ``casep montecarlo`` ends its workers and exits 143 with one line instead of
    dying with them orphaned.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise Terminated

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def write_figure(res: MonteCarloResult, path: str | os.PathLike) -> Path:
    """RMS error / CRLB std per coefficient and method (log scale)."""
    from casep.reporting.plots import _pyplot, _save

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(max(9, 0.3 * len(res.names)), 4.5))
    x = np.arange(len(res.names))
    for meth in res.estimates:
        ax.semilogy(x, 1.0 / res.stats(meth)["efficiency"], "o-", ms=3, lw=1, label=meth)
    ax.axhline(1.0, color="k", lw=1, ls="--")
    ax.set_xticks(x, res.names, rotation=90, fontsize=7)
    ax.set_ylabel("RMS error / CRLB std")
    ax.set_title(f"Monte Carlo, scenario {res.scenario}, {res.runs} runs (1 = efficient)")
    ax.legend(fontsize=8, ncol=3)
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


#: A truth prior may reach this many declared magnitudes (mean + 6 std): wide priors of poorly known
#: second-order terms (the demo's: 1e4 x) pass, 1e308 does not.
TRUTH_PRIOR_LIMIT = 1e6


def _check_truth_prior(tp: tuple[np.ndarray, np.ndarray], model, source: str) -> None:
    """Refuse a truth prior whose draws (mean +- 6 std) reach beyond :data:`TRUTH_PRIOR_LIMIT` times a
    coefficient's declared magnitude (no instrument is that far off its spec sheet), or overflow (std 1e308)."""
    mu, sd = tp
    scales = model.scales
    for j, name in enumerate(model.names):
        if not np.isfinite(sd[j]):
            continue  # not drawn
        reach = abs(float(mu[j])) + 6.0 * float(sd[j])
        limit = TRUTH_PRIOR_LIMIT * scales[name] if name in scales else np.finfo(float).max / 1e10
        if not reach <= limit:
            raise ValueError(f"{source}: `{name}`: draws reach |mean| + 6 std = {reach:.4g} {model.units[j]}, beyond "
                             + (f"{TRUTH_PRIOR_LIMIT:g} x its declared magnitude {scales[name]:g} (no instrument is "
                                "that far off its spec sheet)" if name in scales else "what a flight can hold"))


def _own_trajectory(scenario, flight, truth: Mapping) -> dict[str, Any]:
    """The scenario of a Monte Carlo on one's own flight: its times, specific force, model, truth and noise."""
    import dataclasses

    from casep.analysis.problem import Problem
    from casep.io.files import read_flight
    from casep.io.flight import FlightData
    from casep.io.provenance import file_record
    from casep.simulation.noise import NoiseModel
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import _truth_vector

    sc = get_scenario(scenario)
    fl = flight if isinstance(flight, FlightData) else read_flight(flight)
    if not isinstance(truth, Mapping):
        raise ValueError(f"`truth` must be a mapping {{name: value}} or a truth file's dict, got "
                         f"{type(truth).__name__}")
    coefs = truth["coefficients"] if isinstance(truth.get("coefficients"), Mapping) else truth
    model = _model(str(truth.get("model", sc.model)))
    vec = _truth_vector(model, {k: v for k, v in coefs.items() if k not in ("model", "noise")}, "`truth`")
    if isinstance(truth.get("noise"), Mapping):
        try:
            noise = NoiseModel(**truth["noise"])
        except (TypeError, ValueError) as exc:
            raise ValueError(f"`truth`: `noise` must be a noise model of casep simulate ({exc})") from None
        how = "the truth file's"
    else:  # the flight's own least-squares residual std: its tracking noise
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllConditionedWarning)
            pb = Problem.from_flight(fl, model)
        noise = NoiseModel("white", float(np.sqrt(pb.ls_rss() / max(pb.m - pb.rank().rank, 1))))
        how = "the flight's least-squares residual std"
    rate = float(1.0 / np.median(np.diff(fl.t)))
    name = f"flight {Path(fl.source).name}"
    sc = dataclasses.replace(sc, name=name, description=f"own trajectory {fl.source}; noise: {how}", rate=rate,
                             model=model.name, truth=dict(zip(model.names, vec.tolist())), noise=noise)
    record = file_record(fl.source, "flight") if Path(fl.source).is_file() else {"file": fl.source}
    return {"scenario": sc, "model": model, "truth": vec, "t": np.asarray(fl.t), "f": np.asarray(fl.f),
            "record": {**record, "noise": noise.to_dict(), "noise_from": how}}
