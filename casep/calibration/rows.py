"""The rows of a ground test's regression: segment means, turn integrals, position weighting.

Rows. Each sensor triad (accelerometer, gyro) is its own regression ``y = S D + e`` over the
coefficients of its output, solved by the registered estimators (:mod:`casep.estimators`, on a
:class:`casep.Problem`), so the noise level, the std, outlier handling and the collinearity
diagnostics are those of a flight. With readings ``u`` and the model's reading
``u = y0(f, omega) + J(f, omega) D``:

- static segment k (specific force ``f_k = g e_k``, rate ``omega_k``): one row per axis, the segment
  mean ``mean(u) - y0(f_k, omega_k) = J(f_k, omega_k) D`` (``weighting="samples"``: one row per
  sample and axis);
- rotation segment k (gyro only; by angle ``theta`` about axis ``a`` along gravity, over ``T_k =
  sum_i dt_i``, ``dt_i = t_{i+1} - t_i`` the recorded steps, the last 1 / rate): the integral
  ``int u dt = sum_i u_i dt_i`` (evenly sampled: imucal's sum / rate). The reading is affine in omega
  (checked by the model's setup), so
  ``int u dt = T_k y0(f_k, 0) + [y0(f_k, Theta) - y0(f_k, 0)] + (T_k J(f_k, 0) + [J(f_k, Theta) -
  J(f_k, 0)]) D`` exactly, ``Theta = theta a`` in rad, whatever the rate profile of the turn.

Weighting. A hand-held or fixture position is never exactly the nominal one: its error is shared by
every sample of the segment, so the means misfit the model far above the sample noise (imucal's
session: up to 25 raw units against 0.2). ``positions`` (default): the static means whitened by the
covariance a tilt ``phi ~ N(0, tilt^2 I)`` of the position gives,
``V_k = tilt^2 g^2 J_f P_k J_f^T + g^2 tilt^4 (J_f e)(J_f e)^T + diag(s_i^2 / n_k)`` with
``J_f = dy/df`` (the model's, at an equal-weight first estimate) and ``P_k = I - e e^T`` (a tilt
moves the readings across gravity, not along it), the turns by their white-noise std
``s_i sqrt(n_k) / rate`` (``s_i``: pooled within-segment sample std of axis i); ``tilt`` is where the
whitened least-squares residual std is 1, estimated on the accelerometer and used for the gyro. A tilted
position senses on average ``g cos|phi x e| ~ g (1 - tilt^2)`` along e (``E |phi x e|^2 / 2 = tilt^2``):
the static rows are taken at ``f_k = g (1 - tilt^2) e_k`` (tilt and rows by a few fixed-point steps).
``segments``: the means with equal weight and the noise level from their misfit (the turns scaled to
that level); ``samples``: every static sample a row, the white-noise GLS (exact positions only).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from casep.calibration.model import CalibrationModel
from casep.calibration.session import ACC_UNITS, GYR_UNITS, RAW_UNIT, Segment, Session

__all__ = ["readings_for", "sample_noise", "sample_steps", "rotation_row", "unit_text", "static_rows", "ls_sigma",
           "position_whitening", "tilted_rows", "solve_tilt", "sensor_rows"]


def readings_for(session: Session, model: CalibrationModel) -> tuple[np.ndarray, np.ndarray, str, str]:
    """Readings as the model wants them, and their units."""
    if model.readings == "raw":
        return session.acc, session.gyr, session.acc_unit, session.gyr_unit
    out = []
    for what, unit, table, arr in (("accelerometer", session.acc_unit, ACC_UNITS, session.acc),
                                   ("gyro", session.gyr_unit, GYR_UNITS, session.gyr)):
        if unit not in table:
            raise ValueError(f"model `{model.name}` reads SI; the session's {what} unit is `{unit}`. Use: "
                             f"--{'acc' if what == 'accelerometer' else 'gyr'}-unit one of {', '.join(table)} "
                             "(or a raw-readings model such as ferraris)")
        out.append(arr * table[unit])
    return out[0], out[1], "m/s^2", "rad/s"


def sample_noise(segs: Sequence[Segment], u: np.ndarray) -> np.ndarray:
    """Pooled within-segment sample std per axis over the static segments, (3,)."""
    ss, dof = np.zeros(3), 0
    for s in segs:
        x = u[s.rows]
        ss += ((x - x.mean(axis=0)) ** 2).sum(axis=0)
        dof += len(s.rows) - 1
    return np.sqrt(ss / max(dof, 1))


def sample_steps(seg: Segment, t: np.ndarray, rate: float) -> np.ndarray:
    """The time each sample of a segment stands for, s: the step to the next sample, the last one 1 / rate."""
    return np.append(np.diff(t[seg.rows]), 1.0 / rate)


def rotation_row(model, slot, seg: Segment, u: np.ndarray, g: float, rate: float, t: np.ndarray):
    """(y, J, T, dt) of a rotation segment: the integral over the turn (module notes)."""
    assert seg.angle_deg is not None and seg.axis is not None  # a rotation segment has both
    f = g * seg.gravity
    theta = np.deg2rad(seg.angle_deg) * seg.axis  # rad
    # int u dt by the rectangle rule on the recorded times: u_i (t_{i+1} - t_i), the last sample 1 / rate
    # (evenly sampled: imucal's sum / rate; samples missing inside the turn do not shorten it)
    dt = sample_steps(seg, t, rate)
    T = float(dt.sum())
    z = np.zeros(3)
    integral = (u[seg.rows] * dt[:, None]).sum(axis=0)
    y0 = T * model.known(slot, f, z) + (model.known(slot, f, theta) - model.known(slot, f, z))
    J0 = model.jacobian(slot, f, z)
    J = T * J0 + (model.jacobian(slot, f, theta) - J0)
    return integral - y0, J, T, dt


def unit_text(model: CalibrationModel, session: Session) -> list[str]:
    """The coefficients' unit text: a raw-readings model's ``a.u.`` is the session's unit of that sensor."""
    units = list(model.units)
    if model.readings != "raw":
        return units
    for slot, unit in (("accel_reading", session.acc_unit), ("gyro_reading", session.gyr_unit)):
        if slot in model.slots and unit != RAW_UNIT:
            for j in model.columns(slot):
                units[j] = units[j].replace(RAW_UNIT, unit)
    return units


def tilted_rows(tilt, S, y, model, slot, cols, static, u, gravity, n_static, Jf, s_i, floor, y_rot, sd_rot):
    """The static rows of `S`, `y` (in place) at the mean specific force of positions tilted by `tilt` rad rms,
    ``g (1 - tilt^2) e``, and their ``whiten`` (:func:`position_whitening`)."""
    S[:3 * n_static], y[:3 * n_static] = static_rows(model, slot, cols, static, u, gravity * (1.0 - tilt**2))
    return position_whitening(static, Jf, s_i, gravity, floor, S[:3 * n_static], y[:3 * n_static],
                               S[3 * n_static:], y_rot, sd_rot)


def static_rows(model, slot, cols, static, u: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """The static means' rows at specific force ``g e_k``: ``S`` (3 per segment) and ``mean(u) - y0``."""
    S, y = [], []
    for s in static:
        f, w = g * s.gravity, np.deg2rad(s.omega_dps)
        S.append(model.jacobian(slot, f, w)[:, cols])
        y.append(u[s.rows].mean(axis=0) - model.known(slot, f, w))
    return np.vstack(S), np.concatenate(y)


def ls_sigma(S: np.ndarray, y: np.ndarray) -> float:
    """Least-squares residual std ``sqrt(RSS / (m - rank))`` (0 without degrees of freedom)."""
    x, _, rank, _ = np.linalg.lstsq(S, y, rcond=None)
    dof = S.shape[0] - rank
    r = y - S @ x
    return float(np.sqrt(r @ r / dof)) if dof > 0 else 0.0


def position_whitening(static, Jf, s_i, g, floor, S_st, y_st, S_rot, y_rot, sd_rot):
    """``whiten(tilt) -> (S_w, y_w)``: the rows whitened by the position-error and noise covariance.

    A static position tilted by a small rotation ``phi ~ N(0, tilt^2 I)`` senses ``f = g (e + phi x e
    - |phi x e|^2 e / 2)``: the mean reading of segment k moves by ``J_f (g phi x e)`` (``J_f = dy/df``),
    whose covariance is ``tilt^2 g^2 J_f P J_f^T``, ``P = I - e e^T`` (tilts do not move the reading
    along gravity to first order), plus the second-order shortfall along e (variance ``g^2 tilt^4``)
    and the sample noise of the mean ``diag(s_i^2 / n_k)``:
    ``V_k = tilt^2 g^2 J_f P J_f^T + g^2 tilt^4 (J_f e)(J_f e)^T + diag(s_i^2 / n_k)``. Rows of segment
    k are multiplied by ``L_k^-1`` (``V_k = L_k L_k^T``); the turns by 1 / their white-noise std.
    """
    blocks = []
    for s, J in zip(static, Jf):
        e = s.gravity
        P = np.eye(3) - np.outer(e, e)
        Je = J @ e
        blocks.append((g**2 * J @ P @ J.T, g**2 * np.outer(Je, Je), np.diag(s_i**2 / len(s.rows)) + floor * np.eye(3)))
    rot_w = 1.0 / sd_rot

    def whiten(tilt: float):
        Sw, yw = [], []
        for k, (A, B, N) in enumerate(blocks):
            L = np.linalg.cholesky(tilt**2 * A + tilt**4 * B + N)
            Sw.append(np.linalg.solve(L, S_st[3 * k:3 * k + 3]))
            yw.append(np.linalg.solve(L, y_st[3 * k:3 * k + 3]))
        return np.vstack(Sw + [S_rot * rot_w[:, None]]), np.concatenate(yw + [y_rot * rot_w])

    return whiten


def solve_tilt(whiten, m: int, n: int) -> float:
    """The position error (rad rms) at which the whitened least-squares residual std is 1.

    `m` rows, `n` the rank of the rows (not the number of coefficients: the six axis positions leave
    some undetermined). 0 when the sample noise alone explains the misfit (or no degree of freedom is
    left); capped at 0.5 rad.
    """
    from scipy.optimize import brentq

    if m <= n:
        return 0.0

    def excess(log_tilt: float) -> float:
        return ls_sigma(*whiten(math.exp(log_tilt))) - 1.0

    if ls_sigma(*whiten(0.0)) <= 1.0:
        return 0.0
    lo, hi = math.log(1e-9), math.log(0.5)
    if excess(lo) <= 0.0:
        return math.exp(lo)
    if excess(hi) > 0.0:
        return 0.5
    return math.exp(brentq(excess, lo, hi, xtol=1e-10))


def sensor_rows(model: CalibrationModel, slot: str, cols: np.ndarray, static: Sequence[Segment],
                rots: Sequence[Segment], u: np.ndarray, t: np.ndarray, gravity: float, rate: float, weighting: str,
                s_i: np.ndarray) -> tuple[np.ndarray, np.ndarray, list, list[tuple[str, int]], list, int]:
    """The unweighted rows of one sensor (readings `u`, output `slot`, coefficient columns `cols`).

    Static segments first (``weighting`` "positions" or "segments": the mean, three rows; "samples":
    three rows per sample), then, for the gyro, one integral per turn (:func:`rotation_row`).

    Returns
    -------
    S, y : ndarray
        Rows ``(m, len(cols))`` and their right-hand side, reading units.
    sd : list
        Per block the rows' noise std (``None``: the static level, estimated by the caller).
    seg : list of (str, int)
        Per block the segment name and its number of row triples.
    times : list of float
        Time of each row triple, s.
    n_static : int
        Number of static blocks.
    """
    rows_S, rows_y, rows_seg, rows_t = [], [], [], []
    rows_sd: list[np.ndarray | None] = []  # None: the static level, estimated
    for s in static:
        f = gravity * s.gravity
        w = np.deg2rad(s.omega_dps)
        J = model.jacobian(slot, f, w)[:, cols]
        y0 = model.known(slot, f, w)
        if weighting in ("positions", "segments"):
            rows_S.append(J)
            rows_y.append(u[s.rows].mean(axis=0) - y0)
            rows_sd.append(None)  # the static level, estimated
            rows_seg.append((s.name, 1))
            rows_t.append(t[s.rows].mean())
        else:
            k = len(s.rows)
            rows_S.append(np.broadcast_to(J, (k, 3, len(cols))).reshape(-1, len(cols)))
            rows_y.append((u[s.rows] - y0).reshape(-1))
            rows_sd.append(np.tile(s_i, k))
            rows_seg.append((s.name, k))
            rows_t.extend(t[s.rows])
    n_static = len(rows_S)
    if slot == "gyro_reading":
        for s in rots:
            y_k, J, _, dt = rotation_row(model, slot, s, u, gravity, rate, t)
            rows_S.append(J[:, cols])
            rows_y.append(y_k)
            rows_sd.append(s_i * math.sqrt(float(dt @ dt)))  # white noise integrated: s sqrt(sum dt^2)
            rows_seg.append((s.name, 1))
            rows_t.append(t[s.rows].mean())
    S = np.vstack([np.atleast_2d(x).reshape(-1, len(cols)) for x in rows_S])
    y = np.concatenate([np.ravel(x) for x in rows_y])
    return S, y, rows_sd, rows_seg, rows_t, n_static
