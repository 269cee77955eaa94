"""Coarse alignment of tracking and telemetry time tags.

Notes
-----
Tracking time tags late by ``tau`` give ``v_trk(t) = v_true(t - tau)``; telemetry velocity is
``v_tel = v_true + dv`` with a slowly varying instrument-error ``dv``. Lining up the velocities
themselves would be pulled by ``dv`` (by ``mean(a . dv) / mean(|a|^2)``: -63 ms on the paper
scenario), so the coarse offset lines up their *increments* over a lag ``L`` of about 1 s, in
which ``dv`` hardly moves::

    J(tau) = mean_k || [v_tel(t_k+L - tau) - v_tel(t_k - tau)] - [v_trk(t_k+L) - v_trk(t_k)] ||^2

over ``|tau| <= max_offset`` (``v_tel`` a cubic spline of the telemetry samples): a grid search
(at most 200 points, on at most ~400 samples), then Brent's bounded minimisation in the best cell
on all samples. Measured on the paper scenarios (20 Hz, 0.1 m/s noise): offsets of 0, 20 and
300 ms found to within 0.7 ms. The model term ``dt_trk`` (first order: ``dv += a dt_trk``) then
estimates what is left with its Cramer-Rao std; the flight's offset is their sum.

The offset is judged on the tracking epochs the fit uses (:func:`fresh_epochs`): a receiver that holds each 1 Hz
velocity over its 20 Hz epochs lags the vehicle by up to a second between fixes, which the screen leaves out
(:func:`casep.io.pair.stale_epochs`) and which would otherwise read as tags some 400 ms late.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TimeAlignment", "coarse_time_offset", "fresh_epochs", "unaligned_lateness", "late_tags_clause",
           "lateness_left", "LATENESS_Z", "EXPLAIN_GAIN", "EXPLAIN_F", "AUTO_MAX_STD"]

#: A coarse offset "explains" the data when it removes at least this fraction of J(0) ...
EXPLAIN_GAIN = 0.2
#: ... and its F statistic (:attr:`TimeAlignment.f_statistic`, chi-square 1 dof without an offset)
#: exceeds this (P(chi2_1 > 25) ~ 6e-7).
EXPLAIN_F = 25.0
#: ``time_offset="auto"`` applies the coarse offset only when its std (:attr:`TimeAlignment.std`) is below this
#: fraction of the tracking sample period: beyond it the record barely determines the offset (no acceleration to
#: line up, a vehicle at rest), and a shift anywhere in the search range would be noise.
AUTO_MAX_STD = 0.25


@dataclass(frozen=True)
class TimeAlignment:
    """The coarse offset ``tau`` (s; tracking tags late by it), the cost ``J`` at it and at zero
    (m^2/s^2, of velocity increments), the tracking sample period (s) and the samples used."""

    tau: float
    cost: float
    cost_at_zero: float
    tracking_period: float
    samples: int
    std: float = np.inf  # s: the least-squares std of tau for white tracking noise (coarse_time_offset)

    @property
    def gain(self) -> float:
        """Fraction of the unshifted misfit the shift removes: ``1 - J(tau) / J(0)``."""
        return float(1.0 - self.cost / self.cost_at_zero) if self.cost_at_zero > 0 else 0.0

    @property
    def f_statistic(self) -> float:
        """``(J(0) - J(tau)) / J(tau) * n_eff``: the misfit the shift removes against what is left, with
        ``n_eff = samples / lag`` independent increments (increments over a lag of about 1 s overlap);
        about chi-square with 1 dof when there is no offset."""
        lag = max(1, round(1.0 / self.tracking_period)) if np.isfinite(self.tracking_period) else 1
        n_eff = max(self.samples / lag, 1.0)
        return float((self.cost_at_zero - self.cost) / self.cost * n_eff) if self.cost > 0 else np.inf

    @property
    def explains(self) -> bool:
        """The shift explains the data: it removes at least :data:`EXPLAIN_GAIN` of the misfit of the
        velocity increments and its F statistic exceeds :data:`EXPLAIN_F`. A wrong launch site or
        azimuth leaves a misfit no shift removes (measured: 0.0001-0.3 % removed), a real offset of
        60-300 ms at 5-20 Hz tracking removes 32-92 %."""
        return self.gain >= EXPLAIN_GAIN and self.f_statistic >= EXPLAIN_F

    @property
    def exceeds_period(self) -> bool:
        """``|tau|`` larger than one tracking sample period."""
        return abs(self.tau) > self.tracking_period

    def to_dict(self) -> dict:
        return {"tau_s": self.tau, "cost": self.cost, "cost_at_zero": self.cost_at_zero,
                "tracking_period_s": self.tracking_period, "samples": self.samples, "gain": self.gain,
                "f_statistic": self.f_statistic if np.isfinite(self.f_statistic) else None, "explains": self.explains,
                "exceeds_period": self.exceeds_period, "std_s": self.std if np.isfinite(self.std) else None}


def unaligned_lateness(record: dict | None) -> float | None:
    """The tracking tags' coarse lateness, s, that a pair left in place (no ``time_offset`` given) although it
    exceeds a tracking sample period and explains the data (:attr:`TimeAlignment.exceeds_period`,
    :attr:`TimeAlignment.explains`): the reader's warning, and what a fit that then fails says of its cause (a
    first-order ``dt_trk`` does not take it). `record`: ``meta["time_alignment"]`` (:meth:`TimeAlignment.to_dict`
    with the reader's ``mode``). None otherwise."""
    if not record or record.get("mode") != "none" or not record.get("explains") or not record.get("exceeds_period"):
        return None
    return float(record["tau_s"])


def late_tags_clause(record: dict | None) -> str:
    """What a result says of tracking time tags the pair found late by more than a sample period and left in place
    (:func:`unaligned_lateness`); else ''."""
    tau = unaligned_lateness(record)
    if tau is None:
        return ""
    assert record is not None
    return (f"the tracking time tags look {tau * 1e3:.1f} ms late (said when the pair was read), more than a "
            f"tracking sample period ({record['tracking_period_s'] * 1e3:.4g} ms), which a first-order dt_trk does "
            "not take: align them (--time-offset auto) and separate again")


#: The fit's tracking offset (``dt_trk``) accounts for a lateness left in place when it is within this many std
#: (its own and the coarse offset's, combined) of it (:func:`lateness_left`).
LATENESS_Z = 3.0


def lateness_left(record: dict | None, offset_s: float | None, offset_std_s: float | None) -> str | None:
    """Why a fit's result is probably wrong because the pair's tracking tags are late by more than a sample period,
    left in place (:func:`unaligned_lateness`) and not taken by the fit: its tracking offset `offset_s` (the
    estimated ``dt_trk`` including any re-pairing, s; None without that term: 0) differs from the lateness by more
    than :data:`LATENESS_Z` std (`offset_std_s` and the coarse offset's ``std_s`` combined). None otherwise."""
    tau = unaligned_lateness(record)
    if tau is None:
        return None
    assert record is not None
    dt = float(offset_s) if offset_s is not None else 0.0
    have = offset_s is not None and bool(np.isfinite(dt))
    own = float(offset_std_s) if have and offset_std_s is not None and np.isfinite(offset_std_s) else 0.0
    sd = float(np.hypot(own, record.get("std_s") or 0.0))
    if have and abs(dt - tau) <= LATENESS_Z * sd:
        return None
    fit = (f"the fit's dt_trk {dt * 1e3:.4g} +- {own * 1e3:.2g} ms is {abs(dt - tau) / sd:.3g} std "
           "from it" if have and sd > 0 else "the fit has no dt_trk to take it")
    return f"{late_tags_clause(record)} ({fit}: the estimates absorb the rest)"


def fresh_epochs(t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, v_trk: np.ndarray,
                 repeated: np.ndarray, frozen: np.ndarray | None = None,
                 r_trk: np.ndarray | None = None, rest: list[float] | None = None) -> np.ndarray:
    """The tracking epochs not stale, (M,) bool: :func:`casep.io.pair.stale_epochs` (the screen's
    rule, with the telemetry's velocity change ``v_tel`` itself, a cubic spline at the tracking times) on the
    unshifted tags; `repeated` (M,) bool: the epochs whose file row repeats the previous one's velocity; `frozen`
    (M,) bool and `r_trk` (M, 3), an Earth-fixed file's: the epochs whose row repeats the previous one's position,
    and the tracked launch-inertial positions (m; :func:`casep.io.pair.position_gap`); `rest` ``[T1, T2]`` s, the
    window the telemetry was levelled over. Epochs outside the telemetry's span are kept
    (:func:`coarse_time_offset` does not use them)."""
    from scipy.interpolate import CubicSpline

    from casep.io.pair import position_gap, stale_epochs

    t_tel, t_trk = np.asarray(t_tel, dtype=float), np.asarray(t_trk, dtype=float)
    fresh = np.ones(t_trk.size, bool)
    inside = np.flatnonzero((t_trk >= t_tel[0]) & (t_trk <= t_tel[-1]))
    if inside.size < 3:
        return fresh
    V = CubicSpline(t_tel, np.asarray(v_tel, dtype=float), axis=0)(t_trk[inside])
    gap = None if frozen is None or r_trk is None else position_gap(t_tel, v_tel, t_trk, r_trk)[inside]
    fresh[inside] = ~stale_epochs(t_trk[inside], V, V - np.asarray(v_trk, dtype=float)[inside],
                                  np.asarray(repeated, bool)[inside],
                                  None if gap is None else np.asarray(frozen, bool)[inside], gap, rest)
    return fresh


def coarse_time_offset(t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, v_trk: np.ndarray, *,
                       max_offset: float = 2.0) -> TimeAlignment:
    """The tracking-telemetry time offset that best lines up the two velocities (module notes).

    Parameters
    ----------
    t_tel, v_tel : (N,), (N, 3) arrays
        Telemetry times (s, increasing) and velocity (m/s).
    t_trk, v_trk : (M,), (M, 3) arrays
        Tracking times (s, increasing) and velocity (m/s).
    max_offset : float, optional
        Search ``|tau| <= max_offset`` s (default 2).

    Returns
    -------
    TimeAlignment
    """
    from scipy.interpolate import CubicSpline
    from scipy.optimize import minimize_scalar

    t_tel, t_trk = np.asarray(t_tel, dtype=float), np.asarray(t_trk, dtype=float)
    v_tel, v_trk = np.asarray(v_tel, dtype=float), np.asarray(v_trk, dtype=float)
    if not (np.isfinite(max_offset) and max_offset > 0):
        raise ValueError(f"`max_offset` must be finite and > 0 s, got {max_offset}")
    spline = CubicSpline(t_tel, v_tel, axis=0)
    use = (t_trk - max_offset >= t_tel[0]) & (t_trk + max_offset <= t_tel[-1])  # v_tel(t - tau) defined
    if use.sum() < 4:
        raise ValueError(f"fewer than 4 tracking samples lie {max_offset:g} s inside the telemetry span: "
                         "cannot align the time tags (reduce max_offset)")
    tt, vv = t_trk[use], v_trk[use]
    period = float(np.median(np.diff(t_trk))) if t_trk.size > 1 else np.inf
    lag = int(min(max(1, round(1.0 / period)), tt.size - 1)) if np.isfinite(period) else 1  # about 1 s
    dvv = vv[lag:] - vv[:-lag]  # tracking velocity increments over the lag

    def cost(tau: float, every: int = 1) -> float:  # J(tau): increments of v_tel(t - tau) against v_trk's
        v = spline(tt - tau)
        return float(np.mean(np.sum((v[lag:] - v[:-lag] - dvv)[::every] ** 2, axis=1)))

    step = max(float(np.median(np.diff(t_tel))), max_offset / 100)  # J is a smooth bowl: ~200 grid points
    grid = np.arange(-np.floor(max_offset / step), np.floor(max_offset / step) + 1) * step
    every = max(1, tt.size // 400)  # the grid search on at most ~400 samples; the refinement on all
    J = np.array([cost(g, every) for g in grid])
    k = int(np.argmin(J))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    best = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7 * max(step, 1e-3)})
    tau = float(best.x) if best.fun <= cost(float(grid[k])) else float(grid[k])
    j_min = cost(tau)
    return TimeAlignment(tau, j_min, cost(0.0), period, int(use.sum()), _tau_std(spline, tt, tau, lag, j_min))


def _tau_std(spline, tt: np.ndarray, tau: float, lag: int, J: float) -> float:
    """Std of the offset that minimises ``J`` (module notes), s, for white tracking noise of variance ``J / 6``
    per axis (each increment's component ``e_k+L - e_k``: twice that; three axes).

    Linearised at ``tau``: the increment's derivative ``g_k = -[a(t_k+L - tau) - a(t_k - tau)]``, and
    ``tau^ - tau = sum_k g_k . (e_k+L - e_k) / sum_k |g_k|^2 = sum_j c_j . e_j / sum_k |g_k|^2`` with
    ``c_j = g_j-L - g_j``: ``Var = sigma^2 sum_j |c_j|^2 / (sum_k |g_k|^2)^2``. Infinite when the velocity
    increments do not change with the offset (no acceleration: a vehicle at rest)."""
    acc = spline.derivative()(tt - tau)
    g = -(acc[lag:] - acc[:-lag])
    c = np.zeros_like(acc)
    c[lag:] += g
    c[:-lag] -= g
    gg = float(np.sum(g**2))
    return float(np.sqrt(J / 6.0 * np.sum(c**2)) / gg) if gg > 0 else np.inf
