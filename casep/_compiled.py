"""The sequential kernels numpy cannot fuse, compiled by numba (``cache=True``).

Imported by :mod:`casep._kernels` on the first call of one of them (not when casep is imported:
numba's import and the set-up of its target take about 0.3 s). Kept free of Python objects so that
numba compiles them in nopython mode; the callers validate every argument.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["rels_ud", "sv_integrate_chunk", "all_pole_filter", "gmw_filter", "joint_filter", "reml_scale_fit"]


@numba.njit(cache=True, nogil=True)
def sv_integrate_chunk(G, A, f, half_dt, gcols, acols, phi, G_prev, I_prev, S_prev, out):  # pragma: no cover
    """Trapezoid-integrate one chunk of S_V in place (see :mod:`casep.model.sv` for the equations).

    G (K, 3, ng), A (K, 3, na): Jacobians per sample; f (K, 3); half_dt (K,) = dt_k / 2;
    phi (3, ng), G_prev (3, ng), I_prev (3, n), S_prev (3, n): carries, updated in place;
    out (K, 3, n): S_V rows of the chunk.
    """
    K = G.shape[0]
    ng = gcols.size
    na = acols.size
    n = out.shape[2]
    Icur = np.zeros((3, n))
    for k in range(K):
        h = half_dt[k]
        fx = f[k, 0]
        fy = f[k, 1]
        fz = f[k, 2]
        for i in range(3):
            for j in range(n):
                Icur[i, j] = 0.0
        for j in range(ng):
            # Phi_k = Phi_{k-1} + (G_{k-1} + G_k) dt_k / 2
            for i in range(3):
                g = G[k, i, j]
                phi[i, j] += (G_prev[i, j] + g) * h
                G_prev[i, j] = g
            # [f x] Phi: (fy Phi_z - fz Phi_y, fz Phi_x - fx Phi_z, fx Phi_y - fy Phi_x)
            c = gcols[j]
            Icur[0, c] += fy * phi[2, j] - fz * phi[1, j]
            Icur[1, c] += fz * phi[0, j] - fx * phi[2, j]
            Icur[2, c] += fx * phi[1, j] - fy * phi[0, j]
        for j in range(na):
            c = acols[j]
            for i in range(3):
                Icur[i, c] += A[k, i, j]  # + Delta Jacobian
        # S_k = S_{k-1} + (I_{k-1} + I_k) dt_k / 2
        for i in range(3):
            for j in range(n):
                S_prev[i, j] += (I_prev[i, j] + Icur[i, j]) * h
                I_prev[i, j] = Icur[i, j]
                out[k, i, j] = S_prev[i, j]


@numba.njit(cache=True, nogil=True)
def _bierman(U, D, x, h, f, b, r, dz, start):  # pragma: no cover
    """One scalar measurement ``z = h x + e``, Var e = r, innovation dz = z - h x: Bierman's U-D update.

    U (n, n) unit upper triangular stored transposed, D (n,), x (n,) updated in place;
    f, b (n,) work arrays. ``h[j] = 0`` for ``j < start`` (skipped: exact).
    """
    n = x.size
    # f = U^T h ; b = D f
    for j in range(n):
        s = 0.0
        if j >= start:
            s = h[j]
            for i in range(start, j):
                s += U[j, i] * h[i]
        f[j] = s
        b[j] = D[j] * s
    # Bierman: sweep j = start..n-1 (the steps j < start change nothing)
    alpha = r
    gamma = 1.0 / alpha
    for j in range(start, n):
        beta = alpha
        alpha = alpha + f[j] * b[j]
        lam = -f[j] * gamma
        gamma = 1.0 / alpha
        D[j] = beta * gamma * D[j]
        bj = b[j]
        for i in range(j):
            u = U[j, i]
            U[j, i] = u + b[i] * lam
            b[i] = b[i] + bj * u
    # x <- x + K dz, K = b / alpha
    g = dz * gamma
    for j in range(n):
        x[j] += g * b[j]


@numba.njit(cache=True, nogil=True)
def rels_ud(H, y, x, U, D, weight, forgetting, n_c, posterior, stride, history, history_var, D0, past,
            k0):  # pragma: no cover
    """Recursive (extended) least squares with Bierman's UD scalar updates, in place.

    H (N, 3, p): scaled regressors; y (N, 3); x (p + n_c): estimate; U (p + n_c, p + n_c)
    unit upper-triangular stored *transposed* (Ut[j, i] = U[i, j], rows contiguous);
    D (p + n_c): P = U diag(D) U^T, on entry the diagonal prior P_0 = diag(D) (U = I, x = 0).
    Per sample, when forgetting < 1, stabilized forgetting: P <- P / forgetting, then n
    pseudo-measurements ``x_j = 0`` of variance D_0,j / (1 - forgetting), i.e.
    P^-1 <- forgetting P^-1 + (1 - forgetting) P_0^-1 (see :mod:`casep.estimators.rls`); then one scalar
    update per axis with measurement variance 1 / weight. The last n_c entries of x are the
    noise-model coefficients; their regressors are each axis' last n_c residuals
    (a-posteriori when `posterior`, else a-priori). Every `stride` samples x is copied to
    history[k // stride] and diag(P) to history_var[k // stride]. Returns the residuals
    (N, 3): a-priori innovations y - h x_{k-1} (the sequence the recursion whitens).

    Resumable over blocks of samples: x, U, D and `past` (3, n_c + 1: each axis' last
    residuals, newest first) carry the state; D0 is the prior diagonal (forgetting pulls
    towards it) and k0 the index of this block's first sample in the flight (history rows).
    """
    N = H.shape[0]
    p = H.shape[2]
    n = p + n_c
    h = np.zeros(n)
    f = np.zeros(n)
    b = np.zeros(n)
    e_j = np.zeros(n)
    innov = np.zeros((N, 3))
    r = 1.0 / weight
    inv_lam = 1.0 / forgetting
    for k in range(N):
        if forgetting != 1.0:
            for j in range(n):
                D[j] *= inv_lam  # P <- P / lambda
            for j in range(n):
                # + (1 - lambda) P_0^-1: pseudo-measurement 0 = e_j^T x + v, Var v = D_0,j / (1 - lambda)
                e_j[j] = 1.0
                _bierman(U, D, x, e_j, f, b, D0[j] / (1.0 - forgetting), -x[j], j)
                e_j[j] = 0.0
        for axis in range(3):
            for j in range(p):
                h[j] = H[k, axis, j]
            for j in range(n_c):
                h[p + j] = past[axis, j]
            # innovation dz = y - h x
            dz = y[k, axis]
            for j in range(n):
                dz -= h[j] * x[j]
            innov[k, axis] = dz
            _bierman(U, D, x, h, f, b, r, dz, np.int64(0))  # not the literal 0: one signature, compiled once
            if n_c > 0:
                e = dz
                if posterior:
                    e = y[k, axis]
                    for j in range(n):
                        e -= h[j] * x[j]
                for j in range(n_c - 1, 0, -1):
                    past[axis, j] = past[axis, j - 1]
                past[axis, 0] = e
        if stride > 0 and (k0 + k) % stride == 0:
            row = (k0 + k) // stride
            for j in range(n):
                history[row, j] = x[j]
            # diag(P)_i = sum_{j >= i} U_ij^2 D_j  (U unit upper triangular, stored transposed)
            for i in range(n):
                s = D[i]
                for j in range(i + 1, n):
                    s += U[j, i] * U[j, i] * D[j]
                history_var[row, i] = s
    return innov


@numba.njit(cache=True, nogil=True)
def all_pole_filter(a, x, y):  # pragma: no cover
    """``y = lfilter([1], a, x, axis=0)`` for x (N, m), a (K + 1,) with ``a[0] = 1``, written into y.

    The direct form II transposed of ``scipy.signal.lfilter`` with its operations in its order
    (the zero coefficients of the padded numerator included), so the same numbers.
    """
    N, m = x.shape
    K = a.size - 1
    Z = np.zeros(max(K, 1))
    for j in range(m):
        for i in range(K):
            Z[i] = 0.0
        for k in range(N):
            xn = x[k, j]
            if K == 0:
                y[k, j] = xn * 1.0
                continue
            yn = Z[0] + 1.0 * xn  # y = z_0 + b_0 x
            for i in range(K - 1):
                Z[i] = Z[i + 1] + xn * 0.0 - yn * a[i + 1]  # z_i = z_(i+1) + b_(i+1) x - a_(i+1) y
            Z[K - 1] = xn * 0.0 - yn * a[K]
            y[k, j] = yn


@numba.njit(cache=True, nogil=True)
def gmw_filter(X, dt, tau, share, m, P, out):  # pragma: no cover
    """Innovations whitening of Gauss-Markov plus white noise (:func:`casep._kernels.gmw_filter`: the
    equations); returns ``sum ln F_k``. The same operations as :func:`casep._kernels.gmw_filter_numpy`."""
    K, n = X.shape
    q = 1.0 - share
    logdet = 0.0
    for k in range(K):
        x = dt[k] / tau
        a = np.exp(-x)  # a_k = exp(-dt_k / tau)
        b = -np.expm1(-2.0 * x)  # 1 - a_k^2 without cancellation
        Pm = a * a * P[0] + q * b  # P_k^- = a^2 P + q (1 - a^2)
        F = Pm + share
        s = 1.0 / np.sqrt(F)
        gain = Pm / F
        for j in range(n):
            nu = X[k, j] - a * m[j]  # innovation x_k - a_k m_(k-1)
            out[k, j] = nu * s
            if share == 0.0:
                m[j] = X[k, j]  # K = 1: the state is the sample
            else:
                m[j] = a * m[j] + gain * nu
        P[0] = Pm * share / F
        logdet += np.log(F)
    return logdet


@numba.njit(cache=True, nogil=True)
def _acc(A, B, transpose_b, sign, out):  # pragma: no cover
    """``out += sign A B`` (``A B^T`` with `transpose_b`) by scalar loops (matrices of 3 x 3 to 18 x 18)."""
    n, m = A.shape
    p = out.shape[1]
    for i in range(n):
        for l in range(m):
            x = sign * A[i, l]
            if x == 0.0:
                continue
            if transpose_b:
                for j in range(p):
                    out[i, j] += x * B[j, l]
            else:
                for j in range(p):
                    out[i, j] += x * B[l, j]


@numba.njit(cache=True, nogil=True)
def _acc_times_sparse_t(A, B, rows, count, out):  # pragma: no cover
    """``out += A B^T`` as :func:`_acc` (``transpose_b``, sign 1) computes it, with the terms ``x B[j, l]`` of a zero
    ``B[j, l]`` left out: column ``l`` of `B` is nonzero in the rows ``rows[l, :count[l]]`` (increasing) only. Each
    ``out[i, j]`` receives the same products in the same order (l increasing), less the ones that are zero; adding
    a zero does not change a sum started at +0 (round to nearest never makes -0 of nonzero terms), so the numbers are
    :func:`_acc`'s (for finite `A`). A transition that is nearly the identity (the known states' ``Phi``) then costs
    ``n nnz`` instead of ``n^3``."""
    n, m = A.shape
    for i in range(n):
        for l in range(m):
            x = A[i, l]
            if x == 0.0:
                continue
            for q in range(count[l]):
                j = rows[l, q]
                out[i, j] += x * B[j, l]


@numba.njit(cache=True, nogil=True)
def joint_filter(X, T, Q, H, P0, a, qb, d, out):  # pragma: no cover
    """Kalman whitening of Gauss-Markov plus white noise per axis beside a known linear state
    (:func:`casep._kernels.joint_filter`: the equations); returns ``sum ln det F_r``. The same recursion as
    :func:`casep._kernels.joint_filter_numpy` on ``x = (z, g)`` (n = s + 3 states), in scalar loops: numba compiles
    slice assignments and array expressions slowly (this kernel: 9-15 s of CPU with them, 3 s without)."""
    M, _, k = X.shape
    s = T.shape[1]
    n = s + 3
    P = np.zeros((n, n))
    for i in range(s):
        for j in range(s):
            P[i, j] = P0[i, j]
    m = np.zeros((n, k))
    Phi = np.zeros((n, n))
    rows = np.zeros((n, n), dtype=np.int64)  # Phi's nonzero rows per column (_acc_times_sparse_t)
    count = np.zeros(n, dtype=np.int64)
    Hx = np.zeros((3, n))
    logdet = 0.0
    for r in range(M):
        for i in range(s):
            for j in range(s):
                Phi[i, j] = T[r, i, j]
        for i in range(3):
            for j in range(s):
                Hx[i, j] = H[r, i, j]
        for i in range(3):
            Phi[s + i, s + i] = a[r, i]
            Hx[i, s + i] = 1.0
        for l in range(n):
            c = 0
            for j in range(n):
                if Phi[j, l] != 0.0:
                    rows[l, c] = j
                    c += 1
            count[l] = c
        tmp = np.zeros((n, n))
        _acc(Phi, P, False, 1.0, tmp)
        P = np.zeros((n, n))
        _acc_times_sparse_t(tmp, Phi, rows, count, P)  # Phi P Phi^T
        for i in range(s):
            for j in range(s):
                P[i, j] += Q[r, i, j]
        for i in range(3):
            P[s + i, s + i] += qb[r, i]
        mm = np.zeros((n, k))
        _acc(Phi, m, False, 1.0, mm)
        m = mm
        PH = np.zeros((n, 3))
        _acc(P, Hx, True, 1.0, PH)  # P^- Hx^T
        F = np.zeros((3, 3))
        _acc(Hx, PH, False, 1.0, F)
        L = np.zeros((3, 3))  # F + diag d = L L^T
        for i in range(3):
            for j in range(i + 1):
                v = 0.5 * (F[i, j] + F[j, i]) + (d[i] if i == j else 0.0)
                for l in range(j):
                    v -= L[i, l] * L[j, l]
                if i == j:
                    if not v > 0.0:
                        return np.inf
                    L[i, i] = np.sqrt(v)
                else:
                    L[i, j] = v / L[j, j]
        nu = np.zeros((3, k))
        _acc(Hx, m, False, -1.0, nu)
        for i in range(3):
            for c in range(k):
                nu[i, c] += X[r, i, c]
        W = np.zeros((n, 3))  # P^- Hx^T L^-T: K nu = W u, K F K^T = W W^T
        for i in range(3):  # u = L^-1 nu (in nu), W L^T = P^- Hx^T
            for l in range(i):
                for c in range(k):
                    nu[i, c] -= L[i, l] * nu[l, c]
                for q in range(n):
                    W[q, i] -= L[i, l] * W[q, l]
            for c in range(k):
                nu[i, c] /= L[i, i]
                out[3 * r + i, c] = nu[i, c]
            for q in range(n):
                W[q, i] = (W[q, i] + PH[q, i]) / L[i, i]
            logdet += 2.0 * np.log(L[i, i])
        _acc(W, nu, False, 1.0, m)
        _acc(W, W, True, -1.0, P)
    return logdet


@numba.njit(cache=True, nogil=True)
def _lower_cholesky(G, L, k):  # pragma: no cover
    """``L L^T = G`` (lower, from `G`'s lower triangle) of the leading k x k block by the scalar loops of the
    Cholesky-Banachiewicz order; False where a pivot is not positive (not definite, or NaN), as LAPACK's dpotrf."""
    for i in range(k):
        for j in range(i + 1):
            v = G[i, j]
            for m in range(j):
                v -= L[i, m] * L[j, m]
            if i == j:
                if not v > 0.0:
                    return False
                L[i, i] = np.sqrt(v)
            else:
                L[i, j] = v / L[j, j]
    return True


@numba.njit(cache=True, nogil=True)
def reml_scale_fit(Ms, sc0, N, p, logdets):  # pragma: no cover
    """The axis scales at their REML fixed point from `sc0` and ``-2 l_R`` there: ``(value, scales, ok)``
    (:func:`casep._kernels.reml_scale_fit`: the equations); the steps of :meth:`casep.noise.fit.Reml._scale_steps`
    and the value of :meth:`casep.noise.fit.Reml._value` by scalar loops."""
    k = p + 1
    sc = sc0.copy()
    G = np.empty((k, k))
    L = np.zeros((k, k))
    U = np.zeros((p, p))  # T_p^-1, upper (T = L^T)
    Ginv = np.empty((p, p))
    v = np.empty(k)
    v[p] = -1.0
    rss = np.empty(3)
    new = np.empty(3)
    eps = np.finfo(np.float64).eps
    for _ in range(50):
        w0, w1, w2 = sc[0] ** -2, sc[1] ** -2, sc[2] ** -2
        for i in range(k):
            for j in range(i + 1):
                G[i, j] = w0 * Ms[0, i, j] + w1 * Ms[1, i, j] + w2 * Ms[2, i, j]
        if not _lower_cholesky(G, L, k) or not np.isfinite(L[k - 1, k - 1]):
            return np.inf, sc, False
        for j in range(p):  # U = T_p^-1 column by column (T[i, m] = L[m, i])
            U[j, j] = 1.0 / L[j, j]
            for i in range(j - 1, -1, -1):
                s = 0.0
                for m in range(i + 1, j + 1):
                    s += L[m, i] * U[m, j]
                U[i, j] = -s / L[i, i]
        for i in range(p):  # beta = T_p^-1 T[:p, p]
            s = 0.0
            for m in range(i, p):
                s += U[i, m] * L[p, m]
            v[i] = s
        for i in range(p):  # (Z_w^T Z_w)^-1 = U U^T
            for j in range(i + 1):
                s = 0.0
                for m in range(i, p):
                    s += U[i, m] * U[j, m]
                Ginv[i, j] = s
                Ginv[j, i] = s
        worst = 0.0
        for a in range(3):
            r = 0.0  # ||[Z_a y_a] (beta, -1)||^2
            for i in range(k):
                s = 0.0
                for j in range(k):
                    s += Ms[a, i, j] * v[j]
                r += v[i] * s
            if r < 0.0:
                r = 0.0
            h = 0.0  # the leverage of the axis' rows
            for i in range(p):
                for j in range(p):
                    h += Ms[a, i, j] * Ginv[i, j]
            h /= sc[a] ** 2
            den = N - h
            if den < 1.0:
                den = 1.0
            rss[a] = r
            new[a] = np.sqrt(r / den)  # r_a^2 = RSS_a / (N - h_a)
        for a in range(3):
            if not new[a] > 0.0:
                return np.inf, sc, False
        n0 = new[0]
        for a in range(3):
            new[a] /= n0
            worst = max(worst, Ms[a, p, p] / max(rss[a], 1e-300))
        tol = max(1e-7, 10.0 * eps * worst)
        step = 0.0
        for a in range(3):
            step = max(step, abs(np.log(new[a] / sc[a])))
        for a in range(3):
            sc[a] = new[a]
        if step < tol:
            break
    for i in range(k):  # -2 l_R at the scales (Reml._value)
        for j in range(i + 1):
            G[i, j] = Ms[0, i, j] / sc[0] ** 2 + Ms[1, i, j] / sc[1] ** 2 + Ms[2, i, j] / sc[2] ** 2
    if not _lower_cholesky(G, L, k) or not np.isfinite(L[k - 1, k - 1]):
        return np.inf, sc, True
    r = L[p, p] ** 2
    if not r > 0.0:
        return np.inf, sc, True
    val = (3 * N - p) * np.log(r)
    for i in range(p):
        d = abs(L[i, i])
        if d == 0.0:
            return np.inf, sc, True
        val += 2.0 * np.log(d)
    for a in range(3):
        val += N * np.log(sc[a] ** 2) + logdets[a]
    return val, sc, True
