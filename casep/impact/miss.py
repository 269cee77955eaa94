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
    from casep.io.result_json import load_json

    source = "<memory>" if isinstance(result, (EstimateResult, dict)) else os.fspath(result)
    res, model = read_input_result(result, model, option="--result" if source != "<memory>" else "result")
    raw = result if isinstance(result, dict) else None if source == "<memory>" else load_json(result, "--result")
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
    for j, nm in enumerate(names):
        if nm in where:
            est[j] = res.estimate[where[nm]]
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
    C = np.asarray(res.covariance, dtype=float)
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
    d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
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
    D = np.where(have, coef.estimate, 0.0)
    contributions = np.where(have, G * D, np.nan)  # c_j = G_j D_j
    miss = np.nansum(contributions, axis=1)  # linear miss = sum of contributions
    cov = None
    if coef.covariance is not None:
        Ck = np.nan_to_num(coef.covariance[np.ix_(known, known)])
        Gk = G[:, known]
        cov = Gk @ Ck @ Gk.T  # G Cov G^T
        cov = 0.5 * (cov + cov.T)
    dx = B @ D  # (dr_b, dv_b)
    nonlinear = np.array(impact(r_b - dx[:3], v_b - dx[3:])) - nominal  # impact(x_b - dx_b) - impact(x_b)

    gidx, gsource = _groups(res, model.names, coef.covariance, known)
    groups = []
    for members in gidx:
        m = [j for j in members if have[j]]
        contrib = np.nansum(contributions[:, m], axis=1) if m else np.zeros(2)
        gstd = None
        if coef.covariance is not None:
            k = [j for j in members if known[j]]
            Gg = G[:, k]
            gstd = np.sqrt(np.clip(np.diag(Gg @ np.nan_to_num(coef.covariance[np.ix_(k, k)]) @ Gg.T), 0.0, None))
        groups.append(Group(tuple(model.names[j] for j in members), contrib, gstd))

    return ImpactAnalysis(
        names=model.names, units=model.units, coefficient_status=coef.status,
        estimate=np.where(have, coef.estimate, np.nan),
        t_b=t_b, r_b=r_b, v_b=v_b, nominal=nominal, impact_point=impact_point(r_b, v_b), jacobian=J, sp=sp, sv=sv,
        sensitivity=G, contributions=contributions, miss=miss, cov=cov, nonlinear=nonlinear, groups=tuple(groups),
        group_source=gsource, covariance_source=coef.covariance_source, model=model.name, method=res.method,
        flight=flight.source, trajectory=None if trajectory is None else target.source, result=rsource,
        reasons=coef.reasons,
        coefficient_std=None if coef.covariance is None else np.where(
            known, np.sqrt(np.clip(np.diag(np.nan_to_num(coef.covariance)), 0.0, None)),
            np.where(have, 0.0, np.nan)))
