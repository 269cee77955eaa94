"""Solve a problem under its noise model: whitened rows for every estimator, robust if asked.

The noise model, the robust weights and the removed samples belong to the data, not to a
method: :func:`casep.regression.rows.prepare_rows` works them out once for a
problem, and :func:`solve_problem` hands the resulting rows to any registered method, so its std
hold in coloured noise and with glitches, and every method of a comparison sees the same rows.

Residuals are reported on the raw rows (``dv - S_V D``) of every sample.

Several flights (:class:`~casep.regression.joint.Flights`) go through the same entry point :func:`fit`:
every rule of the request applies to each flight as it does to one flight alone (de-noising with each
flight's own wavelet sigma, the noise model per flight and axis, the robust fit and the outlier exclusion
on each flight's own rows, or a method's own rows: GLS whitens each flight by its own tau); the flights
are then combined into one whitened :class:`~casep.regression.joint.JointProblem` over
``theta = [shared, per-flight(1), ..., per-flight(K)]`` (:func:`joint_rows`) and solved by the method.
On the joint result: HAC std (Newey-West within each flight, never across two), the studentized outlier
flags (each named by its flight) and, per flight, one flight's residual checks (noise-free data,
outliers, time offset, a given sigma) on that flight's own residuals ``dv_k - S_k P_k theta``.

``std="hac"`` replaces a white-noise least-squares fit's std by the Newey-West sandwich
(:func:`hac_covariance`).
"""

from __future__ import annotations

import dataclasses
import types
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from casep.estimators.registry import METHODS
from casep.estimators.result import EstimateResult
from casep.estimators.spec import STD_CHOICES, FitSpec, NoiseSpec
from casep.exceptions import NoiseNotWhiteWarning
from casep.noise.model import NoiseModel
from casep.noise.whiteness import ALPHA_FITTED, default_lags, find_gaps, whiteness_test
from casep.regression.joint import Flights, JointProblem
from casep.regression.linalg import covariance_std, undetermined_nan
from casep.regression.problem import Problem
from casep.regression.rows import Rows, prepare_rows

# Rows and prepare_rows live in casep.regression.rows (the data's), re-exported here beside solve_problem
__all__ = ["fit", "fit_flights", "joint_rows", "JointRows", "flight_sigmas", "rows_for", "solve_problem",
           "solve_spec", "noise_account", "prepare_rows", "Rows", "Solved", "hac_covariance", "with_hac",
           "richer_noise_factor", "STD_CHOICES", "kept_samples"]


@dataclass
class Solved:
    """A method solved under a noise model.

    Attributes
    ----------
    result : EstimateResult
        Residuals on the raw rows of every sample; ``diagnostics["noise"]`` the noise model,
        ``diagnostics["robust"]``/``["excluded"]`` what was down-weighted or removed.
    problem : Problem
        What the method solved (whitened, without the removed samples).
    noise : NoiseModel
    excluded : (k,) int ndarray
        Samples (of the problem given) removed from the fit.
    weights : (N, 3) ndarray or None
        Robust row weights (samples of the problem given).
    """

    result: EstimateResult
    problem: Problem
    noise: NoiseModel
    excluded: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    weights: np.ndarray | None = None


def _x(res: EstimateResult) -> np.ndarray:
    return res.fitted_coefficients()


def fit(problem: Problem | Flights, spec: FitSpec, *, rows: Rows | JointRows | None = None,
        checks: bool = True) -> EstimateResult:
    """Fit `problem` as `spec` asks: the one entry point of every path (one flight, several, radar, demo, Monte Carlo,
    calibration, ...); no other module solves a request's method itself (``tests/test_structure.py``).

    Several flights (a :class:`~casep.regression.joint.Flights`): :func:`fit_flights`, the same rules on each.

    De-noise if asked (:func:`casep.noise.denoise.denoise`; sigma then the wavelet's estimate of
    the raw noise unless given), solve the rows under the noise model (:func:`solve_spec`), check the
    residuals on the raw rows (:func:`casep.checks.plausibility.check_fit`: noise-free data, outliers, time
    offset) and a given sigma against them, and flag outliers if asked.

    Parameters
    ----------
    problem : Problem
        Raw rows with their times (a flight's :meth:`~casep.regression.problem.Problem.from_flight`).
    spec : FitSpec
        The request, checked when it was made.
    rows : Rows, optional
        Rows prepared before for this problem (:func:`rows_for`: several methods on one flight share them).
    checks : bool, optional
        False: the estimate and its std only, without the judgements of the residuals (noise-free data,
        outliers, time offset, a given sigma, whiteness): a Monte Carlo run, whose numbers are judged
        over the runs; radar rows and a calibration's rows, which their own checks judge.

    Returns
    -------
    EstimateResult
    """
    from casep.checks.plausibility import check_fit, check_sigma

    if isinstance(problem, Flights):
        assert rows is None or isinstance(rows, JointRows)
        return fit_flights(problem, spec, rows=rows, checks=checks)
    assert rows is None or isinstance(rows, Rows)
    if not problem.has_rows:
        raise ValueError("`flight` is a reduction-only Problem: a fit needs the flight's rows")
    solved, den, sigma, from_wavelet = problem, None, spec.sigma, False
    if spec.noise.denoise == "wavelet":
        from casep.noise.denoise import denoise as wavelet_denoise

        den = wavelet_denoise(problem._need_rows(), **dict(spec.noise.wavelet_options))
        solved = problem.with_y(den.dv)
        if sigma is None:
            sigma = float(np.sqrt(np.mean(den.sigma**2)))  # raw-noise sigma, not post-de-noising residuals
            from_wavelet = True
    if sigma is not spec.sigma:
        spec = dataclasses.replace(spec, sigma=sigma)
    out = solve_spec(solved, spec, rows=rows, check_white=den is None and checks)
    res = out.result
    if checks:
        check_fit(problem, problem._need_rows(), res, t=problem.t, f=problem.f, source=problem.source,  # type: ignore[arg-type]
                  outliers_handled="robust" in res.diagnostics or spec.noise.exclude_outliers is not None,
                  excluded=out.excluded, noise=out.problem.noise)
    if checks and sigma is not None and not from_wavelet:
        check_sigma(problem, sigma, source=problem.source)  # the given sigma against the residuals
    if spec.outliers is not None:  # studentized residuals on the rows the method solved (whitened), samples named
        from casep.regression.outliers import flag_outliers

        flags = flag_outliers(out.problem, alpha=spec.outliers)
        res = dataclasses.replace(res, diagnostics={**res.diagnostics, "outliers_studentized": flags.to_dict()})
    if den is not None:
        settings = dict(res.settings)
        if from_wavelet:
            settings["sigma"] = "estimated"  # none given: the wavelet's estimate is res.sigma (sigma_source)
        res = dataclasses.replace(res, denoise=den.to_dict(), settings=settings,
                                  sigma_source="wavelet" if from_wavelet else res.sigma_source)
    return res


def solve_problem(problem: Problem, method: str, options: Mapping[str, Any] | None = None, *,
                  noise: str = "auto", tau=None, robust: str | None = "auto", std: str = "model",
                  exclude_outliers: float | None = None, check_white: bool = True, rows: Rows | None = None,
                  **labels) -> Solved:
    """Fit `problem`'s noise model (:func:`prepare_rows`) and solve its rows with a registered `method`.

    The keyword form of :func:`solve_spec`: the arguments make a :class:`~casep.estimators.spec.FitSpec`
    (checked there).

    Parameters
    ----------
    problem : Problem
        Raw rows ``(N, 3)`` with their times.
    method : str
        A registered method (:data:`casep.estimators.registry.METHODS`).
    options : mapping
        The method's options.
    noise, tau, robust, exclude_outliers
        As :func:`prepare_rows`.
    std : {"model", "hac"}
        ``hac``: Newey-West std for a white-noise least-squares fit.
    check_white : bool
        With noise "white": test the residuals' whiteness and warn (not for de-noised data).
    rows : Rows, optional
        Rows prepared before (:func:`prepare_rows` of this problem): reused, the noise options
        are then ignored (several methods on one flight share them).
    **labels
        ``sigma`` and solver keywords, passed to the method.
    """
    labels = dict(labels)
    sigma = labels.pop("sigma", None)
    spec = FitSpec(method, dict(options or {}), sigma, NoiseSpec(noise, tau, robust, std, exclude_outliers),
                   keywords=labels)
    return solve_spec(problem, spec, rows=rows, check_white=check_white)


def solve_spec(problem: Problem, spec: FitSpec, *, rows: Rows | None = None, check_white: bool = True) -> Solved:
    """Solve `problem`'s rows under the noise model `spec` asks for, with its method (no residual checks).

    The rows (:func:`prepare_rows`: noise model, robust weights, removed samples) are the data's;
    the method solves them; residuals are reported on the raw rows of every sample.
    """
    meth = METHODS[spec.method]
    ns = spec.noise
    opts = {**dict(spec.options), **dict(spec.keywords), "sigma": spec.sigma}
    if meth.own_noise_model is not None:
        return _solve_own_noise(problem, meth, opts, _robust(ns), ns.exclude_outliers, check_white)
    if rows is None:
        rows = rows_for(problem, ns)
    elif rows.problem is not problem:
        raise ValueError("`rows` were prepared for another problem")
    robust_sigma = opts.get("sigma") is None and rows.sigma is not None
    if robust_sigma:
        opts["sigma"] = rows.sigma  # robust: the M-estimator's sigma (module notes)
    res = meth.solve(rows.solved, **opts)
    if robust_sigma:  # found, not given: settings keep the input (none given), the value is res.sigma
        res = dataclasses.replace(res, sigma_source="robust", settings={**res.settings, "sigma": "estimated"})
    if ns.std == "hac":
        res = with_hac(res, rows.solved)
    return Solved(_finish(rows, res, check_white), rows.solved, rows.noise, np.flatnonzero(~rows.keep),
                  rows.weights)


def _robust(noise: NoiseSpec) -> str | None:
    """The robust fit a noise request runs: HAC std are those of plain least squares (no automatic robust fit)."""
    return None if noise.std == "hac" and noise.robust == "auto" else noise.robust


def rows_for(problem: Problem, noise: NoiseSpec) -> Rows:
    """The rows of `problem` under the noise request `noise` (:func:`prepare_rows`): noise model, robust
    weights, removed samples; prepared once, they serve every method of a comparison (``fit(..., rows=)``)."""
    return prepare_rows(problem, noise.kind, noise.tau, _robust(noise), noise.exclude_outliers)


def _places(problem: Problem, samples) -> list[dict]:
    """``{"sample", "t", "file", "row", "line", "where"}`` of rows of `problem` (one numbering everywhere)."""
    from casep.io.locate import where

    return [{**loc, "where": where(loc)} for loc in problem.locate(samples)]


def noise_account(rows: Rows | None, asked: str, noise: NoiseModel | None = None, *,
                  note: str | None = None) -> dict[str, Any]:
    """The noise account of a fit, assembled here only: ``{"noise": ..., "robust": ..., "excluded": ...}``.

    ``noise``: the noise model (`noise`, default the rows') with the kind `asked` (and a `note`);
    ``robust``: what the robust fit did with the samples it rejected, located in their files;
    ``excluded``: the samples removed as flagged outliers, located; ``misfit_runs``: the runs of rejections that kept
    robust "auto" off (:attr:`casep.regression.rows.Rows.misfit_runs`); ``removed_samples``: every sample the fit left
    out (a robust fit's rejections and the excluded outliers; ``robust["rejected"]`` locates the first 200 only), read
    back by :func:`kept_samples`. The last four only when they apply.
    """
    if noise is None:
        assert rows is not None  # the rows' own noise model
        noise = rows.noise
    out: dict[str, Any] = {"noise": {**noise.to_dict(), "asked": asked, **({"note": note} if note else {})}}
    if rows is None:
        return out
    if rows.robust is not None and rows.problem.t is not None:
        out["robust"] = {**rows.robust, "rejected": _places(rows.problem, np.flatnonzero(~rows.keep)[:200])}
    if rows.misfit_runs is not None:  # robust "auto" not engaged: runs, not glitches (the std do not cover them)
        out["misfit_runs"] = rows.misfit_runs
    if rows.excluded is not None:
        ex = rows.excluded
        locs = _places(rows.problem, [r["sample"] for r in ex["samples"]])
        out["excluded"] = {**ex, "samples": [{**r, **loc} for r, loc in zip(ex["samples"], locs)]}
    if not rows.keep.all():
        out["removed_samples"] = [int(k) for k in np.flatnonzero(~rows.keep)]
    return out


def kept_samples(diagnostics: Mapping[str, Any], n_samples: int) -> np.ndarray:
    """The samples (N,) bool a fit kept, from its result's diagnostics (:func:`noise_account`'s ``removed_samples``):
    what its noise model was fitted on and its method solved; all of them when the fit removed none."""
    keep = np.ones(n_samples, dtype=bool)
    keep[np.asarray(diagnostics.get("removed_samples") or [], dtype=int)] = False
    return keep


def _finish(rows: Rows, res: EstimateResult, check_white: bool) -> EstimateResult:
    problem, keep, nm, noise = rows.problem, rows.keep, rows.noise, rows.asked
    x = _x(res)
    raw = problem.residuals(x)
    diag = {**res.diagnostics, **noise_account(rows, noise)}
    if problem.t is not None:
        gaps = find_gaps(problem.t)
        for g, loc in zip(gaps, _places(problem, [g["row"] - 1 for g in gaps])):
            g.update(loc)  # the first sample after the gap
        diag["gaps"] = gaps
    if check_white and problem.t is not None and raw.ndim == 2 and rows.solved.has_rows \
            and not (problem if keep.all() else problem.subset(keep)).is_noise_free():
        # rounding residuals (of the samples kept: glitches on noise-free data removed): no noise to test
        # the residuals whitened by the noise model (raw ones for white noise): still correlated?
        e = raw[keep] if nm.is_white and rows.weights is None else rows.solved.residuals(x).reshape(-1, 3)
        alpha = 0.01 if noise == "white" else ALPHA_FITTED  # raw residuals at 1 %, whitened ones at 0.1 %
        wt = dataclasses.replace(whiteness_test(e, problem.t[keep], alpha=alpha), kind=noise)
        if wt.rejected:
            factor = _gm_factor(res, rows) if noise in ("white", "gm") else (None, None)
            wt = dataclasses.replace(wt, std_factor=factor[0], std_factor_max=factor[1])
            warnings.warn(f"{res.method}: {wt.text()}", NoiseNotWhiteWarning, stacklevel=3)
        diag["whiteness"] = wt.to_dict()
    settings = {**res.settings, "noise": noise}
    return dataclasses.replace(res, residuals=raw, n_samples=problem.n_samples, diagnostics=diag, settings=settings)


# --------------------------------------------------------------------------- HAC
def hac_covariance(problem: Problem, x: np.ndarray, lags: int | None = None) -> np.ndarray:
    """Newey-West (Bartlett kernel) covariance of a least-squares estimate, natural units.

    Each axis is its own time series (the axes' noises independent)::

        Omega = sum_a [G_a0 + sum_{l=1}^{L} (1 - l / (L + 1)) (G_al + G_al^T)],
        G_al = sum_k g_{a,k} g_{a,k-l}^T,   g_{a,k} = S_{k,a}^T r_{k,a}
        Cov = (S^T S)^-1 Omega (S^T S)^-1

    with lags in samples (``L`` default ``floor(4 (N / 100)^(2/9))``). Equal to statsmodels'
    ``cov_type="hac-panel"`` with the axis as the group, Bartlett kernel and no small-sample
    correction (tested). Several flights stacked (a problem's ``segment_starts``): each flight's lag
    products within that flight only (``L`` by its own length), summed into ``Omega``.
    """
    N = problem.n_samples
    S = problem.sv()  # (N, 3, n)
    r = problem.residuals(x).reshape(-1, 3)  # (N, 3)
    n = S.shape[-1]
    c = np.where(problem.red.scale > 0, problem.red.scale, 1.0)
    Omega = np.zeros((n, n))
    ends = list(problem.segment_starts[1:]) + [N]
    for start, end in zip(problem.segment_starts, ends):  # several flights: lags within each flight only
        L = default_lags(end - start) if lags is None else int(lags)
        for a in range(3):
            g = S[start:end, a, :] * r[start:end, a, None] / c  # scores on the scaled columns
            Omega += g.T @ g
            for lag in range(1, min(L, end - start - 1) + 1):
                G = g[lag:].T @ g[:-lag]
                Omega += (1.0 - lag / (L + 1.0)) * (G + G.T)
    ra = problem.rank()
    V, inv_s = ra.pinv_factors()
    B = (V * inv_s**2) @ V.T  # (Z^T Z)^+ = R^+ R^+T on the scaled columns
    cov_s = B @ Omega @ B
    return cov_s / np.outer(c, c)


def with_hac(res: EstimateResult, solved: Problem) -> EstimateResult:
    """`res` with its covariance and std replaced by the Newey-West ones (:func:`hac_covariance`)."""
    cov = undetermined_nan(hac_covariance(solved, _x(res)), np.isnan(res.estimate))
    std = covariance_std(cov)  # NaN where undetermined
    return dataclasses.replace(res, covariance=cov, std=std, settings={**res.settings, "std": "hac"})


def richer_noise_factor(res: EstimateResult, problem: Problem) -> float:
    """How far too small the std of a white-noise least-squares fit `res` of `problem` are: the median ratio of
    the Gauss-Markov plus white (REML) std to its own (:func:`_gm_factor`, the whiteness test's measure), at least 1;
    1 where it cannot be measured (no times, a given noise, noise-free rows)."""
    if problem.t is None or problem.y is None or problem.is_noise_free():
        return 1.0
    med = _gm_factor(res, prepare_rows(problem, "white", robust="none"))[0]
    return max(1.0, float(med)) if med is not None and np.isfinite(med) else 1.0


def _gm_factor(res: EstimateResult, rows: Rows) -> tuple[float | None, float | None]:
    """Median and largest ratio of the Gauss-Markov plus white (REML) least-squares std to the reported std.

    How far too small the reported std are, measured from the fit: the same data (the samples
    kept) under the richest noise model, which nests the one fitted.
    """
    from casep.estimators.ols import solve_ols

    raw = rows.problem if rows.keep.all() else rows.problem.subset(rows.keep)
    if res.std is None or raw.noise is not None or not raw.has_rows:
        return None, None
    try:
        rich = prepare_rows(raw, "gmw", robust="huber")  # robust: glitches would collapse tau
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # conditioning: said by the result
            gm = solve_ols(rich.solved)
    except (ValueError, np.linalg.LinAlgError):
        return None, None
    if gm.std is None:
        return None, None
    ok = np.isfinite(res.std) & (res.std > 0) & np.isfinite(gm.std)
    if not ok.any():
        return None, None
    ratio = gm.std[ok] / res.std[ok]
    return float(np.median(ratio)), float(np.max(ratio))


def _solve_own_noise(problem: Problem, meth: Any, opts: dict[str, Any], robust: str | None,
                     exclude_outliers: float | None, check_white: bool = True) -> Solved:
    """A method that fits its own noise model (GLS: one Gauss-Markov tau for every axis, its own option).

    Glitches (a robust fit asked or found, :func:`casep.regression.rows.prepare_rows`) and flagged
    outliers are removed first, so that they cannot collapse the correlation time. What the noise
    request may ask of such a method was checked with the request (:class:`~casep.estimators.spec.FitSpec`).
    """
    sub, rows = problem, None
    if robust not in (None, "none") or exclude_outliers is not None:
        rows = prepare_rows(problem, "gm", None, robust, exclude_outliers)
        if not rows.keep.all():
            sub = problem.subset(rows.keep)
    res = meth.solve(sub, **opts)
    nm = meth.own_noise_model(res)
    diag = {**res.diagnostics, **noise_account(rows, "gm", nm, note=f"method {meth.name}: one tau for all axes")}
    raw = problem.residuals(_x(res))
    # the whitened residuals still correlated? (not asked: a Monte Carlo run, rows judged by their own checks)
    if check_white and sub.t is not None and sub.has_rows and not sub.is_noise_free():
        from casep.noise.model import whiten

        r = sub.residuals(_x(res)).reshape(-1, 3)
        e = whiten(np.zeros(r.shape + (0,)), r, sub.t, nm)[1]
        wt = dataclasses.replace(whiteness_test(e, sub.t, alpha=ALPHA_FITTED), kind=meth.name)
        if wt.rejected:
            warnings.warn(f"{meth.name}: {wt.text()}", NoiseNotWhiteWarning, stacklevel=3)
        diag["whiteness"] = wt.to_dict()
    res = dataclasses.replace(res, diagnostics=diag, settings={**res.settings, "noise": "gm"}, residuals=raw,
                              n_samples=problem.n_samples)
    return Solved(res, sub, nm, np.zeros(0, dtype=int) if rows is None else np.flatnonzero(~rows.keep))


# --------------------------------------------------------------------------- several flights
@dataclass
class JointRows:
    """Several flights' rows as a method solves them (:func:`joint_rows`), prepared once.

    Attributes
    ----------
    joint : JointProblem
        The whitened joint problem (each flight divided by its sigma).
    rows : list of Rows or None
        Each flight's noise rows (noise model, robust weights, removed samples); None when the method
        makes its own rows (GLS).
    state : Any
        What the method's own rows hand to its ``finish`` hook (GLS: the flights' tau).
    denoised : list of dict or None
        Each flight's de-noising (:meth:`casep.noise.denoise.DenoiseResult.to_dict`) when asked.
    sigma_given : bool
        The flights' sigma were given (the request's, or the de-noising's estimates), not their residuals'.
    """

    joint: JointProblem
    rows: list | None
    state: Any
    denoised: list[dict] | None
    sigma_given: bool


def joint_rows(flights: Flights, spec: FitSpec, sigma: Any = None) -> JointRows:
    """Each flight's rows under `spec` (de-noised if asked, its noise model and robust cleaning, or the method's
    own rows), weighted by its sigma (`sigma`: one per flight or one for all, else the request's, the wavelet's
    estimate, or its own least-squares residual std) and combined into one
    :class:`~casep.regression.joint.JointProblem`."""
    hooks = METHODS[spec.method].flights
    assert hooks is not None  # refused by fit_flights
    problems, denoised = list(flights.problems), None
    sigma = spec.sigma if sigma is None else sigma
    if spec.noise.denoise == "wavelet":
        from casep.noise.denoise import denoise as wavelet_denoise

        dens = [wavelet_denoise(p._need_rows(), **dict(spec.noise.wavelet_options)) for p in problems]
        problems = [p.with_y(d.dv) for p, d in zip(problems, dens)]
        denoised = [d.to_dict() for d in dens]
        if sigma is None:  # raw-noise sigma of each flight, not its post-de-noising residuals
            sigma = [float(np.sqrt(np.mean(d.sigma**2))) for d in dens]
    state: Any = None
    rows = None
    if hooks.rows is not None:  # the method's own rows (GLS: each flight whitened by its own tau)
        solved, state = hooks.rows(problems, dict(spec.options), spec.noise.kind, spec.noise.robust)
    else:
        rows = [rows_for(p, spec.noise) for p in problems]
        solved = [r.solved for r in rows]
    jp = JointProblem(solved, flight_sigmas(solved, sigma), flights.layout, raw=flights.problems,
                      interpolated=flights.interpolated)
    return JointRows(jp, rows, state, denoised, sigma is not None)


def flight_sigmas(problems, sigma) -> list[float]:
    """Each flight's noise std: given (one for all, or one per flight), or its own least-squares residual std
    ``sqrt(RSS_k / (m_k - rank_k))``."""
    if sigma is None:
        return [float(np.sqrt(p.ls_rss() / (p.m - p.rank().rank))) for p in problems]
    values = [sigma] * len(problems) if np.ndim(sigma) == 0 else list(sigma)
    if len(values) != len(problems):
        raise ValueError(f"`sigma` has {len(values)} values for {len(problems)} flights")
    for k, v in enumerate(values):
        if not (isinstance(v, (int, float, np.floating)) and np.isfinite(v) and v > 0):
            raise ValueError(f"`sigma` of flight {k + 1} must be finite and > 0, got {v!r}")
    return [float(v) for v in values]


def fit_flights(flights: Flights, spec: FitSpec, *, rows: JointRows | None = None,
                checks: bool = True) -> EstimateResult:
    """Fit several flights as `spec` asks (module notes); :func:`casep.estimators.solve.fit` of a :class:`Flights`.

    Parameters
    ----------
    flights : Flights
    spec : FitSpec
        Its sigma, when set, is every flight's (one per flight: :func:`joint_rows`' `sigma`).
    rows : JointRows, optional
        Prepared before (:func:`joint_rows`): its joint problem is the one solved (the caller keeps it for
        the flights' summary).
    checks : bool, optional
        False: the estimate and its std only, without each flight's residual checks.

    Returns
    -------
    EstimateResult
        Over the joint parameters (names ``name`` for shared, ``name[label]`` per flight), std from the
        whitened system (``sigma_source`` "whitened").
    """
    meth = METHODS[spec.method]
    hooks = meth.flights
    if hooks is None:
        joint = [k for k, m in METHODS.items() if m.flights is not None]
        raise ValueError(f"method `{spec.method}` cannot be estimated jointly; use one of {', '.join(joint)}")
    if rows is None:
        rows = joint_rows(flights, spec)
    jp = rows.joint
    by = hooks.solve_as or meth
    kw = {k: v for k, v in {**dict(spec.options), **dict(spec.keywords)}.items()
          if k in by.options or k in {o.name for o in by.keywords}}
    res = by.solve(jp, sigma=hooks.sigma, **kw)
    settings = {**res.settings, "sigma": "per flight" if not rows.sigma_given else "given per flight"}
    res = dataclasses.replace(res, sigma_source="whitened", settings=settings)
    if spec.noise.std == "hac":
        res = with_hac(res, jp)
    if rows.rows is not None:
        res = _noise_account(res, rows, spec.noise.kind)
    if rows.denoised is not None:
        res = dataclasses.replace(res, denoise={"flights": dict(zip(jp.layout.labels, rows.denoised))})
    if checks:
        _check_flights(res, rows, spec)
    if spec.outliers is not None:
        res = _flag_outliers(res, jp, spec.outliers)
    if hooks.finish is not None:
        res = hooks.finish(res, jp, rows.state, dict(spec.options))
    return res


def _noise_account(res: EstimateResult, rows: JointRows, kind: str) -> EstimateResult:
    """Each flight's noise account (:func:`casep.estimators.solve.noise_account`), by its label."""
    per_flight = {}
    assert rows.rows is not None
    for lab, rw in zip(rows.joint.layout.labels, rows.rows):
        acc = noise_account(rw, kind)
        per_flight[lab] = {**acc["noise"], **{k: acc[k] for k in ("robust", "excluded") if k in acc}}
    return dataclasses.replace(res, diagnostics={**res.diagnostics, "noise": per_flight},
                               settings={**res.settings, "noise": kind})


def _check_flights(res: EstimateResult, rows: JointRows, spec: FitSpec) -> None:
    """One flight's residual checks on each flight (:func:`casep.checks.plausibility.check_fit`): its own
    residuals under the joint estimate, its removed samples left out; a given sigma against its residuals."""
    from casep.checks.plausibility import check_fit, check_sigma

    jp = rows.joint
    x = res.fitted_coefficients()
    robust = "robust" in res.diagnostics or any(
        isinstance(v, dict) and "robust" in v for v in (res.diagnostics.get("noise") or {}).values())
    for k, p in enumerate(jp.raw):
        xk = x[jp.layout.columns(k)]  # flight k's coefficients
        est = types.SimpleNamespace(estimate=xk, names=p.names, fitted_coefficients=lambda xk=xk: xk)
        excluded = None if rows.rows is None else np.flatnonzero(~rows.rows[k].keep)
        check_fit(p, p._need_rows(), est, t=p.t, f=p.f, source=p.source,  # type: ignore[arg-type]
                  outliers_handled=robust or spec.noise.exclude_outliers is not None, excluded=excluded,
                  noise=None if rows.rows is None else rows.rows[k].noise)
        if rows.sigma_given and rows.denoised is None:
            check_sigma(p, float(jp.sigmas[k]), source=p.source)


def _flag_outliers(res: EstimateResult, jp: JointProblem, alpha: float) -> EstimateResult:
    """Studentized residuals of the joint whitened rows, each flagged row named by its flight and its sample
    there (the stacked rows are flight after flight)."""
    from casep.regression.outliers import flag_outliers

    flags = flag_outliers(jp, alpha=alpha).to_dict()
    starts = np.asarray(jp.segment_starts)
    named = []
    for r in flags.get("rows", []):
        k = int(np.searchsorted(starts, r["sample"], side="right") - 1)
        sample = int(r["sample"] - starts[k])
        loc = jp.raw[k].locate([sample])[0]
        named.append({**r, **loc, "flight": jp.layout.labels[k], "flight_sample": sample})
    flags["rows"] = named
    return dataclasses.replace(res, diagnostics={**res.diagnostics, "outliers_studentized": flags})
