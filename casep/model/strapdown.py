"""Strapdown inputs of a model file: the INS attitude, body specific force and body rate as symbols.

A strapdown flight carries, beside ``t`` and ``v_tel_*`` / ``dv_*``, the columns of
:data:`STRAPDOWN_COLUMNS` (``docs/reference/file-formats.md``):

- ``q_w, q_x, q_y, q_z``: the INS attitude, a Hamilton unit quaternion, scalar first, rotating
  body vectors into the navigation frame (casep's launch-inertial frame, :mod:`casep.frames`):
  ``v_nav = C(q) v_body``;
- ``fb_x, fb_y, fb_z``: the measured body specific force, m/s^2;
- ``w_x, w_y, w_z``: the measured body rate (inertial, in body axes), rad/s.

A model file reads them with ``model.signal(name)``; :func:`strapdown_inputs` does it once and
returns the body-to-navigation matrix, built from the quaternion in its homogeneous form::

    C(q) = (1 / |q|^2) [[w^2+x^2-y^2-z^2, 2(xy - wz),       2(xz + wy)      ],
                        [2(xy + wz),       w^2-x^2+y^2-z^2, 2(yz - wx)      ],
                        [2(xz - wy),       2(yz + wx),       w^2-x^2-y^2+z^2]]

(q and -q give the same C, so a sign flip of the quaternion changes nothing here). The errors act
in body axes and reach the navigation frame through C; the model's slots take them as

    gyro_drift  = phidot = -C delta_w        (attitude error, INS attitude = (I - [phi x]) true)
    accel_error = Delta  =  C delta_f        (so dv_dot = C delta_f + f_nav x phi)

with the navigation-frame specific force ``f_nav = C fb`` as the model's ``m.f``.

Numerically, :func:`body_errors` evaluates a set-up model's errors in body axes at given inputs and
coefficients from the model's own outputs (``delta_f = C^T Delta``, ``delta_w = -C^T phidot``), and
:func:`corrected_imu` inverts them: the IMU record the sensors would have given without the errors.
Both use the model file's equations themselves, never a copy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from casep.io.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS, STRAPDOWN_COLUMNS

if TYPE_CHECKING:
    import casadi as ca

__all__ = ["corrected_attitude", "correction_errors",
           "QUATERNION_COLUMNS", "BODY_FORCE_COLUMNS", "BODY_RATE_COLUMNS", "STRAPDOWN_COLUMNS",
           "quaternion_dcm", "strapdown_inputs", "body_errors", "corrected_imu", "imu_error_signals", "input_scaling",
           "not_inverted",
           "CORRECTION_TOL", "CORRECTION_FLOOR", "CORRECTION_MAX_STEPS", "CORRECTION_GROWING"]

#: The fixed-point inversion of :func:`corrected_imu` stops when a step moves no input by more than this
#: relative amount (a few units in the last place of a double), relative to the rounding of what forms the step:
#: the largest norm of the measured, corrected or error vectors (force and rate each their own) over the record.
#: The measured inputs alone are no such scale: a lateral specific force measured at 1e-6 m/s^2 whose
#: misalignment error is 0.05 m/s^2 is corrected to 0.05, whose last digit moves 7e-18, 4.5e-12 of 1.5e-6.
CORRECTION_TOL = 1e-15
#: ... or when it no longer contracts below this (the rounding of the errors' own evaluation, the rotations
#: to the navigation frame and back amplified by the map's own gain) ...
CORRECTION_FLOOR = 1e-12
#: ... or after this many steps: not converged (sensor errors too large for the record to be invertible) ...
CORRECTION_MAX_STEPS = 60
#: ... or once each of this many steps in a row moved the inputs more than the one before: diverging.
CORRECTION_GROWING = 3



def corrected_attitude(C_ins: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The body -> navigation attitude (3, 3) an estimated attitude error `phi` (rad, navigation frame) says is
    true: ``INS = (I - [phi x]) true`` to first order (module notes), so ``true = R(phi) INS``, ``R(phi)`` the
    rotation by the vector `phi` (``I + [phi x]`` to first order, and a rotation whatever its size).

    The one rule for every start attitude corrected by a model's ``phi0`` (a pass of the iterated separation
    from raw IMU data, a window of a long record) and for an attitude carried on by ``phi(T)``.
    """
    from casep.rotations import quat_from_rotvec, quat_to_dcm

    return quat_to_dcm(quat_from_rotvec(np.asarray(phi, dtype=float))) @ np.asarray(C_ins, dtype=float)


def correction_errors(m: Any, coefficients: np.ndarray) -> None:
    """Turn an unlocked strapdown model's sensor errors into the first-order errors of :func:`corrected_imu` at
    `coefficients` (natural units): what S_V must integrate for its columns to be the derivative of a
    navigation of the corrected record.

    :func:`corrected_imu` solves ``x + delta(x; D) = x_m`` for the true inputs ``x = (fb, w)``; so at the
    corrected ``x`` (implicit function theorem)::

        d x / d D_j = -(I + K)^{-1} d delta / d D_j,        K = d delta / d x   (6 x 6, at x and D)

    ``K`` holds the scale factors, misalignments and g-sensitivity at `D`: with a MEMS IMU's
    misalignment of 0.02 rad, a bias along the roll axis then also turns the record about a transverse axis
    by 2 % of its size, which is most of what the bias does to the velocity when the thrust is along that axis.
    The model's outputs are replaced by ``C (I + K)^{-1} delta_f`` and ``-C (I + K)^{-1} delta_w`` (the same
    at ``D = 0``, where ``K = 0``). ``K`` is taken with the attitude at the identity (the errors are in body
    axes: :func:`body_errors`) and the navigation-frame specific force ``m.f`` written as ``C fb``; a constant
    ``K`` (errors linear in the inputs) is inverted numerically, else symbolically.
    """
    import casadi as ca

    C, fb, w = strapdown_inputs(m)
    Delta = ca.substitute(m.output("accel_error"), m.f, ca.mtimes(C, fb))
    phidot = ca.substitute(m.output("gyro_drift"), m.f, ca.mtimes(C, fb))
    delta = ca.vertcat(ca.mtimes(C.T, Delta), -ca.mtimes(C.T, phidot))  # body axes: C^T C = I at a unit q
    x = ca.vertcat(fb, w)
    q = ca.vertcat(*(m.signal(c) for c in QUATERNION_COLUMNS))
    K = ca.substitute(ca.jacobian(delta, x), ca.vertcat(q, ca.vertcat(*m.symbols)),
                      ca.SX(ca.vertcat(ca.DM([1.0, 0.0, 0.0, 0.0]), ca.DM(np.asarray(coefficients, float)))))
    if K.is_constant():
        eff = ca.mtimes(ca.DM(np.linalg.inv(np.eye(6) + np.array(ca.DM(ca.evalf(K))))), delta)
    else:
        eff = ca.solve(ca.SX.eye(6) + K, delta)
    m.set_accel_error(ca.mtimes(C, eff[:3]))
    m.set_gyro_drift(-ca.mtimes(C, eff[3:]))


def quaternion_dcm(w: Any, x: Any, y: Any, z: Any) -> ca.SX:
    """Body-to-navigation matrix C(q) of a Hamilton quaternion (scalar first), 3 x 3 CasADi expression.

    The homogeneous form divided by ``|q|^2`` (see the module notes): exact for a unit quaternion,
    a proper rotation for any non-zero one.
    """
    import casadi as ca

    n = w * w + x * x + y * y + z * z
    return ca.vertcat(
        ca.horzcat(w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z),
    ) / n


def strapdown_inputs(m: Any) -> tuple[ca.SX, ca.SX, ca.SX]:
    """``(C, fb, w)`` of an :class:`~casep.model.error_model.ErrorModel` from its strapdown signal columns.

    C (3 x 3) rotates body vectors into the navigation frame (:func:`quaternion_dcm`), fb (3 x 1) is
    the measured body specific force (m/s^2), w (3 x 1) the measured body rate (rad/s).
    """
    import casadi as ca

    C = quaternion_dcm(*(m.signal(c) for c in QUATERNION_COLUMNS))
    fb = ca.vertcat(*(m.signal(c) for c in BODY_FORCE_COLUMNS))
    w = ca.vertcat(*(m.signal(c) for c in BODY_RATE_COLUMNS))
    return C, fb, w


def imu_error_signals(model: Any) -> tuple[str, ...]:
    """The signals (flight columns) a set-up model's IMU errors (``accel_error``, ``gyro_drift``) depend on."""
    import casadi as ca

    fn = model.functions
    sig = ca.SX.sym("s", len(model.signals))
    f, t, D = ca.SX.sym("f", 3), ca.SX.sym("t"), ca.SX.sym("D", model.n_coefficients)
    out = []
    for name in ("Delta", "phidot"):
        args = {"f": f, "t": t, "signals": sig, "D": D}
        value = fn[name].call({k: args[k] for k in fn[name].name_in()})[name]
        out.append(value)
    both = ca.vertcat(*out)
    return tuple(s for i, s in enumerate(model.signals) if ca.depends_on(both, sig[i]))


def body_errors(model: Any, q: np.ndarray, fb: np.ndarray, w: np.ndarray, t: np.ndarray,
                coefficients: np.ndarray,
                signals: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The body-axis sensor errors of a set-up strapdown model at the inputs and coefficients given.

    ``delta_f = C^T Delta(f_nav, t, signals, D)`` and ``delta_w = -C^T phidot(...)``, each (N, 3), from
    the model's own outputs (the model file states ``accel_error = C delta_f`` and
    ``gyro_drift = -C delta_w``), with ``C = C(q)`` and ``f_nav = C fb``.

    Parameters
    ----------
    model : ErrorModel
        Set up; its IMU errors may use the signals ``q_*``, ``fb_*``, ``w_*`` only.
    q : (N, 4) ndarray
        Attitude, Hamilton, scalar first, body -> navigation.
    fb, w : (N, 3) ndarray
        Body specific force (m/s^2) and rate (rad/s) at which the errors are evaluated.
    t : (N,) ndarray
        Time since the flight's first sample, s.
    coefficients : (n,) ndarray
        In the model's natural units.
    signals : dict, optional
        Further flight columns the errors use (name -> (N,) array at the same samples), beside ``q_*``,
        ``fb_*``, ``w_*`` (a window flight's ``ground_speed``).
    """
    from casep.io.strapdown import quaternion_dcm_array

    cols = {**{k: np.asarray(v, float) for k, v in (signals or {}).items()},
            **dict(zip(QUATERNION_COLUMNS, np.asarray(q, float).T)), **dict(zip(BODY_FORCE_COLUMNS, fb.T)),
            **dict(zip(BODY_RATE_COLUMNS, w.T))}
    missing = [c for c in model.signals if c not in cols]
    if missing and set(missing) & set(imu_error_signals(model)):
        raise ValueError(f"model `{model.name}`: its IMU errors use column(s) "
                         f"{', '.join(sorted(set(missing) & set(imu_error_signals(model))))}, which raw IMU data "
                         "do not have (a strapdown model's sensor errors use q_*, fb_*, w_* and the columns passed "
                         "as signals only)")
    n = len(t)
    C = quaternion_dcm_array(q)
    values = {"f": np.einsum("kij,kj->ki", C, fb).T, "t": np.asarray(t, float)[None, :],
              "signals": np.array([cols.get(c, np.zeros(n)) for c in model.signals]),
              "D": np.repeat(np.asarray(coefficients, float)[:, None], n, 1)}
    from casep.model.sv import evaluate_samples

    fn = model.functions
    delta, phidot = (evaluate_samples(fn[k], values, n) for k in ("Delta", "phidot"))
    return np.einsum("kji,kj->ki", C, delta), -np.einsum("kji,kj->ki", C, phidot)


def corrected_imu(model: Any, q: np.ndarray, fb_measured: np.ndarray, w_measured: np.ndarray, t: np.ndarray,
                  coefficients: np.ndarray, *, start: tuple[np.ndarray, np.ndarray] | None = None,
                  signals: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The IMU record without the model's errors: the inverse of ``measured = true + error(true)``.

    The model's sensor errors are functions of the true inputs (:func:`body_errors`: the forward law
    a simulator applies), so the true body specific force and rate solve, sample by sample::

        fb + delta_f(fb, w; D) = fb_measured,     w + delta_w(fb, w; D) = w_measured

    found by the fixed-point iteration ``x_{k+1} = x_measured - delta(x_k)`` from ``x_0 = x_measured``
    (or `start`)
    (``x = (fb, w)``). It contracts by the size of the errors' dependence on the inputs (scale
    factors, misalignments, g-sensitivity: 1e-2 for a MEMS IMU, so each step gains two digits) and
    stops when a step moves no input by more than :data:`CORRECTION_TOL` of the largest force or rate vector of
    the record (measured, corrected or error: the rounding of the step's terms), or no longer contracts below
    :data:`CORRECTION_FLOOR` of it (the rounding of the errors' own evaluation). For strapdown33
    this is the closed form ``fb = (I + M_a)^{-1} (fb_m - b_a)``, ``w = (I + M_g)^{-1} (w_m - b_g -
    G fb / g0)`` (``M`` scale factors on the diagonal, misalignments off it, ``G`` g-sensitivity),
    which the tests check.

    Parameters
    ----------
    model, q, t, coefficients
        As :func:`body_errors` (`q` the attitude at which the model's navigation-frame outputs are
        turned back into body axes; a body-axis model does not depend on it).
    fb_measured, w_measured : (N, 3) ndarray
        The measured body specific force (m/s^2) and rate (rad/s).
    start : (fb, w), optional
        Where the iteration starts (default the measured record): a correction at nearby coefficients.
    signals : dict, optional
        Further flight columns the errors use (:func:`body_errors`).

    Raises
    ------
    ValueError
        The iteration does not converge in :data:`CORRECTION_MAX_STEPS` steps, or diverges (each of
        :data:`CORRECTION_GROWING` steps in a row larger than the one before) (errors of the order of
        the inputs themselves: a scale factor near -100 %, or coefficients far off).
    """
    fb_m, w_m = np.asarray(fb_measured, float), np.asarray(w_measured, float)
    fb, w = (fb_m.copy(), w_m.copy()) if start is None else (np.asarray(start[0], float), np.asarray(start[1], float))

    def norms(*vectors: np.ndarray) -> float:  # the largest row norm of a vector group over the record
        return max(float(np.sqrt(np.einsum("ki,ki->k", v, v)).max(initial=0.0)) for v in vectors)

    measured = (max(norms(fb_m), 1e-300), max(norms(w_m), 1e-300))
    moved, size, growing, n_steps = np.inf, np.inf, 0, 0
    last = np.full(6, np.nan)  # the last step per column (fb_x .. w_z), of its group's size
    while n_steps < CORRECTION_MAX_STEPS:
        n_steps += 1
        df, dw = body_errors(model, q, fb, w, t, coefficients, signals)
        new_fb, new_w = fb_m - df, w_m - dw
        per_column = (np.abs(new_fb - fb).max(axis=0, initial=0.0), np.abs(new_w - w).max(axis=0, initial=0.0))
        steps = (per_column[0].max(initial=0.0), per_column[1].max(initial=0.0))
        # the rounding of the step: its terms' size (measured, corrected, error), force and rate each
        terms = (max(measured[0], norms(new_fb, df)), max(measured[1], norms(new_w, dw)))
        last = np.concatenate([per_column[0] / measured[0], per_column[1] / measured[1]])
        fb, w = new_fb, new_w
        if not all(np.isfinite(v) for v in (*steps, *terms)):
            break
        moved = max(s / r for s, r in zip(steps, terms))
        # whether it contracts: the step against the fixed measured size (the terms grow with a diverging record)
        size, size_before = max(s / r for s, r in zip(steps, measured)), size
        if moved <= CORRECTION_TOL or (size >= size_before and moved <= CORRECTION_FLOOR):
            return fb, w  # converged, or at the rounding of the error evaluation itself
        growing = growing + 1 if size > size_before else 0
        if growing == CORRECTION_GROWING:
            break  # diverging: no contraction grows that long (the f -> w coupling for one step at most)
    raise ValueError(not_inverted(model, coefficients, last, n_steps))


def input_scaling(model: Any) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The coefficients of a set-up strapdown model that scale or turn its inputs: those on which the derivative
    of the body force errors (first) and of the body rate errors (second) with respect to the inputs (the
    specific force, ``fb_*``, ``w_*``) depends (scale factors, misalignments, g-sensitivity; not the biases). They
    alone decide whether :func:`corrected_imu` inverts: its fixed-point map's derivative is theirs."""
    import casadi as ca

    fn = model.functions
    sig = ca.SX.sym("s", len(model.signals))
    f, t, D = ca.SX.sym("f", 3), ca.SX.sym("t"), ca.SX.sym("D", model.n_coefficients)
    inputs = ca.vertcat(f, *(sig[i] for i, c in enumerate(model.signals)
                             if c in BODY_FORCE_COLUMNS or c in BODY_RATE_COLUMNS))
    out = []
    for name in ("Delta", "phidot"):
        args = {"f": f, "t": t, "signals": sig, "D": D}
        J = ca.jacobian(fn[name].call({k: args[k] for k in fn[name].name_in()})[name], inputs)
        out.append(tuple(n for j, n in enumerate(model.names) if ca.depends_on(J, D[j])))
    return out[0], out[1]


def not_inverted(model: Any, coefficients: np.ndarray, last: np.ndarray, n_steps: int) -> str:
    """Why :func:`corrected_imu` did not invert a record at `coefficients` (natural units): the columns its last
    fixed-point step still moved (`last`, per column ``fb_x .. w_z``, of the largest force or rate of the record)
    and the coefficients that scale those columns' inputs (:func:`input_scaling`), those beyond what a linear
    error model can describe first (:data:`casep.units.LINEAR_LIMITS`: a scale factor or misalignment
    of 0.1)."""
    from casep.units import LINEAR_LIMITS, si_factor

    columns = (*BODY_FORCE_COLUMNS, *BODY_RATE_COLUMNS)
    unsettled = [j for j in np.argsort(-np.nan_to_num(last, nan=np.inf)) if not last[j] <= CORRECTION_FLOOR]
    moved = ", ".join(f"{columns[j]} by {last[j]:.3g}" if np.isfinite(last[j]) else f"{columns[j]} beyond any number"
                      for j in unsettled)
    force, rate = input_scaling(model)
    groups = ({*force} if any(j < 3 for j in unsettled) else set()) | ({*rate} if any(j >= 3 for j in unsettled)
                                                                       else set())
    D = np.asarray(coefficients, float)

    def share(j: int) -> float:  # the coefficient's size against its linear limit (0 without one)
        u = model.units[j]
        return abs(D[j]) * si_factor(u) / LINEAR_LIMITS[u] if u in LINEAR_LIMITS and np.isfinite(D[j]) else 0.0

    involved = sorted((j for j, n in enumerate(model.names) if n in groups and D[j] != 0), key=lambda j: -share(j))
    beyond = [j for j in involved if share(j) >= 1.0]
    def one(j: int) -> str:
        u = model.units[j]
        return f"{model.names[j]} {D[j]:.4g} {u}" + (f" (limit {LINEAR_LIMITS[u] / si_factor(u):.3g})"
                                                     if u in LINEAR_LIMITS else "")

    listed = "; ".join(one(j) for j in (beyond or involved)[:6])
    more = len(beyond or involved) - 6
    listed += f" and {more} more" if more > 0 else ""
    which = (f"beyond what a linear error model can describe: {listed}" if beyond
             else f"largest against what a linear error model can describe: {listed}" if involved
             else "none of them scales the inputs")
    return (f"model `{model.name}`: the sensor errors at the coefficients given do not invert: after {n_steps} "
            f"steps the last fixed-point step still moved {moved or 'no column'} (of the largest force or rate): "
            f"errors as large as the measured rates or forces; the coefficients that scale those columns' inputs are "
            f"{which}")
