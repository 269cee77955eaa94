"""Compiled inner loops (numba, ``cache=True``): the sequential parts numpy cannot fuse.

Kept free of Python objects so that numba compiles them in nopython mode; the callers in
:mod:`casep.sv` validate every argument.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["sv_integrate_chunk"]


@numba.njit(cache=True, nogil=True)
def sv_integrate_chunk(G, A, f, half_dt, gcols, acols, phi, G_prev, I_prev, S_prev, out):  # pragma: no cover
    """Trapezoid-integrate one chunk of S_V in place (see :mod:`casep.sv` for the equations).

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
