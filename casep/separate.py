"""The end-to-end job: flight -> model -> S_V -> estimator -> result."""

from __future__ import annotations

import dataclasses
import os

from .flight import FlightData, check_enough_samples
from .flight_io import read_flight
from .model import ErrorModel
from .model_loader import load_model
from .ols import solve_ols
from .result import EstimateResult
from .sv import build_sv

__all__ = ["separate", "METHODS"]

#: Estimators available through :func:`separate`.
METHODS = ("ols",)


def separate(
    flight: FlightData | str | os.PathLike,
    model: str | os.PathLike | ErrorModel = "platform36",
    method: str = "ols",
    *,
    sigma: float | None = None,
) -> EstimateResult:
    """Estimate a model's error coefficients from one flight.

    Parameters
    ----------
    flight : FlightData or path
        The flight, or a flight file to read.
    model : str, path or ErrorModel, optional
        Model name (``"platform36"``), model file, or model object.
    method : {"ols"}, optional
        Estimator.
    sigma : float, optional
        Known noise standard deviation, m/s (default: estimated from the residuals).

    Returns
    -------
    EstimateResult
    """
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {', '.join(METHODS)}, got {method!r}")
    if not isinstance(flight, FlightData):
        flight = read_flight(flight)
    model = load_model(model)
    check_enough_samples(flight, model.n_coefficients, model.name)
    S = build_sv(model, flight.t, flight.f)
    res = solve_ols(S, flight.dv, names=model.names, units=model.units, si_factors=model.si_factors,
                    sigma=sigma)
    return dataclasses.replace(res, model=model.name, n_samples=flight.n_samples)
