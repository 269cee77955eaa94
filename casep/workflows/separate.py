"""The end-to-end job: flight -> model -> S_V -> estimator -> result."""

from __future__ import annotations

import dataclasses
import os
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from casep.analysis.checks import check_fit, check_sigma
from casep.analysis.denoise import denoise as wavelet_denoise
from casep.analysis.problem import Problem
from casep.estimators.pcr import DEFAULT_MAX_CONDITION_INDEX
from casep.estimators.registry import METHODS as _REGISTRY
from casep.estimators.registry import OPTIONS, check_method_options
from casep.estimators.result import EstimateResult
from casep.io.files import read_flight, read_json_table
from casep.io.flight import FlightData
from casep.model._model import ErrorModel
from casep.model.loader import load_model
from casep.workflows.solve import solve_problem

if TYPE_CHECKING:
    from casep.frames import LaunchSite
    from casep.workflows.radar import RadarResult

__all__ = ["separate", "regression_rows", "judge_setup"]  # and METHODS (module __getattr__)


def __getattr__(name: str) -> Any:
    # METHODS: the estimators available through separate() and ``casep separate --method``, the registry's as
    # it is now (a method registered at run time included)
    if name == "METHODS":
        return tuple(_REGISTRY)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def regression_rows(flight: FlightData, model: ErrorModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The regression of a flight as arrays: ``(S_V, dv, t)`` at the observed samples.

    The :class:`~casep.analysis.problem.Problem` of the flight with S_V kept whole (same checks:
    :meth:`~casep.analysis.problem.Problem.from_flight`). Prefer the Problem itself: it need
    not hold S_V.
    """
    pb = Problem.from_flight(flight, model, keep_sv=True)
    assert pb.t is not None  # a flight's problem has its times
    return pb.sv(), pb._need_rows(), pb.t


def separate(
    flight: FlightData | Problem | str | os.PathLike,
    model: str | os.PathLike | ErrorModel = "platform36",
    method: str = "ols",
    *,
    sigma: float | None = None,
    p0: float = OPTIONS["p0"].default,
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
    outliers: float | None = None,
    tau: float | str | None = "auto",
    options: Mapping | None = None,
    noise: str = "auto",
    robust: str | None = "auto",
    std: str = "model",
    exclude_outliers: float | None = None,
    fit_time_offset: bool | None = None,
    radar: Sequence | None = None,
    site: LaunchSite | None = None,
    tracking_model: Any = "radar_biases",
    **method_options: Any,
) -> EstimateResult | RadarResult:
    """Estimate a model's error coefficients from one flight.

    Parameters
    ----------
    flight : FlightData, Problem or path
        The flight, a flight file to read, or a :class:`~casep.analysis.problem.Problem` built
        earlier (``casep demo`` solves every method on one; `model` is then its model). With
        `radar`: the telemetry file (``t, f_*, v_tel_*`` and optionally ``r_tel_*``) or a
        :class:`casep.tracking.regression.Telemetry`.
    model : str, path or ErrorModel, optional
        Model name (``"platform36"``), model file, or model object.
    method : str, optional
        A registered estimator (:data:`casep.estimators.registry.METHODS`, default ``ols``):
        :func:`~casep.solve_ols`, :func:`~casep.solve_rls` (``rels`` with
        `noise_order`), :func:`~casep.solve_ridge`, :func:`~casep.solve_bounded`,
        :func:`~casep.solve_pcr`, :func:`~casep.solve_map`, :func:`~casep.solve_gls`
        (Gauss-Markov noise of correlation time `tau`, "auto" = REML), :func:`~casep.solve_huber`, or one
        registered with :func:`casep.estimators.registry.register`.
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
    options : mapping, optional
        The method's options by name, as an alternative to the keywords above
        (``options={"lam": 0.1}``); :data:`casep.estimators.registry.OPTIONS` lists them.
    **method_options
        Options of a registered method that are no keyword above (a method added to the registry:
        ``z_ratio=2.0``), the same as giving them in `options`.

    Notes
    -----
    After de-noising, the residuals no longer measure the noise (thresholding removes most
    of it from dv but not from the estimate), so unless `sigma` is given the std use the
    noise sigma the wavelet transform estimates from the raw finest details (RMS over the
    axes). The result records the de-noising settings and the per-axis sigma.

    outliers : float, optional
        Flag rows by their studentized residual on the whitened rows
        (:func:`casep.analysis.outliers.flag_outliers`) with this chance of any false flag in a
        clean flight (e.g. 0.01); the flags go to ``diagnostics["outliers_studentized"]``.
    noise : {"auto", "gm", "gmw", "white"}, optional
        The noise model of the rows (:mod:`casep.analysis.noise`), for every method: ``auto``
        (default) chooses white, Gauss-Markov or Gauss-Markov plus white per axis by likelihood-ratio
        tests and says so in ``diagnostics["noise"]``; ``gm`` Gauss-Markov on every axis (correlation
        time `tau`, or REML); ``gmw`` Gauss-Markov plus white on every axis (REML); ``white`` one
        std, no correlation. Whatever the kind, a whiteness test of the whitened residuals warns
        when they are still correlated.
    tau : float, three floats or "auto", optional
        Gauss-Markov correlation time(s), s; a number implies ``noise="gm"`` (unless ``"gmw"``).
    robust : {"auto", "huber", "bisquare", "none"}, optional
        Robust fit for any method: glitches removed by a robust filter on the innovations, the
        rest weighted (:mod:`casep.analysis.rows`). ``auto`` (default): Huber when the filter
        finds more glitches than Gaussian noise explains, said in ``diagnostics["robust"]``.
    std : {"model", "hac"}, optional
        ``hac``: Newey-West std (method ols with noise "white").
    exclude_outliers : float, optional
        Remove the samples flagged at this family-wise false-alarm chance and fit again (the
        removed samples in ``diagnostics["excluded"]``).
    fit_time_offset : bool, optional
        Add the tracking time offset ``dt_trk`` to the model (:func:`casep.model.loader.with_time_offset`).
        Default: when the tracking time tags were aligned automatically (``read_flight_pair(...,
        time_offset="auto")``), so that the alignment's error of a few ms is estimated and in the std
        instead of biasing the coefficients that correlate with it.
    radar : sequence, optional
        Radar measurements instead of tracking velocities: ``[(station, measurements), ...]``, each
        station a station JSON file or a :class:`casep.tracking.stations.Station` and each measurement
        file a CSV (``t, range, azimuth, elevation``, optionally ``range_rate``), or
        :class:`casep.tracking.stations.RadarMeasurements`. The instrument coefficients and every
        station's tracking terms are then estimated jointly by :func:`casep.separate_radar` (as
        ``casep separate TEL --radar S1.json S1.csv``). `sigma` may then be ``{(station, type): std}``
        (SI); the method options (``bounds``, ``prior``, ... and `options`) go to the method. The
        keywords that do not apply (:data:`casep.workflows.radar.NOT_WITH_RADAR`: `denoise`,
        `wavelet_options`, `outliers`, `exclude_outliers`, `robust`, ``std="hac"``, ``noise="gm"``, a
        number as `sigma`, `max_condition_index`, `fit_time_offset`) are a ValueError, as is a
        FlightData or Problem as `flight`.
    site : LaunchSite, required with `radar`
        Launch point, azimuth and launch time (``t0`` in the radar files' time scale).
    tracking_model : name, path or TrackingModel, optional
        With `radar`: the tracking model (default ``radar_biases``).

    Returns
    -------
    EstimateResult or RadarResult
        With `radar`: the :class:`casep.workflows.radar.RadarResult` of :func:`casep.separate_radar`
        (its ``result`` the EstimateResult over the instrument coefficients and the station terms
        ``<station>.<term>``, with ``summary`` and ``diagnostics``). Without: the EstimateResult, judged
        against the set-up (:func:`judge_setup`): failed with status -4 when the flight failed a set-up check
        (launch site, azimuth, launch time, time scales: ``flight.meta["setup"]``), with status -5 when
        estimates exceed 1e4 times their declared magnitudes (a warning from 100 times);
        a given `sigma` far from the residual std is a warning (:func:`casep.analysis.checks.check_sigma`).
    """
    # One rule table (casep.estimators.registry): an option the method does not take is an error, not ignored.
    kw = {"p0": p0, "weight": weight, "forgetting": forgetting, "noise_order": noise_order, "lam": lam,
          "bounds": bounds, "prior": prior, "n_components": n_components, "tau": "auto" if tau is None else tau}
    if method_options:
        if options is not None and set(options) & set(method_options):
            raise ValueError(f"option(s) {', '.join(sorted(set(options) & set(method_options)))} given both as a "
                             "keyword and in `options`")
        options = {**(options or {}), **method_options}
    for k, v in dict(options or {}).items():
        if k not in OPTIONS:
            raise ValueError(f"unknown option `{k}`: no registered method takes it; the options are "
                             f"{', '.join(OPTIONS)}")
        if k in kw and not _is_default(k, kw[k]):
            raise ValueError(f"option `{k}` given both as a keyword and in `options`")
        kw[k] = v
    if radar is not None:
        return _separate_radar(flight, model, method, kw, radar, site, tracking_model, sigma=sigma, denoise=denoise,
                               wavelet_options=wavelet_options, outliers=outliers, exclude_outliers=exclude_outliers,
                               robust=robust, std=std, noise=noise, max_condition_index=max_condition_index,
                               fit_time_offset=fit_time_offset)
    if site is not None or not _is_tracking_default(tracking_model):
        raise ValueError(f"`{'site' if site is not None else 'tracking_model'}` is used only with `radar`")
    if method not in _REGISTRY:
        raise ValueError(f"`method` must be one of {', '.join(_REGISTRY)}, got {method!r}")
    meth = _REGISTRY[method]
    # tau is the noise model's (every method); a method may also take it as its own option (gls: one tau)
    tau_given = None if isinstance(kw["tau"], str) and kw["tau"] == "auto" else kw["tau"]
    tau_is_methods = "tau" in meth.options
    if not tau_is_methods:
        kw.pop("tau")
        if tau_given is not None:
            if noise == "white":
                raise ValueError("`tau` given with noise 'white': a correlation time means noise 'gm'")
            noise = noise if noise == "gmw" else "gm"
    given = {k: v for k, v in kw.items() if v is not None and not _is_default(k, v)}
    check_method_options(method, given)  # once, here: the method takes them as checked
    # A bounds or prior table may be given as its JSON file (as on the command line).
    for k in ("bounds", "prior"):
        path = kw.get(k)
        if isinstance(path, (str, os.PathLike)):
            kw[k] = read_json_table(path, k)
            from casep.io.result_json import looks_like_result

            if k == "prior" and looks_like_result(kw[k]):  # a result file (any form): its posterior
                from casep.estimators.map import prior_from_result
                from casep.estimators.reading import read_result

                res_prior, m = read_result(path, None if isinstance(flight, Problem) else model, option="prior")
                kw[k] = prior_from_result(res_prior, model=m)
    if denoise not in (None, "none", "wavelet"):
        raise ValueError(f"`denoise` must be 'none' or 'wavelet', got {denoise!r}")
    if wavelet_options and denoise != "wavelet":
        raise ValueError("`wavelet_options` given without `denoise='wavelet'`")
    if isinstance(flight, Problem):
        problem = flight
        if not problem.has_rows:
            raise ValueError("`flight` is a reduction-only Problem: separate needs the flight's rows")
    else:
        if not isinstance(flight, FlightData):
            flight = read_flight(flight)
        align = flight.meta.get("time_alignment") if isinstance(flight.meta, dict) else None
        if fit_time_offset is None:
            fit_time_offset = isinstance(align, dict) and align.get("mode") == "auto"
        if fit_time_offset:
            from casep.model.loader import with_time_offset

            model = with_time_offset(model)
        model = load_model(model)
        problem = Problem.from_flight(flight, model)  # S_V integrated and reduced once, checks on the way
    solved, den, sigma_from_wavelet = problem, None, False
    if denoise == "wavelet":
        den = wavelet_denoise(problem._need_rows(), **dict(wavelet_options or {}))
        solved = problem.with_y(den.dv)
        if sigma is None:
            sigma = float(np.sqrt(np.mean(den.sigma**2)))  # raw-noise sigma, not post-de-noising residuals
            sigma_from_wavelet = True
    labels: dict[str, Any] = {"sigma": sigma}
    keywords = {o.name for o in meth.keywords}  # solver keywords separate passes on to the methods that take them
    if "max_condition_index" in keywords:
        labels["max_condition_index"] = meth.option("max_condition_index").check(max_condition_index)
    elif max_condition_index != DEFAULT_MAX_CONDITION_INDEX:  # given to a method that would ignore it
        takers = [k for k, m in _REGISTRY.items() if "max_condition_index" in {o.name for o in m.keywords}]
        raise ValueError(f"`max_condition_index` is not taken by method `{method}`; it is a keyword of "
                         f"{', '.join(takers)}. Use: method={takers[0]!r}, or leave it out")
    if den is not None:
        if noise in ("gm", "gmw") or robust not in (None, "auto", "none") or exclude_outliers is not None \
                or std != "model":
            raise ValueError("`denoise='wavelet'` removes the noise a noise model, a robust fit or HAC std describe: "
                             "use them without de-noising")
        noise, robust = "white", None  # the de-noised residuals are no noise sample to fit a model on
    out = solve_problem(solved, method, {k: v for k, v in kw.items() if k in meth.options},
                        noise=noise, tau=None if tau_is_methods else tau_given, robust=robust, std=std,
                        exclude_outliers=exclude_outliers, check_white=den is None, **labels)
    res = out.result
    # raw dv: noise-free, outliers, offset
    check_fit(problem, problem._need_rows(), res, t=problem.t, f=problem.f, source=problem.source,  # type: ignore[arg-type]
              outliers_handled="robust" in res.diagnostics or exclude_outliers is not None)
    if sigma is not None and not sigma_from_wavelet:
        check_sigma(problem, sigma, source=problem.source)  # the given sigma against the residuals
    res = judge_setup(res, flight if isinstance(flight, FlightData) else None, model, noise_free=_noise_free(problem))
    if outliers is not None:  # studentized residuals on the rows the method solved (whitened), samples named
        from casep.analysis.outliers import flag_outliers

        flags = flag_outliers(out.problem, alpha=outliers)
        res = dataclasses.replace(res, diagnostics={**res.diagnostics, "outliers_studentized": flags.to_dict()})
    if den is not None:
        settings = dict(res.settings)
        if sigma_from_wavelet:
            settings["sigma"] = "estimated"  # none given: the wavelet's estimate is res.sigma (sigma_source)
        res = dataclasses.replace(res, denoise=den.to_dict(), settings=settings,
                                  sigma_source="wavelet" if sigma_from_wavelet else res.sigma_source)
    if not isinstance(flight, Problem) and isinstance(model, ErrorModel):
        from casep.model.loader import model_file_reference

        ref = model_file_reference(model)  # a model loaded from a path: impact/fuse find it again
        if ref:
            res = dataclasses.replace(res, model_file=ref)
    return res


def _is_tracking_default(value) -> bool:
    return isinstance(value, str) and value == "radar_biases"


def _separate_radar(telemetry, model, method: str, kw: dict, radar: Sequence, site, tracking_model, *,
                    sigma, **refused) -> RadarResult:
    """:func:`separate` with radar inputs: the refusals, then :func:`casep.workflows.radar.separate_radar`."""
    from casep.frames import LaunchSite
    from casep.workflows.radar import check_radar_options, separate_radar

    check_radar_options({"sigma": sigma, **refused})
    if isinstance(telemetry, (FlightData, Problem)):
        raise ValueError(f"`flight` is a {type(telemetry).__name__}: with `radar` it is the telemetry file (t, f_*, "
                         "v_tel_* and optionally r_tel_*) or a casep.tracking.regression.Telemetry, since the "
                         "radar regression integrates the telemetry itself")
    if not isinstance(site, LaunchSite):
        raise ValueError("`radar` needs `site`, a casep.LaunchSite (launch point, azimuth and launch time t0 in the "
                         "radar files' time scale): it ties the telemetry's launch-inertial frame to the stations, "
                         f"got {site!r}")
    if isinstance(radar, (str, os.PathLike)) or not isinstance(radar, Sequence):
        raise ValueError(f"`radar` must be a list of (station, measurements) pairs, got {radar!r}")
    # the method's options as the caller set them; the method refuses the ones it does not take
    opts = {k: v for k, v in kw.items() if v is not None and not _is_default(k, v)}
    for k in ("bounds", "prior"):
        if isinstance(opts.get(k), (str, os.PathLike)):
            opts[k] = read_json_table(opts[k], k)
    return separate_radar(telemetry, radar, site, model, tracking_model, method,
                          sigma=sigma if isinstance(sigma, Mapping) else None, options=opts)


def _is_default(name: str, value) -> bool:
    try:
        return bool(value == OPTIONS[name].default)
    except (TypeError, ValueError):  # e.g. a mapping or an array: given
        return False


def _noise_free(problem: Problem) -> bool:
    """Least-squares residual std at the rounding level of dv (:data:`casep.analysis.checks.NOISE_FREE`)."""
    from casep.analysis.checks import NOISE_FREE

    if problem.y is None:
        return False
    dof = max(problem.m - problem.rank().rank, 1)
    return float(np.sqrt(problem.ls_rss() / dof)) <= NOISE_FREE * float(np.max(np.abs(problem.y)))


def judge_setup(res: EstimateResult, flight: FlightData | None, model, *, noise_free: bool = False) -> EstimateResult:
    """A result judged against the set-up: failed (status -4) when its flight failed a set-up check
    (:func:`casep.analysis.checks.setup_problems`: launch site, azimuth, launch time, time scales), and against
    the model's declared magnitudes (:func:`casep.estimators._base.check_magnitudes`), except on noise-free
    data (`noise_free`), where every std is rounding and a biased method's estimate is its bias, not a
    set-up mistake (check_fit's NoiseFreeWarning says so)."""
    from casep.analysis.checks import setup_problems
    from casep.estimators._base import STATUS_SETUP, check_magnitudes, failed

    problems = setup_problems(flight) if flight is not None else []
    if flight is not None and problems:
        res = failed(res, STATUS_SETUP, f"failed: set-up check of {flight.source}: " + "; ".join(problems))
    if isinstance(model, ErrorModel) and model.name == res.model and not noise_free:
        meth = _REGISTRY.get(res.method)
        res = check_magnitudes(res, model.scales, source=flight.source if flight is not None else "",
                               regularised=meth is not None and meth.regularised)
    return res
