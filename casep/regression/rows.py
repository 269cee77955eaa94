"""The rows every method solves: the noise model, robust weights and removed samples of a problem.

These belong to the data, not to a method: :func:`prepare_rows` works them out once for a
problem (with least squares, whatever method follows),
and every method then solves the same rows (:func:`casep.estimators.solve.solve_problem`), so its
std hold in coloured noise and with glitches, and every method of a comparison sees the same rows.

* Noise: :func:`casep.noise.fit.fit_noise` (white, Gauss-Markov per axis, or chosen by a
  likelihood-ratio test), rows whitened by :meth:`casep.regression.problem.Problem.whitened`.
* Robust (``robust="huber"|"bisquare"``): iterate least squares on the whitened, weighted rows
  and the robust filter on the innovations of its residuals
  (:func:`casep.noise.robust.robust_filter`: gross glitches removed as gaps, the rest
  weighted); the correlation time is fitted again on the kept samples (so glitches cannot
  collapse it); until the kept samples settle and the estimate stops moving. The methods then
  take the M-estimator's noise std (:func:`_robust_sigma`).
* ``exclude_outliers=alpha``: rows flagged by their externally studentized residual on the
  whitened rows (:func:`casep.regression.outliers.flag_outliers`, family-wise false-alarm chance
  ``alpha``); their samples removed and the rows prepared again, until nothing is flagged.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from casep._kernels import runs
from casep.noise.fit import fit_noise
from casep.noise.model import NoiseModel
from casep.noise.robust import MAX_RUN, robust_filter
from casep.noise.spec import NoiseSpec
from casep.regression.problem import NOISE_FREE, Problem  # NOISE_FREE re-exported: the one noise-free constant

__all__ = ["Rows", "prepare_rows", "NOISE_FREE", "GLITCH_SIGMAS", "rejected_runs", "mostly_runs", "misfit_runs_text",
           "stepped_rows", "STEPPED_MIN"]

_MAX_ROBUST_ITER = 12
_MAX_EXCLUDE_PASSES = 6


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
    misfit_runs : dict or None
        Robust "auto" not engaged because most of the samples the robust filter would reject lie in runs (a smooth
        misfit of the model, :func:`mostly_runs`): ``found``, ``in_runs`` and ``runs`` (``first``, ``last``: where
        each run's first and last sample come from, :meth:`Problem.locate`; ``samples``); the std do not cover it.
    """

    problem: Problem
    solved: Problem
    noise: NoiseModel
    keep: np.ndarray
    weights: np.ndarray | None = None
    robust: dict | None = None
    excluded: dict | None = None
    asked: str = "auto"
    misfit_runs: dict | None = None

    @property
    def sigma(self) -> float | None:
        """The noise std a method should take on the weighted rows (robust fits), else None (estimated)."""
        return None if self.robust is None else self.robust.get("sigma_effective")


def _rows(problem: Problem, keep: np.ndarray, nm: NoiseModel, weights) -> Problem:
    sub = problem if keep.all() else problem.subset(keep)
    w = None if weights is None else weights[keep]
    return sub if (nm.is_white and w is None) else sub.whitened(nm, weights=w)


def _ls(pb: Problem) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_ls_factor` without the covariance factor."""
    x, sd, _ = _ls_factor(pb)
    return x, sd


def _ls_factor(pb: Problem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares estimate (the minimum-norm solution: its fitted values are the least-squares ones also
    where a coefficient is undetermined, :mod:`casep.estimators.solution`) and unit-free std (inf where
    undetermined) of a problem, from its reduction.

    ``x = c^-1 V_r diag(1/s_r) U_r^T q`` on the scaled columns; std ``sigma sqrt(diag((Z^T Z)^+)) / c``; and the
    factor ``L = sigma c^-1 V_r diag(1/s_r)`` (n, r) of the covariance ``L L^T = sigma^2 (Z^T Z)^+``.
    """
    ra, red = pb.rank(), pb.red
    V, inv_s = ra.pinv_factors()
    inv_c = np.where(red.scale > 0, 1.0 / np.where(red.scale > 0, red.scale, 1.0), 0.0)
    x = (V @ (inv_s * (ra.U.T @ red.qty)[: ra.rank])) * inv_c
    sig = float(np.sqrt(pb.ls_rss() / max(red.m - ra.rank, 1)))
    sd = sig * np.sqrt(np.sum((V * inv_s) ** 2, axis=1)) * inv_c
    ok = ra.estimable & (sd > 0)
    return x, np.where(ok, sd, np.inf), sig * (V * inv_s) * inv_c[:, None]


def _predicted(problem: Problem, x: np.ndarray, L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The residuals ``y - S x`` (N, 3) of a problem's raw rows and ``G = S L`` (N, 3, r), in one pass over its
    blocks: the factor of the variance of what a fit with the covariance ``L L^T`` predicts at each sample
    (:func:`casep.noise.robust.robust_filter`'s `predicted`)."""
    r, G = problem.residuals_and_product(x, L)
    assert G is not None
    return r, G


#: ``robust="auto"``: the robust fit engages when the robust filter rejects more samples than
#: Gaussian noise explains: more than ``expected + GLITCH_SIGMAS sqrt(expected) + GLITCH_MIN``, with
#: ``expected = N P(any axis |u| > 4)`` (Poisson; 0.7 on a 20 Hz, 200 s flight, so 8 trigger).
GLITCH_SIGMAS = 4.0
GLITCH_MIN = 3
#: ... or when one rejection is gross: an innovation beyond this many robust sigma on any axis, which
#: Gaussian noise gives with P = 1.6e-23 per value (3e-18 on a 200 s, 20 Hz flight). A few 3 m/s glitches
#: in 0.1 m/s noise (|u| ~ 30) stay below the count of rejections that engages the fit, but bias it.
GLITCH_GROSS = 10.0


def _glitches(problem: Problem, nm: NoiseModel) -> tuple[int, float, int, list[tuple[int, int]], np.ndarray]:
    """(rejections of the robust filter on the least-squares residuals, the count Gaussian noise gives,
    the rejections beyond :data:`GLITCH_GROSS`, the runs of rejections as long as the filter's
    :data:`casep.noise.robust.MAX_RUN` (``(first, stop)`` samples): a step or a smooth misfit, not a glitch;
    the residuals judged, (N, 3))."""
    from casep._special import normal_sf  # without importing scipy.special (its import, 0.1-0.6 s)
    from casep.noise.robust import REJECT

    assert problem.t is not None  # the caller checked
    # judged on a fit without the samples rejected, iterated: glitches distort the least-squares fit, and on
    # low-noise data the misfit they leave is itself rejected (in runs) while the glitches bias the fit
    keep = np.ones(problem.n_samples, dtype=bool)
    floor = problem.rounding_floor()
    for _ in range(_MAX_ROBUST_ITER):
        x, _, L = _ls_factor(_rows(problem, keep, nm, None))
        r = problem.residuals(x)
        rw = robust_filter(r, problem.t, nm, floor=floor)
        if not rw.keep.all():  # the fit's prediction variance only widens an innovation: with no rejection on the
            r, G = _predicted(problem, x, L)  # noise alone there is none with it (and u is the noise's either way)
            rw = robust_filter(r, problem.t, nm, floor=floor, predicted=G)
        if np.array_equal(rw.keep, keep) or 3 * int(rw.keep.sum()) <= problem.n:  # too few rows left to refit
            break
        keep = rw.keep
    expected = problem.n_samples * (1.0 - (1.0 - 2.0 * normal_sf(REJECT)) ** 3)  # P(|z| > REJECT), any axis
    gross = int(np.sum(~rw.keep & np.any(np.abs(rw.u) > GLITCH_GROSS, axis=1)))
    long = [(a, b) for a, b in runs(~rw.keep) if b - a >= MAX_RUN]
    return int((~rw.keep).sum()), float(expected), gross, long, r


def rejected_runs(keep: np.ndarray) -> list[int]:
    """The lengths of the runs of rejected samples (False in `keep`) at least :data:`casep.noise.robust.MAX_RUN`
    long: a step or a smooth misfit of the model, not glitches (a glitch is isolated)."""
    return [b - a for a, b in runs(~np.asarray(keep, dtype=bool)) if b - a >= MAX_RUN]


def mostly_runs(found: int, long: list[int]) -> bool:
    """Whether most of `found` rejected samples lie in the runs `long` (:func:`rejected_runs`): the residuals hold
    a smooth misfit of the model, which rejecting (or down-weighting) its peaks hides and biases the fit with."""
    return 2 * sum(long) > found


#: The runs a misfit warning and record name (the rest counted).
MISFIT_RUNS_SAID = 6


#: Steps of the rows at one period this many times in a row or more are a stepped tracking (:func:`stepped_rows`).
STEPPED_MIN = 4
#: The chance that steps at random epochs (as many as found) chain at one period as long, above which a chain is
#: not said to be a stepped tracking (:func:`stepped_rows`).
STEPPED_ALARM = 0.01


def stepped_rows(t: np.ndarray, y: np.ndarray, first: int) -> dict | None:
    """Whether a fit's residuals `y` ``(N, 3)`` (of ``dv = v_tel - v_trk``, m/s) at times `t` (s) step at a regular
    period from the sample `first` on: a tracking velocity updated at a lower rate than its epochs and held between
    (a receiver updating its velocity at 1 Hz, perhaps late), which leaves runs of misfit the fit cannot absorb.

    A step is an epoch-to-epoch change of a residual beyond :data:`casep.noise.robust.REJECT` robust sigma (1.4826
    MAD of the changes per axis, from `first` on: the vehicle's motion is in both velocities and what the model
    explains is out, the tracking's error is left); the steps are regular when :data:`STEPPED_MIN` or more of them
    in a row are spaced by one period (within half an epoch; at least two epochs: a step every epoch is noise), and
    as many steps at random epochs would chain so by chance at most :data:`STEPPED_ALARM` of the time. Returns the
    longest such chain ``{"first_t", "last_t", "period_s", "steps"}`` or None. Nothing is masked on it: it is
    said."""
    from casep._special import MAD_SIGMA
    from casep.noise.robust import REJECT

    lo = max(int(first) - 1, 0)  # the step that lands on the first sample counts
    t = np.asarray(t, dtype=float)[lo:]
    y = np.asarray(y, dtype=float)[lo:]
    if y.ndim != 2 or t.size <= 2 * STEPPED_MIN or not np.all(np.diff(t) > 0):
        return None  # too short, or several flights' rows after one another
    d = np.diff(y, axis=0)
    dev = np.abs(d - np.median(d, axis=0))
    s = MAD_SIGMA * np.median(dev, axis=0)
    k = np.flatnonzero(np.any(dev > REJECT * np.where(s > 0, s, np.inf), axis=1)) + 1  # where a step lands
    if k.size < STEPPED_MIN:
        return None
    tk, epoch = t[k], float(np.median(np.diff(t)))
    gaps = np.diff(tk)
    best, i = (0, -1), 0
    while i < gaps.size:  # the longest chain of gaps equal to its first
        j = i
        while j + 1 < gaps.size and abs(gaps[j + 1] - gaps[i]) < 0.5 * epoch:
            j += 1
        if gaps[i] >= 1.5 * epoch and j - i > best[1] - best[0]:
            best = (i, j)
        i = j + 1
    i, j = best
    q = k.size / d.shape[0]  # the share of epochs with a step; steps that many, at random, chain by chance this often:
    chance = gaps.size * (q * (1.0 - q) ** (round(gaps[i] / epoch) - 1)) ** (j - i + 1)
    if j - i + 2 < STEPPED_MIN or chance > STEPPED_ALARM:
        return None
    return {"first_t": float(tk[i]), "last_t": float(tk[j + 1]), "period_s": float(np.mean(gaps[i:j + 1])),
            "steps": int(j - i + 2)}


def _misfit_runs(problem: Problem, found: int, spans: list[tuple[int, int]], resid: np.ndarray) -> dict:
    """The record of :attr:`Rows.misfit_runs`: the runs `spans` (``(first, stop)`` samples) located in their files,
    and whether the residuals `resid` (N, 3) step at a regular period from the first run on
    (:func:`stepped_rows`)."""
    said = spans[:MISFIT_RUNS_SAID]
    locs = problem.locate([k for a, b in said for k in (a, b - 1)])
    return {"found": int(found), "in_runs": int(sum(b - a for a, b in spans)), "count": len(spans),
            "runs": [{"first": locs[2 * i], "last": locs[2 * i + 1], "samples": int(b - a)}
                     for i, (a, b) in enumerate(said)],
            "stepped": None if not spans or problem.t is None else stepped_rows(problem.t, resid, spans[0][0])}


def misfit_runs_text(record: dict) -> str:
    """Where the runs of a :attr:`Rows.misfit_runs` record lie: ``lines 1083..1102 of f.csv, t = 60..60.95 s (20)``,
    each run, the first :data:`MISFIT_RUNS_SAID` of them."""
    from pathlib import Path

    parts = []
    for r in record["runs"]:
        first, last = r["first"], r["last"]
        at = "" if first.get("file") is None else (
            f"lines {first['line']}..{last['line']}" if first.get("line") is not None else
            f"rows {first['row']}..{last['row']}") + f" of {Path(first['file']).name}, "
        parts.append(f"{at}t = {first['t']:.10g}..{last['t']:.10g} s ({r['samples']})")
    more = record["count"] - len(record["runs"])
    step = record.get("stepped")
    said = "" if not step else (
        f"; the residuals step every {step['period_s']:.3g} s over t = {step['first_t']:.10g}..{step['last_t']:.10g} s "
        f"({step['steps']} steps in a row beyond the noise of their epoch-to-epoch change): a velocity (the "
        f"tracking's, or the telemetry's) updated every {step['period_s']:.3g} s and held between (perhaps late), "
        "not a term of the model: check the tracking there")
    return ", ".join(parts) + (f" and {more} more" if more > 0 else "") + said


def _warn_misfit(problem: Problem, record: dict, shortest: int) -> None:
    """Say that the least-squares residuals hold runs, not glitches, and where (:func:`prepare_rows`)."""
    import warnings

    from casep.exceptions import NoiseNotWhiteWarning
    from casep.noise.robust import REJECT

    warnings.warn(NoiseNotWhiteWarning(
        f"{problem.source}: {record['in_runs']} of the {record['found']} samples the robust filter would reject lie "
        f"in {record['count']} run(s) of {shortest} or more consecutive samples beyond {REJECT:g} robust sigma "
        f"({misfit_runs_text(record)}): a smooth misfit of the model (a missing term, a frame or time-tag error, "
        "or instrument errors too large for the linear model) or a block of wrong tracking epochs, not isolated "
        "glitches; the robust fit is not engaged, and the std do not cover the misfit"), stacklevel=3)


def prepare_rows(problem: Problem, noise: str | NoiseSpec = "auto", tau=None, robust: str | None = "auto",
                 exclude_outliers: float | None = None) -> Rows:
    """The noise model, robust weights and removed samples of a problem (module notes).

    Parameters
    ----------
    problem : Problem
        Raw rows ``(N, 3)`` with their times.
    noise : {"auto", "gm", "gmw", "white"} or NoiseSpec
        The noise kind; or a whole noise request (its tau, robust and exclude_outliers are then taken and
        the other arguments ignored). Checked by :class:`casep.noise.spec.NoiseSpec`, the request's one check.
    tau : float, three floats or None
        Given Gauss-Markov correlation time(s), s (``noise="gm"``).
    robust : {"auto", None, "none", "huber", "bisquare"}
        ``auto`` (default): Huber when the robust filter finds glitches (more rejections than
        Gaussian noise explains: :data:`GLITCH_SIGMAS`; or one beyond :data:`GLITCH_GROSS` sigma),
        else none, and said in ``robust``; when most rejections come in runs of
        :data:`casep.noise.robust.MAX_RUN` (a smooth model misfit, not glitches: a glitch is isolated)
        none, with a :class:`~casep.exceptions.NoiseNotWhiteWarning`;
        None or ``none``: never.
    exclude_outliers : float, optional
        Family-wise false-alarm chance of the outlier flags whose samples are removed.
    """
    # the request's one check (a NoiseSpec given is checked already)
    spec = noise if isinstance(noise, NoiseSpec) else NoiseSpec(noise, tau, robust, exclude_outliers=exclude_outliers)
    noise, tau, robust, exclude_outliers = spec.kind, spec.tau, spec.robust, spec.exclude_outliers
    noise_free = problem.is_noise_free()  # nothing to fit a noise model or a robust filter on
    nm = _noise_model(problem, noise, tau, noise_free)
    keep = np.ones(problem.n_samples, dtype=bool)
    weights = None
    robust_info = None
    auto = None
    misfit = None
    if robust == "auto":
        robust = None
        if not noise_free and exclude_outliers is None and problem.t is not None and problem.y is not None \
                and problem.y.ndim == 2:
            found, expected, gross, spans, resid = _glitches(problem, nm)
            limit = expected + GLITCH_SIGMAS * np.sqrt(expected) + GLITCH_MIN
            auto = {"glitches_found": found, "expected_from_noise": expected, "limit": float(limit),
                    "gross": gross, "gross_sigmas": GLITCH_GROSS}
            long = [b - a for a, b in spans]
            if mostly_runs(found, long):  # a smooth misfit, which rejecting its peaks would bias
                misfit = _misfit_runs(problem, found, spans, resid)
                _warn_misfit(problem, misfit, min(long))
            elif found > limit or gross:
                robust = "huber"
    if robust is not None:
        nm, keep, weights, robust_info = _robust(problem, nm, noise, tau, robust)
        if auto is not None:
            robust_info["automatic"] = auto
    solved = _rows(problem, keep, nm, weights)
    excluded_info = None
    if exclude_outliers is not None:
        solved, keep, excluded_info, nm = _exclude(problem, solved, nm, keep, weights, exclude_outliers, noise, tau)
    return Rows(problem, solved, nm, keep, weights, robust_info, excluded_info, noise, misfit)


def _noise_model(problem: Problem, noise: str, tau, noise_free: bool | None = None) -> NoiseModel:
    """The noise model of a problem's rows: :func:`casep.noise.fit.fit_noise`, or white on noise-free rows
    (:meth:`Problem.is_noise_free`: nothing to fit it on; also the samples a robust fit keeps of noise-free
    data with glitches)."""
    if noise != "white" and (problem.is_noise_free() if noise_free is None else noise_free):
        return dataclasses.replace(NoiseModel.white(), kind=noise, rule="noise-free data: white")
    return fit_noise(problem, noise, tau)


def _robust(problem, nm, noise, tau, function):
    """Least-squares IRLS with the robust filter (module notes): noise model, keep, weights, info."""
    keep = np.ones(problem.n_samples, dtype=bool)
    weights = None
    refits = 0
    history = []
    x, sd, L = _ls_factor(_rows(problem, keep, nm, weights))
    floor = problem.rounding_floor()  # the robust scale is never below the noise-free level
    rw = None
    for it in range(1, _MAX_ROBUST_ITER + 1):
        r, G = _predicted(problem, x, L)  # and the fit's own uncertainty at each sample: not a glitch
        rw = robust_filter(r, problem.t, nm, function=function, floor=floor, predicted=G)
        if not np.array_equal(rw.keep, keep) and noise != "white" and tau is None and refits < 2:
            # the correlation time on the kept samples only: glitches cannot collapse it
            nm = _noise_model(problem.subset(rw.keep), noise, None)
            refits += 1
            rw = robust_filter(r, problem.t, nm, function=function, floor=floor, predicted=G)
        changed = not np.array_equal(rw.keep, keep)
        keep, weights = rw.keep, rw.row_weights  # each stretch's rows at its own noise level, robustly weighted
        x_new, sd, L = _ls_factor(_rows(problem, keep, nm, weights))
        move = float(np.max(np.abs(x_new - x) / sd))
        x = x_new
        history.append({"iteration": it, "rejected": int((~keep).sum()), "max_step_std": move})
        if not changed and move < 1e-3:
            break
    if tau is not None and noise != "white" and not keep.all():  # given tau: the scales and sigma on the kept rows
        nm = _noise_model(problem.subset(keep), noise, tau)
    kept_noise_free = (problem if keep.all() else problem.subset(keep)).is_noise_free()  # then sigma estimated
    sigma = _robust_sigma(rw, keep, function, _row_scale(problem, keep, nm, x, rw.precision if rw else None)) \
        if rw is not None and not kept_noise_free else None
    info = {"function": function, "iterations": len(history), "rejected_count": int((~keep).sum()),
            "scale": rw.scale if rw is not None else None, "sigma_effective": sigma,
            "downweighted": int(np.sum(rw.weights[keep] < 1.0)) if rw is not None else 0,
            "rejected_runs": rejected_runs(keep),
            "noise_refits": refits, "history": history}
    return nm, keep, weights, info


def _row_scale(problem: Problem, keep: np.ndarray, nm: NoiseModel, x: np.ndarray,
               precision: np.ndarray | None = None) -> float:
    """Robust scale (1.4826 MAD) of the kept samples' residuals on the exactly whitened rows, the rows the
    methods solve (each times the square root of its stretch's `precision`, :class:`casep.noise.robust.
    RobustWeights`: at the one scale). On an axis with a white part the robust filter's innovations are those of
    the Gauss-Markov part alone, several times wider than the exact (Kalman) innovations: their scale is not the
    rows' own."""
    from casep.noise.robust import MAD_SIGMA

    per_sample = _rows(problem, keep, nm, None).residuals(x).reshape(-1, 3)
    if precision is not None:
        per_sample = per_sample * np.sqrt(precision[keep])[:, None]
    r = per_sample.reshape(-1)
    return float(MAD_SIGMA * np.median(np.abs(r - np.median(r))))


def _robust_sigma(rw, keep: np.ndarray, function: str, scale: float | None = None) -> float | None:
    """The sigma that makes the weighted least-squares covariance the M-estimator's (Huber 1981)::

        Cov = s^2 E[psi^2] / E[psi']^2 (Z^T Z)^-1 ~ sigma_eff^2 (Z^T W Z)^-1,
        sigma_eff^2 = s^2 mean(psi^2) mean(w) / mean(psi')^2,   psi = w u

    over the kept rows (``Z^T W Z ~ mean(w) Z^T Z``); ``s`` the robust scale of the rows solved
    (`scale`, :func:`_row_scale`; default the filter's own). The weighted residual std alone,
    ``s^2 mean(w u^2)``, is about 10 % too small for Huber at the Gaussian (0.821 against 1.030).
    """
    from casep.noise.robust import BISQUARE_C, HUBER_C

    u = rw.u[keep].reshape(-1)
    w = rw.weights[keep].reshape(-1)
    s = rw.scale if scale is None or not scale > 0 else scale
    if not s > 0 or u.size == 0:
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
    return float(s * np.sqrt(np.mean(psi**2) * np.mean(w)) / d)


def _exclude(problem, solved, nm, keep, weights, alpha, noise="auto", tau=None):
    """Remove the samples of flagged rows and prepare the rows again until nothing is flagged."""
    from casep.regression.outliers import flag_outliers

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
        if noise != "white":  # the noise model of the kept samples: the removed ones had bent it
            nm = _noise_model(problem.subset(keep), noise, tau)
        solved = _rows(problem, keep, nm, weights)
    info = {"alpha": alpha, "count": len(removed), "samples": removed}
    return solved, keep, info, nm


