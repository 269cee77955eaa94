"""Seeded Monte Carlo of the estimators against the Cramer-Rao bound.

The scenario's trajectory (hence S_V and the true dv) is the same in every run; run k adds
tracking noise drawn from ``numpy.random.default_rng(SeedSequence(seed).spawn(runs)[k])``,
so a run's data do not depend on how runs are batched or distributed over processes.

Methods whose estimate is a fixed linear function of the data (``ols``, ``rls`` with no
forgetting, ``ridge:<lambda>``, ``pcr``, ``map`` with the scenario's sigma) are solved for
all runs at once through the estimator's own linear map ``D = K y + b``
(:func:`casep.estimators.ols.ols_linear_map` and its siblings, tested equal to the solvers),
applied to a matrix of right-hand sides in blocks; S_V is built once per flight. The others
(``rels``, ``ridge`` with GCV, ``bounded``, ``gls``, ``wavelet+<method>``) call the public solver per
run in a process pool using every core. Both paths report the same numbers as the solvers
(tested).

Statistics per method and coefficient (natural units): ``bias`` = mean error, ``rms``,
``crlb_std`` (white: sigma^2 (S^T S)^-1; Gauss-Markov scenarios: the GLS bound),
``efficiency`` = crlb_std / rms, ``coverage95`` = share of runs with
``|error| <= 1.96 std`` among the runs that report a std for that coefficient (bounded least
squares reports none on a bound; null when the method gives none).
"""

from __future__ import annotations

import csv
import ctypes
import json
import multiprocessing
import os
import signal
import sys
import threading
import time
import warnings
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from casep.io._atomic import atomic_open
from casep.estimators.bounded import parse_bounds
from casep.analysis.diagnostics import crlb_covariance
from casep.exceptions import IllConditionedWarning
from casep.estimators.map import parse_prior
from casep.estimators.registry import METHODS as _REGISTRY
from casep.simulation.paper import demo_bounds, demo_prior
from casep.simulation.scenarios import Scenario
from casep.simulation.simulate import scenario_setup
from casep.model.sv import build_sv

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
           bounds: Mapping | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """One run of a (de-noised) method through the public solvers: estimate and reported std.

    `given` is the sigma handed to the solver (None: estimated), `tau` the GLS correlation time,
    `prior` and `bounds` those of ``map`` and ``bounded`` (default: the paper's demo values).
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
    r = run_method(method, S, y, t, opts, names=names, sigma=given)  # the registry's solver and defaults
    return r.estimate, r.std


_WORKER: dict[str, Any] = {}
_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _exit_with_parent(parent: int) -> None:
    """End this worker when process `parent` ends, even by SIGKILL (no orphans left waiting).

    Linux: the kernel sends SIGKILL on the parent's death (prctl PR_SET_PDEATHSIG); elsewhere,
    and as a fallback, a daemon thread polls the parent id every 0.5 s.
    """
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the line above
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="casep-parent-watch", daemon=True).start()


def _pool_worker_init(parent: int, *args) -> None:
    from threadpoolctl import threadpool_limits

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and ends the workers
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the parent's handler (forked): terminate() ends us
    _exit_with_parent(parent)
    # One BLAS/OpenMP thread per worker, for the worker's life: several per worker oversubscribe
    # the cores (measured 6-30x slower on 2 cores).
    _WORKER["blas_limit"] = threadpool_limits(limits=1)
    _worker_init(*args)


def _worker_init(S, clean, t, scenario, names, sigma, prior=None, bounds=None):
    warnings.simplefilter("ignore", IllConditionedWarning)
    _WORKER.update(S=S, clean=clean, t=t, scenario=scenario, names=names, sigma=sigma, prior=prior, bounds=bounds)


def _worker_run(args) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """A chunk of runs of one method; GLS estimates tau for the whole chunk at once."""
    from casep.estimators.gls import estimate_tau_many

    method, seqs = args
    w = _WORKER
    runs = [_denoised(method, w["clean"] + _noise(w["scenario"], w["t"], seq)) for seq in seqs]
    if runs[0][0] == "gls":  # one REML lattice for the chunk, then the public solver at each tau
        taus = estimate_tau_many(w["S"], np.stack([y for _, y, _ in runs], axis=-1), w["t"])
    else:
        taus = ["auto"] * len(runs)
    return [_solve(m, w["S"], y, w["names"], w["sigma"], w["t"], given, tau, prior=w["prior"], bounds=w["bounds"])
            for (m, y, given), tau in zip(runs, taus)]


@contextmanager
def _worker_pool(n_workers: int, initargs: tuple):
    """A process pool of single-threaded-BLAS workers that die with this process.

    Forked, not spawned: a spawned worker re-imports the caller's main script, which re-runs
    an unguarded notebook-style script (``examples/*.py``) in every worker. The BLAS thread
    limit is set in each worker by threadpoolctl (:func:`_pool_worker_init`). On any
    exception, KeyboardInterrupt included, the workers are terminated at once rather than
    awaited.
    """
    ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    main = threading.current_thread() is threading.main_thread()
    old_int = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None  # children inherit SIG_IGN
    try:
        pool = ctx.Pool(n_workers, initializer=_pool_worker_init, initargs=(os.getpid(), *initargs))
    finally:
        if main:
            signal.signal(signal.SIGINT, old_int)
    try:
        yield pool
    except BaseException:
        pool.terminate()
        raise
    else:
        pool.close()
        pool.join()


def _chunks(method: str, runs: int, n_workers: int) -> list[range]:
    """Runs per job: GLS in chunks that depend on `runs` only (same numbers for any `workers`)."""
    if method.split("+")[-1] == "gls":
        size = -(-runs // -(-runs // _GLS_CHUNK))  # <= _GLS_CHUNK, as even as possible
    else:
        size = max(1, runs // (4 * n_workers))
    return [range(k, min(k + size, runs)) for k in range(0, runs, size)]


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


def _batched(maps, S2, clean2, scenario, t, seqs, progress) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every run of every linear method, `_BLOCK` right-hand sides at a time."""
    runs, n = len(seqs), S2.shape[1]
    out = {k: (np.empty((runs, n)), np.empty((runs, n))) for k in maps}
    for b0 in range(0, runs, _BLOCK):
        idx = range(b0, min(b0 + _BLOCK, runs))
        Y = np.empty((S2.shape[0], len(idx)))
        for j, k in enumerate(idx):
            Y[:, j] = clean2 + _noise(scenario, t, seqs[k]).reshape(-1)
        for name, lm in maps.items():
            X, std = lm.apply(S2, Y)  # D = K y + b and the solver's std, all runs of the block
            out[name][0][b0:b0 + len(idx)] = X.T
            out[name][1][b0:b0 + len(idx)] = std.T
        progress(len(idx))
    return out


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

    def stats(self, method: str) -> dict[str, np.ndarray]:
        """bias, rms, efficiency, coverage95 arrays of one method (NaN where undefined)."""
        E = self.estimates[method] - self.truth
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
        """The Monte Carlo JSON of ``interfaces.md``."""
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
        return {"scenario": self.scenario, "runs": self.runs, "seed": self.seed, "methods": methods}

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
) -> MonteCarloResult:
    """Run `runs` noise draws of a scenario through each method.

    Parameters
    ----------
    scenario : str or Scenario
    runs : int
    methods : sequence of str
        See :data:`METHOD_HELP`.
    seed : int
        Root of the per-run seed sequence.
    rate : float, optional
        Sample rate, Hz (default: the scenario's).
    workers : int, optional
        Processes for the per-run methods (default: all cores; 1 runs in this process).
    progress : bool, optional
        Progress on stderr: True, a bar on a terminal and a plain line with the ETA every 5 s
        otherwise; False, none; default: the bar on a terminal only.
    batched : bool, optional
        Use the one-factorisation path for the linear methods (False: per run, for checks).
    prior, bounds : mapping, optional
        The prior of ``map`` (``{name: {"mean": m, "std": s}}``) and the bounds of ``bounded``
        (``{name: [lo, hi] | value}``), natural units, as ``casep separate --prior/--bounds``
        take them. Default: the paper's demo values (:func:`casep.simulation.paper.demo_prior`,
        :func:`casep.simulation.paper.demo_bounds`).
    """
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise ValueError(f"`runs` must be an int >= 1, got {runs!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"`seed` must be an int >= 0, got {seed!r}")
    methods = [_check_method(m) for m in methods]
    if not methods:
        raise ValueError("`methods` is empty")
    sc, traj, model, truth = scenario_setup(scenario, rate)  # every run shares the trajectory
    if prior is not None:
        parse_prior(prior, model.names)  # checked once, before any run
    if bounds is not None:
        parse_bounds(bounds, model.names)
    t = traj.t
    S = build_sv(model, t, traj.specific_force)
    clean = S @ truth
    sigma = sc.noise.sigma
    tau = sc.noise.tau if sc.noise.kind == "ar1" else None
    crlb = np.sqrt(np.diag(crlb_covariance(S, sigma, t=t if tau else None, tau=tau)))
    seqs = np.random.SeedSequence(seed).spawn(runs)
    names = model.names
    lin = [m for m in methods if batched and (m in BATCHED or m.startswith("ridge:"))]
    other = [m for m in methods if m not in lin]
    bar = _Progress(runs, ([",".join(lin)] if lin else []) + other, _progress_mode(progress))
    est: dict[str, np.ndarray] = {}
    std: dict[str, np.ndarray | None] = {}
    secs: dict[str, float] = {}
    n_workers = (os.cpu_count() or 1) if workers is None else int(workers)
    with warnings.catch_warnings(), ExitStack() as stack:
        stack.callback(bar.close)
        warnings.simplefilter("ignore", IllConditionedWarning)
        if lin:
            t0 = time.perf_counter()
            S2 = S.reshape(-1, S.shape[-1])
            maps = _linear_maps(S2, names, sigma, lin, prior)
            res = _batched(maps, S2, clean.reshape(-1), sc, t, seqs, bar)
            dt = time.perf_counter() - t0
            for m_ in lin:
                est[m_], std[m_] = res[m_]
                secs[m_] = dt / len(lin)
            if other:
                bar.next_stage()
        initargs = (S, clean, t, sc, names, sigma, prior, bounds)
        if other and n_workers > 1 and runs > 1:
            run_jobs = stack.enter_context(_worker_pool(n_workers, initargs)).imap
        else:
            _worker_init(*initargs)
            run_jobs = map
        for i, m_ in enumerate(other):
            t0 = time.perf_counter()
            outs = []
            for o in run_jobs(_worker_run, [(m_, [seqs[k] for k in c]) for c in _chunks(m_, runs, n_workers)]):
                outs.extend(o)
                bar(len(o))
            est[m_] = np.array([o[0] for o in outs])
            std[m_] = None if outs[0][1] is None else np.array([o[1] for o in outs])
            secs[m_] = time.perf_counter() - t0
            if i + 1 < len(other):
                bar.next_stage()
    ordered = {m_: est[m_] for m_ in methods}
    return MonteCarloResult(scenario=sc.name, runs=runs, seed=seed, names=names, units=model.units,
                            truth=truth, crlb_std=crlb, estimates=ordered, stds={m_: std[m_] for m_ in methods},
                            seconds=secs)


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
