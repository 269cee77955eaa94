"""Fisher information of a flight as a CasADi function of the manoeuvre, and the design objectives.

The chain (all symbolic, so IPOPT gets exact gradients by automatic differentiation):

1. Nominal flight on the design grid (``design_rate`` Hz): times ``t_k``, attitude
   ``(theta_k, psi_k)`` and the axial acceleration ``a_k = f_k . e_b(theta_k, psi_k)`` (thrust minus
   drag over mass, m/s^2), all fixed.
2. Offsets ``d_theta_k, d_psi_k = B x`` (piecewise-linear in the knots ``x``, deg), and the designed
   specific force ``f_k = a_k e_b(theta_k + d_theta_k, psi_k + d_psi_k)``.
3. ``S_V`` by the model's own Jacobians (``dphidot_dD(f)``, ``dDelta_dD(f)``, ``dvelocity_error_dD(f)``)
   and the trapezoid recursions of :mod:`casep.model.sv` on the design grid.
4. Fisher information ``F = (rate / sigma^2) sum_k w_k S_k^T S_k`` (``w_k`` trapezoid weights: the sum
   over the flight's samples at the scenario's ``rate`` Hz, white noise of std sigma).
5. Scaled information ``M = diag(s) F diag(s) + P`` with ``s`` the coefficients' declared magnitudes
   (:attr:`casep.ErrorModel.scales`) and ``P`` the prior information in the same scaling (``--prior``),
   or, without a prior, ``eps I`` (``eps`` = :data:`REGULARISATION`: a vague prior of std 10 declared
   magnitudes, so that an unidentifiable coefficient gives a bounded objective, not an infinite one, and
   the hopeless ones do not drown the rest).
6. Objectives on the scaled covariance ``C = M^-1`` (Cholesky ``M = L L^T``, written out in CasADi):
   ``A`` = trace C (sum of the squared CRLB/magnitude ratios; optionally over a subset of the
   coefficients, "those that matter"), ``D`` = log det C, ``miss`` = variance
   of the predicted impact miss of the *nominal* trajectory, ``sum_r g_r^T C g_r`` over downrange and
   crossrange with ``g = diag(s) G^T``, ``G = -J [S_P; S_V]`` at burnout (:mod:`casep.impact`).
   ``A`` and ``miss`` are minimised as logarithms (same optimum, better scaling).

**Approximation**: the manoeuvre rotates the nominal specific force; its effect on the trajectory
itself (velocity, altitude, so drag and the gravity-turn pitch) is neglected. :func:`design` measures
that error by re-simulating the designed flight (``simulate_boost`` with the offsets) and building its
S_V at the scenario's rate.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca
import numpy as np

from casep.design.maneuver import Maneuver, interpolation_matrix

__all__ = ["DesignProblem", "OBJECTIVES", "REGULARISATION", "fisher_information", "objective_value"]

OBJECTIVES = ("A", "D", "miss")
#: Scaled prior information where no prior is given: a prior std of 10 declared magnitudes. A coefficient
#: whose CRLB is far above that adds about 100 to the A objective whatever the manoeuvre; the objective
#: responds to the coefficients between well determined and 10 magnitudes, those a manoeuvre can bring
#: to identifiability.
REGULARISATION = 1e-2


def _cholesky_objectives(n: int, g_rows: np.ndarray | None, weights: np.ndarray | None = None) -> ca.Function:
    """SX function M (n x n, symmetric positive definite) -> (sum_j w_j [M^-1]_jj, log det M^-1,
    sum_r g_r^T M^-1 g_r); weights w_j 1 by default (the trace)."""
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
    M = ca.SX.sym("M", n, n)
    L = [[ca.SX(0) for _ in range(n)] for _ in range(n)]
    for j in range(n):
        s = M[j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        L[j][j] = ca.sqrt(s)
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    logdet: Any = 0  # a CasADi expression once the first term is added
    for j in range(n):
        logdet = logdet + 2 * ca.log(L[j][j])

    def forward(b):  # y = L^-1 b
        y = []
        for i in range(n):
            s = b[i]
            for k in range(i):
                s = s - L[i][k] * y[k]
            y.append(s / L[i][i])
        return y

    trace: Any = 0
    for j in range(n):  # [M^-1]_jj = ||L^-1 e_j||^2 (column j of L^-1, zero above the diagonal)
        if w[j] == 0:
            continue
        e = [ca.SX(1) if i == j else ca.SX(0) for i in range(n)]
        y = forward(e)
        cjj: Any = 0  # a CasADi expression once the first term is added
        for i in range(j, n):
            cjj = cjj + y[i] * y[i]
        trace = trace + float(w[j]) * cjj
    miss = 0
    if g_rows is not None:
        for g in g_rows:
            y = forward([ca.SX(float(v)) for v in g])
            for v in y:
                miss = miss + v * v
    return ca.Function("design_objectives", [M], [trace, -logdet, miss], ["M"], ["A", "D", "miss"])


class DesignProblem:
    """The manoeuvre -> scaled information -> objective chain for one nominal flight.

    Parameters
    ----------
    model : ErrorModel
        A set-up model without signal columns.
    t, attitude, force : arrays
        The nominal flight on the design grid: times (K,), s; attitude (K, 3) rad (pitch, yaw, roll);
        specific force (K, 3) m/s^2 (platform frame).
    maneuver : Maneuver
    rate : float
        Sample rate of the flown flight, Hz (the Fisher information counts its samples).
    sigma : float
        White tracking-noise std, m/s.
    scales : (n,) array
        Declared magnitude per coefficient, natural units.
    prior_information : (n, n) array, optional
        Prior information (natural units, ``Cov_prior^-1``).
    miss_sensitivity : (2, n) array, optional
        ``G``, metres per natural unit (needed for the ``miss`` objective).
    weights : (n,) array, optional
        Weight of each coefficient's scaled variance in the A objective (default 1: the trace; 0/1 to
        design for a subset, "the coefficients that matter").
    """

    def __init__(self, model, t, attitude, force, maneuver: Maneuver, *, rate: float, sigma: float,
                 scales: np.ndarray, prior_information: np.ndarray | None = None,
                 miss_sensitivity: np.ndarray | None = None, weights: np.ndarray | None = None) -> None:
        if model.signals:
            raise ValueError(f"model `{model.name}` uses flight columns ({', '.join(model.signals)}): "
                             "casep design supports models of the specific force (and time) only")
        t = np.asarray(t, dtype=float)
        att = np.asarray(attitude, dtype=float)
        f = np.asarray(force, dtype=float)
        K, n = t.size, model.n_coefficients
        self.model, self.maneuver, self.rate, self.sigma = model, maneuver, float(rate), float(sigma)
        self.t = t
        self.scales = np.asarray(scales, dtype=float)
        theta0, psi0 = att[:, 0], att[:, 1]
        e0 = np.column_stack([np.cos(psi0) * np.cos(theta0), np.cos(psi0) * np.sin(theta0), np.sin(psi0)])
        self.axial = np.einsum("ki,ki->k", f, e0)  # a_k = f . e_b (f = a e_b exactly in the simulator)
        B = interpolation_matrix(np.asarray(maneuver.knots), t)[:, 1:]  # first knot held at zero
        x = ca.MX.sym("x", maneuver.n_variables)
        m = maneuver.n_free
        d = {"pitch": ca.MX.zeros(K, 1), "yaw": ca.MX.zeros(K, 1)}
        for k, axis in enumerate(maneuver.axes):
            d[axis] = ca.mtimes(ca.DM(B), x[k * m:(k + 1) * m]) * (math.pi / 180.0)
        theta = ca.DM(theta0) + d["pitch"]
        psi = ca.DM(psi0) + d["yaw"]
        ex, ey, ez = ca.cos(psi) * ca.cos(theta), ca.cos(psi) * ca.sin(theta), ca.sin(psi)
        a = ca.DM(self.axial)
        fx, fy, fz = a * ex, a * ey, a * ez  # K x 1 each
        fT = ca.horzcat(fx, fy, fz).T  # 3 x K
        fns = model.functions
        n_in = fns["dphidot_dD"].n_in()
        args = [fT] + ([ca.DM(t - t[0]).T] if n_in > 1 else [])

        def stacked(name):  # 3 x (n K) -> (3 n) x K, row i + 3 j = component i, coefficient j
            out = fns[name].map(K)(*args)
            return ca.reshape(out, 3 * n, K)

        G, A, V = stacked("dphidot_dD"), stacked("dDelta_dD"), stacked("dvelocity_error_dD")
        dt = np.diff(t)
        half_dt = ca.DM(0.5 * dt).T  # 1 x (K - 1)

        def cumtrapz(Y):  # rows of Y integrated in time: column k = trapezoid from t_0 to t_k
            steps = (Y[:, :-1] + Y[:, 1:]) * ca.repmat(half_dt, Y.shape[0], 1)
            return ca.horzcat(ca.MX.zeros(Y.shape[0], 1), ca.cumsum(steps, 1))

        phi0 = model.numeric("phi0").reshape(-1, order="F")  # row i + 3 j
        dv0 = model.numeric("dv0").reshape(-1, order="F")
        Phi = ca.repmat(ca.DM(phi0), 1, K) + cumtrapz(G)
        rows = [list(range(i, 3 * n, 3)) for i in range(3)]
        P = [Phi[r, :] for r in rows]  # n x K per component
        Fr = [ca.repmat(c.T, n, 1) for c in (fx, fy, fz)]  # f component as n x K
        cross = [Fr[1] * P[2] - Fr[2] * P[1], Fr[2] * P[0] - Fr[0] * P[2], Fr[0] * P[1] - Fr[1] * P[0]]  # f x phi
        S = [ca.repmat(ca.DM(dv0[r]), 1, K) + cumtrapz(cross[i] + A[r, :]) + V[r, :]
             for i, r in enumerate(rows)]  # S_V per component, n x K
        w = np.zeros(K)
        w[1:] += 0.5 * dt
        w[:-1] += 0.5 * dt  # trapezoid weights of integral dt
        W = ca.DM(np.sqrt(w * self.rate) / self.sigma)
        Fisher = 0
        for c in S:
            Sw = c * ca.repmat(W.T, n, 1)
            Fisher = Fisher + ca.mtimes(Sw, Sw.T)
        sc = ca.DM(np.outer(self.scales, self.scales))
        Pinfo = (REGULARISATION * np.eye(n) if prior_information is None
                 else np.asarray(prior_information, dtype=float) * np.outer(self.scales, self.scales))
        self.prior_scaled = Pinfo
        self.prior_information = None if prior_information is None else np.asarray(prior_information, dtype=float)
        Msc = Fisher * sc + ca.DM(Pinfo)
        Msc = 0.5 * (Msc + Msc.T)
        g_rows = None
        if miss_sensitivity is not None:
            g_rows = np.asarray(miss_sensitivity, dtype=float) * self.scales  # g_r = diag(s) G_r
        self.weights = None if weights is None else np.asarray(weights, dtype=float)
        objs = _cholesky_objectives(n, g_rows, self.weights)(Msc)
        self.has_miss = g_rows is not None
        self.x = x
        self.fisher = ca.Function("fisher", [x], [Fisher], ["x"], ["F"])  # natural units
        self.sv = ca.Function("sv", [x], [ca.vertcat(*S)], ["x"], ["S"])  # (3 n) x K, component-major
        self._objs = ca.Function("objectives", [x], list(objs), ["x"], ["A", "D", "miss"])
        # Lateral acceleration: cos(gamma_k) = e0_k . e_k >= cos(gamma_max_k)
        self.cos_gamma = ca.DM(e0[:, 0]) * ex + ca.DM(e0[:, 1]) * ey + ca.DM(e0[:, 2]) * ez
        self._e0 = e0

    # -- evaluation helpers -------------------------------------------------------------
    def objective_expr(self, kind: str) -> ca.MX:
        """The minimised expression for objective `kind` (log for A and miss)."""
        if kind not in OBJECTIVES:
            raise ValueError(f"unknown objective `{kind}`: use one of {', '.join(OBJECTIVES)}")
        if kind == "miss" and not self.has_miss:
            raise ValueError("objective `miss` needs the miss sensitivities (`miss_sensitivity`)")
        val = self._objs(self.x)[OBJECTIVES.index(kind)]
        return val if kind == "D" else ca.log(val)

    def value(self, kind: str, x) -> float:
        """Objective `kind` (not logged) at design vector `x` (deg)."""
        return float(self._objs(np.asarray(x, dtype=float))[OBJECTIVES.index(kind)])

    def function(self, kind: str) -> ca.Function:
        """``x -> minimised objective`` as a CasADi function (with exact derivatives)."""
        return ca.Function(f"objective_{kind}", [self.x], [self.objective_expr(kind)], ["x"], ["J"])

    def covariance(self, x) -> np.ndarray:
        """Predicted covariance in natural units at `x`: the CRLB, or the Bayesian bound with the prior
        (no regularisation: NaN for what the flight and prior leave undetermined)."""
        return fisher_covariance(np.array(self.fisher(np.asarray(x, dtype=float))), self.prior_information)

    def lateral_g(self, x) -> np.ndarray:
        """``|f| sin gamma`` per design sample, g."""
        cg = np.clip(np.array(ca.Function("cg", [self.x], [self.cos_gamma])(np.asarray(x, dtype=float))).ravel(),
                     -1.0, 1.0)
        from casep.units import G0

        return np.abs(self.axial) * np.sqrt(1.0 - cg**2) / G0


def fisher_covariance(F: np.ndarray, prior_info: np.ndarray | None = None) -> np.ndarray:
    """``(F + prior)^-1`` by eigen-decomposition in the column-equilibrated form, NaN for directions
    with no information (rows/columns of coefficients in the null space)."""
    from casep.checks.diagnostics import crlb_covariance

    F = np.asarray(F, dtype=float)
    n = F.shape[0]
    H = F if prior_info is None else F + prior_info
    H = 0.5 * (H + H.T)
    d = np.sqrt(np.clip(np.diag(H), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    lam, U = np.linalg.eigh(H / np.outer(d, d))  # equilibrated first: natural units span many decades
    lam = np.clip(lam, 0.0, None)
    R = (np.sqrt(lam)[:, None] * U.T) * d  # R^T R = H
    return crlb_covariance(R.reshape(n, 1, n), 1.0)


def fisher_information(S: np.ndarray, sigma: float) -> np.ndarray:
    """``S^T S / sigma^2`` for an (N, 3, n) S_V (white noise)."""
    A = np.asarray(S, dtype=float).reshape(-1, S.shape[-1])
    return A.T @ A / sigma**2


def objective_value(kind: str, F: np.ndarray, scales: np.ndarray, prior_info: np.ndarray | None = None,
                    miss_sensitivity: np.ndarray | None = None, weights: np.ndarray | None = None) -> float:
    """Objective `kind` (as reported, not logged) from a Fisher information `F` in natural units:
    the numpy twin of :class:`DesignProblem`'s (same regularisation)."""
    s = np.asarray(scales, dtype=float)
    n = s.size
    P = REGULARISATION * np.eye(n) if prior_info is None else np.asarray(prior_info) * np.outer(s, s)
    M = F * np.outer(s, s) + P
    M = 0.5 * (M + M.T)
    L = np.linalg.cholesky(M)
    if kind == "A":
        Li = np.linalg.inv(L)
        w = np.ones(n) if weights is None else np.asarray(weights, dtype=float)
        return float(np.sum(w * np.sum(Li**2, axis=0)))  # [M^-1]_jj = column norms of L^-1
    if kind == "D":
        return float(-2.0 * np.sum(np.log(np.diag(L))))
    if kind == "miss":
        g = np.asarray(miss_sensitivity, dtype=float) * s
        y = np.linalg.solve(L, g.T)
        return float(np.sum(y**2))
    raise ValueError(f"unknown objective `{kind}`: use one of {', '.join(OBJECTIVES)}")
