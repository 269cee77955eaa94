"""REML of the tracking noise beside a known noise term in state-space form (the IMU's own noise).

Model
-----
At the epochs ``t_r`` (r = 0 .. M-1) the rows' noise (3 axes) is the tracking noise of
:mod:`casep.noise.model` plus a known term that a linear state ``z`` (s states) carries::

    e_r = H_r z_r + g_r + v_r,
    z_r = T_r z_(r-1) + w_r,   w_r ~ N(0, Q_r),   z_(-1) ~ N(0, P_0)          (the known term)
    g_(a,r) = a_(a,r) g_(a,r-1) + n,   Var n = c_a (1 - a_(a,r)^2),   a_(a,r) = exp(-(t_r - t_(r-1)) / tau_a)
    Var v_(a,r) = d_a

per axis ``a`` (``g`` Gauss-Markov of stationary variance ``c_a`` and correlation time ``tau_a``, absent on a
white axis; ``v`` white of variance ``d_a``, absent on a Gauss-Markov axis). ``T_r``, ``Q_r``, ``H_r``, ``P_0``
are known (:class:`KnownStates`); the tracking parameters ``theta = (c_a, d_a, tau_a)`` are not. The
covariance of the rows is ``Sigma(theta) = Sigma_track(theta) + Sigma_known``, never formed.

Whitening and likelihood
------------------------
The Kalman filter of ``x = (z, g)`` (s + 3 states) whitens the rows exactly: with ``Hx_r = [H_r  I_3]``,
``Phi_r = blockdiag(T_r, diag a_r)``, ``Qx_r = blockdiag(Q_r, diag c (1 - a_r^2))``, ``R = diag d``::

    P_r^- = Phi_r P_(r-1) Phi_r^T + Qx_r,   F_r = Hx_r P_r^- Hx_r^T + R = L_r L_r^T,
    u_r = L_r^-1 (e_r - Hx_r m_r^-),         K_r = P_r^- Hx_r^T F_r^-1,
    m_r = m_r^- + K_r (e_r - Hx_r m_r^-),    P_r = P_r^- - K_r F_r K_r^T,      m_r^- = Phi_r m_(r-1)

(first epoch: ``a = 0``, ``P^-`` of ``z`` is ``T_0 P_0 T_0^T + Q_0``), ``ln det Sigma = sum_r ln det F_r``. The
gains depend on the times and the parameters only, so one pass whitens every column of ``[Z dv]``
(``Z = S B`` the estimable basis of :func:`casep.noise.fit.estimable_basis`, orthonormal columns). The
restricted likelihood, without the constant ``(3M - p) ln 2 pi``::

    -2 l_R(theta) = ln det Sigma + ln det(Z_w^T Z_w) + RSS_w,    RSS_w = min_beta ||y_w - Z_w beta||^2

(``Z^T Z = I``, so no ``- ln det(Z^T Z)``), which :func:`restricted_likelihood` evaluates in O(M (s + 3)^2 p);
:func:`fit_tracking` maximises it over ``theta`` (Nelder-Mead in the logarithms) from a fitted
:class:`~casep.noise.model.NoiseModel`, whose kinds per axis it keeps. ``sigma^2`` cannot be profiled out: the
known term has its own scale.

The estimate's covariance under ``Sigma_track`` needs ``Sigma_track V`` (:func:`tracking_covariance_times`):
per axis ``sum_j c exp(-|t_i - t_j| / tau) v_j + d v_i``, a forward and a backward AR(1) recursion::

    f_i = v_i + a_i f_(i-1),   b_i = v_i + a_(i+1) b_(i+1),   (Sigma_track v)_i = c (f_i + b_i - v_i) + d v_i
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casep._kernels import ar1_terms, joint_filter
from casep.noise.model import AXES, NoiseModel

__all__ = ["KnownStates", "TrackingParameters", "joint_whiten", "restricted_likelihood", "fit_tracking",
           "tracking_covariance_times", "PART_RANGE", "RemlRows", "PooledParts", "pool_parts", "POOL_LEVEL",
           "level_interval", "stated_tau_check"]

#: How far (natural logarithm, down and up) :func:`fit_tracking` moves a part's variance from its start: e^-25 is
#: 1e-11 of the start (a part that small adds nothing a record tells from none: it is then 0), e^20 4.9e8 of it.
PART_RANGE = (25.0, 20.0)
#: The grid per part (over that range, steps of 3.2: a factor 5 in std) whose best point starts the simplex.
PART_GRID = 15


@dataclass(frozen=True)
class KnownStates:
    """A known noise term of the rows as a linear state (module notes): per epoch r the transition ``T`` (M, s, s)
    from the epoch before (r = 0: from the prior), the noise ``Q`` (M, s, s) added with it, the rows' map ``H``
    (M, 3, s); the prior ``P0`` (s, s)."""

    T: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    P0: np.ndarray
    #: Terms of unknown size: ``(Q_k (M, s, s), P0_k (s, s))`` per unit of their variance ``q_k``, which
    #: :meth:`scaled` adds (the IMU's bias instability: :func:`casep.checks.tracking_quality.imu_noise_states`).
    parts: tuple = ()

    def scaled(self, q) -> "KnownStates":
        """The known term with its `parts` at the variances `q` (one per part): ``Q + sum q_k Q_k``, ``P0 + sum q_k
        P0_k`` (the transitions do not depend on them, so the covariance is ``Sigma + sum q_k Sigma_k``, exactly)."""
        if len(q) != len(self.parts):
            raise ValueError(f"{len(self.parts)} parts, {len(q)} variances given")
        Q, P0 = self.Q.copy(), self.P0.copy()
        for q_k, (Q_k, P0_k) in zip(q, self.parts):
            Q += q_k * Q_k
            P0 += q_k * P0_k
        return KnownStates(self.T, Q, self.H, P0)

    def dense(self) -> np.ndarray:
        """``Sigma_known`` (3M, 3M), rows epoch by epoch, x y z: for tests on small cases only."""
        M = self.T.shape[0]
        P = self.P0.copy()
        covs = []
        for r in range(M):  # Cov(z_r) = T_r Cov(z_(r-1)) T_r^T + Q_r
            P = self.T[r] @ P @ self.T[r].T + self.Q[r]
            covs.append(P)
        out = np.zeros((3 * M, 3 * M))
        for r in range(M):
            C = covs[r]  # Cov(z_q, z_r) for q >= r: T_q..T_(r+1) Cov(z_r)
            for q in range(r, M):
                if q > r:
                    C = self.T[q] @ C
                out[3 * q:3 * q + 3, 3 * r:3 * r + 3] = self.H[q] @ C @ self.H[r].T
                out[3 * r:3 * r + 3, 3 * q:3 * q + 3] = out[3 * q:3 * q + 3, 3 * r:3 * r + 3].T
        return out


@dataclass(frozen=True)
class TrackingParameters:
    """``theta`` of the module notes, absolute: per axis the Gauss-Markov variance ``c`` (m^2/s^2; 0 on a white
    axis), its correlation time ``tau`` (s; None on a white axis) and the white variance ``d`` (m^2/s^2)."""

    c: tuple
    tau: tuple
    d: tuple

    @classmethod
    def of(cls, noise: NoiseModel) -> "TrackingParameters":
        """The parameters of a fitted noise model (its ``sigma`` is the x axis' std)."""
        if noise.sigma is None or not np.isfinite(noise.sigma):
            raise ValueError("the noise model has no fitted sigma")
        var = [(noise.sigma * noise.scale[j]) ** 2 for j in range(3)]
        c = tuple(0.0 if noise.tau[j] is None else var[j] * (1.0 - noise.share[j]) for j in range(3))
        d = tuple(var[j] if noise.tau[j] is None else var[j] * noise.share[j] for j in range(3))
        return cls(c, tuple(noise.tau), d)

    def model(self, kind: str, rule: str, **extra) -> NoiseModel:
        """The :class:`NoiseModel` of these parameters (``sigma`` the x axis' std, scales relative to it).

        An axis whose Gauss-Markov variance is below the rounding of its white one (the white share rounds to 1:
        the search drove ``c`` to nothing) is white: its correlation time is dropped."""
        var = np.array(self.c) + np.array(self.d)
        sd = np.sqrt(var)
        share = [0.0 if self.tau[j] is None else float(self.d[j] / var[j]) for j in range(3)]
        tau = list(self.tau)
        for j in range(3):
            if share[j] >= 1.0:
                tau[j], share[j] = None, 0.0
        return NoiseModel(kind=kind, tau=tuple(tau), scale=tuple(float(v) for v in sd / sd[0]), rule=rule,
                          sigma=float(sd[0]), share=tuple(share), extra=dict(extra))


def joint_whiten(X: np.ndarray, t: np.ndarray, theta: TrackingParameters, known: KnownStates
                 ) -> tuple[np.ndarray, float]:
    """The rows ``X`` (M, 3, k) whitened by the filter of the module notes (:func:`casep._kernels.joint_filter`):
    ``(U (3M, k), ln det Sigma)``; ``ln det`` inf where a variance is not positive."""
    M, _, k = X.shape
    dt = np.empty(M)
    dt[0] = np.inf
    np.subtract(t[1:], t[:-1], out=dt[1:])
    a, qb = np.zeros((M, 3)), np.zeros((M, 3))
    for j in range(3):
        if theta.tau[j] is not None:
            a[:, j], qb[:, j] = ar1_terms(dt, theta.tau[j])
            qb[:, j] *= theta.c[j]  # c (1 - a^2)
    U = np.empty((3 * M, k))
    logdet = joint_filter(np.ascontiguousarray(X, dtype=float), known.T, known.Q, known.H, known.P0, a, qb,
                          np.asarray(theta.d, dtype=float), U)
    return U, logdet


def restricted_likelihood(X: np.ndarray, t: np.ndarray, theta: TrackingParameters, known: KnownStates) -> float:
    """``-2 l_R(theta)`` of the rows ``X = [Z dv]`` (M, 3, p + 1) (module notes; ``Z^T Z = I``); inf where the
    filter fails (a variance not positive)."""
    U, logdet = joint_whiten(X, t, theta, known)
    if not np.isfinite(logdet):
        return np.inf
    p = X.shape[2] - 1
    try:
        T = np.linalg.cholesky(U.T @ U).T  # [Z_w y_w]^T [Z_w y_w] = T^T T: ln det(Z_w^T Z_w), RSS_w = T_pp^2
    except np.linalg.LinAlgError:
        return np.inf
    d = np.abs(np.diag(T))
    return float(logdet + 2.0 * np.sum(np.log(d[:p])) + d[p] ** 2)


def fit_tracking(X: np.ndarray, t: np.ndarray, start: NoiseModel, known: KnownStates, *,
                 xatol: float = 5e-3, maxfun: int = 600, part_start: tuple = ()) -> tuple[NoiseModel, float]:
    """The tracking noise by REML beside the known term (module notes), the kinds per axis of `start` (a fitted
    model: its parameters start the search; a given tau stays given): ``(model, -2 l_R)``.

    Free are, per axis, ``ln c`` (Gauss-Markov), ``ln d`` (white part) and ``ln tau`` (unless given; within
    :func:`casep.noise.fit.tau_search_bounds` of `t`, the interval :func:`casep.noise.fit.fit_noise` searches).
    The model returned has rule ``"REML beside the IMU noise"`` (``"tau given, REML beside ..."``) and the fitted
    ``-2 l_R``.

    A known term with `parts` (:meth:`KnownStates.scaled`) has their variances ``q_k`` free too, ``ln q_k`` from
    `part_start` (one per part, > 0) within ``[ln q0 - PART_RANGE[0], ln q0 + PART_RANGE[1]]`` (below it the part
    adds nothing the rows can tell from none: it is then ``q_k = 0``); the model's ``extra["known_scales"]`` holds
    them.
    """
    from casep.noise.fit import nelder_mead, tau_search_bounds

    lo, hi = tau_search_bounds(np.asarray(t, dtype=float))
    theta0 = TrackingParameters.of(start)
    free_tau = start.rule != "given"
    slots: list[tuple[str, int]] = []
    for j in range(3):
        if theta0.tau[j] is not None:
            slots.append(("c", j))
            if free_tau:
                slots.append(("tau", j))
        if theta0.d[j] > 0 or theta0.tau[j] is None:
            slots.append(("d", j))
    x0 = np.log([getattr(theta0, name)[j] for name, j in slots])
    # ln tau stays in fit_noise's search interval: beyond the record's span a Gauss-Markov term is a random
    # constant plus a random walk, which the likelihood cannot tell apart from one another (c and tau trade)
    low = np.array([lo if name == "tau" else -700.0 for name, _ in slots])
    high = np.array([hi if name == "tau" else 700.0 for name, _ in slots])
    x0 = np.clip(x0, low, high)
    n_t = x0.size
    if len(part_start) != len(known.parts) or any(not (q > 0) for q in part_start):
        raise ValueError(f"fit_tracking: one positive start per part of the known term ({len(known.parts)}), got "
                         f"{part_start}")
    lq = np.log(np.asarray(part_start, dtype=float))
    x0 = np.concatenate([x0, lq])
    low = np.concatenate([low, lq - PART_RANGE[0]])
    high = np.concatenate([high, lq + PART_RANGE[1]])

    def theta(x: np.ndarray) -> TrackingParameters:
        v = {"c": list(theta0.c), "tau": list(theta0.tau), "d": list(theta0.d)}
        for (name, j), value in zip(slots, np.exp(np.clip(x[:n_t], low[:n_t], high[:n_t]))):
            v[name][j] = float(value)
        return TrackingParameters(tuple(v["c"]), tuple(v["tau"]), tuple(v["d"]))

    def scales(x: np.ndarray) -> list[float]:
        xq = np.clip(x[n_t:], low[n_t:], high[n_t:])
        return [0.0 if v <= lo else float(np.exp(v)) for v, lo in zip(xq, low[n_t:])]

    def value(x: np.ndarray) -> float:
        return restricted_likelihood(X, t, theta(x), known.scaled(scales(x)) if known.parts else known)

    if known.parts:  # the parts' variances span orders of magnitude: the simplex starts at the best of a grid
        grid = np.linspace(-PART_RANGE[0], PART_RANGE[1], PART_GRID)
        cands = np.array(np.meshgrid(*[v + grid for v in lq], indexing="ij")).reshape(len(known.parts), -1).T
        x0[n_t:] = cands[int(np.argmin([value(np.concatenate([x0[:n_t], c])) for c in cands]))]
    best = nelder_mead(value, x0, np.full(x0.size, 0.5), xatol, maxfun=maxfun + 200 * len(known.parts))
    val = value(best)
    rule = ("REML" if free_tau else "tau given, REML") + " beside the IMU noise"
    extra = {"neg2_reml": val} if not known.parts else {"neg2_reml": val, "known_scales": scales(best)}
    return theta(best).model(start.kind, rule, **extra), val


@dataclass(frozen=True)
class RemlRows:
    """One record's restricted likelihood beside a known term: the rows ``X = [Z dv]`` (M, 3, p + 1), their times
    `t` (M,), the fitted tracking noise model `start` whose kinds the refit keeps, the known term `known` with its
    `parts` unscaled (:class:`KnownStates`), and `part_start` (one start per part, > 0: the refit's
    ``part_start``)."""

    X: np.ndarray
    t: np.ndarray
    start: NoiseModel
    known: KnownStates
    part_start: tuple


#: The rise of ``-2 l_R`` that bounds :func:`pool_parts`' 95 % interval of a part's variance (chi-square, 1 dof).
POOL_LEVEL = 3.841


@dataclass(frozen=True)
class PooledParts:
    """:func:`pool_parts`' answer: per part the variance ``q`` (per unit weight), its 95 % interval (``lo``, ``hi``;
    ``hi`` inf when the rows do not bound it from above within the search range), the summed ``-2 l_R`` at it and
    with every part 0, and each record's tracking noise refitted at its ``w_k q`` (``models``; None where the
    record's weight is 0 and it has no part to scale: still refitted, at 0)."""

    q: tuple
    interval: tuple
    neg2_reml: float
    neg2_reml_none: float
    weights: tuple
    models: tuple
    evaluations: int
    #: ``(q, -2 l_R)`` at the variances asked for by :func:`pool_parts`' `reference` (None: not asked)
    reference: tuple | None = None

    def to_dict(self) -> dict:
        return {"variances": list(self.q), "interval_95": [list(v) for v in self.interval],
                "neg2_reml": self.neg2_reml, "neg2_reml_without": self.neg2_reml_none, "weights": list(self.weights),
                "evaluations": self.evaluations,
                "reference": None if self.reference is None else {"variances": list(self.reference[0]),
                                                                  "neg2_reml": self.reference[1]},
                "rule": "one variance per part of the known term, q_k = w_k q in record k, fitted by the restricted "
                        "likelihood summed over the records, each record's tracking noise refitted at it "
                        "(casep.noise.known.pool_parts); the interval: where -2 l_R rises by 3.84 along that part, "
                        "the other parts held at their best"}


def pool_parts(records, weights=None, *, xatol: float = 0.1, step: float = 0.7,
               reference: tuple | None = None) -> PooledParts:
    """One size for the parts of several records' known terms (:class:`RemlRows`), fitted jointly.

    Record ``k``'s parts are at ``w_k q`` (`weights` ``w_k >= 0``, one per record, a measure of what drives the
    term in that record, or one per record and part, (K, n); default 1 each): ``q`` maximises the restricted
    likelihood summed over the records, each record's tracking noise profiled out (refitted at ``w_k q`` by
    :func:`fit_tracking`, from its own `start`, so the sum does not depend on the search's path)::

        -2 l_R(q) = sum_k  min_theta_k  -2 l_R,k(theta_k; w_k q)

    The search is in ``ln q_i`` within :data:`PART_RANGE` of the records' starts (their geometric mean, per unit
    weight); below the range a part is 0. It scans each part in turn over :data:`PART_GRID` points (the others at the
    best found so far), then runs the simplex to `xatol`. Each part's 95 % interval is where ``-2 l_R`` rises by
    :data:`POOL_LEVEL` from its best along that part (steps in ``ln q`` from `step` on, doubling, up to the search
    range's end, which counts: within the level there, the interval reaches 0 or has no upper end; the crossing
    bisected three times, then linear between its two points), the other parts held at their best: with one part
    the profile-likelihood interval; with several, the conditional one (no wider than the profile's).

    `reference` (one variance per part, >= 0): ``-2 l_R`` there is also returned (a size given beforehand, to compare
    the fitted one with: the white noise's density at rest, ``(1, 1)``)."""
    from casep.noise.fit import nelder_mead

    records = list(records)
    K = len(records)
    if K == 0:
        raise ValueError("pool_parts: no records")
    n = len(records[0].known.parts)
    if n == 0 or any(len(r.known.parts) != n or len(r.part_start) != n for r in records):
        raise ValueError("pool_parts: every record needs the same number of parts (> 0) and one start per part")
    w = np.ones(K) if weights is None else np.asarray(weights, dtype=float)
    if w.shape == (K,):
        w = np.repeat(w[:, None], n, axis=1)
    if w.shape != (K, n) or not np.all(np.isfinite(w)) or np.any(w < 0) or not np.all(np.any(w > 0, axis=0)):
        raise ValueError(f"pool_parts: one finite weight >= 0 per record ({K}), or per record and part ({K} x {n}), "
                         f"not all 0 for a part; got {weights!r}")
    starts = np.array([r.part_start for r in records], dtype=float)
    if np.any(~(starts > 0)):
        raise ValueError("pool_parts: every part start must be > 0")
    with np.errstate(divide="ignore"):
        lq = np.log(starts / w)
    lq0 = np.array([np.mean(lq[w[:, i] > 0, i]) for i in range(n)])
    low, high = lq0 - PART_RANGE[0], lq0 + PART_RANGE[1]
    count = [0]
    memo: dict = {}

    def sizes(x: np.ndarray) -> np.ndarray:
        xq = np.clip(x, low, high)
        return np.where(xq <= low, 0.0, np.exp(xq))

    def refit(x: np.ndarray) -> tuple[float, list]:
        key = tuple(np.round(np.clip(x, low, high), 9))
        if key not in memo:
            q = sizes(np.array(key))
            total, models = 0.0, []
            for r, wk in zip(records, w):
                model, val = fit_tracking(r.X, r.t, r.start, r.known.scaled([float(v) for v in wk * q]))
                total += val
                models.append(model)
            count[0] += 1
            memo[key] = (total, models)
        return memo[key]

    def value(x: np.ndarray) -> float:
        return refit(x)[0]

    grid = np.linspace(0.0, 1.0, PART_GRID)
    x = low.copy()
    for i in range(n):
        cands = [np.where(np.arange(n) == i, low[i] + g * (high[i] - low[i]), x) for g in grid]
        x = cands[int(np.argmin([value(c) for c in cands]))]
    x = np.clip(nelder_mead(value, x, np.full(n, 1.0), xatol, maxfun=40 * n + 20), low, high)
    best = value(x)
    interval = []
    for i in range(n):
        def along(v: float, i: int = i) -> float:  # -2 l_R with part i at ln q = v, the others at their best
            return value(np.where(np.arange(n) == i, v, x))

        lo_i, hi_i = level_interval(along, float(x[i]), best, float(low[i]), float(high[i]), POOL_LEVEL, step)
        lo_e = 0.0 if lo_i is None or lo_i <= low[i] else float(np.exp(lo_i))
        interval.append((lo_e if x[i] > low[i] else 0.0, np.inf if hi_i is None else float(np.exp(hi_i))))
    q = sizes(x)
    ref = None
    if reference is not None:
        r_q = np.asarray(reference, dtype=float)
        if r_q.shape != (n,) or np.any(~(r_q >= 0)) or np.any(~np.isfinite(r_q)):
            raise ValueError(f"pool_parts: the reference needs one finite variance >= 0 per part ({n}), got "
                             f"{reference!r}")
        with np.errstate(divide="ignore"):
            ref = (tuple(float(v) for v in r_q), value(np.where(r_q > 0, np.log(r_q), low)))
    weights_out = tuple(float(v[0]) if np.all(v == v[0]) else tuple(float(u) for u in v) for v in w)
    return PooledParts(tuple(float(v) for v in q), tuple(interval), best, value(low), weights_out,
                       tuple(refit(x)[1]), count[0], ref)


def level_interval(along, x: float, best: float, low: float, high: float, level: float, step: float,
                   outside: dict | None = None) -> tuple[float | None, float | None]:
    """The ends of ``{v: along(v) - best < level}`` around `x` (its best point) within ``[low, high]``: from `x`
    steps of `step` on each side, doubling, up to the bound, which counts (within the level there: that end None,
    the rows do not bound it); the crossing bisected three times, then linear between its two points. `outside`
    (``{v: along(v)}``) holds points already known beyond the level: a side with one starts bracketed by the
    nearest. The rule of :func:`pool_parts`' intervals and of :func:`stated_tau_check`'s."""
    ends: list[float | None] = []
    for sign, bound in ((-1.0, low), (1.0, high)):
        known = sorted((v for v in (outside or {}) if sign * (v - x) > 0), key=lambda v: abs(v - x))
        inside, d = x, step  # the last point within the level, and the next step (doubling)
        if known:
            cur = known[0]
        else:
            while True:
                cur = inside + sign * d
                if sign * (cur - bound) >= 0:
                    cur = bound
                if along(cur) - best >= level:
                    break
                if cur == bound:  # the bound itself within the level: the rows do not bound it there
                    break
                inside, d = cur, 2.0 * d
            if cur == bound and along(cur) - best < level:
                ends.append(None)
                continue
        for _ in range(3):  # bisect the crossing, then linear between the two points left
            mid = 0.5 * (inside + cur)
            if along(mid) - best >= level:
                cur = mid
            else:
                inside = mid
        v_in, v_out = along(inside), along(cur)
        frac = (best + level - v_in) / (v_out - v_in) if v_out > v_in else 1.0
        ends.append(inside + frac * (cur - inside))
    return ends[0], ends[1]


#: The white shares :func:`stated_tau_check` scans (with the profile's grid of tau) for its free fit's start, and (with
#: these factors on the axis's variance) for an upper bound of a point's ``-2 l_R`` (below the level: no refit needed).
SCAN_SHARES = (0.1, 0.3, 0.5, 0.7, 0.9)
BOUND_SCALES = (0.6, 0.8, 1.0, 1.25, 1.6)


def stated_tau_check(X: np.ndarray, t: np.ndarray, fit: NoiseModel, known: KnownStates, stated, *,
                     part_start: tuple = (), level: float | None = None
                     ) -> tuple[NoiseModel, list[dict], NoiseModel | None]:
    """Stated correlation times of the tracking noise judged by the restricted likelihood beside the known term:
    `fit` the tracking noise fitted at them (:func:`fit_tracking` from a model of rule ``"given"``, its
    ``extra["neg2_reml"]``), `stated` the three taus (s), `known`, `part_start` as that fit's.

    The free fit (tau by REML too, from the best taus and white shares of a scan) is the best point; per axis ``a``
    the profile point at the stated tau holds that axis's tau there and the others' at the free fit's, every
    variance refitted (the rule of :func:`casep.noise.fit.tau_profile`'s points, here beside the known term: the
    IMU's random walks left in the rows read as a longer correlation time, and on a rail launch with MEMS noise the
    true tau was outside the profile of the rows alone on 5 of 6 axes, 2 seeds). Its ``-2 l_R`` above the best (the
    least of the free fit's, `fit`'s and the points') is the drop (``drop_bound``: an upper bound of it, that
    axis's variances on a grid, the rest held, where that bound is already below the level: no refit needed); within
    `level` (:data:`casep.noise.fit.PROFILE_LR`,
    chi2_1 95 %) the stated tau is inside the profile's 95 % interval. Where it is not, the interval itself is found
    along that axis (:func:`level_interval` in ``ln tau`` over :func:`casep.noise.fit.tau_search_bounds`, the stated
    point bracketing its side).

    Returns the free fit, per axis ``{"tau_s", "reml_tau_s", "drop", "within", "drop_bound", "interval_s"}``
    (``interval_s`` None where within; an end None where the search interval's bound is within the level), and,
    where some axis is outside, the tracking noise fitted at the closest taus the data accept (the stated tau where
    within, else the interval's end nearer to it; None when every axis is within): against it the std at the stated
    tau are judged
    (:func:`casep.workflows.imu_separate.warn_tau_stated`). REML's tau is a poor yardstick there: on a rail launch
    whose tracking noise dominates, the std at REML's tau were 1.71 times those at the true tau in one of 12 runs
    (one of its axes outside by chance: failed)."""
    from casep.noise.fit import PROFILE_LR, PROFILE_POINTS, tau_search_bounds

    level = PROFILE_LR if level is None else float(level)
    lo, hi = tau_search_bounds(np.asarray(t, dtype=float))
    th_fit = TrackingParameters.of(fit)
    # the simplex started at the stated taus stops in a local minimum near them (a stated 0.2 s on 1 s noise: 0.46 s,
    # 10 below the maximum at 1.3 s); so it starts from each axis's best tau and white share on a grid (tau: the
    # profile's, evenly in ln tau over the search interval; the axis's variance at the stated fit's; the stated fit's
    # own values among the candidates; the axes in turn)
    fixed = known.scaled(list(fit.extra["known_scales"])) if known.parts else known
    th = th_fit
    taus = np.exp(np.linspace(lo, hi, PROFILE_POINTS))
    for j in range(3):
        var = th.c[j] + th.d[j]
        shares = SCAN_SHARES if th.d[j] > 0 else (0.0,)  # a Gauss-Markov axis without white noise stays so
        grid = [(float(g), w) for g in taus for w in shares]

        def at(g: float, w: float, j: int = j, var: float = var, th: TrackingParameters = th) -> TrackingParameters:
            return TrackingParameters(*(tuple(new if k == j else old[k] for k in range(3)) for old, new in
                                        ((th.c, var * (1.0 - w)), (th.tau, g), (th.d, var * w))))

        cands = [*grid, (th.tau[j], th.d[j] / var)] if th.tau[j] is not None and var > 0 else grid
        th = at(*cands[int(np.argmin([restricted_likelihood(X, t, at(g, w), fixed) for g, w in cands]))])
    free = fit_tracking(X, t, th.model(fit.kind, "REML"), known, part_start=part_start)[0]
    th_free = TrackingParameters.of(free)
    fixed = known.scaled(list(free.extra["known_scales"])) if known.parts else known
    memo: dict = {}

    def moved(j: int, v: float) -> TrackingParameters:  # axis j's tau at e^v, the rest at the free fit's
        c, tau, d = list(th_free.c), list(th_free.tau), list(th_free.d)
        if tau[j] is None:  # a white axis in the free fit: its Gauss-Markov part starts at the stated fit's
            c[j], d[j] = th_fit.c[j], th_fit.d[j]
        tau[j] = float(np.exp(v))
        return TrackingParameters(tuple(c), tuple(tau), tuple(d))

    def point(j: int, v: float) -> float:  # -2 l_R with axis j's tau at e^v, the others' at the free fit's
        if (j, v) not in memo:
            memo[(j, v)] = fit_tracking(X, t, moved(j, v).model(fit.kind, "given"), known, part_start=part_start)[1]
        return memo[(j, v)]

    def bound(j: int, v: float) -> float:  # point's upper bound: axis j's variances on a grid, the rest held
        th0 = moved(j, v)
        var = th0.c[j] + th0.d[j]
        return min(restricted_likelihood(X, t, TrackingParameters(*(
            tuple(new if k == j else old[k] for k in range(3)) for old, new in
            ((th0.c, var * sc * (1.0 - w)), (th0.tau, th0.tau[j]), (th0.d, var * sc * w)))), fixed)
            for sc in BOUND_SCALES for w in (SCAN_SHARES if th0.d[j] > 0 else (0.0,)))

    # each axis's drop: the refitted point where its bound is not already below the level (then it is within)
    logs = [float(np.log(v)) for v in stated]
    bounds = [bound(j, logs[j]) for j in range(3)]
    vals: list[float | None] = [None, None, None]
    best = min(free.extra["neg2_reml"], fit.extra["neg2_reml"])
    while True:
        for j in range(3):
            if vals[j] is None and bounds[j] - best >= level:
                vals[j] = point(j, logs[j])
        lowest = min([best, *(v for v in vals if v is not None)])
        if lowest == best:
            break
        best = lowest
    out = []
    for j in range(3):
        v, drop = logs[j], (bounds[j] if vals[j] is None else vals[j]) - best
        rec = {"tau_s": float(stated[j]), "reml_tau_s": free.tau[j], "drop": float(drop), "within": bool(drop < level),
               "drop_bound": vals[j] is None, "interval_s": None}
        if not rec["within"] and free.tau[j] is not None:
            x = float(np.clip(np.log(free.tau[j]), lo, hi))
            ends = level_interval(lambda u, j=j: point(j, u), x, best, lo, hi, level, 0.7, {v: drop + best})  # pool's
            rec["interval_s"] = [None if e is None else float(np.exp(e)) for e in ends]
        out.append(rec)
    if all(rec["within"] for rec in out):
        return free, out, None
    # the closest taus the data accept: the stated where within, else the nearer end of the interval (the search
    # interval's bound where the interval reaches it; its bottom where REML finds the axis white)
    near = []
    for rec in out:
        below = rec["tau_s"] < (rec["reml_tau_s"] or 0.0)
        edge = (rec["interval_s"] or [None, None])[0 if below else 1]
        near.append(rec["tau_s"] if rec["within"] else float(np.exp(lo if rec["reml_tau_s"] is None or below else hi))
                    if edge is None else edge)
    accepted = TrackingParameters(th_free.c, tuple(near), th_free.d).model(fit.kind, "given")
    return free, out, fit_tracking(X, t, accepted, known, part_start=part_start)[0]


def tracking_covariance_times(V: np.ndarray, t: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """``Sigma_track V`` for rows ``V`` (N, 3, k) of the noise model `noise` (with its fitted ``sigma``): per axis
    the forward and backward AR(1) recursions of the module notes. O(N k)."""
    theta = TrackingParameters.of(noise)
    V = np.asarray(V, dtype=float)
    out = np.empty_like(V)
    N = t.size
    for j, _ in enumerate(AXES):
        v = V[:, j, :]
        out[:, j, :] = theta.d[j] * v
        if theta.tau[j] is None:
            continue
        a = np.concatenate([[0.0], ar1_terms(np.diff(t), theta.tau[j])[0]])
        fwd, bwd = np.empty_like(v), np.empty_like(v)
        fwd[0] = v[0]
        for i in range(1, N):
            fwd[i] = v[i] + a[i] * fwd[i - 1]
        bwd[-1] = v[-1]
        for i in range(N - 2, -1, -1):
            bwd[i] = v[i] + a[i + 1] * bwd[i + 1]
        out[:, j, :] += theta.c[j] * (fwd + bwd - v)
    return out
