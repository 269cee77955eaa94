"""Seeding, the campaign's context and the task: a chunk of runs of a stage's methods.

Run k draws its tracking noise from ``default_rng(SeedSequence(seed, spawn_key=(k,)))`` (=
``SeedSequence(seed).spawn(runs)[k]``), its dispersed vehicle from spawn key ``(k, 0)`` and its
true coefficients from ``(k, 1)`` (:func:`run_seq`); tasks are cut by :func:`chunks` from the
number of runs only. So a run's numbers depend on the seed and k, not on how runs are grouped
into tasks or which worker runs them.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from casep.checks.diagnostics import diagnose
from casep.exceptions import IllConditionedWarning
from casep.model.sv import build_sv
from casep.montecarlo.methods import MethodSpec, linear_maps, solve_runs
from casep.simulation.scenarios import Scenario

__all__ = ["BLOCK", "Context", "chunks", "per_run_noise", "reported_crlb", "run_seq", "run_task"]

BLOCK = 128  # most runs per task (columns of one block of right-hand sides)


def run_seq(seed: int, k: int, stream: int | None = None) -> np.random.SeedSequence:
    """Run k's seed sequence: noise ``(k,)`` (= ``SeedSequence(seed).spawn(runs)[k]``), dispersion
    ``(k, 0)``, true coefficients ``(k, 1)``: a run's numbers depend on the seed and k only."""
    return np.random.SeedSequence(seed, spawn_key=(k,) if stream is None else (k, stream))


@dataclass(frozen=True)
class Context:
    """What every task of one campaign needs (scattered once to the workers).

    The model and the linear maps of the nominal trajectory are built on first use in each
    process and kept on this object, so they live as long as the campaign and are never sent
    (see ``__getstate__``).
    """

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
    noise: Any = None  # the NoiseSpec the methods assume (None: white, no robust fit)
    fits: Mapping[str, Any] = field(default_factory=dict)  # each per-run method's FitSpec, by its text
    linear: tuple[str, ...] = ()  # the batched methods of the campaign
    magnitudes: Mapping[str, float] = field(default_factory=dict)  # the model's declared ones (ErrorModel.scales)


    @cached_property
    def model(self) -> Any:
        """The scenario's error model (dispersed runs build their S_V with it)."""
        from casep.model.loader import load_model

        return load_model(self.scenario.model)

    @cached_property
    def nominal_maps(self) -> dict[str, Any]:
        """The linear maps of the batched methods on the nominal trajectory."""
        assert self.S is not None
        return linear_maps(self.S.reshape(-1, self.S.shape[-1]), self.names, self.sigma, self.linear, self.prior,
                           self.magnitudes)

    def __getstate__(self) -> dict[str, Any]:
        # the cached model (CasADi, not picklable) and maps are rebuilt where they are used
        return {k: v for k, v in self.__dict__.items() if k not in ("model", "nominal_maps")}


def per_run_noise(noise: Any) -> bool:
    """Each run's rows need a noise model or a robust fit under the NoiseSpec `noise` (prepared once per run
    for every method; the linear methods then run per run, not batched). None: white, no robust fit."""
    return noise is not None and (noise.kind != "white" or noise.robust is not None)


def reported_crlb(S: np.ndarray, t: np.ndarray, sigma: float, tau: float | None, names: Sequence[str],
                  magnitudes: Mapping[str, float]) -> np.ndarray:
    """The CRLB std per coefficient of the regression `S` ``(N, 3, n)`` as the results report it
    (:func:`casep.checks.diagnostics.diagnose` with the model's declared `magnitudes`): NaN for an unidentifiable
    coefficient, the bound of the solution of least size in declared magnitudes for an exactly dependent one
    whose partners the flight barely excites; Gauss-Markov (`tau`) or white."""
    return diagnose(S, sigma=sigma, t=t if tau else None, tau=tau, names=names, scales=magnitudes).crlb_std


Flight = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, float]]


def flight(ctx: Context, k: int) -> Flight:
    """Run k's S_V, times, true coefficients, CRLB std and dispersion draws (nominal or dispersed)."""
    truth = ctx.truth
    if ctx.truth_prior is not None:
        mu, sd = ctx.truth_prior
        fin = np.isfinite(sd)
        truth = truth.copy()
        truth[fin] = mu[fin] + sd[fin] * np.random.default_rng(run_seq(ctx.seed, k, 1)).standard_normal(fin.sum())
    if ctx.dispersions is None:
        assert ctx.S is not None and ctx.t is not None and ctx.crlb is not None
        return ctx.S, ctx.t, truth, ctx.crlb, {}
    from casep.simulation.dispersions import disperse_vehicle, draw_dispersion
    from casep.simulation.trajectory import simulate_boost

    values = draw_dispersion(ctx.dispersions, np.random.default_rng(run_seq(ctx.seed, k, 0)))
    try:
        traj = simulate_boost(disperse_vehicle(ctx.scenario.vehicle, values), ctx.scenario.rate)
    except (ValueError, RuntimeError) as exc:  # a draw the vehicle cannot fly: say which run and which values
        drawn = ", ".join(f"{n} {v:.6g}" for n, v in values.items())
        raise ValueError(f"run {k}: the dispersed vehicle ({drawn}) cannot be flown: {exc}. Narrow the "
                         "--dispersions (the same seed draws the same values again)") from None
    from casep.simulation.simulate import sv_inputs, with_roll

    traj = with_roll(ctx.scenario, traj)
    force, signals = sv_inputs(ctx.scenario, traj, ctx.model, ctx.truth)
    keep = ctx.scenario.noise.keep_mask(traj.t)  # tracking gaps: no rows there
    S = build_sv(ctx.model, traj.t, force, signals=signals)[keep]
    t = traj.t[keep]
    return S, t, truth, reported_crlb(S, t, ctx.sigma, ctx.tau, ctx.names, ctx.magnitudes), values


def run_task(ctx: Context, linear: Sequence[MethodSpec], other: Sequence[MethodSpec],
             runs: Sequence[int]) -> dict[str, Any]:
    """Runs `runs` of the `linear` methods (their linear maps) and the `other` (per-run) methods.

    Linear methods are applied to all runs sharing a trajectory at once (the whole task when
    nominal, run by run when dispersed). Returns run ids, true coefficients, CRLB std, dispersion
    draws and per method the estimates and stds, ``(len(runs), n)`` each (std None: the method
    gives none).
    """
    from threadpoolctl import threadpool_limits

    n = len(ctx.names)
    with threadpool_limits(limits=1), warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        flights = [flight(ctx, k) for k in runs]
        # dv = S_V D_true + noise, each run its own noise stream
        ys = [S @ tr + ctx.scenario.noise.sample(t, np.random.default_rng(run_seq(ctx.seed, k)))
              for k, (S, t, tr, *_) in zip(runs, flights)]
        est: dict[str, np.ndarray] = {}
        std: dict[str, np.ndarray | None] = {}
        if linear:
            texts = [m.text for m in linear]
            if ctx.dispersions is None:  # one trajectory: every run of the task in one product
                assert ctx.S is not None
                groups = [(ctx.nominal_maps, ctx.S, list(range(len(runs))))]
            else:
                groups = [(linear_maps(S.reshape(-1, S.shape[-1]), ctx.names, ctx.sigma, texts, ctx.prior,
                                       ctx.magnitudes), S, [j])
                          for j, (S, *_rest) in enumerate(flights)]
            est_l = {m: np.empty((len(runs), n)) for m in texts}
            std_l = {m: np.empty((len(runs), n)) for m in texts}
            for maps, S, idx in groups:
                S2 = S.reshape(-1, S.shape[-1])
                Y = np.stack([ys[j].reshape(-1) for j in idx], axis=-1)
                for m in texts:
                    X, sd = maps[m].apply(S2, Y)  # D = K y + b and the solver's std
                    est_l[m][idx], std_l[m][idx] = X.T, sd.T
            est.update(est_l)
            std.update(std_l)
        rows = None
        if per_run_noise(ctx.noise):  # each run's noise model and weights, worked out once for every method
            from casep.estimators.solve import rows_for
            from casep.regression.problem import Problem

            rows = [rows_for(Problem.from_arrays(S, y, t, names=ctx.names, magnitudes=ctx.magnitudes), ctx.noise)
                    for y, (S, t, *_) in zip(ys, flights)]
        shared = (ctx.S, ctx.t) if ctx.dispersions is None and ctx.S is not None and ctx.t is not None else None
        for spec in other:
            est[spec.text], std[spec.text] = solve_runs(ctx.fits[spec.text], ys, [(S, t) for S, t, *_ in flights],
                                                        names=ctx.names, rows=rows, shared=shared,
                                                        magnitudes=ctx.magnitudes)
    draws = {name: np.array([f[4][name] for f in flights]) for name in (flights[0][4] if flights else {})}
    return {"runs": np.asarray(runs, dtype=np.int64), "truth": np.array([f[2] for f in flights]),
            "crlb": np.array([f[3] for f in flights]), "est": est, "std": std, "draws": draws}


def _task_size(spec: MethodSpec, runs: int) -> int:
    """Runs per task: a function of `runs` only, so the numbers do not depend on the workers.

    A method with a limit of its own (GLS: runs sharing one REML lattice): at most that many,
    as even as possible; others: about 16 tasks, at most :data:`BLOCK` runs each.
    """
    most = spec.max_task_runs
    if most:
        return -(-runs // -(-runs // most))  # ceil(runs / ceil(runs / most)) <= most
    return max(1, min(BLOCK, -(-runs // 16)))


def chunks(methods: Sequence[MethodSpec], runs: int) -> list[range]:
    """The tasks of a stage of `methods`: consecutive ranges of run numbers."""
    size = min(_task_size(m, runs) for m in methods)
    return [range(k, min(k + size, runs)) for k in range(0, runs, size)]
