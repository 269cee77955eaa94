"""The tracking noise of a flight, identified from its least-squares residuals (``casep noise``).

The error coefficients are fitted by ordinary least squares; the residuals
r = dv - S_V D_hat (per axis) are then the tracking noise plus whatever the model leaves out, and
their Allan deviation tells white noise (slope -1/2), Gauss-Markov noise (a hump at about its
correlation time) and random walk (slope +1/2) apart (:func:`casep.noise.identification.identify_noise`).
The Allan deviation needs a uniform sample step: on a flight with tracking gaps it runs on the
longest evenly sampled stretch (a :class:`~casep.exceptions.GapWarning` says which); a flight whose
steps vary otherwise is refused.
"""

from __future__ import annotations

import warnings
from typing import Any

__all__ = ["flight_noise", "STEP_TOLERANCE", "MIN_STRETCH"]

#: Largest relative departure of a sample step from the median step for a "uniform" flight.
STEP_TOLERANCE = 0.01
#: Fewest samples of the evenly sampled stretch the Allan deviation runs on (its longest averaging
#: time is a tenth of the stretch: below 64 samples it has hardly two octaves).
MIN_STRETCH = 64


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
        The sample steps vary by more than :data:`STEP_TOLERANCE` of their median other than at gaps
        (steps longer than the median), or no evenly sampled stretch has :data:`MIN_STRETCH` samples.
    """
    import numpy as np

    from casep.checks.flight import flight_problem
    from casep.estimators.ols import solve_ols
    from casep.exceptions import CasepWarning
    from casep.noise.identification import identify_noise

    problem = flight_problem(flight, model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)  # conditioning: not the question here
        res = solve_ols(problem)
    r = problem.residuals(res.estimate).reshape(-1, 3)  # r = dv - S_V D_hat, one row per sample
    if problem.t is None:
        raise ValueError(f"{problem.source}: no sample times: the Allan deviation needs them")
    step = np.diff(problem.t)
    dt = float(np.median(step))
    even = np.abs(step - dt) <= STEP_TOLERANCE * dt
    gap = step > (1.0 + STEP_TOLERANCE) * dt  # a tracking dropout: the stretches on either side are even
    if np.any(~even & ~gap):
        raise ValueError(f"{problem.source}: sample steps vary from {step.min():.4g} to {step.max():.4g} s: the "
                         "Allan deviation needs a uniform step")
    if gap.any():
        edges = np.r_[0, np.flatnonzero(gap) + 1, problem.t.size]  # stretches [edges[k], edges[k + 1])
        k = int(np.argmax(np.diff(edges)))
        a, b = int(edges[k]), int(edges[k + 1])
        if b - a < MIN_STRETCH:
            raise ValueError(f"{problem.source}: {int(gap.sum())} gap(s) leave at most {b - a} evenly sampled "
                             f"samples; the Allan deviation needs {MIN_STRETCH}")
        from casep.exceptions import GapWarning

        warnings.warn(f"{problem.source}: {int(gap.sum())} tracking gap(s): the Allan deviation uses the longest "
                      f"evenly sampled stretch, t = {problem.t[a]:.6g} .. {problem.t[b - 1]:.6g} s ({b - a} of "
                      f"{problem.t.size} samples)", GapWarning, stacklevel=2)
        r = r[a:b]
    return identify_noise(r, dt), problem
