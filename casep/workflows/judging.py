"""How a separation's result is judged against its flight: the set-up, the misfit, the declared magnitudes
(:func:`judge_setup`) and the tracking's stretches (:func:`judge_tracking`); one place for every workflow that
separates a flight (:func:`casep.separate`, the raw-IMU and telemetry iterations, several flights, the demo)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from casep.estimators.registry import METHODS as _REGISTRY
from casep.estimators.registry import STATUS_MISFIT, STATUS_PRIOR_CONFLICT, STATUS_SETUP
from casep.estimators.result import EstimateResult
from casep.model.error_model import ErrorModel

if TYPE_CHECKING:
    from casep.io.flight import FlightData
    from casep.regression.problem import Problem

__all__ = ["judge_setup", "judge_tracking", "judge_pad_hold", "untrusted", "ABSORBED"]

#: The failures that say the estimates absorb an effect the model does not hold (a set-up problem: lost rows, the
#: levelling, the heading; a misfit; a prior the data contradict: the IMU clock's drift, the heading given): the
#: combinations a result failed so states are not to be trusted (:func:`untrusted`).
ABSORBED = (STATUS_SETUP, STATUS_MISFIT, STATUS_PRIOR_CONFLICT)


def untrusted(res: EstimateResult) -> str | None:
    """What a statement of the combinations `res` determines says when `res` has failed on an effect its estimates
    absorb (status in :data:`ABSORBED`, the first failure of its message): they are not to be trusted, neither their
    values nor their std, which do not hold that effect; None for a success or another failure (a tracking whose
    noise differs between stretches: the combinations are its answer; an iteration not converged says so). One rule for
    every place a failed result states combinations (:func:`judge_tracking`, the iterated passes':
    :func:`casep.workflows.imu_separate._with_determined`)."""
    if res.success or res.status not in ABSORBED:
        return None
    return (f"not to be trusted: the result failed (status {res.status}) on an effect its estimates absorb (the first "
            "failure above), which neither these values nor their std hold")


def judge_setup(res: EstimateResult, flight: FlightData | None, model, *, noise_free: bool = False) -> EstimateResult:
    """A result judged against the set-up: failed (status -4) when its flight failed a set-up check
    (:func:`casep.checks.plausibility.setup_problems`: launch site, azimuth, launch time, time scales), failed
    (status -8) when its residuals are a model error, not noise (:func:`casep.checks.plausibility.misfit_problem`:
    100 times the tracking's sample-to-sample noise and correlated after the noise model, or, in a robust fit,
    with most of the samples it rejected in runs: :func:`casep.regression.rows.mostly_runs`; or robust "auto"
    left off because most of the samples it would reject lie in runs: ``diagnostics["misfit_runs"]``, the runs
    named), and against
    the model's declared magnitudes (:func:`casep.estimators._base.check_magnitudes`), except on noise-free
    data (`noise_free`), where every std is rounding and a biased method's estimate is its bias, not a
    set-up mistake (check_fit's NoiseFreeWarning says so)."""
    from casep.checks.plausibility import levelling_problem, misfit_advice, misfit_problem, setup_problems
    from casep.estimators.registry import STATUS_MISFIT, STATUS_SETUP, check_magnitudes, failed
    from casep.regression.rows import mostly_runs

    problems = setup_problems(flight) if flight is not None else []
    if flight is not None and problems:
        res = failed(res, STATUS_SETUP, f"failed: set-up check of {flight.source}: " + "; ".join(problems))
    why_lost = _lost_rows_problem(flight)
    if why_lost is not None:
        res = failed(res, STATUS_SETUP, f"failed: {flight.source if flight is not None else ''}: {why_lost}")
    why_late = _lateness_left(res, flight)
    if why_late is not None:
        res = failed(res, STATUS_SETUP, f"failed: {flight.source if flight is not None else ''}: {why_late}")
    why_level = levelling_problem(flight, model, _determined_estimates(res, model)) if flight is not None else None
    if why_level is not None:
        res = failed(res, STATUS_SETUP, f"failed: {why_level}")
    if flight is not None and not noise_free:
        rb = res.diagnostics.get("robust") or {}
        long = rb.get("rejected_runs") or []
        runs = (sum(long), int(rb.get("rejected_count") or 0), len(long)) \
            if mostly_runs(int(rb.get("rejected_count") or 0), long) else None
        # a robust fit's rejections in runs stand for the correlation (its weights absorbed the misfit as
        # "glitches"); otherwise the axes the whiteness test rejects
        correlated = "xyz" if runs is not None else (res.diagnostics.get("whiteness") or {}).get("rejected") or ()
        why = misfit_problem(flight, res.residual_rms, correlated, runs=runs,
                             advice=misfit_advice(res.model, res.names, res.units, res.estimate, res.std),
                             noise=res.diagnostics.get("noise"))
        if why is not None:
            res = failed(res, STATUS_MISFIT, f"failed: {flight.source}: {why}")
        found = res.diagnostics.get("misfit_runs")
        if found:  # robust "auto" left off for runs of rejections: a misfit neither the noise model nor the std cover
            res = failed(res, STATUS_MISFIT, f"failed: {flight.source}: {_runs_problem(found)}")
    if isinstance(model, ErrorModel) and model.name == res.model and not noise_free:
        meth = _REGISTRY.get(res.method)
        res = check_magnitudes(res, model.scales, source=flight.source if flight is not None else "",
                               regularised=meth is not None and meth.regularised)
    return res


def judge_tracking(res: EstimateResult, flight: FlightData, problem: Problem, scales: dict,
                   about: np.ndarray | None = None,
                   widen: Callable[[list[dict]], tuple[list[dict], str | None, dict | None]] | None = None,
                   tag_clock: bool = True) -> EstimateResult:
    """`res` failed (status ``STATUS_TRACKING``) when the flight's screened tracking noise differs between
    stretches beyond :data:`casep.checks.tracking_quality.NOISE_RATIO`: its message says which combinations the flight
    determines (:func:`casep.checks.tracking_quality.determined`) instead of each coefficient;
    ``diagnostics["determined"]`` holds them (``combinations``, ``std_factor``, the ``scales`` they divide by); `about`:
    the coefficients an iterated pass was linearised about (the combinations' estimates are totals); `widen`: ``combos
    -> (combos, note, record)``, what the nonlinearity does to them (an iterated pass's
    :meth:`casep.workflows.imu_separate._Run.determined_curvature`): the combinations said are its, `note` (or None)
    follows them, `record` goes in ``diagnostics["determined"]["curvature"]``. Their std carry the consider terms
    `res`'s covariance holds (the terms the model leaves out, a clock drift:
    :func:`casep.workflows.row_estimators.combinations_with_consider`, as the coefficients' std), and which are stated
    as determined is decided on that final std (:func:`casep.checks.tracking_quality.determined_split`); those it leaves
    out are said, with their std before each widening, and kept in ``diagnostics["determined"]["left_out"]``. The
    tracking clock's drift is measured on the fit's residuals (:func:`casep.checks.tracking_quality.fit_clock_drift`)
    and, with ``dt_trk`` in the fit, by that offset split between the flight's halves
    (:func:`casep.checks.tracking_quality.offset_halves`, ``["halves"]``), warned beyond its threshold and recorded in
    ``diagnostics["clock_drift"]`` (:func:`casep.checks.tracking_quality.clock_drift_record`: where not measured, why);
    not with `tag_clock` False (a separation from raw IMU data: its clock's drift stretches the steps too, which a late
    tag's model does not hold; :meth:`casep.workflows.imu_separate._Run.clock_judged` tests it)."""
    from casep.checks.tracking_quality import (
        clock_drift_record,
        combination_terms,
        determined,
        determined_message,
        determined_split,
        noise_problem,
        offset_halves,
        plausible_size,
        widened_said,
    )
    from casep.estimators.registry import STATUS_TRACKING, failed
    from casep.workflows.row_estimators import combinations_with_consider

    # the clock drift, on the residuals: the raw dv's instrument errors fake one (not where a strapdown telemetry's
    # clock was tested with its exact effect, its tags and steps: casep.workflows.telemetry_clock)
    if problem.y is not None and tag_clock and "telemetry" not in (res.diagnostics.get("clock_drift") or {}):
        drift = clock_drift_record(flight, problem.raw_residuals(res.fitted_coefficients()))
        # and by the fit's own time offset split in two, on a pair of files (a clock of its own)
        halves = offset_halves(flight.source, problem, res.diagnostics.get("noise")) \
            if flight.meta.get("format") == "pair" else None
        if drift is not None and halves is not None:
            drift["halves"] = halves
        if drift is not None:
            res = dataclasses.replace(res, diagnostics={**res.diagnostics, "clock_drift": drift})
    if tag_clock:
        res = _ins_clock_said(res, flight)
    why = noise_problem(flight)
    if why is None or problem.y is None or problem.t is None:
        return res
    combos, k = determined(problem, flight.meta["tracking_screen"]["stretches"], scales, imu=flight, about=about)
    note, record = None, None
    if widen is not None and combos:
        combos, note, record = widen(combos)
    if list(res.names) == list(problem.names):  # the consider terms the coefficients carry, as theirs
        combos = combinations_with_consider(combos, res, scales)
    combos, left = determined_split(combos)  # on the final std: every widening made
    size = plausible_size(combos)
    for c in combos:  # the terms that matter against the std it now has (determined's rule)
        c["terms"], c["more"] = combination_terms(list(problem.names), np.array(c["weights"]), c["std"], size)
    said = determined_message(why, combos, k, len(problem.names), scales,
                              widened_said(left, list(problem.names), scales))
    distrust = untrusted(res)
    said = said if distrust is None else f"{said} ({distrust})"
    res = failed(res, STATUS_TRACKING, said if note is None else f"{said}; {note}")
    res.diagnostics["determined"] = {"combinations": combos, "std_factor": k, "left_out": left, "untrusted": distrust,
                                     "scales": {nm: scales.get(nm, 1.0) for nm in problem.names}}
    if record is not None:
        res.diagnostics["determined"]["curvature"] = record
    return res


def judge_pad_hold(res: EstimateResult, flight: FlightData, model: ErrorModel,
                   about: np.ndarray | None = None) -> EstimateResult:
    """`res` with the pad's zero-velocity check of the flight's static hold: the epochs the tracking screen took out
    of the fit (``meta["tracking_screen"]["static_hold_rows"]``, :func:`casep.checks.tracking_quality.static_hold`: a
    receiver holding zero velocity while the vehicle stood) hold ``dv = S_V D`` with no tracking noise, so the
    estimate must predict them: ``r = dv - S_V x`` (``x`` the estimate, less `about` where the pass was linearised
    there: an iterated pass's ``D``) within :data:`casep.navigation.navigator.PAD_NOISE_FACTOR` times its std at
    every epoch and axis, ``sqrt(g C g^T + n(T)^2 + e^2)`` (``g`` the epoch's row of S_V, ``C`` the estimate's
    covariance; ``n(T)`` the speed the IMU's white noise navigates to in the ``T`` s since the levelling window began,
    :func:`casep.navigation.navigator.pad_noise_speed`, measured as :func:`casep.checks.tracking_quality.
    imu_sample_noise` measures it, 0 where the flight holds no samples; ``e`` the rows' rounding floor). A row whose
    prediction the fit does not determine (along the null space of its S_V) is not judged, and counted. Recorded in
    ``diagnostics["pad_check"]`` and said on a line of the message; beyond the bound the result fails
    (``STATUS_MISFIT``): the estimate contradicts the vehicle at rest (or the held velocity was not the vehicle's)."""
    import warnings

    from casep.checks.flight import flight_problem
    from casep.checks.tracking_quality import imu_sample_noise, rest_window, static_hold_samples
    from casep.estimators.registry import STATUS_MISFIT, failed
    from casep.io.flight import FlightDataError
    from casep.navigation.navigator import PAD_NOISE_FACTOR, pad_noise_speed

    held = static_hold_samples(flight)
    if not held.any() or res.covariance is None:
        return res
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the flight's warnings were said with its fit
            problem = flight_problem(dataclasses.replace(flight, observed=held), model)
    except FlightDataError as exc:  # too few epochs for the model, or a dv exactly 0 (nothing to predict)
        said = f"pad zero-velocity check of the static hold not made: {exc}"
        return dataclasses.replace(res, message=f"{res.message}\n{said}",
                                   diagnostics={**res.diagnostics, "pad_check": {"checked": False, "why": str(exc)}})
    S, y, t = problem.sv(), problem.y, problem.t
    if y is None or t is None or S.shape[2] != len(res.names):
        return res
    x = np.nan_to_num(res.fitted_coefficients()) - (0.0 if about is None else np.asarray(about, dtype=float))
    C = res.solution.covariance if res.solution is not None and res.solution.covariance is not None \
        else res.covariance
    C = np.nan_to_num(np.asarray(C, dtype=float))
    r = y - np.einsum("tij,j->ti", S, x)
    var = np.einsum("tij,jk,tik->ti", S, C, S)
    judged = np.isfinite(r)  # a dv the flight does not hold there: not judged
    if res.solution is not None:  # a prediction along the fit's null space is not determined: not judged
        judged &= res.solution.determined(S.reshape(-1, S.shape[2])).reshape(r.shape)
    if not judged.any():
        why = "the fit determines none of its predicted values there"
        said = f"pad zero-velocity check of the static hold not made: {why}"
        return dataclasses.replace(res, message=f"{res.message}\n{said}",
                                   diagnostics={**res.diagnostics, "pad_check": {"checked": False, "why": why}})
    window = rest_window(flight.meta) or [float(t[0]), float(t[-1])]
    measured = imu_sample_noise(flight, t)
    noise = np.zeros(t.size) if measured is None else pad_noise_speed(
        measured[0][:3], measured[0][3:], measured[1], np.maximum(t - window[0], 0.0), 9.80665)
    sd = np.sqrt(np.maximum(var, 0.0) + noise[:, None] ** 2 + problem.rounding_floor() ** 2)
    z = np.where(judged, np.abs(r) / np.where(sd > 0, sd, np.inf), 0.0)
    k, axis = np.unravel_index(int(np.argmax(z)), z.shape)
    record = {"checked": True, "span_s": [float(t[0]), float(t[-1])], "epochs": int(t.size),
              "not_judged": int((~judged).sum()),
              "largest_m_s": float(np.max(np.abs(np.where(judged, r, 0.0)))), "at_s": float(t[k]),
              "axis": "xyz"[axis], "largest_std": float(z[k, axis]), "limit_std": PAD_NOISE_FACTOR,
              "passed": bool(z[k, axis] <= PAD_NOISE_FACTOR),
              "rule": "dv - S_V x over the static hold within the limit times sqrt(g C g^T + the IMU's white noise "
                      "navigated since the levelling window began + the rows' rounding floor), per epoch and axis"}
    said = (f"pad zero-velocity check: the static hold {t[0]:.10g}..{t[-1]:.10g} s ({t.size} epochs, out of the fit: "
            f"no measurement noise) is predicted by the estimate to {record['largest_m_s']:.3g} m/s at most "
            f"({record['largest_std']:.3g} std at t = {t[k]:.10g} s, axis {'xyz'[axis]}; limit {PAD_NOISE_FACTOR:g})"
            + (f", {record['not_judged']} of its values not determined by the fit" if record["not_judged"] else ""))
    diag = {**res.diagnostics, "pad_check": record}
    if record["passed"]:
        return dataclasses.replace(res, message=f"{res.message}\n{said}", diagnostics=diag)
    return failed(dataclasses.replace(res, diagnostics=diag), STATUS_MISFIT,
                  f"failed: {flight.source}: {said}: beyond it, the estimate contradicts the vehicle at rest on the "
                  "pad (or the velocity held there was not the vehicle's)")


def _ins_clock_said(res: EstimateResult, flight: FlightData) -> EstimateResult:
    """`res` saying that a clock drift given for a telemetry (``flight.meta["clock_drift_ppm"]``, taken out of the
    tracking time tags: :func:`casep.io.pair.telemetry_time`) leaves the INS's own integration as it ran: where the
    drift is the flight computer's clock's, every step of the INS's integration was that much too long, a common scale
    factor ``-ppm`` on every gyro and accelerometer (gravity's integral too) that the scale factors take in. Recorded in
    ``diagnostics["clock_drift_given"]``; nothing without a drift given, or with the drift taken out of a raw IMU
    record's own steps (``clock_drift_of`` "imu": :func:`casep.navigation.imu.on_clock`). Measured on a strapdown
    telemetry navigated from a raw record whose clock ran 104 ppm fast, separated with ``--clock-drift -104``
    (``strapdown15_phi0``): ``sa_x`` and ``sg_x`` moved by +132 and +104 ppm (3.1 and 3.0 std) from the same record's
    on a true clock, the other coefficients by 1.4 std at most."""
    ppm = float(flight.meta.get("clock_drift_ppm") or 0.0)
    if not ppm or flight.meta.get("clock_drift_of") == "imu" or "clock_drift_given" in res.diagnostics:
        return res  # none, a raw record's own steps, or said already (a telemetry's iteration judges its last pass)
    said = (f"the clock drift given ({ppm:g} ppm) is taken out of the tracking time tags only: if it is the "
            "telemetry's own clock (a flight computer's) that drifts, its INS integrated over steps that much too "
            f"long, and that integration is not corrected: a common scale factor of {-ppm:+.3g} ppm on every gyro "
            "and accelerometer (gravity's integral too) that the scale factors take in (from raw IMU data, "
            "casep separate --imu takes the drift out of the IMU's own steps)")
    diag = {**res.diagnostics, "clock_drift_given": {"ppm": ppm, "taken_out_of": "the tracking time tags",
                                                     "ins_integration_corrected": False,
                                                     "scale_factor_if_ins_clock_ppm": -ppm}}
    return dataclasses.replace(res, message=f"{res.message}; {said}", diagnostics=diag)


def _runs_problem(found: dict) -> str:
    """The failure of a fit whose residuals hold runs of rejections (``diagnostics["misfit_runs"]``, the record of
    :attr:`casep.regression.rows.Rows.misfit_runs`), with where they lie."""
    from casep.noise.robust import REJECT
    from casep.regression.rows import misfit_runs_text

    return (f"the residuals hold {found['in_runs']} of the {found['found']} samples beyond {REJECT:g} robust sigma in "
            f"{found['count']} run(s) of consecutive samples ({misfit_runs_text(found)}): a smooth misfit of the "
            "model (a missing term, a frame or time-tag error, instrument errors too large for the linear model) "
            "or a block of wrong tracking epochs, not noise; the std do not cover it (check those times; wrong "
            "epochs left out of the tracking file, or the term added, give a result)")


def _lateness_left(res: EstimateResult, flight: FlightData | None) -> str | None:
    """:func:`casep.io.align.lateness_left` of the flight's pair and the result's ``dt_trk`` (ms in the result)."""
    from casep.io.align import lateness_left
    from casep.model.loader import TIME_OFFSET

    if flight is None or not isinstance(flight.meta, dict):
        return None
    record = flight.meta.get("time_alignment")
    if TIME_OFFSET in res.names:
        j = res.names.index(TIME_OFFSET)
        sd = None if res.std is None else 1e-3 * float(res.std[j])
        return lateness_left(record, 1e-3 * float(res.estimate[j]), sd)
    if any(n.startswith(TIME_OFFSET + "[") for n in res.names):  # several flights: each its own, not told apart here
        return None
    return lateness_left(record, None, None)


def _lost_rows_problem(flight: FlightData | None) -> str | None:
    """:func:`casep.io.strapdown.lost_rows_problem` of the flight's strapdown telemetry."""
    from casep.io.strapdown import lost_rows_problem

    if flight is None or not isinstance(flight.meta, dict):
        return None
    used = flight.t[flight.observed] if flight.observed is not None else flight.t
    return lost_rows_problem(flight.meta.get("strapdown"), float(used[-1]) if used.size else -np.inf)


def _determined_estimates(res: EstimateResult, model: Any) -> dict[str, float]:
    """`res`'s estimates (natural units, by name) of the coefficients the flight determines: a finite estimate and
    std, the std below the declared magnitude (:func:`casep.estimators.registry.not_determined`'s rule); the others'
    values are the solver's in directions the data do not fix, and figures formed from them say nothing (a levelled
    telemetry under strapdown33: ba_y, ba_z of 6e6 and 1.3e7 mg, "a start tilt of 2.93e+09 arcsec")."""
    from casep.estimators.registry import not_determined

    if res.std is None or res.estimate is None:
        return {}
    scales = getattr(model, "scales", None) or {}
    left = set(not_determined(res.names, res.std, scales))
    return {n: float(x) for j, (n, x, sd) in enumerate(zip(res.names, res.estimate, res.std))
            if j not in left and np.isfinite(x) and np.isfinite(sd)}
