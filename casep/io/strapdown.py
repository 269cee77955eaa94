"""Strapdown telemetry at the edge: the attitude, body specific force and body rate columns, checked.

Columns (:data:`casep.model.strapdown.STRAPDOWN_COLUMNS`): ``q_w, q_x, q_y, q_z`` the INS attitude
(Hamilton quaternion, scalar first, rotating body vectors into the navigation frame, casep's
launch-inertial frame), ``fb_x, fb_y, fb_z`` the measured body specific force (m/s^2) and ``w_x, w_y,
w_z`` the measured body rate (rad/s). A flight file without ``f_*`` (and ``W_*``) gets its
navigation-frame specific force from them, ``f = C(q) fb`` (:func:`strapdown_force`).

Checks, each naming the file, the columns, the rows and the numbers:

- **unit quaternions**: ``| |q| - 1 | <= 1e-6`` in every row (:data:`NORM_TOL`), else an error at the
  first row off, with how many rows are off and the worst;
- **sign flips**: q and -q are the same attitude; a step where ``q_{k-1} . q_k < 0`` is a flip, counted
  (``meta["strapdown"]["sign_flips"]``) and removed before the comparison below (C(q) does not see it);
- **attitude against the integrated body rate**: the rotation between consecutive quaternions in body
  axes, ``rotvec(C_{k-1}^T C_k)``, against the rotation vector a strapdown navigator forms from ``w``
  over the step (:func:`casep.rotations.rotation_increments`: the fourth-order integral of ``w`` plus
  the coning term, casep's own navigator's, so its output agrees to rounding; a trapezoid would differ
  by tens of per cent on vibrating 100 Hz data, whose rate changes within a step), or, when that fits
  better, ``w`` read as each step's mean rate written at its end (a navigator of angle increments
  writing ``dtheta / step``: :data:`RATE_READINGS`). Their RMS difference
  relative to the RMS step rotation above :data:`RATE_TOL` (5 %) is a :class:`StrapdownWarning` with its
  size (deg/s) and the worst row, unless one explanation fits, which is an error saying so, or the
  disagreement is systematic, an error too: the gain ``G`` with ``rv ~ G inc + b dt`` (a bias ``b``
  allowed; fitted as ``inc ~ H rv + c dt``, ``G = H^-1``, so that noise in the written rate does not pull
  it towards 0) departing from the identity by more than :data:`GAIN_TOL` (5 %) in an element
  determined beyond :data:`GAIN_Z` std
  (the rates times 3, an axis negated, two axes swapped, times 1.1: the INS integrated other rates than
  the file's ``w``, whose sensor errors it shares; a model fitted on them gets the gyro terms wrong):

  * ``w`` in deg/s: the quaternions turn by 1/57.3 of the integrated rate (multiply by pi/180);
  * the other quaternion conventions: scalar last (the columns hold x, y, z, w), or
    navigation-to-body (the conjugate), or both: the integrated rate agrees with the quaternions
    read that way.

  A flight that turns by less than :data:`MIN_ROTATION` in all gets no comparison (nothing to see).

  A disagreement that coincides with a clipped gyro is no axis, sign or factor: when the comparison
  disagrees and body-rate readings are held at a full scale (:func:`casep.fullscale.held_full_scale`,
  the saturation rule of calibration, navigation and the telemetry's screen; no declared full scale
  is known here), the steps those readings reach (:data:`CLIP_REACH`) are left out and the rest is
  compared again: agreeing, it is a warning that the gyro clipped (column, value, full scale, rows,
  times: the INS's attitude followed the motion, the written rate did not; ``meta["strapdown"]
  ["rate_clipped"]``); disagreeing, the finding above on the rest, saying the clip was left out.

  The body rate's steps between samples (:func:`casep.io.flight.signal_steps`, the IMU record's rule: a pitch
  kick, a roll programme switched on) and the steps next to them are left out of the comparison
  (:func:`_rate_steps`: the integrated rate rings across a step). A time skew of the attitude against the rate
  shows only where the rate changes from step to step: when the two agree, the skew the compared steps tell and
  its std (:func:`_skew_std`); a std beyond :data:`SKEW_STD_MAX` samples is a :class:`StrapdownWarning` that the
  skew is not checked (with the std, the steps used, any rate step left out). When they disagree and agree at a
  skew (:func:`_lag_agreement`, on pairs of steps that reach across no step left out) the error names it, or the
  range of skews at which they agree when the record cannot tell it closer.

- **velocity against the specific force** (files with ``v_tel_*``): the INS's velocity is the integral of
  ``C(q) fb + g``; over windows of :data:`KINEMATIC_WINDOW` the misfit ``(v_tel(b) - v_tel(a) - int_a^b
  (C(q) fb + g) dt) / (b - a)`` turned into body axes (the attitude at the window's middle), its median over
  the windows per body axis: beyond :data:`KINEMATIC_LIMIT` an error naming the ``fb_*`` column (``fb`` in g,
  an offset of g in a column, a column that is not the INS's), beyond :data:`KINEMATIC_WARN` a warning
  (:func:`check_kinematics`).

A body-rate peak above :data:`RATE_PEAK_HIGH` is a warning (deg/s?); so are ``f_*`` columns beside the
strapdown ones that differ from ``C(q) fb`` by more than :data:`FORCE_TOL` (1 %) RMS. The specific force's units are
checked on the computed ``f`` by :func:`casep.checks.plausibility.check_flight`, which names the ``fb_*`` columns:
a peak below :data:`casep.checks.plausibility.F_AT_REST` g that read in g exceeds 1 g is ``fb`` in g, an error
(its accelerometers read g at rest and in level flight).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.exceptions import PlausibilityWarning
from casep.fullscale import held_full_scale, held_mask
from casep.gravity import kinematic_acceleration
from casep.io.flight import LOST_SAMPLE_FACTOR, FlightDataError, gap_steps, signal_steps, time_unit_factors
from casep.rotations import (
    increments_from_deltas,
    quat_conjugate,
    quat_multiply,
    quat_to_dcm,
    quat_to_rotvec,
    rotation_increments,
)
from casep.units import G0, MEMS_ACCEL_BIAS, RATE_UNIT_MISTAKES, unit_factorisation, unit_mistakes

__all__ = ["StrapdownWarning", "strapdown_force", "lost_rows_problem", "GAP_TURN_LIMIT",
           "check_strapdown", "compare_force", "FORCE_TOL", "check_kinematics",
           "KINEMATIC_WINDOW", "KINEMATIC_LIMIT", "KINEMATIC_WARN",
           "quaternion_dcm_array", "clock_stretch", "STRETCH_STEP",
           "RATE_READINGS", "NORM_TOL", "CLIP_REACH", "RATE_TOL", "GAIN_TOL", "GAIN_Z",
           "SKEW_STD_MAX", "MAX_LAG", "MIN_ROTATION", "RATE_PEAK_HIGH",
           "CONVENTIONS", "STRAPDOWN_COLUMNS", "QUATERNION_COLUMNS", "BODY_FORCE_COLUMNS", "BODY_RATE_COLUMNS"]

#: The scale the gravity gradient's part of :func:`clock_stretch` is differenced at (100 ppm: a position error of
#: metres to tens of metres, where the gradient is linear).
STRETCH_STEP = 1e-4
#: The strapdown telemetry columns (``docs/reference/file-formats.md``): the INS attitude (Hamilton unit
#: quaternion, scalar first, body to navigation frame), the body specific force (m/s^2), the body rate (rad/s).
QUATERNION_COLUMNS = ("q_w", "q_x", "q_y", "q_z")
BODY_FORCE_COLUMNS = ("fb_x", "fb_y", "fb_z")
BODY_RATE_COLUMNS = ("w_x", "w_y", "w_z")
#: The columns of a strapdown flight beside t and the velocities.
STRAPDOWN_COLUMNS = QUATERNION_COLUMNS + BODY_FORCE_COLUMNS + BODY_RATE_COLUMNS

#: Largest accepted | |q| - 1 |.
NORM_TOL = 1e-6
#: RMS disagreement between the quaternion steps and the integrated rate, relative to the RMS step, above
#: which the attitude and the body rate disagree (5 %: far above the integration's error on a rate that is
#: smooth over a few samples).
RATE_TOL = 0.05
#: The systematic part of a disagreement, ``max |G_ij - I_ij|`` with ``G`` the gain that maps the integrated
#: rate onto the quaternion steps (its elements determined beyond GAIN_Z std), above which it is an error.
#: The INS integrates its own measured rate, so its sensor errors are in both columns alike and cancel:
#: only a compensation the INS applies to its readings before integrating them (a calibrated scale factor
#: and misalignment: a few per cent for the cheapest MEMS gyros) or a mistake in the file makes G differ
#: from the identity. 5 %: beyond any such compensation; a noise-like disagreement (rates decimated from a
#: faster navigator) leaves G at I.
GAIN_TOL = 0.05
#: An element of G is judged when it departs from the identity by this many of its std (its axis turned enough).
GAIN_Z = 5.0
#: Total rotation (rad, sum of the step angles) below which the attitude is not compared with the rate.
MIN_ROTATION = 0.05
#: Body-rate peak, rad/s, above which a rate is implausible for a vehicle (20 rev/s spin ~ 126 rad/s).
RATE_PEAK_HIGH = 200.0
_DEG = np.pi / 180.0


class StrapdownWarning(PlausibilityWarning):
    """The strapdown columns are suspicious: the attitude disagrees with the integrated body rate."""


def _as_scalar_last(q: np.ndarray) -> np.ndarray:
    """The quaternions if the columns ``q_w, q_x, q_y, q_z`` held ``x, y, z, w``: scalar first again."""
    return q[:, [3, 0, 1, 2]]


#: Readings of the quaternion columns the rate comparison tries, name -> transform to the declared one.
CONVENTIONS = {
    "as declared (Hamilton, scalar first, body to navigation)": lambda q: q,
    "scalar last (the columns q_w, q_x, q_y, q_z hold x, y, z, w)": _as_scalar_last,
    "navigation to body (the conjugate of the declared one)": quat_conjugate,
    "scalar last and navigation to body": lambda q: quat_conjugate(_as_scalar_last(q)),
}


def _held_rate_increments(t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rotation vectors (rad, (N-1, 3)) of rates that are each step's mean, written at its end: increments / step.

    ``dtheta_k = w_k (t_k - t_{k-1})`` with Ignagni's coning (:func:`casep.rotations.increments_from_deltas`):
    what a navigator integrating angle increments steps by, when it writes ``w = dtheta / step``.
    """
    inc = increments_from_deltas(w[1:] * np.diff(t)[:, None], np.zeros((t.size - 1, 3)))
    return inc.dtheta + inc.coning


#: Readings of the body-rate columns the comparison tries, name -> rotation vectors of the steps: a
#: navigator steps by the integral of sampled rates, or by angle increments it writes as ``dtheta / step``.
RATE_READINGS = {
    "samples of the body rate": rotation_increments,
    "each step's mean rate at its end (angle increments / step)": _held_rate_increments,
}


def quaternion_dcm_array(q: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` body-to-navigation matrices of ``(N, 4)`` Hamilton unit quaternions (scalar first)."""
    return quat_to_dcm(q)


def clock_stretch(t: np.ndarray, q: np.ndarray, fb: np.ndarray, w: np.ndarray, v: np.ndarray,
                  r: np.ndarray | None = None, gravitation: Any = None) -> np.ndarray:
    """``(N, 3)`` the velocity error, m/s per unit of scale, of an INS that integrated its samples over steps
    ``(1 + d)`` times the true ones (its clock running fast by ``d``), at its own time tags: ``d`` times this.

    Every integrated quantity is scaled by ``1 + d``: the specific force's and the gravitation's integral, the
    velocity from the INS's start, ``v - v(t_0)`` (`v` (N, 3) the telemetry velocity, its first row the start),
    and the attitude, a common gyro scale factor ``d``: ``phi = -d int C w dt``, whose velocity error is
    ``int f_nav x phi dt`` (the strapdown model's ``phidot = -C delta_w``, ``dv_dot = C delta_f + f_nav x phi``,
    ``f_nav = C fb``). Trapezoids over the telemetry's samples `t` (s); `q` (N, 4) Hamilton, scalar first, body to
    navigation; `fb` (N, 3) m/s^2, `w` (N, 3) rad/s. The INS's states are also ``d t`` late against true time,
    which is the time tags' drift, not this.

    With the INS's positions `r` (N, 3, launch-inertial, m) and its `gravitation` ``(t, r) -> (N, 3)``
    (:func:`casep.gravity.launch_gravitation`), the INS's position error ``d int E dt`` is carried through the
    gravitation too, ``int [G(r + d int E) - G(r)] dt`` (the gravity gradient: on the simulated 195 s strapdown boost
    at 80 ppm, 0.05 m/s vertically, 2/3 of what ``E`` without it missed); a difference at
    :data:`STRETCH_STEP` of scale, divided by it."""
    t, v = np.asarray(t, dtype=float), np.asarray(v, dtype=float)
    C = quaternion_dcm_array(np.asarray(q, dtype=float))

    def integral(x: np.ndarray) -> np.ndarray:  # 0 at the first sample
        return cumulative_trapezoid(x, t)

    phi = -integral(np.einsum("nij,nj->ni", C, np.asarray(w, dtype=float)))
    f_nav = np.einsum("nij,nj->ni", C, np.asarray(fb, dtype=float))
    E = v - v[0] + integral(np.cross(f_nav, phi))
    if r is None or gravitation is None:
        return E
    r = np.asarray(r, dtype=float)
    dr = STRETCH_STEP * integral(E)
    return E + integral(np.asarray(gravitation(t, r + dr)) - np.asarray(gravitation(t, r))) / STRETCH_STEP


def _step_rotations(q: np.ndarray) -> np.ndarray:
    """``(N-1, 3)`` rotation vectors of ``C_{k-1}^T C_k`` (body axes), rad: ``log(q_{k-1}* (x) q_k) * 2``."""
    return quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:]))


def _mismatch(rv: np.ndarray, inc: np.ndarray) -> float:
    """RMS of ``|rv - inc|`` relative to the RMS of ``|inc|``."""
    return float(np.sqrt(np.mean(np.sum((rv - inc) ** 2, axis=1)) / np.mean(np.sum(inc**2, axis=1))))


def _fits(steps: dict[str, np.ndarray], inc: np.ndarray) -> dict[str, dict[str, float]]:
    """Mismatch of each reading's quaternion steps with the rate's rotation vectors `inc`, and the scale that fits."""
    fits = {}
    for name, rv in steps.items():
        scale = float(np.sum(rv * inc) / np.sum(inc * inc))  # quaternion turn per unit of integrated rate
        fits[name] = {"mismatch": _mismatch(rv, inc), "scale": scale,
                      "scaled_mismatch": _mismatch(rv, scale * inc) if scale > 0 else np.inf}
    return fits


def _rate_evidence(t: np.ndarray, q: np.ndarray, w: np.ndarray, keep: np.ndarray | None = None) -> dict[str, Any]:
    """How well each reading of the quaternions (:data:`CONVENTIONS`) matches the integrated rate.

    The rate is read the way of :data:`RATE_READINGS` under which some reading of the quaternions
    (scaled or not) fits best. `keep` ((N-1,) bool): the steps compared (default all); rows and times stay the
    file's. When they disagree, the skew at which they agree (``lag``, :func:`_lag_agreement`); when they agree,
    the skew they tell and its std (``skew``, :func:`_skew_std`).
    """
    dt_all = np.diff(t)
    keep = np.ones(dt_all.size, bool) if keep is None else keep
    inc = rotation_increments(t, w)[keep]  # the navigator's dtheta + coning of each step, rad
    total = float(np.sum(np.linalg.norm(inc, axis=1)))
    out: dict[str, Any] = {"rotation_rad": total, "rows": int(t.size)}
    if total < MIN_ROTATION or t.size < 3 or keep.sum() < 2:
        return out
    every = {name: _step_rotations(transform(q)) for name, transform in CONVENTIONS.items()}
    steps = {name: rv[keep] for name, rv in every.items()}
    step_index = np.flatnonzero(keep)  # step i of the comparison: the file's rows step_index[i] + 1, + 2
    dt = dt_all[keep]
    best: tuple[float, str, np.ndarray, dict[str, dict[str, float]]] | None = None
    for reading, rotation_vectors in RATE_READINGS.items():
        inc = rotation_vectors(t, w)[keep]
        fits = _fits(steps, inc)
        fit = min(min(f["mismatch"], f["scaled_mismatch"]) for f in fits.values())
        if best is None or fit < best[0]:
            best = (fit, reading, inc, fits)
    assert best is not None
    _, reading, inc, fits = best
    rv = steps[next(iter(CONVENTIONS))]
    err = np.linalg.norm(rv - inc, axis=1) / dt  # rad/s per step
    gain, bias, systematic = _rate_gain(rv, inc, dt)
    worst = int(step_index[int(np.argmax(err))])
    out.update(fits=fits, rate_reading=reading, rms_rate_error_rad_s=float(np.sqrt(np.mean(err**2))),
               worst_row=worst + 2, worst_t=float(t[worst + 1]),
               worst_rate_error_rad_s=float(err.max()), rms_rate_rad_s=float(np.sqrt(np.mean(np.sum(w**2, 1)))),
               rate_gain=[[float(x) if np.isfinite(x) else None for x in row] for row in gain],
               rate_bias_rad_s=bias.tolist(), systematic=systematic, steps_compared=int(keep.sum()))
    rv_all = every[next(iter(CONVENTIONS))]
    if not _agrees(out):  # a time skew between q and w: a lag at which they agree
        lag = _lag_agreement(t, w, rv_all, keep)
        if lag is not None:
            out["lag"] = lag
    else:
        out["skew"] = {**_skew_std(t, w, rv_all, keep, RATE_READINGS[reading]), "sample_s": float(np.median(dt))}
    return out


#: Samples of skew between the attitude and the body rate tried when they disagree (:func:`_lag_agreement`).
MAX_LAG = 3


def _pairs(keep: np.ndarray, k: int) -> np.ndarray:
    """The rate's steps ``i`` paired with the attitude's step ``i + k`` (``k > 0``: the attitude ``k`` samples late)
    whose steps from ``i`` to ``i + k`` are all compared (`keep`: no pair reaches across a step left out, a gap or a
    rate step)."""
    out = np.concatenate([[0], np.cumsum(~keep)])  # out[b] - out[a]: steps a..b-1 left out
    i = np.arange(max(0, -k), keep.size - max(0, k))
    return i[out[np.maximum(i, i + k) + 1] - out[np.minimum(i, i + k)] == 0]


def _lagged(rv: np.ndarray, inc: np.ndarray, dt: np.ndarray, keep: np.ndarray,
            k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step ``i + k`` of the attitude `rv` against step ``i`` of the rate `inc` over the pairs of :func:`_pairs`;
    ``(rv, inc, dt)`` of those pairs."""
    i = _pairs(keep, k)
    return rv[i + k], inc[i], dt[i]


def _lag_agreement(t: np.ndarray, w: np.ndarray, rv: np.ndarray, keep: np.ndarray) -> dict[str, Any] | None:
    """The skew of the attitude against the body rate, in samples, at which the quaternion steps `rv` ((N-1, 3), all
    the file's) and the rate's rotation vectors (each of :data:`RATE_READINGS`) agree by :func:`_agrees`' rule
    (mismatch within :data:`RATE_TOL`, gain within :data:`GAIN_TOL` of the identity) over the compared steps
    (`keep`, :func:`_lagged`): step ``i + k`` of the attitude against step ``i`` of the rate, ``k > 0`` the attitude
    late. The (reading, ``|k| <=`` :data:`MAX_LAG`) of least mismatch, with ``agreeing``, every skew at which they
    agree, and ``std_samples``, the std of the skew around it (:func:`_skew_std`; a record whose rate changes only at
    a step between samples, left out, cannot tell the skew closer than the agreeing range); None when it is
    ``k = 0`` (no skew explains the disagreement better than none) or none agrees."""
    best: dict[str, Any] | None = None
    agreeing: set[int] = set()
    dt = np.diff(t)
    fitting = None
    for reading in RATE_READINGS.values():
        inc = reading(t, w)
        for k in range(-MAX_LAG, MAX_LAG + 1):
            a, b, d = _lagged(rv, inc, dt, keep, k)
            if a.shape[0] < 3:
                continue
            mismatch = _mismatch(a, b)
            if mismatch > RATE_TOL:
                continue
            systematic = _rate_gain(a, b, d)[2]
            if systematic <= GAIN_TOL:
                agreeing.add(k)
                if best is None or mismatch < best["mismatch"]:
                    best = {"samples": float(k), "seconds": float(k * np.median(dt)), "mismatch": float(mismatch),
                            "systematic": float(systematic)}
                    fitting = reading
    if best is None or best["samples"] == 0:
        return None
    told = _skew_std(t, w, rv, keep, fitting, int(best["samples"]))
    return {**best, "agreeing": sorted(agreeing), "std_samples": told["std"]}


#: The std of the skew (samples) beyond which a record cannot tell a sample's lateness (:func:`_skew_std`): a skew of
#: one sample is then within 3 std of none.
SKEW_STD_MAX = 1.0 / 3.0


def _skew_std(t: np.ndarray, w: np.ndarray, rv: np.ndarray, keep: np.ndarray, reading: Any,
              k: int = 0) -> dict[str, float]:
    """The skew of the attitude against the body rate, in samples, that the compared steps (`keep`) tell, beyond the
    whole `k` (the lag at which they are compared, :func:`_lagged`), and its std: ``tau`` and ``std``.

    An attitude late by ``tau`` samples steps by ``rv_i = inc_{i - tau} ~ inc_i - tau a_i``, ``a_i = (inc_{i+1} -
    inc_{i-1}) / 2`` the change of the rate's rotation vectors (`reading` of :data:`RATE_READINGS`) per sample:
    least squares of ``rv - inc = -tau a`` over the steps whose neighbours are compared too, ``std^2 = sum_c s_c^2
    sum_i a_ic^2 / (sum a.a)^2`` with ``s_c^2`` axis c's residual long-run variance (:func:`_long_run_variance`:
    the cubic spreads a reading over neighbouring steps), at least ``NORM_TOL^2``: the attitude is known to the
    1e-6 its unit check accepts, so residuals at rounding level (noise-free data) do not pretend to tell a skew from a
    rate that changes by as little. A skew shows only where the rate changes from step to
    step: on a constant rate (a pitch kick's once its step is left out) ``sum a.a`` is ~0 and the std unbounded.
    Also ``motion_rad``: the RMS of ``|a|`` (rad per sample), ``steps``: how many steps it used."""
    inc = reading(t, w)
    acc = np.zeros_like(inc)
    acc[1:-1] = 0.5 * (inc[2:] - inc[:-2])
    inner = keep.copy()  # the steps whose neighbours are compared too
    inner[0] = inner[-1] = False
    inner[1:-1] &= keep[:-2] & keep[2:]
    i = _pairs(inner, k)
    e, da = rv[i + k] - inc[i], acc[i]
    aa = float(np.sum(da * da))
    n = int(e.shape[0])
    if n < 3 or aa <= 0.0:
        return {"tau": 0.0, "std": float("inf"), "motion_rad": 0.0, "steps": n}
    tau = -float(np.sum(e * da)) / aa
    s2 = np.maximum(_long_run_variance(e + tau * da), NORM_TOL**2)  # no better than the attitude's resolution
    std = float(np.sqrt(np.sum(s2 * np.sum(da * da, axis=0))) / aa)
    return {"tau": tau, "std": std, "motion_rad": float(np.sqrt(aa / n)), "steps": n}


def _determined(A: np.ndarray) -> np.ndarray:
    """Indices of the first three columns of `A` not (numerically) in the span of its other columns."""
    keep = []
    for j in range(3):
        others = np.delete(A, j, axis=1)
        part = A[:, j] - others @ np.linalg.lstsq(others, A[:, j], rcond=None)[0]  # a_j - P a_j
        if float(part @ part) > 1e-12 * float(A[:, j] @ A[:, j]):
            keep.append(j)
    return np.array(keep, dtype=int)


def _long_run_variance(r: np.ndarray, lags: int = 3) -> np.ndarray:
    """Per column of residuals `r`, ``max(g_0, g_0 + 2 sum_{l<=lags} g_l)`` (``g_l`` the lag-l autocovariance).

    The integrated rate of step k uses samples k-2..k+1 (a cubic through four), so white rate noise reaches
    neighbouring steps alike (MA(3)): on a slowly varying regressor a coefficient's variance is the residual's
    long-run variance over the regressor's sum of squares, not its lag-0 variance (which understates it by
    ~1.3x in std). Never below ``g_0``.
    """
    n = max(r.shape[0] - 4, 1)
    g0 = np.sum(r * r, axis=0) / n
    lr = g0 + 2.0 * sum(np.sum(r[lag:] * r[:-lag], axis=0) / n for lag in range(1, min(lags, r.shape[0] - 1) + 1))
    return np.maximum(lr, g0)


def _rate_gain(rv: np.ndarray, inc: np.ndarray, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The gain ``G`` and bias ``b`` (rad/s) that map the rate's rotation vectors onto the quaternion steps,
    ``rv_k ~ G inc_k + b dt_k``, and the largest determined departure of ``G`` from the identity:
    ``max |G_ij - I_ij|`` over the elements beyond :data:`GAIN_Z` of their std (module notes, :data:`GAIN_TOL`).

    The file's rate may be noisy samples of what the INS integrated, while its attitude is smooth: a fit with the
    integrated rate as regressor would pull ``G`` towards 0 by the noise (errors in variables). So the rate is the
    response: ``inc_k ~ H rv_k + c dt_k`` (least squares on the axes both sides determine) and ``G = H^-1``, exact
    for noise-free data and unbiased for white rate noise. ``cov(H_k.) = s_k^2 M`` (``s_k^2`` the long-run
    variance of axis k's residual, :func:`_long_run_variance`; ``M`` the regressors' inverse normal matrix), and
    ``dG = -G dH G``: ``var G_ij = (sum_k G_ik^2 s_k^2) g_j^T M g_j`` with ``g_j = G[:, j]``. An axis whose rate
    is the bias's twin (constant) or zero says nothing: its column of ``G`` is undetermined (NaN, not judged);
    an axis the attitude keeps still (rows of ``G`` of an undetermined quaternion axis) is fitted the direct way
    (``rv_i`` on the rate: its gains are ~0, where attenuation changes nothing)."""
    gain, std = np.full((3, 3), np.nan), np.full((3, 3), np.inf)
    bias = np.zeros(3)
    cols = _determined(np.column_stack([inc, dt]))
    rows = _determined(np.column_stack([rv, dt]))
    if cols.size and cols.size == rows.size:
        R = np.column_stack([rv[:, rows], dt])
        coef, *_ = np.linalg.lstsq(R, inc[:, cols], rcond=None)  # inc[:, cols] = R coef
        H = coef[:-1].T
        if abs(np.linalg.det(H)) > 1e-12:
            G = np.linalg.inv(H)
            M = np.linalg.inv(R.T @ R)[:-1, :-1]
            s2 = _long_run_variance(inc[:, cols] - R @ coef)
            gain[np.ix_(rows, cols)] = G
            std[np.ix_(rows, cols)] = np.sqrt(np.outer(G**2 @ s2, np.einsum("lj,lm,mj->j", G, M, G)))
            bias[rows] = -G @ coef[-1]
            still = np.setdiff1d(np.arange(3), rows)
            if still.size:  # rv_i ~ G_i. inc + b_i dt
                A = np.column_stack([inc[:, cols], dt])
                c2, *_ = np.linalg.lstsq(A, rv[:, still], rcond=None)
                s2 = _long_run_variance(rv[:, still] - A @ c2)
                gain[np.ix_(still, cols)] = c2[:-1].T
                std[np.ix_(still, cols)] = np.sqrt(np.outer(s2, np.diag(np.linalg.inv(A.T @ A))[:-1]))
                bias[still] = c2[-1]
    sure = np.abs(gain - np.eye(3)) > GAIN_Z * std
    gain = np.where(sure | (std < GAIN_TOL / GAIN_Z), gain, np.nan)  # judged or judgeable
    off = np.abs(gain - np.eye(3))
    return gain, bias, float(np.nanmax(off)) if np.isfinite(off).any() else 0.0


def check_strapdown(src: str, t: np.ndarray, q: np.ndarray, fb: np.ndarray, w: np.ndarray, *,
                    error: Any = None) -> tuple[np.ndarray, dict[str, Any]]:
    """Check strapdown columns (module notes); return the sign-continuous quaternions and what was found.

    Parameters
    ----------
    src : str
        The file, for messages.
    t : (N,) s; q : (N, 4) q_w, q_x, q_y, q_z; fb : (N, 3) m/s^2; w : (N, 3) rad/s
    error : callable, optional
        ``error(message, column, row) -> Exception`` (a table's, which adds the file line); default a
        :class:`~casep.io.flight.FlightDataError` of `src`.

    Returns
    -------
    q : (N, 4) ndarray
        The quaternions with their sign flips removed (``q_{k-1} . q_k >= 0``).
    info : dict
        ``sign_flips``, ``rotation_rad`` and, when the flight turns enough, the rate comparison.

    Raises
    ------
    FlightDataError
        A quaternion that is not a unit one, rates in deg/s, quaternions of another convention.

    Warns
    -----
    StrapdownWarning
        Attitude and integrated rate disagree without an explanation; a body-rate peak above
        :data:`RATE_PEAK_HIGH`.
    """
    if error is None:
        def error(message: str, column: str | None = None, row: int | None = None) -> Exception:
            return FlightDataError(src, message, column, row)
    qcols = ", ".join(QUATERNION_COLUMNS)
    off = np.abs(np.linalg.norm(q, axis=1) - 1.0)
    bad = np.flatnonzero(off > NORM_TOL)
    if bad.size:
        r, worst = int(bad[0]), int(np.argmax(off))
        raise error(f"the quaternion is not a unit one: |q| = {np.linalg.norm(q[r]):.9g} (| |q| - 1 | = "
                    f"{off[r]:.3g} > {NORM_TOL:g}); {bad.size} of {t.size} rows are off, the worst |q| = "
                    f"{np.linalg.norm(q[worst]):.9g} at row {worst + 1}. Give the INS attitude as a unit Hamilton "
                    "quaternion (scalar first): normalise it, or check the columns", qcols, r + 1)
    flips = np.concatenate([[False], np.sum(q[1:] * q[:-1], axis=1) < 0])
    sign = np.where(np.logical_xor.accumulate(flips), -1.0, 1.0)
    q = q * sign[:, None]
    info: dict[str, Any] = {"sign_flips": int(flips.sum())}
    peak = np.linalg.norm(w, axis=1)
    if peak.size and peak.max() > RATE_PEAK_HIGH:
        k = int(np.argmax(peak))
        warnings.warn(StrapdownWarning(
            f"{src}: body rate ({', '.join(BODY_RATE_COLUMNS)}) peaks at {peak[k]:.4g} rad/s ({peak[k] / _DEG:.4g} "
            f"deg/s, {peak[k] / (2 * np.pi):.3g} rev/s) at row {k + 1}, above the {RATE_PEAK_HIGH:g} rad/s of "
            "vehicles: is it in deg/s (multiply by pi/180)?"), stacklevel=3)
    across, lost = _lost_rows(src, t, q, w)
    if lost:
        info["lost_rows"] = lost
    kicks, kicked = _rate_steps(t, w)
    if kicks is not None:
        info["rate_steps"] = kicked
        across = kicks if across is None else kicks & across
    ev = _rate_evidence(t, q, w, across)
    info.update({k: v for k, v in ev.items() if k != "fits"})
    if "fits" in ev and _agrees(ev) and not ev["skew"]["std"] <= SKEW_STD_MAX:
        _warn_skew_unseen(src, t, ev, kicks, kicked)
    if "fits" in ev and not _agrees(ev):
        _time_unit_explains(t, q, w, across, ev, error)
        note, clip = _lost_note(lost, across) + _steps_note(kicks, kicked), _clipped_rates(t, w)
        if clip is not None:  # judged off the clipped readings: a clip is no axis, sign or factor
            keep, said = clip
            ev = _rate_evidence(t, q, w, keep if across is None else keep & across)
            info["rate_clipped"] = said
            if "fits" not in ev or _agrees(ev):
                _warn_clip_only(src, ev, said, keep)
                return q, info
            note += (f". The gyro also clipped ({'; '.join(said)}): the {int((~keep).sum())} steps at and next to "
                     "those readings are left out of this comparison")
        _judge_rate_fits(src, ev, error, note)
    return q, info


#: The turn of the body across a gap in the telemetry (rad) beyond which the model's S_V, integrated across it by
#: the trapezoid rule from the attitude at its ends, is not known: for a turn ``theta`` about a fixed axis the
#: trapezoid's ``(1 + cos theta) / 2`` against the exact mean ``sin theta / theta`` misses by ``theta^2 / 12`` of
#: the gap's increment, beyond :data:`RATE_TOL` (the disagreement of the step rotations the rate comparison
#: accepts) above ``sqrt(12 RATE_TOL)``, 0.77 rad (44 deg).
GAP_TURN_LIMIT = float(np.sqrt(12.0 * RATE_TOL))


def _gap_turn(t: np.ndarray, q: np.ndarray, w: np.ndarray, k: int) -> float:
    """The body's turn across the gap of step ``k`` (rad): the larger of the rate at its ends times its length (the
    trapezoid of ``|w|``) and the rotation between its quaternions (a turn of more than half a revolution shows as
    less: the rates say it)."""
    h = float(t[k + 1] - t[k])
    by_rate = 0.5 * (float(np.linalg.norm(w[k])) + float(np.linalg.norm(w[k + 1]))) * h
    by_attitude = float(np.linalg.norm(_step_rotations(q[k:k + 2])[0]))
    return max(by_rate, by_attitude)


def _lost_rows(src: str, t: np.ndarray, q: np.ndarray,
               w: np.ndarray) -> tuple[np.ndarray | None, list[dict[str, float]]]:
    """The telemetry's lost rows: the ``(N-1,)`` steps of the attitude/rate comparison that no gap reaches (None
    without a gap) and each gap (rows before and after, times, length, the body's turn across it:
    :func:`_gap_turn`), warned of with a :class:`StrapdownWarning`.

    A gap is a step over :data:`casep.io.flight.LOST_SAMPLE_FACTOR` median steps (:func:`casep.io.flight.gap_steps`,
    the IMU's rule for lost samples: the same rates integrated). The integrated rate of a step is a cubic through the
    readings around it (:data:`CLIP_REACH`): over a gap it guesses the motion, so the gap's step and its neighbours
    are left out of the comparison, not judged as the INS's rate."""

    if t.size < 3:
        return None, []
    steps = gap_steps(t)
    if not steps.size:
        return None, []
    h = float(np.median(np.diff(t)))
    lost = [{"row_before": int(k) + 1, "row_after": int(k) + 2, "t_before": float(t[k]), "t_after": float(t[k + 1]),
             "length_s": float(t[k + 1] - t[k]), "rows_lost": int(round((t[k + 1] - t[k]) / h)) - 1,
             "turn_rad": _gap_turn(t, q, w, int(k))} for k in steps]
    keep = np.ones(t.size - 1, bool)
    for k in steps:
        keep[max(k - CLIP_REACH + 1, 0): k + CLIP_REACH] = False
    listed = "; ".join(_gap_text(g) for g in lost[:5]) + (f"; and {len(lost) - 5} more" if len(lost) > 5 else "")
    warnings.warn(StrapdownWarning(
        f"{src}: column t: the telemetry lost rows: {len(lost)} gap(s) over {LOST_SAMPLE_FACTOR:g} x the median step "
        f"{h:.4g} s ({listed}); the attitude/rate comparison leaves the {int((~keep).sum())} steps across and next "
        "to them out (a rate integrated over a gap guesses the motion)"), stacklevel=4)
    return keep, lost


def _gap_text(g: dict[str, float]) -> str:
    """One gap of :func:`_lost_rows`: its length, the rows and times on either side."""
    return (f"{g['length_s']:.4g} s, ~{g['rows_lost']} row(s) lost between rows {g['row_before']} and "
            f"{g['row_after']}, t = {g['t_before']:.10g} .. {g['t_after']:.10g} s, the body turning by "
            f"{g['turn_rad'] / _DEG:.3g} deg across it")


def lost_rows_problem(info: dict[str, Any] | None, last_used: float = np.inf) -> str | None:
    """Why a separation of strapdown telemetry with lost rows is probably wrong: a gap across which the body turned
    by more than :data:`GAP_TURN_LIMIT` (the S_V of body-frame errors across it is not known; every row after it
    carries that); `info` the flight's ``meta["strapdown"]``. None otherwise. A gap after the last row the fit uses
    (`last_used`, s: a clipped IMU's rows after its first clipped sample are left out) reaches no row of the fit.

    None for rows navigated from a raw IMU record with gaps (``info["lost_rows_bridged"]``: ``casep separate --imu``):
    the navigation and the model's S_V integrate across them alike from the record, and what a gap leaves unknown is
    the bridge's velocity and attitude across it, carried in the std
    (:func:`casep.workflows.imu_separate.step_rows`). The trapezoid's miss of S_V across the gap, ``theta^2 / 12``
    of the part of the gap's own S_V increment that turns with the body, is second order beside that: it scales the
    coefficients' effect over the gap alone (at 15 g over 0.075 s the increment is 0.11 m/s per 1 % of a transverse
    scale factor or misalignment, and a 60 deg turn misses 9 % of it: 0.01 m/s)."""
    if (info or {}).get("lost_rows_bridged"):
        return None
    lost = [g for g in (info or {}).get("lost_rows") or ()
            if g.get("turn_rad", 0.0) > GAP_TURN_LIMIT and g["t_after"] <= last_used]
    if not lost:
        return None
    return (f"the telemetry lost rows while the body turned ({'; '.join(_gap_text(g) for g in lost[:3])}"
            f"{' ...' if len(lost) > 3 else ''}; beyond {GAP_TURN_LIMIT / _DEG:.3g} deg): the model's S_V is "
            "integrated across the gap from the attitude at its ends, which does not know the turn inside it, and "
            "every row after it carries that error; the estimates absorb it. Give the lost rows, or separate the "
            "stretch before the gap")


def _lost_note(lost: list[dict[str, float]], keep: np.ndarray | None) -> str:
    """What a finding of the comparison says of the gaps it left out ('' without any)."""
    if not lost or keep is None:
        return ""
    return (f". The telemetry lost rows ({'; '.join(_gap_text(g) for g in lost[:3])}{' ...' if len(lost) > 3 else ''}):"
            f" the {int((~keep).sum())} steps across and next to the gaps are left out of this comparison")


def _time_unit_explains(t: np.ndarray, q: np.ndarray, w: np.ndarray, keep: np.ndarray | None, ev: dict[str, Any],
                        error: Any) -> None:
    """Before the body rate is blamed: t in another unit than s also breaks the comparison (the step's rotation is the
    rate times a step 1000 times too long), alone or with the body rate in another unit than rad/s (t in ms and w in
    deg/s: the attitude turns by ``(pi/180) / 1000`` of the rate integrated over the file's steps). Each choice of
    unit mistakes with a time unit (:func:`casep.units.unit_mistakes` over the units of t that bring the median step
    and the span into the range of telemetry, :func:`casep.io.flight.time_unit_factors`, the rule the flight check
    warns with, and :data:`casep.units.RATE_UNIT_MISTAKES`), fewest first: the first in whose units the attitude
    and the rate agree (:func:`_agrees`) is an error naming each (``t``, and ``w_*`` with it). The body rate's unit
    alone is :func:`_judge_rate_fits`' (judged off any clipped readings)."""
    h, span = float(np.median(np.diff(t))), float(t[-1] - t[0])
    time_units = time_unit_factors(h, span)
    mine = ev["fits"][next(iter(ev["fits"]))]
    for found in unit_mistakes((time_units, RATE_UNIT_MISTAKES)):
        in_time = [(u, k) for u, k in found if (u, k) in time_units]
        if not in_time:
            continue
        k_t, k_w = in_time[0][1], math.prod(k for u, k in found if (u, k) not in time_units)
        alt = _rate_evidence(k_t * t, q, k_w * w, keep)
        if not ("fits" in alt and _agrees(alt)):
            continue
        agree = 100 * alt["fits"][next(iter(alt["fits"]))]["mismatch"]
        unit = in_time[0][0].split(" ")[0]
        if len(found) == 1:
            raise error(f"t looks like {unit}, not s: median time step {h:.4g} s ({1 / h:.4g} Hz) over "
                        f"{span:.4g} s; read as {unit} the attitude (q_*) and the integrated body rate "
                        f"({', '.join(BODY_RATE_COLUMNS)}) agree within {agree:.2g} %, read as s they are "
                        f"{100 * mine['mismatch']:.3g} % off. Give t in s: t is in {in_time[0][0]}", "t", None)
        parts = {u: (u.split(" (")[0], u.split(" (")[1].rstrip(")")) for u, _ in found}  # unit, its fix
        rates = [u for u, k in found if (u, k) not in time_units]
        gain = np.array(ev["rate_gain"], dtype=float).diagonal()
        turned = np.where(np.isfinite(gain), np.sum(w**2, axis=0), -1.0)
        a = int(np.argmax(turned))
        said = f"G = {gain[a]:.4g} on {BODY_RATE_COLUMNS[a]} (the axis that turns most), " if turned[a] >= 0 else ""
        factors = " x ".join(f"{k:.5g} ({parts[u][0]})" for u, k in found)
        wcols = ", ".join(BODY_RATE_COLUMNS)
        raise error(f"t looks like {unit}, not s, and the body rate ({wcols}) like "
                    f"{' and '.join(parts[r][0] for r in rates)}, not rad/s: the quaternion steps turn by {said}the "
                    f"product of their factors {factors} = {k_t * k_w:.4g}, times the integrated rate; read in those "
                    f"units (t: median step {h:.4g}, span {span:.4g}) the attitude (q_*) and the integrated body rate "
                    f"agree within {agree:.2g} %, read as s and rad/s they are {100 * mine['mismatch']:.3g} % off. "
                    f"Give t in s ({unit}: {parts[in_time[0][0]][1]}) and {wcols} in rad/s "
                    f"({'; '.join(f'{parts[r][0]}: {parts[r][1]}' for r in rates)})", f"t, {wcols}", None)


def _agrees(ev: dict[str, Any]) -> bool:
    """Whether :func:`_rate_evidence` finds the attitude and the integrated rate in agreement (module notes)."""
    return bool(ev["fits"][next(iter(ev["fits"]))]["mismatch"] <= RATE_TOL and ev["systematic"] <= GAIN_TOL)


#: Samples on either side of a clipped reading whose steps a clip reaches: the integrated rate of step k (rows k, k+1)
#: is a cubic through the readings k-1..k+2 (:func:`casep.rotations.rotation_increments`).
CLIP_REACH = 2


def _rate_steps(t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray | None, list[dict[str, float]]]:
    """The body rate's steps between samples (:func:`casep.io.flight.signal_steps`, the rule of an IMU record's
    steps: a pitch kick, a roll programme switched on): the ``(N-1,)`` steps of the attitude/rate comparison none
    of them reaches (None without any) and each step (the rows and times on either side, its size).

    The integrated rate of step ``k`` is a cubic through the readings ``k-1 .. k+2`` (:data:`CLIP_REACH`), which a
    jump in interval ``j`` makes ring over steps ``j-1 .. j+1``, while the attitude's step rotations follow the
    motion: those steps say nothing of the rate or of a skew (a 10 Hz record cut 2 s after its pitch kick read as
    one sample late), and are left out of the comparison."""
    if t.size < 5:
        return None, []
    big, jumps = signal_steps(t, w)
    at = np.flatnonzero(np.any(big, axis=1))
    if at.size == 0:
        return None, []
    keep = np.ones(t.size - 1, bool)
    for j in at:
        keep[max(j - CLIP_REACH + 1, 0): j + CLIP_REACH] = False
    said = [{"row_before": int(j) + 1, "row_after": int(j) + 2, "t_before": float(t[j]), "t_after": float(t[j + 1]),
             "step_rad_s": float(np.linalg.norm(jumps[j]))} for j in at]
    return keep, said


def _steps_text(kicked: list[dict[str, float]]) -> str:
    """The rate's steps of :func:`_rate_steps`, listed (the first three)."""
    return "; ".join(f"{s['step_rad_s'] / _DEG:.3g} deg/s between rows {s['row_before']} and {s['row_after']}, "
                     f"t = {s['t_before']:.10g} .. {s['t_after']:.10g} s" for s in kicked[:3]) \
        + (f"; and {len(kicked) - 3} more" if len(kicked) > 3 else "")


def _steps_note(keep: np.ndarray | None, kicked: list[dict[str, float]]) -> str:
    """What a finding of the comparison says of the rate's steps it left out ('' without any)."""
    if keep is None:
        return ""
    return (f". The body rate steps between samples ({_steps_text(kicked)}): the {int((~keep).sum())} steps "
            "across and next to them are left out of this comparison (the integrated rate rings across a step)")


def _warn_skew_unseen(src: str, t: np.ndarray, ev: dict[str, Any], kicks: np.ndarray | None,
                      kicked: list[dict[str, float]]) -> None:
    """The :class:`StrapdownWarning` of an attitude that agrees with the body rate on a record that cannot tell
    whether the two are on one time base: the skew's std (:func:`_skew_std`) beyond :data:`SKEW_STD_MAX` samples."""
    sk = ev["skew"]
    h = sk["sample_s"]
    told = (f"the skew's std is {sk['std']:.3g} samples ({sk['std'] * h:.3g} s)" if np.isfinite(sk["std"])
            else "the skew is not determined at all")
    left = ("" if kicks is None else
            f"; the {int((~kicks).sum())} steps across and next to the body rate's steps between samples "
            f"({_steps_text(kicked)}), the motion that would show a skew, are left out: the integrated rate rings "
            "across a step and says nothing of a skew")
    warnings.warn(StrapdownWarning(
        f"{src}: the attitude (q_*) and the body rate ({', '.join(BODY_RATE_COLUMNS)}) agree, but this record cannot "
        f"tell whether they are on one time base: a skew shows only where the rate changes from step to step, and "
        f"over the {sk['steps']} steps it uses (of {ev['steps_compared']} compared, rows 1-{ev['rows']}, "
        f"{ev['rotation_rad'] / _DEG:.3g} deg turned) the rate's rotation changes by {sk['motion_rad'] / _DEG:.3g} "
        f"deg RMS per sample: {told}, beyond the {SKEW_STD_MAX:.2g} sample ({SKEW_STD_MAX * h * 1e3:.3g} ms) that "
        f"tells a sample's lateness{left}. The time skew of q_* against w_* is not checked: an attitude a sample "
        "late or early would pass unseen (its error, the body rate times the skew, reaches the navigation-frame "
        "specific force C(q) fb); make sure the INS wrote them on one time base"), stacklevel=4)


def _clipped_rates(t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, list[str]] | None:
    """The body-rate readings held at a full scale (:func:`casep.fullscale.held_full_scale`, the saturation rule of
    calibration, navigation and the telemetry's saturation screen; no declared full scale is known here): the
    ``(N-1,)`` steps no clipped reading reaches (:data:`CLIP_REACH`) and what was found (column, side, value, full
    scale, rows, times), or None when no reading is held."""
    found = held_full_scale(w, "gyro")
    if not found:
        return None
    held = held_mask(found, w.shape).any(axis=1)
    reach = np.convolve(held.astype(float), np.ones(2 * CLIP_REACH), mode="full")  # [j]: held in j+1-2 CLIP_REACH..j
    near = reach[CLIP_REACH: CLIP_REACH + t.size - 1] > 0  # step k: held in k - CLIP_REACH + 1 .. k + CLIP_REACH
    said = []
    for h in found:
        n = sum(b - a for a, b in h.runs)
        a0, b1 = h.runs[0][0], h.runs[-1][1] - 1
        said.append(f"{BODY_RATE_COLUMNS[h.axis]} held at its {h.side} {h.value / _DEG:.6g} deg/s ({h.why}) for {n} "
                    f"samples in {len(h.runs)} run(s), rows {a0 + 1}..{b1 + 1}, t = {t[a0]:.10g} .. {t[b1]:.10g} s")
    return ~near, said


def _warn_clip_only(src: str, ev: dict[str, Any], said: list[str], keep: np.ndarray) -> None:
    """The :class:`StrapdownWarning` of an attitude that disagrees with the body rate only at its clipped readings."""
    off = f"off the {int((~keep).sum())} steps at and next to those readings"
    if "fits" in ev:
        mine = ev["fits"][next(iter(ev["fits"]))]
        rest = (f"only there: {off} they agree within {100 * mine['mismatch']:.2g} % (the gain G departs from the "
                f"identity by {100 * ev['systematic']:.2g} %), so the INS integrated the motion, not the clipped "
                "readings, and w_* there are not the rates it integrated")
    else:
        rest = f"there; {off} the record turns too little to compare them"
    warnings.warn(StrapdownWarning(
        f"{src}: the gyro clipped: {'; '.join(said)}. The attitude (q_*) disagrees with the integrated body rate "
        f"({', '.join(BODY_RATE_COLUMNS)}) {rest}. A separation leaves the rows from the first clipped reading on "
        "out of its fit (the saturation screen); declare the gyro's range with --gyr-range if it is known"),
        stacklevel=4)


def _judge_rate_fits(src: str, ev: dict[str, Any], error: Any, note: str = "") -> None:
    """Error or warning from :func:`_rate_evidence` (module notes); `note` ends each message (what the comparison
    left out)."""
    fits = ev["fits"]
    declared = next(iter(fits))
    mine = fits[declared]
    wcols = ", ".join(BODY_RATE_COLUMNS)
    if _agrees(ev):
        return
    if (mine["mismatch"] > RATE_TOL and mine["scaled_mismatch"] <= RATE_TOL
            and unit_factorisation(mine["scale"], (RATE_UNIT_MISTAKES,)) == RATE_UNIT_MISTAKES[:1]):
        raise error(f"the body rate looks like deg/s, not rad/s: the attitude (q_*) turns by {mine['scale']:.5g} "
                    f"times the integrated rate (1/{1 / mine['scale']:.4g}; pi/180 = 1/57.30), which then agrees "
                    f"within {100 * mine['scaled_mismatch']:.2g} % (as rad/s it is {100 * mine['mismatch']:.3g} % "
                    f"off, over rows 1-{ev['rows']}). Give {wcols} in rad/s: multiply by pi/180{note}", "w_x", None)
    for name, fit in list(fits.items())[1:]:
        if fit["mismatch"] <= RATE_TOL < mine["mismatch"]:
            raise error(f"the quaternions look {name}: read so, the integrated body rate ({wcols}) agrees with "
                        f"their steps within {100 * fit['mismatch']:.2g} %, read as declared (Hamilton, scalar "
                        f"first, body to navigation) it is {100 * mine['mismatch']:.3g} % off (rows 1-{ev['rows']}). "
                        "Convert them to "
                        f"the declared convention{note}", ", ".join(QUATERNION_COLUMNS), None)
    what = (f"the attitude (q_*) disagrees with the integrated body rate ({wcols}) by "
            f"{ev['rms_rate_error_rad_s'] / _DEG:.3g} deg/s RMS ({100 * mine['mismatch']:.3g} % of the step rotation; "
            f"worst {ev['worst_rate_error_rad_s'] / _DEG:.3g} deg/s at row {ev['worst_row']}, "
            f"t = {ev['worst_t']:.6g} s; "
            f"rows 1-{ev['rows']}), against {ev['rms_rate_rad_s'] / _DEG:.3g} deg/s RMS body rate")
    lag = ev.get("lag")
    if lag is not None:
        k, sec = int(lag["samples"]), lag["seconds"]
        side = [j for j in lag["agreeing"] if j * k > 0]
        if len(side) > 1 and not lag["std_samples"] <= SKEW_STD_MAX:  # the record tells the skew only within a range
            h = sec / k
            lo, hi = min(side, key=abs), max(side, key=abs)
            more, late = " or more" if abs(hi) == MAX_LAG else "", "later" if k > 0 else "earlier"
            raise error(f"{what}: the attitude (q_*) is {abs(lo)} to {abs(hi)}{more} samples "
                        f"({abs(lo * h) * 1e3:.4g} to {abs(hi * h) * 1e3:.4g} ms{more}) {late} "
                        f"than the body rate ({wcols}): shifted by any of those they agree (within "
                        f"{100 * lag['mismatch']:.2g} % at best; this record cannot tell the skew closer: its std "
                        f"there is {lag['std_samples']:.3g} samples, the rate hardly changes from step to step in the "
                        "steps compared). The INS's attitude and rate are on different time bases: "
                        f"put them on one (find the INS's skew: q_* is at least {abs(lo * h) * 1e3:.4g} ms "
                        f"{'late' if k > 0 else 'early'}){note}", ", ".join(QUATERNION_COLUMNS), None)
        raise error(f"{what}: the attitude (q_*) is {abs(k)} sample(s) ({abs(sec) * 1e3:.4g} ms) "
                    f"{'later' if k > 0 else 'earlier'} than the body rate ({wcols}): shifted by that they agree "
                    f"within {100 * lag['mismatch']:.2g} % (gain within {100 * lag['systematic']:.2g} % of the "
                    "identity). The INS's attitude and rate are on different time bases: put them on one (move "
                    f"q_* by {-sec * 1e3:+.4g} ms){note}", ", ".join(QUATERNION_COLUMNS), None)
    if ev["systematic"] > GAIN_TOL:
        G = np.array(ev["rate_gain"], dtype=float)
        raise error(f"{what}. The quaternion steps are G times the integrated rate with G = "
                    + "[" + "; ".join(" ".join(f"{x:.3g}" if np.isfinite(x) else "?" for x in row) for row in G) + "]"
                    f" (? where the flight does not determine it; an element {100 * ev['systematic']:.3g} % away "
                    f"from the identity, beyond the {100 * GAIN_TOL:g} % "
                    "a gyro compensation could apply): these are not the rates the INS integrated (axes swapped, a "
                    f"sign, a factor?). Give the INS's own body rate, in rad/s, body axes{note}", wcols, None)
    warnings.warn(StrapdownWarning(
        f"{src}: {what}; no other quaternion convention or rate unit explains it, and its systematic part (a gain) is "
        f"{100 * ev['systematic']:.2g} % (bias {', '.join(f'{b / _DEG:.3g}' for b in ev['rate_bias_rad_s'])} deg/s): "
        f"check that q, fb and w are the INS's own, on one time base{note}"), stacklevel=4)


#: RMS of ``f - C(q) fb`` relative to the RMS of f above which a file's f_* and its strapdown columns disagree.
FORCE_TOL = 0.01


def compare_force(src: str, f: np.ndarray, f_body: np.ndarray) -> None:
    """A :class:`StrapdownWarning` when the file's ``f_*`` differ from ``C(q) fb`` by more than :data:`FORCE_TOL`."""
    diff = np.linalg.norm(f - f_body, axis=1)
    rms, scale = float(np.sqrt(np.mean(diff**2))), float(np.sqrt(np.mean(np.sum(f**2, axis=1))))
    if scale > 0 and rms > FORCE_TOL * scale:
        k = int(np.argmax(diff))
        warnings.warn(StrapdownWarning(
            f"{src}: f_x, f_y, f_z differ from C(q) fb (q_*, fb_*) by {rms:.4g} m/s^2 RMS ({100 * rms / scale:.3g} % "
            f"of f; worst {diff[k]:.4g} m/s^2 at row {k + 1}): f_* is used, while the strapdown models use q_*, "
            "fb_*; check the quaternion convention and that both are the INS's"), stacklevel=4)


def strapdown_force(tab: Any, t: np.ndarray) -> tuple[np.ndarray, dict[str, Any], np.ndarray]:
    """Navigation-frame specific force ``f = C(q) fb`` of a table with the strapdown columns, checked.

    Parameters
    ----------
    tab : casep.io.tables.Table
        With every column of :data:`STRAPDOWN_COLUMNS`.
    t : (N,) ndarray
        Its time, s.

    Returns
    -------
    f : (N, 3) ndarray
        m/s^2, navigation (launch-inertial) frame.
    info : dict
        What :func:`check_strapdown` found (for the flight's ``meta["strapdown"]``).
    q : (N, 4) ndarray
        The sign-continuous quaternions (the flight's ``q_*`` signals).
    """
    tab.require(STRAPDOWN_COLUMNS, ". Use: q_w, q_x, q_y, q_z (unit quaternion, scalar first, body to navigation), "
                                   "fb_x, fb_y, fb_z (m/s^2) and w_x, w_y, w_z (rad/s)")
    q = tab.vectors(QUATERNION_COLUMNS)
    fb = tab.vectors(BODY_FORCE_COLUMNS)
    w = tab.vectors(BODY_RATE_COLUMNS)
    q, info = check_strapdown(tab.src, t, q, fb, w, error=tab.error)
    f = np.einsum("kij,kj->ki", quaternion_dcm_array(q), fb)
    return f, info, q


#: Windows of the kinematic check, s: long enough that the velocity's noise over it is small against the limit
#: (0.1 m/s of noise makes 0.14 m/s^2), short enough that the attitude hardly turns within one.
KINEMATIC_WINDOW = 1.0
#: The least steps in a window of the kinematic check (a slow record's windows are longer than KINEMATIC_WINDOW).
KINEMATIC_MIN_STEPS = 4
#: Median misfit of a body axis (m/s^2) beyond which the velocity and the specific force cannot be the same INS's:
#: 3 m/s^2 (0.31 g), almost 4 times the largest MEMS bias (:data:`casep.units.MEMS_ACCEL_BIAS`, 80 mg, an
#: instrument error the separation estimates); the flat-Earth gravity of :func:`casep.gravity.kinematic_acceleration`
#: errs by 0.3 m/s^2 at 100 km altitude and 0.17 m/s^2 per 100 km downrange. ``fb`` in g misses by ``|fb| (1 -
#: 1/9.81)``, 8.8 m/s^2 in level flight; a column offset by a g, by that g.
KINEMATIC_LIMIT = 3.0
#: ... and beyond which it is a warning: twice the largest MEMS bias.
KINEMATIC_WARN = 2.0 * MEMS_ACCEL_BIAS


def _kinematic_windows(t: np.ndarray) -> np.ndarray:
    """Row indices of the window edges of :func:`check_kinematics`: every :data:`KINEMATIC_WINDOW` s and at least
    :data:`KINEMATIC_MIN_STEPS` steps apart."""
    edges = [0]
    while True:
        k = edges[-1]
        j = max(int(np.searchsorted(t, t[k] + KINEMATIC_WINDOW)), k + KINEMATIC_MIN_STEPS)
        if j > t.size - 1:
            break
        edges.append(j)
    return np.array(edges, dtype=int)


def _kinematic_misfit(t: np.ndarray, q: np.ndarray, fb: np.ndarray, v: np.ndarray,
                      edges: np.ndarray) -> np.ndarray:
    """The misfit ``d(v_tel)/dt - (C fb + g)`` of each window in body axes, m/s^2, (W, 3): minus the constant offset
    of ``fb`` that explains it (NaN where the window's attitude turns too much to tell the axes apart).

    ``dv - int (C fb + g) dt = (int C dt) b`` over the window: ``b = (int C dt)^-1 (dv - int (C fb + g) dt)``, exact
    for a constant offset however the body turns; the
    mean of ``C`` is near ``C_mid`` while the body turns little, and loses its rank only when it turns by a whole
    revolution about an axis in the window (condition number beyond 10: NaN).
    """
    C = quaternion_dcm_array(q)
    a = kinematic_acceleration(t, np.einsum("kij,kj->ki", C, fb))
    integral, C_int = cumulative_trapezoid(a, t), cumulative_trapezoid(C, t)
    i, j = edges[:-1], edges[1:]
    miss = v[j] - v[i] - (integral[j] - integral[i])
    M = C_int[j] - C_int[i]
    sv = np.linalg.svd(M, compute_uv=False)
    ok = sv[:, -1] > 0.1 * sv[:, 0]
    b = np.full((i.size, 3), np.nan)
    b[ok] = np.linalg.solve(M[ok], miss[ok][:, :, None])[:, :, 0]
    return b  # d(v_tel)/dt - (C fb + g) in body axes: minus the offset fb carries


def check_kinematics(src: str, t: np.ndarray, q: np.ndarray, fb: np.ndarray, v_tel: np.ndarray, *,
                     error: Any = None) -> dict[str, Any]:
    """The INS's velocity against its specific force: ``d v_tel / dt = C(q) fb + g`` (module notes).

    Parameters
    ----------
    src : str
        The file, for messages.
    t : (N,) s; q : (N, 4) sign-continuous unit quaternions; fb : (N, 3) m/s^2; v_tel : (N, 3) m/s
    error : callable, optional
        ``error(message, column, row) -> Exception``; default a :class:`~casep.io.flight.FlightDataError` of `src`.

    Returns
    -------
    dict
        ``median_misfit_m_s2`` (body axes), ``windows``, ``window_s``; empty when the record holds fewer than
        three windows.

    Raises
    ------
    FlightDataError
        A body axis's median misfit beyond :data:`KINEMATIC_LIMIT`, naming its ``fb_*`` column.

    Warns
    -----
    StrapdownWarning
        A median misfit beyond :data:`KINEMATIC_WARN`.
    """
    if error is None:
        def error(message: str, column: str | None = None, row: int | None = None) -> Exception:
            return FlightDataError(src, message, column, row)
    edges = _kinematic_windows(t)
    if edges.size < 4:
        return {}
    m = _kinematic_misfit(t, q, fb, v_tel, edges)
    if int(np.sum(np.isfinite(m[:, 0]))) < 3:
        return {}
    med = np.nanmedian(m, axis=0)
    info = {"median_misfit_m_s2": med.tolist(), "windows": int(np.sum(np.isfinite(m[:, 0]))),
            "window_s": float(np.median(np.diff(t[edges])))}
    k = int(np.argmax(np.abs(med)))
    size = float(abs(med[k]))
    if size <= KINEMATIC_WARN:
        return info
    col = BODY_FORCE_COLUMNS[k]
    beyond = np.flatnonzero(np.abs(m[:, k]) > KINEMATIC_WARN)
    rows = f"rows {edges[0] + 1}-{edges[-1] + 1}"
    text = (f"the telemetered velocity (v_tel_*) and the specific force (q_*, fb_*) disagree: d(v_tel)/dt - (C(q) fb "
            f"+ g) in body axes has the median {', '.join(f'{x:.3g}' for x in med)} m/s^2 (x, y, z) over "
            f"{info['windows']} windows of {info['window_s']:.3g} s ({rows}); {col} is off by {size:.3g} m/s^2 "
            f"({1000 * size / G0:.3g} mg), beyond {KINEMATIC_WARN / G0 * 1000:.3g} mg in {beyond.size} of "
            f"the windows, where the largest MEMS bias is {MEMS_ACCEL_BIAS / G0 * 1000:.3g} mg")
    scaled = np.nanmedian(_kinematic_misfit(t, q, G0 * fb, v_tel, edges), axis=0)
    if float(np.max(np.abs(scaled))) <= KINEMATIC_WARN:
        hint = (f". Read in g (times 9.80665) fb fits: median misfit {', '.join(f'{x:.3g}' for x in scaled)} m/s^2: "
                f"give {', '.join(BODY_FORCE_COLUMNS)} in m/s^2 (multiply by 9.80665)")
        col = ", ".join(BODY_FORCE_COLUMNS)
    elif abs(size / G0 - round(size / G0)) < 0.1:
        hint = (f" ({size / G0:.3g} g: an offset of whole g in {col}?). Give the INS's own body specific force, "
                "m/s^2, in body axes, and the velocity it integrated")
    else:
        hint = (". Give the INS's own body specific force (m/s^2, body axes) and the velocity it integrated, in the "
                "launch-inertial frame, on one time base")
    if size > KINEMATIC_LIMIT:
        raise error(f"{text}; beyond {KINEMATIC_LIMIT:g} m/s^2 no instrument error explains it{hint}", col, None)
    warnings.warn(StrapdownWarning(f"{src}: {text}: an accelerometer bias that large, or a column that is not the "
                                   f"INS's{hint}"), stacklevel=4)
    return info
