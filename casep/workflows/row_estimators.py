"""The GLS estimators of a fit's rows and what they carry: any linear estimator on the rows of a fit (its
coefficients, a combination of them, or columns beside its design), its noise (the tracking noise refitted beside
the IMU's, the uncertainty of its correlation times, the IMU's own noise) and consider parameters through it.

One place for the separation of a raw IMU record (:mod:`casep.workflows.imu_separate`, which re-exports these names)
and for every test of columns beside a fit (the given heading, the clock, a frame's rotation, a richer model's
terms: :mod:`casep.workflows.omitted_terms`). The functions named here without a module are
:mod:`casep.workflows.imu_separate`'s.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from casep.estimators.result import EstimateResult
from casep.io.flight import FlightData

__all__ = ["estimator_noise", "combination_estimators", "with_heading", "with_consider", "column_estimates",
           "tau_spread", "relative_positive_part", "with_extra_covariance", "added_covariance", "with_added_variance",
           "combinations_with_consider", "CONSIDER_KEY"]


def estimator_noise(a: np.ndarray, res: EstimateResult, problem: Any, flight: FlightData,
                    levelling: tuple | None = None, profile: tuple | None = None,
                    heading: np.ndarray | None = None,
                    full: bool = False) -> tuple[np.ndarray | None, np.ndarray] | None:
    """The variances of the estimators `a` (m, 3N: rows on the raw rows of `problem`, axis-interleaved) under the
    noise of :func:`imu_noise_budget`: ``(tracking part, IMU part)``, as :func:`combination_imu_noise` (its rule, for
    any linear estimator on the rows: the stated combinations' and :func:`heading_conflict`'s); with `full` their
    covariances (m, m) instead (a joint test of several estimators: :mod:`casep.workflows.omitted_terms`)."""
    from casep.checks.tracking_quality import imu_noise_effect
    from casep.noise.known import tracking_covariance_times
    from casep.noise.model import NoiseModel

    nd = res.diagnostics["noise"]
    t = np.asarray(problem.t, dtype=float)
    N, m = t.size, a.shape[0]
    held = (nd.get("imu") or {}).get("instability")
    AG = imu_noise_effect(flight, t, a, levelling, None if not held or held.get("variances") is None else
                          (held["tau_s"], *held["variances"]))
    if AG is None:
        return None
    AG = with_heading(AG, a, heading)
    refit = (nd.get("imu") or {}).get("tracking_noise")
    trk = None
    if refit is not None:
        times = tracking_covariance_times(a.T.reshape(N, 3, m), t, NoiseModel.from_dict(refit)).reshape(3 * N, m)
        spread = tau_spread(a, problem, profile)
        trk = a @ times + spread if full else np.einsum("ij,ji->i", a, times) + np.diag(spread)
    return trk, (AG @ AG.T if full else np.sum(AG**2, axis=1))


def combination_estimators(W: np.ndarray, scale: np.ndarray, res: EstimateResult, problem: Any,
                           column: np.ndarray | None = None) -> np.ndarray | None:
    """The estimators (m, 3N) of the combinations ``W (D / scale)`` on the raw rows of `problem` (axis-interleaved): the
    rows of ``W P``, ``P`` the GLS estimator of ``D / scale`` under `res`'s noise model (:func:`combination_imu_noise`);
    None without times or a noise model. With `column` (N, 3) the design gains it as one more column (the rows'
    derivative along the heading: :func:`heading_conflict`), `W` one more entry per row for its coefficient; (N, 3, k):
    k more columns (a frame's rotation about three axes: :mod:`casep.workflows.telemetry_frame`), k more entries."""
    out = _estimators(W, scale, res, problem, column)
    return None if out is None else out[1]


def _estimators(W: np.ndarray, scale: np.ndarray, res: EstimateResult, problem: Any,
                column: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`combination_estimators` on the whitened rows and on the raw rows: ``(W P_w, W P)``, each (m, 3N)."""
    from casep.noise.model import NoiseModel, whiten, whiten_transpose

    nd = res.diagnostics.get("noise")
    if problem.t is None or not isinstance(nd, dict) or "axes" not in nd:
        return None
    t = np.asarray(problem.t, dtype=float)
    S = problem.sv()
    if column is not None:
        extra = np.asarray(column, dtype=float).reshape(S.shape[0], 3, -1)
        S, scale = np.concatenate([S, extra], axis=2), np.append(scale, np.ones(extra.shape[2]))
    N, _, n = S.shape
    m = W.shape[0]
    U = whiten(S, np.zeros((N, 3)), t, NoiseModel.from_dict(nd))[0].reshape(3 * N, n) * scale
    a = W @ np.linalg.pinv(U)  # (m, 3N): the combinations' estimators on the whitened rows
    return a, whiten_transpose(a.T.reshape(N, 3, m), t, NoiseModel.from_dict(nd)).reshape(3 * N, m).T  # ... raw rows


def with_heading(AG: np.ndarray, a: np.ndarray, heading: np.ndarray | None) -> np.ndarray:
    """``A G`` (k, p) of the estimators `a` (k, 3N) with the given heading's column: ``a s``, `heading` ``s`` (N, 3)
    the rows' shift for one std of the heading (:meth:`_Run.heading_rows`); `AG` itself without one. The estimate is
    linear in the rows, so a heading off by ``e`` std moves it by ``e a s``, and its variance over the heading's
    uncertainty is ``(a s)^2``: the consider term, formed here for the coefficients (:func:`imu_noise_budget`) and the
    stated combinations (:func:`combination_imu_noise`) alike. `heading` (N, 3, c): c such columns (each an
    independent consider parameter: :func:`consider_columns`)."""
    if heading is None:
        return AG
    return np.column_stack([AG, a @ np.asarray(heading, dtype=float).reshape(a.shape[1], -1)])


def coefficient_estimators(res: EstimateResult, problem: Any) -> np.ndarray | None:
    """The coefficients' own estimators (n, 3N) on the raw rows of `problem`: :func:`combination_estimators` of the
    identity (None as it)."""
    n = len(res.names)
    return combination_estimators(np.eye(n), np.ones(n), res, problem)


def consider_estimators(res: EstimateResult, problem: Any) -> np.ndarray:
    """What a consider column goes through to the coefficients (n, 3N): :func:`coefficient_estimators`, and for a fit
    without a noise model the OLS pseudo-inverse of S_V (:func:`with_consider`, :func:`with_drift`)."""
    a = coefficient_estimators(res, problem)
    if a is None:
        S = problem.sv()
        a = np.linalg.pinv(S.reshape(-1, S.shape[2]))
    return a


def widened_std(res: EstimateResult, cov: np.ndarray) -> np.ndarray | None:
    """The std of `res` under its covariance widened to `cov` (a consider term, the IMU's noise): NaN where the fit's
    is NaN (a coefficient it does not determine stays so); None where `res` has none."""
    from casep.regression.linalg import covariance_std

    return None if res.std is None else np.where(np.isfinite(res.std), covariance_std(cov), np.nan)


def with_consider(res: EstimateResult, problem: Any, cols: np.ndarray) -> EstimateResult:
    """`res` whose covariance gains the consider columns `cols` (N, 3, c; :func:`with_heading`) through its own
    estimators (:func:`combination_estimators`; a fit without a noise model: the OLS pseudo-inverse of S_V); for a
    result :func:`with_imu_noise` did not extend (a flight without the IMU's samples or noise)."""
    if res.covariance is None:
        return res
    a = consider_estimators(res, problem)
    g = a @ np.asarray(cols, dtype=float).reshape(a.shape[1], -1)
    return with_extra_covariance(res, g @ g.T)


#: The key of a result's ``diagnostics`` that holds what :func:`with_extra_covariance` added to its covariance.
CONSIDER_KEY = "consider"
#: A result's diagnostics key: the covariance the rest's shift added
#: (:meth:`casep.workflows.imu_separate._Run.with_rest_shift`), part of the consider total, which the stated
#: combinations' ``curvature_shift`` holds already.
REST_SHIFT_KEY = "rest_shift_covariance"


def with_extra_covariance(res: EstimateResult, extra: np.ndarray) -> EstimateResult:
    """`res` whose covariance, its solution's and its std gain `extra` (natural units: a consider term's ``g g^T``),
    ``C + extra`` where ``C`` is finite (:func:`widened_std`): the one place a consider term widens a result, so that
    what reads the solution's covariance (the iteration's step) sees what the stated std do. The sum of what was
    added is kept in ``diagnostics["consider"]["covariance"]`` (:func:`added_covariance`): a later step that sets
    the covariance anew (the IMU's noise with the tracking noise refitted:
    :func:`casep.workflows.imu_separate.with_imu_noise`) adds it back, and the stated combinations' std gain
    ``w^T E w`` of it (:func:`with_added_variance`)."""
    C = np.asarray(res.covariance)
    extra = np.asarray(extra, dtype=float)
    cov = np.where(np.isfinite(C), C + extra, np.nan)
    solution = res.solution
    if solution is not None and solution.covariance is not None:
        solution = dataclasses.replace(solution, covariance=solution.covariance + extra)
    before = added_covariance(res)
    total = extra if before is None else before + extra
    diag = {**res.diagnostics, CONSIDER_KEY: {
        "covariance": total.tolist(), "names": list(res.names),
        "rule": "the consider terms added on top of the noise's covariance (natural units): the omitted terms, the "
                "clock drift, the steps between samples and the IMU record's gaps where the IMU's noise is not "
                "carried; kept through a covariance set anew, and in the stated combinations' std (w^T E w)"}}
    return dataclasses.replace(res, covariance=cov, std=widened_std(res, cov), solution=solution, diagnostics=diag)


def added_covariance(res: EstimateResult) -> np.ndarray | None:
    """What :func:`with_extra_covariance` added to `res`'s covariance, summed (n, n, natural units); None: nothing."""
    got = (res.diagnostics.get(CONSIDER_KEY) or {}).get("covariance")
    return None if got is None else np.asarray(got, dtype=float).reshape(len(res.names), len(res.names))


def with_added_variance(res: EstimateResult, W: np.ndarray, scale: np.ndarray, var: np.ndarray) -> np.ndarray:
    """The variances `var` (m,) of the combinations ``W (D / scale)`` (`W` (m, n)) with the consider terms
    :func:`with_extra_covariance` added to the coefficients (:func:`added_covariance` ``E``): ``var + w_s^T E w_s``,
    ``w_s = w / scale``. The one rule by which those terms reach a stated combination: for a combination the rows
    determine (orthogonal to the fit's null space) its estimator is ``w_s^T`` times the coefficients' own, so its
    consider variance is ``(w_s^T g)^2`` summed over the terms' ``g``, as the coefficients' ``g g^T``."""
    E = added_covariance(res)
    if E is None:
        return np.asarray(var, dtype=float)
    Ws = np.asarray(W, dtype=float) / np.asarray(scale, dtype=float)
    return np.asarray(var, dtype=float) + np.einsum("ij,jk,ik->i", Ws, E, Ws)


def combinations_with_consider(combos: list[dict], res: EstimateResult, scales: Any) -> list[dict]:
    """The stated combinations `combos` (``weights`` on ``D / scale`` over `res`'s coefficients, ``std`` in declared
    magnitudes; `scales` the declared magnitudes by name, 1 for a name without one) with every consider term `res`'s
    covariance gained on top of its noise's in their std (:func:`with_added_variance`: the richer model's terms, the
    IMU clock's drift, the steps between samples where the IMU's noise is not carried), as the coefficients have
    them; each keeps its std without them as ``std_without_consider`` (the same without such terms). One rule for
    every statement of what a flight determines: the combinations of a flight whose tracking noise differs between
    stretches (:func:`casep.workflows.judging.judge_tracking`) and those an iteration stepped along
    (:meth:`casep.workflows.imu_separate._Run.finish`).

    The stretches' combinations are estimated with a weighting of their own (each stretch by its noise:
    :func:`casep.checks.tracking_quality.determined`), not the fit's estimators the consider terms went through. For
    the part of a term the fit's columns take (the absorbed part: on the strapdown boost almost all of it, module notes
    of :mod:`casep.workflows.omitted_terms`) that is the same: any unbiased estimator of a combination the rows
    determine moves alike. The part beyond the columns goes through each estimator differently; it is what the rows'
    test of :func:`casep.workflows.omitted_terms.judge_omitted` sees and bounds."""
    if not combos:
        return combos
    W = np.array([c["weights"] for c in combos], dtype=float)
    scale = np.array([scales.get(nm, 1.0) for nm in res.names], dtype=float)
    var = with_added_variance(res, W, scale, np.array([c["std"] ** 2 for c in combos]))
    rest = res.diagnostics.get(REST_SHIFT_KEY)
    if rest is not None:  # the rest's shift: in the consider total as the coefficients carry it, in the std of the
        # combinations that hold ``curvature_shift`` already (the same ``mean(b b^T)`` along ``w``): not added again
        Ws = W / scale
        held = np.array(["curvature_shift" in c for c in combos])
        var = var - held * np.einsum("ij,jk,ik->i", Ws, np.asarray(rest, dtype=float), Ws)
    return [{**c, "std_without_consider": c["std"], "std": float(np.sqrt(v))} for c, v in zip(combos, var)]


def column_estimates(res: EstimateResult, problem: Any, flight: FlightData, columns: np.ndarray | None,
                     levelling: tuple | None = None, profile: tuple | None = None,
                     consider: np.ndarray | None = None, covariance: bool = False) -> tuple[np.ndarray, ...] | None:
    """The GLS estimates (k,) of `columns` (N, 3) or (N, 3, k) as k more coefficients of `problem`'s design (S_V
    projected out, `res`'s whitening), each with the others free, and their std (k,): :func:`heading_conflict`'s rule
    for the heading's column, one place for every such test (a frame's rotation about three axes:
    :mod:`casep.workflows.telemetry_frame`). The std are those of any linear estimator on the rows
    (:func:`estimator_noise`: the tracking noise refitted beside the IMU's, the uncertainty of its correlation
    times, the IMU's own noise, the `consider` columns (:func:`consider_columns`) as the stated combinations' std
    carry them; the fit's own ``sigma`` with its whitening where the noise was not refitted). None without the
    columns, rows, times or a noise model (:func:`heading_conflict`, :func:`clock_check`). With `covariance` their
    covariance (k, k) too, as a third item (a joint test of the columns: :mod:`casep.workflows.omitted_terms`)."""
    if columns is None or problem.y is None or not np.all(np.isfinite(columns)):
        return None
    n = len(res.names)
    k = np.asarray(columns).reshape(np.asarray(columns).shape[0], 3, -1).shape[2]
    W = np.zeros((k, n + k))
    W[:, n:] = np.eye(k)
    est = _estimators(W, np.ones(n), res, problem, columns)
    if est is None:
        return None
    a_w, a = est
    offset = a @ np.asarray(problem.y, dtype=float).reshape(-1)
    # the fit's own noise (its whitening, its sigma)
    own = float(res.sigma) ** 2 * (a_w @ a_w.T if covariance else np.sum(a_w**2, axis=1))
    var = estimator_noise(a, res, problem, flight, levelling, profile, consider, full=covariance)
    var_c = own if var is None else (own if var[0] is None else np.asarray(var[0], float)) + np.asarray(var[1], float)
    if covariance:
        return offset, np.sqrt(np.maximum(np.diag(var_c), 0.0)), var_c
    return offset, np.sqrt(np.maximum(var_c, 0.0))


def tau_spread(a: np.ndarray, problem: Any, profile: tuple | None) -> np.ndarray:
    """The covariance (m, m) the uncertainty of the tracking noise's correlation times adds to the estimators `a`
    (m, 3N: rows on the raw rows of `problem`, axis-interleaved); `profile` :func:`casep.noise.fit.tau_profile`'s of
    `problem` (:meth:`_Run.tau_profile`; None: zero, as where the request states tau, which is conditioned on).

    The tracking noise's covariance of the estimators is ``a Sigma_track(theta) a^T`` at the fitted ``theta``; a
    short record holds each axis's tau only to a factor of several, and over that range the variance of a
    combination can change several times (a 20 s rail launch at 5 Hz, tau 1 s, Gauss-Markov plus white:
    ``benchmarks/mc_imu_gmw_combinations.py``; REML's tau from white to 9.5 s over its 12 seeds, the best-determined
    combination's variance 6 times the fitted one's under the true noise). Per axis, the mean of ``a Sigma a^T`` over
    the posterior of that axis's tau (the profile's 95 % interval, weighted by the restricted likelihood, the other
    axes at the Gauss-Markov plus white fit) less its value at that fit, its part that adds variance to that value
    (:func:`relative_positive_part`: the same in any units), summed over the axes (the axes one at a time). The
    average stops at the record length (:func:`casep.noise.fit.tau_profile`'s notes), where the record does not bound
    tau (said: :func:`warn_tau_unbounded`). The coefficients' covariance (:func:`imu_noise_budget`) and the stated
    combinations' std (:func:`combination_imu_noise`) both gain it. The profile is of the rows with the IMU's noise
    in them (not beside it: :func:`_tracking_beside_imu`), as the fit that chose the noise model saw them."""
    from casep.noise.known import tracking_covariance_times

    t = np.asarray(problem.t, dtype=float)
    N, m = t.size, a.shape[0]
    extra = np.zeros((m, m))
    if profile is None:
        return extra

    def cov(noise: Any) -> np.ndarray:
        return a @ tracking_covariance_times(a.T.reshape(N, 3, m), t, noise).reshape(3 * N, m)

    base, axes = profile
    c0 = cov(base)
    for points in axes:
        extra += relative_positive_part(sum(w * cov(nm) for w, nm in points) - c0, c0)
    return extra


def relative_positive_part(M: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The part of the symmetric `M` that adds variance to the covariance `C` (both (m, m)): with the generalized
    eigenvectors ``M v = lam C v`` (``V^T C V = I``), ``C V diag(max(lam, 0)) V^T C``; zero along `C`'s null space.

    Each ``lam`` is the factor by which `M` changes the variance of one combination relative to `C`'s, so the part is
    the same whatever units the coefficients are in (a congruence ``R M R^T``, ``R C R^T`` gives ``R P R^T``). The
    positive part in the coefficients' own units (``eigh(M)``) is not: on a 16 s pad record at rest, where ``M`` spans
    1e22 (natural units) along what the record does not determine, it raised the best-determined combination's std
    from 0.05 to 17.6 declared magnitudes, and the record "determined none". Here `C` is equilibrated (unit
    diagonal) before its eigen-decomposition, so its directions hold to eps times its condition number relative to
    their own variance; directions below ``m eps`` of its largest eigenvalue are its null space."""
    from casep.regression.linalg import covariance_std

    m = C.shape[0]
    d = covariance_std(C)
    inv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    lam0, Q = np.linalg.eigh(C * np.outer(inv, inv))
    if not lam0.size or not lam0[-1] > 0:
        return np.zeros_like(C)
    keep = lam0 > m * np.finfo(float).eps * lam0[-1]
    R = Q[:, keep] * np.sqrt(lam0[keep])  # C (equilibrated) = R R^T
    T = Q[:, keep] / np.sqrt(lam0[keep])  # R^T T = I
    lam, V = np.linalg.eigh(T.T @ (M * np.outer(inv, inv)) @ T)
    RV = R @ V
    return (RV * np.clip(lam, 0.0, None)) @ RV.T * np.outer(d, d)
