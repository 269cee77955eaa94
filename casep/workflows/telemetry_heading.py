"""A strapdown telemetry turned about the vertical against its tracking: the heading of the INS that wrote it.

A strapdown INS aligned on the pad at a wrong heading (``casep navigate --heading``, or a flight computer's) integrates
its specific force turned about the pad's vertical by the heading's error ``h``: ``v_tel - v_0 - int g ~ R_up(h) int
f``, so the rows hold ``dv ~ (R_up(h) - I) V`` (``V`` the specific force integrated from the first sample,
``int C f dt``), to first order ``h e_up x V``, a turn of the boost's velocity. A tracking written in a frame turned
about the vertical (an azimuth off) leaves the same rows. A body-frame model takes part of it into its coefficients
(a misalignment, a gyro bias about the vertical) and the rest looks like a model error or a noise as slow as the
record: the result blamed the model (``casep navigate`` 10 and 3 deg off, then ``casep separate`` on its telemetry:
"a Gauss-Markov noise as slow as the record ... likelier a model error"; the tracking turned by 10 deg: "try
strapdown33").

The test (:func:`telemetry_heading_record`) runs on a telemetry whose linear result failed, and on a success whose
model has no initial attitude error about the vertical (:func:`vertical_attitude_terms`): with one, its ``phi0`` holds
a small turn to first order and the coefficients stay right (``strapdown15_phi0``, ``casep navigate`` 0.5-3 deg off:
the determined combinations' RMS z unchanged, 2.6 and 0.9 on seeds 11 and 12); without one (a flight computer's
telemetry, no alignment line, ``strapdown15_axial``, seeds 11-13 at 10 Hz), a turn of 0.5-1 deg was a plain success on
all three and 2 deg on one, bg_x 8-20 of its std off (the determined combinations at RMS 19-80 std, 3.6-3.8 at the
true heading). The test names 2 deg on all three (z 10-10.5), 1 deg on two (z 5.7, 7.5) and 0.5 deg on none (z
2.4-4.4); on seeds 1-5, 2 deg on five, 1 deg on four (z 5.0-6.4; seed 1, whose clean flight reads +0.26 deg, z
3.7), 0.5 deg on none (z 2.4-3.2) (``benchmarks/telemetry_heading_mc.py``; the hypotheses chosen by least squares, 1
deg was named on one: both coarse scans are smallest at 0 deg with one value, and the tie took the tracking at about
-0.2 deg). A turn not named is carried in the std of such a success (:func:`turn_consider`): bg_x at RMS z 1.03 on the
five seeds 0.5 deg off (10 std off without it), at the cost of bg_x's std 3.6-12 times wider on clean flights (its
RMS z 0.29 over seeds 1-15 at 10 and 20 Hz, where no flight was called turned: z largest 2.6). It costs 0.8-1.2 s of
CPU at 10 Hz, an eighth to a sixth of the separation. The turn about the launch
frame's y axis (up at the launch point, the pad) is located by least squares as the frame's rotation is
(:mod:`casep.workflows.telemetry_frame`: Gauss-Newton, the rows and S_V turned back by the turn found, until a step
is below a tenth of its std; the first-order column does not hold a turn of degrees over a boost of km/s), each
hypothesis on its own profile, and the hypothesis whose located turn has the higher restricted likelihood (the
noise refitted, Gauss-Markov plus white, as the fit's) is taken; then tested there as the raw-IMU path's heading is
(:func:`casep.workflows.imu_separate.heading_conflict`'s rule:
:func:`casep.workflows.row_estimators.column_estimates`, the noise refitted beside the column, S_V projected out;
``z = |turn| / sqrt(stated std^2 + its std^2)`` against :data:`casep.estimators.rls.PRIOR_CONFLICT_Z`). The stated std
is :data:`casep.workflows.imu_separate.HEADING_STD_DEG` where ``casep navigate``'s header says the heading was given,
else 0 (the telemetry and the tracking stated in one frame). A model's own initial attitude error about the vertical
(``phi0`` mapped onto the y axis) is that turn to first order: it is left out of the test's design, which otherwise
could not tell them apart (the first order takes a turn of degrees only in part, the misfit is its second order).
A turn is named (``conflict``) where the test is beyond its limit, the turn was located, the flight determines it
within the small-angle reach (its std times the limit within
:data:`casep.workflows.telemetry_frame.FRAME_LARGE_DEG`) and the rows turned back leave no misfit by the rule that
failed the result (:func:`casep.checks.plausibility.misfit_problem`, the dv sign test's condition): then the heading
is named first (:func:`casep.workflows.imu_separate.heading_first`, status ``STATUS_PRIOR_CONFLICT``).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.estimators.result import EstimateResult
from casep.io.flight import FlightData

__all__ = ["telemetry_heading_record", "telemetry_heading_message", "judge_telemetry_heading", "said_unless_turned",
           "vertical_attitude_terms", "turn_consider", "with_turn_considered", "turn_column"]

#: The launch frame's axis up at the launch point (casep's launch-inertial frame: y up, x downrange).
_UP = 1
#: The turn is scanned over +-SMALL_ANGLE_REACH_DEG in steps of this (deg), the least-squares residual's profile ...
SCAN_STEP_DEG = 3.0
#: ... refined by golden section to this (deg) ...
LOCATE_TOL_DEG = 0.01
#: ... and its std from the restricted likelihood's curvature over plus and minus this (deg).
CURVATURE_STEP_DEG = 0.5


def _turn(a: np.ndarray, rad: float) -> np.ndarray:
    """`a` (N, 3) or (N, 3, n) turned about the launch frame's y axis by `rad` (right-handed)."""
    c, s = math.cos(rad), math.sin(rad)
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.einsum("ij,nj...->ni...", R, a)


def turn_column(rows: np.ndarray) -> np.ndarray:
    """The first-order change (N, 3, m/s per deg) of `rows` (N, 3) turned about the launch frame's y axis by one
    degree (:func:`_turn`'s derivative at 0: ``(a_z, 0, -a_x)`` per rad): the rows' change for a small turn of the
    hypothesis that turns them (:func:`_turned_rows`)."""
    a = np.asarray(rows, dtype=float)
    return np.stack([a[:, 2], np.zeros(a.shape[0]), -a[:, 0]], axis=1) * math.radians(1.0)


def _integrated_force(flight: FlightData) -> np.ndarray:
    """The navigation-frame specific force integrated from the flight's first sample (trapezoid), (N, 3) m/s."""
    return cumulative_trapezoid(flight.f, flight.t)


def _minimum(grid: np.ndarray, scan: np.ndarray, ssr: Any) -> tuple[float, bool]:
    """The turn (deg) at the least-squares profile's minimum: the scan's (`grid`, `scan`) refined between its
    neighbours to :data:`LOCATE_TOL_DEG` by Brent's bounded search (:func:`casep.noise.fit.bounded_minimum`, the
    project's 1-D minimiser; `ssr` the profile), and whether it lies inside the scan (at the scan's edge the
    profile still falls beyond it: the turn is not located, and what is found there is the edge's neighbourhood)."""
    from casep.noise.fit import bounded_minimum

    k = int(np.argmin(scan))
    lo, hi = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, grid.size - 1)])
    return float(bounded_minimum(ssr, lo, hi, LOCATE_TOL_DEG)), 0 < k < grid.size - 1


def _turned_rows(problem: Any, flight: FlightData) -> tuple[np.ndarray, np.ndarray | None] | None:
    """What each hypothesis turns, at the rows of `problem` (N, 3, m/s): the navigation-frame specific force
    integrated from the first sample (the telemetry's heading), and the tracked velocity (the telemetry's,
    interpolated, less dv: a tracking turned in azimuth; None without the telemetry's velocity); None without a
    strapdown telemetry, rows or times."""
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    if not isinstance(meta.get("strapdown"), dict) or problem.y is None or problem.t is None:
        return None
    V = _integrated_force(flight)[np.asarray(flight.observed)]
    y0 = np.asarray(problem.y, dtype=float)
    if V.shape != y0.shape:
        return None
    inp = meta.get("pair_inputs")
    if inp is None or getattr(inp, "v_tel", None) is None:
        return V, None
    t_obs = np.asarray(problem.t, float)
    v_tel = np.column_stack([np.interp(t_obs, np.asarray(inp.t_tel, float), np.asarray(inp.v_tel, float)[:, i])
                             for i in range(3)])
    return V, v_tel - y0


def vertical_attitude_terms(model: Any, n: int) -> np.ndarray:
    """Which of the `n` coefficients are the model's initial attitude error about the launch frame's vertical (y):
    the columns of its ``phi0`` Jacobian's y row (a bool mask, all False for a model without ``phi0``)."""
    vertical = np.zeros(n, dtype=bool)
    phi0 = getattr(model, "numeric", None)
    if callable(phi0):
        try:
            up = np.asarray(phi0("phi0"), float)[_UP]
            vertical[:min(up.size, n)] = up[:n] != 0
        except (KeyError, ValueError, IndexError, RuntimeError):
            pass
    return vertical


def telemetry_heading_record(res: EstimateResult, problem: Any, flight: FlightData, model: Any, spec: Any,
                             locating: Any) -> dict | None:
    """The turn of a strapdown telemetry about the vertical against its tracking (module notes): ``{"turn_deg",
    "std_deg", "z", "limit_z", "stated_std_deg", "located", "explains", "conflict", "heading_deg",
    "suggested_heading_deg", ...}`` (``turn_deg`` right-handed about the launch frame's y axis; the heading given,
    body axis clockwise from north, less it is the one the rows point to), or None without a strapdown telemetry,
    rows, times or a fit."""
    from casep.checks.plausibility import misfit_problem
    from casep.estimators.rls import PRIOR_CONFLICT_Z
    from casep.noise.fit import fit_noise
    from casep.regression.problem import Problem
    from casep.workflows.heading_rules import HEADING_STD_DEG, SMALL_ANGLE_REACH_DEG, within_small_angle_reach
    from casep.workflows.heading_rules import quiet_fit as _quiet_fit

    meta = flight.meta if isinstance(flight.meta, dict) else {}
    turned = _turned_rows(problem, flight)
    if turned is None:
        return None
    V, tracked = turned
    y0 = np.asarray(problem.y, dtype=float)
    S = problem.sv()
    names = list(res.names)
    vertical = vertical_attitude_terms(model, len(names))
    keep = ~vertical
    S, names = S[:, :, keep], [n for n, k in zip(names, keep) if k]
    kind = "telemetry"

    def at(deg: float, which: str | None = None) -> Any:
        rad = math.radians(deg)
        if (which or kind) == "telemetry":  # the INS's attitude and integrated force turned back
            Vt = _turn(V, -rad)
            return Problem.from_arrays(_turn(S, -rad), y0 + Vt - V, problem.t, names=names)
        assert tracked is not None  # the tracking turned back: the attitude, and S_V, as given
        return Problem.from_arrays(S, y0 - _turn(tracked, rad) + tracked, problem.t, names=names)

    def ssr(deg: float, which: str | None = None) -> float:
        rms = _quiet_fit(at(deg, which), locating).residual_rms or {}
        return float(sum(float(v) ** 2 for v in rms.values() if v is not None))

    def neg2(deg: float, which: str | None = None) -> float:
        return float(fit_noise(at(deg, which), "gmw").extra["neg2_reml"])

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the hypotheses' fits: judged here, not said
            grid = np.arange(-SMALL_ANGLE_REACH_DEG, SMALL_ANGLE_REACH_DEG + SCAN_STEP_DEG / 2, SCAN_STEP_DEG)
            # each hypothesis located on its least-squares profile, then chosen by the restricted likelihood there
            # (the tracking turned instead: the hypothesis whose located turn the noise model finds likelier)
            hypotheses = ["telemetry"] + (["tracking"] if tracked is not None else [])
            found = {w: _minimum(grid, np.array([ssr(d, w) for d in grid]), lambda d, w=w: ssr(d, w))
                     for w in hypotheses}
            likelihood = {w: neg2(found[w][0], w) for w in hypotheses}
            kind = min(hypotheses, key=lambda w: likelihood[w])
            (turn, located), n_at = found[kind], likelihood[kind]
            n0 = neg2(0.0)
            n_plus, n_minus = neg2(turn + CURVATURE_STEP_DEG), neg2(turn - CURVATURE_STEP_DEG)
            fit_there = _quiet_fit(at(turn), spec)
    except (ValueError, np.linalg.LinAlgError, KeyError):
        return None
    if not all(np.isfinite([n0, n_at, n_plus, n_minus])):
        return None
    curv = (n_plus + n_minus - 2.0 * n_at) / CURVATURE_STEP_DEG**2  # -2 ln L'' = 2 / std^2
    std = math.sqrt(2.0 / curv) if curv > 0 else math.inf
    lr = max(n0 - n_at, 0.0)
    lev: dict = meta["levelled"] if isinstance(meta.get("levelled"), dict) else {}
    given = lev.get("heading") == "given" and lev.get("heading_deg") is not None
    stated = HEADING_STD_DEG if given and kind == "telemetry" else 0.0
    z = min(math.sqrt(lr), abs(turn) / math.hypot(stated, std))
    why = misfit_problem(flight, fit_there.residual_rms or {}, (), noise=fit_there.diagnostics.get("noise"))
    judged = within_small_angle_reach(std, PRIOR_CONFLICT_Z)
    heading = float(lev["heading_deg"]) if given else None
    # no finite std (the profile's curvature not positive: an edge of the scan, a flat profile): None, not inf
    return {"turn_deg": turn, "std_deg": std if math.isfinite(std) else None, "turned": kind, "z": float(z),
            "ln_ratio": lr / 2.0,
            "limit_z": PRIOR_CONFLICT_Z, "stated_std_deg": stated, "located": bool(located), "judged": bool(judged),
            "explains": why is None,
            "left_out": [n for n, v in zip(res.names, vertical) if v],
            "residual_rms_turned": {a: float(v) for a, v in (fit_there.residual_rms or {}).items() if v is not None},
            "heading_deg": heading, "heading_axis": lev.get("heading_axis") if given else None,
            "suggested_heading_deg": None if heading is None or kind != "telemetry" else heading + turn,
            "conflict": bool(located and judged and why is None and z > PRIOR_CONFLICT_Z),
            "rule": "the rows and S_V turned back about the launch frame's vertical (y) by the turn that minimises "
                    "the least-squares residual (scanned over +-30 deg, refined by golden section; a model's phi0 "
                    "about y left out), per hypothesis, the one of higher restricted likelihood there taken; the "
                    "restricted likelihood with the noise refitted (Gauss-Markov plus white) "
                    "there against the rows as given (z = sqrt of -2 ln of their ratio) and the turn against its "
                    "std (the likelihood's curvature) and the stated std, the smaller of the two z beyond limit_z, "
                    "the turn located inside the scan, determined within the small-angle reach and the turned rows "
                    "leaving no misfit: the telemetry's heading (or the tracking's azimuth) is off"}


def telemetry_heading_message(record: dict, source: str, imu: bool = False) -> str:
    """What a result says when the telemetry is turned about the vertical against its tracking
    (:func:`telemetry_heading_record`'s conflict): the telemetry's heading (the INS's attitude and integrated force
    turned) or the tracking's azimuth (the tracked velocity turned), whichever fits the rows better, and what to do
    (the tracking's frame; the heading: ``--heading``, or a model with ``phi0`` about the vertical for a turn within
    its first order); `imu` a raw record's separation (``casep separate --imu``: the heading is its own option)."""
    turn, sd, z = record["turn_deg"], record["std_deg"], record["z"]
    rms = ", ".join(f"{a} {v:.3g}" for a, v in record["residual_rms_turned"].items())
    which = "the tracked velocity" if record.get("turned") == "tracking" else "the telemetry (its attitude and " \
        "integrated specific force)"
    head = (f"{source}: the telemetry and the tracking are turned about the vertical against each other: the rows "
            f"fit with {which} turned by {turn:+.3g} +- {sd:.2g} deg about the launch frame's y axis (up at the "
            f"pad; z = {z:.3g} against the stated std {record['stated_std_deg']:g} deg and the estimate's, above "
            f"{record['limit_z']:g}), and leave residuals the noise explains there (RMS {rms} m/s). The "
            f"coefficients absorb such a turn and "
            + ("the fit passed its checks with them off by what they took" if record.get("on_success")
               else "the misfit is its remainder"))
    if record.get("left_out"):
        head += (f" ({', '.join(record['left_out'])}, the model's initial attitude error about the vertical, is "
                 f"that turn to first order: a turn of degrees is beyond it)")
    again = "separate --imu again" if imu else "navigate again"
    heading = (f"a heading off: {again} with the right --heading (its body axis, true north), or fit a model with "
               "phi0 about the vertical (strapdown42_extended) where the turn is within its first order (a degree or "
               "so)")
    if record.get("turned") == "tracking":
        return head + (": a tracking written in a frame turned in azimuth (check its frame: the launch azimuth, "
                       "--launch-site AZ, and the axes its velocity is given in), or a wrong heading of the INS "
                       f"that wrote the telemetry ({heading})")
    if imu and record["heading_deg"] is not None:
        return head + (f": a wrong heading given (body {record['heading_axis']} at {record['heading_deg']:g} deg): "
                       f"the data point to about {record['suggested_heading_deg']:.4g} deg (+- {record['std_deg']:.2g}"
                       f"; approximate): separate --imu again with --heading {record['suggested_heading_deg']:.4g}, "
                       "or a tracking written in a frame turned in azimuth (check its frame: --launch-site AZ)")
    if record["heading_deg"] is not None:
        return head + (f": a wrong heading of the INS. casep navigate aligned it at the heading given (body "
                       f"{record['heading_axis']} at {record['heading_deg']:g} deg): check it (its body axis, true "
                       f"north, not magnetic or grid); the data point to about {record['suggested_heading_deg']:.4g} "
                       f"deg (+- {record['std_deg']:.2g}; the coefficients take part of a turn, so it is "
                       f"approximate): navigate again with --heading {record['suggested_heading_deg']:.4g} and "
                       "separate again (the test then says what is left)")
    return head + (": a wrong heading of the INS that wrote the telemetry, or a tracking written in a frame turned in "
                   "azimuth: check the INS's heading at alignment and the tracking's frame (its azimuth, "
                   f"--launch-site AZ); {heading}")


def judge_telemetry_heading(res: EstimateResult, flight: Any, problem: Any, model: Any, spec: Any,
                            locating: Any) -> EstimateResult:
    """`res`, a strapdown telemetry's result, with the turn about the vertical tested
    (:func:`telemetry_heading_record`, in ``diagnostics["heading"]["test"]``); a turn named is said
    (:class:`casep.exceptions.SetupWarning`) and put first (:func:`casep.workflows.imu_separate.heading_first`:
    status ``STATUS_PRIOR_CONFLICT``, the other failures after it; a success failed by it, ``on_success``). A success
    whose model holds the turn to first order (its ``phi0`` about the vertical: :func:`vertical_attitude_terms`), a
    dv sign or the attitude's frame named (:func:`casep.workflows.telemetry_frame.judge_frame`), anything but a
    strapdown telemetry, noise-free rows or a flight that failed a set-up check: `res` unchanged."""
    from casep.checks.plausibility import setup_problems
    from casep.estimators.registry import STATUS_PRIOR_CONFLICT, failed
    from casep.exceptions import SetupWarning
    from casep.workflows.heading_rules import heading_first

    named = (res.diagnostics.get("dv_signs") or {}).get("named") or (res.diagnostics.get("frame") or {}).get("conflict")
    if named or not isinstance(flight, FlightData) or problem.y is None or setup_problems(flight):
        return res  # named already: a dv sign, the attitude's frame (judge_frame)
    if problem.is_noise_free() or (res.success and vertical_attitude_terms(model, len(res.names)).any()):
        return res  # a success whose model holds the turn to first order (its phi0 about the vertical)
    record = telemetry_heading_record(res, problem, flight, model, spec, locating)
    if record is None:
        return res
    res.diagnostics["heading"] = {**(res.diagnostics.get("heading") or {}), "test": record}
    if not record["conflict"]:
        if res.success and not vertical_attitude_terms(model, len(res.names)).any():
            record["consider"] = turn_consider(res, problem, flight, getattr(model, "name", None))
        return res
    record["on_success"] = bool(res.success)
    said = telemetry_heading_message(record, flight.source)
    record["said"] = f"failed: {said}"
    warnings.warn(said, SetupWarning, stacklevel=3)
    return heading_first(failed(res, STATUS_PRIOR_CONFLICT, record["said"]))


def said_unless_turned(res: EstimateResult, caught: list) -> EstimateResult:
    """`res` with the warnings recorded while its clocks were judged (`caught`: the telemetry clock's drift,
    :func:`casep.workflows.telemetry_clock.judge_telemetry_clock`, and the tracking's,
    :func:`casep.workflows.judging.judge_tracking`) said as they were, unless the turn about the vertical is named
    (:func:`judge_telemetry_heading`'s conflict): a turn leaves a misfit that grows with the velocity, which the
    drift's column (tags late by ``eps t``, steps stretched by ``1 + d``) takes a share of, and the drift read there
    is the turn's. Then their drift warnings
    (:class:`casep.exceptions.TrackingQualityWarning`) are not said but recorded in
    ``diagnostics["clock_drift"]["beside_turn"]`` (the report's drift lines say that they were read beside the
    turn); a failure they made (a drift given and contradicted) stays in the message, after the turn
    (:func:`casep.workflows.imu_separate.heading_first`). Other warnings are said."""
    from casep.exceptions import TrackingQualityWarning

    turned = bool(((res.diagnostics.get("heading") or {}).get("test") or {}).get("conflict"))
    withheld = [str(w.message) for w in caught if turned and issubclass(w.category, TrackingQualityWarning)]
    for w in caught:
        if not (turned and issubclass(w.category, TrackingQualityWarning)):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if not turned or not isinstance(res.diagnostics.get("clock_drift"), dict):
        return res
    res.diagnostics["clock_drift"] = {**res.diagnostics["clock_drift"], "beside_turn": withheld}
    return res


def turn_consider(res: EstimateResult, problem: Any, flight: FlightData, model_name: str | None = None) -> dict | None:
    """A turn about the vertical too small for :func:`telemetry_heading_record` to name, as consider parameters of a
    success whose model has no initial attitude error about the vertical (``record["consider"]``, carried by
    :func:`with_turn_considered`): ``{"hypotheses": {"telemetry": {"turn_deg", "std_deg", "size_deg", "per_deg"},
    "tracking": {...}}, ...}``, or None without the rows or a covariance.

    Such a model takes a turn ``h`` into its coefficients: the fit's estimators
    (:func:`casep.workflows.row_estimators.consider_estimators`) on the rows' first-order change (:func:`turn_column`
    of what a hypothesis turns: the telemetry's integrated specific force, the tracked velocity) move them by ``g h``
    (``per_deg``, natural units per deg). A turn below the test's limit still moves them by many of their std where
    the flight determines it poorly beside them (the strapdown boost at 10 Hz under ``strapdown15_axial``, 0.5 deg off:
    bg_x 10 std off, the turn read -0.24 to -0.59 +- 0.15-0.18 deg). Each hypothesis's turn is estimated as one more
    column of the fit (:func:`casep.workflows.row_estimators.column_estimates`: GLS, the coefficients free, the std
    of any linear estimator on the rows), and the size the data cannot exclude is its estimate and std in quadrature
    (``size_deg``, the turn's mean square given the rows), so the covariance gains ``g g^T size^2`` per hypothesis
    (both: near zero the rows do not tell them apart). With a turn's std alone it would be the covariance of the fit
    with the turn free (the Schur complement), whose estimate differs by ``g`` times the turn's: the estimate's
    square carries that difference. The coefficients' error ``g h`` is then within their std whatever the turn, at
    the cost of wider std where it is small."""
    from casep.model.loader import PHI0_MODELS
    from casep.workflows.row_estimators import column_estimates, consider_estimators

    turned = _turned_rows(problem, flight)
    if turned is None or res.covariance is None:
        return None
    a = None
    hypotheses = {}
    for which, rows in zip(("telemetry", "tracking"), turned):
        if rows is None:
            continue
        col = turn_column(rows)
        est = column_estimates(res, problem, flight, col)
        a = consider_estimators(res, problem) if a is None else a
        g = a @ col.reshape(-1)
        if est is None or not np.all(np.isfinite(g)) or not np.all(np.isfinite([est[0][0], est[1][0]])):
            return None
        turn, sd = float(est[0][0]), float(est[1][0])
        hypotheses[which] = {"turn_deg": turn, "std_deg": sd, "size_deg": math.hypot(turn, sd),
                             "per_deg": {n: float(v) for n, v in zip(res.names, g)}}
    if not hypotheses:
        return None
    return {"hypotheses": hypotheses, "phi0_model": PHI0_MODELS.get(model_name or "", "strapdown42_extended"),
            "rule": "per hypothesis (the telemetry's heading, the tracking's azimuth) the turn estimated as one more "
                    "column of the fit (GLS, first order), its estimate and std in quadrature (the size the data "
                    "cannot exclude) times how far one degree of it moves each coefficient (the fit's estimators "
                    "on the column): g g^T size^2 added to the covariance"}


def with_turn_considered(res: EstimateResult, record: dict | None) -> EstimateResult:
    """`res` whose covariance and std carry the turn about the vertical the test did not name (`record`, the linear
    pass's :func:`telemetry_heading_record` with its ``consider``: :func:`turn_consider`) through
    :func:`casep.workflows.row_estimators.with_extra_covariance`, said in its message, with the record in
    ``diagnostics["heading"]["test"]`` (an iterated result, whose passes do not test the turn, gains the linear
    pass's: its coefficients move with a turn as the linear pass's do, to first order); `res` itself without a
    consider, for a failed result or other coefficients."""
    from casep.workflows.row_estimators import with_extra_covariance

    c = (record or {}).get("consider")
    if record is None or c is None or not res.success or res.covariance is None:
        return res
    hyp = c["hypotheses"]
    if any(list(h["per_deg"]) != list(res.names) for h in hyp.values()):
        return res
    extra = sum(np.outer(g, g) for g in (np.array([h["per_deg"][n] for n in res.names]) * h["size_deg"]
                                         for h in hyp.values()))
    out = with_extra_covariance(res, np.asarray(extra))
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.asarray(out.std, dtype=float) / np.asarray(res.std, dtype=float)
    k = int(np.nanargmax(np.where(np.isfinite(factor), factor, np.nan))) if np.isfinite(factor).any() else None
    c["std_factor_max"] = None if k is None else float(factor[k])
    c["std_factor_worst"] = None if k is None else res.names[k]
    sizes = " and ".join(f"{h['size_deg']:.2g} deg ({w}: {h['turn_deg']:+.2g} +- {h['std_deg']:.2g})"
                         for w, h in hyp.items())
    line = (f"a turn about the vertical of the telemetry against its tracking below the test's limit (z "
            f"{record['z']:.3g}, within {record['limit_z']:g}: not named) is in the std as a consider parameter of "
            f"{sizes} (each turn's estimate and std in quadrature, the size the data cannot exclude): the model has "
            "no initial attitude error about the vertical to take it")
    if k is not None:
        line += f"; it widens {res.names[k]}'s std {factor[k]:.3g} times"
    line += (f"; with the heading known better (casep navigate --heading) or a model with phi0 ({c['phi0_model']}) "
             "the std need not carry it")
    heading = {**(out.diagnostics.get("heading") or {}), "test": record}
    return dataclasses.replace(out, message=f"{out.message}; {line}", diagnostics={**out.diagnostics,
                                                                                    "heading": heading})
