"""Separation from raw IMU data: navigate, separate, and iterate while the errors are too large to stay linear.

:func:`separate_imu` is ``casep separate --imu IMU.csv --tracking TRK.csv --launch-site ... --align T1 T2``.
One pass navigates the raw IMU (:func:`casep.navigation.navigate`: levelled and headed on the pad,
integrated in the launch-inertial frame), pairs the strapdown telemetry with the tracking
(:func:`casep.io.files.read_flight_pair`, the reader of ``casep separate TEL --tracking TRK``),
builds S_V and solves through :func:`casep.estimators.solve.fit`.

**The alignment.** The pad levelling turns the accelerometer errors on the pad into an attitude
error at the first sample, ``phi0 = A D`` (at rest the INS makes ``C (fb + delta_f)`` vertical:
``phi0_h = u x (C delta_f) / g``; a gyrocompassed heading takes the gyro errors too). ``A`` (3 x n,
per natural unit) is the derivative of the alignment itself (:func:`casep.navigation.pad_state`)
along each coefficient's body errors over the pad window, by central differences (the errors are
linear in D, the alignment smooth: exact to about 1e-10); the model gains it as an initial
misalignment, ``phi0 += A D``. Without it S_V would predict a velocity error on the pad that the
levelling cancels. This is the navigation casep aligned itself; a telemetry's free ``phi0`` (``strapdown15_phi0``)
and a window's (``strapdown6_window``) are the same slot for navigations it did not align
(``docs/reference/model.md``, "The initial attitude error"); every start attitude is corrected by
:func:`casep.model.strapdown.corrected_attitude`.

**Iterating** (``iterate=True``, the default): MEMS errors over tens of seconds turn the attitude
by degrees and the linear error model is biased by many std. With ``D_k`` the coefficients so far
(``D_0 = 0``), pass k

1. corrects the raw IMU by the model's own error equations applied inversely
   (:func:`casep.model.strapdown.corrected_imu`: ``fb + delta_f(fb, w; D_k) = fb_measured``,
   ``w + delta_w(fb, w; D_k) = w_measured``), and the start state by the model's initial terms
   (``C_start = R(phi0(D_k)) C_aligned``, ``v_start -= dv0(D_k)``);
2. re-aligns and re-navigates with the corrected record;
3. pairs it with the tracking, less the model's direct velocity terms at ``D_k`` (a lever arm, the
   tracking time offset ``dt_trk``), leaves out the tracking epochs the first pass's screen left out,
   rebuilds S_V (and ``A``) about the corrected trajectory, and solves for the remaining correction
   ``d_k`` along the combinations the flight determines (:func:`determined_step`); ``D_{k+1} = D_k + d_k``.

**S_V is the derivative of a pass.** A pass is a function of the coefficients: the record corrected at ``D``,
levelled, navigated and paired. The correction inverts ``x + delta(x; D) = x_m``, so its derivative is
``-(I + d delta / d x)^{-1} d delta / d D``, not ``-d delta / d D``: with a MEMS IMU's misalignments of a degree at
``D``, a bias of the roll-axis gyro also turns the corrected record about a transverse axis, and with the thrust
along the roll axis that is most of what it does to the velocity. Each pass's model carries the factor
(:func:`casep.model.strapdown.correction_errors`), in S_V and in the levelling's ``A``, so the passes are
Gauss-Newton with the exact Jacobian (``tests/workflows/test_imu_separate.py`` checks it against central differences
of a whole pass).

**The curvature at one std.** Where the flight determines a combination poorly, one std of it can be tens of
degrees of attitude, and the second-order terms of the navigation then move the well-determined combinations by
many of their std: the linear covariance of the last pass is overconfident along exactly what it says the flight
determines. :meth:`_Run.curvature` navigates seeded draws from the estimate's own distribution, takes each draw's
nonlinear remainder and the shift of the estimate it makes, and adds their mean square to the covariance; above
:data:`CURVATURE_TOL` std it warns with the numbers (:class:`casep.exceptions.NonlinearityWarning`) and the message
says it. On the MEMS rail launch of ``benchmarks/mems_rail_honesty.py`` the chi-square of the error over the
determined combinations went from 18-22 000 per degree of freedom (6 seeds) to 0.8-2.0 (1.24 pooled; the code of
that time; the figure of today's code is below).

**The curvature over what the stretches leave undetermined.** When the tracking's noise differs between stretches
the passes step only along the few combinations the stretches' weighting determines, and the rest of the coefficients
stays where the first pass put it; with MEMS errors its second order moves those combinations by tens of their linear
std. :meth:`_Run.determined_curvature` navigates :data:`DETERMINED_DRAWS` seeded draws with the rest at its plausible
size (:func:`casep.checks.tracking_quality.plausible_size`), carries the shift in each combination's std and says it;
those no longer determined once the consider terms widen them too are left out
(:func:`casep.checks.tracking_quality.determined_split`, on the final std). On three own MEMS rocket logs (800 Hz, gyro
biases 150-750 deg/h) 11 of the 12 linear combinations were 19 to 58 std off; with the curvature all 12 are within 1.8
std (std 0.65 to 34 declared magnitudes), and one is still stated.

**The curvature over what the passes leave out.** The same holds for the combinations the steps leave out (below):
the stated ones are gradients about where the passes left the rest, hundreds of declared magnitudes from a MEMS
unit's truth. :meth:`_Run.left_out_curvature` draws the rest at the plausible size, carries the shift in the stated
combinations' std (:meth:`_Run.determined_curvature`, the stated combinations' own size their limit), says it with
the smaller shipped models (:data:`SMALLER_MODELS`), and fails the result when no draw can be navigated. On 4 seeded
MEMS boosts under ``strapdown33`` the stated combinations were 36, 8.7, 0.75 and 14 std RMS off the truth, each a
success; with the shift in their std 1.17, 0.19, 0.14 and 0.63 (the rest drawn at the plausible size along each of
its directions; 0.57, 0.03, 0.03 and 0.23 re-run on 2026-11-29's main); drawn at that length, 0.67, 0.25, 0.04 and
0.25 (1.31, 0.43, 0.28 and 0.56 over the std without the consider terms of omitted models;
:meth:`_Run.determined_curvature`'s ``length``). Where the passes left the rest is no evidence of the truth (the
first pass steps along everything, its estimates mostly linearisation error): the draws reach back to the prior as
well (the rest's covariance ``rho^2 Q Q^T / (n - m) + u u^T``, ``u`` the estimate's part along it: the rest's length
the plausible size, not each of its ``n - m`` directions' size, :meth:`_Run.determined_curvature`), their mean
square shift enters the covariance as well as the stated std (:meth:`_Run.with_rest_shift`), and a part beyond
:data:`BACK_BEYOND` times the plausible size is taken back to the prior where the record fits as well there
(:meth:`_Run.back_to_prior`). On the MEMS rail launch of ``benchmarks/mems_rail_honesty.py`` (6 seeds; the first
pass put seed 6's ``bg_x`` at -9380 deg/h, the truth -120) the stated combinations went from RMS z 2.35 (largest
16.4) to 1.23 (largest 2.8), the chi-square per dof over the covariance's directions better than their declared
magnitudes from 8.51 to 1.79.

**The tracking screen** (:func:`casep.checks.tracking_quality.screen_tracking`: stale fixes, the physics
check against the IMU, the noise per stretch) runs once, on the first pass, where its warnings are
said; every later pass leaves out the same tracking rows (:func:`casep.checks.tracking_quality.keep_screen`).
A fixed point needs the same rows in every pass (a row that came and went between passes would move it),
and what the screen tests (a repeated fix while the IMU moved by 0.5 m/s, jumps beyond 10 m/s + 2 m/s^2 dt or
beyond 10 sigma of the epoch-to-epoch noise and back)
is far above what correcting the IMU changes between passes; the first pass is also what ``casep navigate``
then ``casep separate`` screens, so both paths leave out the same epochs.

**Only what the flight determines is corrected.** A coefficient without an estimate (exactly dependent
columns) or a combination the result says the flight does not determine (the stretches' statement,
:func:`casep.checks.tracking_quality.determined`) says nothing about the IMU: correcting the record by the
solver's value there, or by 0 in place of a missing estimate (which drops the determined combination it
is part of), would move the linearisation where the data do not say. :func:`determined_step` builds ``d_k``
from the determined combinations only and measures it in their std. Nor does a combination whose std exceeds the
plausible size of what the record determines (:func:`_determined_size`): it stays at the prior (0), so that the
combinations the result states, gradients about ``D_k``, are evaluated at a plausible point (a pad record then a 3 s
boost under ``strapdown33``: corrections of 1e9 declared magnitudes and stated combinations 59 std off the truth
before). The std that leave a combination out are the ones its left-out correction is judged by
(:func:`_outside_failure`) and the stop rule reads: the tracking's (the record's IMU noise is the same in every pass;
a combination the tracking determines to 0.009 declared magnitudes is never left out because the record's noise,
measured on a moving telemetry's differences, puts its std at 1); the stated combinations' std carry the
record's own noise as the coefficients' do (:func:`combination_imu_noise`).

Far from convergence the passes are solved by OLS under white noise, then as requested; once every
correction is below :data:`ACCELERATE_BELOW` std, ``D_{k+1}`` is the secant (Anderson, depth one)
step through the last two passes (:func:`_secant_step`, its metric the corrections of the combinations stepped along
in their std: under ``strapdown33`` no coefficient has a std of its own). It stops when the correction of every
determined combination is below :data:`ITERATE_TOL` (0.1) of its std, ``|g . d_k| < 0.1 std(g . d_k)``
for every ``g`` the result states as determined (:func:`determined_step`; Gauss-Newton with S_V as the
Jacobian: its fixed point makes the residual orthogonal to S_V about the corrected trajectory, the
noise-free truth included), or when the correction is at the rounding level of the coefficients
(:func:`_at_rounding`: noise-free tracking makes every std rounding too) or the pass's rows are at the rounding
level of the data and no longer fall (:meth:`_Run.at_rounding`, :data:`STALL`), and fails (status
:data:`STATUS_NOT_CONVERGED`) after ``max_iterations`` passes or when a correction cannot be
applied with nothing left to leave out (the message names an IMU gap whose bounds are large against
the tracking noise: :func:`_gap_clause`). The estimate is ``D_k + d_k`` of the last pass, the std and
covariance those of its linearisation; ``diagnostics["iterations"]`` lists every pass (the largest correction in std and
the combination it was).

**Only where the linear model holds** (:meth:`_Run.trial`). A step whose correction cannot be applied (the
record does not invert, the corrected pad is no longer at rest) or that does not descend is rejected: in a white
pass (whose objective is the rows' sum of squares) when that sum after it exceeds the largest of the last
:data:`DESCENT_MEMORY` passes' by more than :data:`DESCENT_SLACK` ``sigma^2`` (a non-monotone descent), in a pass
solved as requested when the residual's RMS is more than :data:`WORSE` times what it was; never at the data's
rounding level (:meth:`_Run.at_rounding`). A white pass's step that does not descend is first halved, up to
:data:`HALVINGS` times (a backtracking line search, ``passes[k]["damped"]`` the fraction taken); beyond that, or for
any other rejection, the same pass steps again without the combinations whose std (in
the declared magnitudes) exceeds the widest one it stepped along over :data:`NARROW` (:func:`determined_step`'s
``limit``: the truncated Gauss-Newton step, the damping in the declared magnitudes, the stop rule still in std).
Full rank does not make a record informative: on a stationary pad every coefficient has an estimate, and the full
step along what the pad does not determine is noise of 1e3-1e10 declared magnitudes (a gyro scale factor of -2e5,
an accelerometer bias of several g), which the next pass cannot invert. On the shipped MEMS example under the
default ``strapdown33`` the first pass's full step (2.9e3 declared magnitudes along combinations of std up to 1.6e3)
raised the rows' RMS from 13.6 to 16.8 m/s; under the tenfold rule alone it was kept, the passes crept back by 0.64 a
pass and the run failed at 20, and with the descent rule half that step was taken and the run converged in 10 passes
(that first step's size came from an estimate beyond its linear limit, which :func:`_determined_size` does not take
as evidence of the instrument's size: the full step then descends, and the run converges in 5).
The combinations and their std come from the fit's covariance, or from the design when the covariance holds them only
to its rounding (:func:`_scaled_spectrum`): on a pad at rest under ``strapdown33`` the best-determined combinations'
variances are 1e-20 of the largest, read from the covariance as 0 (a null direction, stepped along unjudged) or as
hundreds of declared magnitudes; the reviewer's 60 s pad record wandered for 17 passes (corrections of 65-93 std)
and failed on the levelling, and with the spectrum of the design converges in 5 passes along the 4 combinations it
determines.
What is left out is judged when the passes converge: a combination whose correction is above :data:`SIGNIFICANT`
std and whose std is within the coefficients' plausible size (the one it was left out by: :func:`_step_size`) is
determined but not linear over
its size (failed); otherwise the record does not determine it, and a :class:`~casep.exceptions.NonlinearityWarning`
says how many combinations it determines and which it does not (their estimates are one linear pass's, their std
linear), with any result that has a solution, failed or not; ``diagnostics["iterations"]["passes"][-1]["determined"]``
lists the combinations stepped along (std, weights on ``D / scale``, estimate).
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping, NamedTuple, Sequence

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.estimators.registry import STATUS_NOT_CONVERGED
from casep.exceptions import GapWarning, SaturationWarning
from casep.frames import LaunchSite
from casep.navigation.imu import ImuData
from casep.workflows.heading_rules import (
    HEADING_STD_DEG,
    SMALL_ANGLE_REACH_DEG,
    heading_first,
    named_first,
    within_small_angle_reach,
)
from casep.workflows.heading_rules import quiet_fit as _quiet_fit
from casep.workflows.row_estimators import (
    REST_SHIFT_KEY,
    added_covariance,
    coefficient_estimators,
    column_estimates,
    combination_estimators,
    combinations_with_consider,
    consider_estimators,
    estimator_noise,
    tau_spread,
    widened_std,
    with_consider,
    with_extra_covariance,
    with_heading,
)

if TYPE_CHECKING:
    from casep.checks.tracking_quality import ImuNoise
    from casep.estimators.result import EstimateResult
    from casep.estimators.spec import FitSpec
    from casep.io.flight import FlightData
    from casep.model.error_model import ErrorModel
    from casep.navigation.result import NavigationResult

__all__ = ["separate_imu", "ImuSeparation", "Step", "determined_step", "ITERATE_TOL", "MAX_ITERATIONS",
           "STATUS_NOT_CONVERGED", "CURVATURE_TOL", "CURVATURE_RELIABLE", "CURVATURE_DRAWS", "WORSE", "NARROW",
           "SIGNIFICANT", "DESCENT_SLACK", "DESCENT_MEMORY", "HALVINGS",
           "std_shift", "DETERMINED_DRAWS", "FAIL_SHIFT", "STALL",
           "combination_imu_noise", "with_imu_noise_beyond", "imu_noise_widening", "IMU_NOISE_SHARE",
           "linearisation_shift", "linearisation_record", "one_pass_judged", "Shift", "shift_said", "SMALLER_MODELS",
           "prior_fits_p", "HEADING_STD_DEG", "HEADING_STEP_DEG", "HEADING_SETTLED_Z", "given_heading_std",
           "heading_first", "SMALL_ANGLE_REACH_DEG", "within_small_angle_reach", "warn_tau_stated", "TAU_STATED_FACTOR"]

#: The iteration stops when the correction of every determined combination is below this fraction of its std.
ITERATE_TOL = 0.1
#: Passes after which an iteration that has not converged is a failed result.
MAX_ITERATIONS = 20
#: Below this largest correction (std) the passes take the secant step of the last two (:func:`_secant_step`).
ACCELERATE_BELOW = 5.0
#: Why an iteration fails, unless an IMU gap is the likelier cause (:func:`_gap_clause`).
_BLAME = "the errors are too large for the model, or the data are inconsistent with it"
#: The estimate's part along what the record does not determine is taken back to the prior when the record cannot
#: tell the two apart: the likelihood ratio's p-value above this (:meth:`_Run.back_to_prior`).
BACK_TO_PRIOR_P = 0.01
#: ... and only the combinations further from it than this many times the plausible size: as a draw of
#: ``N(0, rho^2)`` beyond 3 of its std, the first pass's value is no plausible one (:func:`_beyond_plausible`).
BACK_BEYOND = 3.0
#: ``diagnostics`` key of the rest's shift :meth:`_Run.with_rest_shift` added to the covariance (natural units, n x n)

#: The curvature check: second-order shifts of the estimate above this (std, the largest over the combinations) are
#: warned about (:meth:`_Run.curvature`).
CURVATURE_TOL = 0.3
#: Above this shift (std) the second-order term exceeds the first at one std: the covariance with its mean square is
#: a second-order expansion outside its range, and the warning says the std are not reliable (:meth:`_Run.curvature`).
CURVATURE_RELIABLE = 1.0
#: ... from this many draws per coefficient of the estimate's own distribution (seeded: the same every run).
CURVATURE_DRAWS = 1
#: A step is outside the linear model when the residual's RMS after it is this many times that before it (a pass
#: solved as requested: its noise model's metric is not the rows' plain sum of squares) ...
WORSE = 10.0
#: ... or, in a white least-squares pass (:func:`_fast_spec`, whose objective is the rows' plain sum of squares), when
#: that sum after it exceeds the largest of the last :data:`DESCENT_MEMORY` passes' by more than this many times the
#: fit's variance ``sigma^2`` (one unit of its chi-square: a rise the data cannot tell from none). The Gauss-Newton
#: step must descend (:meth:`_Run.trial`) ...
DESCENT_SLACK = 1.0
#: ... against the largest sum of this many passes (the pass before and those before it): a non-monotone descent
#: (Grippo, Lampariello and Lucidi's line search), since the passes are Gauss-Newton on an objective that moves with
#: them (each pass leaves the combinations it does not determine where they are, about a new linearisation). A
#: noise-free pad record under ``strapdown33`` reaches rows of 7.4e-8 m/s (the fit's own 6.4e-13), where a step's
#: rows rise to 6.9e-7 m/s and the later passes' fall to 1.3e-10 (its rounding level): a monotone rule rejected that
#: step and every halving of it, and failed the record. No pass's rows exceed the first's by more than sigma^2 a pass.
DESCENT_MEMORY = 3
#: ... such a step is halved up to this many times (to 1/16: a backtracking line search) before the pass steps again
#: without its widest combinations (:data:`NARROW`).
HALVINGS = 4
#: How :meth:`_Run.trial` says a step does not descend.
_NO_DESCENT = "the step does not descend"
#: ... and the next step leaves out the combinations whose std exceeds the widest one stepped along, over this.
NARROW = 10.0
#: A linear result kept (``iterate=False``) whose second-order remainder moves it by more than this (std) fails
#: (:func:`one_pass_judged`).
FAIL_SHIFT = 3.0
#: A noise-free record has converged when a pass's rows are at the data's rounding level and above this fraction of
#: the pass before's (:meth:`_Run.at_rounding`; the passes no longer lower them).
STALL = 0.1
#: A combination left out whose correction exceeds this many of its std: the iteration fails (it is determined, and
#: the model is not linear over its size); below it, the record does not determine it (said, not iterated).
SIGNIFICANT = 4.0
#: The heading's derivative: central differences of a pass navigated at the heading plus and minus this, deg.
HEADING_STEP_DEG = 0.1
#: The heading test's turn left at the heading it pointed to (the rows navigated there), in its std, beyond which
#: the heading it pointed to is said to be approximate (:func:`heading_message`): the test is linear in the heading's
#: error. Measured on the aircraft of ``benchmarks/aircraft_flight.py`` with launch-frame tracking, a heading 25 deg
#: off: read as 24.1 +- 0.26 deg, 1.8 deg left at the heading it pointed to; navigating again at the headings the
#: test points to with the coefficients' correction held walked to 68.8 deg, past the true 70 (the correction
#: absorbed part of the turn), so the rule says where the test stops being exact instead of searching.
HEADING_SETTLED_Z = 3.0
#: The IMU clock drift's derivative: central differences of a pass navigated with its tags stretched by plus and minus
#: this, ppm (the rows are linear in it to parts in 10^4 over a flight: a crystal's drift of tens of ppm).
CLOCK_STEP_PPM = 100.0
#: The data's estimate of an IMU clock drift beyond the one given, beyond this many of its std but not beyond the
#: clock-drift rule (:func:`casep.checks.tracking_quality.drift_determined`), fails the result as well: the
#: coefficients take the drift in and their std do not cover it (a record whose clock runs 104 ppm slow read +84.9 +-
#: 23 ppm and left ``dt_trk`` 10 std off); a clock on the tracking's rate reaches it on 0.27 % of records.
CLOCK_HINT_Z = 3.0
#: The std of the IMU clock's drift against the tracking's (GPS) time when none is given, ppm (``--clock-drift-std``;
#: :meth:`_Run.with_clock`). A flight computer's clock is an undisciplined crystal: its frequency tolerance at 25 C
#: (10 to 30 ppm), its change over the operating temperatures (10 to 50 ppm) and its ageing (a few ppm a year) add up
#: to the +-100 ppm a microcontroller's timing budget allows, taken here as two std; a sounding rocket's flight
#: computer ran 104 ppm fast against GPS time (two std of this).
CLOCK_DRIFT_STD_PPM = 50.0
#: The std of a drift given (``--clock-drift``) when its std is not, ppm: measured against GPS time on the ground or a
#: previous flight (to well below a ppm over minutes), it holds in flight to the crystal's change with temperature
#: between then and the flight, a few ppm.
CLOCK_GIVEN_STD_PPM = 2.0
#: A covariance's eigenvalue below this fraction of its largest is its rounding (:func:`_scaled_spectrum`).
_SPECTRUM_RTOL = 1e-10
#: A covariance's quadratic form is read where it exceeds its rounding, ``n eps`` times its largest eigenvalue, by
#: this factor (:func:`_scaled_spectrum`).
_RESOLVED = 100.0
#: The alignment's derivative is taken with steps that turn the attitude by about this much, rad.
_ALIGN_STEP_RAD = 1e-6
#: The curvature over what the tracking's stretches leave undetermined: this many seeded draws, each one navigation of
#: the record (:meth:`_Run.determined_curvature`).
DETERMINED_DRAWS = 4
#: The shipped strapdown models with fewer terms than a model, by the model: what to try when a raw record determines
#: too little of it to be linear over the rest (:meth:`_Run.left_out_curvature`; the levelling's phi0 is added to any).
SMALLER_MODELS = {"strapdown42_extended": "strapdown33, strapdown15_axial or strapdown12",
                  "strapdown33": "strapdown15_axial or strapdown12", "strapdown15_axial": "strapdown12"}


@dataclass
class ImuSeparation:
    """The separation of a raw IMU record: the estimate, the navigation it was made on, the passes.

    Attributes
    ----------
    result : EstimateResult
        The coefficients (``D_k + d_k`` of the last pass), std and covariance of the last linearisation;
        failed (status :data:`STATUS_NOT_CONVERGED`) when the iteration did not converge;
        ``diagnostics["iterations"]`` the passes.
    navigation : NavigationResult
        The last navigation (the IMU corrected by the coefficients of the last pass).
    flight : FlightData
        The last flight (that navigation paired with the tracking).
    iterations : list of dict
        One per pass: ``iteration``, ``fit`` (how it was solved), ``max_z`` (the largest |correction| /
        std), ``worst`` (its coefficient), ``z`` (every coefficient's), ``estimate`` (after the pass).
    """

    result: EstimateResult
    navigation: NavigationResult
    flight: FlightData
    iterations: list[dict] = field(default_factory=list)

    @property
    def success(self) -> bool:
        return self.result.success

    @property
    def status(self) -> int:
        return self.result.status

    @property
    def message(self) -> str:
        return self.result.message

    def to_dict(self) -> dict[str, Any]:
        """The result JSON (:meth:`EstimateResult.to_dict`; the passes in ``diagnostics.iterations``) with the
        navigation summary under ``navigation``."""
        return {**self.result.to_dict(), "navigation": self.navigation.to_dict()}

    def text(self) -> str:
        """The estimate's table, then one line per pass."""
        return "\n".join([self.result.text(), *iteration_lines(self.result.diagnostics)])


def iteration_lines(diagnostics: dict) -> list[str]:
    """What the command line prints of ``diagnostics["iterations"]`` (none without it)."""
    it = diagnostics.get("iterations")
    if not it:
        return []
    if not it["iterate"]:
        return ["one linear pass (no iteration): the std hold only while the errors stay linear"]
    lines = [f"iterations: {it['passes'][-1]['iteration']} passes (stop when every correction < {it['tol']:g} std, "
             f"at most {it['max_iterations']}): {'converged' if it['converged'] else 'NOT converged'}"]
    for p in it["passes"]:
        for r in p.get("rejected", []):
            lines.append(f"  pass {p['iteration']}: a step along combinations of std up to {r['widest']:.3g} declared "
                         f"magnitudes rejected ({r['why']})")
        damped = f"; {p['damped']:g} of its step taken (the full step does not descend)" if p.get("damped") else ""
        lines.append(f"  pass {p['iteration']}: largest correction {p['max_z']:.3g} std ({p['worst']}); {p['fit']}"
                     + damped)
    return lines


def separate_imu(imu: ImuData | str | os.PathLike, tracking: str | os.PathLike, site: LaunchSite,
                 align_window: tuple[float, float], model: str | os.PathLike | ErrorModel = "strapdown33", *,
                 heading_deg: float | None = None, heading_axis: str = "x", spec: FitSpec | None = None,
                 iterate: bool = True, tol: float = ITERATE_TOL, max_iterations: int | None = None,
                 tracking_frame: str = "launch", grid: str = "tracking", time_offset: float | str | None = None,
                 time_shift: float = 0.0, clock_drift: float = 0.0, fit_time_offset: bool | None = None,
                 gyr_range: float | None = None, acc_range: float | None = None,
                 accel_bias_tolerance: float | None = None, gyro_bias_tolerance: float | None = None,
                 heading_std_deg: float | None = None, clock_drift_std: float | None = None) -> ImuSeparation:
    """Separate a strapdown IMU's errors from its raw data and tracking (module notes).

    Parameters
    ----------
    imu : ImuData or path
        The raw IMU record (:func:`casep.navigation.read_imu`).
    tracking : path
        The tracking file (frame `tracking_frame`; :func:`casep.io.files.read_flight_pair`).
    site : LaunchSite
        Launch point, azimuth and launch time, ``t0`` in the tracking file's time scale (the IMU's is
        ``(t0 - time_shift) / (1 + clock_drift 1e-6)``, :func:`casep.io.pair.telemetry_time`).
    align_window : (T1, T2)
        The span at rest on the pad, in the IMU's time scale, s.
    clock_drift : float
        The IMU clock's drift against the tracking's, ppm: the tracking time tags late by ``clock_drift 1e-6 t``
        more at IMU time ``t`` (an IMU clock fast by 104 ppm: about -104). Taken out of the IMU's own tags and
        steps before it is navigated (:func:`casep.navigation.imu.on_clock`), not out of the tracking's: a clock
        that runs fast stretches every integration step, a common scale factor on every sensor, beside the
        tags' drift against the tracking.
    model : name, path or ErrorModel
        A strapdown model (its sensor errors in ``q_*``, ``fb_*``, ``w_*``), default ``strapdown33``.
    heading_deg, heading_axis
        :func:`casep.navigation.navigate` (None: gyrocompassing, with a warning).
    spec : FitSpec, optional
        The fit request (default :meth:`FitSpec.build`: OLS, the noise model chosen by the data). Its ``prior`` or
        ``bounds`` may be a JSON file's path, read as :func:`casep.separate` and ``casep separate --prior`` read it
        (:func:`casep.workflows.coefficients.read_coefficient_file`; a result of this very flight refused).
    iterate : bool
        Iterate until the correction of every determined combination is below `tol` of its std (default);
        False: one linear pass.
    tol, max_iterations
        The stop rule and the passes allowed (None: :data:`MAX_ITERATIONS`).
    tracking_frame, grid, time_offset, time_shift, fit_time_offset
        As :func:`casep.io.files.read_flight_pair` and :func:`casep.separate` (the time offset found by
        ``"auto"`` on the first pass is kept for the others).
    gyr_range, acc_range : float, optional
        With `imu` a path: the sensors' declared full scales, rad/s and m/s^2 (:func:`casep.navigation.read_imu`:
        the rows from the first clipped sample on are left out); an ImuData was checked when it was read.
    accel_bias_tolerance : float, optional
        :func:`casep.navigation.alignment.align` (m/s^2; None: its default, 80 mg).
    gyro_bias_tolerance : float, optional
        :func:`casep.navigation.alignment.large_pad_rate` (rad/s; None: its default, 2.9 deg/s).
    heading_std_deg : float, optional
        The std of `heading_deg`, deg (None: :data:`HEADING_STD_DEG`; 0: the heading exact), carried into the std
        and covariance as a consider parameter (:meth:`_Run.heading_rows`); only with `heading_deg`.
    clock_drift_std : float, optional
        The std of the IMU clock's drift beyond `clock_drift`, ppm (None: :data:`CLOCK_DRIFT_STD_PPM` without a drift
        given, :data:`CLOCK_GIVEN_STD_PPM` with one; 0: the clock's rate exact), carried into the std and covariance
        as a consider parameter (:meth:`_Run.with_clock`).

    Returns
    -------
    ImuSeparation
    """
    from casep.estimators.spec import FitSpec
    from casep.model.loader import load_model
    from casep.navigation.imu import read_imu

    max_iterations = MAX_ITERATIONS if max_iterations is None else max_iterations
    if not 0 < tol < 1:
        raise ValueError(f"`tol` must be a fraction of the std in (0, 1), got {tol!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"`max_iterations` must be an integer >= 1, got {max_iterations!r}")
    if not isinstance(site, LaunchSite):
        raise TypeError(f"`site` must be a casep.frames.LaunchSite, got {type(site).__name__}")
    heading_std = given_heading_std(heading_deg, heading_std_deg)
    clock_std = given_clock_std(clock_drift, clock_drift_std)
    files = [str(p) for p in (imu, tracking) if isinstance(p, (str, os.PathLike)) and os.path.isfile(p)]
    if not isinstance(imu, ImuData):
        imu = read_imu(imu, gyr_range=gyr_range, acc_range=acc_range)
    elif gyr_range is not None or acc_range is not None:
        raise ValueError("`gyr_range`, `acc_range`: give them to casep.navigation.read_imu (the record is checked "
                         "for clipping as it is read), or pass the IMU file's path")
    spec = FitSpec.build() if spec is None else spec
    base = load_model(model)
    from casep.workflows.coefficients import with_tables

    # a prior or bounds given as a file read as casep.separate and the CLI read it (a result of this flight refused)
    spec = with_tables(spec, None, base, files)
    source = model if isinstance(model, (str, os.PathLike)) else (base.source_file or base.name)
    from casep.io.pair import clock_drift_ppm, telemetry_time, tracking_time
    from casep.navigation.imu import on_clock

    # a clock drift is the IMU's: its tags and steps put at the tracking clock's rate (on_clock), the pad window with
    # them; the navigation then integrates over the true steps and its states pair with the tracking by the shift
    drift = clock_drift_ppm(clock_drift)
    t0_imu = float(telemetry_time(site.t0, time_shift))  # the launch time on the IMU's tags, at the tracking's rate
    window = tuple(float(tracking_time(w, 0.0, drift)) for w in align_window)
    run = _Run(on_clock(imu, drift), tracking, dataclasses.replace(site, t0=t0_imu), site, window, base,
               source, spec, heading_deg, heading_axis,
               {"tracking_frame": tracking_frame, "grid": grid, "time_offset": time_offset, "time_shift": time_shift,
                "clock_drift": 0.0}, fit_time_offset)
    run.clock_ppm = drift
    for name, value in (("accel_bias_tolerance", accel_bias_tolerance), ("gyro_bias_tolerance", gyro_bias_tolerance)):
        if value is not None:
            run.heading[name] = value
    run.heading_std, run.clock_std = heading_std, clock_std
    return run.iterate(iterate, tol, int(max_iterations))


class _Run:
    """One separation: the inputs, and a pass at given coefficients."""

    #: (problem, its tau_profile), formed once per problem (:meth:`tau_profile`; a subclass's too)
    _tau_profile: tuple | None = None
    #: the given heading's std, deg (:meth:`heading_rows`; 0: exact, or gyrocompassed)
    heading_std: float = 0.0
    #: the IMU clock's drift taken out of its tags, ppm (:func:`casep.navigation.imu.on_clock`; 0: none, a telemetry)
    clock_ppm: float = 0.0
    #: the std of the IMU clock's drift beyond :attr:`clock_ppm`, ppm (:meth:`with_clock`; 0: the rate exact)
    clock_std: float = 0.0
    #: (problem, the clock test's record (:func:`clock_check`), the rows' shift for the drift carried): with_clock's
    _clock: tuple | None = None
    #: whether the pairing measured the time offset on the data (``time_offset="auto"``: :meth:`clock_pivot`)
    offset_measured: bool = False
    #: the heading check's finding (:meth:`heading_check`, on the first pass; a class default: a telemetry's passes)
    heading_said: str | None = None
    #: (problem, the rows' derivative along the heading per deg), formed once per problem by :meth:`finish`
    _heading: tuple | None = None
    #: (problem, the rows' shift for one std of each step between samples: :func:`step_rows`), formed by :meth:`finish`
    _steps: tuple | None = None
    #: (problem, :func:`gap_rows`: the rows' shift for unit steps across the IMU's gaps, their times), by :meth:`finish`
    _gaps: tuple | None = None
    #: (problem, noise request, rows, the warnings their preparation gave) of the last pass's fit (:meth:`pass_fit`)
    _rows: tuple | None = None
    #: the IMU's white noise measured on the pad window (:func:`_pad_noise`; empty: not measurable), formed once
    _pad_noise: dict | None = None
    #: (fit, problem, flight, model) of the first pass, linear about no correction (:meth:`turn_judged`)
    _first_pass: tuple | None = None

    def __init__(self, imu: ImuData, tracking: Any, nav_site: LaunchSite, site: LaunchSite, window: tuple,
                 base: ErrorModel, source: Any, spec: FitSpec, heading_deg: float | None, heading_axis: str,
                 pair: dict, fit_time_offset: bool | None) -> None:
        self.imu, self.tracking, self.nav_site, self.site, self.window = imu, tracking, nav_site, site, window
        self.base, self.source, self.spec = base, source, spec
        self.heading: dict[str, Any] = {"heading_deg": heading_deg, "heading_axis": heading_axis}
        self.pair, self.fit_time_offset = dict(pair), fit_time_offset
        if pair["tracking_frame"] != "launch":
            self.pair["site"] = site
        self.nav: NavigationResult | None = None
        self.imu_k: ImuData = imu  # the IMU of the last pass (corrected)
        self.model_k: ErrorModel | None = None  # the model of the last pass
        self.q_aligned = np.array([1.0, 0.0, 0.0, 0.0])  # the last pass's aligned start attitude
        self.C_tb = np.eye(3)  # ... and its body -> launch triad
        self.screen: dict | None = None  # the first pass's tracking screen, kept
        self.inputs_said = False  # whether the inputs' warnings were said before the first pass
        self.limit = np.inf  # the linear region of the last step (:func:`determined_step`), declared magnitudes
        self.rest_shift: np.ndarray | None = None  # mean square shift of the rest's draws (determined_curvature)
        self.data_scale: float | None = None  # the largest of the first pass's rows (m/s): the data's scale

    # ------------------------------------------------------------------ one pass
    def navigate(self, D: np.ndarray) -> NavigationResult:
        """The IMU corrected by `D` (at the attitude of the last navigation), aligned and navigated."""
        from casep.model.strapdown import corrected_attitude, corrected_imu
        from casep.navigation.imu import with_rates
        from casep.navigation.navigator import check_pad_drift, navigate_from, pad_state
        from casep.rotations import dcm_to_quat, quat_to_dcm

        imu = self.imu
        i0 = int(np.searchsorted(imu.t, self.window[0]))
        D = D[:self.base.n_coefficients]  # the IMU's (a fitted dt_trk follows them)
        if self.nav is not None and np.any(D):
            fb, w = corrected_imu(self.base, self.nav.q, imu.f[i0:], imu.w[i0:], imu.t[i0:] - imu.t[i0], D,
                                  start=(self.imu_k.f[i0:], self.imu_k.w[i0:]))  # from the last pass's
            imu = with_rates(imu, np.vstack([imu.w[:i0], w]), np.vstack([imu.f[:i0], fb]))
        q0, r0, v0, t_s, alignment = pad_state(imu, self.nav_site, self.window, **self.heading,
                                               as_given=self.nav is None)
        self.q_aligned, self.C_tb = q0, alignment.C_tb
        phi0, dv0 = self.base.numeric("phi0") @ D, self.base.numeric("dv0") @ D  # the model's own initial terms
        q0 = dcm_to_quat(corrected_attitude(quat_to_dcm(q0), phi0))
        nav = navigate_from(imu, self.nav_site, q0, r0, v0 - dv0, t_start=t_s)
        nav.alignment, nav.align_window = alignment, (float(self.window[0]), float(self.window[1]))
        nav.source = self.imu.source
        if self.nav is None:  # the record as given: rates that no navigating gyro has on a pad are refused
            check_pad_drift(nav, imu, self.nav_site, warn=False,
                            gyro_bias_tolerance=self.heading.get("gyro_bias_tolerance"))
        self.imu_k = imu
        return nav

    def flight(self, nav: NavigationResult, D: np.ndarray, model: ErrorModel | None) -> FlightData:
        """The navigation paired with the tracking, less the model's direct velocity terms at `D`."""
        from casep.checks.tracking_quality import IMU_NOISE_PAD
        from casep.io.files import read_flight_pair
        from casep.io.tables import Table

        tel = Table.from_columns(nav.columns(), f"{self.imu.source} (navigated)")
        # the clipped samples are the IMU record's, found and said once when it was read (casep.navigation.imu:
        # from where on, and that the separation leaves those rows out) and marked ins_valid = 0: the pair's warning
        # of the rows it leaves out for them (their count: meta["ins_invalid"]) and the saturation screen of a
        # telemetry (casep.checks.saturation.screen_saturation), finding them again on the navigated rates, would
        # say them twice more
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", category=SaturationWarning)
            flight = read_flight_pair(tel, self.tracking, **self.pair, rest_window=self.window)  # levelled: at rest
        flight.meta["saturation"] = _imu_saturation(self.imu)
        rows = flight.meta.get("strapdown")
        if isinstance(rows, dict) and rows.get("lost_rows"):  # the record's own gaps: bridged, in the std (step_rows)
            flight.meta["strapdown"] = {**rows, "lost_rows_bridged": True}
        if self._pad_noise is None:
            self._pad_noise = _pad_noise(self.imu, self.window)
        if self._pad_noise:  # the IMU's noise on the pad declared at rest, where the record's counts motion
            flight.meta[IMU_NOISE_PAD] = self._pad_noise
        if self.clock_ppm:  # out of the IMU's own tags and steps (separate_imu), not the tracking's
            flight.meta["clock_drift_ppm"], flight.meta["clock_drift_of"] = self.clock_ppm, "imu"
        if self.heading_said is not None:  # found on the first pass's screened epochs (heading_check)
            _add_setup_problem(flight, self.heading_said)
        if self.pair["tracking_frame"] == "launch":  # taken as launch-inertial: the pad's rotation says if it is
            from casep.io.setup import earth_relative_tracking

            obs = np.asarray(flight.observed)
            why = earth_relative_tracking(self.nav_site, flight.t[obs], flight.dv[obs])
            if why is not None:
                _add_setup_problem(flight, why)
        # the late-start check: the speed relative to the pad (launch-inertial v_tel carries the Earth's rotation)
        flight.meta["start_speed_m_s"] = float(np.linalg.norm(nav.earth_relative()[1][0]))
        if model is None or not np.any(D):
            return flight
        return dataclasses.replace(flight, dv=flight.dv - _direct_velocity(model, flight, D))

    def heading_check(self, flight: FlightData, nav: NavigationResult | None = None) -> str | None:
        """Why the navigation's start heading is wrong (:func:`casep.io.setup.heading_problem`: the navigated
        horizontal velocity turned from the tracked one early in flight), recorded as a set-up problem of `flight`
        (and of every later pass), or None. With the tracked state (``r_*``, ``v_*``: an Earth-fixed tracking) from
        it; with launch-frame tracking from the navigation `nav` (its position, within the INS's drift of the truth:
        the Earth's rotation about it, ``omega_E x r``, is what turns the launch-inertial velocity into the
        Earth-relative one, 0.07 m/s per km of error) and the tracked velocity ``v_tel - dv``; not made without
        either."""
        from casep.io.pair import STATE_SIGNALS
        from casep.io.setup import heading_problem

        heading = getattr(self, "heading", None)  # a telemetry's passes (_TelemetryRun) have no pad alignment
        if heading is None:
            return None
        obs = np.asarray(flight.observed)
        t = flight.t[obs]
        if all(c in flight.signals for c in STATE_SIGNALS):
            r = np.column_stack([flight.signals[f"r_{a}"] for a in "xyz"])[obs]
            v = np.column_stack([flight.signals[f"v_{a}"] for a in "xyz"])[obs]
        elif nav is not None and self.pair.get("tracking_frame") == "launch":
            from casep.checks.plausibility import setup_problems

            if setup_problems(flight):  # a tracking relative to the Earth (earth_relative_tracking): not turned
                return None
            r = np.column_stack([np.interp(t, nav.t, nav.r[:, i]) for i in range(3)])
            v = np.column_stack([np.interp(t, nav.t, nav.v[:, i]) for i in range(3)]) - flight.dv[obs]
        else:
            return None
        h, axis = heading["heading_deg"], heading["heading_axis"]
        said = "gyrocompassing" if h is None else f"--heading {h:g} deg, of body axis {axis}"
        why = heading_problem(self.nav_site, t, v + flight.dv[obs], v, r, said)
        if why is not None:
            _add_setup_problem(flight, why)
        return why

    def model(self, nav: NavigationResult, D: np.ndarray, source: Any = None) -> ErrorModel:
        """The model linearised about the correction at `D` (:func:`casep.model.strapdown.correction_errors`)
        with the alignment's attitude error ``phi0 += A D`` (and ``dt_trk`` when fitted), set up: its S_V is the
        derivative of a pass (navigate the record corrected at `D`, pair) with respect to `D`. `source` another
        model file's (the richer model of :mod:`casep.workflows.omitted_terms`), about the same correction (its
        terms the run's model lacks at 0)."""
        import casadi as ca

        from casep.model.loader import add_time_offset

        A = self.alignment_sensitivity(nav, self._linearised(D, source).setup())
        m = self._linearised(D, source)
        m.set_initial_misalignment(m.output("initial_misalignment") + ca.mtimes(ca.DM(A), ca.vertcat(*m.symbols)))
        if self.fit_time_offset:
            add_time_offset(m)
        m.setup()
        return m

    def _linearised(self, D: np.ndarray, source: Any = None) -> ErrorModel:
        """The model file's model (or `source`'s: its coefficients the run's model lacks at 0), unlocked, its sensor
        errors those of the correction at `D`."""
        from casep.model.loader import build_model
        from casep.model.strapdown import correction_errors

        m = build_model(self.source if source is None else source)
        own = D[:self.base.n_coefficients]
        if source is not None:
            at = dict(zip(self.base.names, own))
            own = np.array([at.get(nm, 0.0) for nm in m.names[:m.n_coefficients]], dtype=float)
        correction_errors(m, own)
        return m

    def alignment_sensitivity(self, nav: NavigationResult, model: ErrorModel | None = None) -> np.ndarray:
        """``A = d phi0 / d D`` (3 x n, rad per natural unit): central differences of the pad alignment
        along each coefficient's body errors over the window (module notes): `model`'s (set up; default the
        model file's), those of the correction at the pass's coefficients (:meth:`model`).

        The alignment's attitude depends on the pad data only through their means over the window
        (:func:`casep.navigation.alignment.align`), so each step aligns two rows holding the perturbed
        means; its attitude error turns from the Earth-fixed triad into the launch-inertial frame with
        the fixed rotation ``R = C_lb C_tb^T`` of the pass.
        """
        from casep.model.strapdown import body_errors

        model = self.base if model is None else model
        imu, (t1, t2) = self.imu_k, self.window
        sel = (imu.t >= t1) & (imu.t <= t2)
        k = np.searchsorted(nav.t, imu.t[sel])
        n = model.n_coefficients
        unit = np.eye(n)
        per = [body_errors(model, nav.q[k], imu.f[sel], imu.w[sel], imu.t[sel] - nav.t[0], unit[j])
               for j in range(n)]
        directions, steps = [], []
        for df, dw in per:
            df, dw = df.mean(axis=0), dw.mean(axis=0)
            size = max(np.abs(df).max() / 9.8, np.abs(dw).max() / 7.3e-5)
            directions.append((df, dw))
            steps.append(_ALIGN_STEP_RAD / size if size > 0 else 0.0)
        return self._alignment_derivative(directions, steps)

    def levelling_jacobian(self) -> np.ndarray:
        """``L = d phi0 / d mean(delta_f)`` (3 x 3, rad per m/s^2): the start attitude error (launch-inertial) per
        unit error of the pad window's mean body specific force, by central differences of the alignment of the
        last pass (as :meth:`alignment_sensitivity`, along each body axis): what the accelerometer noise on the
        pad does to the start (:func:`imu_noise_budget`)."""
        imu, (t1, t2) = self.imu_k, self.window
        sel = (imu.t >= t1) & (imu.t <= t2)
        h = _ALIGN_STEP_RAD * float(np.linalg.norm(imu.f[sel].mean(axis=0)))  # m/s^2: turns the attitude by ~1e-6 rad
        return self._alignment_derivative([(np.eye(3)[i], np.zeros(3)) for i in range(3)], [h] * 3)

    def _alignment_derivative(self, directions: list[tuple[np.ndarray, np.ndarray]], steps: list[float]) -> np.ndarray:
        """The derivative of the last pass's start attitude error (launch-inertial) along changes of the pad window's
        mean body specific force and rate, by central differences: column j along ``(df_j, dw_j)`` (`directions`)
        with step ``h_j`` (`steps`; 0: the column is 0).

        The alignment depends on the pad data only through their means over the window
        (:func:`casep.navigation.alignment.align`), so each step aligns two rows holding the perturbed means;
        with ``C`` the perturbed triad and ``C_ref`` the unperturbed one (``C = (I - [phi x]) C_ref``), ``phi`` is
        the rotation vector of ``C_ref C^T``, turned into the launch-inertial frame by the fixed ``R = C_lb C_tb^T``::

            A[:, j] = (phi(+h_j) - phi(-h_j)) / (2 h_j)
        """
        from scipy.spatial.transform import Rotation

        from casep.navigation.alignment import align
        from casep.navigation.strapdown import quat_to_dcm

        imu, (t1, t2) = self.imu_k, self.window
        sel = (imu.t >= t1) & (imu.t <= t2)
        f_mean, w_mean = imu.f[sel].mean(axis=0), imu.w[sel].mean(axis=0)
        R = quat_to_dcm(self.q_aligned) @ self.C_tb.T  # triad -> launch-inertial at the first sample
        tt = np.array([t1, t2])
        A = np.zeros((3, len(directions)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a gyrocompassing warning per step: said once, by the pass itself
            C_ref = align(tt, np.tile(w_mean, (2, 1)), np.tile(f_mean, (2, 1)), self.window, self.nav_site,
                          **self.heading, as_given=False, judge_earth_rate=False).C_tb  # a derivative's means
            for j, ((df, dw), h) in enumerate(zip(directions, steps)):
                if h == 0:
                    continue
                phi = [R @ Rotation.from_matrix(C_ref @ align(tt, np.tile(w_mean + s * dw, (2, 1)),
                                                             np.tile(f_mean + s * df, (2, 1)), self.window,
                                                             self.nav_site, **self.heading,
                                                             as_given=False, judge_earth_rate=False).C_tb.T
                                               ).as_rotvec()
                       for s in (h, -h)]
                A[:, j] = (phi[0] - phi[1]) / (2 * h)
        return A

    def solve(self, D: np.ndarray | None, spec: FitSpec) -> tuple[EstimateResult, NavigationResult, FlightData,
                                                                   ErrorModel, Any]:
        """One pass at `D` (None: the first, uncorrected): navigate, pair, model, and the estimate alone (no
        judgement of the residuals, no warnings: the last pass's fit is made again, whole, by :meth:`iterate`)."""
        from casep.checks.flight import flight_problem
        from casep.checks.tracking_quality import keep_screen, screen_tracking

        first = D is None
        quiet = not first or self.inputs_said
        D = np.zeros(self.base.n_coefficients) if D is None else D
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")  # the inputs' warnings were shown on the first pass
            nav = self.navigate(D)
            flight = self.flight(nav, D, None if first else self.model_k)
        if first:  # the tracking screen of the first pass, said and kept for every pass (module notes)
            flight = screen_tracking(flight, drift_warning=False)  # the drift: on the fit's residuals
            self.screen = flight.meta.get("tracking_screen")
            self.heading_said = self.heading_check(flight, nav)
        else:
            flight = keep_screen(flight, self.screen)
        if first:
            from casep.io.pair import fits_time_offset

            if self.fit_time_offset is None:
                self.fit_time_offset = fits_time_offset(flight.meta)
            align = flight.meta.get("time_alignment") or {}
            if self.pair["time_offset"] == "auto":  # the offset of the first pass, kept (the grid stays)
                self.pair["time_offset"] = align.get("applied_s", 0.0) or None
                self.offset_measured = True
        self.nav = nav
        with warnings.catch_warnings():
            if quiet:
                warnings.simplefilter("ignore")  # S_V's warnings said once, too
            # the navigated telemetry's gaps are the IMU's, said when it was read with what they leave unknown
            # (casep.navigation.imu: one GapWarning); S_V's own of the same gaps would say them twice
            warnings.filterwarnings("ignore", category=GapWarning)
            model = self.model(nav, D)
            problem = flight_problem(flight, model)
        # the passes step along the combinations the record determines exactly (estimable rows, module notes);
        # an exactly dependent coefficient stays without an estimate here, whatever its partners' magnitudes
        # (casep.regression.linalg.PartnerBound: a statement of the linear fit, not a step direction)
        problem.magnitudes = {}
        self.model_k = model
        return self.pass_fit(problem, spec.about(model.names, D)), nav, flight, model, problem

    def pass_fit(self, problem: Any, spec: FitSpec) -> EstimateResult:
        """:func:`_quiet_fit` of a pass, its rows (:func:`casep.estimators.solve.rows_for`: the noise model fitted, the
        robust weights) and the warnings their preparation gave kept for :meth:`judged_fit` of the same problem."""
        if not _rows_reusable(spec):
            return _quiet_fit(problem, spec)
        from casep.estimators.solve import fit, rows_for

        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            rows = rows_for(problem, spec.noise)
        self._rows = (problem, spec.noise, rows, list(said))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fit(problem, spec, rows=rows, checks=False)

    def judged_fit(self, problem: Any, spec: FitSpec) -> EstimateResult:
        """``fit(problem, spec)``, its warnings shown: with the rows of the last pass's fit (:meth:`pass_fit`) when
        they are this problem's (the same object) under the same noise request, their preparation's warnings said
        again; the same numbers, without fitting the same noise model twice."""
        from casep.estimators.solve import fit

        kept = self._rows
        if kept is None or kept[0] is not problem or kept[1] != spec.noise or not _rows_reusable(spec):
            return fit(problem, spec)
        for w in kept[3]:
            warnings.warn(w.message, w.category, stacklevel=2)
        return fit(problem, spec, rows=kept[2])

    # ------------------------------------------------------------------ the iteration
    def trial(self, D: np.ndarray, spec: FitSpec, before: Any, bound: float | None = None) -> tuple | str:
        """The pass at `D` (:meth:`solve`), or why the step to `D` leaves the linear model (the state of the last
        pass kept): the correction does not invert, or the step does not descend: with `bound` (a white pass, m^2/s^2:
        :meth:`iterate`'s non-monotone bound) the rows' sum of squares after it exceeds `bound`, otherwise their RMS
        grows more than :data:`WORSE` times that of the pass before (`before`, the rows the step was fitted to);
        never at the rounding level (:meth:`at_rounding`). `before` None: not judged (a step that cannot be narrowed:
        the stretches' combinations, or no covariance).

        The white passes minimise the rows' plain sum of squares, so their Gauss-Newton steps must lower it: with the
        tenfold rule alone, the first pass of the shipped MEMS example under ``strapdown33`` stepped 2.9e3 declared
        magnitudes along combinations of std up to 1.6e3, raised the rows' RMS from 13.6 to 16.8 m/s, and the passes
        then crept back by 0.64 a pass from a point whose rows' RMS was 0.062 m/s (the white fixed point's 0.033) and
        did not converge in 20."""
        state = self._state()
        try:
            out = self.solve(D, spec)
        except ValueError as exc:
            why = f"the correction does not apply: {exc}"
        else:
            if before is None:
                return out
            rms = [_rms(p.y) for p in (before, out[4])]
            if self.at_rounding(rms[1]):
                return out
            if bound is None:
                if rms[1] <= WORSE * rms[0]:
                    return out
                why = f"the residual grew from {rms[0]:.3g} to {rms[1]:.3g} m/s RMS"
            else:
                ssr = _ssr(out[4].y)
                if ssr <= bound:
                    return out
                why = (f"{_NO_DESCENT}: the rows' sum of squares after it is {ssr:.4g} m^2/s^2 (RMS {rms[1]:.3g} m/s, "
                       f"{rms[0]:.3g} before it), above {bound:.4g}, the largest of the last {DESCENT_MEMORY} passes' "
                       "and one sigma^2")
        self._restore(state)
        return why

    def _state(self) -> tuple:
        """What a pass leaves on the run (navigation, corrected IMU, model, aligned attitude, triad), to restore."""
        return self.nav, self.imu_k, self.model_k, self.q_aligned, self.C_tb

    def _restore(self, state: tuple) -> None:
        """The run as :meth:`_state` found it."""
        self.nav, self.imu_k, self.model_k, self.q_aligned, self.C_tb = state

    def back_to_prior(self, D: np.ndarray, move: np.ndarray, back: tuple[np.ndarray, int], spec: FitSpec,
                      trial: tuple, noise_factor: float = 1.0) -> tuple[np.ndarray, tuple]:
        """The step `move` from `D` (its pass `trial`), or ``move - back`` (its pass) when the record fits as well
        with the estimate's part along what it does not determine, beyond its plausible size (`back`,
        :func:`_beyond_plausible`), back at the prior.

        A first pass steps along everything, its estimates mostly linearisation error; a later pass leaves what the
        record does not determine where that put it, and linearises about that point (a MEMS rail launch,
        ``benchmarks/mems_rail_honesty.py`` seed 6: ``bg_x`` at -9380 deg/h, the truth -120: the stated
        combinations 16 std off). But the navigation is not linear, and a record can see that size where the linear
        fit cannot (a MEMS gyro bias of 800 deg/h turns the pad attitude by degrees): the prior is taken only when
        the residuals' sum of squares after the pass's fit grows by less than a chi-square on as many degrees of
        freedom as there are combinations taken back exceeds with probability :data:`BACK_TO_PRIOR_P` (in the
        variance of the residuals of the step kept): the likelihood ratio's test that the record cannot tell the
        two points apart.

        Under correlated tracking noise (Gauss-Markov plus white) that variance is not the growth's scale: the growth
        is ``dx^T S^T S dx`` of the estimate's move ``dx``, whose variance is `noise_factor` squared times the white
        one (:func:`casep.estimators.solve.richer_noise_factor`, the white passes' factor), so the statistic is

            chi^2 = (SSR_prior - SSR_kept) / (s^2 noise_factor^2)

        With ``s^2`` alone, a tactical aircraft flight (5 Hz GNSS, tau 2.5 s, factor 4.0) kept the first pass's
        ``ma_zy`` 78 declared magnitudes from the truth: the prior, 0.8 from it, grew the sum by 9.8 to 18.9 of
        ``s^2`` on 2 combinations (p 0.007 to 8e-5), 0.6 to 1.2 in the noise's own scale."""
        state = self._state()
        pull, k = back
        other = self.trial(D + move - pull, spec, None)
        if not isinstance(other, str):
            ssr = [float(np.sum(np.square(t[0].residuals))) for t in (trial, other)]
            dof = trial[0].residuals.size - len(trial[0].names)
            if prior_fits_p(ssr[0], ssr[1], dof, k, noise_factor) > BACK_TO_PRIOR_P:
                return move - pull, other
        self._restore(state)
        return move, trial

    def at_rounding(self, rms: float) -> bool:
        """Whether a pass's rows of RMS `rms` (m/s) are at the rounding level of the data, the first pass's rows (the
        velocity errors before any correction): :func:`casep.regression.problem.is_rounding_level`, the project's one
        noise-free rule, on their largest magnitude. A later pass's own rows are residuals, and their rounding level
        would be that of the residual itself: on a noise-free pad record (rows of 0.13 m/s before the first pass,
        1e-11 to 8e-11 m/s from the fourth on) the passes rejected steps that took the rows from 1e-11 to 1e-9 m/s as
        growing a hundredfold and never stopped. Without the pair's interpolation floor
        (:meth:`casep.regression.problem.Problem.is_noise_free`): it bounds what the pair of files holds, not where the
        passes' fixed point is (on the noise-free MEMS boost of the tests it is 3.3e-3 m/s, and rows below it left
        coefficients 1e-4 off)."""
        from casep.regression.problem import is_rounding_level

        return self.data_scale is not None and is_rounding_level(float(rms), self.data_scale)

    def iterate(self, iterate: bool, tol: float, max_iterations: int) -> ImuSeparation:
        """Passes until the correction of every determined combination is below `tol` std (:func:`determined_step`;
        one pass without `iterate`).

        While the corrections are large, a pass is solved by OLS under white noise (:func:`_fast_spec`: the
        noise model of the requested fit is fitted to residuals that are still mostly linearisation
        error); once they are below `tol` std, the same pass is solved as requested and the passes go on
        with it until its corrections are below `tol` std too.
        """
        fast = _fast_spec(self.spec) if iterate else None
        spec = fast or self.spec
        res, nav, flight, model, problem = self.solve(None, spec)
        self._first_pass = (res, problem, flight, model)
        from casep.checks.plausibility import setup_problems

        if setup_problems(flight):  # a set-up mistake (site, frame, times): passes would fit it, not the instrument
            iterate = False  # one pass, which the set-up judgement fails (judge_setup, in finish)
        self.data_scale = float(np.max(np.abs(problem.y), initial=0.0)) if problem.y is not None else None
        from casep.regression.problem import rounding_level

        floor = 0.0 if self.data_scale is None else float(rounding_level(self.data_scale))  # the data's, every pass
        D = np.zeros(len(res.names))
        passes: list[dict] = []
        failure, last = None, None
        rejected: list[dict] = []  # the steps of this pass outside the linear model
        k, limit = 1, np.inf
        rows_before = np.inf  # the RMS of the rows of the pass before (m/s)
        noise_factor = 1.0  # the white passes' std under the record's correlated noise (Step.noise_factor)
        history = [_ssr(problem.y)]  # the rows' sum of squares of every pass (m^2/s^2; DESCENT_MEMORY)
        while True:
            step = determined_step(res, problem, flight, model.scales, limit, about=D, floor=floor)
            noise_factor = step.noise_factor if spec is fast else noise_factor
            how = "ols, white noise (while far)" if spec is fast else "as requested"
            # noise-free: the correction at the coefficients' rounding, or the rows at `D` at the data's and no longer
            # falling (to under STALL of the pass before's): `D` fits the data to their rounding, a fixed point
            rows = _rms(problem.y)
            rounding = _at_rounding(D, step, model.scales, res.names) or (self.at_rounding(rows)
                                                                           and rows > STALL * rows_before)
            passes.append(_pass_record(k, res, step, D + res.fitted_coefficients(), how, rounding))
            if rejected:  # the same pass, its step narrowed
                passes[-1]["rejected"] = list(rejected)
            if step.beyond:
                passes[-1]["left_out"] = [{"std": sd, "z": z, "combination": nm} for sd, z, nm in step.beyond]
                passes[-1]["plausible_size"] = _step_size(step, D, model.scales, res.names)
            if step.kept:  # some combination left out: the ones stepped along, stated
                scale = _scale_of(model.scales, res.names)
                passes[-1]["determined"] = [{"std": sd, "weights": w.tolist(), "estimate": float(w @ ((D + step.d)
                                                                                                     / scale))}
                                            for sd, w in step.kept]
            if not iterate:
                break
            if _stopped(passes[-1], tol):
                if spec is self.spec or step.combinations is not None:  # the stretches' combinations: any fit
                    failure = _outside_failure(step, rejected, _step_size(step, D, model.scales, res.names))
                    break
                spec, last = self.spec, None  # the same linearisation, solved as requested (another map)
                res = self.pass_fit(problem, spec.about(res.names, D))
                continue
            if k == max_iterations:
                failure = (f"failed: the iteration did not converge in {max_iterations} passes (the last correction "
                           f"was {step.max_z:.3g} std of {step.worst}, the stop rule {tol:g} std): " + _BLAME)
                break
            near = step.max_z < ACCELERATE_BELOW
            move = _secant_step(D, step.d, step.metric, last) if near else step.d
            judged = problem if 0 < step.widest < np.inf else None
            bound = max(history[-DESCENT_MEMORY:]) + DESCENT_SLACK * float(res.sigma) ** 2 \
                if spec is fast and np.isfinite(res.sigma) else None  # the non-monotone descent (DESCENT_MEMORY)
            trial = self.trial(D + move, spec, judged, bound)
            if isinstance(trial, str) and move is not step.d:  # the secant step rejected: the pass's own step first
                move = step.d
                trial = self.trial(D + move, spec, judged, bound)
            alpha = 1.0  # a white pass's step that does not descend: halved (a backtracking line search) ...
            while isinstance(trial, str) and trial.startswith(_NO_DESCENT) and alpha > 0.5**HALVINGS:
                alpha *= 0.5
                move = alpha * step.d
                trial = self.trial(D + move, spec, judged, bound)
            if alpha < 1.0 and not isinstance(trial, str):
                passes[-1]["damped"] = alpha
            back = _beyond_plausible(step, D + move, model.scales, res.names)
            if back is not None and not isinstance(trial, str):
                move, trial = self.back_to_prior(D, move, back, spec, trial, noise_factor)
            if isinstance(trial, str):  # outside the linear model: the same pass, the widest combinations left out
                if not 0 < step.widest < np.inf:  # nothing to narrow (no covariance, or no combination left)
                    failure = f"failed: pass {k + 1} could not take the step of pass {k} ({trial}): " + _BLAME
                    break
                rejected.append({"limit": float(limit) if np.isfinite(limit) else None, "widest": step.widest,
                                 "why": trial})
                passes.pop()
                limit, last = step.widest / NARROW, None
                continue
            last = (D, step.d) if near else None
            D, k, rejected, rows_before = D + move, k + 1, [], _rms(problem.y)
            res, nav, flight, model, problem = trial
            history.append(_ssr(problem.y))
        self.limit = step.limit
        # the last linearisation, judged (its warnings are the result's); a prior or bounds on the coefficients
        res = _settings_on_coefficients(self.judged_fit(problem, self.spec.about(res.names, D)), D)
        return self.finish(res, nav, flight, model, problem, D, passes, failure, (iterate, tol, max_iterations))

    def finish(self, res: EstimateResult, nav: NavigationResult, flight: FlightData, model: ErrorModel,
               problem: Any, D: np.ndarray, passes: list[dict], failure: str | None,
               rule: tuple[bool, float, int]) -> ImuSeparation:
        """The result of the last pass (linearised about `D`) with the accumulated estimate ``D + x`` (``x`` the
        solver's solution: :meth:`EstimateResult.fitted_coefficients`), judged as :func:`casep.separate` judges a
        flight (set-up, magnitudes, the tracking's stretches: the combinations as totals), its warnings re-issued."""
        from casep.estimators.registry import failed
        from casep.model.loader import model_record
        from casep.workflows.judging import judge_pad_hold, judge_setup, judge_tracking

        iterate, tol, max_iterations = rule
        total = D + res.fitted_coefficients()
        estimate = np.where(np.isfinite(res.estimate), total, np.nan)
        diag = dict(res.diagnostics)
        diag["iterations"] = {"iterate": iterate, "tol": tol, "max_iterations": max_iterations,
                              "converged": failure is None and (not iterate or _stopped(passes[-1], tol)),
                              "passes": passes}
        solution = None if res.solution is None else dataclasses.replace(res.solution, x=total)
        out = dataclasses.replace(res, estimate=estimate, diagnostics=diag, solution=solution,
                                  **model_record(self.base))
        self._heading = (problem, self.heading_rows(D))
        # a telemetry's passes (casep.workflows.telemetry_iterate) have no raw record, and no steps between samples
        self._steps = (problem, step_rows(getattr(self, "imu", None), nav, problem))
        self._gaps = (problem, gap_rows(getattr(self, "imu", None), nav, problem))
        out = self.with_noise(out, problem, flight)
        out = self.with_clock(out, problem, flight, D)
        if passes[-1].get("determined"):  # the stated combinations' std carry the record's noise as the coefficients'
            passes[-1]["determined"] = self.combinations_with_noise(passes[-1]["determined"], out, problem, flight,
                                                                    model.scales)
        if iterate and failure is None and not _stopped(passes[-1], tol) and out.success:
            failure = f"failed: the iteration stopped at pass {len(passes)} before converging"
        if failure is not None:
            gap = self.gap_clause(float(out.sigma)) or _late_tags_clause(flight)
            out = failed(out, STATUS_NOT_CONVERGED, failure.replace(_BLAME, gap) if gap else failure)
        out = self.unit_or_heading_judged(out, problem, flight, D, settled=_stopped(passes[-1], tol))
        test = (out.diagnostics.get("heading") or {}).get("test") or {}
        if test.get("conflict") and _BLAME in out.message:  # the step failed on the turn the heading leaves
            out = dataclasses.replace(out, message=out.message.replace(_BLAME, _heading_blame(test)))
        out = self.clock_judged(out, problem, flight, D)
        from casep.workflows.omitted_terms import judge_omitted

        # the richer model's terms beside the last pass, its S_V that pass's (the richer model linearised alike)
        out = judge_omitted(out, flight, problem, model, lambda name: self.model(nav, D, name))
        widen = None
        if iterate and failure is None:  # the combinations' curvature over what the flight does not determine
            def widen(combos: list[dict]) -> tuple[list[dict], str | None, dict | None]:
                return self.determined_curvature(combos, problem, flight, D)
        out = judge_setup(out, flight, model, noise_free=False)
        # the tracking clock's tests measure a late tag's drift, which is not a raw IMU clock's (clock_judged)
        out = judge_tracking(out, flight, problem, model.scales, about=D, widen=widen,
                             tag_clock=getattr(self, "imu", None) is None)
        if iterate and out.success and passes[-1].get("determined") and not out.diagnostics.get("determined"):
            out = self.left_out_curvature(out, passes[-1], problem, flight, D)
        if passes[-1].get("determined"):  # every consider term the coefficients carry (the last: the omitted terms)
            _with_consider_stated(passes[-1], out, model.scales, stated=iterate)
        if iterate and passes[-1].get("determined") and not out.diagnostics.get("determined"):
            out = _with_determined(out, passes[-1], model.scales)
        out.diagnostics["iterations"]["limit"] = float(self.limit) if np.isfinite(self.limit) else None
        # what the record leaves undetermined is said with every result that has estimates, failed or not, of the
        # iteration or of one linear pass (its pass steps along what the record determines as an iteration's first)
        smaller = None if "a smaller model" in out.message else SMALLER_MODELS.get(self.base.name)
        alone = int(np.isfinite(out.estimate).sum()) - len(out.diagnostics.get("not_determined") or ())
        said = _outside_note(passes, len(out.names), passes[-1].get("plausible_size", np.inf), smaller, alone,
                             out.names) \
            if out.solution is not None or np.any(np.isfinite(out.estimate)) else None
        if said:
            from casep.exceptions import NonlinearityWarning

            warnings.warn(said, NonlinearityWarning, stacklevel=3)
            if iterate:
                out = _with_line(out, said)
        if iterate and out.success:  # a failed result's std are not used: no curvature to carry
            out = self.curvature(out, problem, D)
        elif not iterate and out.success:  # one linear pass: its second-order remainder judged, as a telemetry's
            shift = linearisation_shift(self, res, problem, flight, model.scales)
            if shift.std is not None:
                out = one_pass_judged(out, shift)
        if said and not iterate:  # after the judgement, whose failure message replaces a success's
            out = _with_line(out, said)
        # the static hold on the pad, out of the fit's rows: its zero-velocity check, with the covariance as stated
        out = judge_pad_hold(out, flight, model, about=D)
        heading = heading_said((out.diagnostics.get("heading") or {}).get("test"))
        if heading is not None:  # last: a failure's message replaces a success's
            if heading[1]:
                from casep.exceptions import SetupWarning

                warnings.warn(heading[0], SetupWarning, stacklevel=3)
            out = _with_line(out, heading[0])
        out = unit_first(heading_first(out))
        return ImuSeparation(_advice_first(out, SMALLER_MODELS.get(self.base.name)), nav, flight, passes)

    def unit_or_heading_judged(self, out: EstimateResult, problem: Any, flight: FlightData, D: np.ndarray,
                               settled: bool) -> EstimateResult:
        """`out` judged for rates in another unit, else for the heading and a turned tracking (:meth:`finish`).

        Rates in another unit (deg/s read as rad/s) turn the navigation from the tracking as no error model can:
        where the result misfits beyond the noise (judged or not yet), the other reading's one linear pass
        (:mod:`casep.workflows.imu_units`) is named first (a failed set-up); otherwise the heading given is tested
        (:meth:`heading_judged`; `settled`: the passes met the stop rule) and a turned tracking named
        (:meth:`turn_judged`)."""
        from casep.estimators.registry import STATUS_SETUP, failed
        from casep.workflows.imu_units import rate_unit_reading

        unit = rate_unit_reading(self, out, flight, _fast_spec(self.spec) or self.spec)
        if unit is None:
            return self.turn_judged(self.heading_judged(out, problem, flight, D, settled=settled))
        from casep.exceptions import SetupWarning

        out.diagnostics["rate_unit"] = unit
        warnings.warn(unit["said"], SetupWarning, stacklevel=4)
        return failed(out, STATUS_SETUP, f"failed: {unit['said']}")

    def left_out_curvature(self, res: EstimateResult, last: dict, problem: Any, flight: FlightData,
                           D: np.ndarray) -> EstimateResult:
        """`res` with the curvature of what the passes left out in the std of the combinations it states (``last``:
        the last pass's record, its ``determined`` the combinations stepped along, their std with the record's noise;
        updated in place, the curvature's record in ``last["curvature"]``).

        The combinations the steps leave out (:func:`determined_step`) stay where the passes put them, and the truth is
        the instrument's plausible size away there. The stated combinations are gradients about that point, and their
        linear std leave out the second order over that distance: on 4 seeded MEMS boosts under ``strapdown33``
        (``tests/workflows/test_imu_separate.py``) 3 were a success with the stated combinations 9 to 36 std RMS off the
        truth (up to 101), and the second-order remainder of the pass over the distance to the truth was their whole
        error (RMS z 0.8 to 1.3 once taken off). :meth:`determined_curvature` draws the rest at the plausible size
        ``rho`` of the stated combinations (:func:`casep.checks.tracking_quality.plausible_size`), carries the shift in
        their std and says it (those whose std, the consider terms added, reach ``rho`` are no longer determined:
        :func:`_determined_size`'s rule, decided in :meth:`finish`); when it moves them by more than their linear std
        the message names the smaller shipped models (:data:`SMALLER_MODELS`), which leave less undetermined. No draw
        that can be navigated: the stated combinations cannot be checked, and the result fails (status
        ``STATUS_MISFIT``, as :func:`one_pass_judged` fails a linear pass whose record does not invert at the estimate).
        It fails the same way when some draws cannot be navigated and those that can move a combination by more than
        :data:`CURVATURE_RELIABLE` times its linear std: the draws lost are the far ones, so the mean square of the rest
        understates the shift, and the second order already outgrows the first (an outside clean 800 Hz MEMS rocket: 2
        of 4 draws navigated, shift up to 13 std, the stated combinations 2.4 std RMS off the truth)."""
        from casep.estimators.registry import STATUS_MISFIT, failed

        combos = last["determined"]
        kept, note, record = self.determined_curvature(combos, problem, flight, D, length=True)
        last["determined"], last["curvature"] = kept, record
        if note is None:
            return self.with_rest_shift(res)
        smaller = SMALLER_MODELS.get(self.base.name)
        if smaller:
            note += (f"; the passes stepped along {len(kept)} of {len(res.names)} combinations of `{self.base.name}`: "
                     f"a smaller model ({smaller}) leaves less undetermined")
        if not record["checked"]:
            return failed(res, STATUS_MISFIT, f"failed: {note}, so whether the combinations stated are what the "
                                              "record determines is unknown")
        res = self.with_rest_shift(res)
        worst = max(record.get("shift_std") or [0.0])
        if record["draws"] < record["asked"] and worst > CURVATURE_RELIABLE:
            # the draws the record cannot invert at are the far ones: the mean square of those it can is no bound
            return failed(res, STATUS_MISFIT,
                          f"failed: {note}; {record['asked'] - record['draws']} of the {record['asked']} draws do not "
                          f"invert (the far ones), and the {record['draws']} that do already move a stated combination "
                          f"by {worst:.3g} times its linear std (above {CURVATURE_RELIABLE:g}): the std stated are no "
                          "bound on the error, so the combinations are not presented as a result")
        return _with_line(res, note)

    def with_rest_shift(self, res: EstimateResult) -> EstimateResult:
        """`res` whose covariance gains the mean square of the shifts :meth:`determined_curvature`'s draws of the
        rest made, ``C + mean(b b^T)`` (``b`` each draw's shift of the estimate, natural units): the truth is such a
        draw away, as :meth:`curvature` adds one std's. Without it the stated combinations carried the shift and
        the covariance did not (a MEMS rail launch, ``benchmarks/mems_rail_honesty.py`` seed 6: chi-square 254 on
        the 6 directions of the covariance with std below their declared magnitudes). Added through
        :func:`~casep.workflows.row_estimators.with_extra_covariance`, the one place a consider term widens a result:
        the solution's covariance (what the iteration's step reads) gains it too, a coefficient without an estimate
        keeps its NaN, and the running total of the consider terms (``diagnostics["consider"]["covariance"]``) holds
        it, so that a covariance set anew later adds it back. ``diagnostics["rest_shift_std_factor"]``: each std
        over the one before (None: no estimate)."""
        extra, C = self.rest_shift, res.covariance
        if extra is None or C is None:
            return res
        before = np.sqrt(np.abs(np.diag(np.asarray(C, dtype=float))))
        out = with_extra_covariance(res, extra)
        after = np.sqrt(np.abs(np.diag(np.asarray(out.covariance, dtype=float))))
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(before > 0, after / np.where(before > 0, before, 1.0), np.nan)
        out.diagnostics["rest_shift_std_factor"] = {nm: float(v) if np.isfinite(v) else None
                                                    for nm, v in zip(res.names, factor)}
        out.diagnostics[REST_SHIFT_KEY] = np.asarray(extra, dtype=float).tolist()  # in the consider total: its part
        return out

    def with_noise(self, res: EstimateResult, problem: Any, flight: FlightData) -> EstimateResult:
        """`res` with the record's own noise in its std, the pad levelling's start tilt with it
        (:func:`with_imu_noise`)."""
        heading = self.heading_effect(problem)
        steps = self.steps_effect(problem)
        # the coefficients' estimators, formed once for the budget and the heading's record (the budget's refit
        # changes the covariance, not the noise model that whitens the rows, so they are the same)
        a = None if heading is None else coefficient_estimators(res, problem)
        out = with_imu_noise(res, problem, flight, self.levelling(), self.tau_profile(problem),
                             consider_columns(heading, steps), estimators=a)
        if steps is not None:
            out = with_steps(out if out is not res else with_consider(res, problem, steps), res, problem,
                             getattr(self, "imu", None))
        if heading is not None and a is not None and out is not res and out.std is not None:
            out.diagnostics["heading"] = {"coefficients": heading_record(
                self.heading["heading_deg"], self.heading_std, a @ heading.reshape(-1), out.std, list(out.names))}
        return out

    def heading_judged(self, res: EstimateResult, problem: Any, flight: FlightData,
                       D: np.ndarray, settled: bool = True) -> EstimateResult:
        """`res` with the test of the given heading against the data (:func:`heading_conflict`) in
        ``diagnostics["heading"]["test"]``; where the data contradict it, said (:class:`casep.exceptions.SetupWarning`,
        :func:`heading_message`) and failed (status ``STATUS_PRIOR_CONFLICT``: the heading's std is its prior). Not
        on noise-free rows (:meth:`at_rounding`, :meth:`casep.regression.problem.Problem.is_noise_free`): their std
        are rounding, and the passes' remainder at their fixed point would read as a heading error; nor on a flight
        with a set-up problem (:func:`casep.checks.plausibility.setup_problems`: a wrong tracking frame, a heading
        turned beyond 30 deg), whose rows are that mistake, not a heading within the linear model's reach. Judged
        only where the record determines the heading within the small-angle reach (its std times the limit within
        :data:`SMALL_ANGLE_REACH_DEG`, the frame test's rule): an iteration stopped two
        passes early read -417 +- 34 deg. Where the passes `settled` (the stop rule met: a success, or a
        combination left out after it), a test beyond its limit is a conflict and the heading is named first
        (:func:`heading_first`), whatever else fails: the coefficients absorb a wrong heading's turn, and the
        misfit, the estimates beyond the linear model and the step that leaves it are its consequences. The pass's
        rows navigated at the heading the data point to (at `D`: ``at_suggested_deg``) say how far the linear test
        reaches: a turn left there beyond :data:`HEADING_SETTLED_Z` of its std makes the heading it points to
        approximate (``settled`` False), which the message says. (A rule that took a turn left there above half of
        the one found for the passes' remainder, no conflict, hid a heading 10 deg off on the simulated strapdown
        boost: +9.63 +- 0.55 deg, z 17, -6.96 deg left at the suggested 200.44 deg, the truth 200.07, where the
        coefficients fitted at the wrong heading had absorbed the turn; the rail launch under ``strapdown12`` it was
        made for reads z 0.26 to 0.85 at the true heading now, 5 seeds: ``python benchmarks/heading_test_mc.py rail
        --model strapdown12 --seeds 1 2 3 4 5 --offsets 0``.) Where the passes stopped before settling (the pass
        bound, a step that could not be taken), the rows hold the passes' remainder, and that rule stands: a
        conflict only where the turn left at the suggestion is below half of the one found, said after the
        failure that stopped them (an IMU gap stopped at two passes read +2.14 +- 0.08 deg, 0.35 left)."""
        from casep.checks.plausibility import setup_problems
        from casep.estimators.registry import STATUS_PRIOR_CONFLICT, failed
        from casep.exceptions import SetupWarning
        per_deg = self.heading_derivative(problem)
        if per_deg is None or problem.y is None or setup_problems(flight):  # a set-up mistake: its failure says it
            return res
        rms = problem.ls_rms()
        if self.at_rounding(rms) or problem.is_noise_free(rms):  # no noise: no std to test the heading against
            return res
        noise, h0 = self.with_heading_noise(res, problem, per_deg, D), self.heading["heading_deg"]
        args = (self.levelling(), self.tau_profile(problem))
        record = heading_conflict(noise, problem, flight, per_deg, h0, self.heading_std, *args)
        if record is None:
            return res
        res.diagnostics["heading"] = {**res.diagnostics.get("heading", {}), "test": record}
        record["judged"] = bool(within_small_angle_reach(record["std_deg"], record["limit_z"]))
        record["first"] = bool(settled)
        if not record["judged"]:
            record["conflict"] = False  # beyond the small-angle reach: the test says nothing
        if not record["conflict"]:
            return res
        # the linear model at the heading the data point to: the pass's rows there, the same estimator
        try:
            there = self.rows_at_heading(D, record["suggested_heading_deg"])
        except ValueError:
            there = None
        again = None if there is None else heading_conflict(noise, problem.with_y(there), flight, per_deg, h0,
                                                            self.heading_std, *args)
        record["at_suggested_deg"] = None if again is None else again["estimate_deg"]
        if not settled and (again is None or not abs(again["estimate_deg"]) < abs(record["estimate_deg"]) / 2):
            record["conflict"] = False  # passes stopped before settling: their remainder, not a turn the data show
            return res
        record["settled"] = bool(again is not None
                                 and abs(again["estimate_deg"]) <= HEADING_SETTLED_Z * again["std_deg"])
        said = heading_message(record, self.heading["heading_axis"])
        record["said"] = f"failed: {said}"
        warnings.warn(said, SetupWarning, stacklevel=4)
        return failed(res, STATUS_PRIOR_CONFLICT, record["said"])

    def turn_judged(self, res: EstimateResult) -> EstimateResult:
        """A raw record's failed separation whose heading test named nothing (:meth:`heading_judged`), with its first
        pass (linear about no correction, as a telemetry's fit) tested for a turn about the vertical against the
        tracking as a telemetry is (:func:`casep.workflows.telemetry_heading.telemetry_heading_record`: the
        telemetry's heading or the tracking's azimuth, the rows and S_V turned back, whichever the likelihood
        prefers); a turn named fails `res` first (status ``STATUS_PRIOR_CONFLICT``, the record in
        ``diagnostics["heading"]["turn"]``). The heading's column does not hold a tracking turned in azimuth (its
        turn of the pad's inertial velocity, the Earth's rotation, is a constant the coefficients cannot take): with
        the tracking turned 10 deg the passes stepped out of the linear model and the result failed as errors too
        large for it (status -7), the heading read +4.7 +- 29 deg. Only the tracking's turn is named here: the
        telemetry's (the heading given) is the heading test's, and on the first pass the linear remainder of errors
        the passes would take out reads as one (the noise-free flight stopped at two passes: -2.83 +- 0.18 deg, z
        11.5). A success, a heading named, a telemetry's passes (tested on their linear fit before they iterate):
        `res` unchanged."""
        from casep.estimators.registry import STATUS_PRIOR_CONFLICT, failed
        from casep.estimators.spec import FitSpec
        from casep.exceptions import SetupWarning
        from casep.workflows.telemetry_heading import telemetry_heading_message, telemetry_heading_record

        test = (res.diagnostics.get("heading") or {}).get("test") or {}
        if res.success or test.get("conflict") or self._first_pass is None or getattr(self, "imu", None) is None:
            return res
        first, problem, flight, _ = self._first_pass
        if problem.is_noise_free():
            return res
        # no term left out of the test's design: the pass's phi0 is the levelling's, a function of the accelerometer
        # terms (left out with it, the rows turned back misfit by 2.2 m/s)
        locating = _fast_spec(FitSpec.build())  # the passes' own far fit: OLS, white noise, no robust filter
        record = telemetry_heading_record(first, problem, flight, None, self.spec, locating)
        if record is None:
            return res
        record["heading_deg"], record["heading_axis"] = self.heading["heading_deg"], self.heading["heading_axis"]
        record["suggested_heading_deg"] = (None if record["turned"] != "telemetry" or record["heading_deg"] is None
                                           else record["heading_deg"] + record["turn_deg"])
        record["on_first_pass"] = True
        res.diagnostics["heading"] = {**(res.diagnostics.get("heading") or {}), "turn": record}
        if not record["conflict"] or record["turned"] != "tracking":
            return res  # the heading's own turn: its test (heading_judged), on the passes, not the first's remainder
        said = telemetry_heading_message(record, flight.source, imu=True)
        record["said"] = f"failed: {said}"
        warnings.warn(said, SetupWarning, stacklevel=4)
        return named_first(failed(res, STATUS_PRIOR_CONFLICT, record["said"]), record["said"], STATUS_PRIOR_CONFLICT,
                           "the turn named above (the heading, or the frames)")

    def with_clock(self, res: EstimateResult, problem: Any, flight: FlightData, D: np.ndarray) -> EstimateResult:
        """`res` with the test of the IMU clock's rate against the data (:func:`clock_check`) in
        ``diagnostics["clock_drift"]`` and, with a drift std (:attr:`clock_std`, ``--clock-drift-std``), the drift's
        uncertainty in its covariance and std (:func:`clock_carried`, :func:`with_drift`), the record and the rows'
        shift for the drift carried kept for :meth:`clock_judged` and the stated combinations
        (:meth:`drift_effect`). A drift not given is not known: a crystal's tens of ppm move every scale factor by
        as much, and a record that cannot tell them apart takes them in unseen; the drift is carried as the heading
        is, a consider parameter (the estimate the fit's, its std wider by the drift's effect). Not without a raw
        record (a telemetry's passes), on noise-free rows (no std to test against or widen) nor on a flight with a
        set-up problem (its rows are that mistake)."""
        from casep.checks.plausibility import setup_problems

        self._clock = None
        if getattr(self, "imu", None) is None or problem.y is None or problem.t is None or setup_problems(flight):
            return res
        rms = problem.ls_rms()
        if self.at_rounding(rms) or problem.is_noise_free(rms):
            return res
        per_ppm = self.clock_rows(D, problem.t)
        gaps = self._gaps[1] if self._gaps is not None and self._gaps[0] is problem else None
        record = clock_check(res, problem, flight, per_ppm, self.clock_ppm, self.levelling(),
                             self.tau_profile(problem),
                             consider_columns(self.heading_effect(problem), self.steps_effect(problem)), gaps)
        if record is None:
            return res
        column = None
        if self.clock_std > 0 and per_ppm is not None:
            record["carried"] = clock_carried(record, self.clock_std)
            column = per_ppm * record["carried"]["effective_std_ppm"]
            res = with_drift(res, problem, column, record["carried"])
        self._clock = (problem, record, column)
        res.diagnostics["clock_drift"] = record
        return res

    def drift_effect(self, problem: Any) -> np.ndarray | None:
        """The shift of `problem`'s rows (N, 3, m/s) for the IMU clock's drift carried (:meth:`with_clock`; None
        before it, for another problem, or no drift carried)."""
        return self._clock[2] if self._clock is not None and self._clock[0] is problem else None

    def clock_judged(self, res: EstimateResult, problem: Any, flight: FlightData, D: np.ndarray) -> EstimateResult:
        """`res` judged by the test of the IMU clock's rate (:meth:`with_clock`'s record,
        ``diagnostics["clock_drift"]``): a drift the data see beyond the one given (the clock-drift rule, or beyond
        :data:`CLOCK_HINT_Z` of its std), said (:class:`casep.exceptions.TrackingQualityWarning`,
        :func:`clock_message`) and failed (status ``STATUS_PRIOR_CONFLICT``: state it); else the drift carried in the
        std and how much it widens them, or a record that would not see a drift beyond
        :data:`casep.checks.tracking_quality.DRIFT_MIN_PPM`, said in a line of the result. `res` itself where
        :meth:`with_clock` made no test."""
        from casep.checks.tracking_quality import DRIFT_MIN_PPM
        from casep.estimators.registry import STATUS_PRIOR_CONFLICT, failed
        from casep.exceptions import TrackingQualityWarning

        if self._clock is None or self._clock[0] is not problem:
            return res
        record = self._clock[1]
        res.diagnostics["clock_drift"] = record
        said = clock_message(record)
        if record["determined"] or record["indicated"]:
            warnings.warn(f"{flight.source}: {said}", TrackingQualityWarning, stacklevel=4)
            return failed(res, STATUS_PRIOR_CONFLICT, f"failed: {said}")
        return _with_line(res, said) if record["unseen_ppm"] > DRIFT_MIN_PPM or record.get("carried") else res

    def clock_rows(self, D: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """The rows' derivative (N, 3, m/s per ppm) at `D` and the pass's epochs `t` along the IMU clock's drift
        (:meth:`rows_at_clock`, central differences of :data:`CLOCK_STEP_PPM`; one-sided from the rows at `D` at an
        epoch that one side's stretched record no longer reaches, at either end); None where a pass there cannot be
        navigated or an epoch is on neither side."""
        t = np.asarray(t, dtype=float)
        try:
            sides = [self.rows_at_clock(D, s) for s in (CLOCK_STEP_PPM, -CLOCK_STEP_PPM)]
        except ValueError:
            return None
        # an epoch that a telemetry sample tags moves with the stretch (a sample's own time, by ppm t at most): each
        # side's row of an epoch is its nearest within that (NaN where it has none)
        reach = CLOCK_STEP_PPM * 1e-6 * np.abs(t - self.clock_pivot()) + 1e-9
        if t.size > 1:
            reach = np.minimum(reach, 0.5 * float(np.min(np.diff(t))))
        on = []
        for t_s, y_s in sides:
            on.append(np.full((t.size, 3), np.nan))
            if t_s.size == 0:
                continue
            k = np.clip(np.searchsorted(t_s, t), 1, max(t_s.size - 1, 1)) if t_s.size > 1 else np.zeros(t.size, int)
            k = np.where(np.abs(t_s[k - 1] - t) < np.abs(t_s[k] - t), k - 1, k) if t_s.size > 1 else k
            hit = np.abs(t_s[k] - t) <= reach
            on[-1][hit] = y_s[k[hit]]
        out = (on[0] - on[1]) / (2 * CLOCK_STEP_PPM)
        edge = ~np.all(np.isfinite(out), axis=1)
        if edge.any():
            t_0, y_0 = self.rows_at_clock(D, 0.0)
            if t_0.shape != t.shape or not np.allclose(t_0, t, rtol=0, atol=1e-9):
                return None
            one = np.where(np.isfinite(on[0]), (on[0] - y_0) / CLOCK_STEP_PPM, (y_0 - on[1]) / CLOCK_STEP_PPM)
            out[edge] = one[edge]
        return out if np.all(np.isfinite(out)) else None

    def clock_pivot(self) -> float:
        """The IMU time (its tags at the tracking clock's rate, s) about which a drift beyond the one given stretches
        them (:meth:`rows_at_clock`): 0, where ``T - time_shift = t (1 + clock_drift 1e-6)`` ties the two clocks (a
        drift given is taken out about it: :func:`casep.navigation.imu.on_clock`), so that the pairing of a record
        whose clock drifts by ``d`` more is late by ``d t`` at IMU time ``t``; where the pairing measured the time
        offset on the data (``time_offset="auto"``) the launch time, near where that measurement ties them. A fitted
        time offset (``dt_trk``) takes in the difference. About the launch time alone, on a rail launch without
        ``dt_trk`` whose IMU clock tags 0 six seconds before lift-off, the test read a drift of 104 ppm as 185 +- 19
        and the rows moved under it twice as far as that derivative said (the offset of 6 s times the drift, 0.6 ms,
        is 0.04 m/s at 6 g). The rule: :func:`casep.io.pair.drift_pivot` (a fitted ``dt_trk`` takes the launch time
        too)."""
        from casep.io.pair import drift_pivot

        return drift_pivot(self.nav_site.t0, self.offset_measured or bool(self.fit_time_offset))

    def rows_at_clock(self, D: np.ndarray, ppm: float) -> tuple[np.ndarray, np.ndarray]:
        """The epochs and :meth:`rows` at `D` with the IMU's tags and the pad window stretched by a drift `ppm` more
        about :meth:`clock_pivot` (:func:`casep.navigation.imu.on_clock`), restored after."""
        from casep.navigation.imu import on_clock

        imu, window, t0 = self.imu, self.window, self.clock_pivot()
        try:
            self.imu = on_clock(imu, ppm, about=t0)
            self.window = tuple(t0 + (w - t0) * (1.0 + ppm * 1e-6) for w in window)
            return self.timed_rows(D)
        finally:
            self.imu, self.window = imu, window

    def with_heading_noise(self, res: EstimateResult, problem: Any, per_deg: np.ndarray,
                           D: np.ndarray | None = None) -> EstimateResult:
        """`res` whose noise model and sigma are those of the fit (as requested) of `problem`'s rows with the
        heading's error as one more coefficient (:func:`with_columns_noise`, the column `per_deg`,
        :meth:`heading_rows`; the spec's prior about `D`, where `problem` is linear): the noise the rows hold once a
        turn of the velocity is fitted too. The fit's own noise model was fitted to residuals that hold what its
        coefficients cannot fit of a wrong heading, and took it for tracking noise: on an aircraft whose turns
        determine the heading to 0.12-0.21 deg, a heading 2 deg off raised the std of its estimate to 0.37 deg."""
        return with_columns_noise(res, problem, per_deg, self.spec if D is None else self.spec.about(res.names, D),
                                  ["heading"])

    def heading_rows(self, D: np.ndarray) -> np.ndarray | None:
        """The rows' derivative (N, 3, m/s per deg) at `D` along the given heading (None: gyrocompassed, no alignment
        (a telemetry's passes), or a pass at the heading's steps cannot be navigated).

        On a rail launch the lateral terms cannot tell the heading from the coefficients: a heading error turns the
        thrust's velocity about the vertical, a lateral velocity error that the coefficients fit, and a heading taken
        as exact gives estimates off by many std with residuals as good as the right heading's. The heading is a
        consider parameter: not fitted, its uncertainty carried into the estimate's covariance through the same
        estimator as the record's noise (:func:`imu_noise_budget`, :func:`combination_imu_noise`: one more column of
        ``G``, this derivative times the heading's std: :meth:`heading_effect`), and tested against the data
        (:func:`heading_conflict`, at any std, 0 too). It is the derivative of a pass (the record corrected at `D`,
        aligned at the heading, navigated and paired: :meth:`rows`) along the heading, by central differences of
        :data:`HEADING_STEP_DEG`."""
        heading = getattr(self, "heading", None)  # a telemetry's passes (_TelemetryRun) have no pad alignment
        if heading is None or heading["heading_deg"] is None:
            return None
        h0 = heading["heading_deg"]
        try:
            ys = [self.rows_at_heading(D, h0 + s) for s in (HEADING_STEP_DEG, -HEADING_STEP_DEG)]
        except ValueError:  # the record does not invert there: no column (the std without it, no test)
            return None
        return (ys[0] - ys[1]) / (2 * HEADING_STEP_DEG)

    def rows_at_heading(self, D: np.ndarray, heading_deg: float) -> np.ndarray:
        """:meth:`rows` at `D` with the pad aligned at `heading_deg` instead of the given heading (restored after;
        ValueError where the record does not invert there)."""
        h0 = self.heading["heading_deg"]
        try:
            self.heading["heading_deg"] = heading_deg
            return self.rows(D)
        finally:
            self.heading["heading_deg"] = h0

    def steps_effect(self, problem: Any) -> np.ndarray | None:
        """:func:`step_rows` of `problem`'s pass (None before :meth:`finish` formed it, for another problem, or
        without steps)."""
        return self._steps[1] if self._steps is not None and self._steps[0] is problem else None

    def heading_effect(self, problem: Any) -> np.ndarray | None:
        """The shift of `problem`'s rows (N, 3, m/s) for one std of the given heading: :meth:`heading_rows` times
        :attr:`heading_std` (None before :meth:`finish` formed it, for another problem, or the heading exact)."""
        per_deg = self.heading_derivative(problem)
        return None if per_deg is None or not self.heading_std > 0 else per_deg * self.heading_std

    def heading_derivative(self, problem: Any) -> np.ndarray | None:
        """:meth:`heading_rows` of `problem`'s pass (None before :meth:`finish` formed it, or for another problem)."""
        return self._heading[1] if self._heading is not None and self._heading[0] is problem else None

    def tau_profile(self, problem: Any) -> tuple | None:
        """:func:`casep.noise.fit.tau_profile` of `problem`'s rows (the last pass's, formed once; the coefficients'
        and the stated combinations' std, one rule: :func:`tau_spread`). None when the request states the correlation
        time (:attr:`casep.estimators.spec.FitSpec.tau_given`): the std are conditioned on it, nothing averaged, and
        the data judge it beside the IMU's noise (:func:`casep.noise.known.stated_tau_check`, :func:`warn_tau_stated`);
        None without times or a finite Gauss-Markov fit."""
        from casep.noise.fit import tau_profile

        if self._tau_profile is not None and self._tau_profile[0] is problem:
            return self._tau_profile[1]
        out = None
        if problem.y is not None and problem.t is not None and self.spec.tau_given is None:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # the profile's fits: the chosen model's fit says what it finds
                    out = tau_profile(problem)
            except ValueError:  # no finite Gauss-Markov likelihood (noise-free rows)
                out = None
        self._tau_profile = (problem, out)
        return out

    def levelling(self) -> tuple | None:
        """The pad window and the alignment's derivative along its mean specific force (:meth:`levelling_jacobian`):
        the start tilt the accelerometer noise leaves (:func:`imu_noise_budget`'s `levelling`)."""
        return self.window, self.levelling_jacobian()

    def combinations_with_noise(self, combos: list[dict], res: EstimateResult, problem: Any, flight: FlightData,
                                scales: dict[str, float]) -> list[dict]:
        """The combinations the passes stepped along (``passes[-1]["determined"]``) with the record's own noise in
        their std, as :meth:`with_noise` puts it in the coefficients' (:func:`combination_imu_noise`, the given
        heading and the steps between samples with it; `res` the result with it, its noise account holding the
        tracking noise refitted beside it). Each keeps its std without it as ``std_tracking_noise_only``; unchanged
        when the flight does not hold the IMU's samples. The consider terms added on top (the clock drift, the
        richer model's terms, the steps where the IMU's noise is not carried):
        :func:`~casep.workflows.row_estimators.combinations_with_consider`, once the coefficients hold them all."""
        scale = _scale_of(scales, res.names)
        W = np.array([c["weights"] for c in combos], dtype=float)
        heading = self.heading_effect(problem)
        a = combination_estimators(W, scale, res, problem)  # once: their noise (combination_imu_noise's rule) and
        var = None if a is None else estimator_noise(  # the heading's shift
            a, res, problem, flight, self.levelling(), self.tau_profile(problem),
            consider_columns(heading, self.steps_effect(problem)))
        if var is None:
            return combos
        trk, imu = var
        trk = np.array([c["std"] ** 2 for c in combos]) if trk is None else trk
        out = [{**c, "std_tracking_noise_only": c["std"], "std": float(math.sqrt(a + b))}
               for c, a, b in zip(combos, trk, imu)]
        drift = self.drift_effect(problem)
        if drift is not None:
            assert a is not None  # var is not None
            out = [{**c, "drift_shift": float(h)} for c, h in zip(out, a @ drift.reshape(-1))]
        if heading is not None:
            assert a is not None  # var is not None
            shift = a @ heading.reshape(-1)
            out = [{**c, "heading_shift": float(h)} for c, h in zip(out, shift)]
            record = heading_record(self.heading["heading_deg"], self.heading_std, shift,
                                    np.array([c["std"] for c in out]), [_combination(list(res.names), w) for w in W])
            res.diagnostics["heading"] = {**res.diagnostics.get("heading", {}), "combinations": record}
        return out

    def gap_clause(self, sigma: float) -> str:
        """What a failed iteration says of the record's gaps (:func:`_gap_clause`)."""
        return _gap_clause(self.imu, sigma)

    def curvature(self, res: EstimateResult, problem: Any, D: np.ndarray, draws: int | None = None) -> EstimateResult:
        """`res` with the pipeline's curvature at one std of its estimate in its covariance (module notes).

        With ``C = L L^T`` the result's covariance and ``y(.)`` a pass's rows (the record corrected, navigated and
        paired: :meth:`rows`), each of ``K`` seeded draws ``a ~ N(0, I)`` gives the nonlinear remainder of the pass at
        ``D + L a`` about the linearisation ``D`` (where S_V is the pass's derivative:
        :func:`casep.model.strapdown.correction_errors`; the estimate ``D + x`` is within a tenth of a std of it once
        the passes converged) and the shift of the (OLS) estimate it makes::

            r(a) = y(D + L a) - (y(D) - S_V L a),        b(a) = S_V^+ r(a)

        The covariance gains their mean square, ``C + mean(b b^T)`` (the truth is such a draw away: the estimate is
        off by ``b`` beside the noise); above :data:`CURVATURE_TOL` std along the combination it moves most
        (``max eig C^-1 mean(b b^T)``) a :class:`~casep.exceptions.NonlinearityWarning` says so, with the shift of
        the mean ``mean(b)`` (the second order's bias, part of the mean square) beside it; above
        :data:`CURVATURE_RELIABLE` std the second order outgrows the first at one std, and the warning says the std
        are not reliable (the mean square at one std is then no bound on the error of an estimate whose truth is
        that many std away). Skipped (recorded)
        when the covariance is not finite (undetermined coefficients). `draws`: ``K`` (default
        :data:`CURVATURE_DRAWS` per combination drawn along). After steps left combinations out
        (:func:`determined_step`'s `limit`, :meth:`iterate`), the draws ``L a`` lose their part along those (in the
        declared magnitudes, as the steps did): one std there is outside the linear model by the passes' own test,
        and a draw there would only find the record not invertible; their covariance stays linear (``left_out``).
        """
        from casep.exceptions import NonlinearityWarning

        C = res.covariance
        names = list(res.names)
        if C is None or not np.all(np.isfinite(C)) or problem.y is None:
            res.diagnostics["curvature"] = {"checked": False, "why": "the covariance is not finite"}
            return res
        lam, V = np.linalg.eigh(C)
        lam = np.clip(lam, 0.0, None)
        L = V * np.sqrt(lam)
        left_out = []
        if np.isfinite(self.limit):  # only where the passes' steps were linear: no draw beyond (determined_step)
            scale = _scale_of(self.model_k.scales if self.model_k else {}, names)
            N = 0 if res.solution is None else np.asarray(res.solution.null_space).reshape(len(names), -1).shape[1]
            sig, q = _scaled_spectrum(C, scale, problem, float(res.sigma), N, res.diagnostics.get("noise"))
            left_out = [_combination(names, q[:, i]) for i in np.flatnonzero(sig > self.limit)]
            qb = q[:, sig > self.limit]
            L = scale[:, None] * (L / scale[:, None] - qb @ (qb.T @ (L / scale[:, None])))
        S = problem.sv()
        M = S.reshape(-1, len(names))
        y0 = problem.y
        K = CURVATURE_DRAWS * (len(names) - len(left_out)) if draws is None else int(draws)  # per direction drawn
        R = []
        for a in np.random.default_rng(0).standard_normal((K, len(names))):
            step = L @ a
            try:
                y = self.rows(D + step)
            except ValueError:  # the record does not invert there: the draw says nothing of the second order
                continue
            R.append((y - y0 + np.einsum("ijk,k->ij", S, step)).reshape(-1))
        if not R:
            res.diagnostics["curvature"] = {"checked": False, "why": "no draw could be navigated"}
            return res
        B = np.linalg.lstsq(M, np.array(R).T, rcond=None)[0]  # (n, K): the shift of each draw
        extra = B @ B.T / B.shape[1]
        shift = std_shift(C, extra)
        bias = std_shift(C, np.outer(B.mean(axis=1), B.mean(axis=1)))  # the mean shift (in extra), said apart
        cov = C + extra
        info = {"checked": True, "draws": len(R), "max_shift_std": shift, "mean_shift_std": bias, "tol": CURVATURE_TOL,
                "reliable_below": CURVATURE_RELIABLE, "left_out": left_out,
                "std_factor": {nm: float(v) for nm, v in zip(names, np.sqrt(np.diag(cov) / np.diag(C)))}}
        message = res.message
        if shift > CURVATURE_TOL:
            worst = names[int(np.argmax(np.diag(cov) / np.diag(C)))]
            said = (f"the navigation is curved at one std of the estimate: its second-order terms move the estimate "
                    f"along one combination of the coefficients by up to {shift:.3g} of that combination's std "
                    f"(RMS over {len(R)} draws, above {CURVATURE_TOL:g}; their mean {bias:.3g}); its mean square is "
                    f"added to the covariance (each coefficient's std up to "
                    f"{np.sqrt(np.max(np.diag(cov) / np.diag(C))):.3g} times its linear one, {worst})")
            if shift > CURVATURE_RELIABLE:
                said += (f"; above {CURVATURE_RELIABLE:g} the second-order term outgrows the first at one std, so the "
                         f"expansion is not the error's distribution and the std are not reliable: check them against "
                         f"a simulation of the flight")
            warnings.warn(said, NonlinearityWarning, stacklevel=4)
            message = f"{message}\n{said}"  # a line of its own (_with_line)
        diag = dict(res.diagnostics)
        diag["curvature"] = info
        return dataclasses.replace(res, covariance=cov, std=np.sqrt(np.diag(cov)), message=message, diagnostics=diag)

    def determined_curvature(self, combos: list[dict], problem: Any, flight: FlightData,
                             D: np.ndarray, length: bool = False) -> tuple[list[dict], str | None, dict]:
        """The combinations a flight with stretches of different tracking noise determines
        (:func:`casep.checks.tracking_quality.determined`, linearised about `D`) with the navigation's second order
        over what it does not determine in their std; what is said of it; the record.

        The passes step only along the determined combinations (:func:`determined_step`): the rest of the
        coefficients stays where the first pass put it, and the truth can be far from there (a MEMS gyro's bias of
        hundreds of deg/h turns the pad attitude by degrees). To second order that moves the determined combinations'
        estimates, which their linear std cannot say, and :meth:`curvature`'s draws at one std cannot reach: the
        rest has no std. With ``W`` (m x n) the combinations' weights (orthonormal rows; coefficients in declared
        magnitudes), ``Q`` an orthonormal basis of the rest, ``s`` their linear std, ``rho`` the plausible size
        of a combination the flight does not determine (:func:`casep.checks.tracking_quality.plausible_size`) and
        ``u`` the part of `D` along the rest (where the passes left it: the first pass steps along everything, its
        estimates mostly linearisation error, and that value is no evidence of the truth, which may be at the prior
        as well; the rest's covariance is ``rho^2 Q Q^T / k + u u^T``: on a MEMS rail launch the first pass put
        ``bg_x`` at -9380 deg/h, the truth -120, and drawn at ``rho`` alone the stated combinations were up to 16 std
        off), :data:`DETERMINED_DRAWS` seeded draws::

            delta = scale * (W^T (s * a) + rho Q b / sqrt(k) + g u),
            a ~ N(0, I_m),  b ~ N(0, I_(n-m)),  g ~ N(0, 1)
            u = Q Q^T (D / scale)
            r = y(D + delta) - (y(D) - S_V delta),         beta = W A^+ (r / sigma)

        With `length` (the iteration's rule, :meth:`left_out_curvature`: ``k = n - m``) the rest's part is ``rho``
        long (its mean square length ``rho^2``), not ``rho`` along each of its ``n - m`` directions: there the
        combinations stated are every one the record resolves below ``rho``, the largest estimate among them is the
        instrument's size the record shows (a unit combination of the coefficients: their vector is at least that
        long), and the rest is what the record cannot resolve at that size. Drawn at ``rho`` per direction the rest
        was ``sqrt(n - m)`` (4 to 5) times longer than the coefficients' vector, and the second order, quadratic in
        it, about 20 times the truth's own: on an outside 800 Hz MEMS rocket under ``strapdown33`` (errors of 10
        mg, 2000 ppm, 600 arcsec, 300 deg/h) the 13 stated combinations were 0.1 of their std RMS off the truth (a
        std of 0.24 against a linear 0.013), and on seed 1 of the 3 s MEMS boost of
        ``tests/workflows/test_imu_separate.py`` the shift was 40 times the remainder at the truth and the stated
        combinations 0.037 of their std RMS off (0.43 with the length). Without it (the stretches' rule, ``k = 1``)
        ``rho`` is each direction's size: the stretches state only what the record resolves below the declared
        magnitude, whose estimates need not show the instrument's size (the stretched MEMS flight of the tests: ``rho``
        78, the truth's rest 440 long; drawn as a length its stated combinations were up to 22 std off).

        They give the pass's nonlinear remainder ``r`` (:meth:`rows`) and the shift ``beta`` of the combinations'
        estimates it makes, weighted as :func:`~casep.checks.tracking_quality.determined` weights them (``sigma`` of
        :func:`~casep.checks.tracking_quality.stretch_sigma`, ``A = (S_V / sigma) scale``). Each variance gains
        ``mean(beta_i^2)`` (the std before it kept as ``std_linear``); a shift above the linear std is said
        (:class:`~casep.exceptions.NonlinearityWarning`). Whether a combination whose std grows is still determined is
        decided once its std carries every widening, the consider terms too
        (:func:`casep.checks.tracking_quality.determined_split`: the stretches' rule, the declared magnitude (1), in
        :func:`casep.workflows.judging.judge_tracking`; the iteration's, the plausible size ``rho``, in :meth:`finish`).
        The weighting ``sigma`` is 1 when no stretch has a scatter (noise-free tracking). The record holds ``shift_std``
        (each shift over its linear std) and ``checked`` (whether any draw could be navigated)."""
        from casep.checks.tracking_quality import combination_terms, plausible_size, stretch_sigma
        from casep.exceptions import NonlinearityWarning

        self.rest_shift = None
        names = list(problem.names)
        n, m = len(names), len(combos)
        scale = _scale_of(self.model_k.scales if self.model_k else {}, names)
        W = np.array([c["weights"] for c in combos])
        s = np.array([c["std"] for c in combos])
        Q = np.linalg.svd(W)[2][m:].T  # (n, n - m): the rest, orthonormal
        rho = plausible_size(combos)
        stretches = (flight.meta.get("tracking_screen") or {}).get("stretches") or []
        sig = stretch_sigma(problem, stretches, self.model_k.scales if self.model_k else {}) \
            if any(x[3] > 0 for x in stretches) else np.ones(problem.t.size)
        S = problem.sv()
        u = Q @ (Q.T @ (D / scale))  # where the passes left the rest, from the prior (declared magnitudes)
        k_rest = np.sqrt(max(n - m, 1)) if length else 1.0  # rho the rest's length, or each of its directions' size
        R = []
        rng, back = np.random.default_rng(0), np.random.default_rng(1)
        for _ in range(DETERMINED_DRAWS):
            a, b, g = rng.standard_normal(m), rng.standard_normal(n - m), back.standard_normal()
            delta = scale * (W.T @ (s * a) + rho / k_rest * (Q @ b) + g * u)  # the rest ~ N(0, rho^2 Q Q^T / k + u u^T)
            try:
                y = self.rows(D + delta)
            except ValueError:  # the record does not invert there
                continue
            R.append(((y - problem.y + np.einsum("ijk,k->ij", S, delta)) / sig[:, None]).reshape(-1))
        record: dict[str, Any] = {"draws": len(R), "asked": DETERMINED_DRAWS, "plausible_size": rho,
                                  "left_at": float(np.linalg.norm(u)), "checked": bool(R)}
        if not R:
            note = (f"the record does not invert with the undetermined coefficients at their plausible size ({rho:.3g} "
                    "declared magnitudes): the combinations' std are linear, their curvature not checked")
            warnings.warn(note, NonlinearityWarning, stacklevel=5)
            return combos, note, record
        A = (S / sig[:, None, None]).reshape(-1, n) * scale
        X = np.linalg.lstsq(A, np.array(R).T, rcond=1e-12)[0]  # (n, draws): each draw's shift, declared magnitudes
        beta = W @ X  # (m, draws)
        self.rest_shift = scale[:, None] * (X @ X.T / X.shape[1]) * scale  # mean(b b^T), natural units
        shift = np.sqrt(np.mean(beta**2, axis=1))
        out = [{**c, "std_linear": c["std"], "curvature_shift": float(b), "std": float(np.hypot(c["std"], b))}
               for c, b in zip(combos, shift)]
        for c in out:  # the terms that matter against the std it now has
            c["terms"], c["more"] = combination_terms(names, np.array(c["weights"]), c["std"], rho)
        record["shift_std"] = [float(v) for v in shift / s]
        if not np.any(shift > s):
            return out, None, record
        j = int(np.argmax(shift / s))
        note = (f"the navigation is not linear over what the flight does not determine: with those coefficients at "
                f"their plausible size ({rho:.3g} declared magnitudes, the largest determined combination's"
                + (f", or at the prior, {record['left_at']:.3g} from where the passes left them"
                   if record["left_at"] > rho else "") + f"; "
                f"{len(R)} draws) its second order moves {int(np.sum(shift > s))} of the {m} combinations by more "
                f"than their linear std (up to {shift[j] / s[j]:.3g} times, {shift[j]:.3g} against {s[j]:.2g} "
                f"declared magnitudes); their std include it, a second-order expansion that is not reliable this far "
                f"beyond its linear std: check them against a simulation of the flight")
        warnings.warn(note, NonlinearityWarning, stacklevel=5)
        return out, note, record

    def rows(self, D: np.ndarray) -> np.ndarray:
        """A pass's rows at `D` (the record corrected, navigated and paired, the first pass's screen kept), about the
        last navigation; the state of the last pass is left as it was."""
        return self.timed_rows(D)[1]

    def timed_rows(self, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rows` with their epochs first: ``(t, rows)``."""
        from casep.checks.tracking_quality import keep_screen

        state = (self.imu_k, self.q_aligned, self.C_tb)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                nav = self.navigate(D)
                flight = keep_screen(self.flight(nav, D, self.model_k), self.screen)
        finally:
            self.imu_k, self.q_aligned, self.C_tb = state
        _, y, t = flight.observed_rows(flight.t)
        return t, y


def _pad_noise(imu: ImuData, window: tuple) -> dict:
    """The IMU's white noise per sample on the pad `window` (:func:`casep.checks.tracking_quality.pad_white_std` of
    the raw samples there: the vehicle at rest, no trajectory in their differences), as the flight's
    ``meta[IMU_NOISE_PAD]``; empty when the window holds fewer than 20 samples (an Allan deviation needs them)."""
    from casep.checks.tracking_quality import pad_white_std

    pad = (imu.t >= window[0]) & (imu.t <= window[1])
    if int(pad.sum()) < 20:
        return {}
    s, e = pad_white_std(np.column_stack([imu.f[pad], imu.w[pad]]), float(np.median(np.diff(imu.t[pad]))))
    return {"std": s, "rel_error": e, "span": (float(window[0]), float(window[1]))}


def _imu_saturation(imu: ImuData) -> dict | None:
    """``meta["saturation"]`` of a flight navigated from `imu` (:func:`casep.checks.saturation.screen_saturation`'s
    record): None when the record did not clip, else where it did, as :func:`casep.navigation.imu.check_imu` found it
    (its SaturationWarning said so; the navigation marks the solution from there ``ins_valid = 0``)."""
    if imu.clipped is None or not np.any(imu.clipped):
        return None
    return {"from_s": float(imu.t[int(np.argmax(imu.clipped))]), "found": ["the IMU record (casep.navigation.imu)"]}


def std_shift(C: np.ndarray, extra: np.ndarray) -> float:
    """``sqrt(max eig C^+ extra)``: how far a second-order term of mean square `extra` (one shift ``b``: ``b b^T``)
    moves the estimate along the combination it moves most, in that combination's std (`C` the estimate's
    covariance; its null directions, eigenvalues below 1e-14 of the largest, left out)."""
    lam, V = np.linalg.eigh(C)
    keep = lam > lam.max() * 1e-14
    W = V[:, keep] / np.sqrt(lam[keep])
    return float(np.sqrt(max(np.linalg.eigvalsh(W.T @ extra @ W).max(), 0.0)))


def _add_setup_problem(flight: FlightData, why: str) -> None:
    """A set-up problem of `flight` (``meta["setup"]["problems"]``: the failure :func:`casep.workflows.judging.
    judge_setup` makes of it), beside any the pair found; the pair's record is copied, not changed."""
    setup = {**(flight.meta.get("setup") or {})}
    setup["problems"] = [*setup.get("problems", []), why]
    flight.meta["setup"] = setup


def _late_tags_clause(flight: FlightData) -> str:
    """What a failed iteration says of tracking time tags the pair found late by more than a sample period and
    left in place (:func:`casep.io.align.late_tags_clause`); else nothing."""
    from casep.io.align import late_tags_clause

    return late_tags_clause(flight.meta.get("time_alignment") if isinstance(flight.meta, dict) else None)


def _gap_clause(imu: ImuData, sigma: float) -> str:
    """What a failed iteration says of the IMU's gaps: the worst one, when what it leaves unknown is large against
    the tracking noise `sigma` (m/s); else nothing.

    A gap's bounds are those the navigation warned of (:func:`casep.navigation.imu.bridge_gaps`): the velocity
    across it (m/s) and the attitude (rad), the latter a velocity error growing by up to ``|f|max * attitude`` m/s
    per s after it. Large: either, over one second, above `sigma`. No model of constant coefficients fits across a
    jump of that size, so the passes cannot converge whatever the errors' size.
    """
    from casep.navigation.imu import bridge_gaps

    if not imu.gaps or not sigma > 0:
        return ""
    br = bridge_gaps(imu.t, imu.w, imu.f)
    growth = float(np.linalg.norm(imu.f, axis=1).max()) * br.attitude  # m/s per s after each gap
    worst = int(np.argmax(np.maximum(br.velocity, growth)))
    if max(br.velocity[worst], growth[worst]) <= sigma:
        return ""
    return (f"the IMU gap of {br.h[worst]:.3g} s after t = {imu.t[br.steps[worst]]:.10g} s leaves the velocity "
            f"known to {br.velocity[worst]:.3g} m/s and the attitude to {br.attitude[worst]:.3g} rad (a velocity error "
            f"growing by up to {growth[worst]:.3g} m/s per s), large against the tracking noise {sigma:.3g} m/s: "
            "the gap, not the errors' size, is the likelier cause")


def _at_rounding(D: np.ndarray, step: Step, scales: dict[str, float], names: Any) -> bool:
    """Whether a pass's correction is at the rounding level of the coefficients: noise-free data make every std
    rounding too, and the stop rule ``|d| < tol std`` can then never hold.

    In the declared magnitudes (``z = d / scale``, ``Z = (D + d) / scale``): ``max |z| <= NOISE_FREE max |Z|``
    (:func:`casep.regression.problem.is_rounding_level`, the project's one noise-free rule; False at ``Z = 0``).
    """
    from casep.regression.problem import is_rounding_level

    scale = _scale_of(scales, names)[:D.size]
    z, Z = step.d[:D.size] / scale, (D + step.d)[:D.size] / scale
    if not (np.all(np.isfinite(z)) and np.any(Z)):
        return False
    return is_rounding_level(float(np.abs(z).max()), float(np.abs(Z).max()))


def _stopped(record: dict, tol: float) -> bool:
    """The stop rule on a pass's record: every correction below `tol` std, or at the rounding level
    (:func:`_at_rounding`)."""
    return bool(record["max_z"] < tol or record.get("rounding"))


def _secant_step(D: np.ndarray, d: np.ndarray, whiten: np.ndarray | None, last: tuple | None) -> np.ndarray:
    """The step from `D` after a pass that found the correction `d`: `d` itself, or with the pass before (`last`,
    its ``(D, d)``) the Anderson (secant) step of depth one, on the corrections of the determined combinations in
    their std (`whiten`, :attr:`Step.metric`: ``f = W d``).

    The passes are the fixed-point map ``G(D) = D + d(D)``. Near its fixed point the map is linear, and with
    noise its contraction along a poorly determined direction can be close to 1 or to -1 (the residual's
    curvature, not the Jacobian, sets it: Gauss-Newton on a non-zero residual). With ``f = W d``,
    ``f_last = W d_last`` and ``df = f - f_last``::

        gamma = (f . df) / (df . df),      D_next = D + d - gamma ((D + d) - (D_last + d_last))

    the root of the secant through the last two passes along their difference (for a contraction ``rho``
    in one direction: the fixed point in one step, whatever ``rho``). The metric is the covariance's restricted to
    the combinations the pass steps along, the one the stop rule reads: a coefficient's own std is no metric when
    the model has exactly dependent columns (``strapdown33`` on a rail launch: every coefficient is in a dependent
    group, no std is finite, and with them as the metric ``df`` was 0 and no pass ever took the secant step; the
    shipped MEMS example then contracted by 0.64 a pass and did not converge in 20).
    """
    if last is None or whiten is None or whiten.size == 0:
        return d
    f, f_last = whiten @ d, whiten @ last[1]
    df = f - f_last
    den = float(df @ df)
    if not (np.isfinite(den) and den > 0):
        return d
    gamma = float(f @ df) / den
    return d - gamma * ((D + d) - (last[0] + last[1]))


def _fast_spec(spec: FitSpec) -> FitSpec | None:
    """The fit of the passes far from convergence: OLS under white noise, no robust filter (None when `spec` asks
    another method or de-noising: then every pass is fitted as asked)."""
    from casep.estimators.spec import FitSpec

    if spec.method != "ols" or spec.noise.denoise not in (None, "none") or spec.options:
        return None
    return FitSpec.build("ols", noise="white", robust="none", sigma=spec.sigma)


def _rows_reusable(spec: FitSpec) -> bool:
    """Whether a fit as `spec` asks solves the rows :func:`casep.estimators.solve.rows_for` prepares from its problem
    (not a method that fits its own noise model, nor de-noised rows)."""
    from casep.estimators.registry import METHODS

    return METHODS[spec.method].own_noise_model is None and spec.noise.denoise in (None, "none")


def _settings_on_coefficients(res: EstimateResult, D: np.ndarray) -> EstimateResult:
    """`res`, a fit of the correction from `D` (:meth:`casep.FitSpec.about`), with the prior and bounds it records
    (``settings``) back on the coefficients, as given."""
    from casep.estimators.bounded import shift_bounds
    from casep.estimators.map import shift_prior

    back = {n: -float(d) for n, d in zip(res.names, D) if np.isfinite(d) and d != 0.0}
    moved = {k: f(res.settings[k], back) for k, f in (("prior", shift_prior), ("bounds", shift_bounds))
             if isinstance(res.settings.get(k), Mapping)}
    return dataclasses.replace(res, settings={**res.settings, **moved}) if back and moved else res


def _pass_record(k: int, res: EstimateResult, step: Step, total: np.ndarray, how: str, rounding: bool = False) -> dict:
    """One pass for ``diagnostics["iterations"]``: the largest correction of a determined combination in its std
    (`step`), whose, every coefficient's |correction| / std (None where the flight does not determine it), the
    combinations' (with the tracking's stretches), and the pass's estimate (`total`, natural units: the coefficients
    it was linearised about plus its whole linear solution, whatever its step was restricted to; the first pass's is
    the one linear pass's)."""
    std = res.std if res.std is not None else np.full(len(res.names), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(res.estimate) / std
    out = {"iteration": k, "fit": how, "max_z": step.max_z, "worst": step.worst, "rounding": rounding,
           "z": {nm: (float(v) if np.isfinite(v) else None) for nm, v in zip(res.names, z)},
           "estimate": {nm: (float(v) if np.isfinite(e) else None)
                        for nm, v, e in zip(res.names, total, res.estimate)}}
    if step.combinations is not None:
        out["combinations_z"] = [abs(c["correction"]) / c["std"] for c in step.combinations]
    return out


@dataclass
class Step:
    """A pass's correction along what the flight determines (:func:`determined_step`).

    Attributes
    ----------
    d : (n,) ndarray
        The correction, natural units, with no part along what the flight does not determine.
    max_z : float
        The largest correction of a determined combination, in its std (:func:`determined_step`).
    worst : str
        The coefficient (or combination) with the largest correction in its std.
    metric : (k, n) ndarray
        The secant step's metric (:func:`_secant_step`): ``W d`` the correction `d` (natural units) of each
        combination the step is along, in its std (``W = diag(1 / sigma_i) q_i^T / scale`` over the stepped
        combinations; with the tracking's stretches ``V_i / (std_i scale)``; without a covariance the coefficients'
        own std, where finite).
    combinations : list of dict or None
        With the tracking's stretches: :func:`casep.checks.tracking_quality.determined`'s combinations.
    widest : float
        The largest std (declared magnitudes) of a combination the correction is along (:func:`determined_step`).
    beyond : list of (std, z, str)
        The combinations left out by the step's `limit`: their std (declared magnitudes), correction in that std,
        name.
    kept : list of (std, weights)
        The combinations stepped along (when some were left out): their std and weights on ``D / scale``.
    limit : float
        The std (declared magnitudes) above which combinations were left out: the `limit` asked, or the plausible
        size of what the record determines when that is smaller (:func:`determined_step`).
    size : float
        That plausible size (:func:`_determined_size`; inf when the step did not judge it).
    noise_factor : float
        How many times too small the pass's white-noise std are under the record's correlated tracking noise
        (:func:`casep.estimators.solve.richer_noise_factor`; 1 when the pass was not white, or not judged).
    undetermined : (n, k) ndarray or None
        The combinations (orthonormal, on ``D / scale``) the record does not determine: std above the plausible size,
        or the fit's null space (:meth:`_Run.back_to_prior`).
    """

    d: np.ndarray
    max_z: float
    worst: str
    metric: np.ndarray
    combinations: list | None = None
    widest: float = np.inf
    beyond: list = field(default_factory=list)
    kept: list = field(default_factory=list)
    limit: float = np.inf
    size: float = np.inf
    undetermined: np.ndarray | None = None
    noise_factor: float = 1.0


def determined_step(res: EstimateResult, problem: Any, flight: FlightData, scales: dict[str, float],
                    limit: float = np.inf, about: np.ndarray | None = None, floor: float = 0.0) -> Step:
    """The correction of one pass along the combinations the flight determines, and its size in their std.

    Two cases, one per statement the result makes of what the flight determines:

    - the tracking noise differs between stretches (:func:`casep.checks.tracking_quality.noise_problem`):
      the result states the combinations ``c_i = V_i . (D / scale)`` whose std, weighted per stretch, is below
      their declared magnitude (:func:`casep.checks.tracking_quality.determined`); the correction is
      ``d = scale * sum_i V_i c_i`` over those (``V_i`` orthonormal: nothing along the others), and their
      estimates are uncorrelated, so ``max_z = sqrt(sum_i (c_i / std_i)^2)``;
    - otherwise the fit's own: ``x`` the solver's solution (:meth:`EstimateResult.fitted_coefficients`) with
      its part along the null space ``N`` of S_V removed in the declared magnitudes (``z = x / scale``
      projected off ``N / scale``: of the corrections that fit the data alike, the smallest against the
      declared magnitudes; every determined combination ``g . d = g . x``, since ``g N = 0``), and
      ``max_z`` the largest ``|P_j . d| / std(P_j . d)`` over the coefficients, ``P = I - N N^+`` (``P_j``: the
      part of coefficient j the flight determines; the coefficient itself where it is determined, so at full
      rank the largest ``|d_j| / std_j``; for two exactly dependent columns their sum).

    Not the largest over *every* determined combination (``sqrt(d^T C^+ d)``): on the MEMS flight of
    ``benchmarks/mc_imu_iterate.py`` that rule left 4 of 12 runs unconverged after 20 passes (the
    well-determined directions of an ill-conditioned fit contract slowly under a changing noise model),
    where the per-coefficient rule converges in 7 to 14.

    An undetermined coefficient's estimate is never read (it is NaN; 0 in its place would drop the
    determined combination it is part of).

    **The linear region** (`limit`, declared magnitudes; :meth:`_Run.iterate` sets it): with ``C_z = C / (scale
    scale^T)`` the covariance in the declared magnitudes, ``C_z = sum_i sigma_i^2 q_i q_i^T``, the Gauss-Newton
    correction is ``z = sum_i (q_i . z) q_i`` and each term is estimated to ``sigma_i``. The terms with
    ``sigma_i > limit`` are left out of the step as the null space is (``N`` widened by ``scale * q_i``): the
    truncated-SVD step, Levenberg-Marquardt's limit with the damping in the declared magnitudes::

        d = scale * sum_{sigma_i <= limit} (q_i . z) q_i

    and ``max_z`` is taken over what is left. ``limit = inf`` (the default) is the full Gauss-Newton step.

    **What the record determines** (`about`: the coefficients the pass was linearised about, natural units; the
    iteration's passes give it): the step is also limited to the combinations whose std is below the plausible size
    of the coefficients (:func:`_determined_size`), so that what the record does not determine stays where the prior
    puts it (0) and the passes linearise about a plausible point: on a pad record followed by a short boost under
    ``strapdown33`` the full step took a gyro scale factor to 2.7e3 declared magnitudes (std 7e3), and the
    combinations stated as determined, gradients about that point, were up to 59 of their std off the truth.
    The std compared with that size are the ones the stop rule reads and :func:`_outside_failure` judges a left-out
    correction by: the tracking's, the fit's own (``sig``). The record's IMU noise is the same in every pass (each
    navigates the same record again), so it does not blur where the passes' fixed point is; it enters which
    estimates count as evidence of the instrument's size (:func:`_determined_size`) and the std stated
    (:meth:`_Run.combinations_with_noise`). With it in the std that leave combinations out, a clipped-gyro telemetry
    (gyro noise measured on its own second differences, 3 times the noise written) had every combination left out,
    ``ba_x`` among them at 0.0087 declared magnitudes (1.03 with the IMU's noise, the size 1.0), and failed on it
    at 217 std of the tracking's. The passes far from convergence are white-noise least squares (:func:`_fast_spec`),
    whose std are too small under correlated tracking noise (Gauss-Markov plus white: 2.2 to 2.6 times on a 20 s, 5
    Hz rail launch, by the true covariance and a Monte Carlo of 300 draws); judged by them, noise looked significant
    (an estimate of 92 declared magnitudes at 10 of its white std, 3.8 of its true ones), the plausible size became
    92, the passes stepped along combinations of that std and linearised so far from the truth that the combinations
    stated were 14 to 50 std off (the shipped MEMS example of ``docs/guide/navigate.md``: up to 152). So in a
    white-noise pass the std that judge the size are multiplied by the Gauss-Markov plus white fit's factor
    (:func:`casep.estimators.solve.richer_noise_factor`, the whiteness test's measure).

    **The noise floor** (`floor`, m/s: :meth:`_Run.iterate` gives the rounding level of the first pass's rows,
    :func:`casep.regression.problem.rounding_level`): a fit's noise ``res.sigma`` below it is rounding, and every std
    here is taken at the floor instead (the covariance times ``(floor / sigma)^2``), so that no std, step or size is
    measured against rounding (the rule of :func:`casep.regression.problem.rounding_level`). A later pass's rows are
    residuals, whose own rounding is not the data's: on a noise-free pad record (rows of 0.13 m/s before the first
    pass) the passes' noise, fitted to residuals of 1e-15 to 1e-11 m/s, set the std of a combination whose effect at
    its declared magnitude is below the data's rounding (0.91 ``ba_y`` + 0.28 ``ba_z`` + 0.26 ``ma_yx``) to 6e-4 or
    1e-3 declared magnitudes by how the last digits of that fit rounded, and with it whether the passes stepped along
    it (and so whether they stated any combination as determined).
    """
    from casep.checks.tracking_quality import determined, noise_problem

    names = list(res.names)
    scale = _scale_of(scales, names)
    if noise_problem(flight) is not None and problem.y is not None and problem.t is not None:
        combos, _ = determined(problem, flight.meta["tracking_screen"]["stretches"], scales, imu=flight)
        if not combos:
            return Step(np.zeros(len(names)), 0.0, "(no combination determined)", np.zeros((0, len(names))), combos)
        V = np.array([c["weights"] for c in combos])
        c = np.array([c["correction"] for c in combos])
        s = np.array([c["std"] for c in combos])
        z = c / s
        return Step(scale * (V.T @ c), float(np.linalg.norm(z)), _combination(names, V.T @ (z / s)),
                    V / s[:, None] / scale, combos)
    x = res.fitted_coefficients()
    C = res.covariance if res.solution is None else res.solution.covariance
    std = res.std if res.std is not None else np.full(len(names), np.nan)
    sigma = float(res.sigma) if res.sigma is not None else np.nan
    if 0.0 < sigma < floor:  # rounding: the std at the data's rounding level (the noise floor above)
        lift = floor / sigma
        C, std, sigma = (None if C is None else C * lift**2), std * lift, floor
    P = np.eye(len(names))
    widest, beyond, kept, size, undetermined, factor = np.inf, [], [], np.inf, None, 1.0
    own = np.isfinite(std) & (std > 0)
    metric = np.eye(len(names))[own] / std[own, None]  # no covariance: the coefficients' own std, where finite
    N = np.zeros((len(names), 0)) if res.solution is None else \
        np.asarray(res.solution.null_space, dtype=float).reshape(len(names), -1)
    if C is not None and np.all(np.isfinite(C)) and np.all(np.isfinite(x)):
        sig, q = _scaled_spectrum(C, scale, problem, sigma, N.shape[1], res.diagnostics.get("noise"))
        out = sig > limit
        if about is not None:  # what the record determines (the size: the IMU's noise in the std that judge it)
            imu = combination_imu_noise(q.T, scale, res, problem, flight)
            eff = sig if imu is None else np.where(sig > 0, np.sqrt(sig**2 + imu[1]), 0.0)
            if (res.settings or {}).get("noise") == "white" and problem.t is not None:
                from casep.estimators.solve import richer_noise_factor

                factor = richer_noise_factor(res, problem)
                eff = eff * factor  # white std under correlated noise: too small
            est = q.T @ ((np.asarray(about, dtype=float) + x) / scale)
            size = _determined_size(eff, est, _linear_reach(q, scale, res.units))
            out, limit = out | (sig > size), min(limit, size)
        widest = float(sig[~out].max(initial=0.0))
        zq = q.T @ (x / scale) / np.where(sig > 0, sig, np.inf)  # each combination's correction in its std
        beyond = [(float(sig[i]), float(abs(zq[i])), _combination(names, q[:, i])) for i in np.flatnonzero(out)]
        kept = [(float(sig[i]), q[:, i]) for i in np.flatnonzero(~out & (sig > 0))] if beyond else []
        on = ~out & (sig > 0)  # stepped along: determined, not the null space (sig 0) nor left out
        undetermined = q[:, (sig > size) | (sig == 0)] if about is not None else None  # scaled, orthonormal
        x = scale * (q[:, on] @ (q[:, on].T @ (x / scale)))  # the part of the correction along them, nothing else
        metric = q[:, on].T / sig[on, None] / scale  # their corrections in their std (the secant step's metric)
        N = scale[:, None] * q[:, ~on]  # left out as the null space is
        C = _in_covariance(sig, q, scale, ~out)  # what is stepped along, without the rounding of what is not
        Qn, _ = np.linalg.qr(N)
        P = P - Qn @ Qn.T  # row j: the part of coefficient j the flight determines (P N = 0)
    elif res.solution is not None:
        Q, _ = np.linalg.qr(N / scale[:, None])
        x = scale * (x / scale - Q @ (Q.T @ (x / scale)))
        Qn, _ = np.linalg.qr(N)
        P = P - Qn @ Qn.T  # row j: the part of coefficient j the flight determines (P N = 0)
    if C is None or not np.all(np.isfinite(P @ C @ P.T)):  # own std
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.abs(x) / std
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.abs(P @ x) / np.sqrt(np.clip(np.einsum("ij,jk,ik->i", P, C, P), 0.0, None))
    zf = np.where(np.isfinite(z), z, 0.0)
    j = int(np.argmax(zf))
    return Step(x, float(zf[j]), _combination(names, scale * P[j]), metric, widest=widest, beyond=beyond, kept=kept,
                limit=float(limit), size=float(size), undetermined=undetermined, noise_factor=float(factor))


def _determined_size(sig: np.ndarray, estimate: np.ndarray, reach: np.ndarray | None = None) -> float:
    """The std (declared magnitudes) up to which a combination of the spectrum ``(sig, q)`` (:func:`_scaled_spectrum`)
    is determined, its estimates `estimate` (``q_i . (D / scale)``): the plausible size of the coefficients
    (:func:`casep.checks.tracking_quality.plausible_size`) from the combinations the record determines by themselves,
    a std below the declared magnitude (:func:`casep.checks.tracking_quality.determined`'s rule) or an estimate above
    :data:`SIGNIFICANT` of its std (not 0 whatever the prior: a MEMS unit under a navigation-grade model, whose gyro
    biases of hundreds of declared magnitudes are estimated to tens) whose std and estimate are below its linear
    limit (`reach`, declared magnitudes: :func:`_linear_reach`; None: not judged). A combination the data do not
    resolve at the scale of what a linear error model can describe (the coefficients the check against
    :data:`casep.units.LINEAR_LIMITS` tests as a family, ``casep.estimators._base``) is no evidence of the instrument's
    size, significant or not: a strapdown-boost record at 20 Hz under ``strapdown33`` estimated a combination of std
    4.5e9 declared magnitudes (scale factors of 1e12 ppm) at 5.6 of its std, set the size to 2.6e10 by it, and failed
    on another of std 1.9e9 at 7.8 as determined but not linear. Nor is an estimate beyond that limit, which no
    coefficient of a linear error model can have (the rule of :data:`casep.units.LINEAR_LIMITS`): on a MEMS rail
    launch under ``strapdown33`` (``benchmarks/mc_imu_iterate.py``, seed 3; the truth 448 declared magnitudes from
    the prior in all) a pass far from the truth estimated a combination of std 249 at -1085 (its limit 890, the truth
    +47: linearisation error, 4.3 of its std), the size became 1.6e3, the passes kept the first pass's values of 1.9e3
    along what they left out, and the curvature's draws at that size did not invert: the run failed. A combination
    whose std exceeds it says less of
    the instrument than its plausible size: the data do not determine it (that std is the tracking's:
    :func:`determined_step`). The fit's null space (``sig = 0``) is neither. `sig` must hold the IMU's noise
    (:func:`combination_imu_noise`): whether an estimate is evidence of the instrument's size is a question of its
    error, the record's noise included; with the tracking's alone, a gyro noisy enough to tilt a pad by more than its
    tracking holds made noise look significant, and the steps walked to 550 declared magnitudes."""
    from casep.checks.tracking_quality import plausible_size

    est = np.abs(np.asarray(estimate, dtype=float))
    resolved = np.ones(est.shape, dtype=bool) if reach is None else (sig < reach) & (est < reach)
    own = (sig > 0) & np.isfinite(sig) & np.isfinite(est) & ((sig < 1.0) | ((est > SIGNIFICANT * sig) & resolved))
    return plausible_size([{"estimate": float(v)} for v in est[own]])


def _linear_reach(q: np.ndarray, scale: np.ndarray, units: Any) -> np.ndarray:
    """Each combination's linear limit (declared magnitudes): the size ``c`` of ``q_i . (D / scale)`` at which a
    coefficient of ``D = scale q_i c`` reaches what a linear error model can describe
    (:data:`casep.units.LINEAR_LIMITS`, by the coefficients' `units`), ``min_j L_j / (|q_ji| scale_j si_j)``; inf for
    a combination of coefficients without a limit."""
    from casep.units import LINEAR_LIMITS, si_factor

    L = np.array([LINEAR_LIMITS[u] / si_factor(u) if u in LINEAR_LIMITS else np.inf for u in units], dtype=float)
    with np.errstate(divide="ignore"):
        return np.min((L / scale)[:, None] / np.abs(q), axis=0, initial=np.inf)


def _scaled_spectrum(C: np.ndarray, scale: np.ndarray, problem: Any = None, sigma: float = np.nan,
                     nulls: int = 0, noise: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(sigma, q)``: the std (declared magnitudes) and directions (columns) of the combinations ``q_i . (D /
    scale)`` whose estimates are uncorrelated: ``C / (scale scale^T) = sum_i sigma_i^2 q_i q_i^T``; the null space's
    (``sigma_i = 0`` from a pseudo-inverse covariance, `nulls` of them) included.

    A covariance holds its small eigenvalues only to its rounding, ``n eps lambda_max``: on a record that leaves
    combinations undetermined by 1e10 declared magnitudes (a pad at rest under ``strapdown33``) the best-determined
    combinations' variances, ~1e-20 of the largest, are rounding of either sign, read as 0 (a null direction) or as
    hundreds of declared magnitudes. When more than `nulls` eigenvalues are below :data:`_SPECTRUM_RTOL` of the
    largest, the spectrum is taken from the design instead (`problem`'s S_V in the declared magnitudes, whose SVD
    ``S diag(scale) / sigma = U diag(s) V^T`` resolves the largest ``s`` to rounding: ``sigma_i = 1 / s_i``,
    ``q_i = V_i``; `sigma` the fit's noise, m/s: the white-noise covariance of the least-squares fit, which the
    passes far from convergence are; the `nulls` smallest ``s_i``: the fit's null space, ``sigma_i = 0``), times
    ``sqrt(k)``, ``k >= 1`` the median over the combinations the covariance and the design both resolve of ``q_i^T C
    q_i / sigma_i^2`` (when there is none, the same median of the variances of the combinations' estimators under the
    fit's `noise` model, ``res.diagnostics["noise"]``: :func:`_whitened_ratio`; 1 without one): a fit under
    correlated noise (Gauss-Markov tracking) has std that many times the white ones, 1 for the white least-squares
    fit."""
    lam, q = np.linalg.eigh(C / np.outer(scale, scale))
    if problem is None or problem.y is None or not sigma > 0 or np.sum(lam < lam.max() * _SPECTRUM_RTOL) <= nulls:
        sig = np.sqrt(np.clip(lam, 0.0, None))
        sig[:nulls] = 0.0  # the fit's null space: its smallest (rounding of either sign)
        return sig, q
    S, y = problem.sv(), problem.y
    ok = np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(S), axis=(1, 2))
    _, s, Vt = np.linalg.svd(S[ok].reshape(-1, scale.size) * scale / sigma, full_matrices=False)
    sig = 1.0 / np.where(s > 0, s, np.nan)
    sig[s.size - nulls:] = 0.0  # the fit's null space: its smallest
    sig, q = np.nan_to_num(sig, nan=np.inf), Vt.T
    # the fit's noise model (correlated noise: std above the white ones), where the covariance resolves it and the
    # design does too (a combination the design holds within _SPECTRUM_RTOL of its best variance: beyond, the
    # covariance's value is its solver's rounding, 1e6-1e8 times the white one on a pad at rest). The covariance
    # resolves a quadratic form q^T C q above its rounding, n eps lambda_max, by _RESOLVED times: its value, not the
    # white one, is judged against it (a tactical aircraft flight, equilibrated condition 1e9: white std 1e-4 to 1e6
    # declared magnitudes, the largest eigenvalue 1.8e13; by the white std no combination was resolved by both, and
    # the Gauss-Markov plus white fit's std were taken as the white ones, 4 times too small)
    cq = np.einsum("ji,jk,ki->i", q, C / np.outer(scale, scale), q)
    seen = np.isfinite(sig) & (cq > _RESOLVED * scale.size * np.finfo(float).eps * lam.max()) \
        & (s**2 >= _SPECTRUM_RTOL * s.max() ** 2)
    ratio = cq[seen] / sig[seen] ** 2
    if not ratio.size and noise is not None:  # none above the covariance's rounding: the noise model's own estimators
        ratio = _whitened_ratio(sig, q, s, scale, problem, sigma, noise)
    return sig * math.sqrt(max(1.0, float(np.median(ratio)) if ratio.size else 1.0)), q


def _whitened_ratio(sig: np.ndarray, q: np.ndarray, s: np.ndarray, scale: np.ndarray, problem: Any, sigma: float,
                    noise: dict) -> np.ndarray:
    """``var_i / sigma_i^2`` of the combinations ``q_i`` of the design's spectrum (:func:`_scaled_spectrum`) it resolves
    (``s_i^2 >= _SPECTRUM_RTOL s_max^2``, finite ``sigma_i``, not the null space): ``var_i`` the variance of the
    combination's estimate under the fit's noise model `noise` (``res.diagnostics["noise"]``), from the estimators on
    the rows whitened by it (:func:`_estimators`' rule: the rows of ``q_i^T (W S diag(scale))^+``, their squared norm
    times the noise model's variance, `sigma` squared when it states none),
    not from the covariance: an estimator's variance is held to its own rounding, where ``q_i^T C q_i`` is held to the
    covariance's largest eigenvalue's (a 20 Hz rolling boost under ``strapdown33``, combinations undetermined by 1e12
    declared magnitudes: no Gauss-Markov variance was above that rounding, and the white std, 3 to 5 times too small,
    were taken). Empty when the noise model cannot whiten the rows (no times, no fitted noise)."""
    from casep.noise.model import NoiseModel, whiten

    if problem.t is None or not isinstance(noise, dict) or "axes" not in noise:
        return np.zeros(0)
    model = NoiseModel.from_dict(noise)
    if model.is_white:
        return np.zeros(0)  # the design's own std
    use = np.isfinite(sig) & (sig > 0) & (s**2 >= _SPECTRUM_RTOL * s.max() ** 2)
    if not use.any():
        return np.zeros(0)
    S, y = problem.sv(), problem.y
    ok = np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(S), axis=(1, 2))  # the rows the design path uses
    t = np.asarray(problem.t, dtype=float)[ok]
    U = whiten(S[ok], np.zeros((t.size, 3)), t, model)[0].reshape(3 * t.size, -1) * scale
    a = q[:, use].T @ np.linalg.pinv(U)  # the combinations' estimators on the rows whitened to the x axis's std
    std = model.sigma if model.sigma is not None and model.sigma > 0 else sigma  # the noise model's own, m/s
    return std**2 * np.sum(a**2, axis=1) / sig[use] ** 2


def _in_covariance(sig: np.ndarray, q: np.ndarray, scale: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The covariance (natural units) of the estimate's part along the combinations `keep` of the spectrum ``(sig,
    q)`` (:func:`_scaled_spectrum`): ``scale q_k diag(sig_k^2) q_k^T scale``, without the rounding the combinations
    left out would add (``sig`` up to 1e10 declared magnitudes: ``eps sig^2`` is larger than a kept one's variance)."""
    B = scale[:, None] * q[:, keep] * sig[keep]
    return B @ B.T


def prior_fits_p(ssr_kept: float, ssr_prior: float, dof: int, k: int, noise_factor: float = 1.0) -> float:
    """The p-value of the likelihood ratio's test that a record fits as well with `k` combinations at the prior as
    where the fit kept them (:meth:`_Run.back_to_prior`): the residuals' sums of squares after each fit
    (`ssr_kept`, `ssr_prior`, m^2/s^2), the kept fit's residual degrees of freedom `dof`, and `noise_factor`, how many
    times too small white-noise std are under the record's correlated noise
    (:func:`casep.estimators.solve.richer_noise_factor`)::

        s^2 = SSR_kept / dof
        chi^2 = max(SSR_prior - SSR_kept, 0) / (s^2 noise_factor^2)  ~  chi^2_k
        p = P(chi^2_k > chi^2)

    0 when that variance is 0 (a noise-free record: the fit kept is exact, the prior taken on no evidence)."""
    from casep._special import chi2_sf

    var = ssr_kept / max(dof, 1) * noise_factor**2
    return chi2_sf(k, max(ssr_prior - ssr_kept, 0.0) / var) if var > 0 else 0.0


def _outside_note(passes: list[dict], n: int, size: float = np.inf, smaller: str | None = None,
                  alone: int | None = None, names: Sequence[str] | None = None) -> str | None:
    """What an iteration says of the combinations its steps left out (:func:`determined_step`'s `limit`):
    none, or how many, their std and names, why (the last rejected step, or their std above the plausible size of
    what the record determines), and that their estimates are linear; when they are most of the combinations, or
    no coefficient is determined on its own (`alone`, how many are: 0), the smaller shipped models to try
    (`smaller`, :data:`SMALLER_MODELS`; None: not said). The counts add up to the `n` combinations: those the
    last pass states (``determined``), those its step left out at the prior (``left_out``), those it stepped along
    whose std with the record's noise, the curvature and the consider terms reach the plausible size (``widened_out``:
    :meth:`_Run.finish`, named by the coefficient `names`) and the fit's
    null space (the rest).
    None when one of them is determined (:func:`_outside_failure`: std within the plausible `size`, correction above
    :data:`SIGNIFICANT` std): that is a failure, not a note."""
    left = passes[-1].get("left_out") or []
    why = [r["why"] for p in passes for r in p.get("rejected", [])]
    if not left or any(c["z"] > SIGNIFICANT and c["std"] <= size for c in left):
        return None
    sd = sorted(c["std"] for c in left)
    near = [c["z"] for c in left if c["std"] <= size]
    names_left = "; ".join(c["combination"] for c in sorted(left, key=lambda c: c["std"])[:3])
    kept = len(passes[-1].get("determined") or [])
    # stepped along but not stated: their std with the record's noise, the curvature and the consider terms reach the
    # plausible size
    late = passes[-1].get("widened_out") or []
    null = max(n - kept - len(left) - len(late), 0)  # the rest of the n: the fit's null space
    why_smaller = "most of the combinations undetermined" if len(left) + len(late) > kept else \
        "no coefficient determined on its own" if alone == 0 else None
    rest = []
    if late:
        ls = sorted(late, key=lambda c: c["std"])
        rest.append(f"{len(late)} stepped along, whose std with the record's noise, the curvature and the consider "
                    "terms "
                    f"({ls[0]['std']:.3g}" + (f" to {ls[-1]['std']:.3g}" if len(ls) > 1 else "")
                    + " declared magnitudes: "
                    + "; ".join(_combination(list(names), np.array(c["weights"])) if names is not None and
                                "weights" in c else "combination " + " ".join(
                                    f"{v:+.2f} {k}" for k, v in (c.get("terms") or {}).items()).lstrip("+")
                                for c in ls[:3]) + f"{'; ...' if len(late) > 3 else ''}) reach the coefficients' "
                    f"plausible size ({size:.3g})")
    if null:
        rest.append(f"{null} in the fit's null space (no information at all)")
    other = f"the other {n - kept}: {', '.join(rest)}, and {len(left)}" if rest else f"the other {len(left)}"
    return (f"the record determines {kept} of {n} combinations of the coefficients well enough to iterate; "
            f"{other} (std {sd[0]:.3g} to {sd[-1]:.3g} declared magnitudes: {names_left}"
            f"{'; ...' if len(left) > 3 else ''}) are left at the prior (0)"
            + (f", a step along them leaves the linear model ({why[-1]})" if why else "") + ", and "
            + (f"their corrections are noise (at most {max(near):.2g} std) or " if near else "")
            + f"their std exceed the coefficients' plausible size ({size:.3g} declared magnitudes): the record does "
            "not determine them. Their estimates are the last linear pass's, their std linear (not checked for "
            "curvature)" + (f"; with {why_smaller}, a smaller model ({smaller}) leaves less undetermined"
                            if smaller and why_smaller else ""))


def _with_consider_stated(last: dict, res: EstimateResult, scales: dict[str, float], stated: bool) -> None:
    """The combinations the last pass stepped along (``last["determined"]``, updated in place) with every consider
    term `res`'s coefficients carry in their std (:func:`~casep.workflows.row_estimators.combinations_with_consider`:
    the richer model's terms, the IMU clock's drift, the steps where the IMU's noise is not carried), after the
    curvature of what the passes leave out (:meth:`_Run.left_out_curvature`), which is judged on their own std: the
    consider terms are parameters beside the rows, not a distance the record is navigated over. Where they are
    `stated` (an iteration's: :func:`_with_determined`) those still determined on that final std are kept
    (:func:`casep.checks.tracking_quality.determined_split`, within the plausible size of what the record determines,
    :func:`casep.checks.tracking_quality.plausible_size`), the others moved to ``last["widened_out"]`` (said by
    :func:`_outside_note`)."""
    from casep.checks.tracking_quality import determined_split, plausible_size

    last["determined"] = combinations_with_consider(last["determined"], res, scales)
    if stated:
        last["determined"], late = determined_split(last["determined"], plausible_size(last["determined"]))
        if late:
            last["widened_out"] = late


def _with_determined(res: EstimateResult, last: dict, scales: dict[str, float]) -> EstimateResult:
    """`res` with the combinations the iteration's last pass stepped along (``last["determined"]``, their std with
    the record's noise) in ``diagnostics["determined"]`` (``combinations`` with ``terms``, ``more``, ``weights``,
    ``estimate``, ``std``; the ``scales`` the weights divide by: :func:`judge_tracking`'s record) and its message
    stating them, value and std: what the flight determines when its steps left combinations out and the
    coefficients one by one are not determined."""
    from casep.checks.tracking_quality import combination_terms, plausible_size
    from casep.workflows.judging import untrusted

    names = list(res.names)
    combos = sorted(({**c} for c in last["determined"]), key=lambda c: c["std"])
    size = plausible_size(combos)
    for c in combos:
        c["terms"], c["more"] = combination_terms(names, np.array(c["weights"]), c["std"], size)
    distrust = untrusted(res)
    diag = {**res.diagnostics, "determined": {"combinations": combos, "std_factor": None, "from": "iterations",
                                              "untrusted": distrust,
                                              "scales": {nm: scales.get(nm, 1.0) for nm in names}}}
    said = "; ".join(" + ".join(f"{w:.2g} {nm}/{scales.get(nm, 1.0):g}" for nm, w in c["terms"].items())
                     + (f" (+ {c['more']} smaller terms)" if c.get("more") else "")
                     + f" = {c['estimate']:.4g} +- {c['std']:.2g}" for c in combos[:6])
    msg = (f"{res.message}\nthe iterated passes stepped along {len(combos)} combinations (coefficient / declared "
           f"magnitude) the flight determines: {said}" + ("; ..." if len(combos) > 6 else "")
           + " (all in diagnostics.determined)" + ("" if distrust is None else f"; {distrust}"))
    return dataclasses.replace(res, diagnostics=diag, message=msg)


def _with_line(res: EstimateResult, part: str) -> EstimateResult:
    """`res` with `part` on a line of its own after its message: a raw-IMU result's message is its status reason
    (and the advice, :func:`_advice_first`) on the first line, each finding of the passes (the combinations stated,
    those left out, the curvature) on a line below, not one paragraph of thousands of characters."""
    return dataclasses.replace(res, message=f"{res.message}\n{part}")


def _advice_first(res: EstimateResult, smaller: str | None) -> EstimateResult:
    """`res` with the smaller shipped models (`smaller`, :data:`SMALLER_MODELS`) named on its message's first line
    when a line below advises them (the reason there), so that the first line holds the status reason and the
    advice."""
    first, _, rest = res.message.partition("\n")
    if not smaller or "a smaller model" not in rest or "a smaller model" in first:
        return res
    return dataclasses.replace(res, message=f"{first}; try a smaller model ({smaller}): why below\n{rest}")


def _ssr(y: np.ndarray | None) -> float:
    """The sum of squares of a pass's rows (m^2/s^2; the finite ones)."""
    y = np.asarray(y, dtype=float)
    return float(np.sum(np.square(y[np.isfinite(y)])))


def _rms(y: np.ndarray | None) -> float:
    """The RMS of a pass's rows (m/s; the finite ones)."""
    y = np.asarray(y, dtype=float)
    y = y[np.isfinite(y)]
    return float(np.sqrt(np.mean(y * y))) if y.size else 0.0


def _heading_blame(test: dict) -> str:
    """What a failed step blames where the data contradict the heading given (:func:`heading_conflict`'s `test`,
    its conflict standing): the turn of the velocity that heading leaves, which the coefficients cannot take, before
    errors too large for the model (:data:`_BLAME`)."""
    return (f"the heading given is the likelier cause: the data put it {test['estimate_deg']:+.3g} deg off (said "
            "first), a turn of the velocity the coefficients cannot take; else the errors are too large for the model")


def _outside_failure(step: Step, rejected: list[dict], size: float = np.inf) -> str | None:
    """Why a converged iteration fails: a combination left out of the step (:func:`determined_step`'s `limit`,
    set by a rejected step: `rejected`) whose correction is above :data:`SIGNIFICANT` std. The record determines it,
    and the model is not linear over its size: the errors are too large (None when every one left out is below).
    One whose std exceeds the coefficients' plausible `size` (declared magnitudes: the one the step left
    combinations out by, :func:`_step_size`) is not determined whatever its correction (the rule of
    :func:`casep.checks.tracking_quality.determined`): on a pad at rest under ``strapdown33`` such combinations have
    std of 1e6 declared magnitudes, and their corrections in the white-noise std of the design
    (:func:`_scaled_spectrum`) say nothing of the instrument."""
    big = [(sd, z, nm) for sd, z, nm in step.beyond if z > SIGNIFICANT and sd <= size]
    if not big:
        return None
    sd, z, nm = max(big, key=lambda b: b[1])
    return (f"failed: the correction of {nm} is {z:.3g} of its std ({sd:.3g} declared magnitudes), but a step along "
            f"it leaves the linear model ({rejected[-1]['why'] if rejected else 'rejected'}): " + _BLAME)


def _scale_of(scales: dict[str, float], names: Any) -> np.ndarray:
    """The declared magnitudes (natural units) of the coefficients `names`, 1 for a name without one."""
    return np.array([scales.get(nm, 1.0) for nm in names], dtype=float)


def _beyond_plausible(step: Step, D: np.ndarray, scales: dict[str, float], names: Any) -> tuple[np.ndarray, int] | None:
    """The part of `D` (natural units) along the combinations `step` judged undetermined (``step.undetermined``)
    further from the prior than :data:`BACK_BEYOND` times their plausible size (``step.size``, declared magnitudes),
    and how many combinations that is; None when none is (:meth:`_Run.back_to_prior`)."""
    U = step.undetermined
    if U is None or not U.size or not np.isfinite(step.size):
        return None
    scale = _scale_of(scales, names)
    c = U.T @ (D / scale)
    far = np.abs(c) > BACK_BEYOND * step.size
    return (scale * (U[:, far] @ c[far]), int(far.sum())) if far.any() else None


def _plausible(D: np.ndarray, scales: dict[str, float], names: Any) -> float:
    """The size (declared magnitudes) a coefficient combination plausibly has, from the estimate `D` the passes
    stepped to (natural units; along the combinations they determine only):
    :func:`casep.checks.tracking_quality.plausible_size` of its coefficients."""
    from casep.checks.tracking_quality import plausible_size

    scale = _scale_of(scales, names)[:D.size]
    return plausible_size([{"estimate": float(v)} for v in D / scale if np.isfinite(v)])


def _step_size(step: Step, D: np.ndarray, scales: dict[str, float], names: Any) -> float:
    """The plausible size (declared magnitudes) a step's left-out combinations are judged by: the one
    :func:`determined_step` left them out by (``step.size``), else :func:`_plausible` of ``D + step.d``."""
    return float(step.size) if np.isfinite(step.size) else _plausible(D + step.d, scales, names)


def _combination(names: list[str], w: np.ndarray, top: int = 3) -> str:
    """A combination by its weights `w` on the coefficients divided by their declared magnitudes: the coefficient's
    name when it is nearly alone (95 % of the weight's norm), else its `top` largest terms."""
    w = np.asarray(w, dtype=float)
    norm = float(np.linalg.norm(w))
    if not norm > 0:
        return "(none)"
    w = w / norm
    j = np.argsort(-np.abs(w))[:top]
    if abs(w[j[0]]) >= 0.95:
        return names[j[0]]
    w = w if w[j[0]] > 0 else -w
    return "combination " + " ".join(f"{w[m]:+.2f} {names[m]}" for m in j).lstrip("+")


def _direct_velocity(model: ErrorModel, flight: FlightData, D: np.ndarray) -> np.ndarray:
    """The model's direct velocity error ``velocity_error(f, t, signals; D)`` (m/s) at every flight sample (N, 3)."""
    from casep.model.sv import evaluate_samples

    fn = model.functions["velocity_error"]
    n = flight.t.size
    values = {"f": flight.f.T, "t": (flight.t - flight.t[0])[None, :],
              "signals": np.array([flight.signals[c] for c in model.signals]).reshape(-1, n),
              "D": np.repeat(D[:, None], n, 1)}
    return evaluate_samples(fn, values, n)


def imu_noise_budget(res: EstimateResult, problem: Any, flight: FlightData, levelling: tuple | None = None,
                     profile: tuple | None = None, heading: np.ndarray | None = None,
                     estimators: np.ndarray | None = None,
                     measured: ImuNoise | None = None) -> tuple[np.ndarray | None, np.ndarray, dict] | None:
    """The estimate's covariance with the IMU's own white noise: ``(tracking part, IMU part, what was used)`` (None
    when the flight does not hold the IMU's samples, or the result has no covariance; the tracking part None: the
    fit's own covariance).

    The navigated velocity carries the IMU's white noise integrated: a velocity random walk (accelerometer) and
    an attitude random walk that ``f x phi`` turns into a velocity error growing with the specific force
    (gyro). Its densities are measured on the record (:func:`casep.checks.tracking_quality.imu_sample_noise`) and
    carried to the tracking epochs as ``dv = G xi`` (``Sigma_imu = G G^T``;
    :func:`casep.checks.tracking_quality.imu_noise_effect`; with `levelling`, the pad window and the alignment's
    derivative along the mean specific force (:meth:`_Run.levelling_jacobian`), the start tilt its accelerometer
    noise leaves too; with `heading`, the rows' shift for one std of the given heading (:meth:`_Run.heading_rows`),
    one more column of ``G``: a consider parameter, not a noise the tracking's refit sees). The rows' covariance is
    ``Sigma = Sigma_track(theta) + Sigma_imu``.

    The fit's noise model was fitted to residuals that hold the IMU's noise as well. Where it was fitted (REML),
    ``theta`` is fitted again by the restricted likelihood of the whole ``Sigma``, ``Sigma_imu`` known
    (:func:`casep.noise.known.fit_tracking`, its kinds per axis and a given tau kept; ``Sigma_imu`` as the linear
    state of :func:`casep.checks.tracking_quality.imu_noise_states`: never an N x N matrix). The estimate stays the
    fit's, linear in the raw rows, ``x = A dv`` with ``A = (U^T U)^+ (W^T U)^T``, ``U = W S`` whitened by the fit's
    noise model (:func:`casep.noise.model.whiten_transpose`), so its covariance is, exactly::

        Cov(x) = A Sigma_track(theta) A^T + (A G) (A G)^T

    (``Sigma_track A^T`` by :func:`casep.noise.known.tracking_covariance_times`). A noise model not fitted (white:
    the solver's sigma) keeps the fit's covariance as the tracking part. With `profile` (:meth:`_Run.tau_profile`)
    the tracking part gains what the uncertainty of the correlation times adds (:func:`tau_spread`, as the stated
    combinations' std do: :func:`combination_imu_noise`), and the account says over which correlation times, whether
    the record bounds them and by how much it raises the std (``tau_profile``: :func:`warn_tau_unbounded` says when
    the record does not bound them). A fit whose correlation times the request stated (its noise model's rule
    ``"given"``) is conditioned on them, no profile averaged over (:meth:`_Run.tau_profile`), and the data judge them
    beside the IMU's noise (:func:`casep.noise.known.stated_tau_check`): the account's ``tau_stated``
    (:func:`_tau_stated_record`, said by :func:`warn_tau_stated`). `estimators`: ``A`` when the caller formed it already
    (:func:`combination_estimators` of the identity on `res`); `measured`: the IMU's noise when the caller measured
    it already (:func:`casep.checks.tracking_quality.imu_noise_measured` of `flight` and the problem's times).
    """
    from casep.checks.tracking_quality import imu_noise_effect
    from casep.noise.model import NoiseModel

    nd = res.diagnostics.get("noise")
    if res.covariance is None or problem.t is None or not isinstance(nd, dict) or "axes" not in nd:
        return None
    t = np.asarray(problem.t, dtype=float)
    from casep.checks.tracking_quality import imu_noise_measured

    measured = imu_noise_measured(flight, t) if measured is None else measured
    if measured is None:
        return None
    noise = NoiseModel.from_dict(nd)
    N, n = t.size, len(res.names)
    A = estimators if estimators is not None else coefficient_estimators(res, problem)
    assert A is not None  # (n, 3N), the coefficients' estimators: times and a noise model checked above
    refit, stated = _tracking_beside_imu(problem, flight, noise, levelling, res.diagnostics)
    instability = _instability(refit, flight)
    AG = imu_noise_effect(flight, t, A, levelling, None if instability is None else instability[:3], measured.sample)
    if AG is None:
        return None
    AG = with_heading(AG, A, heading)
    C_imu = AG @ AG.T
    if refit is None:
        return None, C_imu, _imu_account(res, measured, np.asarray(res.covariance), C_imu, refit, flight)
    from casep.noise.known import tracking_covariance_times

    C_trk = A @ tracking_covariance_times(A.T.reshape(N, 3, n), t, refit).reshape(3 * N, n)
    if profile is None:
        account = _imu_account(res, measured, C_trk, C_imu, refit, flight)
        if stated is not None:  # a stated tau: conditioned on, judged beside the IMU's noise
            near = stated[2]
            C_near = None if near is None else \
                A @ tracking_covariance_times(A.T.reshape(N, 3, n), t, near).reshape(3 * N, n) + C_imu
            account["tau_stated"] = _tau_stated_record(res, stated, C_trk + C_imu, C_near)
        return C_trk, C_imu, account
    spread = tau_spread(A, problem, profile)
    account = _imu_account(res, measured, C_trk + spread, C_imu, refit, flight)
    account["tau_profile"] = _tau_record(res, t, profile, C_trk + C_imu, spread)
    return C_trk + spread, C_imu, account


def combination_imu_noise(W: np.ndarray, scale: np.ndarray, res: EstimateResult, problem: Any, flight: FlightData,
                          levelling: tuple | None = None, profile: tuple | None = None,
                          heading: np.ndarray | None = None) -> tuple[np.ndarray | None, np.ndarray] | None:
    """The variances of the combinations ``W (D / scale)`` (rows of `W`, declared magnitudes) under the noise of
    :func:`imu_noise_budget`: ``(tracking part, IMU part)``, each (m,); the tracking part None when `res` (the result
    :func:`with_imu_noise` made, or a pass's fit) holds no tracking noise refitted beside the IMU's (then the fit's own
    std stand). None when the flight does not hold the IMU's samples or `res` no noise model.

    The coefficients' budget forms ``A G (A G)^T`` whole, and on a pad at rest its entries along what the record does
    not determine (1e10 declared magnitudes and more) round away the variance of what it does; so each combination's
    estimator row is taken on its own: ``a = W P``, ``P`` the GLS estimator of ``D / scale`` (the pseudo-inverse of
    the whitened design in the declared magnitudes, carried to the raw rows by
    :func:`casep.noise.model.whiten_transpose`, as :func:`imu_noise_budget` does), its IMU variance ``||a G||^2``
    (:func:`casep.checks.tracking_quality.imu_noise_effect`, with `levelling`) and its tracking variance ``a
    Sigma_track a^T`` (:func:`casep.noise.known.tracking_covariance_times`). With `profile` (:meth:`_Run.tau_profile`)
    the tracking part gains what the uncertainty of the tracking noise's correlation times adds (:func:`tau_spread`);
    with `heading` (:meth:`_Run.heading_rows`) the IMU part gains the given heading's (:func:`with_heading`)."""
    a = combination_estimators(W, scale, res, problem)
    return None if a is None else estimator_noise(a, res, problem, flight, levelling, profile, heading)


def consider_columns(*columns: np.ndarray | None) -> np.ndarray | None:
    """The consider columns (N, 3, c) of the given heading (:meth:`_Run.heading_rows`, (N, 3)), of the record's
    steps between samples (:func:`step_rows`, (N, 3, S)) and of the IMU clock's drift (:meth:`_Run.drift_effect`,
    (N, 3)), each the rows' shift for one std; None without any."""
    cols = [np.asarray(c, dtype=float).reshape(c.shape[0], 3, -1) for c in columns if c is not None]
    return np.concatenate(cols, axis=2) if cols else None


#: The steps between samples carried as consider columns, at most (the largest effects; :func:`step_rows`).
MAX_STEP_COLUMNS = 100


def _event_shift_columns(nav: NavigationResult, t: np.ndarray, j: np.ndarray, u: np.ndarray,
                         psi: np.ndarray) -> np.ndarray:
    """The rows' shift (N, 3, S) at epochs `t` of S events, event ``s`` between the navigation's samples ``j_s`` and
    ``j_s + 1``, the velocity off by ``u_s`` and the attitude by ``psi_s`` (S, 3; launch frame) from the interval's
    middle on: ``dv(t) = u + psi x (F(t) - F_mid)``, ``F`` the specific force integrated in the launch frame (first
    order). The one form of :func:`step_rows` (steps between samples, gaps) and :func:`gap_rows` (the gaps' steps)."""
    from casep.rotations import quat_rotate

    F = cumulative_trapezoid(quat_rotate(nav.q, nav.fb), nav.t)
    Ft = np.column_stack([np.interp(t, nav.t, F[:, c]) for c in range(3)])
    after = t[:, None] >= (0.5 * (nav.t[j] + nav.t[j + 1]))[None, :]  # (N, S)
    cols = (u[None, :, :] + np.cross(psi[None, :, :], Ft[:, None, :] - (0.5 * (F[j] + F[j + 1]))[None, :, :])) \
        * after[:, :, None]
    return np.transpose(cols, (0, 2, 1))


def step_rows(imu: ImuData | None, nav: NavigationResult, problem: Any) -> np.ndarray | None:
    """The shift of the rows (N, 3, S) at `problem`'s epochs for one std of each step between samples of `imu`
    (:func:`casep.navigation.imu.sample_steps`) the navigation `nav` integrates across; None without one.

    Where a step fell in its interval ``[t_k, t_k+1]`` is unknown: the integration's error over it is ``s (x_k+1 -
    x_k) h / 2`` with ``s`` uniform in [-1, 1] (std ``1/sqrt 3``), one ``s`` for the rate and the specific force (one
    event). In the launch frame (``C`` the attitude at ``t_k``) the velocity is off by ``u = C df h / 2`` from the
    interval's middle on, and the attitude by ``psi = C dw h / 2``, which turns the specific force integrated since,
    ``dv(t) = u + psi x int f dt`` (first order; ``f = C fb``). Each step is a consider parameter, as the given heading
    is (:func:`with_heading`): not fitted, its uncertainty in the covariance. At most :data:`MAX_STEP_COLUMNS` (the
    largest bounds of ``|dv|`` at the record's end).

    The record's gaps (:func:`casep.navigation.imu.bridge_gaps`, which the navigation integrates across) are such
    events too (:func:`_gap_events`): what each bridge leaves unknown of the velocity and attitude across it is carried
    the same way, never at the cap's mercy."""
    from casep.rotations import quat_to_dcm

    if imu is None or problem.t is None or nav.t.size < 2:
        return None
    st = imu.steps
    i0 = int(np.searchsorted(imu.t, nav.t[0]))
    events = []  # (interval k of the record, launch-frame velocity u (E, 3), attitude psi (E, 3)), one std each
    if st is not None and st.k.size:
        C = quat_to_dcm(nav.q[np.clip(st.k - i0, 0, nav.t.size - 1)])
        u = np.einsum("sij,sj->si", C, st.df) * (st.h / 2)[:, None] / math.sqrt(3.0)  # one std of the uniform s
        psi = np.einsum("sij,sj->si", C, st.dw) * (st.h / 2)[:, None] / math.sqrt(3.0)
        events.append((st.k, u, psi, False))
    gaps = _gap_events(imu, nav, i0)
    if gaps is not None:
        events.append((*gaps, True))
    if not events:
        return None
    t = np.asarray(problem.t, dtype=float)
    out = []
    for k, u, psi, whole in events:
        keep = (k >= i0) & (k < i0 + nav.t.size - 1)
        if nav.valid is not None:  # clipped from there on: those rows are left out
            keep &= np.concatenate([nav.valid, [False]])[np.clip(k - i0 + 1, 0, nav.t.size)]
        if not np.any(keep):
            continue
        cols = _event_shift_columns(nav, t, k[keep] - i0, u[keep], psi[keep])
        if not whole and cols.shape[2] > MAX_STEP_COLUMNS:
            cols = cols[:, :, np.argsort(-np.linalg.norm(cols[-1], axis=0))[:MAX_STEP_COLUMNS]]
        out.append(cols)
    return np.concatenate(out, axis=2) if out else None


def _gap_events(imu: ImuData, nav: NavigationResult, i0: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The consider events (:func:`step_rows`) of the record's gaps: ``(k, u, psi)``, the interval ``t[k] -> t[k+1]``
    of each gap repeated once per event, the launch-frame velocity (m/s) and attitude (rad) of one std of each; None
    without a gap. A gap's bridge (:func:`casep.navigation.imu.bridge_gaps`) leaves unknown its motion term (any path
    between the two sides: ``|x_b - x_a| h / 2``, the bound of a step between samples, carried as one: uniform,
    std ``1 / sqrt 3`` of it, along the difference of the samples either side, for the velocity and for the attitude
    alike) and its noise term (three times the std of the bridge's integral, summed over the axes: each launch axis
    an event of std ``term / (3 sqrt 3)``), the bounds ``casep navigate`` states. ``C`` is the attitude at the gap's
    start (first order: the direction of a term along the sides' difference turns with the body across the gap)."""
    from casep.navigation.imu import bridge_gaps
    from casep.rotations import quat_to_dcm

    if not imu.gaps or imu.kind != "rates":
        return None
    br = bridge_gaps(imu.t, imu.w, imu.f)
    if not br.steps.size:
        return None
    k = br.steps
    C = quat_to_dcm(nav.q[np.clip(k - i0, 0, nav.t.size - 1)])

    def along(x: np.ndarray, size: np.ndarray) -> np.ndarray:  # the motion term along the sides' difference
        d = x[k + 1] - x[k]
        n = np.linalg.norm(d, axis=1)
        unit = np.divide(d, n[:, None], out=np.zeros_like(d), where=n[:, None] > 0)
        return np.einsum("sij,sj->si", C, unit) * (size / math.sqrt(3.0))[:, None]

    zero = np.zeros((k.size, 3))
    ks, us, ps = [k, k], [along(imu.f, br.motion[:, 1]), zero], [zero, along(imu.w, br.motion[:, 0])]
    noise_v = (br.velocity - br.motion[:, 1]) / (3.0 * math.sqrt(3.0))
    noise_a = (br.attitude - br.motion[:, 0]) / (3.0 * math.sqrt(3.0))
    for a in range(3):
        e = np.zeros((k.size, 3))
        e[:, a] = 1.0
        ks += [k, k]
        us += [e * noise_v[:, None], zero]
        ps += [zero, e * noise_a[:, None]]
    return np.concatenate(ks), np.concatenate(us), np.concatenate(ps)


#: The IMU's gaps whose unknown steps the clock test estimates beside the drift, at most (the largest bounds of what
#: each bridge leaves unknown; :func:`gap_rows`): six columns each, three more per epoch inside one.
MAX_GAP_NUISANCE = 16


def gap_rows(imu: ImuData | None, nav: NavigationResult, problem: Any) -> tuple[np.ndarray, list] | None:
    """The rows' shift (N, 3, c) at `problem`'s epochs for a unit step across each of the G gaps in `imu`'s tags
    (:func:`casep.io.flight.gap_steps`) that the navigation `nav` integrates across, and the gaps' ``(t_a, t_b)`` (s);
    None without one.

    A gap's bridge (:func:`casep.navigation.imu.bridge_gaps`) guesses the rate and specific force over it: the
    velocity across it is off by an unknown ``u`` and the attitude by an unknown ``psi``, which turns the specific
    force integrated since (``dv(t) = u + psi x int f dt`` from the gap's middle on, first order; the same shift as a
    step between samples, :func:`step_rows`). Per gap, three columns of ``u`` (1 m/s along each launch axis) and
    three of ``psi`` (1 rad about each), and three more for each epoch inside it (the bridge's guessed path, there
    off by anything up to ``u``: such an epoch is left out): the clock test estimates them beside the drift
    (:func:`clock_check`), so a gap's guess is never read as a clock's rate. At most :data:`MAX_GAP_NUISANCE` gaps
    (the largest bounds of the bridge, velocity plus the attitude's turn of the specific force integrated to the
    record's end)."""
    from casep.io.flight import gap_steps
    from casep.navigation.imu import bridge_gaps
    from casep.rotations import quat_rotate

    if imu is None or problem.t is None or nav.t.size < 2:
        return None
    k = gap_steps(imu.t)
    if not k.size:
        return None
    i0 = int(np.searchsorted(imu.t, nav.t[0]))
    j = k - i0
    keep = (j >= 0) & (j < nav.t.size - 1)
    if nav.valid is not None:  # clipped from there on: those rows are left out
        keep &= np.concatenate([nav.valid, [False]])[np.clip(j + 1, 0, nav.t.size)]
    if not np.any(keep):
        return None
    t = np.asarray(problem.t, dtype=float)
    F = cumulative_trapezoid(quat_rotate(nav.q, nav.fb), nav.t)
    br = bridge_gaps(imu.t, imu.w, imu.f)
    j, bound = j[keep], br.velocity[keep] + br.attitude[keep] * np.linalg.norm(F[-1] - F[j[keep]], axis=1)
    j = np.sort(j[np.argsort(-bound)[:MAX_GAP_NUISANCE]])
    I3, Z3 = np.eye(3), np.zeros((3, 3))
    unit = _event_shift_columns(nav, t, np.repeat(j, 6), np.tile(np.vstack([I3, Z3]), (j.size, 1)),
                                np.tile(np.vstack([Z3, I3]), (j.size, 1)))  # per gap: u on each axis, psi about each
    cols = []
    for n, g in enumerate(j):
        cols += [unit[:, :, 6 * n + i] for i in range(6)]
        for e in np.flatnonzero((t > nav.t[g]) & (t < nav.t[g + 1])):  # an epoch inside: the guessed path itself
            cols += [np.eye(3)[i] * (np.arange(t.size) == e)[:, None] for i in range(3)]
    return np.stack(cols, axis=2), [(float(nav.t[g]), float(nav.t[g + 1])) for g in j]


def with_steps(out: EstimateResult, before: EstimateResult, problem: Any, imu: ImuData | None) -> EstimateResult:
    """`out` (its covariance holding the steps between samples and the gaps: :func:`step_rows`) with them said: in
    ``diagnostics["sampled_steps"]`` and ``diagnostics["imu_gaps"]`` and a line of its message each, with how much they
    raise the std (against `before`'s, the fit's)."""
    if imu is None or out.std is None or before.std is None:
        return out
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(out.std, float) / np.asarray(before.std, float)
    finite = np.isfinite(ratio)
    worst = int(np.argmax(np.where(finite, ratio, -np.inf))) if np.any(finite) else 0
    raised = (f" (they and the IMU noise raise them by up to {ratio[worst]:.3g} x, {out.names[worst]})"
              if np.any(finite) else "")
    st, diag = imu.steps, dict(out.diagnostics)
    if st is not None and st.k.size:
        big = int(np.argmax(st.velocity + st.attitude))
        record = {"count": int(st.k.size), "t_s": [float(imu.t[k]) for k in st.k], "velocity_bound_m_s":
                  [float(v) for v in st.velocity], "attitude_bound_rad": [float(v) for v in st.attitude],
                  "rule": "each a velocity and attitude step at its interval's middle, uniform within +-(x_k+1 - "
                          "x_k) h/2 (casep.workflows.imu_separate.step_rows), a consider parameter in the covariance"}
        out = _with_line(out, f"the record's {st.k.size} step(s) between consecutive IMU samples (the largest at t = "
                              f"{imu.t[st.k[big]]:.6g} s: velocity unknown within +-{st.velocity[big]:.3g} m/s, "
                              f"attitude within +-{st.attitude[big]:.3g} rad) are in the std as consider parameters"
                              + raised)
        if np.any(finite):
            record["std_factor_max"], record["std_factor_worst"] = float(ratio[worst]), out.names[worst]
        diag["sampled_steps"] = record
    if imu.gaps and imu.kind == "rates":
        from casep.navigation.imu import bridge_gaps

        br = bridge_gaps(imu.t, imu.w, imu.f)
        big = int(np.argmax(br.velocity))
        record = {"count": int(br.steps.size), "t_s": [float(imu.t[k]) for k in br.steps],
                  "length_s": [float(h) for h in br.h], "velocity_bound_m_s": [float(v) for v in br.velocity],
                  "attitude_bound_rad": [float(v) for v in br.attitude],
                  "rule": "each gap's bridge (casep.navigation.imu.bridge_gaps) leaves the velocity and attitude "
                          "across it unknown within its bounds: the motion term a step at the gap's middle, uniform "
                          "within +-(x_b - x_a) h/2, the noise term per launch axis of std bound / (3 sqrt 3) "
                          "(casep.workflows.imu_separate.step_rows), consider parameters in the covariance"}
        out = _with_line(out, f"the record's {br.steps.size} gap(s) (the largest velocity bound across the "
                              f"{br.h[big]:.3g} s after t = {imu.t[br.steps[big]]:.10g} s: velocity unknown within "
                              f"+-{br.velocity[big]:.3g} m/s, attitude within +-{br.attitude[big]:.3g} rad) are "
                              "integrated across as casep navigate does and in the std as consider parameters"
                              + raised)
        if np.any(finite):
            record["std_factor_max"], record["std_factor_worst"] = float(ratio[worst]), out.names[worst]
        diag["imu_gaps"] = record
    return dataclasses.replace(out, diagnostics=diag)


def heading_record(heading_deg: float, std_deg: float, shift: np.ndarray, std: np.ndarray, names: list[str]) -> dict:
    """``diagnostics["heading"]``: the given heading, its std, and how far one std of it moves the estimates
    (`shift`; `std` their std with the heading's term, `names` theirs): their largest shift per
    :data:`HEADING_STEP_DEG`, in their std without the heading's term (how much the result depends on the heading)."""
    without = np.sqrt(np.clip(np.asarray(std, dtype=float) ** 2 - shift**2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(shift) / without * HEADING_STEP_DEG / std_deg
    z = np.where(np.isfinite(z), z, 0.0)
    worst = int(np.argmax(z)) if z.size else 0
    return {"heading_deg": float(heading_deg), "std_deg": float(std_deg), "step_deg": HEADING_STEP_DEG,
            "max_shift_std_per_step": float(z.max(initial=0.0)), "worst": names[worst] if names else None,
            "rule": "a consider parameter: the rows' derivative along the heading (central differences of a pass "
                    "navigated at the heading plus and minus the step) times its std, through the estimator, in the "
                    "covariance and the stated combinations' std"}


def heading_conflict(res: EstimateResult, problem: Any, flight: FlightData, per_deg: np.ndarray | None,
                     heading_deg: float, std_deg: float, levelling: tuple | None = None,
                     profile: tuple | None = None) -> dict | None:
    """The data's own estimate of the given heading's error, and its test against the stated std: the record
    ``diagnostics["heading"]["test"]`` (None without the rows' derivative along the heading, `per_deg` (N, 3, m/s per
    deg: :meth:`_Run.heading_rows`), or without a noise model).

    The rows at the given heading ``H`` are, to first order, ``y = S x + d (H - H_true) + e`` (``d`` = `per_deg`):
    the heading's error is one more coefficient of the design, and its GLS estimate after projecting out ``S``
    (:func:`combination_estimators` with ``d`` as one more column, the fit's whitening) is ``c = a y``, deg, the
    heading given less the one the record points to. Its std is that of any linear estimator on the rows
    (:func:`estimator_noise`: the tracking noise refitted beside the IMU's, the uncertainty of its correlation times,
    the IMU's own noise; the fit's own ``sigma`` where the noise was not refitted), under `res`'s noise model, which
    whitens the rows: :meth:`_Run.with_heading_noise` gives the one fitted with the heading's column in the design
    (the rows' noise once a turn of the velocity is fitted too). Under the stated heading (its
    error ``N(0, std_deg^2)``) ``c`` is ``N(0, std_deg^2 + std_c^2)`` (the prior predictive, as
    :func:`casep.estimators.rls.prior_conflict` tests RLS's prior), and beyond
    :data:`casep.estimators.rls.PRIOR_CONFLICT_Z` of that the data contradict the heading and its std (``conflict``):
    the rows the fit explains by its coefficients are a turned boost, and the estimate is off by what the heading's
    consider term does not cover."""
    from casep.estimators.rls import PRIOR_CONFLICT_Z

    est = column_estimates(res, problem, flight, per_deg, levelling, profile)
    if est is None:
        return None
    offset, std_c = float(est[0][0]), float(est[1][0])
    scale = math.hypot(std_deg, std_c)
    z = abs(offset) / scale if scale > 0 else (np.inf if offset else 0.0)
    return {"estimate_deg": offset, "std_deg": std_c, "heading_deg": float(heading_deg),
            "stated_std_deg": float(std_deg), "z": float(z), "limit_z": PRIOR_CONFLICT_Z,
            "suggested_heading_deg": float(heading_deg) - offset, "conflict": bool(z > PRIOR_CONFLICT_Z),
            "rule": "the heading's error as one more coefficient (the rows' derivative along it, the fit's "
                    "whitening, S_V projected out), its std under the rows' noise; z = |estimate| / sqrt(stated "
                    "std^2 + its std^2) (prior predictive) beyond limit_z: the data contradict the heading"}


def with_columns_noise(res: EstimateResult, problem: Any, columns: np.ndarray, spec: FitSpec,
                       names: list[str]) -> EstimateResult:
    """`res` whose noise model and sigma are those of the fit (`spec`) of `problem`'s rows with `columns` (N, 3) or
    (N, 3, k) as k more coefficients (`names`): the noise the rows hold once what the columns describe is fitted
    too, which :func:`column_estimates` whitens with (`res` itself where that fit has no noise model). A fit's own
    noise model was fitted to residuals that hold what its coefficients cannot fit, and takes it for tracking noise
    (:meth:`_Run.with_heading_noise`)."""
    from casep.regression.problem import Problem

    cols = np.asarray(columns, dtype=float).reshape(np.asarray(columns).shape[0], 3, -1)
    try:
        joint = _quiet_fit(Problem.from_arrays(np.concatenate([problem.sv(), cols], axis=2), problem.y, problem.t,
                                               names=[*res.names, *names]), spec)
    except (ValueError, np.linalg.LinAlgError):  # no fit of the augmented rows: the fit's own noise stands
        return res
    nd = joint.diagnostics.get("noise")
    if not isinstance(nd, dict) or "axes" not in nd or joint.sigma is None:
        return res
    noise = {k: v for k, v in nd.items() if k != "imu"}  # no refit beside the IMU's: its sigma, the IMU's added
    return dataclasses.replace(res, sigma=joint.sigma, diagnostics={**res.diagnostics, "noise": noise})


def clock_check(res: EstimateResult, problem: Any, flight: FlightData, per_ppm: np.ndarray | None,
                given_ppm: float, levelling: tuple | None = None, profile: tuple | None = None,
                consider: np.ndarray | None = None, gaps: tuple | None = None) -> dict | None:
    """The data's own estimate of the IMU clock's drift beyond the one given (`given_ppm`, taken out of the IMU's
    tags: :func:`casep.navigation.imu.on_clock`), the record ``diagnostics["clock_drift"]`` of a separation from raw
    IMU data (None without the rows' derivative along the drift, `per_ppm`: :meth:`_Run.clock_rows`).

    A clock running fast by ``d`` stretches every integration step: a common scale factor ``d`` on every gyro and
    accelerometer (gravity's integral too), and the states ``d t`` late against the tracking. The drift is one more
    coefficient of the design (:func:`column_estimates`), so the estimate is the drift *beside* the scale factors,
    not the tracking time offset's drift (:func:`casep.checks.tracking_quality.offset_halves`, whose model, a late
    tag ``dv = a eps t``, is not this one: on a boost at steady thrust the stretch and the tags' lateness cancel, and
    on a record whose IMU clock ran 104 ppm fast it said -47.8 +- 7.9 ppm). Beyond the clock-drift rule
    (:func:`casep.checks.tracking_quality.drift_determined`: the data see a drift, ``determined``); else the drift
    that may hide in the scale factors unseen, ``|estimate| + 2 std`` (``unseen_ppm``). Its std carry the `consider`
    columns (the given heading's, the steps between samples': where a thrust step fell in its interval moves the
    rows as a late tag does). The IMU's gaps (`gaps`, :func:`gap_rows`: their columns and times) are estimated beside
    it, a velocity and an attitude step across each: a bridge's guess shifts every row after it, and fitted by the
    drift alone a gap at burn-out read as thousands of ppm (``gaps`` in the record: their times).

    A drift the data point to beyond a flight computer's crystal (``implausible``: the total drift ``ppm`` beyond
    :data:`casep.estimators.rls.PRIOR_CONFLICT_Z` of ``sqrt(CLOCK_DRIFT_STD_PPM^2 + std^2)``, the prior predictive of
    the crystal's :data:`CLOCK_DRIFT_STD_PPM`, as :func:`heading_conflict` tests a heading) is no value to state:
    :func:`clock_message` names it implausible and the record's other causes (its gaps) instead."""
    from casep.checks.tracking_quality import drift_determined
    from casep.estimators.rls import PRIOR_CONFLICT_Z

    columns = per_ppm
    if per_ppm is not None and gaps is not None:
        columns = np.concatenate([np.asarray(per_ppm, dtype=float).reshape(-1, 3, 1), gaps[0]], axis=2)
    est = column_estimates(res, problem, flight, columns, levelling, profile, consider)
    if est is None:
        return None
    offset, std_c = float(est[0][0]), float(est[1][0])
    ppm = float(given_ppm) - offset
    crystal_z = abs(ppm) / math.hypot(CLOCK_DRIFT_STD_PPM, std_c)
    return {"ppm": ppm, "std_ppm": std_c, "given_ppm": float(given_ppm),
            "beyond_given_ppm": -offset, "determined": bool(drift_determined(offset, std_c)),
            "indicated": bool(abs(offset) > CLOCK_HINT_Z * std_c),
            "unseen_ppm": abs(offset) + 2.0 * std_c, "on": "the IMU clock's rate as one more coefficient (the rows' "
            "derivative along it, the fit's whitening, S_V projected out)"
            + (", a velocity and an attitude step across each of the IMU's gaps beside it" if gaps else ""),
            "gaps": [] if gaps is None else [list(g) for g in gaps[1]],
            "crystal_z": float(crystal_z), "implausible": bool(crystal_z > PRIOR_CONFLICT_Z),
            "crystal_rule": f"|ppm| / sqrt({CLOCK_DRIFT_STD_PPM:g}^2 + std_ppm^2) beyond {PRIOR_CONFLICT_Z:g}: "
                            "beyond a flight computer's crystal (its std, the +-100 ppm budget as two std)"}


def clock_carried(record: dict, std_ppm: float) -> dict:
    """How the IMU clock's drift beyond the one given, of std `std_ppm` (ppm), is carried in the std, given the data's
    own estimate of it (:func:`clock_check`'s `record`: ``c = beyond_given_ppm`` of std ``s = std_ppm``): the record
    ``diagnostics["clock_drift"]["carried"]`` (:func:`with_drift` adds how much it widens the std).

    The estimate is the fit's, which takes a drift ``d`` in: it is off by ``g d`` beside its noise (``g`` its shift
    per ppm, the rows' derivative along the drift through its estimator). With ``d ~ N(0, sigma^2)`` and ``c = d +
    N(0, s^2)``, the drift given ``c`` is ``N(m, v)``, ``m = sigma^2 c / (sigma^2 + s^2)``, ``v = sigma^2 s^2 /
    (sigma^2 + s^2)``, and the mean square of ``g d`` given ``c`` is ``g g^T (m^2 + v)``: the drift is a consider
    parameter of std ``sqrt(m^2 + v)`` (``effective_std_ppm``), as the heading is one of its stated std. Where the data
    do not see the drift (``s >> sigma``) that is ``sigma``; where they do, ``sqrt(c^2 + s^2)``: the drift they
    point to, not the prior's. The fit's noise error is taken as uncorrelated with ``c``'s (exactly so for the GLS
    estimator under the rows' noise model, whose error is uncorrelated with any contrast of the rows): the std are
    then those of the fit's estimate over the drifts and noises that give ``c``, whatever the test later does with
    ``c``."""
    sigma, c, s = float(std_ppm), float(record["beyond_given_ppm"]), float(record["std_ppm"])
    total = sigma**2 + s**2
    m, v = (sigma**2 * c / total, sigma**2 * s**2 / total) if total > 0 else (0.0, 0.0)
    return {"std_ppm": sigma, "effective_std_ppm": math.sqrt(m**2 + v), "mean_ppm": m, "posterior_std_ppm":
            math.sqrt(v), "given": bool(record["given_ppm"]),
            "rule": "a consider parameter: the rows' derivative along the IMU clock's drift times the drift's root "
                    "mean square given the data's own estimate of it (prior N(0, std_ppm^2)), through the estimator, "
                    "in the covariance and the stated combinations' std; the estimate is the fit's"}


def with_drift(res: EstimateResult, problem: Any, column: np.ndarray, carried: dict) -> EstimateResult:
    """`res` whose covariance (and its solution's) gains the IMU clock drift's consider column `column` (N, 3: the
    rows' shift for its effective std, :func:`clock_carried`) through the coefficients' estimators
    (:func:`combination_estimators`, as :func:`with_heading` carries the heading), `carried` (updated) saying how
    much it widens which std (``std_factor``, ``widened``: the largest factors first)."""
    if res.covariance is None:
        return res
    g = consider_estimators(res, problem) @ np.asarray(column, dtype=float).reshape(-1)
    out = with_extra_covariance(res, np.outer(g, g))
    std = out.std
    if std is not None and res.std is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.asarray(std, float) / np.asarray(res.std, float)
        factors = {nm: float(r) for nm, r in zip(res.names, ratio) if np.isfinite(r)}
        carried["std_factor"] = factors
        carried["widened"] = sorted(factors, key=lambda k: -factors[k])[:3]
    carried["shift_per_std"] = {nm: float(v) for nm, v in zip(res.names, g)}
    return out


def carried_said(carried: dict, clock: str = "an IMU clock drift") -> str:
    """What a result says of the IMU clock drift carried in its std (:func:`clock_carried`'s record; `clock` whose:
    a strapdown telemetry's INS clock, :mod:`casep.workflows.telemetry_clock`)."""
    of = "beyond the one given" if carried["given"] else "not given"
    line = (f"{clock} {of} is in the std as a consider parameter of std {carried['std_ppm']:.3g} ppm "
            f"(--clock-drift-std), {carried['effective_std_ppm']:.3g} ppm after the data's own estimate of it")
    factors = carried.get("std_factor") or {}
    worst = [k for k in carried.get("widened", []) if factors.get(k, 1.0) > 1.0 + 5e-4]
    if worst:
        line += ": it widens " + ", ".join(f"{k} {factors[k]:.3g} x" for k in worst)
        rest = sum(1 for v in factors.values() if v > 1.0 + 5e-4) - len(worst)
        line += f" (and {rest} more)" if rest > 0 else ""
    else:
        line += ": it widens none by 0.05 % or more"
    return line


def implausible_drift_said(record: dict, given: str) -> str:
    """What a result says of a drift :func:`clock_check` finds beyond a flight computer's crystal (``implausible``):
    not a value to state, and the other causes its record shows (the IMU's gaps, with their times)."""
    from casep.estimators.rls import PRIOR_CONFLICT_Z

    gaps = record.get("gaps") or []
    listed = ", ".join(f"{a:.6g} .. {b:.6g} s" for a, b in gaps[:8]) + (f" and {len(gaps) - 8} more"
                                                                          if len(gaps) > 8 else "")
    held = (f"the IMU's {len(gaps)} gap(s) (t = {listed}; their bridges guess the motion, a velocity and an attitude "
            "step across each estimated beside the drift, so what remains is not theirs alone)" if gaps
            else "no IMU gap (none in the record's span)")
    return (f"the rows do not fit at the IMU clock's rate: with {given}, a drift of "
            f"{record['beyond_given_ppm']:+.4g} +- {record['std_ppm']:.2g} ppm more would explain them (estimated "
            f"beside the coefficients), a total of {record['ppm']:+.4g} ppm, beyond what a flight computer's crystal "
            f"drifts (z {record['crystal_z']:.3g} above {PRIOR_CONFLICT_Z:g} against its {CLOCK_DRIFT_STD_PPM:g} ppm "
            f"std, the +-100 ppm budget as two std): implausible as a clock's drift, and no value to state. The record "
            f"holds {held}; other causes: a misfit of the model (a missing term, instrument errors too large for the "
            "linear model), wrong or lagged tracking epochs, time tags off. State a drift only as measured against a "
            "reference clock (--clock-drift PPM)")


def clock_message(record: dict) -> str:
    """What a result says of :func:`clock_check`'s `record`: a drift the data see beyond the one given (the failure),
    one they point to (beyond :data:`CLOCK_HINT_Z` std, a failure too), or how large a drift would hide in the scale
    factors unseen (a line of the result)."""
    from casep.checks.tracking_quality import DRIFT_MIN_PPM

    given = f"--clock-drift {record['given_ppm']:g} ppm" if record["given_ppm"] else "no clock drift given"
    effect = ("a clock running fast by d stretches every integration step (a common scale factor d on every gyro "
              "and accelerometer) and tags the states d t late against the tracking")
    carried = record.get("carried") or {}
    covered = bool(carried) and carried["effective_std_ppm"] >= abs(record["beyond_given_ppm"])
    carry = (f"their std carry it at {carried['effective_std_ppm']:.3g} ppm (--clock-drift-std "
             f"{carried['std_ppm']:g}), as wide as a drift unknown to that std makes them" if covered else "")
    if (record["determined"] or record["indicated"]) and record.get("implausible"):
        return implausible_drift_said(record, given)
    if record["determined"]:
        return (f"the IMU clock's rate does not match the tracking's: with {given}, the rows hold a drift of "
                f"{record['beyond_given_ppm']:+.4g} +- {record['std_ppm']:.2g} ppm more, estimated beside the "
                f"coefficients ({effect}); the coefficients take it in, "
                + (f"and {carry}" if covered else "so the estimate is off by more than its std say")
                + f": state it (--clock-drift {record['ppm']:.4g}, manifest clock_drift_ppm)")
    if record["indicated"]:
        return (f"the rows point to an IMU clock drift of {record['beyond_given_ppm']:+.4g} +- "
                f"{record['std_ppm']:.2g} ppm more, with {given} (estimated beside the coefficients, more than "
                f"{CLOCK_HINT_Z:g} of its std from 0 but not beyond the clock-drift rule: {DRIFT_MIN_PPM:g} ppm and 4 "
                f"std): {effect}; the coefficients take it in, and "
                + (carry if covered else "their std do not cover it") + ". State the clock's drift "
                + f"(--clock-drift PPM, measured against a reference clock; these data point to {record['ppm']:.4g} +- "
                f"{record['std_ppm']:.2g}, not precise enough to state: a drift of up to "
                f"{record['unseen_ppm']:.3g} ppm would move every scale factor by as much)")
    head = (f"the record checks the IMU clock's rate only to {record['unseen_ppm']:.3g} ppm: with {given}, its own "
            f"estimate of a drift beyond it, with the coefficients free, is {record['beyond_given_ppm']:+.3g} +- "
            f"{record['std_ppm']:.2g} ppm, and a smaller one would be taken into the scale factors unseen ({effect})")
    if carried:
        return f"{head}; {carried_said(carried)}"
    return (f"{head}; the estimate and its std hold as far as the IMU clock runs at the tracking's rate (a drift known "
            "otherwise: --clock-drift PPM, and its std: --clock-drift-std PPM)")


def heading_message(record: dict, axis: str) -> str:
    """What a result says when the data contradict the given heading (:func:`heading_conflict`'s `record`); where the
    rows navigated at the heading it points to still hold a turn beyond :data:`HEADING_SETTLED_Z` of its std
    (``at_suggested_deg``, ``settled`` False), that the test is linear and that heading approximate."""
    h, c, sd, st = (record[k] for k in ("heading_deg", "estimate_deg", "std_deg", "stated_std_deg"))
    hs = record["suggested_heading_deg"]
    head = (f"the data contradict the heading given: at --heading {h:g} deg (body axis {axis}, --heading-std "
            f"{st:g} deg) the rows hold a turn of the velocity that puts the heading {c:+.3g} +- {sd:.2g} deg "
            f"off (z = {record['z']:.3g} against the stated std and the estimate's, above {record['limit_z']:g}); "
            f"the coefficients absorb it, so the estimate is off by more than its std say. ")
    if record.get("settled", True):
        return head + (f"Check the heading (--heading {hs:.4g} is what the data point to) or state how well it is "
                       f"known (--heading-std {max(abs(c), sd):.2g} or more)")
    return head + (f"The test is linear in the heading's error and a turn this large is beyond its reach: navigated "
                   f"at the heading it points to, {hs:.4g} deg, the rows still hold {record['at_suggested_deg']:+.2g} "
                   f"deg, so that heading is approximate (separate again at it: the test there says what is left). "
                   "Check the heading given first: its body axis (--heading-axis) and its reference (true north, not "
                   f"magnetic or grid); or state how well it is known (--heading-std {max(abs(c), sd):.2g} or more)")


def unit_first(res: EstimateResult) -> EstimateResult:
    """`res` with the rates' unit its separation points to (``diagnostics["rate_unit"]``:
    :func:`casep.workflows.imu_units.rate_unit_reading`) named first, status ``STATUS_SETUP``, the other failures
    after it as what rates read in the wrong unit leave (a turn the heading's test reads, a misfit, estimates beyond
    the linear model); `res` unchanged without it."""
    from casep.estimators.registry import STATUS_SETUP

    unit = res.diagnostics.get("rate_unit") or {}
    said = f"failed: {unit['said']}" if unit.get("said") else None
    if said is None or said not in res.message:
        return res
    return named_first(res, said, STATUS_SETUP, "the unit named above")


def heading_said(record: dict | None) -> tuple[str, bool] | None:
    """The one rule of what a result says of the given heading when the data do not contradict it
    (:func:`heading_conflict`'s `record`), as ``(line, misfit)``, or None (no test, a conflict: said by the failure, the
    data's own std of the heading's error equal to the stated std, or below it but beyond the small-angle reach).

    Where the data know the heading less well than its stated std (their std above it), the line says how far the
    record checks it: on a rail launch the lateral terms fit a heading error as well as the heading
    (``docs/guide/navigate.md``: the MEMS example's record knows it to 44 deg): no test of the data can then see a
    wrong heading, and the result holds only as far as the heading is within its stated std. Where they know it
    better (their std below it), the line gives the data's own estimate of the heading's error and the heading they
    point to: the stated std is carried as a consider parameter, so the estimates' std are as wide as a heading
    known only that well makes them, and the rows keep the turn the data see. ``misfit`` is True where that turn is
    beyond :data:`casep.estimators.rls.PRIOR_CONFLICT_Z` of the data's own std (within the stated std: no conflict):
    the residuals hold it, and it is warned of (a heading 3 deg off given with --heading-std 5 read +2.91 +- 0.19
    deg and left a vertical residual of 0.093 m/s against 0.024 on the other axes, said nowhere)."""
    if record is None or record["conflict"]:
        return None
    c, sd, st = record["estimate_deg"], record["std_deg"], record["stated_std_deg"]
    given = f"the heading given (--heading {record['heading_deg']:g} deg)"
    own = (f"its own estimate of the heading's error, with the coefficients free, is {c:+.3g} +- {sd:.3g} deg")
    if sd > st:
        seen = record["limit_z"] * math.hypot(st, sd)
        if seen >= 180:
            head, unseen = f"the record does not check {given}", "no error of the heading would show in it"
        else:
            head, unseen = f"the record checks {given} only to {seen:.3g} deg", "a smaller error would not show in it"
        return (f"{head}: {own}, and {unseen} (z {record['limit_z']:g}); the estimate and its std hold as far as the "
                f"heading is within its stated std (--heading-std {st:g} deg)"), False
    if not sd < st or not record.get("judged", True):
        return None
    z = abs(c) / sd if sd > 0 else (math.inf if c else 0.0)
    misfit = bool(z > record["limit_z"])
    line = (f"the record determines {given} better than its stated std (--heading-std {st:g} deg): {own} "
            f"(z {z:.3g} against its own std, {record['z']:.2g} against the stated one and its own); the estimates' "
            f"std carry the stated {st:g} deg as a consider parameter")
    if misfit:
        line += (f", and the rows keep the turn the data see (beyond {record['limit_z']:g} of its std: the residuals "
                 "hold it)")
    return (line + f": --heading {record['suggested_heading_deg']:.4g} --heading-std {sd:.2g} is what the data point "
            "to (where nothing else turns the velocity: a frame, the tracking's axes)"), misfit


def given_heading_std(heading_deg: float | None, heading_std_deg: float | None,
                names: tuple[str, str] = ("`heading_deg`", "`heading_std_deg`")) -> float:
    """The given heading's std, deg (:data:`HEADING_STD_DEG` by default; 0 when gyrocompassed); the one rule of
    ``--heading-std`` (the command line checks it with this before any work, `names` its flags)."""
    heading, std = names
    if heading_std_deg is None:
        return HEADING_STD_DEG if heading_deg is not None else 0.0
    if not (math.isfinite(heading_std_deg) and heading_std_deg >= 0):
        raise ValueError(f"{std} must be a finite number >= 0 (deg), got {heading_std_deg!r}")
    if heading_deg is None:
        raise ValueError(f"{std} is the std of {heading}: give the heading (without it the pad alignment "
                         "gyrocompasses, and says how well it knows the heading)")
    return float(heading_std_deg)


def given_clock_std(clock_drift: float, clock_drift_std: float | None,
                    name: str = "`clock_drift_std`") -> float:
    """The std of the IMU clock's drift beyond the one given, ppm (:data:`CLOCK_DRIFT_STD_PPM` without a drift given,
    :data:`CLOCK_GIVEN_STD_PPM` with one); the one rule of ``--clock-drift-std`` (`name` its flag)."""
    if clock_drift_std is None:
        return CLOCK_GIVEN_STD_PPM if clock_drift else CLOCK_DRIFT_STD_PPM
    if not (math.isfinite(clock_drift_std) and clock_drift_std >= 0):
        raise ValueError(f"{name} must be a finite number >= 0 (ppm), got {clock_drift_std!r}")
    return float(clock_drift_std)


def _tau_record(res: EstimateResult, t: np.ndarray, profile: tuple, C: np.ndarray, spread: np.ndarray) -> dict:
    """What :func:`tau_spread` averaged the tracking noise over, for the noise account: per axis the correlation
    times kept (s) and whether the record bounds them (:func:`casep.noise.fit.tau_kept`), the record's length, and
    the largest factor the spread raises a coefficient's std by (over `C`, the covariance without it)."""
    from casep.noise.fit import tau_kept
    from casep.noise.model import AXES

    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt((np.diag(C) + np.diag(spread)) / np.diag(C))
    ok = np.isfinite(ratio) & np.isfinite(np.asarray(res.covariance).diagonal())
    worst = int(np.argmax(np.where(ok, ratio, -np.inf))) if ok.any() else 0
    return {"record_s": float(t[-1] - t[0]),
            "axes": {ax: {"kept_s": [lo, hi], "bounded": not top}
                     for ax, (lo, hi, top) in zip(AXES, tau_kept(t, profile))},
            "std_factor_max": float(ratio[worst]) if ok.any() else None, "std_factor_worst": res.names[worst],
            "rule": "per axis the tracking covariance averaged over tau's profile likelihood (its 95 % interval, "
                    "weighted by the restricted likelihood, uniform in ln tau up to the record length), less its value "
                    "at the fit, its part that adds variance (casep.workflows.row_estimators.tau_spread)"}


def _tau_stated_record(res: EstimateResult, stated: tuple, C: np.ndarray, C_near: np.ndarray | None) -> dict:
    """The data's judgement of the stated correlation times for the noise account (``tau_stated``): per axis
    :func:`casep.noise.known.stated_tau_check`'s record, and where some axis is outside its interval the largest
    factor by which the std at the stated tau (covariance `C`) fall short of those at the closest taus the data accept
    (`C_near`), over the coefficients with a finite std (1 where none falls short; None where every axis is within)."""
    from casep.noise.fit import PROFILE_LR
    from casep.noise.model import AXES

    free, axes, near = stated
    out = {"axes": dict(zip(AXES, axes)), "level": PROFILE_LR, "std_factor_max": None, "std_factor_worst": None,
           "tracking_noise_reml": free.to_dict(),
           "rule": "the std conditioned on the stated tau (no average over it); per axis the restricted likelihood "
                   "beside the IMU's noise with that axis's tau at the stated value (the others' at REML's, every "
                   "variance refitted) against the best, within the level: inside the profile's 95 % interval "
                   "(casep.noise.known.stated_tau_check); the factor: the std at the closest taus the data accept "
                   "(the nearer end of the interval) over those at the stated ones"}
    if C_near is None:
        return out
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt(np.diag(C_near) / np.diag(C))
    ok = np.isfinite(ratio) & np.isfinite(np.asarray(res.covariance).diagonal())
    worst = int(np.argmax(np.where(ok, ratio, -np.inf))) if ok.any() else 0
    out.update({"std_factor_max": max(float(ratio[worst]), 1.0) if ok.any() else None,
                "std_factor_worst": res.names[worst], "tracking_noise_accepted": near.to_dict()})
    return out


#: A stated correlation time outside its profile likelihood's 95 % interval (:func:`_tau_stated_record`) whose std
#: fall short of those at the closest tau the data accept by more than this fails the result (:func:`warn_tau_stated`).
#: At 1.5 a nominal 95 % interval (1.96 std) covers 1.31 true std: 81 %, one estimate in five outside it instead of one
#: in twenty.
TAU_STATED_FACTOR = 1.5


def warn_tau_stated(source: Any, record: dict) -> str | None:
    """A :class:`~casep.exceptions.NoiseLevelWarning` when the data put a stated correlation time outside its profile
    likelihood's 95 % interval on some axis (`record` the noise account's ``tau_stated``, :func:`_tau_stated_record`):
    per such axis the stated tau, the interval, REML's tau and the likelihood drop against its level, and by how much
    the std at the stated tau fall short of those at the closest taus the data accept (the nearer interval ends).
    Returns the failure's message when that factor is above :data:`TAU_STATED_FACTOR` (the caller fails the result,
    status ``STATUS_PRIOR_CONFLICT``: the data contradict the stated tau and the std it gives are too small), else
    None."""
    from casep.exceptions import NoiseLevelWarning

    def s(v: float | None, none: str) -> str:
        return none if v is None else f"{v:.3g} s"

    out = [(ax, v) for ax, v in record["axes"].items() if not v["within"]]
    if not out:
        return None
    factor = record["std_factor_max"]
    said = ("the data put the stated tracking-noise correlation time outside its profile likelihood's 95 % interval "
            "on axes " + ", ".join(
                f"{ax} (stated {v['tau_s']:.3g} s, interval "
                + ("unknown" if v["interval_s"] is None else
                   f"{s(v['interval_s'][0], '0 s')} to {s(v['interval_s'][1], 'the record length')}")
                + f", REML {s(v['reml_tau_s'], 'white')}; "
                f"-2 ln Lambda {v['drop']:.3g} > {record['level']:g})" for ax, v in out) + f" ({source})")
    short = factor is not None and factor > TAU_STATED_FACTOR
    tail = "" if factor is None else (f"; the std at the stated tau are {factor:.3g} x smaller than at the closest "
                                      f"tau the data accept ({record['std_factor_worst']})" if factor > 1.0 else
                                      "; the std at the stated tau are not smaller than at the closest tau the data "
                                      "accept")
    warnings.warn(NoiseLevelWarning(said + tail + (f", beyond {TAU_STATED_FACTOR:g} x" if short else "")
                                    + ". Leave tau out to fit it (REML, its uncertainty in the std), or check it"),
                  stacklevel=3)
    return f"failed: {said}{tail}: the std are too small" if short else None


def warn_tau_unbounded(source: Any, record: dict) -> None:
    """A :class:`~casep.exceptions.UndecidedNoiseWarning` when the record does not bound the tracking noise's
    correlation time on some axis (`record` the noise account's ``tau_profile``, :func:`_tau_record`): its numbers."""
    from casep.exceptions import UndecidedNoiseWarning
    from casep.noise.fit import PROFILE_LR

    loose = {ax: v["kept_s"] for ax, v in record["axes"].items() if not v["bounded"]}
    if not loose:
        return
    factor = record["std_factor_max"]
    warnings.warn(UndecidedNoiseWarning(
        "the record does not bound the tracking noise's correlation time on axes "
        + ", ".join(f"{ax} ({lo:.3g} to {hi:.3g} s)" for ax, (lo, hi) in loose.items())
        + f": its profile likelihood stays within {PROFILE_LR:g} of its best up to the record length "
        f"({record['record_s']:.3g} s, {source}). The std "
        "carry the tracking noise averaged over tau up to the record length, no further (beyond it the record cannot "
        "tell the noise from a drift its coefficients absorb)"
        + ("" if factor is None else f"; that raises them by up to {factor:.3g} x ({record['std_factor_worst']})")),
        stacklevel=3)


def _tracking_beside_imu(problem: Any, flight: FlightData, noise: Any, levelling: tuple | None,
                         diagnostics: dict | None = None) -> tuple[Any, Any]:
    """The tracking noise model fitted again by REML with the IMU's noise a known term
    (:func:`casep.noise.known.fit_tracking`); None when the fit's model has no fitted sigma (white noise). With it,
    where the fit's correlation times were stated (rule ``"given"``): the data's judgement of them beside the same
    known term (:func:`casep.noise.known.stated_tau_check`: the free fit and per axis the drop), else None.

    On the samples the fit kept (`diagnostics` its result's: :func:`casep.estimators.solve.kept_samples`), as the
    noise model it refits was fitted: a robust fit's glitches and the excluded outliers left out. With them in, the
    refit read the glitches as tracking noise (a navigated telemetry with 4 glitches of several m/s: x white noise
    0.29 m/s against the fit's 0.09, the std of a run without the robust fit).

    With the flight's ``meta[IMU_INSTABILITY_TAU]`` (:data:`casep.checks.tracking_quality.IMU_INSTABILITY_TAU`) the
    IMU's bias instability of that correlation time is a term of the known noise whose two variances (the
    accelerometers', the gyros') the same REML fits beside the tracking noise (:func:`_instability` reads them):
    started at the white noise's variance averaged over the correlation time, ``s^2 h / tau`` (the sensor's mean over
    its axes)."""
    from casep.checks.tracking_quality import IMU_REML_ROWS, IMU_WHITE_PARTS, imu_noise_states, imu_sample_noise
    from casep.estimators.solve import kept_samples
    from casep.noise.fit import Reml, estimable_basis
    from casep.noise.known import KnownStates, RemlRows, fit_tracking, stated_tau_check

    if noise.sigma is None or not np.isfinite(noise.sigma) or problem.y is None:
        return None, None
    keep = kept_samples(diagnostics or {}, problem.n_samples)
    rows = problem if keep.all() else problem.subset(keep)
    t = np.asarray(rows.t, dtype=float)
    tau = instability_tau(flight)
    given = instability_given(flight)
    known = imu_noise_states(flight, t, levelling, tau)
    if known is None:
        return None, None
    start: tuple = ()
    if tau is not None:
        measured = imu_sample_noise(flight, t)
        assert measured is not None  # the states above need the IMU's samples
        s, h, _ = measured
        start = tuple(max(float(np.mean(s[k:k + 3] ** 2)) * h / tau, 1e-30) for k in (0, 3))
    X = np.stack(Reml(rows, estimable_basis(rows)).Z, axis=1)  # (N, 3, p + 1): [Z dv] per axis
    kept = flight.meta.get(IMU_REML_ROWS) if isinstance(flight.meta, dict) else None
    if isinstance(kept, list):  # a size pooled over several records reads them (casep.noise.known.pool_parts)
        sensors = flight.meta.get(IMU_WHITE_PARTS)
        if sensors:  # the white noise's sizes too, from the density given (1); "gyro": the gyros' only
            pooled = imu_noise_states(flight, t, levelling, tau, white_parts=True)
            assert pooled is not None  # as `known`
            if sensors == "gyro":  # the accelerometers' part back in the known noise, at the density given
                (Q_a, P0_a), rest = pooled.parts[0], pooled.parts[1:]
                pooled = KnownStates(pooled.T, pooled.Q + Q_a, pooled.H, pooled.P0 + P0_a, rest)
            kept.append(RemlRows(X, t, noise, pooled, (1.0,) * (len(pooled.parts) - len(start)) + start))
        else:
            kept.append(RemlRows(X, t, noise, known, start))
    if given is not None:
        known, start = known.scaled(list(given)), ()
    refit = fit_tracking(X, t, noise, known, part_start=start)[0]
    if given is not None:
        refit.extra["known_scales"] = list(given)
        refit.extra["known_given"] = True
    if noise.rule != "given" or any(v is None for v in noise.tau) or not refit.extra.get("neg2_reml", np.nan) < np.inf:
        return refit, None
    return refit, stated_tau_check(X, t, refit, known, noise.tau, part_start=start)


def instability_given(flight: FlightData) -> tuple[float, float] | None:
    """The variances ``(q_a, q_g)`` of the IMU's bias instability given to the flight rather than fitted
    (``meta[IMU_INSTABILITY_SIZE]``, :data:`casep.checks.tracking_quality.IMU_INSTABILITY_SIZE`; a size pooled over a
    run's windows), None: fitted on the record (with :func:`instability_tau`). Two finite variances >= 0, and a
    correlation time asked for, else an error naming them."""
    from casep.checks.tracking_quality import IMU_INSTABILITY_SIZE

    q = flight.meta.get(IMU_INSTABILITY_SIZE) if isinstance(flight.meta, dict) else None
    if q is None:
        return None
    try:
        q_a, q_g = (float(v) for v in q)
    except (TypeError, ValueError):
        raise ValueError(f"the IMU's bias instability's given size needs two variances (q_a, q_g), got {q!r}") from None
    if not (math.isfinite(q_a) and math.isfinite(q_g) and q_a >= 0 and q_g >= 0):
        raise ValueError(f"the IMU's bias instability's given variances must be finite and >= 0, got {q!r}")
    if instability_tau(flight) is None:
        raise ValueError("the IMU's bias instability's size is given without its correlation time "
                         "(meta[IMU_INSTABILITY_TAU])")
    return q_a, q_g


def instability_tau(flight: FlightData) -> float | None:
    """The correlation time (s) of the IMU's bias instability the flight asks for
    (``meta[IMU_INSTABILITY_TAU]``, :data:`casep.checks.tracking_quality.IMU_INSTABILITY_TAU`), None: white IMU
    noise only; a value that is not a finite positive time is an error naming it."""
    from casep.checks.tracking_quality import IMU_INSTABILITY_TAU

    tau = flight.meta.get(IMU_INSTABILITY_TAU) if isinstance(flight.meta, dict) else None
    if tau is None:
        return None
    if not (isinstance(tau, (int, float)) and math.isfinite(tau) and tau > 0):
        raise ValueError(f"the IMU's bias instability needs a correlation time > 0 s, got {tau!r}")
    return float(tau)


def _instability(refit: Any, flight: FlightData) -> tuple[float, float, float, bool] | None:
    """``(tau, q_a, q_g, fitted)`` of the IMU's bias instability the flight asks for (:func:`instability_tau`): the
    variances the refit beside the IMU's noise fitted (:func:`_tracking_beside_imu`); None when not asked for, or
    when no refit was made (a white tracking noise model: nothing fitted them; the account says so)."""
    tau = instability_tau(flight)
    if tau is None or refit is None or "known_scales" not in refit.extra:
        return None
    q_a, q_g = refit.extra["known_scales"]
    return tau, float(q_a), float(q_g), not refit.extra.get("known_given", False)


def _instability_record(refit: Any, flight: FlightData) -> dict | None:
    """The noise account's ``instability``: the IMU's bias instability asked for (None when not), its correlation
    time and the fitted sizes in natural units (mg, deg/h; per body axis, the stationary std)."""
    from casep.units import G0

    tau = instability_tau(flight)
    if tau is None:
        return None
    got = _instability(refit, flight)
    out: dict = {"tau_s": tau, "variances": None if got is None else [got[1], got[2]],
                 "rule": "a first-order Gauss-Markov bias per body axis of the accelerometers and the gyros, "
                         "correlation time given, its two variances fitted by the restricted likelihood beside the "
                         "tracking noise (casep.checks.tracking_quality.imu_bias_effect)"}
    if got is None:
        out["note"] = "not fitted: the tracking noise model is white (the solver's sigma); the term is left out"
        return out
    if not got[3]:
        out["given"] = True
        out["rule"] = ("a first-order Gauss-Markov bias per body axis of the accelerometers and the gyros, correlation "
                       "time and variances given (meta[IMU_INSTABILITY_SIZE]: a size pooled over a run's windows), the "
                       "tracking noise refitted by the restricted likelihood beside it "
                       "(casep.checks.tracking_quality.imu_bias_effect)")
    out["accelerometer_mg"] = math.sqrt(got[1]) / G0 * 1e3
    out["gyro_deg_h"] = math.degrees(math.sqrt(got[2])) * 3600.0
    return out


def _imu_account(res: EstimateResult, measured: ImuNoise, C_trk: np.ndarray, C_imu: np.ndarray, refit: Any,
                 flight: FlightData | None = None) -> dict:
    """What :func:`imu_noise_budget` used and found, for the result's noise record (`measured`: the IMU's noise, where
    it was measured and its columns not measured said; `flight`: the record whose low-frequency IMU noise, when
    requested, is said)."""
    (s, h, _), at_rest, unresolved, on_pad, pad_span = measured
    C_fit = np.asarray(res.covariance)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt((np.diag(C_trk) + np.diag(C_imu)) / np.diag(C_fit))
    finite = ratio[np.isfinite(ratio)]
    worst = int(np.nanargmax(np.where(np.isfinite(ratio), ratio, -np.inf))) if finite.size else 0
    how = ("the tracking noise model fitted again by REML with the IMU's noise a known term (its random walks and "
           "the levelling tilt as a linear state), Cov(x) = A Sigma_track A^T + (A G)(A G)^T" if refit is not None
           else "Cov(x) = fit covariance + (A G)(A G)^T (a white noise model: the solver's sigma)")
    record = ("the least over difference orders 2-6 of the scatter of the k-th differences of consecutive samples "
              "over its noise gain (MAD / sqrt C(2k, k)), per sample (casep.checks.tracking_quality.white_sample_std)")
    if at_rest:
        source = ("measured at rest: the Allan deviation at 1 s times sqrt(1 s / step), per sample "
                  "(casep.checks.tracking_quality.rest_white_std)")
    elif on_pad and pad_span is not None:
        a, b = pad_span
        source = (f"measured at rest on the pad {a:.6g}..{b:.6g} s for {', '.join(on_pad)} (where the record's own "
                  "figure is above the pad's beyond their sampling errors: the record counts motion; "
                  "casep.checks.tracking_quality.pad_white_std), on the record otherwise: " + record)
    else:
        source = "measured on the record: " + record
    return {"source": source, "on_pad": list(on_pad), "pad_span_s": list(pad_span) if on_pad and pad_span else None,
            "accelerometer_m_s2": [float(v) for v in s[:3]], "gyro_rad_s": [float(v) for v in s[3:]],
            "not_measured": list(unresolved),
            "sample_step_s": h, "vrw_m_s_per_sqrt_s": [float(v * np.sqrt(h)) for v in s[:3]],
            "arw_rad_per_sqrt_s": [float(v * np.sqrt(h)) for v in s[3:]],
            "std_factor_max": float(finite.max()) if finite.size else None, "std_factor_worst": res.names[worst],
            "std_tracking_noise_only": {nm: (float(v) if np.isfinite(v) else None)
                                        for nm, v in zip(res.names, np.sqrt(np.diag(C_fit)))},
            "tracking_noise": None if refit is None else refit.to_dict(),
            "instability": None if flight is None else _instability_record(refit, flight),
            "rule": "the velocity and attitude random walks (and, with the pad window, the levelling's start tilt) "
                    "carried to the estimate exactly; the estimate is the fit's; " + how}


def with_imu_noise(res: EstimateResult, problem: Any, flight: FlightData,
                   levelling: tuple | None = None, profile: tuple | None = None,
                   heading: np.ndarray | None = None, estimators: np.ndarray | None = None,
                   measured: ImuNoise | None = None) -> EstimateResult:
    """`res` with the IMU's own noise (and with `heading` the given heading's uncertainty) in its covariance and std
    and said in its noise account (:func:`imu_noise_budget`, `estimators` and `measured` passed on; `res` itself when
    the flight does not hold the IMU's samples)."""
    budget = imu_noise_budget(res, problem, flight, levelling, profile, heading, estimators, measured)
    if budget is None:
        return res
    C_trk, C_imu, account = budget
    conflict = None
    if "tau_profile" in account:
        warn_tau_unbounded(problem.source, account["tau_profile"])
    if "tau_stated" in account:
        conflict = warn_tau_stated(problem.source, account["tau_stated"])
    C_fit = np.asarray(res.covariance)
    # the tracking part: refitted (the minimum-norm solution's, finite where the fit's is not), else the fit's own;
    # a refit sets the covariance anew, and the consider terms added on top of the fit's (with_extra_covariance: the
    # omitted terms of a telemetry judged before its IMU noise) are added back
    added = added_covariance(res) if C_trk is not None else None
    C_new = None if C_trk is None else C_trk + C_imu + (0.0 if added is None else added)
    cov = C_fit + C_imu if C_new is None else np.where(np.isfinite(C_fit), C_new, np.nan)
    std = widened_std(res, cov)
    solution = res.solution
    if solution is not None and solution.covariance is not None:
        solution = dataclasses.replace(solution, covariance=solution.covariance + C_imu if C_new is None else C_new)
    diag = {**res.diagnostics, "noise": {**res.diagnostics["noise"], "imu": account}}
    out = dataclasses.replace(res, covariance=cov, std=std, solution=solution, diagnostics=diag)
    if conflict is None:
        return out
    from casep.estimators.registry import STATUS_PRIOR_CONFLICT, failed

    return failed(out, STATUS_PRIOR_CONFLICT, conflict)


#: A linear telemetry result (no iteration) carries the IMU's noise (:func:`with_imu_noise`, the tracking noise refitted
#: beside it) when that noise, carried to the estimate with the tracking noise as fitted, widens some combination the
#: flight determines by more than this share of its std (:func:`with_imu_noise_beyond`). Below it the std left out
#: are at most 5 % short: a 95 % interval then still covers 93.8 % (``1.96 / 1.05`` std), and the refit beside the
#: IMU's noise would only lower the tracking part (the fit's noise model already holds the IMU's noise it saw).
IMU_NOISE_SHARE = 0.05


def imu_noise_widening(C: np.ndarray, C_imu: np.ndarray, scale: np.ndarray) -> float:
    """The largest factor by which the covariance `C_imu` widens the std of a combination `C` determines,
    ``sqrt(1 + max v^T C_imu v / v^T C v)`` over the combinations ``v`` (coefficients in their declared magnitudes
    `scale`) whose std under `C` is below 1 (the span of its eigenvectors with eigenvalues below 1, above its rounding
    ``n eps lambda_max``); 1 when it determines none."""
    inv = 1.0 / np.asarray(scale, dtype=float)
    lam, V = np.linalg.eigh(C * np.outer(inv, inv))
    keep = (lam < 1.0) & (lam > lam.size * np.finfo(float).eps * max(float(lam[-1]), 0.0))
    if not keep.any():
        return 1.0
    T = V[:, keep] / np.sqrt(lam[keep])  # T^T C T = I over the determined span
    mu = np.linalg.eigvalsh(T.T @ (C_imu * np.outer(inv, inv)) @ T)
    return float(np.sqrt(1.0 + max(float(mu[-1]), 0.0)))


def with_imu_noise_beyond(res: EstimateResult, problem: Any, flight: FlightData, scales: Mapping[str, float],
                          share: float | None = None) -> EstimateResult:
    """A linear navigated-telemetry result (a pair or one file; no iteration) with its IMU's noise in its std when
    it matters: first its effect on the estimate with the tracking noise as fitted, ``(A G)(A G)^T``
    (:func:`casep.checks.tracking_quality.imu_noise_effect`, no refit); beyond `share` of the std of some determined
    combination (:func:`imu_noise_widening`, `scales` the declared magnitudes; `share` None:
    :data:`IMU_NOISE_SHARE`) the full term of :func:`with_imu_noise`
    (the iterated path's: the tracking noise refitted beside it), the account's ``carried`` True; below it `res` with
    the account (``carried`` False, the widening said). `res` itself when the flight does not hold the IMU's samples
    or the result has no finite covariance or noise model."""
    from casep.checks.tracking_quality import imu_noise_effect

    C, nd = res.covariance, res.diagnostics.get("noise")
    if C is None or problem.t is None or not isinstance(nd, dict) or "axes" not in nd:
        return res
    t = np.asarray(problem.t, dtype=float)
    from casep.checks.tracking_quality import imu_noise_measured

    measured = imu_noise_measured(flight, t)  # once: the effect, the account and the full term's budget take it
    if measured is None or not np.all(np.isfinite(C)):
        return res if measured is None else with_imu_noise(res, problem, flight, measured=measured)
    A = coefficient_estimators(res, problem)
    AG = None if A is None else imu_noise_effect(flight, t, A, noise=measured.sample)
    if AG is None:
        return res
    C_imu = AG @ AG.T
    share = IMU_NOISE_SHARE if share is None else share
    added = added_covariance(res)  # the consider terms judged before (omitted terms): not the noise's std
    own = np.asarray(C) if added is None else np.asarray(C) - added
    factor = imu_noise_widening(own, C_imu, np.array([scales.get(nm, 1.0) for nm in res.names]))
    said = {"carried": factor - 1.0 > share or instability_tau(flight) is not None,
            "determined_std_factor_max": factor, "share": share,
            "share_rule": "a linear telemetry result carries the IMU's noise when, carried with the tracking noise as "
                          "fitted, it widens some determined combination's std by more than share, or when the flight "
                          "asks for the IMU's bias instability (which that widening does not hold)"}
    if said["carried"]:
        out = with_imu_noise(res, problem, flight, estimators=A, measured=measured)
        if out is not res:
            out.diagnostics["noise"]["imu"].update(said)
        return out
    account = {**_imu_account(res, measured, np.asarray(C), C_imu, None), **said}
    account["rule"] = ("not carried: the velocity and attitude random walks, carried to the estimate with the "
                       "tracking noise as fitted, widen no determined combination's std by more than share")
    return dataclasses.replace(res, diagnostics={**res.diagnostics, "noise": {**nd, "imu": account}})


class Shift(NamedTuple):
    """:func:`linearisation_shift`'s judgement: `std` how far the second-order remainder moves the linear result (in
    its std; None: not judged; infinite: not known), `why` the reason the record does not invert at the estimate when
    it is not known (:func:`casep.model.strapdown.not_inverted`'s columns and coefficients)."""

    std: float | None
    why: str | None = None


def linearisation_shift(run: Any, res: EstimateResult, problem: Any, flight: FlightData,
                        scales: dict) -> Shift:
    """How far the second-order remainder of a linear result moves it, in std (a strapdown telemetry's or a raw IMU
    record's one pass, `run` its :class:`_Run`: :mod:`casep.workflows.telemetry_iterate`'s module notes; None when it
    cannot be judged: no finite covariance, no rows; infinite when the record does not invert at the estimate, with
    why).

    Judged on what the flight determines, as the iteration's first pass steps (:func:`determined_step` about 0):
    the rows at the linear estimate's part along the combinations whose std is below the plausible size of the
    coefficients, and the remainder's shift ``b`` along those combinations only, ``|W b|`` (``W`` the step's
    metric: each combination's correction in its std; ``sqrt(b^T C^+ b)`` over them). Not over every combination:
    an undetermined one's linear estimate (thousands of declared magnitudes, std as large) navigates the record
    far from any plausible instrument, and its own remainder, in its own std, says nothing of the determined ones.
    On the tactical-grade Groves flight under ``strapdown33`` (18 of 34 combinations determined) the shift over
    every combination was 2.3e3 std and the telemetry iterated 6 passes."""
    C = res.covariance
    if C is None or problem.y is None or not np.all(np.isfinite(C)):
        return Shift(None)
    step = determined_step(res, problem, flight, scales, about=np.zeros(len(res.names)))
    if not step.metric.size:  # nothing determined: nothing whose linearity to judge
        return Shift(0.0)
    x = step.d
    try:
        y = run.rows(x)
    except ValueError as e:
        return Shift(np.inf, str(e))
    S = problem.sv()
    r = (y - problem.y + np.einsum("ijk,k->ij", S, x)).reshape(-1)
    b = np.linalg.lstsq(S.reshape(-1, len(res.names)), r, rcond=None)[0]
    return Shift(float(np.linalg.norm(step.metric @ b)))


def linearisation_record(shift: Shift) -> dict:
    """``diagnostics["linearisation"]`` of a result judged by :func:`linearisation_shift`'s `shift`."""
    from casep.regression.linearisation import LINEAR_OFFSET_SHARE

    known = shift.std is None or np.isfinite(shift.std)
    return {"shift_std": shift.std if known else None, "tol": LINEAR_OFFSET_SHARE,
            **({} if known else {"why": "the record does not invert at the estimate"
                                        + (f": {shift.why}" if shift.why else "")}),
            "rule": "the second-order remainder of the linear estimate moves it by shift_std std (along the "
                    "combination it moves most); the linear result stands below tol"}


def shift_said(shift: Shift) -> str:
    """What moved a linear result (:func:`linearisation_shift`'s `shift`, judged): the second-order remainder by so
    many std, or, where the record does not invert at the estimate, that and why (never an infinite shift)."""
    from casep.regression.linearisation import LINEAR_OFFSET_SHARE

    if shift.std is not None and np.isfinite(shift.std):
        return (f"the linear estimate's second-order remainder moved it by {shift.std:.3g} std (above "
                f"{LINEAR_OFFSET_SHARE:g})")
    return ("the linear estimate could not be checked for its second order: the record does not invert at the "
            "estimate" + (f": {shift.why}" if shift.why else ""))


def one_pass_judged(res: EstimateResult, shift: Shift) -> EstimateResult:
    """A linear result kept without iterating (a strapdown telemetry's or a raw IMU record's ``iterate=False``)
    judged by its second-order remainder `shift` (:func:`linearisation_shift`, not None): as it is at or below
    ``LINEAR_OFFSET_SHARE``; above it with a :class:`~casep.exceptions.NonlinearityWarning` in its message;
    failed (status -8) beyond :data:`FAIL_SHIFT` std."""
    from casep.estimators.registry import STATUS_MISFIT, failed
    from casep.exceptions import NonlinearityWarning
    from casep.regression.linearisation import LINEAR_OFFSET_SHARE

    res.diagnostics["linearisation"] = {**linearisation_record(shift), "iterated": False}
    why, std = shift.why, float(shift.std if shift.std is not None else np.nan)
    if std <= LINEAR_OFFSET_SHARE:
        return res
    if np.isfinite(std):
        said = (f"the linear model does not hold on this strapdown record: the second-order remainder at the "
                f"estimate moves it by {std:.3g} std along one combination of the coefficients (above "
                f"{LINEAR_OFFSET_SHARE:g}): the linear std leave that out; separate with iterate (CLI: --iterate) to "
                "re-navigate the corrected record")
    else:
        said = ("the linear model cannot be checked on this strapdown record: corrected by the linear estimate the "
                f"record does not invert (navigate){f': {why}' if why else ''}, so how far its second order moves "
                "the estimate is unknown; separate with iterate (CLI: --iterate) to re-navigate the corrected record "
                "pass by pass")
    warnings.warn(said, NonlinearityWarning, stacklevel=3)
    if std > FAIL_SHIFT:
        return failed(res, STATUS_MISFIT, f"failed: {said}")  # the residuals hold the second order
    return dataclasses.replace(res, message=f"{res.message}; {said}")
