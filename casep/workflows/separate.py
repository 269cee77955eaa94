"""The end-to-end job: flight -> model -> S_V -> estimator -> result."""

from __future__ import annotations

import dataclasses
import functools
import os
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence, TypeVar

import numpy as np

from casep.checks.flight import flight_problem
from casep.estimators.registry import METHODS as _REGISTRY
from casep.estimators.result import EstimateResult
from casep.estimators.solve import fit
from casep.estimators.spec import NOT_GIVEN, FitSpec, NotGiven
from casep.io.files import read_flight, read_json_table
from casep.io.flight import FlightData
from casep.model.error_model import ErrorModel
from casep.model.loader import load_model
from casep.regression.linearisation import LINEAR_OFFSET_SHARE, MAX_REPAIRS
from casep.regression.problem import Problem
from casep.workflows.judging import judge_setup, judge_tracking

if TYPE_CHECKING:
    from casep.frames import LaunchSite
    from casep.workflows.radar import RadarResult

__all__ = ["separate", "regression_rows", "judge_setup", "judge_tracking"]  # and METHODS (module __getattr__)

_T = TypeVar("_T")


def __getattr__(name: str) -> Any:
    # METHODS: the estimators available through separate() and ``casep separate --method``, the registry's as
    # it is now (a method registered at run time included)
    if name == "METHODS":
        return tuple(_REGISTRY)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def regression_rows(flight: FlightData, model: ErrorModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The regression of a flight as arrays: ``(S_V, dv, t)`` at the observed samples.

    The :class:`~casep.regression.problem.Problem` of the flight with S_V kept whole, after the checks
    before estimation (:func:`~casep.checks.flight.flight_problem`). Prefer the Problem itself: it need
    not hold S_V.
    """
    pb = flight_problem(flight, model, keep_sv=True)
    assert pb.t is not None  # a flight's problem has its times
    return pb.sv(), pb._need_rows(), pb.t


def separate(
    flight: FlightData | Problem | str | os.PathLike,
    model: str | os.PathLike | ErrorModel = "platform36",
    method: str | NotGiven = NOT_GIVEN,
    *,
    sigma: Any = NOT_GIVEN,
    p0: float | NotGiven = NOT_GIVEN,
    weight: float | NotGiven = NOT_GIVEN,
    forgetting: float | NotGiven = NOT_GIVEN,
    noise_order: int | NotGiven = NOT_GIVEN,
    lam: float | str | NotGiven = NOT_GIVEN,
    bounds: Mapping | str | os.PathLike | None | NotGiven = NOT_GIVEN,
    prior: Mapping | str | os.PathLike | None | NotGiven = NOT_GIVEN,
    n_components: int | None | NotGiven = NOT_GIVEN,
    max_condition_index: float | NotGiven = NOT_GIVEN,
    denoise: str | None | NotGiven = NOT_GIVEN,
    wavelet_options: Mapping | None | NotGiven = NOT_GIVEN,
    outliers: float | None | NotGiven = NOT_GIVEN,
    tau: float | str | None | NotGiven = NOT_GIVEN,
    options: Mapping | None | NotGiven = NOT_GIVEN,
    noise: str | NotGiven = NOT_GIVEN,
    robust: str | None | NotGiven = NOT_GIVEN,
    std: str | NotGiven = NOT_GIVEN,
    exclude_outliers: float | None | NotGiven = NOT_GIVEN,
    fit_time_offset: bool | None = None,
    iterate: bool | None = None,
    radar: Sequence | None = None,
    site: LaunchSite | None = None,
    tracking_model: Any = NOT_GIVEN,
    spec: FitSpec | None = None,
    **method_options: Any,
) -> EstimateResult | RadarResult:
    """Estimate a model's error coefficients from one flight.

    Parameters
    ----------
    flight : FlightData, Problem or path
        The flight, a flight file to read, or a :class:`~casep.regression.problem.Problem` built
        earlier (``casep demo`` solves every method on one; `model` is then its model). With
        `radar`: the telemetry file (``t, f_*, v_tel_*`` and optionally ``r_tel_*``) or a
        :class:`casep.radar.regression.Telemetry`.
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
        De-noise dv per axis before estimation (:func:`casep.noise.denoise.denoise`).
    wavelet_options : mapping, optional
        Keyword arguments of :func:`casep.noise.denoise.denoise` (wavelet, level, rule, mode,
        extension, scaling).
    options : mapping, optional
        The method's options by name, as an alternative to the keywords above
        (``options={"lam": 0.1}``); :data:`casep.estimators.registry.OPTIONS` lists them.
    **method_options
        Options of a registered method that are no keyword above (a method added to the registry:
        ``z_ratio=2.0``), the same as giving them in `options`.
    spec : FitSpec, optional
        The whole fit request as one value (:class:`casep.FitSpec`: method, options, sigma, noise,
        outlier flags), instead of the keywords of the fit (then an error if any is given too). The
        keywords build the same FitSpec (:meth:`casep.FitSpec.build`), checked once, then
        :func:`casep.estimators.solve.fit` runs it.

    The defaults below are those of :meth:`casep.FitSpec.build` (method ``ols``, noise ``auto``,
    robust ``auto``, std ``model``, each method option its registry default). A keyword not given is
    :data:`casep.estimators.spec.NOT_GIVEN`, never recognised by its value: an option given both as
    a keyword and in `options` is an error even when the two values equal its default.

    Notes
    -----
    After de-noising, the residuals no longer measure the noise (thresholding removes most
    of it from dv but not from the estimate), so unless `sigma` is given the std use the
    noise sigma the wavelet transform estimates from the raw finest details (RMS over the
    axes). The result records the de-noising settings and the per-axis sigma.

    outliers : float, optional
        Flag rows by their studentized residual on the whitened rows
        (:func:`casep.regression.outliers.flag_outliers`) with this chance of any false flag in a
        clean flight (e.g. 0.01); the flags go to ``diagnostics["outliers_studentized"]``.
    noise : {"auto", "gm", "gmw", "white"}, optional
        The noise model of the rows (:mod:`casep.noise.model`), for every method: ``auto``
        (default) chooses white, Gauss-Markov or Gauss-Markov plus white per axis by likelihood-ratio
        tests and says so in ``diagnostics["noise"]``; ``gm`` Gauss-Markov on every axis (correlation
        time `tau`, or REML); ``gmw`` Gauss-Markov plus white on every axis (REML); ``white`` one
        std, no correlation. Whatever the kind, a whiteness test of the whitened residuals warns
        when they are still correlated.
    tau : float, three floats or "auto", optional
        Gauss-Markov correlation time(s), s; a number implies ``noise="gm"`` (unless ``"gmw"``).
    robust : {"auto", "huber", "bisquare", "none"}, optional
        Robust fit for any method: glitches removed by a robust filter on the innovations, the
        rest weighted (:mod:`casep.regression.rows`). ``auto`` (default): Huber when the filter
        finds more glitches than Gaussian noise explains, said in ``diagnostics["robust"]``.
    std : {"model", "hac"}, optional
        ``hac``: Newey-West std (method ols with noise "white").
    exclude_outliers : float, optional
        Remove the samples flagged at this family-wise false-alarm chance and fit again (the
        removed samples in ``diagnostics["excluded"]``).
    fit_time_offset : bool, optional
        Add the tracking time offset ``dt_trk`` to the model (:func:`casep.model.loader.with_time_offset`).
        Default (:func:`casep.io.pair.fits_time_offset`): when the tracking time tags were aligned
        automatically (``read_flight_pair(..., time_offset="auto")``) or come from Earth-fixed tracking
        (``tracking_frame="ecef"`` or ``"geodetic"``: the range's clock), so that the offset between the
        two clocks is estimated with its std instead of biasing the coefficients that correlate with it.
    iterate : bool, optional
        On a strapdown telemetry pair (``q_*``, ``fb_*``, ``w_*``, ``v_tel_*`` with tracking) and a strapdown model:
        None (default) iterates (the corrected record re-navigated, S_V rebuilt, solved again:
        :mod:`casep.workflows.telemetry_iterate`) when the linear estimate's second-order remainder moves it by
        more than :data:`casep.regression.linearisation.LINEAR_OFFSET_SHARE` of its std; True iterates always;
        False keeps the linear result and warns beyond that share (failed beyond
        :data:`casep.workflows.imu_separate.FAIL_SHIFT` std). Ignored on other flights.
    radar : sequence, optional
        Radar measurements instead of tracking velocities: ``[(station, measurements), ...]``, each
        station a station JSON file or a :class:`casep.radar.stations.Station` and each measurement
        file a CSV (``t, range, azimuth, elevation``, optionally ``range_rate``), or
        :class:`casep.radar.stations.RadarMeasurements`. The instrument coefficients and every
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
        a given `sigma` far from the residual std is a warning (:func:`casep.checks.plausibility.check_sigma`).
    """
    fit_kw = {k: v for k, v in dict(
        method=method, sigma=sigma, denoise=denoise, wavelet_options=wavelet_options, outliers=outliers, tau=tau,
        options=options, noise=noise, robust=robust, std=std, exclude_outliers=exclude_outliers, p0=p0,
        weight=weight, forgetting=forgetting, noise_order=noise_order, lam=lam, bounds=bounds, prior=prior,
        n_components=n_components, max_condition_index=max_condition_index, **method_options).items()
        if v is not NOT_GIVEN}
    if spec is not None and fit_kw:
        raise ValueError(f"`spec` given with {', '.join(f'`{k}`' for k in fit_kw)}: give the fit request either as "
                         "a FitSpec or as keywords")
    if radar is not None:
        return _separate_radar(flight, model, fit_kw, radar, site,
                               "radar_biases" if tracking_model is NOT_GIVEN else tracking_model, fit_time_offset, spec)
    if site is not None or tracking_model is not NOT_GIVEN:
        raise ValueError(f"`{'site' if site is not None else 'tracking_model'}` is used only with `radar`")
    if spec is None:
        spec = FitSpec.build(**fit_kw)  # every check of the request, once
    flight, problem, model = _problem(flight, model, fit_time_offset)
    from casep.workflows.coefficients import with_tables

    spec = with_tables(spec, flight, model)
    from casep.workflows.telemetry_iterate import iterate_if_curved

    (res, problem, model, flight), caught = _recorded(lambda: _linear(flight, problem, model, spec, fit_time_offset))
    turn = (res.diagnostics.get("heading") or {}).get("test")  # the linear pass's turn about the vertical
    res, iterated = iterate_if_curved(res, flight, problem, model, spec, iterate)
    if not iterated and isinstance(flight, FlightData):
        from casep.workflows.telemetry_clock import carry_telemetry_clock

        # the telemetry clock's drift, after the IMU noise that sets the covariance anew (an iteration carries it)
        res = carry_telemetry_clock(res, flight, problem)
    if turn is not None:
        from casep.workflows.telemetry_heading import with_turn_considered

        # a turn the test did not name, on a success whose model cannot take it: in the std, linear or iterated
        res = with_turn_considered(res, turn)
    # the linear result's warnings are said with it; an iterated result says its own (the inputs' were said above)
    return res if iterated else _replayed(res, caught)


def _linear(flight: Any, problem: Problem, model: Any, spec: FitSpec,
            fit_time_offset: bool | None) -> tuple[EstimateResult, Problem, Any, Any]:
    """The fit (:func:`_fit_offset_if_found`) judged (a strapdown telemetry's dv signs and frame:
    :func:`casep.workflows.telemetry_frame.judge_frame`; :func:`judge_setup`, :func:`judge_tracking`; a failed
    strapdown telemetry's turn about the vertical: :func:`casep.workflows.telemetry_heading.judge_telemetry_heading`),
    with its model's record: the result, its problem, model and flight."""
    res, problem, model, flight = _fit_offset_if_found(flight, problem, model, spec, fit_time_offset)
    from casep.workflows.telemetry_frame import applies, judge_frame

    if applies(flight) and isinstance(model, ErrorModel):
        from casep.workflows.omitted_terms import judge_omitted

        # the richer model's terms beside the fit: before the frame's test, which takes terms the rows see beyond
        # the model for a turned attitude (strapdown15_axial on sg_y = sg_z = 1000 ppm: named 11 deg apart); a
        # pair's once the remainder's test keeps its linear result (iterate_if_curved), an iteration's on its last
        # pass (casep.workflows.imu_separate._Run.finish)
        res = judge_omitted(res, flight, problem, model)
    # a dv axis's sign, the attitude's frame: before the misfit's failure, which they explain
    res = judge_frame(res, flight, problem, spec, LOCATING_FIT)
    res = judge_setup(res, flight if isinstance(flight, FlightData) else None, model,
                      noise_free=problem.is_noise_free())
    if isinstance(flight, FlightData) and isinstance(model, ErrorModel):
        from casep.checks.tracking_quality import noise_problem
        from casep.workflows.telemetry_clock import judge_telemetry_clock
        from casep.workflows.telemetry_heading import judge_telemetry_heading, said_unless_turned

        def clocks(res: EstimateResult) -> EstimateResult:
            # a strapdown telemetry's clock, its tags and steps (carried: separate; here where the tracking's judgement
            # states combinations from this result, their std with what its covariance carries, and no later step
            # sets it anew); the tracking's on the residuals
            stated = flight.meta.get("format") == "pair" and noise_problem(flight) is not None
            res = judge_telemetry_clock(res, flight, problem, model.scales, carry=stated) or res
            return judge_tracking(res, flight, problem, model.scales)

        # the drifts' warnings wait for the turn's test: a turn's misfit reads as a clock drift
        res, drift_said = _recorded(lambda: clocks(res))
        # a strapdown telemetry turned about the vertical against its tracking: named before the failures it explains
        res = judge_telemetry_heading(res, flight, problem, model, spec, LOCATING_FIT)
        res = said_unless_turned(res, drift_said)
        from casep.workflows.judging import judge_pad_hold

        res = judge_pad_hold(res, flight, model)  # the static hold on the pad, out of the fit: its check
    if not isinstance(flight, Problem) and isinstance(model, ErrorModel):
        from casep.model.loader import model_record

        res = dataclasses.replace(res, **model_record(model))  # its file and SHA-256: read back only with that file
    return res, problem, model, flight


def _problem(flight: FlightData | Problem | str | os.PathLike, model: Any,
             fit_time_offset: bool | None) -> tuple[FlightData | Problem, Problem, Any]:
    """The flight (read if a path), its Problem (S_V integrated and reduced once, checks on the way), its model."""
    if isinstance(flight, Problem):
        if not flight.has_rows:
            raise ValueError("`flight` is a reduction-only Problem: separate needs the flight's rows")
        return flight, flight, model
    if not isinstance(flight, FlightData):
        flight = read_flight(flight)
    from casep.checks.saturation import screen_saturation
    from casep.checks.tracking_quality import screen_tracking

    # before the problem: the result is judged on what the screens found
    flight = screen_saturation(screen_tracking(flight, drift_warning=False))  # the drift: on the fit's residuals
    if fit_time_offset is None:
        from casep.io.pair import fits_time_offset

        fit_time_offset = fits_time_offset(flight.meta)
    if fit_time_offset:
        from casep.model.loader import with_time_offset

        model = with_time_offset(model)
    model = load_model(model)
    return flight, flight_problem(flight, model), model


def _fit_offset_if_found(flight: Any, problem: Problem, model: Any, spec: FitSpec,
                         fit_time_offset: bool | None) -> tuple[EstimateResult, Problem, Any, Any]:
    """:func:`fit`, and on a velocity pair whose residuals track the kinematic acceleration (the time-offset test
    of :func:`casep.checks.plausibility.check_fit`: a tracking offset, often below one tracking period, that the
    coarse alignment cannot see) the fit again with ``dt_trk`` in the model, unless the caller decided
    (`fit_time_offset` given). Modelling an offset that is not there costs one coefficient estimated near zero;
    leaving one that is there out inflates every std the offset correlates with: on the paper boost (100 Hz
    telemetry, 20 Hz tracking 30 ms late, 6 seeds) the std are about 10 times smaller with it (RMS z 0.95,
    coverage 0.97; without it 0.87 and 0.99), ``python benchmarks/mc_subperiod_offset.py --runs 6``. The result
    says so in its message. An offset beyond what the linearised ``dt_trk`` holds re-pairs the tracking there
    (:func:`repair_on_offset`). Returns the result, its problem, model and flight (re-paired or as given)."""
    from casep.model.loader import TIME_OFFSET, with_time_offset

    pair = isinstance(flight, FlightData) and not frees_steps(flight)
    box: dict[str, Any] = {"problem": problem, "model": model, "flight": flight}

    def fit_at(flights: Sequence[FlightData], quick: bool = False) -> EstimateResult:
        if TIME_OFFSET not in box["model"].names:
            box["model"] = load_model(with_time_offset(model))
        pb = flight_problem(flights[0], box["model"]) if flights[0] is not flight or box["model"] is not model \
            else problem
        if not quick:
            box["flight"], box["problem"] = flights[0], pb
        return fit(pb, LOCATING_FIT, checks=False) if quick else fit(pb, spec)

    if frees_steps(flight) and isinstance(model, ErrorModel) and TIME_OFFSET in model.names:
        res, problem, flight = _offset_fit_freeing_steps(flight, problem, model, spec)
        return res, problem, model, flight
    if not pair or not isinstance(model, ErrorModel) or (fit_time_offset is not None and not fit_time_offset):
        return fit(problem, spec), problem, model, flight
    if fit_time_offset or TIME_OFFSET in model.names:
        return repair_on_offset([flight], fit_at), box["problem"], box["model"], box["flight"]
    res = refit_on_offset(lambda: fit(problem, spec), lambda: fit_at([flight]), flights=lambda: [flight],
                          fit_at=fit_at)
    return res, box["problem"], box["model"], box["flight"]


def _offset_fit_freeing_steps(flight: FlightData, problem: Problem, model: ErrorModel,
                              spec: FitSpec) -> tuple[EstimateResult, Problem, FlightData]:
    """:func:`fit` of a one-file flight whose model has ``dt_trk``, the samples at a step of the acceleration left
    out (:func:`free_step_samples`). Returns the result, its problem and flight."""
    def fit_at(flights: Sequence[FlightData]) -> tuple[EstimateResult, Problem]:
        pb = problem if flights[0] is flight else flight_problem(flights[0], model)
        return fit(pb, spec), pb

    res, fitted_problem, fitted = free_step_samples([flight], fit_at)
    return res, fitted_problem, fitted[0]


def frees_steps(flight: Any) -> bool:
    """Whether the samples of `flight` at a step of the acceleration are left out of a fit with ``dt_trk``
    (:func:`free_step_samples`): a one-file flight (its specific force gives the kinematic acceleration); a pair
    of files is re-paired at the offset instead (:func:`repair_on_offset`)."""
    return isinstance(flight, FlightData) \
        and not (isinstance(flight.meta, dict) and flight.meta.get("format") == "pair")


def free_step_samples(flights: Sequence[Any],
                      fit_at: Callable[[Sequence[Any]], tuple[EstimateResult, _T]]
                      ) -> tuple[EstimateResult, _T, list]:
    """``fit_at(flights)`` (a model with ``dt_trk``: one per flight), with the samples whose tracking straddles a
    step of the acceleration (a burnout within one sample) at the offset found left out of each flight that
    :func:`frees_steps` (:func:`casep.checks.time_offset.step_rows`: the first-order ``a(t) dt_trk`` jumps there
    where ``v(t - dt)`` ramps, and under Gauss-Markov noise the offset is read mostly off that step), fitted again
    until they settle. The rule of one flight and of several fitted jointly.

    `fit_at` returns the result and what it was fitted on (its problem); only the last fit's warnings are said.
    Returns the result (its message naming the samples left out, ``settings["step_samples_left_out"]`` their
    indices per flight), what `fit_at` returned with it, and the flights it was fitted on.
    """
    from casep.checks.time_offset import acceleration_steps, kinematic_acceleration, step_rows

    (res, fitted_on), caught = _recorded(lambda: fit_at(flights))
    idx = _offset_columns(res.names)
    steps = [acceleration_steps(kinematic_acceleration(fl.t, fl.f)) if frees_steps(fl)
             else (np.zeros(0, dtype=int), np.zeros(0)) for fl in flights] if len(idx) == len(flights) else []
    if not any(st[0].size for st in steps):
        return _replayed(res, caught), fitted_on, list(flights)
    free = [np.zeros(0, dtype=int) for _ in flights]
    fitted = list(flights)
    for _ in range(4):  # the samples left out follow the offsets found, which follow them: a few passes settle
        if res.std is None:  # a method without std: no bound to free the samples within
            break
        dt, sd = res.estimate[idx] * res.si_factors[idx], res.std[idx] * res.si_factors[idx]
        rows = [np.zeros(0, dtype=int) if not (st[0].size and np.isfinite(d) and np.isfinite(e)) else
                (r := step_rows(fl.t, st, float(d), float(e)))[fl.observed[r]]
                for fl, st, d, e in zip(flights, steps, dt, sd)]
        if all(np.array_equal(r, f) for r, f in zip(rows, free)) or \
                any(r.size >= int(fl.observed.sum()) // 2 for r, fl in zip(rows, flights)):
            break
        free = rows
        fitted = [fl if not r.size else dataclasses.replace(fl, observed=_without(fl.observed, r))
                  for fl, r in zip(flights, rows)]
        (res, fitted_on), caught = _recorded(functools.partial(fit_at, fitted))
    said = [f"{r.size} sample(s) at a step of the acceleration left out"
            + (f" of {fl.source}" if len(flights) > 1 else "")
            + f" (t = {', '.join(f'{x:.10g}' for x in fl.t[r[:6]])}{' ...' if r.size > 6 else ''} s)"
            for fl, r in zip(flights, free) if r.size]
    if said:
        note = ("; ".join(said) + ": the first-order dt_trk term a(t) dt_trk does not hold where the tracking "
                "straddles the step")
        res = dataclasses.replace(res, message=f"{res.message}; {note}",
                                  settings={**res.settings, "step_samples_left_out": [[int(k) for k in r]
                                                                                       for r in free]})
    return _replayed(res, caught), fitted_on, fitted


def _without(observed: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """`observed` with the samples `rows` not observed."""
    out = np.array(observed, dtype=bool)
    out[rows] = False
    return out


def refit_on_offset(first: Callable[[], EstimateResult], again: Callable[[], EstimateResult],
                    wanted: Callable[[], bool] = lambda: True, *,
                    flights: Callable[[], Sequence[Any]] = lambda: (),
                    fit_at: Callable[..., EstimateResult] | None = None) -> EstimateResult:
    """The time-offset rule of one flight and of several: `first` (the fit as asked), and when its residual checks
    found a tracking time offset (the :class:`~casep.exceptions.TimeOffsetWarning` of
    :func:`casep.checks.plausibility.check_fit`) and `wanted()` after it (a pair of files, no ``dt_trk`` yet)
    `again` (the fit with ``dt_trk`` in the model), its message saying so; the first fit's warnings are said
    as they were when no offset was found. With `fit_at` (``fit_at(flights, quick=False)``: `again` on the
    flights given, `flights()` those of `again`), an offset beyond what the linearised ``dt_trk`` holds re-pairs
    the tracking there (:func:`repair_on_offset`) instead of `again`."""
    import re

    from casep.exceptions import TimeOffsetWarning

    res, caught = _recorded(first)
    found = [w for w in caught if issubclass(w.category, TimeOffsetWarning) and "would explain them" in str(w.message)]
    if not found or not wanted():
        return _replayed(res, caught)  # said as they were
    res = again() if fit_at is None else repair_on_offset(flights(), fit_at)
    said = re.search(r"time offset of (.+? ms) would", str(found[0].message))
    note = ("tracking time offset modelled (dt_trk added): the residuals of the model as given tracked the kinematic "
            f"acceleration{' (an offset of ' + said.group(1) + ')' if said else ''}")
    return dataclasses.replace(res, message=f"{res.message}; {note}",
                               settings={**res.settings, "time_offset": "modelled: found by the residual test"})


#: The fit that locates the offset before the fit as asked: least squares, white noise, no robust filter and no
#: residual checks (``fit(..., checks=False)``: the misfit of an offset not yet paired is no noise and no glitch).
LOCATING_FIT = FitSpec.build("ols", noise="white", robust="none")


def repair_on_offset(flights: Sequence[Any], fit_at: Callable[..., EstimateResult]) -> EstimateResult:
    """The fit with ``dt_trk`` (one per flight) of the flights, each pair re-formed at its estimated offset
    (:func:`casep.io.pair.repaired`) while the linearisation would not hold, until the offset settles.

    ``dt_trk`` is linear in the offset: ``v(t - dt) ~ v(t) - a dt``; the term left out, ``j dt^2 / 2``, is as
    large as an offset of ``dt^2 rms(j) / (2 rms(a))`` (:func:`casep.io.pair.offset_second_order`). Measured
    in the offset's std (noise or interpolation floor, whichever sets it) it says whether the linearisation
    holds. `fit_at(flights, quick)` fits the flights given: ``quick`` with :data:`LOCATING_FIT`, else as asked.
    The offset is located by quick fits: when that term exceeds :data:`LINEAR_OFFSET_SHARE` of the std of a
    significant offset, the tracking is re-paired at the offsets found so far (its time tags moved back by
    them) and refitted, the fit's ``dt_trk`` added, until every change is within its std or within what the
    linearisation holds (at most :data:`MAX_REPAIRS` fits; else the result fails, status
    ``STATUS_TRACKING``); then the fit as asked runs once, on the pairs found. The reported ``dt_trk`` is the
    whole offset: the shift applied plus that fit's rest.
    """
    from casep.estimators.registry import STATUS_TRACKING, failed

    can = np.array([isinstance(getattr(fl, "meta", None), dict) and "pair_inputs" in fl.meta
                    and "state_from" not in fl.meta for fl in flights])
    res = _recorded(lambda: fit_at(flights, True))[0]
    idx = _offset_columns(res.names)
    total = np.zeros(len(idx))
    steps: list[list[float]] = []
    for k in range(MAX_REPAIRS + 1):
        if len(idx) != len(flights) or res.std is None or not np.all(np.isfinite(res.estimate[idx])):
            return fit_at(flights)  # no offset to locate (the locating fit is not judged: its misfit is known)
        dt, sd = 1e-3 * res.estimate[idx], 1e-3 * res.std[idx]
        beyond = can & np.isfinite(dt) & (np.abs(dt) > sd) & _beyond_linear(flights, dt, sd)
        if k == 0 and not beyond.any():
            return fit_at(flights)
        if not beyond.any():  # every rest within its std or within what the linearisation holds
            return _repaired_fit(fit_at, flights, can, total, steps)
        if k == MAX_REPAIRS:
            break
        total = total + np.where(can, dt, 0.0)
        steps.append([float(v) for v in 1e3 * dt])
        res = _recorded(functools.partial(fit_at, _shifted(flights, total, can), True))[0]
    return failed(fit_at(flights), STATUS_TRACKING, "tracking time offset not settled: re-paired at the offset found "
                  f"{MAX_REPAIRS} times, the rest still {', '.join(f'{v:.3g}' for v in 1e3 * dt)} ms against std "
                  f"{', '.join(f'{v:.2g}' for v in 1e3 * sd)} ms (a drifting clock, or time tags that jump?)")


def _repaired_fit(fit_at: Callable[..., EstimateResult], flights: Sequence[Any], can: np.ndarray, total: np.ndarray,
                  steps: list) -> EstimateResult:
    """The fit as asked on the pairs re-formed at the offsets `total` (s), its ``dt_trk`` the whole offset."""
    from casep.model.loader import TIME_OFFSET

    res = fit_at(_shifted(flights, total, can))
    idx = _offset_columns(res.names)
    est = res.estimate.copy()
    est[idx] = est[idx] + 1e3 * total
    rec = {"passes": len(steps), "shift_ms": [float(v) for v in 1e3 * total], "steps_ms": steps}
    return dataclasses.replace(
        res, estimate=est, settings={**res.settings, "time_offset_repaired": rec},
        message=f"{res.message}; tracking re-paired at the offset found "
                f"({', '.join(f'{1e3 * v:.4g} ms' for v in total)}; {len(steps)} "
                f"pass{'es' if len(steps) > 1 else ''}): {TIME_OFFSET} is that shift plus the fit's rest")


def _offset_columns(names: Sequence[str]) -> list[int]:
    """Columns of ``dt_trk``: one flight's, or each flight's ``dt_trk[label]`` of several."""
    from casep.model.loader import TIME_OFFSET

    return [j for j, n in enumerate(names) if n == TIME_OFFSET or n.startswith(f"{TIME_OFFSET}[")]


def _shifted(flights: Sequence[Any], total: np.ndarray, can: np.ndarray) -> list:
    """The flights, each that `can` be re-paired re-formed with its tracking moved back by `total` (s)."""
    from casep.io.pair import repaired

    return [repaired(fl, s) if c else fl for fl, s, c in zip(flights, total, can)]


def _recorded(call: Callable[[], _T]) -> tuple[_T, list]:
    """`call()` with the warnings it issues recorded, not said."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = call()
    return res, list(caught)


def _replayed(res: EstimateResult, caught: list) -> EstimateResult:
    """`res`, the warnings recorded with it said as they were."""
    import warnings

    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return res


def _beyond_linear(flights: Sequence[Any], dt: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """Per flight, whether the term the linearised ``dt_trk`` = `dt` (s) leaves out, as an offset
    (:func:`casep.io.pair.offset_second_order`), exceeds :data:`LINEAR_OFFSET_SHARE` of the offset's std `sd`."""
    from casep.io.pair import offset_second_order

    return np.array([isinstance(fl, FlightData) and bool(np.isfinite(d))
                     and offset_second_order(fl, float(d)) > LINEAR_OFFSET_SHARE * s
                     for fl, d, s in zip(flights, dt, sd)], dtype=bool)


def _separate_radar(telemetry, model, fit_kw: dict, radar: Sequence, site, tracking_model,
                    fit_time_offset, spec: FitSpec | None = None) -> RadarResult:
    """:func:`separate` with radar inputs: the refusals, then :func:`casep.workflows.radar.separate_radar`.

    The request is one :class:`~casep.estimators.spec.FitSpec` (method, options, noise, tau, robust), as for a
    flight; :data:`casep.workflows.radar.NOT_WITH_RADAR` lists the keywords that do not apply to radar rows.
    """
    from casep.frames import LaunchSite
    from casep.workflows.radar import NOT_WITH_RADAR, check_radar_options, separate_radar

    check_radar_options({**{k: fit_kw.get(k) for k in NOT_WITH_RADAR}, "fit_time_offset": fit_time_offset})
    if isinstance(telemetry, (FlightData, Problem)):
        raise ValueError(f"`flight` is a {type(telemetry).__name__}: with `radar` it is the telemetry file (t, f_*, "
                         "v_tel_* and optionally r_tel_*) or a casep.radar.regression.Telemetry, since the "
                         "radar regression integrates the telemetry itself")
    if not isinstance(site, LaunchSite):
        raise ValueError("`radar` needs `site`, a casep.LaunchSite (launch point, azimuth and launch time t0 in the "
                         "radar files' time scale): it ties the telemetry's launch-inertial frame to the stations, "
                         f"got {site!r}")
    if isinstance(radar, (str, os.PathLike)) or not isinstance(radar, Sequence):
        raise ValueError(f"`radar` must be a list of (station, measurements) pairs, got {radar!r}")
    sigma = fit_kw.get("sigma", spec.sigma if spec is not None else None)
    if spec is None:
        spec = FitSpec.build(**{k: v for k, v in fit_kw.items() if k != "sigma"})  # the one check of the request
    opts = dict(spec.options)
    for k in ("bounds", "prior"):
        if isinstance(opts.get(k), (str, os.PathLike)):
            opts[k] = read_json_table(opts[k], k)
    spec = dataclasses.replace(spec, options=opts, sigma=sigma if isinstance(sigma, Mapping) else None)
    return separate_radar(telemetry, radar, site, model, tracking_model, spec=spec)
