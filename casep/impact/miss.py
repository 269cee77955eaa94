"""The impact miss that the instrument errors cause, and its budget per coefficient and per group.

``docs/reference/file-formats.md`` "Impact JSON". Burnout is the last sample of the flight; its state
``x_b = (r_b, v_b)`` is read from the flight's ``r_*``, ``v_*`` columns (tracked position and
velocity, launch-inertial frame). The navigation error at burnout that the coefficients ``D``
cause is::

    dv_b = S_V(t_b) D,        dr_b = S_P(t_b) D,        S_P(t) = int_{t_0}^{t} S_V dt

(``S_P`` by the cumulative trapezoid rule on the sample times, zero at the first sample).
Guidance flies the *navigated* state to the nominal one, so the true state is ``x_b - dx_b``
with ``dx_b = (dr_b, dv_b)``, and the instrument-error miss is::

    miss = impact(x_b - dx_b) - impact(x_b)             (downrange, crossrange; nonlinear)
         ~ -J dx_b = G D,   G = -J [S_P(t_b); S_V(t_b)]  (linear; J = d impact / d x_b, 2 x 6)

``G`` (2 x n) holds the miss sensitivities, metres per natural unit of each coefficient (the
columns of S_V are per natural unit, so ``D`` enters in natural units: no SI conversion is
needed or done). The contribution of coefficient j is ``G[:, j] D_j``; the predicted miss is
their sum and its covariance is ``G Cov G^T`` with ``Cov`` the result's covariance (natural
units). A coefficient the result has no estimate for (``null``) contributes nothing and is
listed as such; its sensitivity is still reported.

Results of several flights (``"flights"`` in the JSON) hold the shared coefficients only. A
per-flight coefficient of the model (``declare(..., per_flight=True)``: time offset, initial
velocity error, initial misalignment) is taken as **zero** for the flight analysed unless a
value is given (``per_flight={"dt_trk": 1.5}``, natural units, no uncertainty). For
``platform36_timeoffset`` that is the right value anyway: ``dt_trk`` is a tracking error, not a
navigation error.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from casep.impact.ballistic import impact, impact_jacobian, impact_point
from casep.impact.result import Group, ImpactAnalysis
from casep.io.flight import FlightData
from casep.io.trajectory import read_trajectory
from casep.model.sv import cumulative_sp  # S_P = int S_V dt (the tracking layer uses it too)
from casep.regression.linalg import covariance_std

__all__ = ["ImpactAnalysis", "impact_analysis", "burnout_state", "position_sensitivity", "cumulative_sp",
           "STATE_COLUMNS", "CORRELATION_GROUP"]

#: Flight columns that carry the burnout state (m, m/s; launch-inertial frame).
STATE_COLUMNS = ("r_x", "r_y", "r_z", "v_x", "v_y", "v_z")
#: |correlation| above which estimates are grouped when the result carries no near-dependency groups.
CORRELATION_GROUP = 0.9


# ----------------------------------------------------------------------------- inputs
def burnout_state(flight) -> tuple[float, np.ndarray, np.ndarray]:
    """Time, position and velocity of the flight's last sample (burnout), from ``r_*``, ``v_*``.

    Raises
    ------
    FlightDataError
        Naming the file and every missing state column, or the column and row of a value that
        is not finite.
    """
    from casep.io.flight import FlightDataError

    missing = [c for c in STATE_COLUMNS if c not in flight.signals]
    if missing:
        pair = isinstance(flight.meta, dict) and flight.meta.get("format") == "pair"
        how = (": give them in the telemetry file, or read Earth-fixed tracking, which carries the position "
               "(--tracking-frame ecef|geodetic --launch-site LAT LON H AZ --launch-time T0; API: read_flight_pair("
               "tracking_frame=..., site=LaunchSite(...)))" if pair else "")
        raise FlightDataError(flight.source, f"missing column{'s' if len(missing) > 1 else ''} "
                                             f"{', '.join(missing)}: the impact point needs the burnout state "
                                             "(r_x, r_y, r_z in m and v_x, v_y, v_z in m/s, launch-inertial "
                                             f"frame, last row = burnout){how}")
    x = np.array([flight.signals[c][-1] for c in STATE_COLUMNS], dtype=float)
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        c = STATE_COLUMNS[int(bad[0])]
        raise FlightDataError(flight.source, f"burnout value {x[bad[0]]:g} is not finite", c, flight.n_samples)
    return float(flight.t[-1]), x[:3], x[3:]


# ----------------------------------------------------------------------------- S_P
def position_sensitivity(model, flight, *, rows: int = 65536) -> tuple[np.ndarray, np.ndarray]:
    """``S_P(t_b)`` and ``S_V(t_b)`` at the flight's last sample, ``(3, n)`` each, per natural unit.

    S_V is integrated over every sample of the flight (:class:`casep.model.sv.SVBuilder`) block by
    block, and S_P accumulated alongside, so S_V is never held whole.

    Notes
    -----
    ``S_P(t_b) = sum_k (S_V[k-1] + S_V[k]) (t_k - t_{k-1}) / 2`` over all samples (trapezoid from
    the first sample, where S_P = 0); the step across two blocks uses the last row of the first.
    """
    from casep.model.sv import SVBuilder

    t = np.asarray(flight.t, dtype=float)
    signals = flight.model_signals(model.signals, model.name)
    n = model.n_coefficients
    sp = np.zeros((3, n))
    prev, t_prev = None, None
    for s, e, blk in SVBuilder(model).blocks(t, flight.f, rows, signals=signals):
        tb = t[s:e]
        if prev is not None:
            sp += 0.5 * (prev + blk[0]) * (tb[0] - t_prev)  # the step across the block boundary
        if e - s > 1:
            sp += 0.5 * np.einsum("k,kij->ij", np.diff(tb), blk[1:] + blk[:-1])  # trapezoid in the block
        prev, t_prev = blk[-1].copy(), tb[-1]
    if prev is None:
        raise ValueError(f"{flight.source}: the flight has no samples")
    return sp, prev


# ----------------------------------------------------------------------------- the result
@dataclass(frozen=True)
class _Coefficients:
    estimate: np.ndarray  # (n,) natural units, model order; NaN: no estimate
    covariance: np.ndarray | None  # (n, n) natural units; zero rows for per-flight values given
    status: tuple[str, ...]  # "estimated" | "no estimate" | "per-flight"
    reasons: dict[str, str]
    covariance_source: str


def _load_result(result, model=None):
    """``(result, its source, model, its provenance)``: :func:`casep.estimators.reading.read_input_result`
    (every result form, checked, usable as an input; the model shipped with casep that the result names,
    or `model`)."""
    from casep.estimators.reading import read_input_result
    from casep.estimators.result import EstimateResult

    source = "<memory>" if isinstance(result, (EstimateResult, dict)) else os.fspath(result)
    res, model = read_input_result(result, model, option="--result" if source != "<memory>" else "result")
    raw = result if isinstance(result, dict) else None
    if source != "<memory>":  # a file: its provenance (pydantic's parser imported only then)
        from casep.io.result_json import load_json

        raw = load_json(result, "--result")
    return res, source, model, (raw or {}).get("provenance")


def _coefficients(res, model, per_flight: Mapping[str, float] | None, source: str) -> _Coefficients:
    """The result's estimate and covariance in the model's order (see the module notes)."""
    names = model.names
    per_flight = dict(per_flight or {})
    pf = model.per_flight
    for k in per_flight:
        if k not in names:
            raise ValueError(f"per_flight: `{k}` is not a coefficient of model `{model.name}`")
        if not pf[names.index(k)]:
            raise ValueError(f"per_flight: `{k}` is not a per-flight coefficient of model `{model.name}` "
                             "(its value is the result's estimate)")
    tracking = set((res.diagnostics or {}).get("tracking_terms") or ())  # station errors: no part in the miss
    extra = [n for n in res.names if n not in names and n not in tracking]
    if extra:
        raise ValueError(f"result {source} has coefficients that model `{model.name}` lacks: {', '.join(extra[:5])}")
    n = len(names)
    est = np.full(n, np.nan)
    status = []
    where = {nm: i for i, nm in enumerate(res.names)}
    shown = res.presented()[0] if hasattr(res, "presented") else np.asarray(res.estimate, dtype=float)
    for j, nm in enumerate(names):
        if nm in where:
            est[j] = shown[where[nm]]  # none where the result presents none (withheld: as read from its JSON)
            status.append("estimated" if np.isfinite(est[j]) else "no estimate")
        elif pf[j]:
            v = float(per_flight.get(nm, 0.0))
            if not math.isfinite(v):
                raise ValueError(f"per_flight: `{nm}` must be finite, got {v!r}")
            est[j] = v
            status.append("per-flight")
        else:
            raise ValueError(f"result {source} has no coefficient `{nm}` of model `{model.name}`")
    idx = np.array([where.get(nm, -1) for nm in names])
    inres = idx >= 0
    if res.covariance is None:  # the std alone would ignore the coefficients' correlations: a wrong miss std
        raise ValueError(f"result {source} has no `covariance` (n x n, natural units, one row per coefficient): the "
                         "miss std is G Cov G^T and needs the coefficients' covariance, not only their std"
                         f"{' (the file has std only)' if res.std is not None else ''}; casep separate --json "
                         "writes it")
    C = np.array(res.covariance, dtype=float)
    hidden = np.isnan(shown) & np.isfinite(np.asarray(res.estimate, dtype=float))  # withheld: NaN rows, as its JSON
    C[hidden, :] = np.nan
    C[:, hidden] = np.nan
    cov = np.zeros((n, n))
    cov[np.ix_(inres, inres)] = C[np.ix_(idx[inres], idx[inres])]
    cov_source = f"the result's covariance ({res.std_kind})"
    return _Coefficients(est, cov, tuple(status), dict(res.reasons), cov_source)


def _groups(res, names: Sequence[str], cov: np.ndarray | None, known: np.ndarray) -> tuple[list[list[int]], str]:
    """Near-dependency groups as model indices, and where they came from."""
    diag = res.diagnostics or {}
    if "groups" in diag and diag["groups"] is not None:
        out = []
        for g in diag["groups"]:
            members = [names.index(x) for x in g if x in names]
            if len(members) >= 2:
                out.append(members)
        return out, "the result's near-dependency groups (Belsley-Kuh-Welsch: condition index > 30, proportion > 0.5)"
    if cov is None:
        return [], "none (the result has no groups and no covariance)"
    # Fallback: connected components of |rho_ij| > CORRELATION_GROUP among the estimated coefficients.
    d = covariance_std(cov)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = cov / np.outer(d, d)
    link = (np.abs(np.nan_to_num(rho)) > CORRELATION_GROUP) & np.outer(known, known)
    seen, out = set(), []
    for j in range(len(names)):
        if j in seen or not known[j]:
            continue
        comp, stack = [], [j]
        while stack:
            k = stack.pop()
            if k in seen:
                continue
            seen.add(k)
            comp.append(k)
            stack.extend(int(i) for i in np.flatnonzero(link[k]) if i not in seen)
        if len(comp) >= 2:
            out.append(sorted(comp))
    return out, f"estimates correlated with |rho| > {CORRELATION_GROUP:g} (the result has no near-dependency groups)"


@dataclass(frozen=True)
class _LinearMiss:
    miss: np.ndarray  # (2,) G D over the coefficients with a value; NaN where not determined
    cov: np.ndarray | None  # (2, 2) G Cov G^T
    determined: np.ndarray  # (2,) bool
    D: np.ndarray  # (n,) the coefficient vector used (model order)
    groups: list[tuple[np.ndarray, np.ndarray | None]]  # per group: contribution, std
    note: str


def _linear_miss(res, names: Sequence[str], coef: _Coefficients, G: np.ndarray,
                 gidx: list[list[int]]) -> _LinearMiss:
    """The linear miss ``G D``, its covariance ``G Cov G^T`` and each group's share.

    A result whose coefficients all have a value: the sum over them. A result with coefficients the data
    determine only in combination (its :class:`~casep.estimators.solution.Solution`): ``G x`` with the
    solver's solution ``x`` where ``G``'s row is a determined combination (in the row space of S_V: the
    same value and an honest std in every least-squares solution); not determined (NaN) otherwise, said
    in ``note`` with the part of the miss the data cannot see.
    """
    have = np.isfinite(coef.estimate)
    known = np.array([s == "estimated" for s in coef.status])
    D = np.where(have, coef.estimate, 0.0)
    sol = getattr(res, "solution", None)
    if sol is None:  # every coefficient of the result has a value, or a file that has no solution
        miss = np.sum(G * D, axis=1)
        C = None if coef.covariance is None else np.nan_to_num(coef.covariance) * np.outer(known, known)
        undet = ~have & np.any(G != 0.0, axis=0)
        ok = np.full(2, not undet.any())
        note = "" if ok.all() else (
            "the result has no estimate of " + ", ".join(n for n, u in zip(names, undet) if u) + " and no "
            "solution to say which combination of them the data determine: the miss is not determined")
        sel = [np.eye(len(names))[m].sum(axis=0) for m in gidx]
        cov = None if C is None else G @ C @ G.T
        grp = [(np.sum(G[:, m] * D[m], axis=1),
                None if C is None else covariance_std((G * s) @ C @ (G * s).T))
               for m, s in zip(gidx, sel)]
        return _LinearMiss(np.where(ok, miss, np.nan), cov, ok, D, grp, note)
    # map the result's solution onto the model's coefficients (tracking terms of a radar fit: no miss)
    where = {nm: i for i, nm in enumerate(res.names)}
    idx = np.array([where.get(nm, -1) for nm in names])
    inres = idx >= 0
    P = np.zeros((len(res.names), len(names)))  # result order -> model order
    P[idx[inres], np.flatnonzero(inres)] = 1.0
    D = np.where(inres, P.T @ sol.x, D)  # the solution where the result has the coefficient, else per-flight
    fixed = np.where(inres, 0.0, D)  # per-flight values given (no uncertainty)

    def comb(Gm: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        v, c, ok = sol.combination(Gm @ P.T)
        return v + Gm @ fixed, c, ok

    miss, cov, ok = comb(G)
    grp = []
    for m in gidx:
        Gg = np.zeros_like(G)
        Gg[:, m] = G[:, m]
        v, c, _ = comb(Gg)
        grp.append((v, None if c is None else covariance_std(c)))
    note = ""
    if not ok.all():
        N = P.T @ sol.null_space  # null directions in model order
        lost = np.abs(G @ N).max(axis=1)  # miss per unit step along a null direction
        dep = [names[int(j)] for j in np.flatnonzero(np.any(np.abs(N) > 1e-12 * np.abs(N).max(), axis=1))]
        axes = " and ".join(a for a, k in zip(("downrange", "crossrange"), ok) if not k)
        note = (f"the {axes} miss is not determined by this flight: its sensitivity has a part along the "
                f"combinations of {', '.join(dep)} that the data cannot see (up to "
                f"{', '.join(f'{v:.3g}' for v in lost)} m per unit of a null direction, downrange, crossrange); "
                f"the solver's minimum-norm solution gives {', '.join(f'{v:.4g}' for v in G @ D)} m, one value "
                "among many. Fix the dependency (a model without the dependent terms, a prior) or fly a trajectory "
                "that separates them")
    return _LinearMiss(miss, cov, ok, D, grp, note)


def impact_analysis(flight, result, model=None, trajectory=None, *,
                    per_flight: Mapping[str, float] | None = None,
                    burnout_sensitivity: tuple[np.ndarray, np.ndarray] | None = None) -> ImpactAnalysis:
    """Miss sensitivities, predicted miss with covariance, contributions and nonlinear miss.

    Parameters
    ----------
    flight : FlightData or path
        The flight the result was estimated on (``t``, ``f_*``, ``r_*``, ``v_*``).
    result : EstimateResult, dict or path
        An estimate: a ``casep separate --json`` file (one flight, or several with ``"flights"``), or a
        result file of another tool in a form of ``docs/guide/result-files.md``; its units must be the
        model's.
    model : ErrorModel or str, optional
        Default: the model shipped with casep that the result names; a result of any other model needs
        it here (a result file never runs code: the ValueError says which file to give), and its file
        must have the SHA-256 the result records. A model of another name is refused (message names both).
    trajectory : FlightData or path, optional
        Another trajectory (``t``, ``f_*``, ``r_*``, ``v_*``; dv not needed): the result's
        estimate and covariance are applied to *its* S_V and burnout state (the miss of a flight
        not flown). Default: `flight`.
    per_flight : mapping, optional
        Values (natural units) of per-flight coefficients that the result does not hold
        (several-flight results); default 0.
    burnout_sensitivity : (S_P(t_b), S_V(t_b)), optional
        The target's ``(3, n)`` burnout sensitivities when already at hand (e.g. from a Problem
        that keeps S_V: ``np.trapezoid(S, t, axis=0)``, ``S[-1]``); default: integrated here by
        :func:`position_sensitivity`.

    Returns
    -------
    ImpactAnalysis

    Raises
    ------
    ValueError
        A result that may not be an input (failed: :func:`casep.estimators.reading.check_usable`), one
        without a covariance, one whose provenance records other data files than `flight`'s
        (:func:`casep.io.provenance.check_estimated_on`), or one of a model not named (see `model`).

    Notes
    -----
    See the module notes. ``x_b = (r_b, v_b)`` at the last sample; ``B = [S_P(t_b); S_V(t_b)]``
    (6 x n); ``J = d impact / d x_b`` (2 x 6, exact); ``G = -J B``; contributions
    ``c_j = G_j D_j``; ``miss = sum_j c_j`` over the coefficients with a value;
    ``cov = G_k Cov_kk G_k^T`` over the estimated ones; ``nonlinear = impact(x_b - B D) - impact(x_b)``.
    """
    from casep.io.provenance import check_estimated_on

    res, rsource, model, record = _load_result(result, model)
    if not isinstance(flight, FlightData):
        flight = read_trajectory(flight)  # dv is not used here (a radar-tracked flight's telemetry has none)
    check_estimated_on(record, flight, f"--result {rsource}" if rsource != "<memory>" else "the result")
    target = flight
    if trajectory is not None:
        target = trajectory if isinstance(trajectory, FlightData) else read_trajectory(trajectory)

    coef = _coefficients(res, model, per_flight, rsource)
    t_b, r_b, v_b = burnout_state(target)
    nominal = np.array(impact(r_b, v_b))  # impact(x_b)
    J = impact_jacobian(r_b, v_b)  # d impact / d x_b, 2 x 6
    if burnout_sensitivity is None:
        sp, sv = position_sensitivity(model, target)  # S_P(t_b), S_V(t_b): 3 x n
    else:
        sp, sv = (np.asarray(a, dtype=float) for a in burnout_sensitivity)
        if sp.shape != (3, model.n_coefficients) or sv.shape != (3, model.n_coefficients):
            raise ValueError(f"`burnout_sensitivity` must be two (3, {model.n_coefficients}) arrays")
    B = np.vstack([sp, sv])  # dx_b = B D
    G = -J @ B  # miss per natural unit: miss ~ -J dx_b
    have = np.isfinite(coef.estimate)  # estimated, or per-flight value
    known = np.array([s == "estimated" for s in coef.status])
    contributions = np.where(have, G * np.where(have, coef.estimate, 0.0), np.nan)  # c_j = G_j D_j
    gidx, gsource = _groups(res, model.names, coef.covariance, known)
    lin = _linear_miss(res, model.names, coef, G, gidx)
    dx = B @ lin.D  # (dr_b, dv_b)
    nonlinear = np.array(impact(r_b - dx[:3], v_b - dx[3:])) - nominal  # impact(x_b - dx_b) - impact(x_b)
    nonlinear = np.where(lin.determined, nonlinear, np.nan)  # of one solution among many: not said
    groups = tuple(Group(tuple(model.names[j] for j in members), c, sd)
                   for members, (c, sd) in zip(gidx, lin.groups))

    return ImpactAnalysis(
        names=model.names, units=model.units, coefficient_status=coef.status,
        estimate=np.where(have, coef.estimate, np.nan),
        t_b=t_b, r_b=r_b, v_b=v_b, nominal=nominal, impact_point=impact_point(r_b, v_b), jacobian=J, sp=sp, sv=sv,
        sensitivity=G, contributions=contributions, miss=lin.miss, cov=lin.cov, nonlinear=nonlinear, groups=groups,
        group_source=gsource, covariance_source=coef.covariance_source, model=model.name, method=res.method,
        flight=flight.source, trajectory=None if trajectory is None else target.source, result=rsource,
        reasons=coef.reasons, determined=lin.determined, undetermined_note=lin.note,
        coefficient_std=None if coef.covariance is None else np.where(
            known, covariance_std(np.nan_to_num(coef.covariance)),
            np.where(have, 0.0, np.nan)))
