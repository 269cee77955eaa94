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
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from casep.impact.ballistic import impact, impact_jacobian, impact_point
from casep.model.sv import cumulative_sp  # S_P = int S_V dt (the tracking layer uses it too)

__all__ = ["ImpactAnalysis", "impact_analysis", "burnout_state", "position_sensitivity", "cumulative_sp",
           "read_trajectory", "STATE_COLUMNS", "CORRELATION_GROUP"]

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


def read_trajectory(path: str | os.PathLike):
    """A flight file for the impact analysis: ``t``, ``f_*`` (or ``W_*``), ``r_*``, ``v_*``.

    ``dv_*`` (or ``v_tel_*``/``v_trk_*``) may be absent: a trajectory that was not flown has
    none, a radar-tracked flight's telemetry has ``v_tel_*`` only, and the impact analysis does not
    use them (dv is then stored as zeros and
    ``meta["dv"]`` says ``"absent"``).
    """
    from casep.io.files import DV_COLUMNS, VTEL_COLUMNS, _force, _is_parquet, _Table, read_flight
    from casep.io.flight import FlightData

    tab = _Table(path)
    if tab.has(DV_COLUMNS) or (any(c in tab.columns for c in VTEL_COLUMNS) and "v_trk_x" in tab.columns):
        del tab
        return read_flight(path)
    tab.require(("t",))
    t = tab.time()
    f, force_from = _force(tab, t)
    return FlightData(t, f, np.zeros((t.size, 3)), source=tab.src, signals=tab.signals(),
                      meta={"format": "parquet" if _is_parquet(tab.path) else "csv", "force": force_from,
                            "dv": "absent"})


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
    """``(result, its source, model)``: :func:`casep.estimators.result.read_result` (every result form,
    checked; the model the result names, or `model`)."""
    from casep.estimators.result import EstimateResult, read_result

    source = "<memory>" if isinstance(result, (EstimateResult, dict)) else os.fspath(result)
    res, model = read_result(result, model, option="--result" if source != "<memory>" else "result")
    return res, source, model


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
    cov = None
    cov_source = "none: the result has neither covariance nor std"
    if res.covariance is not None:
        C = np.asarray(res.covariance, dtype=float)
        cov = np.zeros((n, n))
        cov[np.ix_(inres, inres)] = C[np.ix_(idx[inres], idx[inres])]
        cov_source = f"the result's covariance ({res.std_kind})"
    elif res.std is not None:
        cov = np.zeros((n, n))
        cov[inres, inres] = np.asarray(res.std, dtype=float)[idx[inres]] ** 2
        cov_source = f"the result's std, no covariance: correlations ignored ({res.std_kind})"
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


# ----------------------------------------------------------------------------- the analysis
def _f(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


@dataclass(frozen=True)
class Group:
    """A near-dependency group's share of the miss: members, contribution and its std, m."""

    names: tuple[str, ...]
    contribution: np.ndarray  # (2,) downrange, crossrange; over the members with an estimate
    std: np.ndarray | None  # (2,) from the members' covariance block

    def to_dict(self) -> dict[str, Any]:
        return {"names": list(self.names), "downrange": _f(self.contribution[0]),
                "crossrange": _f(self.contribution[1]),
                "std_downrange": None if self.std is None else _f(self.std[0]),
                "std_crossrange": None if self.std is None else _f(self.std[1])}


@dataclass(frozen=True)
class ImpactAnalysis:
    """The miss budget of an estimate on one trajectory (``docs/reference/file-formats.md`` "Impact JSON").

    Attributes
    ----------
    names, units, status : tuple of str
        Coefficients (model order), natural units, and ``"estimated"``, ``"no estimate"`` or
        ``"per-flight"`` (a per-flight coefficient absent from a several-flight result: its
        value given or 0).
    estimate : (n,) ndarray
        Coefficients used, natural units (NaN: no estimate, contributes nothing).
    t_b, r_b, v_b
        Burnout time (s), position (m) and velocity (m/s), launch-inertial frame.
    nominal : (2,) ndarray
        Impact of the burnout state: downrange, crossrange, m.
    jacobian : (2, 6) ndarray
        ``d(downrange, crossrange) / d(r_b, v_b)`` (exact, CasADi).
    sp, sv : (3, n) ndarray
        ``S_P(t_b)`` (m per unit) and ``S_V(t_b)`` (m/s per unit).
    sensitivity : (2, n) ndarray
        Miss per natural unit of each coefficient, m: ``G = -J [S_P; S_V]``.
    contributions : (2, n) ndarray
        ``G_j D_j``, m; NaN where there is no estimate.
    miss : (2,) ndarray
        Linear predicted miss, the sum of the contributions, m.
    cov : (2, 2) ndarray or None
        ``G Cov G^T`` over the estimated coefficients, m^2.
    nonlinear : (2,) ndarray
        ``impact(x_b - dx_b) - impact(x_b)``, m.
    groups : tuple of Group
        Contributions per near-dependency group (a coefficient may be in several groups).
    coefficient_std : (n,) ndarray or None
        Std of each coefficient used (natural units; NaN without estimate, 0 for a per-flight value).
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    status: tuple[str, ...]
    estimate: np.ndarray
    t_b: float
    r_b: np.ndarray
    v_b: np.ndarray
    nominal: np.ndarray
    impact_point: np.ndarray
    jacobian: np.ndarray
    sp: np.ndarray
    sv: np.ndarray
    sensitivity: np.ndarray
    contributions: np.ndarray
    miss: np.ndarray
    cov: np.ndarray | None
    nonlinear: np.ndarray
    groups: tuple[Group, ...]
    group_source: str
    covariance_source: str
    model: str
    method: str
    flight: str
    coefficient_std: np.ndarray | None = None
    trajectory: str | None = None
    result: str = "<memory>"
    reasons: dict = field(default_factory=dict)

    @property
    def std(self) -> np.ndarray | None:
        """Std of the predicted miss (downrange, crossrange), m."""
        return None if self.cov is None else np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def dx_b(self) -> np.ndarray:
        """Navigation error at burnout ``(dr_b, dv_b)`` of the coefficients with a value, (6,)."""
        D = np.nan_to_num(self.estimate, nan=0.0)
        return np.concatenate([self.sp @ D, self.sv @ D])

    def to_json(self) -> dict[str, Any]:
        """The impact JSON of ``docs/reference/file-formats.md`` (plus labels, the Jacobian, groups and sources)."""
        std = self.std
        sens = [{"name": n, "unit": u, "dr": [_f(x) for x in self.sp[:, j]], "dv": [_f(x) for x in self.sv[:, j]],
                 "downrange": _f(self.sensitivity[0, j]), "crossrange": _f(self.sensitivity[1, j])}
                for j, (n, u) in enumerate(zip(self.names, self.units))]
        contrib = []
        for j, n in enumerate(self.names):
            row: dict[str, Any] = {"name": n, "downrange": _f(self.contributions[0, j]),
                                   "crossrange": _f(self.contributions[1, j]), "estimate": _f(self.estimate[j]),
                                   "status": self.status[j]}
            if self.status[j] == "no estimate":
                row["note"] = "no estimate: contributes nothing" + (
                    f" ({self.reasons[n]})" if n in self.reasons else "")
            elif self.status[j] == "per-flight":
                row["note"] = "per-flight coefficient not in the result: value given, or 0"
            contrib.append(row)
        return {
            "model": self.model, "method": self.method, "flight": self.flight, "trajectory": self.trajectory,
            "result": self.result,
            "burnout": {"t": _f(self.t_b), "r": [_f(x) for x in self.r_b], "v": [_f(x) for x in self.v_b]},
            "nominal_impact": {"downrange": _f(self.nominal[0]), "crossrange": _f(self.nominal[1]),
                               "point": [_f(x) for x in self.impact_point]},
            "jacobian": [[_f(x) for x in row] for row in self.jacobian],
            "sensitivity": sens,
            "miss": {"downrange": _f(self.miss[0]), "crossrange": _f(self.miss[1]),
                     "std_downrange": None if std is None else _f(std[0]),
                     "std_crossrange": None if std is None else _f(std[1]),
                     "cov": None if self.cov is None else [[_f(x) for x in row] for row in self.cov],
                     "nonlinear": {"downrange": _f(self.nonlinear[0]), "crossrange": _f(self.nonlinear[1])},
                     "covariance_source": self.covariance_source},
            "contributions": contrib,
            "no_estimate": [n for n, s in zip(self.names, self.status) if s == "no estimate"],
            "groups": [g.to_dict() for g in self.groups],
            "group_source": self.group_source,
        }

    def table(self, top: int | None = None) -> str:
        """Terminal text: burnout, nominal impact, miss with std, budget per coefficient and per group.

        `top`: only the `top` (>= 1) largest contributions (by ``|downrange| + |crossrange|``); default all.
        """
        from casep.estimators.result import format_number

        if top is not None and (isinstance(top, bool) or not isinstance(top, (int, np.integer)) or top < 1):
            raise ValueError(f"`top` must be an integer >= 1 (or None for all), got {top!r}")

        std = self.std
        lines = [f"impact of {self.trajectory or self.flight}: model {self.model}, result of method {self.method}"
                 + (f" (estimated on {self.flight})" if self.trajectory else ""),
                 f"burnout t {self.t_b:.3f} s, r [{', '.join(f'{x:.1f}' for x in self.r_b)}] m, "
                 f"v [{', '.join(f'{x:.2f}' for x in self.v_b)}] m/s",
                 f"nominal impact: downrange {self.nominal[0]:.1f} m, crossrange {self.nominal[1]:.1f} m", ""]
        pm = (lambda i: f" +- {std[i]:.4g}") if std is not None else (lambda i: "")
        lines.append(f"predicted miss (linear): downrange {self.miss[0]:.4g}{pm(0)} m, "
                     f"crossrange {self.miss[1]:.4g}{pm(1)} m")
        lines.append(f"nonlinear miss (perturbed burnout state flown): downrange {self.nonlinear[0]:.4g} m, "
                     f"crossrange {self.nonlinear[1]:.4g} m")
        lines.append(f"std from {self.covariance_source}")
        lines.append("")
        lines.append(f"{'coefficient':<12} {'unit':<10} {'estimate':>12} {'m/unit down':>12} {'m/unit cross':>12} "
                     f"{'miss down m':>12} {'miss cross m':>12}")
        order = np.argsort(-np.nan_to_num(np.abs(self.contributions).sum(axis=0), nan=-1.0), kind="stable")
        if top is not None:
            order = order[:top]
        for j in order:
            note = "  no estimate" if self.status[j] == "no estimate" else (
                "  per-flight" if self.status[j] == "per-flight" else "")
            lines.append(f"{self.names[j]:<12} {self.units[j]:<10} {format_number(_f(self.estimate[j]))} "
                         f"{format_number(self.sensitivity[0, j])} {format_number(self.sensitivity[1, j])} "
                         f"{format_number(_f(self.contributions[0, j]))} {format_number(_f(self.contributions[1, j]))}"
                         f"{note}")
        if self.groups:
            lines.append("")
            lines.append(f"per near-dependency group ({self.group_source}):")
            for g in self.groups:
                s = "" if g.std is None else f" (std {g.std[0]:.4g}, {g.std[1]:.4g})"
                lines.append(f"  down {g.contribution[0]:.4g} m, cross {g.contribution[1]:.4g} m{s}: "
                             + ", ".join(g.names))
        missing = [n for n, s in zip(self.names, self.status) if s == "no estimate"]
        if missing:
            lines.append("")
            lines.append(f"no estimate (contribute nothing to the miss): {', '.join(missing)}")
        return "\n".join(lines)


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
        Default: the result's model, found by its name (built-in or ``CASEP_MODEL_PATH``) or by the
        ``model_file`` the result records (a model loaded from a path); when neither finds it, the
        ValueError says to pass the model file. A model of another name is refused (message names both).
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

    Notes
    -----
    See the module notes. ``x_b = (r_b, v_b)`` at the last sample; ``B = [S_P(t_b); S_V(t_b)]``
    (6 x n); ``J = d impact / d x_b`` (2 x 6, exact); ``G = -J B``; contributions
    ``c_j = G_j D_j``; ``miss = sum_j c_j`` over the coefficients with a value;
    ``cov = G_k Cov_kk G_k^T`` over the estimated ones; ``nonlinear = impact(x_b - B D) - impact(x_b)``.
    """
    res, rsource, model = _load_result(result, model)
    if not isinstance(flight, _flight_type()):
        flight = read_trajectory(flight)  # dv is not used here (a radar-tracked flight's telemetry has none)
    target = flight
    if trajectory is not None:
        target = trajectory if isinstance(trajectory, _flight_type()) else read_trajectory(trajectory)

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
        names=model.names, units=model.units, status=coef.status, estimate=np.where(have, coef.estimate, np.nan),
        t_b=t_b, r_b=r_b, v_b=v_b, nominal=nominal, impact_point=impact_point(r_b, v_b), jacobian=J, sp=sp, sv=sv,
        sensitivity=G, contributions=contributions, miss=miss, cov=cov, nonlinear=nonlinear, groups=tuple(groups),
        group_source=gsource, covariance_source=coef.covariance_source, model=model.name, method=res.method,
        flight=flight.source, trajectory=None if trajectory is None else target.source, result=rsource,
        reasons=coef.reasons,
        coefficient_std=None if coef.covariance is None else np.where(
            known, np.sqrt(np.clip(np.diag(np.nan_to_num(coef.covariance)), 0.0, None)),
            np.where(have, 0.0, np.nan)))


def _flight_type():
    from casep.io.flight import FlightData

    return FlightData
