"""The tracking noise of a flight, identified from its least-squares residuals (``casep noise``).

The error coefficients are fitted by ordinary least squares; the residuals
r = dv - S_V D_hat (per axis) are then the tracking noise plus whatever the model leaves out, and
their Allan deviation tells white noise (slope -1/2), Gauss-Markov noise (a hump at about its
correlation time) and random walk (slope +1/2) apart (:func:`casep.analysis.noise_id.identify_noise`).
The Allan deviation needs a uniform sample step; a flight with gaps is refused.
"""

from __future__ import annotations

import warnings
from typing import Any

__all__ = ["flight_noise", "STEP_TOLERANCE"]

#: Largest relative departure of a sample step from the median step for a "uniform" flight.
STEP_TOLERANCE = 0.01


def flight_noise(flight: Any, model: Any) -> tuple[Any, Any]:
    """Identify the noise of a flight's least-squares residuals.

    Parameters
    ----------
    flight : FlightData
        The flight (one file, or telemetry and tracking read together).
    model : ErrorModel
        The error model whose coefficients are fitted first.

    Returns
    -------
    noise : NoiseIdentification
        Allan deviation of the residuals per axis and the fitted noise models.
    problem : Problem
        The regression problem (``problem.source``: the flight's file).

    Raises
    ------
    ValueError
        The sample steps vary by more than :data:`STEP_TOLERANCE` of their median (gaps).
    """
    import numpy as np

    from casep.analysis.noise_id import identify_noise
    from casep.analysis.problem import Problem
    from casep.estimators.ols import solve_ols
    from casep.exceptions import CasepWarning

    problem = Problem.from_flight(flight, model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)  # conditioning: not the question here
        res = solve_ols(problem)
    r = problem.residuals(res.estimate).reshape(-1, 3)  # r = dv - S_V D_hat, one row per sample
    if problem.t is None:
        raise ValueError(f"{problem.source}: no sample times: the Allan deviation needs them")
    step = np.diff(problem.t)
    dt = float(np.median(step))
    if np.max(np.abs(step - dt)) > STEP_TOLERANCE * dt:
        raise ValueError(f"{problem.source}: sample steps vary from {step.min():.4g} to {step.max():.4g} s: the "
                         "Allan deviation needs a uniform step (gaps?)")
    return identify_noise(r, dt), problem
