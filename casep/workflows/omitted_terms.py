"""The terms a fitted strapdown model leaves out: the richer shipped model's extra columns beside the fit.

The richer shipped model (:data:`casep.model.loader.RICHER_MODELS`, the first one named) has terms the fitted one
lacks. Their columns act on the rows in two parts: what the fit's design (S_V, whitened by the fit's noise model)
can take, which its coefficients absorb, and what it leaves. Only the second is seen in the rows.

**The rows' test.** The extra columns less their projection on the whitened design leave a few combinations
(strapdown33 on the strapdown boost is rank 21 of 33: six beside strapdown15_axial; the null space, below
:data:`OMITTED_RCOND` of the largest singular value, is left). Their GLS estimates and covariance are those of any
column beside the fit (:func:`casep.workflows.row_estimators.column_estimates`, the fit's noise model: not refitted
beside them, which cost 5.5 s on a 20 Hz boost), judged jointly: the Wald chi-square ``c^T C^-1 c`` on as many dof,
at the consistency rule of several flights (:data:`casep.estimators.joint.FAIL_P`, 1e-6: a correct model fails
once in 10^6 flights where the std hold). Beyond it the result fails with the status of a model error
(``STATUS_MISFIT``), naming the combinations of the terms the rows determine beyond 3 std (each term over its declared
magnitude, in natural units), their estimates and std, and the richer model.

**The absorbed part.** On the simulated strapdown boost the rows' test sees nothing (chi-square 2-5 on 6 dof with
every strapdown33 term drawn; the terms' non-centrality 0.007): the pitch-plane gyro terms strapdown15_axial lacks
act almost wholly through its own columns (``sum of squares 1.3e3 sigma^2 absorbed``), so its determined
combinations are 30-40 std off and no test on the rows can tell. That part is carried as consider parameters: each
extra term at its declared magnitude (its prior std) through the fit's estimators
(:func:`casep.workflows.row_estimators.with_consider`, the given heading's rule), said in a line with how far those
terms move the best-determined combination in its std without them.

**Where.** Every strapdown path, one rule (:func:`judge_omitted`, :func:`runs_on`): a telemetry read from one file
(before the frame's test), a telemetry paired with tracking (its linear result once the remainder's test keeps it,
:func:`casep.workflows.telemetry_iterate.iterate_if_curved`) and an iterated separation's last pass (a pair's or a
raw IMU record's, :meth:`casep.workflows.imu_separate._Run.finish`: the richer model linearised about the pass's
correction as the pass's own, its pad alignment included). Not noise-free rows, a flight that failed a set-up check,
the windows of :mod:`casep.workflows.windows` (their comparison carries what they leave out), nor a result failed
already. A rank-deficient fit (``strapdown33`` on the boost: 12 of 33 exactly dependent) tests the combinations the
rows determine beside it and carries the terms in the std of the coefficients it states (the others have none); a
fit that states none says that only the determined part was tested.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from casep.estimators.result import EstimateResult
from casep.io.flight import FlightData

__all__ = ["omitted_record", "judge_omitted", "runs_on", "JUDGED_ELSEWHERE", "richer_model", "alias_line",
           "omitted_message", "OMITTED_NAMED", "OMITTED_RCOND", "OMITTED_WEIGHT"]

#: A combination of the extra columns is determined beside the fit where its singular value (the columns less their
#: projection on the whitened design, each per declared magnitude) is above this share of the largest: the rest are
#: the design's null space at rounding (strapdown33's 12 beyond rank 21 on the boost: 1e-16 of the largest; the
#: determined ones down to 1e-3).
OMITTED_RCOND = 1e-8
#: A flight's ``meta`` key naming the workflow that judges the terms its model leaves out itself (the windows of
#: :mod:`casep.workflows.windows`: their comparison carries them, ``separate_windows(consider=...)``): not tested here.
JUDGED_ELSEWHERE = "omitted_terms_judged_by"
#: The determined combinations named in a failure, at most (farthest from 0 in their std first) ...
OMITTED_NAMED = 3
#: ... each by its terms of at least this weight (a unit vector of the terms per declared magnitude).
OMITTED_WEIGHT = 0.3


def richer_model(model: str) -> str | None:
    """The richer shipped model of `model` (the first named in :data:`casep.model.loader.RICHER_MODELS`), or None."""
    from casep.model.loader import RICHER_MODELS

    said = RICHER_MODELS.get(str(model).split("+")[0])
    found = re.match(r"\s*([A-Za-z0-9_]+)", said) if said else None
    return found.group(1) if found else None


def _extra_columns(res: EstimateResult, problem: Any, flight: FlightData, richer: Any,
                   at_pass: Callable[[], Any] | None = None) -> tuple | None:
    """The richer model's columns (N, 3, k) at `problem`'s epochs that `res` lacks, their names, units and declared
    magnitudes; None where the richer model does not hold every term of the fit or the rows do not match. `at_pass`:
    the richer model as a pass of an iterated separation linearises it (its S_V that pass's derivative), else
    `richer` itself."""
    from casep.checks.flight import flight_problem
    from casep.model.loader import TIME_OFFSET

    own = [n for n in res.names if n != TIME_OFFSET]
    if not set(own) <= set(richer.names):
        return None
    extra = [j for j, n in enumerate(richer.names) if n not in res.names]
    if not extra:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the flight's S_V warnings (gaps, conditioning): the fit's, said with it
        rp = flight_problem(flight, richer if at_pass is None else at_pass(), keep_sv=True)
    t, tr = np.asarray(problem.t, float), np.asarray(rp.t, float)
    idx = np.searchsorted(tr, t)
    if np.any(idx >= tr.size) or not np.allclose(tr[np.minimum(idx, tr.size - 1)], t, rtol=0.0, atol=1e-9):
        return None
    names = [richer.names[j] for j in extra]
    units = [richer.units[j] for j in extra] if getattr(richer, "units", None) else [""] * len(extra)
    scale = np.array([richer.scales.get(n, 1.0) or 1.0 for n in names], dtype=float)
    return rp.sv()[idx][:, :, extra], names, units, scale


def _determined(res: EstimateResult, problem: Any, cols: np.ndarray) -> np.ndarray | None:
    """The combinations (k, c) of `cols` (N, 3, k, each per declared magnitude) the rows determine beside the fit's
    design: directions of the columns less their projection on the whitened design whose std is below 1."""
    from casep.noise.model import NoiseModel, whiten

    nd = res.diagnostics.get("noise")
    if problem.t is None or not isinstance(nd, dict) or "axes" not in nd or res.sigma is None:
        return None
    t = np.asarray(problem.t, dtype=float)
    S = problem.sv()
    N, _, n = S.shape
    k = cols.shape[2]
    both = whiten(np.concatenate([S, cols], axis=2), np.zeros((N, 3)), t, NoiseModel.from_dict(nd))[0]
    both = both.reshape(3 * N, n + k)
    U, E = both[:, :n], both[:, n:]
    u, s, _ = np.linalg.svd(U, full_matrices=False)
    Q = u[:, s > s[0] * max(U.shape) * np.finfo(float).eps] if s.size and s[0] > 0 else u[:, :0]
    left = E - Q @ (Q.T @ E)
    _, sv, vt = np.linalg.svd(left, full_matrices=False)
    # beyond the projection's rounding too (the columns' own scale): columns wholly in the design's span leave only
    # rounding, which OMITTED_RCOND of its own largest would take for combinations the rows determine
    rounding = max(both.shape) * np.finfo(float).eps * (np.linalg.norm(E, 2) if E.size else 0.0)
    return vt[sv > max(OMITTED_RCOND * sv[0], rounding)].T if sv.size and sv[0] > rounding else vt[:0].T


def omitted_record(res: EstimateResult, problem: Any, flight: FlightData, model: Any,
                   at_pass: Callable[[str], Any] | None = None) -> tuple[dict, np.ndarray] | None:
    """The test of the richer model's extra terms beside the fit (module notes): ``{"richer", "terms", "chi2", "dof",
    "p_value", "fail_p", "each", "alias", "rule"}`` (``each``: the determined combinations, farthest from 0 in their std
    first, each its terms ``(name, weight, declared magnitude, unit)`` (a unit vector of the terms over their declared
    magnitudes), estimate, std and z; ``alias``: how far the
    terms at their declared magnitudes move the fit's estimates, in the fit's std), and the extra columns per declared
    magnitude (N, 3, k: the consider columns); None without a richer shipped model or a noise model. `at_pass`: the
    richer model (by name) as the pass of an iterated separation that gave `problem` linearises it
    (:meth:`casep.workflows.imu_separate._Run.model`)."""
    from casep._special import chi2_sf
    from casep.estimators.joint import FAIL_P
    from casep.model.loader import load_model
    from casep.workflows.row_estimators import column_estimates

    name = richer_model(getattr(model, "name", res.model))
    if name is None:
        return None
    found = _extra_columns(res, problem, flight, load_model(name),
                           None if at_pass is None else (lambda: at_pass(name)))
    if found is None:
        return None
    cols, names, units, scale = found
    scaled = cols * scale
    V = _determined(res, problem, scaled)
    if V is None:
        return None
    record: dict[str, Any] = {"richer": name, "terms": names, "chi2": 0.0, "dof": int(V.shape[1]), "p_value": 1.0,
                              "fail_p": FAIL_P, "each": [], "alias": _alias(res, problem, scaled), "rule": RULE,
                              "coefficients": len(res.names)}
    if V.shape[1]:
        est = column_estimates(res, problem, flight, scaled @ V, covariance=True)
        if est is None:
            return None
        c, _, C = est
        record["chi2"] = chi2 = float(c @ np.linalg.solve(C, c))
        record["p_value"] = chi2_sf(record["dof"], chi2)
        sd = np.sqrt(np.maximum(np.diag(C), 0.0))
        combos = [{"terms": [(names[j], float(V[j, i]), float(scale[j]), units[j])
                             for j in np.argsort(-np.abs(V[:, i])) if abs(V[j, i]) >= OMITTED_WEIGHT],
                   "estimate": float(c[i]), "std": float(sd[i]), "z": float(abs(c[i]) / sd[i]) if sd[i] > 0 else 0.0}
                  for i in range(c.size)]
        record["each"] = sorted(combos, key=lambda r: -r["z"])
    return record, scaled


RULE = ("the richer model's extra columns less their projection on the fit's whitened design, the combinations left "
        "(above OMITTED_RCOND of the largest) estimated beside the fit (column_estimates, the fit's noise model); "
        "Wald chi2 c^T C^-1 c on as many dof, p below fail_p: the model lacks terms the data need. alias: the extra "
        "terms at their declared magnitudes as consider parameters through the fit's estimators (with_consider)")


def _alias(res: EstimateResult, problem: Any, scaled: np.ndarray) -> dict:
    """How far the extra terms at their declared magnitudes (`scaled`, their columns per magnitude) move the fit's
    estimates: the largest shift of any combination in the fit's std (``sqrt`` of the largest eigenvalue of ``G G^T``
    against the fit's covariance, ``G`` the fit's estimators times the columns) and of each coefficient."""
    from casep.workflows.row_estimators import coefficient_estimators

    a = coefficient_estimators(res, problem)
    P = None if res.covariance is None else np.asarray(res.covariance, float)
    if a is None or P is None:
        return {}
    # the coefficients the fit states (a finite std); a rank-deficient fit's others have none to carry the terms in
    keep = np.isfinite(np.diag(P)) & (np.nan_to_num(np.diag(P)) > 0)
    if not keep.any() or not np.all(np.isfinite(P[np.ix_(keep, keep)])):
        return {}
    names = [nm for nm, k in zip(res.names, keep) if k]
    a, P = a[keep], P[np.ix_(keep, keep)]
    g = a @ scaled.reshape(a.shape[1], -1)
    A = g @ g.T
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return {}
    Li = np.linalg.solve(L, A)
    lam = np.linalg.eigvalsh(np.linalg.solve(L, Li.T))
    with np.errstate(divide="ignore", invalid="ignore"):
        each = np.sqrt(np.diag(A)) / np.sqrt(np.diag(P))
    worst = int(np.nanargmax(each)) if np.any(np.isfinite(each)) else 0
    return {"combination_std": float(np.sqrt(max(lam[-1], 0.0))), "coefficient_std": float(np.nanmax(each)),
            "worst": names[worst], "stated": len(names)}


def omitted_message(record: dict) -> str:
    """What a failed result says of :func:`omitted_record`."""
    named = [r for r in record["each"] if r["z"] > 3.0][:OMITTED_NAMED] or record["each"][:1]
    terms = "; ".join(" ".join(f"{w:+.2g} {nm}/({s:g} {u})" for nm, w, s, u in r["terms"])
                      + f" = {r['estimate']:+.4g} +- {r['std']:.2g} (z {r['z']:.3g})" for r in named)
    return (f"the rows hold terms the model lacks: of {record['richer']}'s {len(record['terms'])} further terms, "
            f"the {record['dof']} combination(s) the flight determines beside the fit are {record['chi2']:.4g} from 0 "
            f"(Wald chi-square on {record['dof']} dof, p {record['p_value']:.3g}; fail below {record['fail_p']:g}); "
            f"the rows determine (each term over its declared magnitude): {terms}. The estimates take in what those "
            f"terms do and are off by more than their std say: fit {record['richer']} (or a model with these terms)")


def alias_line(record: dict) -> str:
    """The line of a result the test of :func:`omitted_record` passed: its std carry the richer model's terms as
    consider parameters (the coefficients it states with a std), or, where it states none, that only the
    combinations the rows determine beside the fit were tested."""
    al = record.get("alias") or {}
    tested = (f"the {record['dof']} combination(s) it determines beside the fit: chi-square {record['chi2']:.3g}, p "
              f"{record['p_value']:.3g}")
    if not al:
        return (f"of {record['richer']}'s {len(record['terms'])} terms this model leaves out, only the combinations "
                f"the rows determine beside the fit were tested ({tested}); the fit states no coefficient with a std, "
                f"so what its own columns take of them is not in any std: fit {record['richer']} for its combinations")
    part = "" if al.get("stated", 0) >= record.get("coefficients", 0) else \
        f" (in the std of the {al['stated']} of {record['coefficients']} coefficients the fit states)"
    return (f"{record['richer']}'s {len(record['terms'])} terms this model leaves out are in the std{part} as "
            f"consider parameters at their declared magnitudes: the fit cannot tell them from its own coefficients "
            f"({tested}) and at those sizes they move the best-determined combination by "
            f"{al['combination_std']:.3g} of its std without them (a coefficient by up to "
            f"{al['coefficient_std']:.3g}, {al['worst']}); fit {record['richer']} for its combinations instead")


def judge_omitted(res: EstimateResult, flight: Any, problem: Any, model: Any,
                  at_pass: Callable[[str], Any] | None = None) -> EstimateResult:
    """`res` failed (``STATUS_MISFIT``) when the richer shipped model's extra terms are beyond
    :data:`casep.estimators.joint.FAIL_P` beside the fit (:func:`omitted_record`, in ``diagnostics["omitted_terms"]``);
    else its covariance carrying them at their declared magnitudes as consider parameters
    (:func:`casep.workflows.row_estimators.with_consider`), said in a line (:func:`alias_line`). The one rule of every
    strapdown path: a telemetry file, a telemetry paired with tracking and a raw IMU record's pass
    (:func:`runs_on`; an iterated separation's last pass, `at_pass` its linearisation of the richer model:
    :meth:`casep.workflows.imu_separate._Run.finish`). Anything else, noise-free rows, a flight that failed a set-up
    check (:func:`casep.checks.plausibility.setup_problems`: the heading, the tracking's frame) or a result failed
    already: `res`."""
    from casep.checks.plausibility import setup_problems
    from casep.estimators.registry import STATUS_MISFIT, failed
    from casep.workflows.row_estimators import with_consider

    if not res.success or not runs_on(flight) or problem.y is None or problem.t is None or problem.is_noise_free():
        return res
    if setup_problems(flight):  # a set-up check failed (a heading, a frame): its failure names the cause, not terms
        return res
    try:
        found = omitted_record(res, problem, flight, model, at_pass)
    except (ValueError, np.linalg.LinAlgError):
        return res
    if found is None:
        return res
    record, scaled = found
    res = dataclasses.replace(res, diagnostics={**res.diagnostics, "omitted_terms": record})
    if record["p_value"] < record["fail_p"]:
        return failed(res, STATUS_MISFIT, f"failed: {flight.source}: {omitted_message(record)}")
    line = alias_line(record)
    out = with_consider(res, problem, scaled) if record["alias"] else res
    return dataclasses.replace(out, message=f"{out.message}; {line}")


def runs_on(flight: Any) -> bool:
    """Whether :func:`judge_omitted` tests `flight`: strapdown rows (``q_*``, ``fb_*``, ``w_*``), read from one file,
    a telemetry paired with tracking, or a raw IMU record navigated and paired (a pass of
    :mod:`casep.workflows.imu_separate`); not a flight whose workflow judges them itself (:data:`JUDGED_ELSEWHERE`)."""
    meta = flight.meta if isinstance(flight, FlightData) and isinstance(flight.meta, dict) else {}
    return isinstance(meta.get("strapdown"), dict) and not meta.get(JUDGED_ELSEWHERE)
