"""A flight's problem, checked before estimation: the one way casep builds the regression of a flight.

:meth:`casep.regression.problem.Problem.from_flight` builds the regression and judges nothing (the
regression layer knows no check); :func:`flight_problem` runs the checks before estimation first
(:func:`check_before_estimation`), so that every workflow, command and campaign refuses and warns
about the same flights, with the same messages, before S_V is integrated.
"""

from __future__ import annotations

from casep.checks.late_start import warn_late_start
from casep.checks.plausibility import (
    check_dv_not_zero,
    check_enough_samples,
    check_flight,
    levelling_problem,
    warn_setup,
)
from casep.checks.saturation import screen_saturation
from casep.checks.tracking_quality import screen_tracking
from casep.io.flight import FlightData, FlightDataError
from casep.model.error_model import ErrorModel
from casep.regression.problem import DEFAULT_BLOCK_ROWS, Problem

__all__ = ["check_before_estimation", "check_bound_describes", "flight_problem"]


def check_before_estimation(flight: FlightData, model: ErrorModel) -> None:
    """The checks of a flight for a set-up model before estimation, in this order.

    Too few observed samples for the model's coefficients (:func:`check_enough_samples`, error);
    unit mistakes and impossible data (:func:`check_flight`); an all-zero dv
    (:func:`check_dv_not_zero`, error); the set-up evidence the pair reader recorded (site,
    azimuth, launch time, time scales: :func:`warn_setup`); tracking that starts after lift-off
    without the model's initial terms (:func:`casep.checks.late_start.warn_late_start`).

    Raises
    ------
    casep.io.flight.FlightDataError
        Data that cannot be a boost flight, or too little of it.

    Warns
    -----
    PlausibilityWarning, SetupWarning, LateStartWarning
        Legal but suspicious data, with the numbers.
    """
    check_enough_samples(flight, model.n_coefficients, model.name)
    check_flight(flight)
    check_dv_not_zero(flight)
    warn_setup(flight)
    warn_late_start(flight, model)


def check_bound_describes(flight: FlightData, model: ErrorModel) -> None:
    """Refuse a bound without an estimate (``casep diagnose``) for a model that cannot describe the flight where
    ``casep separate`` fails its result for it (status -4, :func:`casep.workflows.judging.judge_setup`): a
    telemetry ``casep navigate`` levelled on the pad and a strapdown model without an initial attitude error
    (:func:`casep.checks.plausibility.levelling_problem`, the one rule). Such a bound is that of a telemetry not
    levelled: its pad rows seem to determine the horizontal accelerometer biases that the levelling cancelled
    there (a navigated 90 s record levelled over 29 s, strapdown12: ``ba_x``, ``ba_y`` 0.19, 0.10 mg; with the
    levelling's phi0 free, strapdown15_phi0: 0.57, 0.73 mg), and a bound has no result to fail.

    Raises
    ------
    casep.io.flight.FlightDataError
        Naming the levelling's window and the model or command to use instead.
    """
    why = levelling_problem(flight, model)
    if why is not None:
        raise FlightDataError(flight.source, why.removeprefix(f"{flight.source}: ") + (
            "; a bound with this model would be that of a telemetry not levelled, its pad rows seeming to determine "
            "the horizontal accelerometer biases the levelling cancelled there, so none is given"))


def flight_problem(flight: FlightData, model: ErrorModel, *, keep_sv: bool | None = None,
                   block_rows: int = DEFAULT_BLOCK_ROWS, bound: bool = False) -> Problem:
    """The regression of a flight for a set-up model, after :func:`check_before_estimation`.

    Parameters
    ----------
    flight : FlightData
    model : ErrorModel
        Set up.
    keep_sv, block_rows
        As :meth:`casep.regression.problem.Problem.from_flight` (S_V kept whole or regenerated
        block by block).
    bound : bool
        The problem is for a bound without an estimate (``casep diagnose``): a model that cannot describe the
        flight is refused first (:func:`check_bound_describes`), where ``casep separate`` fails its result.

    Returns
    -------
    Problem
        Of the flight without the tracking epochs :func:`casep.checks.tracking_quality.screen_tracking`
        leaves out (stale, impossible) and the rows from a saturated telemetry sensor on
        (:func:`casep.checks.saturation.screen_saturation`), said with warnings.
    """
    if bound:
        check_bound_describes(flight, model)
    flight = screen_saturation(screen_tracking(flight))
    check_before_estimation(flight, model)
    return Problem.from_flight(flight, model, keep_sv=keep_sv, block_rows=block_rows)
