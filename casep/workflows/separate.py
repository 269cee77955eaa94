"""The end-to-end job: flight -> model -> S_V -> estimator -> result."""

from __future__ import annotations

import dataclasses
import os
from typing import Mapping

import numpy as np

from casep.analysis.checks import check_fit, check_flight
from casep.analysis.denoise import denoise as wavelet_denoise
from casep.io.flight import FlightData, check_dv_not_zero, check_enough_samples, warn_late_start
from casep.io.files import read_flight, read_json_table
from casep.model._model import ErrorModel
from casep.model.loader import load_model
from casep.estimators.pcr import DEFAULT_MAX_CONDITION_INDEX
from casep.estimators.registry import METHODS as _REGISTRY, OPTIONS, check_method_options, run_method
from casep.estimators.result import EstimateResult
from casep.estimators.rls import DEFAULT_P0
from casep.model.sv import build_sv

__all__ = ["separate", "regression_rows", "METHODS"]

#: Estimators available through :func:`separate` and ``casep separate --method`` (the registry's).
METHODS = tuple(_REGISTRY)


def regression_rows(flight: FlightData, model: ErrorModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The regression of a flight: ``(S_V, dv, t)`` at the observed samples.

    S_V is integrated over every sample, from the first telemetry sample where the model has
    dv = 0 and phi = 0, then the rows where tracking observes dv are kept. Shared by
    :func:`separate` and ``casep diagnose``: both first refuse too few observed samples and
    an all-zero dv, and warn when the flight starts after lift-off without the initial terms
    in the model (:func:`casep.io.flight.warn_late_start`).
    """
    check_enough_samples(flight, model.n_coefficients, model.name)
    check_flight(flight)  # unit mistakes, impossible data (casep.checks)
    check_dv_not_zero(flight)
    warn_late_start(flight, model)
    return flight.observed_rows(build_sv(model, flight.t, flight.f,
                                         signals=flight.model_signals(model.signals, model.name)))


def separate(
    flight: FlightData | str | os.PathLike,
    model: str | os.PathLike | ErrorModel = "platform36",
    method: str = "ols",
    *,
    sigma: float | None = None,
    p0: float = DEFAULT_P0,
    weight: float = 1.0,
    forgetting: float = 1.0,
    noise_order: int = 1,
    lam: float | str = "gcv",
    bounds: Mapping | None = None,
    prior: Mapping | None = None,
    n_components: int | None = None,
    max_condition_index: float = DEFAULT_MAX_CONDITION_INDEX,
    denoise: str | None = None,
    wavelet_options: Mapping | None = None,
    tau: float | str = "auto",
) -> EstimateResult:
    """Estimate a model's error coefficients from one flight.

    Parameters
    ----------
    flight : FlightData or path
        The flight, or a flight file to read.
    model : str, path or ErrorModel, optional
        Model name (``"platform36"``), model file, or model object.
    method : {"ols", "rls", "rels", "ridge", "bounded", "pcr", "map", "gls"}, optional
        Estimator: :func:`~casep.solve_ols`, :func:`~casep.solve_rls` (``rels`` with
        `noise_order`), :func:`~casep.solve_ridge`, :func:`~casep.solve_bounded`,
        :func:`~casep.solve_pcr`, :func:`~casep.solve_map`, :func:`~casep.solve_gls`
        (Gauss-Markov noise of correlation time `tau`, "auto" = REML).
    sigma : float, optional
        Known noise standard deviation, m/s (default: estimated).
    p0, weight, forgetting, noise_order
        RLS/RELS options (``noise_order`` only for ``rels``; default 1).
    lam : float or {"gcv", "lcurve"}
        Ridge parameter or rule.
    bounds : mapping or path
        Required for ``bounded``: ``{name: [lo, hi] | value}``, natural units (or its JSON file).
    prior : mapping or path
        Required for ``map``: ``{name: {"mean": m, "std": s}}``, natural units (or its JSON file).
    n_components, max_condition_index
        PCR truncation.
    denoise : {None, "none", "wavelet"}, optional
        De-noise dv per axis before estimation (:func:`casep.analysis.denoise.denoise`).
    wavelet_options : mapping, optional
        Keyword arguments of :func:`casep.analysis.denoise.denoise` (wavelet, level, rule, mode,
        extension, scaling).

    Notes
    -----
    After de-noising, the residuals no longer measure the noise (thresholding removes most
    of it from dv but not from the estimate), so unless `sigma` is given the std use the
    noise sigma the wavelet transform estimates from the raw finest details (RMS over the
    axes). The result records the de-noising settings and the per-axis sigma.

    Returns
    -------
    EstimateResult
    """
    # One rule table (casep.registry): an option the method does not take is an error, not ignored.
    given = {k: v for k, v in (("p0", p0), ("weight", weight), ("forgetting", forgetting),
                               ("noise_order", noise_order), ("lam", lam), ("bounds", bounds), ("prior", prior),
                               ("n_components", n_components), ("tau", tau)) if v != OPTIONS[k].default}
    check_method_options(method, given)
    # A bounds or prior table may be given as its JSON file (as on the command line).
    if isinstance(bounds, (str, os.PathLike)):
        bounds = read_json_table(bounds, "bounds")
    if isinstance(prior, (str, os.PathLike)):
        prior = read_json_table(prior, "prior")
    if not isinstance(flight, FlightData):
        flight = read_flight(flight)
    model = load_model(model)
    S, dv, t = regression_rows(flight, model)
    den, sigma_from_wavelet = None, False
    if denoise not in (None, "none", "wavelet"):
        raise ValueError(f"`denoise` must be 'none' or 'wavelet', got {denoise!r}")
    if denoise == "wavelet":
        den = wavelet_denoise(dv, **dict(wavelet_options or {}))
        dv = den.dv
        if sigma is None:
            sigma = float(np.sqrt(np.mean(den.sigma**2)))  # raw-noise sigma, not post-de-noising residuals
            sigma_from_wavelet = True
    elif wavelet_options:
        raise ValueError("`wavelet_options` given without `denoise='wavelet'`")
    labels = {"names": model.names, "units": model.units, "si_factors": model.si_factors, "sigma": sigma}
    if method == "rels" and (isinstance(noise_order, bool) or not isinstance(noise_order, int) or noise_order < 1):
        raise ValueError(f"`noise_order` must be an int >= 1 for method `rels`, got {noise_order!r}")
    options = {"p0": p0, "weight": weight, "forgetting": forgetting, "noise_order": noise_order, "lam": lam,
               "bounds": bounds, "prior": prior, "n_components": n_components, "tau": tau}
    if method == "pcr":
        labels["max_condition_index"] = max_condition_index
    res = run_method(method, S, dv, t, {k: v for k, v in options.items() if k in _REGISTRY[method].options},
                     **labels)
    obs = flight.observed  # the raw dv, t and f of the rows the estimate used
    check_fit(S, flight.dv[obs], res, t=t, f=flight.f[obs], source=flight.source)  # noise-free, outliers, time offset
    if den is not None:
        settings = dict(res.settings)
        if sigma_from_wavelet:
            settings["sigma"] = f"wavelet estimate {sigma:.6g}"
        res = dataclasses.replace(res, denoise=den.to_dict(), settings=settings)
    return dataclasses.replace(res, model=model.name, n_samples=flight.n_observed)
