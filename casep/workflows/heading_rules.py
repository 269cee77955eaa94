"""The rules a raw IMU record's separation (:mod:`casep.workflows.imu_separate`, which re-exports them) shares with
the tests of a telemetry's turn about the vertical (:mod:`casep.workflows.telemetry_heading`): the given heading's
std, the small-angle tests' reach, a turn named first, and the quiet fit of a hypothesis. Below both, so that the
raw record's separation can run the telemetry's test on its first pass."""

from __future__ import annotations

import dataclasses
import warnings
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.estimators.spec import FitSpec
    from casep.regression.problem import Problem

__all__ = ["HEADING_STD_DEG", "SMALL_ANGLE_REACH_DEG", "within_small_angle_reach", "heading_first", "named_first",
           "quiet_fit"]

#: The std of a given heading when none is given, deg
#: (:meth:`casep.workflows.imu_separate._Run.heading_rows`): a launcher rail's azimuth surveyed to a few hundredths
#: of a degree, and the IMU's mounting on the rail about the vertical, which a bracket holds to a
#: tenth of a degree at best; on a rail launch the lateral terms cannot tell the heading from the coefficients, and
#: the MEMS example's stated combinations (``docs/guide/navigate.md``) move by up to 6 of their std per 0.1 deg.
HEADING_STD_DEG = 0.1
#: The reach of the small-angle tests, deg: a heading (or a frame's rotation about an axis) whose std times the
#: test's limit exceeds it is not judged (:meth:`casep.workflows.imu_separate._Run.heading_judged`;
#: :data:`casep.workflows.telemetry_frame.FRAME_LARGE_DEG` is this): beyond it the first-order column locates a local
#: fit, not the turn (an iteration stopped two passes early read the heading -417 +- 34 deg off).
SMALL_ANGLE_REACH_DEG = 30.0


def within_small_angle_reach(std_deg, limit_z: float):
    """Whether a small-angle test judges an angle of std `std_deg` (deg; a float or an array) at its limit `limit_z`:
    ``std * limit <= SMALL_ANGLE_REACH_DEG`` (a rotation at the limit within the first-order column's reach). The one
    rule of the heading (:meth:`casep.workflows.imu_separate._Run.heading_judged`), the attitude's frame
    (:mod:`casep.workflows.telemetry_frame`) and a telemetry's turn about the vertical
    (:mod:`casep.workflows.telemetry_heading`)."""
    return np.asarray(std_deg) * limit_z <= SMALL_ANGLE_REACH_DEG


def quiet_fit(problem: Problem, spec: FitSpec) -> EstimateResult:
    """The estimate and its std alone (``fit(checks=False)``), its warnings not shown."""
    from casep.estimators.solve import fit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit(problem, spec, checks=False)


def heading_first(res: EstimateResult) -> EstimateResult:
    """`res` with the heading the data contradict (``diagnostics["heading"]["test"]``, its ``conflict`` standing:
    :meth:`casep.workflows.imu_separate._Run.heading_judged`) named first, whatever else failed before or after it:
    status ``STATUS_PRIOR_CONFLICT``, the heading's failure (its ``said``) opening the message, the other failures after
    it as what a wrong heading also leaves (a turn of the velocity the coefficients cannot take: a misfit,
    estimates beyond the linear model, a step that leaves it, a drift the clock's column takes a share of), to be
    judged once the heading is right. `res` unchanged without a conflict."""
    from casep.estimators.registry import STATUS_PRIOR_CONFLICT

    test = (res.diagnostics.get("heading") or {}).get("test") or {}
    said = test.get("said")
    if not test.get("conflict") or not test.get("first", True) or not said or said not in res.message:
        return res  # no conflict, or one read on passes stopped before settling: said after what stopped them
    return named_first(res, said, STATUS_PRIOR_CONFLICT, "the turn named above (the heading, or the frames)")


def named_first(res: EstimateResult, said: str, status: int, what: str) -> EstimateResult:
    """`res` failed with `status` and the failure `said` (in its message) opening the message, every other failure
    after it (the first line's, and those appended after a later line: ``failed`` adds to the message's end), in
    their order, as what `what` may leave, to be judged once it is set right; the message's other lines kept."""
    fails, lines = [], []
    for i, line in enumerate(res.message.split("\n")):
        head, *more = line.split("; failed: ")
        if i == 0 and head.startswith("failed: "):
            more, head = [head.removeprefix("failed: "), *more], ""
        fails += [f for f in more if f and f != said.removeprefix("failed: ")]
        if head:
            lines.append(head)
    others = (f"\nwith {what}, the other findings may be its consequences (judge them once it is set right): "
              + "; ".join(fails)) if fails else ""
    message = "\n".join([said + others, *lines])
    return dataclasses.replace(res, status=status, success=False, message=message)
