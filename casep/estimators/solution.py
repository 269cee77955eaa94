"""The solver's coefficient vector of a fit whose data do not determine every coefficient one by one.

With exactly dependent columns (``S N = 0`` for the columns of a null-space basis ``N``) a coefficient is
reported without an estimate (NaN), but the fit still has one least-squares solution ``x`` (the minimum-norm
one of the solver), and every *determined combination* ``g . D`` -- a row ``g`` orthogonal to the null space
(``g N = 0``: ``g`` in the row space of S_V, the classical estimable-function criterion) -- has the same value
``g . x`` and variance ``g C g^T`` in every least-squares solution, ``C`` the solver's (generalised)
covariance. The fitted values are ``S x``; replacing the missing estimates by 0 instead throws away the
determined combination and gives residuals, glitches and a miss that the data do not say.

Every consumer of "the estimate as a vector" (residuals, the robust filter, the checks, impact) reads
:meth:`EstimateResult.fitted_coefficients` and :meth:`Solution.combination`, the one rule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Solution", "DETERMINED_TOL"]

#: A combination ``g`` is determined when its component along the null space is below this fraction of
#: what it would be without cancellation: ``|g N_k| <= DETERMINED_TOL sum_j |g_j N_jk|`` for every null vector.
DETERMINED_TOL = 1e-6


@dataclass(frozen=True)
class Solution:
    """A least-squares solution of a rank-deficient fit (natural units).

    Attributes
    ----------
    x : (n,) ndarray
        The solver's coefficient vector, every entry finite: ``S_V x`` are the fitted values.
    covariance : (n, n) ndarray or None
        The solver's covariance of `x` (``sigma^2 (S^T S)^+`` for least squares): exact for determined
        combinations only.
    null_space : (n, k) ndarray
        A basis of the null space of S_V (``S_V N = 0``), natural units.
    """

    x: np.ndarray
    covariance: np.ndarray | None
    null_space: np.ndarray

    def determined(self, G: np.ndarray) -> np.ndarray:
        """Which rows of `G` (m, n) are determined combinations ``g . D`` (``g N = 0``, see the module notes)."""
        G = np.atleast_2d(np.asarray(G, dtype=float))
        N = np.asarray(self.null_space, dtype=float).reshape(G.shape[1], -1)
        along = np.abs(G @ N)  # the part of g along each null vector
        scale = np.abs(G) @ np.abs(N)  # what it would be without cancellation
        return np.all(along <= DETERMINED_TOL * scale, axis=1)

    def combination(self, G: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """``(G x, G C G^T, determined)`` of the rows of `G` (m, n); a row not determined has value and
        variance NaN (its value depends on which solution, not on the data)."""
        G = np.atleast_2d(np.asarray(G, dtype=float))
        ok = self.determined(G)
        value = np.where(ok, G @ self.x, np.nan)
        cov = None
        if self.covariance is not None:
            cov = G @ self.covariance @ G.T
            cov = 0.5 * (cov + cov.T)
            cov[~ok, :] = np.nan
            cov[:, ~ok] = np.nan
        return value, cov, ok

    def to_dict(self) -> dict[str, Any]:
        """``{"x", "covariance", "null_space"}`` as lists (every number finite)."""
        return {"x": [float(v) for v in self.x],
                "covariance": None if self.covariance is None else np.asarray(self.covariance).tolist(),
                "null_space": np.asarray(self.null_space).tolist()}

    @classmethod
    def from_dict(cls, d: Any, n: int, source: str) -> Solution | None:
        """The solution of a result file (None when the file has none); checked against `n` coefficients."""
        if d is None:
            return None
        try:
            x = np.asarray(d["x"], dtype=float).reshape(n)
            C = None if d.get("covariance") is None else np.asarray(d["covariance"], dtype=float).reshape(n, n)
            N = np.asarray(d["null_space"], dtype=float).reshape(n, -1)
        except (TypeError, KeyError, ValueError, AttributeError) as exc:
            raise ValueError(f"{source}: field `solution` must hold `x` ({n}), `covariance` ({n} x {n}) and "
                             f"`null_space` ({n} x k) numbers ({exc})") from None
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(N)) and (C is None or np.all(np.isfinite(C)))):
            raise ValueError(f"{source}: field `solution` holds a non-finite number")
        return cls(x, C, N)
