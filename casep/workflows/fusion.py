"""Fusion of results: several estimates of one model's coefficients combined by their information.

:func:`fuse` combines results (each flight's, a joint one, a ground calibration mapped to its flight
model by :func:`fuse_with_ground`) as independent Gaussian measurements of the shared coefficients,
with a consistency test of their agreement.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from casep.estimators.joint import FAIL_P, WARN_P
from casep.estimators.result import EstimateResult

__all__ = ["fuse", "fuse_with_ground", "FUSE_WARN_P", "FUSE_FAIL_P"]


#: Fused results whose consistency test gives p below this are reported failed (``success`` false,
#: exit 1): about 5 sigma, far beyond chance; between it and :data:`FUSE_WARN_P`, a warning. The levels
#: of ``casep separate A B`` (:data:`casep.estimators.joint.FAIL_P`, :data:`casep.estimators.joint.WARN_P`).
FUSE_FAIL_P = FAIL_P
#: Consistency p-value below which ``fuse`` warns.
FUSE_WARN_P = WARN_P


def _fusion_inputs(results: Sequence[EstimateResult], labels: list[str], names: list[str],
                   unit0: dict[str, str]) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Each result's estimate ``D_k``, correlation factor ``L_k`` and std ``d_k`` over the shared `names`,
    ``C_k = diag(d_k) L_k L_k^T diag(d_k)``; ValueError for what cannot be fused (:func:`fuse`'s Raises)."""
    from casep.io.result_json import MAX_RESULT_VALUE, require_invertible

    xs, Ls, ds = [], [], []
    seen: list[tuple[np.ndarray, np.ndarray]] = []
    for r, lab in zip(results, labels):
        if r.covariance is None:
            raise ValueError(f"{lab} ({r.method}) has no covariance: it cannot be fused")
        missing = [n for n in names if n not in r.names]
        if missing:
            raise ValueError(f"{lab} lacks coefficient(s) {', '.join(missing)} of {labels[0]}")
        idx = [list(r.names).index(n) for n in names]
        for n, i in zip(names, idx):
            if r.units[i] != unit0[n]:
                raise ValueError(f"{lab}: `{n}` is in {r.units[i]!r}, but in {unit0[n]!r} in {labels[0]}: the "
                                 "results must give each coefficient in the same unit")
        x, C = np.asarray(r.estimate, dtype=float)[idx], np.asarray(r.covariance, dtype=float)[np.ix_(idx, idx)]
        if not np.all(np.isfinite(x)) or not np.all(np.isfinite(C)):
            bad = [n for n, v in zip(names, x) if not np.isfinite(v)]
            raise ValueError(f"{lab} has coefficients without an estimate ({', '.join(bad) or 'covariance'}): "
                             "their information is not in the result; estimate the flights together, or chain them "
                             "with --prior RESULT.json")
        big = [n for n, v in zip(names, x) if abs(v) > MAX_RESULT_VALUE]
        if big or np.max(np.abs(C)) > MAX_RESULT_VALUE**2:
            raise ValueError(f"{lab}: {'estimate of ' + big[0] if big else 'covariance'} beyond the magnitude limit "
                             f"{MAX_RESULT_VALUE:g} (natural units): a unit or typing mistake?")
        for k, (xo, Co) in enumerate(seen):
            if np.array_equal(xo, x) and np.array_equal(Co, C):
                raise ValueError(f"{lab} is the same estimate as {labels[k]}: its information would count twice")
        seen.append((x, C))
        C = 0.5 * (C + C.T)
        if np.any(np.diag(C) < 0):
            j = int(np.argmin(np.diag(C)))
            raise ValueError(f"{lab}: covariance of `{names[j]}` is {C[j, j]:g}: a variance must be >= 0")
        Ls.append(require_invertible(C, names, lab))  # correlation = L L^T
        ds.append(np.sqrt(np.diag(C)))
        xs.append(x)
    return xs, Ls, ds


def fuse(results: Sequence[EstimateResult], labels: Sequence[str] | None = None, model=None) -> EstimateResult:
    """Combine results saved earlier (Gaussian, with covariance) into one estimate of their shared
    coefficients: ``Lambda = sum_k C_k^-1``, ``D = Lambda^-1 sum_k C_k^-1 D_k``, and test that they agree.

    Each result's shared coefficients are used with their marginal covariance: per-flight
    coefficients (the model's ``per_flight=True`` ones such as ``dt_trk``, and a several-flights
    result's ``name[file]``) are left out, as each flight has its own (marginalising a Gaussian is
    taking its block). A result whose model gained its flight's own tracking offset (``name+dt_trk``:
    ``--imu``, Earth-fixed tracking) is of the same instrument as one of ``name``; the fused result is of
    ``name``. What the results together do not determine is said as a joint fit says it (the model's
    declared magnitudes, :func:`casep.estimators.registry.check_magnitudes`: ``reasons``, the message).
    For independent flights this is the joint estimate exactly (the marginal
    likelihood of the shared coefficients factorises), so fusing two OLS results equals estimating
    both flights at once with the same sigmas. Computed in coordinates scaled by each
    coefficient's std (Cholesky factor of the correlation matrix; no squared condition number of
    natural units). The inputs must be of different flights: the same result twice is refused (its
    information would count twice); a flight inside two results (a joint result and one of its
    flights) cannot be told from the numbers, so the inputs are recorded in ``settings["fused"]``.

    Consistency, like the joint fit's (``diagnostics["consistency"]``): overall, with ``n`` shared
    coefficients and ``K`` results, ::

        chi2 = sum_k (D_k - D)^T C_k^-1 (D_k - D)   ~ chi2((K - 1) n)  when the results agree

    and per coefficient j, ``chi2_j = sum_k (D_kj - dbar_j)^2 / C_k,jj ~ chi2(K - 1)`` (marginal,
    :func:`casep.estimators.joint.coefficient_consistency`). Below ``p = 0.01`` (:data:`FUSE_WARN_P`) a
    :class:`~casep.exceptions.ConsistencyWarning` gives the numbers and the coefficients that disagree
    most; below ``p = 1e-6`` (:data:`FUSE_FAIL_P`, about 5 sigma) the fused result is not a success
    (``success`` false, ``status`` 2: the std of an average of disagreeing results are not its error).

    Parameters
    ----------
    results : sequence of EstimateResult
    labels : sequence of str, optional
        Names of the results (their files) for messages and ``settings``.
    model : ErrorModel or str, optional
        The results' model (default: loaded by name), to tell the per-flight coefficients.

    Raises
    ------
    ValueError
        Results of different instrument models (naming both), a result without covariance, a coefficient
        without an estimate (its information is not in the covariance), a coefficient in another
        unit than in the first result, a value that is not finite or beyond
        :data:`casep.io.result_json.MAX_RESULT_VALUE`, a covariance that is not positive definite,
        the same result twice.
    """
    from casep.estimators.registry import check_magnitudes

    fused, scales = _fused(results, labels, model)
    # what the results together do not determine, said as a joint fit of the flights says it (the model's magnitudes)
    return check_magnitudes(fused, scales)


def _fused(results: Sequence[EstimateResult], labels: Sequence[str] | None,
           model: Any) -> tuple[EstimateResult, dict[str, float]]:
    """:func:`fuse` before the fused estimates are judged against the model's magnitudes: the result and those."""
    import dataclasses
    import warnings

    from scipy import linalg, stats

    from casep.estimators.joint import Consistency, coefficient_consistency, largest_disagreements
    from casep.estimators.map import per_flight_names, result_model
    from casep.exceptions import ConsistencyWarning
    if len(results) < 2:
        raise ValueError(f"fuse needs two or more results, got {len(results)}")
    labels = [f"result {k + 1}" for k in range(len(results))] if labels is None else [str(v) for v in labels]
    from casep.model.loader import base_model_name

    first = results[0]
    for r, lab in zip(results[1:], labels[1:]):  # a flight's own tracking offset (`+dt_trk`): the same instrument
        if r.model and first.model and base_model_name(r.model) != base_model_name(first.model):
            raise ValueError(f"results of different models: `{first.model}` ({labels[0]}) and `{r.model}` ({lab}); "
                             "fuse only results of one model")
    inst = result_model(first, model)
    own = per_flight_names(first, inst)
    names = [n for n in first.names if n not in own]
    shared = base_model_name(first.model) if first.model else first.model  # no per-flight term is fused
    unit0 = dict(zip(first.names, first.units))
    xs, Ls, ds = _fusion_inputs(results, labels, names, unit0)

    # Square-root information: C_k = diag(d_k) L_k L_k^T diag(d_k), so R_k = L_k^-1 diag(d_k)^-1 has
    # R_k^T R_k = C_k^-1; in coordinates y = D / c (c: each coefficient's smallest input std) flight k
    # contributes rows [L_k^-1 diag(c / d_k) | L_k^-1 (D_k / d_k)], stacked and reduced by one QR
    # (casep.estimators.joint.stack_sqrt_information): the information is never formed or inverted.
    from casep.estimators.joint import stack_sqrt_information

    n_coef = len(names)
    c = np.min(np.array(ds), axis=0)
    factors = [(linalg.solve_triangular(L, np.diag(c / d), lower=True),
                linalg.solve_triangular(L, x / d, lower=True)) for L, d, x in zip(Ls, ds, xs)]
    R, z = stack_sqrt_information(factors)
    if np.min(np.abs(np.diag(R))) <= 1e-14 * np.max(np.abs(np.diag(R))):
        raise ValueError("the fused information is singular: the results together do not determine every "
                         "coefficient")
    Ri = linalg.solve_triangular(R, np.eye(n_coef))  # R^-1
    est = c * linalg.solve_triangular(R, z)  # D = c R^-1 z
    cov = np.outer(c, c) * (Ri @ Ri.T)  # Lambda^-1 = diag(c) R^-1 R^-T diag(c)
    cov = 0.5 * (cov + cov.T)
    # Consistency: Mahalanobis distance of each input from the fused estimate, ||R_k (D_k - D)||^2.
    chi2 = float(sum(np.sum(linalg.solve_triangular(L, (x - est) / d, lower=True) ** 2)
                     for L, d, x in zip(Ls, ds, xs)))
    dof = (len(results) - 1) * n_coef
    overall = Consistency(chi2, dof, float(stats.chi2.sf(chi2, dof)))
    per = {}
    for j, nm in enumerate(names):
        t = coefficient_consistency(np.array([x[j] for x in xs]), np.array([d[j] ** 2 for d in ds]))
        if t is not None:
            per[nm] = t.to_dict()
    worst_text = largest_disagreements(per)
    success, status = True, 1
    message = f"{len(results)} results fused ({', '.join(labels)})"
    if overall.p_value < FUSE_WARN_P:
        what = (f"the fused results disagree: chi2 {chi2:.4g} on {dof} dof, p {overall.p_value:.3g} (warn below "
                f"{FUSE_WARN_P:g}, fail below {FUSE_FAIL_P:g}); largest per coefficient: {worst_text}. An unmodelled "
                "error in one flight, a unit or set-up mistake, or std that understate the error?")
        if overall.p_value < FUSE_FAIL_P:
            success, status = False, 2
            message += "; " + what
        else:
            warnings.warn(what, ConsistencyWarning, stacklevel=3)
    left = _left_out(results, labels, names)
    if left:
        message += ("; per-flight terms left out of the fusion (each flight has its own): " + "; ".join(
            f"{lab}: " + ", ".join(f"{n} {v['estimate']:.4g}" + (f" +- {v['std']:.2g}" if v["std"] is not None else "")
                                   + (f" {v['unit']}" if v["unit"] else "") for n, v in terms.items())
            for lab, terms in left.items()))
    idx0 = [list(first.names).index(nm) for nm in names]
    fused = dataclasses.replace(
        first, model=shared, method="fused", names=tuple(names), units=tuple(first.units[i] for i in idx0),
        estimate=est, std=np.sqrt(np.diag(cov)), covariance=cov, reasons={}, residuals=np.zeros((0, 3)),
        si_factors=np.asarray(first.si_factors)[idx0], history=None, history_std=None, status=status,
        message=message, success=success, sigma=math.nan,
        sigma_source="fused", extras=None, rank=len(names),
        diagnostics={"consistency": {"overall": overall.to_dict(), "per_coefficient": per,
                                     "test": "sum_k (D_k - D)^T C_k^-1 (D_k - D) ~ chi2((K-1) n)"}},
        settings={"fused": [{"file": lab, "method": r.method, "n_samples": int(r.n_samples),
                             "sigma": float(r.sigma) if np.isfinite(r.sigma) else None,
                             **({"left_out": left[lab]} if lab in left else {})}
                            for r, lab in zip(results, labels)], "sigma": "each input's own"},
        n_samples=int(sum(r.n_samples for r in results)), stored_residual_rms={a: None for a in "xyz"})
    return fused, inst.scales


def _left_out(results: Sequence[EstimateResult], labels: Sequence[str],
              names: Sequence[str]) -> dict[str, dict[str, dict[str, Any]]]:
    """Each result's coefficients not fused (its per-flight terms, such as ``dt_trk``), by label:
    ``{label: {name: {"estimate", "std", "unit"}}}`` (natural units; std None when not given)."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for r, lab in zip(results, labels):
        std = np.asarray(r.std, dtype=float) if r.std is not None else np.full(len(r.names), np.nan)
        terms = {n: {"estimate": float(r.estimate[j]), "std": float(std[j]) if np.isfinite(std[j]) else None,
                     "unit": r.units[j]} for j, n in enumerate(r.names) if n not in names}
        if terms:
            out[lab] = terms
    return out


def fuse_with_ground(results: Sequence[EstimateResult], labels: Sequence[str] | None = None,
                     model=None) -> tuple[EstimateResult, str]:
    """:func:`fuse` of flight results and ground calibrations (a calibration model with a flight model,
    such as ``platform36_ground``), and the text of each ground-versus-flight consistency test.

    Each ground calibration is mapped to its flight model's coefficients and tested against each flight
    result (:func:`casep.calibration.consistency.consistency`). A pair that disagrees (``p <``
    :data:`casep.calibration.consistency.DISAGREE_P`) means one of the two is wrong for the other (an
    unmodelled error, a unit or sign mistake, a changed instrument): the average of the two is then no
    estimate of either, so the fused result is not a success (``success`` false, ``status`` 2) and a
    :class:`~casep.exceptions.ConsistencyWarning` gives the pair and the numbers. Otherwise as
    :func:`fuse` (whose own consistency test still applies).

    Returns
    -------
    (EstimateResult, str)
        The fused result and the consistency tables ("" without a ground calibration).
    """
    import dataclasses
    import warnings

    from casep.calibration.consistency import DISAGREE_P, ground_flight_checks
    from casep.estimators.registry import check_magnitudes
    from casep.exceptions import ConsistencyWarning

    labels = [f"result {k + 1}" for k in range(len(results))] if labels is None else [str(v) for v in labels]
    mapped, checks, text = ground_flight_checks(results, labels)
    res, scales = _fused(mapped, labels, model)
    bad = [c for c in checks if not c.consistent]
    if bad:
        what = "; ".join(f"{c.labels[0]} and {c.labels[1]} disagree: chi2 {c.chi2:.4g} on {c.dof} dof, p "
                         f"{c.p_value:.3g} (below {DISAGREE_P:g})"
                         + (f", |z| > 3: {', '.join(c.disagree)}" if c.disagree else "") for c in bad)
        what += ("; the fused result averages estimates that contradict each other (an unmodelled error, a unit or "
                 "sign mistake, or a changed instrument): it is not a success")
        warnings.warn(what, ConsistencyWarning, stacklevel=2)
        res = dataclasses.replace(res, success=False, status=res.status if res.status <= 0 else 2,
                                  message=f"{res.message}; {what}")
    return check_magnitudes(res, scales), text  # after the pairs: a disagreement is the first failure
