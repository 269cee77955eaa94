"""A strapdown telemetry's velocity error against its attitude: the sign of each ``dv_*`` axis and the frame.

A strapdown telemetry file that gives ``dv_*`` beside the attitude ``q_*`` (``docs/reference/file-formats.md``)
states two things no column check sees: that each ``dv`` axis has the sign of telemetry minus tracking, and that
``dv`` is in the navigation frame the attitude rotates body vectors into. S_V carries the body-frame errors to the
navigation frame through the attitude, so a ``dv`` axis of the other sign, or an attitude turned against ``dv``'s
frame, is a design the coefficients partly fit: the noise model absorbs the rest (``dv_z`` negated on the
simulated strapdown boost: sigma 0.108 -> 0.176 m/s, tau 0.97 -> 3.8 s, the coefficients 3-4.6 std off, exit 0;
the attitude 3 deg off in azimuth: ``sa_x`` 3.4 std off, exit 0). Both are tested on the rows themselves.

**The sign of each dv axis** (:func:`dv_sign_record`), as the gyro's sign is on the pad
(:func:`casep.navigation.alignment.pad_rate_causes`): each axis negated is a hypothesis with the same design and as
many parameters as the file as given, so their evidence is the ratio of their restricted likelihoods with the noise
model refitted (Gauss-Markov plus white on every axis, REML: :func:`casep.noise.fit.fit_noise`; the richest kind,
so neither is held to a noise the other's misfit chose). The kind's evidence is the mean over its three members
(the look-elsewhere cost of trying three); it is named, with its best member, when that exceeds
:data:`SIGN_NAME_FACTOR` times the evidence of the file as given and the member explains the
rows to within the noise: its fit leaves no misfit by the rule that judges every result
(:func:`casep.checks.plausibility.misfit_problem`), the pad's two conditions. Two axes negated are the third
negated with every coefficient of the other sign (the same residuals): the message says so. All three negated fit
as well as none (every coefficient of the other sign): the rows cannot tell. A sign is checked where its negation is
below ``1/CAUSE_FACTOR`` as likely as the file as given (the simulated boosts as written: e^-29 and below); on a short
record the rows cannot tell (the first 20 s: every negation within a factor 30), and the result says which signs
are not checked (:func:`dv_sign_unchecked`).

**The frame** (:func:`frame_record`): the attitude turned by a constant small rotation ``rho`` (rad, about the
navigation axes) against ``dv``'s frame, ``C_given = R(rho) C``, makes S_V the turned one, ``S_given = R S``
(every term of a body-frame model and ``f x phi`` alike), so the rows are ``y = R^T S_given x + e``, to first order
``y = S_given x + [(S_given x) x e_k] rho_k + e``: the rotation about each axis is one more coefficient whose
column is the model's velocity error turned about that axis (``x`` the current estimate). The model is turned, not
the rows: turning the rows turns their noise with them, and a turn of isotropic noise costs nothing, so the
rows' own ``y x e_k`` as the column drifted about a poorly determined axis (5 deg about z, 5.4 of its
under-stated std, on a correct flight). The rotation is located by least squares (white noise, the design turned
by the rotation found and the step estimated again, Gauss-Newton, until it is below a tenth of its std: a
rotation of degrees leaves a second-order remainder the first-order column does not take, and a noise model
fitted over it absorbs the turn: 10 deg in azimuth estimated at 0.6 +- 0.9 in one step), then tested at the
rotation located as the heading is (:func:`casep.workflows.imu_separate.heading_conflict`'s rule,
:func:`casep.workflows.row_estimators.column_estimates`: the three columns with the noise refitted beside them,
:func:`casep.workflows.imu_separate.with_columns_noise`, S_V projected out, the fit's whitening): the rotation is
the one located plus that last step, each axis's std that of its estimator. The frames are stated to agree, so the
stated std is 0 and an axis beyond :data:`casep.estimators.rls.PRIOR_CONFLICT_Z` std is a rotation the data
determine, where the linear model holds out to it (located, and the last step below half the rotation, the
heading's confirmation) and the axis is determined well enough for that (its std times the limit within
:data:`FRAME_LARGE_DEG`: about the cross-range axis, known to 5-7 deg on the simulated boost, the steps of a
correct flight wandered to 22 deg, z 3.7). The heading of a raw-IMU separation is the same test about the
vertical with a stated std. The fits take the coefficients without an estimate of a rank-deficient design (the
default strapdown33 on a boost, rank 21 of 33) as the fit's own solution does
(:meth:`casep.estimators.result.EstimateResult.fitted_coefficients`). An axis is checked where it is judged and the
rotation located; the others are said in the result's message (:func:`frame_unchecked`), and a judged axis beyond
:data:`FRAME_WARN_Z` std warns whether or not the rotation was located.

A named sign or rotation fails the result with the status of a set-up mistake (``STATUS_SETUP``), naming the
column or the rotation and what to do; a rotation beyond :data:`FRAME_WARN_Z` std but within the limit is a
:class:`casep.exceptions.SetupWarning` with its size. Not on noise-free rows (no noise to test against), nor on a
flight that failed a set-up check already (its rows are that mistake).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import numpy as np

from casep.estimators.result import EstimateResult
from casep.io.flight import FlightData
from casep.workflows.imu_separate import SMALL_ANGLE_REACH_DEG, within_small_angle_reach

__all__ = ["dv_sign_record", "dv_sign_unchecked", "frame_record", "frame_unchecked", "judge_frame",
           "FRAME_STEPS", "FRAME_AXES", "FRAME_LARGE_DEG",
           "FRAME_WARN_Z", "SIGN_NAME_FACTOR"]

#: At most this many least-squares steps locate the frame's rotation (each turns the design by the rotation found).
FRAME_STEPS = 8
#: The navigation axes the rotation is named about (casep's launch-inertial frame: y up at the launch point).
FRAME_AXES = ("x (downrange at the launch azimuth)", "y (up at the launch point: an azimuth)", "z (cross-range)")
#: A rotation beyond this many std on an axis but within the failing limit (PRIOR_CONFLICT_Z) is a warning: on the
#: simulated strapdown boost (10 and 20 Hz, 12 seeds) 3 deg in azimuth is determined at 2.7-5.7 std (9 of 12 beyond
#: 4) while it moves sa_x by up to 7 std; 40 flights as simulated (10, 20, 50 Hz) reached 3.7 at most (Gaussian:
#: 2e-4 of correct flights beyond 4 on one of three axes). ``python benchmarks/telemetry_frame_mc.py``.
FRAME_WARN_Z = 4.0
#: A rotation located beyond this (deg) is said as a large one: the small-angle column locates a local fit there, not
#: the rotation (the attitude 90 deg about x located at 122 deg about another axis), so it is named as indicative.
FRAME_LARGE_DEG = SMALL_ANGLE_REACH_DEG
_AXES = "xyz"


def applies(flight: Any) -> bool:
    """Whether `flight` is a strapdown telemetry file (``q_*``, ``fb_*``, ``w_*``) read from one file, not a pair
    (a pair's passes re-navigate: :mod:`casep.workflows.telemetry_iterate`)."""
    meta = flight.meta if isinstance(flight, FlightData) and isinstance(flight.meta, dict) else {}
    return isinstance(meta.get("strapdown"), dict) and meta.get("format") != "pair"


#: The evidence of a dv axis negated over the file as given beyond which it is named (with the fit's misfit rule):
#: e^16. Not the pad's :data:`casep.navigation.alignment.CAUSE_FACTOR` (300): with the noise refitted per hypothesis,
#: correct records cut to 60 s gave a negation up to e^8.4 (50 Hz, seed 100: 2.2e3 on the mean of the three) and
#: full ones below e^-21.7, while a negated axis gave e^33 to e^66 on every full simulated boost at 10-50 Hz.
SIGN_NAME_FACTOR = math.exp(16.0)


def dv_sign_record(problem: Any, flight: FlightData, spec: Any) -> dict | None:
    """The test of each ``dv`` axis's sign (module notes): ``{"ln_ratio": [x, y, z], "factor", "best", "explains",
    "named", "checked", "rule"}`` (``ln_ratio`` the log-evidence of each axis negated over the file as given;
    ``named`` the column, or None; ``checked`` the columns whose negation the rows reject, less likely than the file
    as given by more than ``limit_factor``: the others' signs the rows cannot tell), or None without the noise fits."""
    from casep.checks.plausibility import misfit_problem
    from casep.navigation.alignment import CAUSE_FACTOR
    from casep.noise.fit import fit_noise
    from casep.workflows.imu_separate import _quiet_fit

    y = np.asarray(problem.y, dtype=float)
    flips = []
    for a in range(3):
        yy = y.copy()
        yy[:, a] = -yy[:, a]
        flips.append(yy)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the hypotheses' noise fits: judged here, not said
            given = float(fit_noise(problem, "gmw").extra["neg2_reml"])
            ln = np.array([(given - float(fit_noise(problem.with_y(yy), "gmw").extra["neg2_reml"])) / 2.0
                           for yy in flips])
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(ln)):
        return None
    top = float(ln.max())
    log_mean = top + math.log(float(np.mean(np.exp(ln - top))))  # the kind's mean evidence over its three members
    factor = math.exp(min(700.0, log_mean))
    k = int(np.argmax(ln))
    record: dict[str, Any] = {"ln_ratio": ln.tolist(), "factor": factor, "limit_factor": CAUSE_FACTOR,
                              "best": f"dv_{_AXES[k]}", "explains": None, "named": None,
                              "checked": [f"dv_{a}" for a, v in zip(_AXES, ln) if v < -math.log(CAUSE_FACTOR)],
                              "rule": "each dv axis negated against the file as given: restricted likelihoods with "
                                      "the noise refitted (Gauss-Markov plus white), the mean evidence over the three "
                                      "beyond name_factor and the best one's fit leaving no misfit (misfit_problem); "
                                      "an axis checked where its negation is below 1/limit_factor"}
    record["name_factor"] = SIGN_NAME_FACTOR
    if factor < SIGN_NAME_FACTOR:
        return record
    alt = _quiet_fit(problem.with_y(flips[k]), spec)
    why = misfit_problem(flight, alt.residual_rms, (), noise=alt.diagnostics.get("noise"))
    record["explains"] = why is None
    record["residual_rms_negated"] = {a: float(v) for a, v in (alt.residual_rms or {}).items() if v is not None}
    if why is None:
        record["named"] = f"dv_{_AXES[k]}"
    return record


def dv_sign_message(record: dict, given_rms: dict | None) -> str:
    """What a result says when a ``dv`` axis's sign is named (:func:`dv_sign_record`)."""
    col = record["named"]
    others = [f"dv_{a}" for a in _AXES if f"dv_{a}" != col]
    neg = record.get("residual_rms_negated") or {}
    rms = ", ".join(f"{a} {neg[a]:.3g}" for a in _AXES if a in neg)
    was = ", ".join(f"{a} {float(given_rms[a]):.3g}" for a in _AXES if given_rms and a in given_rms)
    return (f"{col} looks negated: with its sign changed the rows are {record['factor']:.3g} times as likely as "
            f"the file as given (restricted likelihoods with the noise refitted, each dv axis's sign tried; beyond "
            f"{record['name_factor']:.3g} named) and the fit leaves residuals the noise explains (RMS {rms} m/s; as "
            f"given {was} m/s); equally {others[0]} and {others[1]} negated with every coefficient of the other sign. "
            f"The noise model absorbs the misfit of a dv axis of the wrong sign and the estimates are off by more "
            f"than their std say: check {col}'s sign (dv = v_tel - v_trk, in the frame of q_*), negate it and "
            f"run again")


def dv_sign_unchecked(record: dict | None) -> str | None:
    """What a result says of the ``dv`` axes whose sign the rows cannot tell (:func:`dv_sign_record`: an axis negated
    not below ``1/limit_factor`` as likely as the file as given), or None when every sign is checked."""
    from casep.navigation.alignment import CAUSE_FACTOR

    if record is None:
        return "the dv signs are not checked on this record (no noise fit to weigh them with)"
    left = [f"dv_{a}" for a in _AXES if f"dv_{a}" not in record["checked"]]
    if not left:
        return None
    ratios = ", ".join(f"{a} {math.exp(min(700.0, v)):.3g}" for a, v in zip(_AXES, record["ln_ratio"]))
    also = ""
    if record["factor"] >= CAUSE_FACTOR and record["explains"] is False:
        also = f"; {record['best']} negated is favoured but its fit leaves residuals the noise does not explain"
    elif record["factor"] >= CAUSE_FACTOR:
        also = (f"; {record['best']} negated is favoured by {record['factor']:.3g}, below the {SIGN_NAME_FACTOR:.3g} "
                "that names a sign: correct records cut short reach such factors")
    return (f"the sign of {', '.join(left)} is not checked on this record: the rows cannot tell (with each dv axis "
            f"negated they are {ratios} times as likely as the file as given; a sign is checked where its negation "
            f"is below 1/{CAUSE_FACTOR:g} as likely{also})")


def _turned(S: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """The design `S` (N, 3, n) of the attitude turned back by the rotation vector `rho` (rad): ``R(rho)^T S`` row by
    row (module notes)."""
    from casep.rotations import quat_from_rotvec, quat_to_dcm

    return np.einsum("ji,njk->nik", quat_to_dcm(quat_from_rotvec(np.asarray(rho, float))), S)


def _composed(step: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """The rotation vector of ``R(rho) R(step)`` (rad): `rho` turned further by `step` about the turned axes."""
    from casep.rotations import quat_from_rotvec, quat_multiply, quat_to_rotvec

    return quat_to_rotvec(quat_multiply(quat_from_rotvec(np.asarray(rho, float)),
                                        quat_from_rotvec(np.asarray(step, float))))


def _columns(v: np.ndarray) -> np.ndarray:
    """The rows' derivative along a rotation of the attitude about each navigation axis, (N, 3, 3), m/s per deg:
    ``v x e_k``, `v` (N, 3) the velocity error the model predicts (module notes)."""
    E = np.eye(3)
    return np.stack([np.cross(v, E[k]) for k in range(3)], axis=2) * (math.pi / 180.0)


def _located(problem: Any, S: np.ndarray, y: np.ndarray, names: list[str],
             locating: Any) -> tuple[np.ndarray, bool] | None:
    """The rotation (rad) that least squares locates with the fit `locating` (module notes: the design turned by
    it, Gauss-Newton steps until one is below a tenth of its std) and whether it was located within
    :data:`FRAME_STEPS`."""
    from casep.regression.problem import Problem
    from casep.workflows.imu_separate import _quiet_fit

    rho = np.zeros(3)
    for _ in range(FRAME_STEPS):
        Sc = _turned(S, rho)
        try:
            x = _quiet_fit(Problem.from_arrays(Sc, y, problem.t, names=names[:-3]), locating).fitted_coefficients()
            loc = _quiet_fit(Problem.from_arrays(np.concatenate([Sc, _columns(Sc @ x)], axis=2),
                                                 y, problem.t, names=names), locating)
        except (ValueError, np.linalg.LinAlgError):
            return None
        if loc.std is None:
            return None
        step, sd = np.asarray(loc.estimate[-3:], float), np.asarray(loc.std[-3:], float)
        if not np.all(np.isfinite(step)):
            return None
        rho = _composed(np.radians(step), rho)
        if np.all(np.abs(step) <= 0.1 * sd):
            return rho, True
    return rho, False


def frame_record(res: EstimateResult, problem: Any, flight: FlightData, spec: Any, locating: Any) -> dict | None:
    """The attitude's rotation against ``dv``'s frame (module notes): ``{"rotation_deg", "std_deg", "z", "located",
    "last_step_deg", "conflict", ...}`` (deg about the navigation axes x, y, z), or None without a noise model.
    `spec` the fit as asked (the test's noise), `locating` the least-squares fit that locates the rotation
    (:data:`casep.workflows.separate.LOCATING_FIT`, the time offset's)."""
    from casep.estimators.rls import PRIOR_CONFLICT_Z
    from casep.regression.problem import Problem
    from casep.workflows.imu_separate import _quiet_fit, with_columns_noise
    from casep.workflows.row_estimators import column_estimates

    y = np.asarray(problem.y, dtype=float)
    S = problem.sv()
    names = [*res.names, "rot_x", "rot_y", "rot_z"]
    found = _located(problem, S, y, names, locating)
    if found is None:
        return None
    rho, located = found
    there = Problem.from_arrays(_turned(S, rho), y, problem.t, names=list(res.names))
    try:
        x = _quiet_fit(there, locating).fitted_coefficients()
    except (ValueError, np.linalg.LinAlgError):
        return None
    cols = _columns(there.sv() @ x)
    noise = with_columns_noise(res, there, cols, spec, names[-3:])
    est = column_estimates(noise, there, flight, cols)
    if est is None:
        return None
    last, std = np.asarray(est[0], float), np.asarray(est[1], float)
    total = np.degrees(_composed(np.radians(last), rho))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(std > 0, np.abs(total) / std, 0.0)
    # an axis is judged where the flight determines it well enough that a rotation at the limit is within the
    # small-angle reach (std times the limit within FRAME_LARGE_DEG): about a poorly determined axis (the cross-range
    # z, 5-7 deg) the steps wander to tens of degrees, where the first-order std no longer describes the estimate
    judged = within_small_angle_reach(std, PRIOR_CONFLICT_Z)
    beyond, seen = judged & (z > PRIOR_CONFLICT_Z), judged & (z > FRAME_WARN_Z)

    def reach(axes: np.ndarray) -> bool:
        # the linear model holds out to the rotation located: on each axis named the last step there is below half
        # of the rotation found (the heading's rule: the estimate at the heading the data point to)
        return bool(located and np.any(axes) and np.all(np.abs(last[axes]) < 0.5 * np.abs(total[axes])))

    conflict = reach(beyond)
    # an axis is checked where it is judged and the rotation located; a judged axis beyond the warning's z is said
    # whether or not the rotation was located or the linear model confirmed out to it
    checked = judged if located else np.zeros(3, dtype=bool)
    return {"rotation_deg": total.tolist(), "std_deg": std.tolist(), "z": z.tolist(), "limit_z": PRIOR_CONFLICT_Z,
            "warn_z": FRAME_WARN_Z, "judged": [a for a, j in zip(_AXES, judged) if j],
            "checked": [a for a, c in zip(_AXES, checked) if c],
            "located": located, "last_step_deg": last.tolist(),
            "conflict": conflict, "warn": bool(not conflict and np.any(seen)),
            "rule": "the attitude's rotation about each navigation axis as three more coefficients (the rows' "
                    "derivative along it, (S x) x e_k), located by least squares with the design turned by it, then "
                    "its GLS estimate there with the noise refitted beside it (column_estimates, heading_conflict's "
                    "rule); stated 0, beyond limit_z std on an axis: the frames differ"}


def frame_message(record: dict, warn: bool = False) -> str:
    """What a result says when the attitude's frame is turned against ``dv``'s (:func:`frame_record`); `warn`: the
    rotation is beyond :data:`FRAME_WARN_Z` std but within the limit that fails a result."""
    rot, sd, z = (np.asarray(record[k], float) for k in ("rotation_deg", "std_deg", "z"))
    k = int(np.argmax(np.where([a in record["judged"] for a in _AXES], z, -1.0)))
    each = ", ".join(f"{rot[i]:+.3g} +- {sd[i]:.2g} deg about {_AXES[i]} (z {z[i]:.3g})" for i in range(3))
    angle = float(np.linalg.norm(rot))
    if angle > FRAME_LARGE_DEG:
        return (f"the attitude (q_*) and the velocity error (dv_*) are in navigation frames far apart: the rows fit "
                f"best with the attitude turned by about {angle:.3g} deg ({each}; beyond {FRAME_LARGE_DEG:g} deg "
                f"the small-angle fit locates a local fit, not the rotation itself) against dv's frame (stated to "
                f"agree). S_V takes the attitude's frame, so the coefficients absorb the turn: give q_* and dv_* in "
                f"one navigation frame (casep's launch-inertial frame: y up at the launch point, x downrange at the "
                f"launch azimuth; q_* rotating body vectors into it) and run again")
    if warn:
        how = (f"beyond {FRAME_WARN_Z:g} std but within the {record['limit_z']:g} that fail a result"
               if z[k] <= record["limit_z"] else
               f"beyond the {record['limit_z']:g} std that fail a result, but not confirmed (the rotation "
               f"{'located, the linear model not holding out to it' if record['located'] else 'not located'})")
        return (f"the rows point to the attitude (q_*) turned against dv's frame by {each}, mostly about "
                f"{FRAME_AXES[k]}: {how}. If q_* and dv_* may be in different navigation frames, check: S_V takes "
                f"the attitude's frame and the coefficients absorb such a turn (3 deg in azimuth moved sa_x by up "
                f"to 7 std on a simulated boost)")
    return (f"the attitude (q_*) and the velocity error (dv_*) are in navigation frames {angle:.3g} deg apart: the "
            f"rows put the attitude turned by {each} against dv's frame (stated to agree; beyond "
            f"{record['limit_z']:g} std named), mostly about {FRAME_AXES[k]}. S_V takes the attitude's frame, so the "
            f"coefficients absorb the turn and are off by more than their std say: give q_* and dv_* in one "
            f"navigation frame (casep's launch-inertial frame: the azimuth, launch point and axes that dv_* were "
            f"written in), or turn the attitude back (q <- r q, r the rotation by "
            f"{', '.join(f'{-v:+.3g}' for v in rot)} deg about x, y, z), and run again")


def frame_unchecked(record: dict | None) -> str | None:
    """What a result says of the navigation axes its frame test does not check (:func:`frame_record`: the rotation
    not located, or an axis not judged), or None when every axis is checked."""
    if record is None:
        return "the frame of q_* against dv_* is not checked on this record (no fit of its rotation)"
    left = [a for a in _AXES if a not in record["checked"]]
    if not left:
        return None
    rot, sd, z = (np.asarray(record[k], float) for k in ("rotation_deg", "std_deg", "z"))
    each = ", ".join(f"{rot[i]:+.3g} +- {sd[i]:.2g} deg about {_AXES[i]} (z {z[i]:.3g})" for i in range(3))
    why = ("the least-squares steps did not settle on a rotation" if not record["located"] else
           f"known to +- {', '.join(f'{sd[_AXES.index(a)]:.2g}' for a in left)} deg: a rotation at the "
           f"{record['limit_z']:g} std that fail would be beyond the {FRAME_LARGE_DEG:g} deg the small-angle test "
           f"reaches")
    return (f"the frame of q_* against dv_* is not checked about {', '.join(left)} on this record ({why}; the rows "
            f"put the attitude turned by {each})")


def judge_frame(res: EstimateResult, flight: Any, problem: Any, spec: Any, locating: Any) -> EstimateResult:
    """`res` failed (``STATUS_SETUP``) when a strapdown telemetry file's ``dv`` axis looks negated
    (:func:`dv_sign_record`, files with ``dv_*``) or its attitude is turned against ``dv``'s frame
    (:func:`frame_record`); the records in ``diagnostics["dv_signs"]`` and ``diagnostics["frame"]``; the signs and
    axes the rows do not check said in its message (:func:`dv_sign_unchecked`, :func:`frame_unchecked`). Anything but a
    strapdown telemetry file (:func:`applies`), noise-free rows or a flight that failed a set-up check: `res`.
    `spec` the fit as asked, `locating` the least-squares fit that locates a rotation (:func:`frame_record`)."""
    from casep.checks.plausibility import setup_problems
    from casep.estimators.registry import STATUS_SETUP, failed
    from casep.exceptions import SetupWarning

    if not applies(flight) or problem.y is None or problem.t is None or setup_problems(flight):
        return res
    if problem.is_noise_free():
        return res
    notes = []
    if flight.meta.get("dv") == "dv":
        signs = dv_sign_record(problem, flight, spec)
        if signs is not None:
            res.diagnostics["dv_signs"] = signs
            if signs["named"] is not None:
                said = dv_sign_message(signs, res.residual_rms)
                warnings.warn(f"{flight.source}: {said}", SetupWarning, stacklevel=3)
                return failed(res, STATUS_SETUP, f"failed: {flight.source}: {said}")
        notes.append(dv_sign_unchecked(signs))
    record = frame_record(res, problem, flight, spec, locating)
    if record is not None:
        res.diagnostics["frame"] = record
        if record["conflict"]:
            said = frame_message(record)
            warnings.warn(f"{flight.source}: {said}", SetupWarning, stacklevel=3)
            return failed(res, STATUS_SETUP, f"failed: {flight.source}: {said}")
        if record["warn"]:
            warnings.warn(f"{flight.source}: {frame_message(record, warn=True)}", SetupWarning, stacklevel=3)
    notes.append(frame_unchecked(record))
    said = "; ".join(n for n in notes if n)
    return dataclasses.replace(res, message=f"{res.message}; {said}") if said else res
