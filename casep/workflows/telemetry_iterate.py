"""Strapdown telemetry whose errors are too large to stay linear: the remainder judged, and the iterated separation.

A strapdown telemetry file (``q_*``, ``fb_*``, ``w_*`` with ``v_tel_*``, paired with tracking) holds the INS's
attitude, and the body specific force and rate it integrated, at the telemetry rate. The separation of
:func:`casep.separate` is linear in the coefficients about the telemetry itself: S_V integrates the error model
along the INS attitude. With MEMS errors (gyro biases of hundreds of deg/h over minutes) the attitude error is
tens of degrees and the first-order model is biased by many std (on a 150 s aircraft-like flight with
600-1000 deg/h gyro biases: the accelerometer scale factors 11-14 std off, plain success).

**The corrected telemetry.** The telemetry holds what a re-navigation needs: the record corrected at
coefficients ``D`` (:func:`casep.model.strapdown.corrected_imu`), integrated by the navigator's own
mechanisation (:mod:`casep.navigation.strapdown`: increments, attitude, rotation-compensated velocity) from the
telemetry's first attitude (corrected by the model's ``phi0``), and the uncorrected record integrated the same way
(``B_c``, ``B_r``: attitudes, ``dV_c``, ``dV_r``: body velocity increments)::

    C_c(t) = C_tel(t) B_r(t)^T B_c(t)
    v_c(t_k) = v_tel(t_k) - dv0(D) + sum_{j <= k} [C_c(t_{j-1}) dV_c,j - C_tel(t_{j-1}) dV_r,j]
               + int_{t_0}^{t_k} [G(t, r_c) - G(t, r_tel)] dt,      r_c(t) = r_tel(t_0) + int_{t_0}^t v_c dt

The discretisation of the INS's own integration cancels in the difference (to second order in the correction),
and at ``D = 0`` the telemetry is given back exactly. The gravitation does not cancel: the INS evaluated it at its
own position ``r_tel``, the corrected trajectory is at ``r_c``, and ``G(r_c) - G(r_tel) ~ Gamma (r_c - r_tel)``
(``Gamma`` the gravity gradient, ~1.5e-6 s^-2 across, 3e-6 s^-2 along the vertical) is first order in the
correction: on a 30 s MEMS boost whose telemetry ended 1.95 km off, 0.029 m/s, up to 1.1 std of the estimates.
Its integral is the navigator's own (:func:`casep.navigation.strapdown.propagate_translation`: trapezoid
velocity and position, fixed-point passes on ``r_c`` until it moves by less than 1e-7 m) with the difference
of :func:`casep.navigation.strapdown.launch_gravitation` in place of the gravitation; ``r_tel`` is the
telemetry's ``r_tel_*`` (else ``v_tel`` integrated from the origin: the gradient barely changes over the
distance). It needs the launch site that ties the telemetry's frame to the Earth (:func:`telemetry_gravitation`:
``casep navigate``'s header, else the site given with Earth-fixed tracking); without one the telemetry's
gravitation is taken uniform (the term left out).

That is what a pass of the raw-IMU iteration (:mod:`casep.workflows.imu_separate`) navigates; :class:`_TelemetryRun`
is that iteration with this re-navigation in place of the pad alignment and the navigation (the passes, the stop
rule, the exact S_V of :func:`casep.model.strapdown.correction_errors` and the curvature check at one std are the
raw-IMU path's, called, not copied).

**The INS's sensor noise.** ``v_tel`` holds the velocity and attitude random walks the INS integrated from its noisy
sensors, which the tracking noise model does not describe; a pass's std carry them as the raw-IMU path's do
(:meth:`_TelemetryRun.with_noise`: :func:`casep.workflows.imu_separate.with_imu_noise`, the densities measured on
the telemetered record, the tracking noise refitted beside them). On 8 seeded 30 s MEMS boosts (0.02 m/s
tracking at 10 Hz, IMU white noise 2e-3 m/s^2 and 1e-4 rad/s per 100 Hz sample, integrated by ``casep
navigate``) the 128 z had RMS 1.09 and 95 % coverage 0.90 without the term, 0.74 and 0.99 with it (it raised the
std by up to 2x); the same generator with a noise-free IMU gave 0.77 and 0.99. A linear result that stands (no
iteration; a pair's or a one-file telemetry's, ``v_tel_*`` with ``v_trk_*``) carries it too, when it matters
(:func:`casep.workflows.imu_separate.with_imu_noise_beyond`): the IMU noise's effect on the estimate with the
tracking noise as fitted (no refit) first, and the full term only when that widens some determined combination's
std by more than :data:`~casep.workflows.imu_separate.IMU_NOISE_SHARE` (5 %); the account says which
(``diagnostics.noise.imu.carried``). The remainder below is judged in the tracking noise's std (the IMU noise
measured on the record can be overstated by its motion, and a result judged linear in it would not iterate when the
tracking says it should: iterating costs time, not accuracy). On a 20 Hz boost with 0.05 m/s^2
and 2e-3 rad/s per sample (``benchmarks/mc_telemetry_one_file.py``, 12 seeds) the tracking noise's std alone left
RMS z 78.9 on the determined combinations (coverage 0.14); with the term 1.06 (0.91).

**Rates the INS did not integrate.** The correction is the relative rotation ``B_r^T B_c`` of two integrations of
the telemetered rates, so it assumes they are the rates the INS integrated (a real INS's telemetry). Noise added
to the rates after the INS (a simulation writing noisy rates beside a clean attitude) re-integrates into an
attitude random walk that turns the correction about the wrong axes: on a 150 s flight with 0.01 rad/s of it
(0.012 rad after 150 s) and a correction of tens of degrees, the iterated estimate's RMS z was 2.95 where the same
flight with the rates as integrated gave 0.53.

**When the linear result stands** (:func:`linearisation_shift`). The pass at the linear estimate ``x``
(its part along the combinations the flight determines, as the iteration's first pass steps: std below the
plausible size of the coefficients) gives the rows the nonlinear model predicts; their remainder about the
linear model, ``r = y(x) - (y(0) - S_V x)``, moves the least-squares estimate by ``b = S_V^+ r``. (Its even part
alone, ``(y(x) + y(-x)) / 2 - y(0)``, free of any first-order difference between S_V's quadrature and the
re-navigation's, gave the same shifts to 2 % on three navigation-grade flights, 0.011-0.095 std: one pass is
enough.) The linear result stands while ``sqrt(b^T C^+ b)`` over the determined combinations (the shift along
the one it moves most, in that combination's std; an undetermined combination's linear estimate, its std as large,
says nothing of the linearity of what the result states) is below
:data:`casep.regression.linearisation.LINEAR_OFFSET_SHARE`, the rule the tracking offset and the radar launch time
are held to; beyond it :func:`separate` iterates (``iterate=None``, the default) or, with ``iterate=False``,
the linear result carries a :class:`~casep.exceptions.NonlinearityWarning` with the
shift (and fails, status ``STATUS_MISFIT``: the residuals hold the model's second order, when the shift exceeds
:data:`FAIL_SHIFT` std: an estimate that far off is no success).

On 6 seeded MEMS flights (30 s, tracking at 2 Hz with 0.02 m/s white noise; ``benchmarks/mc_telemetry_iterate.py``)
the remainder moved the linear estimates by 66-73 std; iterated (4 passes each) the 72 z pooled have RMS 0.896 and
95 % coverage 0.986 (max |z| 2.41; without the INS's noise term, which the record's motion raises a little on these
noise-free 25 Hz records: 0.946 and 0.944), the linear ones RMS 4.06 and coverage 0.51.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.workflows.imu_separate import (
    FAIL_SHIFT,
    ITERATE_TOL,
    MAX_ITERATIONS,
    _Run,
    linearisation_record,
    linearisation_shift,
    one_pass_judged,
    shift_said,
    with_imu_noise_beyond,
)
from casep.workflows.telemetry_clock import judge_telemetry_clock, telemetry_gravitation

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.estimators.spec import FitSpec
    from casep.io.flight import FlightData
    from casep.model.error_model import ErrorModel
    from casep.navigation.strapdown import Gravity

__all__ = ["corrected_telemetry", "telemetry_gravitation", "linearisation_shift", "linearisation_record",
           "one_pass_judged", "iterate_if_curved",
           "CorrectedTelemetry", "FAIL_SHIFT"]


@dataclass
class CorrectedTelemetry:
    """The telemetry at its own samples, corrected at some coefficients (:func:`corrected_telemetry`)."""

    q: np.ndarray  # (N, 4) body -> navigation
    fb: np.ndarray  # (N, 3) m/s^2
    w: np.ndarray  # (N, 3) rad/s
    v: np.ndarray  # (N, 3) m/s


def strapdown_arrays(inp: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, fb, w)`` of a pair's telemetry (its :class:`casep.io.pair.PairInputs`), the quaternions normalised."""
    from casep.io.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS

    q, fb, w = (np.column_stack([np.asarray(inp.signals[c], float) for c in cols])
                for cols in (QUATERNION_COLUMNS, BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS))
    return q / np.linalg.norm(q, axis=1, keepdims=True), fb, w


def corrected_telemetry(model: ErrorModel, t: np.ndarray, q: np.ndarray, fb: np.ndarray, w: np.ndarray,
                        v: np.ndarray, D: np.ndarray, start: tuple[np.ndarray, np.ndarray] | None = None,
                        gravity: Gravity | None = None, r: np.ndarray | None = None,
                        signals: dict[str, np.ndarray] | None = None) -> CorrectedTelemetry:
    """The telemetry re-navigated with its record corrected at `D` (module notes: ``C_c``, ``v_c``).

    Parameters
    ----------
    model : ErrorModel
        A set-up strapdown model (its errors in ``q_*``, ``fb_*``, ``w_*``).
    t, q, fb, w, v : arrays
        The telemetry's times (s), attitude (unit quaternions), body specific force (m/s^2), body rate (rad/s)
        and velocity (m/s), (N,) / (N, 4) / (N, 3).
    D : (n,) ndarray
        The coefficients, natural units (the model's first ``n``).
    start : (fb, w), optional
        Where the inversion of the record starts (:func:`casep.model.strapdown.corrected_imu`).
    gravity : callable, optional
        The gravitation of the telemetry's frame, ``gravity(t, r)`` (:func:`telemetry_gravitation`): the
        corrected velocity gains ``int [G(t, r_c) - G(t, r_tel)] dt``. None: a uniform gravitation (no term).
    r : (N, 3) ndarray, optional
        The telemetry's position ``r_tel`` (m), where its INS evaluated `gravity`; None: `v` integrated from the
        origin (trapezoid).
    signals : dict, optional
        Further telemetry columns the model's sensor errors use (name -> (N,) array; a window's ``ground_speed``).
    """
    from casep.model.strapdown import corrected_attitude, corrected_imu
    from casep.navigation.strapdown import (
        body_velocity_increments,
        increments_from_rates,
        propagate_attitude,
        propagate_translation,
        quat_rotate,
    )
    from casep.rotations import dcm_to_quat, quat_conjugate, quat_multiply, quat_to_dcm

    D = np.asarray(D, float)[:model.n_coefficients]
    if not np.any(D):
        return CorrectedTelemetry(q, fb, w, v)
    fb_c, w_c = corrected_imu(model, q, fb, w, t - t[0], D, start=start, signals=signals)
    phi0, dv0 = model.numeric("phi0") @ D, model.numeric("dv0") @ D
    inc_r, inc_c = increments_from_rates(t, w, fb), increments_from_rates(t, w_c, fb_c)
    B_r = propagate_attitude(q[0], inc_r)
    B_c = propagate_attitude(dcm_to_quat(corrected_attitude(quat_to_dcm(q[0]), phi0)), inc_c)
    q_c = quat_multiply(quat_multiply(q, quat_conjugate(B_r)), B_c)
    q_c /= np.linalg.norm(q_c, axis=1, keepdims=True)
    step = quat_rotate(q_c[:-1], body_velocity_increments(inc_c)) - quat_rotate(q[:-1], body_velocity_increments(inc_r))
    if gravity is None:
        v_c = v - dv0 + np.vstack([np.zeros((1, 3)), np.cumsum(step, axis=0)])
        return CorrectedTelemetry(q_c, fb_c, w_c, v_c)
    r_tel = r if r is not None else cumulative_trapezoid(v, t)

    def difference(tt: np.ndarray, rr: np.ndarray) -> np.ndarray:  # G(t, r_c) - G(t, r_tel) at samples of t
        at = np.column_stack([np.interp(tt, t, r_tel[:, i]) for i in range(3)])
        both = gravity(np.concatenate([tt, tt]), np.vstack([rr, at]))
        return both[:len(tt)] - both[len(tt):]

    # v_c = v_tel - dv0 + sum(step) + int dG dt: the navigator's integration of increments diff(v_tel) + step
    _, v_c, _ = propagate_translation(t, np.diff(v, axis=0) + step, r_tel[0], v[0] - dv0, difference)
    return CorrectedTelemetry(q_c, fb_c, w_c, v_c)


class _TelemetryRun(_Run):
    """The raw-IMU iteration (:class:`casep.workflows.imu_separate._Run`) on a strapdown telemetry pair: a pass
    re-navigates the telemetry's record corrected at ``D`` (:func:`corrected_telemetry`) and pairs it with the same
    tracking, the flight's screens kept; no pad alignment (the model's own ``phi0``, if any, is the start's)."""

    def __init__(self, flight: FlightData, base: ErrorModel, source: Any, spec: FitSpec,
                 fit_time_offset: bool | None) -> None:
        from casep.io.files import R_TEL_COLUMNS

        self.flight0, self.inp = flight, flight.meta["pair_inputs"]
        self.base, self.source, self.spec, self.fit_time_offset = base, source, spec, fit_time_offset
        self.pair: dict[str, Any] = {"time_offset": None}
        self.tel = strapdown_arrays(self.inp)
        self.gravity = telemetry_gravitation(flight)
        self.r_tel = (np.column_stack([np.asarray(self.inp.signals[c], float) for c in R_TEL_COLUMNS])
                      if all(c in self.inp.signals for c in R_TEL_COLUMNS) else None)
        q, fb, w = self.tel
        self.nav: Any = None
        self.imu_k: Any = CorrectedTelemetry(q, fb, w, np.asarray(self.inp.v_tel, float))  # the last pass's
        self.model_k: ErrorModel | None = None
        self.q_aligned, self.C_tb = np.array([1.0, 0.0, 0.0, 0.0]), np.eye(3)  # no alignment: the state `rows` keeps
        self.screen: dict | None = None
        self.inputs_said = True  # by the linear separation that asked for the iteration

    def clock_judged(self, res: EstimateResult, problem: Any, flight: FlightData, D: np.ndarray) -> EstimateResult:
        """The telemetry clock's drift with its exact effect (:func:`casep.workflows.telemetry_clock
        .judge_telemetry_clock`) in place of the raw record's (a telemetry has none)."""
        return judge_telemetry_clock(res, flight, problem, self.base.scales) or res

    def navigate(self, D: np.ndarray) -> CorrectedTelemetry:  # type: ignore[override]  # the pass's state, as nav
        """The telemetry corrected at `D` (from the last pass's correction)."""
        q, fb, w = self.tel
        t = np.asarray(self.inp.t_tel, float)
        last = self.imu_k
        tel = corrected_telemetry(self.base, t, q, fb, w, np.asarray(self.inp.v_tel, float), D,
                                  start=(last.fb, last.w), gravity=self.gravity, r=self.r_tel,
                                  signals={c: np.asarray(self.inp.signals[c], float) for c in self.base.signals
                                           if c in self.inp.signals})
        self.imu_k = tel
        return tel

    def flight(self, nav: Any, D: np.ndarray, model: ErrorModel | None) -> FlightData:
        """The corrected telemetry paired with the tracking as the flight was (same grid, same rows observed), less
        the model's direct velocity terms at `D`."""
        from casep.checks.tracking_quality import static_hold_samples
        from casep.io.files import acceleration_signals
        from casep.io.pair import pair_flight
        from casep.io.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS
        from casep.rotations import quat_rotate
        from casep.workflows.imu_separate import _direct_velocity

        f0, inp = self.flight0, self.inp
        if nav is None or not np.any(D[:self.base.n_coefficients]):
            flight = f0
        else:
            sig = dict(inp.signals)
            for cols, arr in ((QUATERNION_COLUMNS, nav.q), (BODY_FORCE_COLUMNS, nav.fb), (BODY_RATE_COLUMNS, nav.w)):
                sig.update({c: arr[:, i] for i, c in enumerate(cols)})
            if "kinematic_acceleration" in f0.meta:  # the time offset's a(t): the corrected trajectory's, not the raw
                sig.update(acceleration_signals(inp.t_tel, nav.v))
            shift = float(f0.meta.get("pair_shift_s", 0.0))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the pair's warnings were said when the flight was read
                new = pair_flight(inp.t_tel, quat_rotate(nav.q, nav.fb), nav.v, inp.t_trk - shift, inp.v_trk,
                                  signals=sig, interpolation=inp.interpolation, grid=inp.grid, source=f0.source)
            observed = np.asarray(new.observed) & np.asarray(f0.observed)
            held = observed | (np.asarray(new.observed) & static_hold_samples(f0))  # the pad check's dv too
            # the pair's other signals (the tracked state r_*, v_* of Earth-fixed tracking) on the same grid kept
            flight = dataclasses.replace(f0, f=new.f, dv=np.where(held[:, None], new.dv, np.nan),
                                         signals={**f0.signals, **new.signals}, observed=observed)
        if model is None or not np.any(D):
            return flight
        return dataclasses.replace(flight, dv=flight.dv - _direct_velocity(model, flight, D))

    def model(self, nav: Any, D: np.ndarray, source: Any = None) -> ErrorModel:
        """The model linearised about the correction at `D` (:func:`casep.model.strapdown.correction_errors`), with
        ``dt_trk`` when fitted, set up (`source`: :meth:`casep.workflows.imu_separate._Run.model`)."""
        from casep.model.loader import add_time_offset

        m = self._linearised(D, source)
        if self.fit_time_offset:
            add_time_offset(m)
        m.setup()
        return m

    def with_noise(self, res: EstimateResult, problem: Any, flight: FlightData) -> EstimateResult:
        """`res` with the INS's own sensor noise in its std (:func:`casep.workflows.imu_separate.with_imu_noise`: the
        velocity and attitude random walks the INS integrated into ``v_tel``, measured on the telemetered record,
        the tracking noise refitted beside them; module notes)."""
        from casep.workflows.imu_separate import with_imu_noise

        return with_imu_noise(res, problem, flight)

    def levelling(self) -> tuple | None:
        """No levelling of casep's own: the telemetry's INS was aligned by its flight computer."""
        return None

    def gap_clause(self, sigma: float) -> str:
        """No raw record with gaps of its own: a failed iteration names none."""
        return ""


def iterate_if_curved(res: EstimateResult, flight: Any, problem: Any, model: Any, spec: FitSpec,
                      iterate: bool | None) -> tuple[EstimateResult, bool]:
    """The result of :func:`casep.separate` on a strapdown telemetry pair, judged for its linearisation (module
    notes): ``(result, iterated)``. `res` as it is (a record in ``diagnostics["linearisation"]``) while its
    second-order remainder is below ``LINEAR_OFFSET_SHARE`` std; beyond it the iterated separation's result
    (`iterate` None or True; True iterates whatever the remainder), or, with `iterate` False, `res` with a
    :class:`~casep.exceptions.NonlinearityWarning` (failed beyond :data:`FAIL_SHIFT` std). Whatever the tracking
    frame: Earth-fixed tracking is paired launch-inertial (its ``r_*``, ``v_*`` kept in every pass's flight), and
    rows a screen left out (tracking, saturation) stay out of every pass. Anything else than a strapdown telemetry
    pair with a strapdown model, or a result that failed already (its failure says more than its curvature would):
    `res` unchanged."""
    from casep.io.flight import FlightData
    from casep.io.pair import PairInputs
    from casep.io.strapdown import STRAPDOWN_COLUMNS
    from casep.model.error_model import ErrorModel
    from casep.model.strapdown import imu_error_signals
    from casep.regression.linearisation import LINEAR_OFFSET_SHARE

    inp = flight.meta.get("pair_inputs") if isinstance(flight, FlightData) else None
    if not isinstance(flight, FlightData) or not isinstance(model, ErrorModel) or not res.success:
        return res, False
    if not isinstance(inp, PairInputs) or not all(c in inp.signals for c in STRAPDOWN_COLUMNS) \
            or not imu_error_signals(model):
        # a one-file telemetry, or a telemetry under another model: linear, its IMU's noise when it matters
        return with_imu_noise_beyond(res, problem, flight, model.scales), False
    from casep.model.loader import TIME_OFFSET, load_model

    base = load_model(model.source_file or model.name) if TIME_OFFSET in model.names else model
    run = _TelemetryRun(flight, base, model.source_file or model.name, spec, TIME_OFFSET in model.names)
    # the remainder judged in the tracking noise's std (the IMU noise measured on the record may be overstated by
    # its motion: judged in the wider std, a clipped telemetry curved by 1.2 tracking std stood linear); the result
    # that stands carries its IMU's noise when it matters
    shift = linearisation_shift(run, res, problem, flight, model.scales)
    record = linearisation_record(shift)
    from casep.workflows.omitted_terms import judge_omitted

    # the richer model's terms beside a linear result that stands (after its IMU noise, whose refit sets the
    # covariance anew); an iterated one's on its last pass (casep.workflows.imu_separate._Run.finish)
    if not iterate and (shift.std is None or shift.std <= LINEAR_OFFSET_SHARE):
        res = with_imu_noise_beyond(res, problem, flight, model.scales)
        res.diagnostics["linearisation"] = {**record, "iterated": False}
        return judge_omitted(res, flight, problem, model), False
    if iterate is False and shift.std is not None:
        res = one_pass_judged(with_imu_noise_beyond(res, problem, flight, model.scales), shift)
        return judge_omitted(res, flight, problem, model), False
    out = run.iterate(True, ITERATE_TOL, MAX_ITERATIONS).result
    out.diagnostics["linearisation"] = {**record, "iterated": True}
    if shift.std is not None and shift.std > LINEAR_OFFSET_SHARE:
        note = (f"iterated: {shift_said(shift)}; the record re-navigated at the estimate in "
                f"{len(out.diagnostics['iterations']['passes'])} passes")
        out = dataclasses.replace(out, message=f"{out.message}; {note}")
    return out, True
