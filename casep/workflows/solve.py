"""Solve a problem under its noise model: whitened rows for every estimator, robust if asked.

This is where the noise model of the data meets a method (:func:`solve_problem`): the noise is
fitted (:func:`casep.analysis.noise.fit_noise`: white, Gauss-Markov per axis, or chosen by a
likelihood-ratio test), the rows are whitened (:meth:`casep.analysis.problem.Problem.whitened`),
and the method solves the whitened problem as any other, so its std hold in coloured noise.
Residuals are reported on the raw rows (``dv - S_V D``) of every sample.

Robust fits (``robust="huber"|"bisquare"``) iterate: fit, robust filter on the innovations of
the residuals (:func:`casep.analysis.robust.robust_filter`: gross glitches removed as gaps, the
rest weighted), correlation time fitted again on the kept samples (so glitches cannot collapse
it), fit again, until the kept samples and weights settle.

``exclude_outliers=alpha`` flags rows by their externally studentized residual on the whitened
rows (:func:`casep.analysis.outliers.flag_outliers`, family-wise false-alarm chance ``alpha``),
removes the flagged samples and fits again, until nothing is flagged.

``std="hac"`` replaces a white-noise least-squares fit's std by the Newey-West sandwich
(:func:`hac_covariance`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from casep.analysis.noise import NoiseModel, check_noise_kind, default_lags, fit_noise, whiteness_test
from casep.analysis.problem import Problem
from casep.analysis.robust import ROBUST_FUNCTIONS, robust_filter
from casep.estimators.registry import run_method
from casep.estimators.result import EstimateResult
from casep.exceptions import NoiseNotWhiteWarning

__all__ = ["solve_problem", "Solved", "hac_covariance", "STD_CHOICES"]

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


def solve_problem(problem: Problem, method: str, options: Mapping[str, Any] | None = None, *,
                  noise: str = "auto", tau=None, robust: str | None = None, std: str = "model",
                  exclude_outliers: float | None = None, check_white: bool = True, **labels) -> Solved:
    """Fit `problem`'s noise model and solve it with a registered `method` (module notes).

    Parameters
    ----------
    problem : Problem
        Raw rows ``(N, 3)`` with their times.
    method : str
        A registered method (:data:`casep.estimators.registry.METHODS`).
    options : mapping
        The method's options.
    noise : {"auto", "gm", "white"}
    tau : float, three floats or None
        Given Gauss-Markov correlation time(s), s (``noise="gm"``).
    robust : {None, "huber", "bisquare"}
    std : {"model", "hac"}
        ``hac``: Newey-West std for a white-noise least-squares fit.
    exclude_outliers : float, optional
        Family-wise false-alarm chance of the outlier flags whose samples are removed.
    check_white : bool
        With noise "white": test the residuals' whiteness and warn (not for de-noised data).
    **labels
        ``sigma`` and solver extras, passed to the method.
    """
    check_noise_kind(noise)
    if std not in STD_CHOICES:
        raise ValueError(f"`std` must be one of {', '.join(STD_CHOICES)}, got {std!r}")
    if robust is not None and robust not in ROBUST_FUNCTIONS:
        raise ValueError(f"`robust` must be one of {', '.join(ROBUST_FUNCTIONS)}, got {robust!r}")
    opts = dict(options or {})
    if method == "gls":
        return _solve_gls(problem, opts, noise, tau, robust, std, exclude_outliers, labels)
    if method == "huber" and robust is not None:
        raise ValueError("method `huber` is robust already; `robust` makes any other method robust "
                         "(e.g. method ols with robust='huber')")
    if std == "hac" and (noise != "white" or method != "ols"):
        raise ValueError("`std='hac'` is the Newey-West std of a white-noise least-squares fit: use it with "
                         "method ols and noise 'white' (in coloured noise, noise 'auto' or 'gm' gives honest std)")
    if noise != "white" and _noise_free(problem):
        nm = dataclasses.replace(NoiseModel.white(), kind=noise, rule="noise-free data: white")
    else:
        nm = fit_noise(problem, noise, tau)

    keep = np.ones(problem.n_samples, dtype=bool)
    weights = None
    robust_info: dict[str, Any] | None = None
    res, solved = _solve(problem, keep, nm, weights, method, opts, labels)
    if robust is not None:
        res, solved, nm, keep, robust_info, weights = _robust(problem, res, solved, nm, method, opts, labels, noise,
                                                              tau, robust)
    excluded_info = None
    if exclude_outliers is not None:
        res, solved, keep, excluded_info = _exclude(problem, res, solved, nm, keep, method, opts, labels,
                                                    exclude_outliers)
    if std == "hac":
        res = _with_hac(res, solved)
    return Solved(_finish(problem, res, solved, nm, keep, robust_info, excluded_info, noise, check_white), solved, nm,
                  np.flatnonzero(~keep), weights)


def _solve(problem: Problem, keep: np.ndarray, nm: NoiseModel, weights, method: str, opts, labels):
    sub = problem if keep.all() else problem.subset(keep)
    w = None if weights is None else weights[keep]
    solved = sub if (nm.is_white and w is None) else sub.whitened(nm, weights=w)
    res = run_method(method, solved, None, solved.t, opts, **labels)
    return res, solved


def _robust(problem, res, solved, nm, method, opts, labels, noise, tau, function):
    """IRLS with the robust filter (module notes)."""
    keep = np.ones(problem.n_samples, dtype=bool)
    refits = 0
    history = []
    for it in range(1, _MAX_ROBUST_ITER + 1):
        x = _x(res)
        r = problem.residuals(x)
        rw = robust_filter(r, problem.t, nm, function=function)
        new_keep = rw.keep
        if not np.array_equal(new_keep, keep) and noise != "white" and tau is None and refits < 3:
            # the correlation time on the kept samples only: glitches cannot collapse it
            nm = fit_noise(problem.subset(new_keep), noise, None)
            refits += 1
            rw = robust_filter(r, problem.t, nm, function=function)
            new_keep = rw.keep
        changed = not np.array_equal(new_keep, keep)
        keep = new_keep
        new_res, solved = _solve(problem, keep, nm, rw.weights, method, opts, labels)
        std = np.where(np.isfinite(new_res.std), new_res.std, np.inf) if new_res.std is not None else None
        step = np.abs(_x(new_res) - x)
        move = float(np.max(step / std)) if std is not None else float(np.max(step))
        history.append({"iteration": it, "rejected": int((~keep).sum()), "max_step_std": move})
        res = new_res
        if not changed and move < 1e-3:
            break
    info = {"function": function, "iterations": len(history), "rejected_count": int((~keep).sum()),
            "scale": rw.scale, "downweighted": int(np.sum(rw.weights[keep] < 1.0)),
            "noise_refits": refits, "history": history}
    return res, solved, nm, keep, info, rw.weights


def _exclude(problem, res, solved, nm, keep, method, opts, labels, alpha):
    """Remove the samples of flagged rows and fit again until nothing is flagged."""
    from casep.analysis.outliers import flag_outliers

    keep = keep.copy()
    removed: list[dict] = []
    sample_ids = np.flatnonzero(keep)
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
        ks = sorted(worst)
        drop = [k for k in ks if not (k - 1 in worst and abs(worst[k - 1]["t_value"]) >= abs(worst[k]["t_value"]))]
        for k in drop:
            keep[k] = False
            removed.append({"sample": k, "t": float(problem.t[k]), "axis": worst[k]["axis"],
                            "t_value": float(worst[k]["t_value"])})
        res, solved = _solve(problem, keep, nm, None, method, opts, labels)
    info = {"alpha": alpha, "count": len(removed), "samples": removed}
    return res, solved, keep, info


def _finish(problem, res, solved, nm, keep, robust_info, excluded_info, noise, check_white) -> EstimateResult:
    x = _x(res)
    raw = problem.residuals(x)
    diag = dict(res.diagnostics)
    nd = nm.to_dict()
    nd["asked"] = noise
    diag["noise"] = nd
    if robust_info is not None:
        rej = np.flatnonzero(~keep)
        robust_info["rejected"] = [{"sample": int(k), "t": float(problem.t[k])} for k in rej[:200]]
        diag["robust"] = robust_info
    if excluded_info is not None:
        diag["excluded"] = excluded_info
    if nm.is_white and noise == "white" and check_white and problem.t is not None and raw.ndim == 2:
        wt = whiteness_test(raw[keep], problem.t[keep])
        if wt.rejected:
            factor = _gm_factor(res, solved)
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
        nm = fit_noise(solved, "gm")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # conditioning: said by the result
            gm = solve_ols(solved.whitened(nm))
    except (ValueError, np.linalg.LinAlgError):
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
