"""Solve a problem under its noise model: whitened rows for every estimator, robust if asked.

The noise model, the robust weights and the removed samples belong to the data, not to a
method: :func:`prepare_rows` works them out once for a problem (with least squares, whatever
method follows), and :func:`solve_problem` hands the resulting rows to any method, so its std
hold in coloured noise and with glitches, and every method of a comparison sees the same rows.

* Noise: :func:`casep.analysis.noise.fit_noise` (white, Gauss-Markov per axis, or chosen by a
  likelihood-ratio test), rows whitened by :meth:`casep.analysis.problem.Problem.whitened`.
* Robust (``robust="huber"|"bisquare"``): iterate least squares on the whitened, weighted rows
  and the robust filter on the innovations of its residuals
  (:func:`casep.analysis.robust.robust_filter`: gross glitches removed as gaps, the rest
  weighted); the correlation time is fitted again on the kept samples (so glitches cannot
  collapse it); until the kept samples settle and the estimate stops moving.
* ``exclude_outliers=alpha``: rows flagged by their externally studentized residual on the
  whitened rows (:func:`casep.analysis.outliers.flag_outliers`, family-wise false-alarm chance
  ``alpha``); their samples removed and the rows prepared again, until nothing is flagged.

Residuals are reported on the raw rows (``dv - S_V D``) of every sample.

``std="hac"`` replaces a white-noise least-squares fit's std by the Newey-West sandwich
(:func:`hac_covariance`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from casep.analysis.noise import NoiseModel, check_noise_kind, default_lags, find_gaps, fit_noise, whiteness_test
from casep.analysis.problem import Problem
from casep.analysis.robust import ROBUST_FUNCTIONS, robust_filter
from casep.estimators.registry import run_method
from casep.estimators.result import EstimateResult
from casep.exceptions import NoiseNotWhiteWarning

__all__ = ["solve_problem", "prepare_rows", "Rows", "Solved", "hac_covariance", "STD_CHOICES"]

STD_CHOICES = ("model", "hac")
#: Residual RMS below this fraction of the RMS of dv: noise-free data, nothing to fit a noise model on.
NOISE_FREE = 1e-9
_MAX_ROBUST_ITER = 12
_MAX_EXCLUDE_PASSES = 6


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

    def rows_problem(self, problem: Problem) -> Problem:
        """`problem` (the raw one given) as the method solved it: samples removed, whitened, weighted."""
        keep = np.ones(problem.n_samples, dtype=bool)
        keep[self.excluded] = False
        sub = problem if keep.all() else problem.subset(keep)
        w = None if self.weights is None else self.weights[keep]
        return sub if (self.noise.is_white and w is None) else sub.whitened(self.noise, weights=w)


def _x(res: EstimateResult) -> np.ndarray:
    return np.where(np.isnan(res.estimate), 0.0, res.estimate)


def _noise_free(problem: Problem) -> bool:
    rss = problem.ls_rss()
    yy = float(problem.red.qty @ problem.red.qty + problem.red.rho2)
    return yy > 0 and rss <= (NOISE_FREE**2) * yy


@dataclass
class Rows:
    """A problem's rows as every method solves them (:func:`prepare_rows`).

    Attributes
    ----------
    problem : Problem
        The raw problem.
    solved : Problem
        Samples removed, whitened for `noise`, weighted.
    noise : NoiseModel
    keep : (N,) bool ndarray
        Samples kept.
    weights : (N, 3) ndarray or None
        Robust row weights.
    robust : dict or None
        What the robust fit did.
    excluded : dict or None
        The samples removed as flagged outliers.
    asked : str
        The noise kind asked for.
    """

    problem: Problem
    solved: Problem
    noise: NoiseModel
    keep: np.ndarray
    weights: np.ndarray | None = None
    robust: dict | None = None
    excluded: dict | None = None
    asked: str = "auto"

    @property
    def sigma(self) -> float | None:
        """The noise std a method should take on the weighted rows (robust fits), else None (estimated)."""
        return None if self.robust is None else self.robust.get("sigma_effective")


def _rows(problem: Problem, keep: np.ndarray, nm: NoiseModel, weights) -> Problem:
    sub = problem if keep.all() else problem.subset(keep)
    w = None if weights is None else weights[keep]
    return sub if (nm.is_white and w is None) else sub.whitened(nm, weights=w)


def _ls(pb: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares estimate (0 where undetermined) and std of a problem, no diagnostics."""
    from casep.estimators._base import prepare
    from casep.estimators.ols import least_squares

    pp = prepare(pb, None, None, None, None, None)
    x, cov, _ = least_squares(pp)
    x = np.where(pp.ra.estimable, x, 0.0)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return x, np.where(pp.ra.estimable & (sd > 0), sd, np.inf)


def prepare_rows(problem: Problem, noise: str = "auto", tau=None, robust: str | None = None,
                 exclude_outliers: float | None = None) -> Rows:
    """The noise model, robust weights and removed samples of a problem (module notes).

    Parameters
    ----------
    problem : Problem
        Raw rows ``(N, 3)`` with their times.
    noise : {"auto", "gm", "white"}
    tau : float, three floats or None
        Given Gauss-Markov correlation time(s), s (``noise="gm"``).
    robust : {None, "huber", "bisquare"}
    exclude_outliers : float, optional
        Family-wise false-alarm chance of the outlier flags whose samples are removed.
    """
    check_noise_kind(noise)
    if robust is not None and robust not in ROBUST_FUNCTIONS:
        raise ValueError(f"`robust` must be one of {', '.join(ROBUST_FUNCTIONS)}, got {robust!r}")
    if noise != "white" and _noise_free(problem):
        nm = dataclasses.replace(NoiseModel.white(), kind=noise, rule="noise-free data: white")
    else:
        nm = fit_noise(problem, noise, tau)
    keep = np.ones(problem.n_samples, dtype=bool)
    weights = None
    robust_info = None
    if robust is not None:
        nm, keep, weights, robust_info = _robust(problem, nm, noise, tau, robust)
    solved = _rows(problem, keep, nm, weights)
    excluded_info = None
    if exclude_outliers is not None:
        solved, keep, excluded_info = _exclude(problem, solved, nm, keep, weights, exclude_outliers)
    return Rows(problem, solved, nm, keep, weights, robust_info, excluded_info, noise)


def solve_problem(problem: Problem, method: str, options: Mapping[str, Any] | None = None, *,
                  noise: str = "auto", tau=None, robust: str | None = None, std: str = "model",
                  exclude_outliers: float | None = None, check_white: bool = True, rows: Rows | None = None,
                  **labels) -> Solved:
    """Fit `problem`'s noise model (:func:`prepare_rows`) and solve its rows with a registered `method`.

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
        ``sigma`` and solver extras, passed to the method.
    """
    check_noise_kind(noise)
    if std not in STD_CHOICES:
        raise ValueError(f"`std` must be one of {', '.join(STD_CHOICES)}, got {std!r}")
    opts = dict(options or {})
    if method == "gls":
        return _solve_gls(problem, opts, noise, tau, robust, std, exclude_outliers, labels)
    if method == "huber" and robust is not None:
        raise ValueError("method `huber` is robust already; `robust` makes any other method robust "
                         "(e.g. method ols with robust='huber')")
    if std == "hac" and (noise != "white" or method != "ols"):
        raise ValueError("`std='hac'` is the Newey-West std of a white-noise least-squares fit: use it with "
                         "method ols and noise 'white' (in coloured noise, noise 'auto' or 'gm' gives honest std)")
    if rows is None:
        rows = prepare_rows(problem, noise, tau, robust, exclude_outliers)
    elif rows.problem is not problem:
        raise ValueError("`rows` were prepared for another problem")
    if labels.get("sigma") is None and rows.sigma is not None:
        labels = {**labels, "sigma": rows.sigma}  # robust: the M-estimator's sigma (module notes)
    res = run_method(method, rows.solved, None, rows.solved.t, opts, **labels)
    if rows.sigma is not None and res.sigma_source == "given" and labels["sigma"] == rows.sigma:
        res = dataclasses.replace(res, sigma_source="robust")
    if std == "hac":
        res = _with_hac(res, rows.solved)
    return Solved(_finish(rows, res, check_white), rows.solved, rows.noise, np.flatnonzero(~rows.keep),
                  rows.weights)


def _robust(problem, nm, noise, tau, function):
    """Least-squares IRLS with the robust filter (module notes): noise model, keep, weights, info."""
    keep = np.ones(problem.n_samples, dtype=bool)
    weights = None
    refits = 0
    history = []
    x, sd = _ls(_rows(problem, keep, nm, weights))
    rw = None
    for it in range(1, _MAX_ROBUST_ITER + 1):
        r = problem.residuals(x)
        rw = robust_filter(r, problem.t, nm, function=function)
        if not np.array_equal(rw.keep, keep) and noise != "white" and tau is None and refits < 2:
            # the correlation time on the kept samples only: glitches cannot collapse it
            nm = fit_noise(problem.subset(rw.keep), noise, None)
            refits += 1
            rw = robust_filter(r, problem.t, nm, function=function)
        changed = not np.array_equal(rw.keep, keep)
        keep, weights = rw.keep, rw.weights
        x_new, sd = _ls(_rows(problem, keep, nm, weights))
        move = float(np.max(np.abs(x_new - x) / sd))
        x = x_new
        history.append({"iteration": it, "rejected": int((~keep).sum()), "max_step_std": move})
        if not changed and move < 1e-3:
            break
    sigma = _robust_sigma(rw, keep, function) if rw is not None else None
    info = {"function": function, "iterations": len(history), "rejected_count": int((~keep).sum()),
            "scale": rw.scale if rw is not None else None, "sigma_effective": sigma,
            "downweighted": int(np.sum(weights[keep] < 1.0)) if weights is not None else 0,
            "noise_refits": refits, "history": history}
    return nm, keep, weights, info


def _robust_sigma(rw, keep: np.ndarray, function: str) -> float | None:
    """The sigma that makes the weighted least-squares covariance the M-estimator's (Huber 1981)::

        Cov = s^2 E[psi^2] / E[psi']^2 (Z^T Z)^-1 ~ sigma_eff^2 (Z^T W Z)^-1,
        sigma_eff^2 = s^2 mean(psi^2) mean(w) / mean(psi')^2,   psi = w u

    over the kept rows (``Z^T W Z ~ mean(w) Z^T Z``). The weighted residual std alone,
    ``s^2 mean(w u^2)``, is about 10 % too small for Huber at the Gaussian (0.821 against 1.030).
    """
    from casep.analysis.robust import BISQUARE_C, HUBER_C

    u = rw.u[keep].reshape(-1)
    w = rw.weights[keep].reshape(-1)
    if not rw.scale > 0 or u.size == 0:
        return None
    psi = w * u
    if function == "huber":
        dpsi = (np.abs(u) <= HUBER_C).astype(float)
    else:
        v = (u / BISQUARE_C) ** 2
        dpsi = np.where(v < 1.0, (1.0 - v) * (1.0 - 5.0 * v), 0.0)
    d = float(np.mean(dpsi))
    if not d > 0:
        return None
    return float(rw.scale * np.sqrt(np.mean(psi**2) * np.mean(w)) / d)


def _exclude(problem, solved, nm, keep, weights, alpha):
    """Remove the samples of flagged rows and prepare the rows again until nothing is flagged."""
    from casep.analysis.outliers import flag_outliers

    keep = keep.copy()
    removed: list[dict] = []
    for _ in range(_MAX_EXCLUDE_PASSES):
        flags = flag_outliers(solved, alpha=alpha)
        if not flags.count:
            break
        sample_ids = np.flatnonzero(keep)
        worst: dict[int, dict] = {}
        for r in flags.rows:
            k = int(sample_ids[r["sample"]])
            if k not in worst or abs(r["t_value"]) > abs(worst[k]["t_value"]):
                worst[k] = r
        # a glitch shows in its own whitened row and (less) in the next: remove the larger of neighbours
        drop = [k for k in sorted(worst)
                if not (k - 1 in worst and abs(worst[k - 1]["t_value"]) >= abs(worst[k]["t_value"]))]
        for k in drop:
            keep[k] = False
            removed.append({"sample": k, "t": float(problem.t[k]), "axis": worst[k]["axis"],
                            "t_value": float(worst[k]["t_value"])})
        solved = _rows(problem, keep, nm, weights)
    info = {"alpha": alpha, "count": len(removed), "samples": removed}
    return solved, keep, info


def _places(problem: Problem, samples) -> list[dict]:
    """``{"sample", "t", "file", "row", "line", "where"}`` of rows of `problem` (one numbering everywhere)."""
    from casep.io.files import where

    return [{**loc, "where": where(loc)} for loc in problem.locate(samples)]


def _finish(rows: Rows, res: EstimateResult, check_white: bool) -> EstimateResult:
    problem, keep, nm, noise = rows.problem, rows.keep, rows.noise, rows.asked
    x = _x(res)
    raw = problem.residuals(x)
    diag = dict(res.diagnostics)
    nd = nm.to_dict()
    nd["asked"] = noise
    diag["noise"] = nd
    if rows.robust is not None and problem.t is not None:
        diag["robust"] = {**rows.robust, "rejected": _places(problem, np.flatnonzero(~keep)[:200])}
    if rows.excluded is not None:
        ex = rows.excluded
        locs = _places(problem, [r["sample"] for r in ex["samples"]])
        diag["excluded"] = {**ex, "samples": [{**r, **loc} for r, loc in zip(ex["samples"], locs)]}
    if problem.t is not None:
        gaps = find_gaps(problem.t)
        for g, loc in zip(gaps, _places(problem, [g["row"] - 1 for g in gaps])):
            g.update(loc)  # the first sample after the gap
        diag["gaps"] = gaps
    if nm.is_white and noise == "white" and check_white and problem.t is not None and raw.ndim == 2:
        wt = whiteness_test(raw[keep], problem.t[keep])
        if wt.rejected:
            factor = _gm_factor(res, rows.solved)
            wt = dataclasses.replace(wt, std_factor=factor[0], std_factor_max=factor[1])
            warnings.warn(f"{res.method}: {wt.message()}", NoiseNotWhiteWarning, stacklevel=3)
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
    correction (tested).
    """
    N = problem.n_samples
    L = default_lags(N) if lags is None else int(lags)
    S = problem.sv()  # (N, 3, n)
    r = problem.residuals(x)  # (N, 3)
    n = S.shape[-1]
    c = np.where(problem.red.scale > 0, problem.red.scale, 1.0)
    Omega = np.zeros((n, n))
    for a in range(3):
        g = S[:, a, :] * r[:, a, None] / c  # scores on the scaled columns
        Omega += g.T @ g
        for lag in range(1, L + 1):
            G = g[lag:].T @ g[:-lag]
            Omega += (1.0 - lag / (L + 1.0)) * (G + G.T)
    ra = problem.rank()
    V, inv_s = ra.pinv_factors()
    B = (V * inv_s**2) @ V.T  # (Z^T Z)^+ = R^+ R^+T on the scaled columns
    cov_s = B @ Omega @ B
    return cov_s / np.outer(c, c)


def _with_hac(res: EstimateResult, solved: Problem) -> EstimateResult:
    cov = hac_covariance(solved, _x(res))
    und = np.isnan(res.estimate)
    cov[und, :] = np.nan
    cov[:, und] = np.nan
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    std[und] = np.nan
    return dataclasses.replace(res, covariance=cov, std=std, settings={**res.settings, "std": "hac"})


def _gm_factor(res: EstimateResult, solved: Problem) -> tuple[float | None, float | None]:
    """Median and largest ratio of the Gauss-Markov (REML) least-squares std to the reported white std.

    How far too small the reported std are, measured from the fit: the same data under the
    noise model the residuals point to.
    """
    from casep.estimators.ols import solve_ols

    if res.std is None or solved.noise is not None or not solved.has_rows:
        return None, None
    try:
        rows = prepare_rows(solved, "gm", robust="huber")  # robust: glitches would collapse tau
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # conditioning: said by the result
            gm = solve_ols(rows.solved)
    except (ValueError, np.linalg.LinAlgError):
        return None, None
    if gm.std is None:
        return None, None
    ok = np.isfinite(res.std) & (res.std > 0) & np.isfinite(gm.std)
    if not ok.any():
        return None, None
    ratio = gm.std[ok] / res.std[ok]
    return float(np.median(ratio)), float(np.max(ratio))


def _solve_gls(problem, opts, noise, tau, robust, std, exclude_outliers, labels) -> Solved:
    """`gls`: least squares with one Gauss-Markov correlation time for every axis (its own solver)."""
    if noise == "white":
        raise ValueError("method `gls` assumes Gauss-Markov noise: noise 'white' contradicts it (use method ols)")
    if robust is not None or exclude_outliers is not None or std != "model":
        raise ValueError("method `gls` takes no `robust`, `exclude_outliers` or `std`: use method ols with "
                         "noise 'gm' (per-axis Gauss-Markov) and those options")
    if tau is not None:
        opts = {**opts, "tau": tau}
    res = run_method("gls", problem, None, problem.t, opts, **labels)
    t_used = float(res.settings["tau"])
    nm = NoiseModel(kind="gm", tau=(t_used,) * 3, rule=str(res.settings.get("tau_rule", "reml")))
    diag = {**res.diagnostics, "noise": {**nm.to_dict(), "asked": "gm", "note": "method gls: one tau for all axes"}}
    return Solved(dataclasses.replace(res, diagnostics=diag, settings={**res.settings, "noise": "gm"}), problem, nm)
