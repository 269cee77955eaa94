"""Outliers by externally studentized residuals of the least-squares fit.

Notes
-----
With the regression ``y = S D + e`` (m rows, rank p), least-squares residuals ``r_i`` and
leverages ``h_i`` (the diagonal of the hat matrix ``S S^+``), the externally studentized residual
of row i is::

    s_(i)^2 = (RSS - r_i^2 / (1 - h_i)) / (m - p - 1)      (sigma^2 without row i)
    t_i     = r_i / (s_(i) sqrt(1 - h_i))                  ~ t(m - p - 1) for white Gaussian noise

Leverages come from the reduction without forming the hat matrix: with column-scaled rows
``Z = S diag(1/c)`` and the SVD of the reduced ``R = U diag(s) V^T`` (rank r),
``h_i = || Z_i V_r diag(1/s_r) ||^2``. A row is flagged when ``|t_i|`` exceeds the two-sided
``rate`` quantile; the default ``rate = alpha / m`` (Bonferroni) makes the chance of any false
flag in a clean flight at most ``alpha``. The test assumes white noise: with correlated noise
use the spike check of :func:`casep.checks.plausibility.check_fit`, and the robust estimator
(``--method huber``) to estimate with outliers in.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from scipy import stats

from casep.regression.linalg import least_squares_rss
from casep.results import Completed, deprecated_alias

__all__ = ["OutlierFlags", "studentized_residuals", "flag_outliers"]


def studentized_residuals(problem, rcond: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Externally studentized residuals of a problem's least-squares fit (module notes).

    Parameters
    ----------
    problem : casep.Problem
        With rows (built from a flight or arrays).

    Returns
    -------
    (t, r, h, dof)
        ``t``, the residuals ``r`` (m/s) and the leverages ``h`` in the shape of the problem's ``y``
        (e.g. (N, 3)); ``dof = m - p - 1``.
    """
    red = problem.red
    ra = problem.rank(rcond)
    r = ra.rank
    c = np.where(red.scale > 0, red.scale, 1.0)
    W = ra.Vt[:r].T / ra.s[:r]  # V_r diag(1/s_r), scaled coordinates
    x = (W @ (ra.U[:, :r].T @ red.qty)) / c  # least-squares D (natural units)
    y = problem.y
    res = np.empty(y.shape)
    h = np.empty(y.shape)
    n = red.n
    for sl, S_b, y_b in problem.blocks():
        Z = S_b.reshape(-1, n) / c  # column-scaled rows
        h[sl] = np.sum((Z @ W) ** 2, axis=1).reshape(y_b.shape)  # h_i = ||Z_i V_r / s_r||^2
        res[sl] = y_b - S_b @ x
    dof = int(red.m - r - 1)
    if dof < 1:
        raise ValueError(f"{red.m} rows and rank {r}: no degree of freedom left to studentize")
    rss = least_squares_rss(red, ra)
    one_h = np.clip(1.0 - h, 1e-12, None)
    s2_i = np.clip((rss - res**2 / one_h) / dof, 1e-300, None)  # sigma^2 without row i
    return res / np.sqrt(s2_i * one_h), res, h, dof


@dataclass(frozen=True)
class OutlierFlags(Completed):
    """Rows flagged by their studentized residual.

    Attributes
    ----------
    rows : list of dict
        ``{"sample", "t", "axis", "t_value", "residual"}`` (sample index, its time s, axis,
        studentized residual, residual m/s), largest ``|t_value|`` first.
    threshold : float
        ``|t|`` above which a row is flagged.
    rate : float
        Per-row false-alarm probability of that threshold.
    rows_tested : int
    """

    what: ClassVar[str] = "outlier flags (studentized residuals)"

    rows: list = field(default_factory=list)
    threshold: float = np.inf
    rate: float = 0.0
    rows_tested: int = 0

    @property
    def count(self) -> int:
        return len(self.rows)

    @property
    def expected_false(self) -> float:
        """Flags expected from white noise alone: rate x rows."""
        return self.rate * self.rows_tested

    summary = deprecated_alias("text", "summary")

    def text(self, top: int = 5) -> str:
        """The flagged rows (the `top` largest named, with file line and time) in one paragraph."""
        head = (f"{self.count} row(s) with studentized residual |t| > {self.threshold:.3g} (false-alarm rate "
                f"{self.rate:.2g} per row: {self.expected_false:.2g} expected from white noise)")
        if not self.rows:
            return head
        rows = "; ".join(f"{r.get('where') or 'sample %d (t = %.6g s)' % (r['sample'] + 1, r['t'])} dv_{r['axis']} "
                         f"{r['residual']:+.3g} m/s, t {r['t_value']:+.3g}" for r in self.rows[:top])
        more = f" and {self.count - top} more" if self.count > top else ""
        return (f"{head}: {rows}{more}. Remove them (--exclude-outliers), fit robustly (--robust) or estimate with "
                "--method huber")

    def to_dict(self) -> dict:
        return {"count": self.count, "threshold": self.threshold, "rate": self.rate, "rows_tested": self.rows_tested,
                "expected_false": self.expected_false, "rows": self.rows}


def flag_outliers(problem, *, alpha: float = 0.01, rate: float | None = None,
                  rcond: float | None = None) -> OutlierFlags:
    """Flag rows whose externally studentized residual exceeds a threshold (module notes).

    Parameters
    ----------
    problem : casep.Problem
    alpha : float, optional
        Chance of any false flag in a clean flight (default 0.01): ``rate = alpha / m``.
    rate : float, optional
        Per-row false-alarm probability instead (two-sided).
    """
    if not (0 < alpha < 1):
        raise ValueError(f"`alpha` must be in (0, 1), got {alpha}")
    t_val, resid, _, dof = studentized_residuals(problem, rcond)
    m = t_val.size
    rate = alpha / m if rate is None else float(rate)
    if not (0 < rate < 1):
        raise ValueError(f"`rate` must be in (0, 1), got {rate}")
    thr = float(stats.t.isf(rate / 2, dof))
    tv = t_val.reshape(-1, 3) if t_val.ndim == 2 and t_val.shape[-1] == 3 else t_val.reshape(-1, 1)
    rv = resid.reshape(tv.shape)
    have_t = problem.t is not None and len(problem.t) == tv.shape[0]
    times = problem.t if have_t else np.arange(tv.shape[0], dtype=float)
    rows: list[dict[str, Any]] = [
        {"sample": int(k), "t": float(times[k]), "axis": "xyz"[i] if tv.shape[1] == 3 else "-",
         "t_value": float(tv[k, i]), "residual": float(rv[k, i])} for k, i in np.argwhere(np.abs(tv) > thr)]
    rows.sort(key=lambda r: -abs(r["t_value"]))
    _add_locations(problem, rows)
    return OutlierFlags(rows, thr, rate, m)


def _add_locations(problem, rows: list[dict], top: int = 200) -> None:
    """File, line and a printable place of the first `top` rows (:meth:`casep.Problem.locate`)."""
    locate = getattr(problem, "locate", None)
    if locate is None or not rows:
        return
    from casep.io.locate import where

    for r, loc in zip(rows[:top], locate([r["sample"] for r in rows[:top]])):
        r.update(file=loc["file"], line=loc["line"], where=where(loc))
