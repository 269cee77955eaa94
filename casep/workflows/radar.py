"""Separation in the measurement domain: telemetry + radar stations -> instrument and station errors.

:func:`separate_radar` reads the inputs, builds the joint regression
(:class:`casep.radar.regression.RadarRegression`: relinearised, group noise estimated), hands
it to any registered estimator as a whitened :class:`~casep.regression.problem.Problem`, and
returns a :class:`RadarResult`: the :class:`~casep.estimators.result.EstimateResult` over the
instrument coefficients and the station terms ``<station>.<term>``, plus the radar summary
(noise per station and type, residual RMS per group, how the telemetered position was had) and,
unless asked not to, the diagnostics of :mod:`casep.radar.diagnostics`.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from casep.estimators.pcr import DEFAULT_MAX_CONDITION_INDEX
from casep.estimators.registry import (
    METHODS,
    STATUS_MAGNITUDE,
    STATUS_MISFIT,
    STATUS_NOT_CONVERGED,
    STATUS_SETUP,
)
from casep.estimators.registry import failed as mark_failed
from casep.estimators.result import EstimateResult
from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.frames import LaunchSite
from casep.model.loader import load_model
from casep.model.tracking import load_tracking_model
from casep.radar.diagnostics import diagnostics_table, radar_diagnostics
from casep.radar.regression import (
    KEYHOLE,
    LAUNCH_TIME,
    LAUNCH_TIME_SCALE,
    TYPE_UNITS,
    LinearisedRadar,
    RadarRegression,
    RadarResidualWarning,
    Telemetry,
    read_telemetry,
)
from casep.radar.setup import check_setup
from casep.radar.stations import RadarMeasurements, Station, read_radar, read_station
from casep.results import OfEstimate, deprecated_alias
from casep.workflows.radar_noise import RadarNoise, fit_radar_noise

__all__ = ["RadarResult", "separate_radar", "diagnose_radar", "read_radar_inputs", "simulate_radar_files",
           "radar_simulation_outputs", "NOT_WITH_RADAR", "check_radar_options", "check_radar_spec"]

#: Keywords of :func:`casep.separate` that do not apply with radar inputs: name -> (the flag of
#: ``casep separate``, the test that the value asks for something). The radar rows take the noise layer
#: of the velocity domain (``noise``, ``tau``, ``robust``: :mod:`casep.workflows.radar_noise`), per station and
#: measurement type; these others have no meaning there: the rows are no velocity (de-noising, a sigma in
#: m/s), the time-tag error is the tracking model's ``time_bias`` and the launch time the common ``dt_launch``.
NOT_WITH_RADAR: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "denoise": ("--denoise wavelet", lambda v: v not in (None, "none")),
    "wavelet_options": ("--wavelet, --level, --threshold-rule, --threshold-mode, --extension, --noise-scaling",
                        bool),
    "outliers": ("--outliers", lambda v: v is not None),
    "exclude_outliers": ("--exclude-outliers", lambda v: v is not None),
    "std": ("--std hac", lambda v: v not in (None, "model")),
    # a number is the std of the telemetry-minus-tracking velocity, m/s; the radar's is per station and type
    "sigma": ("--sigma", lambda v: v is not None and not isinstance(v, Mapping)),
    "max_condition_index": ("--max-condition-index", lambda v: v is not None and v != DEFAULT_MAX_CONDITION_INDEX),
    "fit_time_offset": ("--fit-time-offset", bool),
}


def check_radar_options(given: Mapping[str, Any], *, cli: bool = False,
                        outputs: Mapping[str, Any] | None = None) -> None:
    """Refuse the options of :func:`casep.separate` that do not apply with radar inputs.

    Parameters
    ----------
    given : mapping
        Keyword of :func:`casep.separate` (a :data:`NOT_WITH_RADAR` key) -> the value the caller has.
    cli : bool
        Name the command-line flag in the error instead of the keyword.
    outputs : mapping, optional
        ``{flag: value}`` of outputs the radar result does not write (the command line's).

    Raises
    ------
    ValueError
        Naming the first option given, and why it does not apply.
    """
    for name, value in given.items():
        flag, asks = NOT_WITH_RADAR[name]
        if asks(value):
            what = flag if cli else f"`{name}={value!r}`"
            raise ValueError(f"{what} is not available with {'--radar' if cli else '`radar`'} (the radar rows take the "
                             "noise model per station and measurement type: --noise, --tau, --robust; "
                             "sigma_range/sigma_angle in the station files give it as white; a time-tag error is the "
                             "tracking model's time_bias, a launch-time error the common dt_launch); leave it out")
    for flag, value in dict(outputs or {}).items():
        if value:
            raise ValueError(f"{flag} is not available with --radar (the radar result writes --json and --report); "
                             "leave it out")


def check_radar_spec(spec: FitSpec) -> None:
    """Refuse a fit request that asks what radar rows do not take (:data:`NOT_WITH_RADAR`, from the request)."""
    ns = spec.noise
    check_radar_options({"denoise": ns.denoise, "wavelet_options": dict(ns.wavelet_options), "outliers": spec.outliers,
                         "exclude_outliers": ns.exclude_outliers, "std": ns.std, "sigma": spec.sigma,
                         "max_condition_index": spec.keywords.get("max_condition_index")})


@dataclass(frozen=True)
class RadarResult(OfEstimate):
    """The joint estimate and what goes with it; the result protocol of :mod:`casep.results`.

    ``success``, ``status`` and ``message`` are the joint estimate's (a linearisation that did
    not converge, residuals far above the noise, a wrong station position or station terms far
    beyond their magnitudes make it a failure, with the status of the first of them in the status table,
    :data:`casep.estimators.registry.FAILURE_STATUSES`); :meth:`text` is what the command line prints,
    :meth:`to_dict` the result JSON with a ``radar`` section and the ``provenance``.
    """

    result: EstimateResult
    linearised: LinearisedRadar
    summary: dict
    diagnostics: dict | None = None
    provenance: dict | None = None

    def to_dict(self) -> dict[str, Any]:
        """The result JSON with a ``radar`` section (``diagnostics.tracking_terms`` lists the station terms)
        and, when the inputs were files, the ``provenance`` (their SHA-256)."""
        d = self.result.to_dict()
        d["radar"] = {**self.summary, **({"diagnostics": self.diagnostics} if self.diagnostics else {})}
        if self.provenance:
            d["provenance"] = self.provenance
        return d

    def text(self) -> str:
        """What ``casep separate --radar`` prints: the coefficients, the fit, the noise and residuals per
        station and type, the set-up estimate, the outcome and the diagnostics."""
        from casep.estimators.result import format_number

        res, s = self.result, self.summary
        w = max(12, *(len(n) for n in res.names))  # station terms are longer than instrument names
        lines = [f"{'coefficient':<{w}} {'unit':<10} {'estimate':>12} {'std':>12}  note"]
        for r in res.coefficient_rows():
            lines.append(f"{r['name']:<{w}} {r['unit']:<10} {format_number(r['estimate'])} "
                         f"{format_number(r['std'])}  {r.get('reason', '')}".rstrip())
        n_rows = sum(g["n"] for g in s["noise"])
        given = all(g["source"] == "given" for g in s["noise"])
        lines += ["", f"method {res.method}, model {res.model} + {s['tracking_model']} per station, "
                      f"{len(s['stations'])} station(s), {n_rows} radar measurements, rank {res.rank}/{len(res.names)}",
                  f"noise: {s.get('noise_asked', 'white')} per station and type, "
                  f"{'given' if given else 'estimated per group'}; rows whitened by it, common scale "
                  f"{s['noise_scale']:.4g} (dimensionless: 1 when the noise models are right); std {res.std_kind}",
                  "noise: " + ", ".join(_group_noise_text(g) for g in s["noise"]),
                  "residual RMS: " + ", ".join(f"{k} {v:.4g} {TYPE_UNITS[k.split('.', 1)[1]][0]}"
                                               for k, v in s["residual_rms"].items()),
                  f"telemetered position: {s['telemetry_position']}",
                  f"linearisation: {len(s['gauss_newton_steps'])} Gauss-Newton steps, last change "
                  f"{s['gauss_newton_steps'][-1]:.2g} std"]
        lt = (s.get("setup") or {}).get("launch_time")
        alias = (s.get("setup") or {}).get("aliased")
        if alias:
            from casep.radar.setup import alias_text

            lines.append(alias_text(alias))
        if lt:
            lines.append(f"launch time: correction {lt['estimate_ms']:.4g} +- {lt['std_ms']:.2g} ms to --launch-time "
                         f"{s['launch_site']['t0']:.10g} s (estimated with the other terms)")
        lines.append(("" if self.success else "FAILED: ") + self.message)
        if self.diagnostics:
            lines += ["", diagnostics_table(self.diagnostics)]
        return "\n".join(lines)

    table = deprecated_alias("text", "table")

    @property
    def tracking_names(self) -> tuple[str, ...]:
        return tuple(self.summary["tracking_terms"])

    @property
    def scales(self) -> dict[str, float]:
        """The declared magnitude of every coefficient (instrument, station terms, launch time), natural units."""
        return dict(self.summary["declared_magnitudes"])


def _group_noise_text(g: Mapping[str, Any]) -> str:
    """One group's noise for the console: ``S1.range GM tau 1.1 s 2.9 + white 1.2 m (estimated, reml)``."""
    u = g["unit"]
    what = {"white": f"white {g['sigma']:.4g} {u}", "gm": f"GM tau {g.get('tau_s', 0):.3g} s {g['sigma']:.4g} {u}",
            "gmw": f"GM tau {g.get('tau_s', 0):.3g} s {g.get('sigma_gm', 0):.4g} + white {g.get('sigma_white', 0):.4g} "
                   f"{u}"}[g.get("kind", "white")]
    return f"{g['station']}.{g['type']} {what} ({g['source']})"


def read_radar_inputs(pairs: Sequence) -> list[RadarMeasurements]:
    """``[(station.json or Station, measurements.csv), ...]`` (or RadarMeasurements) -> measurements, stations read."""
    out = []
    for p in pairs:
        if isinstance(p, RadarMeasurements):
            out.append(p)
            continue
        if not isinstance(p, (tuple, list)) or len(p) != 2:
            raise ValueError(f"each radar input must be (station.json, measurements.csv), got {p!r}")
        out.append(read_radar(p[1], p[0] if isinstance(p[0], Station) else read_station(p[0])))
    return out


def _inputs(telemetry, radars, model, tracking, site, fit_launch_time: bool | None = None):
    if not isinstance(site, LaunchSite):
        raise ValueError("`site` (--launch-site LAT LON H AZ --launch-time T0) is required: it ties the "
                         "launch-inertial frame of the telemetry to the stations on the Earth")
    meas = read_radar_inputs(radars)  # station files first: the smallest inputs, the likeliest mistakes
    model = load_model(model)
    tracking = load_tracking_model(tracking)
    tel = telemetry if isinstance(telemetry, Telemetry) else read_telemetry(telemetry, site)
    return RadarRegression(tel, meas, model, tracking, site,
                           fit_launch_time=len(meas) > 1 if fit_launch_time is None else bool(fit_launch_time))


def separate_radar(telemetry: Telemetry | str | os.PathLike, radars: Sequence, site: LaunchSite,
                   model: Any = "platform36", tracking: Any = "radar_biases", method: str = "ols", *,
                   sigma: Mapping | None = None, options: Mapping | None = None, noise: str = "auto", tau: Any = None,
                   robust: str | None = "auto", spec: FitSpec | None = None,
                   diagnostics: bool = True, fit_launch_time: bool | None = None) -> RadarResult:
    """Estimate the instrument coefficients and every station's tracking terms jointly.

    Parameters
    ----------
    telemetry : Telemetry or path
        ``t, f_* (or W_*), v_tel_*`` and optionally ``r_tel_*`` (launch-inertial).
    radars : sequence
        ``(station.json, measurements.csv)`` pairs or :class:`RadarMeasurements`.
    site : LaunchSite
        Launch point, azimuth and launch time (``t0`` in the radar files' time scale).
    model, tracking : name, path or model
        Instrument model (``platform36``) and tracking model (``radar_biases``).
    method : str
        Any registered estimator; ``gls`` only with one station (it whitens one time series).
    sigma : mapping, optional
        ``{(station, type): std}`` known noise, SI (m, rad, m/s): white; also read from the station
        files. The others are estimated per station and type.
    options : mapping, optional
        The method's options (``bounds``, ``prior`` with ``S1.range_bias``-style names, ...).
    noise, tau, robust
        The noise model per station and measurement type and the robust fit, as for a flight
        (:class:`~casep.estimators.spec.NoiseSpec`; :mod:`casep.workflows.radar_noise`): ``auto`` (default) chooses
        white, Gauss-Markov or Gauss-Markov plus white per station and type by REML; ``tau`` one
        correlation time or three (range, azimuth, elevation), s.
    spec : FitSpec, optional
        The whole request instead of `method`, `sigma`, `options`, `noise`, `tau`, `robust`.
    diagnostics : bool
        Add the CRLB fixed/free, mixed groups and station gains (:mod:`casep.radar.diagnostics`).
    fit_launch_time : bool, optional
        Estimate the launch-time correction ``dt_launch`` (ms) with the other terms (see
        :class:`casep.radar.regression.RadarRegression`). Default: with two stations or more. One
        station alone cannot tell it from its own time-tag term: with a ``time_bias`` in the tracking
        model the two are one combination (said in the result, with its numbers:
        :func:`casep.radar.setup.launch_time_alias`); without one, ``dt_launch`` is estimated.
        The fit also says which set-up error the residuals point to (:func:`casep.radar.setup.check_setup`).
    """
    if spec is None:
        spec = FitSpec.build(method, options=options, sigma=sigma, noise=noise, tau=tau, robust=robust)
    check_radar_spec(spec)
    reg = _inputs(telemetry, radars, model, tracking, site, fit_launch_time)
    if METHODS[spec.method].needs_time and len(reg.stations) > 1:
        raise ValueError(f"--method {spec.method} uses the sample times (one time series per axis); with several "
                         "stations the rows of different stations share times. Use: --method ols (the noise model "
                         "per station and type), or one station")
    reg, lin, rn, res, steps, unsettled = _at_launch_time(reg, spec)
    all_given = bool(lin.sigma_given.all())
    opts = {**dict(spec.options), **dict(spec.keywords)}
    x = res.fitted_coefficients()  # of the rows as solved (at the launch time re-solved at: dt_launch the rest)
    summary = _summary(reg, lin, rn, res, x)
    failed, suspicious = _judge(reg, lin, rn, res, summary)
    failed += [(STATUS_NOT_CONVERGED, unsettled)] if unsettled else []
    res = _with_shift(res, reg, steps)
    whiteness = rn.whiteness(x) if not failed else {}  # a failed fit's residuals hold its set-up error: said already
    if failed:  # a probably wrong result is never a plain success: the first failure's status, every message
        res = mark_failed(res, failed[0][0], "; ".join(text for _, text in failed))
    from casep.model.loader import model_record

    res = dataclasses.replace(
        res, residuals=np.empty((0, 3)), stored_residual_rms=dict.fromkeys("xyz"), sigma_source="whitened",
        **model_record(reg.model),
        # the stacked rows interleave the stations' times: their gaps are no station's (each its own noise model's)
        diagnostics={**{k: v for k, v in res.diagnostics.items() if k != "gaps"},
                     "tracking_terms": summary["tracking_terms"],
                     "tracking_model": reg.tracking.name, "noise": rn.accounts(),
                     **({"whiteness": whiteness} if whiteness else {})},
        settings={**res.settings, "noise": rn.asked + " per station and type"
                  + (", given" if all_given else ""), "robust": spec.noise.robust})
    # the CRLB rows divided by the noise the fit used: the table's noise is the `noise:` line's (one per group)
    diag = radar_diagnostics(lin, scales=_scales(reg), noise=summary["noise"]) if diagnostics else None
    return RadarResult(res, lin, summary, diag, _provenance(telemetry, radars, reg, spec.method, opts))


def _fit_rows(reg: RadarRegression, spec: FitSpec) -> tuple[LinearisedRadar, RadarNoise, EstimateResult]:
    """The regression linearised, its noise model fitted and the whitened rows fitted as `spec` asks."""
    lin = reg.solve(spec.sigma)
    rn = fit_radar_noise(lin, spec)
    # the whitened rows through the one entry point of every fit; the radar's own checks follow (_judge)
    res = fit(rn.problem(), rn.fit_spec(spec, 1.0 if bool(lin.sigma_given.all()) else None), checks=False)
    return lin, rn, res


def _at_launch_time(reg: RadarRegression, spec: FitSpec
                    ) -> tuple[RadarRegression, LinearisedRadar, RadarNoise, EstimateResult, list[float], str]:
    """The fit, re-solved at the launch time it finds while the linear ``dt_launch`` would not hold:
    ``(reg, lin, rn, res, steps, unsettled)``, ``steps`` the corrections taken into the geometry (ms).

    The rule of the tracking time offset (:mod:`casep.regression.linearisation`, as
    :func:`casep.workflows.separate.repair_on_offset`): a correction beyond its std whose left-out second-order
    term moves an estimate by more than :data:`~casep.regression.linearisation.LINEAR_OFFSET_SHARE` of its std
    (:func:`casep.radar.setup.launch_time_nonlinearity`) is taken into the geometry
    (:meth:`RadarRegression.at_launch_shift`) and the regression solved again, until every rest is within
    its std or within what the linearisation holds (at most :data:`~casep.regression.linearisation.MAX_REPAIRS`
    re-solves; else `unsettled` says so and the result fails). :func:`_with_shift` then reports the whole
    correction.
    """
    from casep.radar.setup import launch_time_nonlinearity
    from casep.regression.linearisation import LINEAR_OFFSET_SHARE, MAX_REPAIRS

    lin, rn, res = _fit_rows(reg, spec)
    steps: list[float] = []
    if LAUNCH_TIME not in reg.names or res.std is None:
        return reg, lin, rn, res, steps, ""
    j = reg.names.index(LAUNCH_TIME)
    for k in range(MAX_REPAIRS + 1):
        dt, sd = float(res.estimate[j]), float(res.std[j])  # ms
        if not (np.isfinite(dt) and lin.converged and abs(dt) > sd
                and launch_time_nonlinearity(lin, rn.whiten, dt) > LINEAR_OFFSET_SHARE):
            break
        if k == MAX_REPAIRS:
            return reg, lin, rn, res, steps, (
                f"launch time not settled: re-solved at the correction found {MAX_REPAIRS} times, the rest still "
                f"{dt:.3g} ms against std {sd:.2g} ms and beyond what the linear {LAUNCH_TIME} holds")
        steps.append(dt)
        reg = reg.at_launch_shift(reg.launch_shift + 1e-3 * dt)
        lin, rn, res = _fit_rows(reg, spec)
    return reg, lin, rn, res, steps, ""


def _with_shift(res: EstimateResult, reg: RadarRegression, steps: list[float]) -> EstimateResult:
    """`res` with its ``dt_launch`` the whole correction: the shift its rows carry (``reg.launch_shift``) plus the
    fit's rest, with the fit's std; the re-solves (`steps`, ms) recorded in ``settings`` and the message."""
    if not steps:
        return res
    shift = 1e3 * reg.launch_shift
    est = res.estimate.copy()
    est[reg.names.index(LAUNCH_TIME)] += shift
    rec = {"passes": len(steps), "shift_ms": shift, "steps_ms": [float(v) for v in steps]}
    return dataclasses.replace(
        res, estimate=est, settings={**res.settings, "launch_time_resolved": rec},
        message=f"{res.message}; the geometry re-solved at the launch-time correction found ({shift:.4g} ms; "
                f"{len(steps)} pass{'es' if len(steps) > 1 else ''}): {LAUNCH_TIME} is that shift plus the fit's rest")


def _summary(reg: RadarRegression, lin: LinearisedRadar, rn: RadarNoise, res: EstimateResult,
             x: np.ndarray) -> dict[str, Any]:
    """The radar section of the result: stations, site, models, noise per group, residuals, linearisation."""
    return {
        "stations": [{**s.meas.station.to_dict(), "file": s.meas.source, "station_file": s.meas.station.source,
                      "n_samples": int(s.t.size), "types": list(s.types)} for s in reg.stations],
        "launch_site": reg.site.to_dict(), "telemetry": reg.telemetry.source,
        "telemetry_position": reg.telemetry.r_source, "instrument_model": reg.model.name,
        "tracking_model": reg.tracking.name, "tracking_terms": list(reg.names[reg.nD:]),
        "noise": rn.group_records(), "noise_asked": rn.asked, "residual_rms": lin.group_residual_rms(x),
        "gauss_newton_steps": [float(v) for v in lin.history],
        "noise_scale": float(res.sigma), "declared_magnitudes": _scales(reg),
        "keyhole": {"elevation_deg": float(np.degrees(KEYHOLE)), "azimuth_left_out": reg.keyhole_counts},
    }


def _judge(reg: RadarRegression, lin: LinearisedRadar, rn: RadarNoise, res: EstimateResult,
           summary: dict) -> tuple[list[tuple[int, str]], list[str]]:
    """``(failures, warnings)`` of a radar fit: the linearisation, the set-up (launch time, station positions,
    whitened by the noise model), the residuals against the noise, the station terms against their
    magnitudes; the set-up warnings are issued here, the others returned. Each failure with its status of the
    status table (:data:`casep.estimators.registry.FAILURE_STATUSES`): a linearisation that did not converge
    ``STATUS_NOT_CONVERGED``, a set-up error ``STATUS_SETUP``, residuals far above the noise ``STATUS_MISFIT``,
    station terms far above their magnitudes ``STATUS_MAGNITUDE``."""
    x = res.fitted_coefficients()
    setup = check_setup(lin, rn.whiten) if lin.converged else None
    failed = [] if lin.converged else [(STATUS_NOT_CONVERGED, lin.convergence_message)]
    if setup:  # a set-up error named first: it explains the misfits the other checks see
        failed += [(STATUS_SETUP, f) for f in setup["failures"]]
    # residuals and station terms are checked at a converged linearisation only (else already failed)
    bad, suspicious = lin.residual_check(x) if lin.converged else ([], [])
    if bad:
        failed.append((STATUS_MISFIT, "radar residuals far above the noise: " + "; ".join(bad)))
    # station terms are judged against their magnitudes only when no station position is wrong (they absorb it)
    big, large = _tracking_magnitude_check(reg, res, (setup or {}).get("aliased")) if lin.converged and not failed \
        else ([], [])
    if big:
        failed.append((STATUS_MAGNITUDE, "station terms far above their declared magnitudes: " + "; ".join(big)))
    suspicious += large
    if setup:
        summary["setup"] = {k: setup[k] for k in ("launch_time", "stations", "aliased") if k in setup}
        if setup["warnings"]:
            warnings.warn("radar set-up: " + "; ".join(setup["warnings"]), RadarResidualWarning, stacklevel=3)
    if suspicious:
        warnings.warn("radar residuals or station terms larger than expected: " + "; ".join(suspicious),
                      RadarResidualWarning, stacklevel=3)
    return failed, suspicious


def _scales(reg: RadarRegression) -> dict[str, float]:
    """Declared magnitudes of the regression's coefficients: the models', per station, and the launch time's."""
    out = {**reg.model.scales, **{f"{s.meas.station.name}.{k}": v for s in reg.stations
                                  for k, v in reg.tracking.scales.items()}}
    return {**out, **({LAUNCH_TIME: LAUNCH_TIME_SCALE} if LAUNCH_TIME in reg.names else {})}


def _provenance(telemetry, radars: Sequence, reg: RadarRegression, method: str, options: Mapping) -> dict:
    """:func:`casep.io.provenance.provenance` of a radar separation: the telemetry, station and measurement
    files read (with their SHA-256; objects given in memory have none), the models and the options."""
    from casep.io.provenance import provenance

    inputs: dict[str, Any] = {"telemetry": telemetry if isinstance(telemetry, (str, os.PathLike)) else None}
    for k, p in enumerate(radars):
        if isinstance(p, (tuple, list)) and len(p) == 2:
            inputs[f"station {k + 1}"] = p[0] if isinstance(p[0], (str, os.PathLike)) else None
            inputs[f"radar measurements {k + 1}"] = p[1] if isinstance(p[1], (str, os.PathLike)) else None
    for role, m in (("model", reg.model), ("tracking model", reg.tracking)):
        inputs[role] = getattr(m, "source_file", None)
    opts = {"method": method, "model": reg.model.name, "tracking_model": reg.tracking.name,
            "launch_site": reg.site.to_dict(), "fit_launch_time": LAUNCH_TIME in reg.names,
            **{k: v for k, v in options.items() if isinstance(v, (int, float, str, bool))}}
    return provenance([], inputs=inputs, options=opts)


#: A station term estimated, by more than 3 std, above this many times its declared magnitude (the
#: tracking model's scale) fails the result: a time scale or station position that is wrong, not a
#: bias (10 times: a warning).
TERM_FAIL_RATIO, TERM_WARN_RATIO = 100.0, 10.0


def _tracking_magnitude_check(reg: RadarRegression, res: EstimateResult,
                              alias: Mapping | None = None) -> tuple[list[str], list[str]]:
    """Station terms against the tracking model's declared magnitudes: ``(failures, warnings)``; with one
    station (`alias`: :func:`casep.radar.setup.launch_time_alias`) a term the launch time moves says how many
    ms of launch-time error would explain it."""
    per_ms = dict((alias or {}).get("absorbed_per_ms", {}))
    fail: list[str] = []
    warn: list[str] = []
    scales = reg.tracking.scales
    for j, name in enumerate(reg.names[reg.nD:], start=reg.nD):
        if "." not in name:  # a term shared by the stations (the launch time): judged by check_setup
            continue
        term = name.split(".", 1)[1]
        est = float(res.estimate[j])
        std = float(res.std[j]) if res.std is not None else float("nan")
        if term not in scales or not np.isfinite(est) or scales[term] <= 0:
            continue
        ratio = abs(est) / scales[term]
        low = (abs(est) - 3.0 * (std if np.isfinite(std) else np.inf)) / scales[term]  # |est| - 3 std, in scales
        if low > TERM_WARN_RATIO:
            txt = (f"{name} = {est:.4g} +- {std:.2g} {res.units[j]} is {ratio:.3g} times its declared magnitude "
                   f"{scales[term]:g} {res.units[j]}" + (" (time tags off: check the radar time scale and "
                                                         "--launch-time)" if term == "time_bias" else "")
                   + (f" (or a launch time {-est / per_ms[name]:+.4g} ms off: with one station it moves {name} by "
                      f"{per_ms[name]:+.3g} {res.units[j]} per ms; check --launch-time)" if per_ms.get(name) else ""))
            (fail if low > TERM_FAIL_RATIO else warn).append(txt)
    return fail, warn


def diagnose_radar(telemetry, radars: Sequence, site: LaunchSite, model: Any = "platform36",
                   tracking: Any = "radar_biases", *, sigma: Mapping | None = None) -> dict[str, Any]:
    """The diagnostics of :mod:`casep.radar.diagnostics` for these inputs (noise estimated when not given)."""
    reg = _inputs(telemetry, radars, model, tracking, site)
    lin = reg.solve(sigma)
    return radar_diagnostics(lin, scales=reg.model.scales)


def radar_simulation_outputs(output: str | os.PathLike, stations: Sequence) -> dict[str, Any]:
    """The files :func:`simulate_radar_files` writes: ``{label: path}`` (telemetry, truth, per station json/csv)."""
    from pathlib import Path

    from casep.simulation.simulate import truth_path

    out = Path(output)
    files: dict[str, Any] = {"-o": out, "-o (truth sidecar)": truth_path(out)}
    for st in stations:
        files[f"station {st.name} (json)"] = out.with_name(f"{out.stem}.{st.name}.json")
        files[f"station {st.name} (csv)"] = out.with_name(f"{out.stem}.{st.name}.csv")
    return files


def simulate_radar_files(output: str | os.PathLike, stations: Sequence, site: LaunchSite, *,
                         truth: Mapping | None = None, tracking_truth: Mapping | None = None, **options):
    """Simulate a radar-tracked flight and write it (:func:`casep.simulation.radar.write_radar_simulation`).

    Parameters
    ----------
    output : path
        The telemetry file; the stations' files and the truth go beside it.
    stations : sequence of Station or station-file paths
    site : LaunchSite
        t0 = 0 (lift-off).
    truth : mapping, optional
        Instrument truth ``{name: value}`` or a truth sidecar's dict (its ``coefficients``).
    tracking_truth : mapping, optional
        ``{station: {term: value}}``.
    **options
        :func:`casep.simulation.radar.simulate_radar`'s keywords (scenario, seed, telemetry_rate,
        radar_rate, model, noise, range_rate, tracking).

    Returns
    -------
    (RadarSimulation, list of Path)
    """
    from casep.radar.stations import Station
    from casep.simulation.radar import simulate_radar, write_radar_simulation

    stations = [s if isinstance(s, Station) else read_station(s) for s in stations]
    if truth is not None and isinstance(truth.get("coefficients"), dict):
        truth = truth["coefficients"]
    sim = simulate_radar(stations, site, truth=truth, tracking_truth=tracking_truth, **options)
    return sim, write_radar_simulation(sim, output)
