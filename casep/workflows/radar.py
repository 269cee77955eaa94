"""Separation in the measurement domain: telemetry + radar stations -> instrument and station errors.

:func:`separate_radar` reads the inputs, builds the joint regression
(:class:`casep.tracking.regression.RadarRegression`: relinearised, group noise estimated), hands
it to any registered estimator as a whitened :class:`~casep.analysis.problem.Problem`, and
returns a :class:`RadarResult`: the :class:`~casep.estimators.result.EstimateResult` over the
instrument coefficients and the station terms ``<station>.<term>``, plus the radar summary
(noise per station and type, residual RMS per group, how the telemetered position was had) and,
unless asked not to, the diagnostics of :mod:`casep.tracking.diagnostics`.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from casep.estimators.pcr import DEFAULT_MAX_CONDITION_INDEX
from casep.estimators.registry import METHODS, OPTIONS, check_method_options
from casep.estimators.result import EstimateResult
from casep.frames import LaunchSite
from casep.model.loader import load_model
from casep.model.tracking import load_tracking_model
from casep.tracking.diagnostics import diagnostics_table, radar_diagnostics
from casep.tracking.regression import (
    TYPE_UNITS,
    LinearisedRadar,
    RadarRegression,
    RadarResidualWarning,
    Telemetry,
    read_telemetry,
)
from casep.tracking.stations import RadarMeasurements, Station, read_radar, read_station

__all__ = ["RadarResult", "separate_radar", "diagnose_radar", "read_radar_inputs", "simulate_radar_files",
           "radar_simulation_outputs", "NOT_WITH_RADAR", "check_radar_options"]

#: Keywords of :func:`casep.separate` that do not apply with radar inputs: name -> (the flag of
#: ``casep separate``, the test that the value asks for something). The radar rows have their own
#: noise (white per station and measurement type, given in the station files or estimated), a fit
#: of their own (relinearised) and their own time-tag term (the tracking model's ``time_bias``).
NOT_WITH_RADAR: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "denoise": ("--denoise wavelet", lambda v: v not in (None, "none")),
    "wavelet_options": ("--wavelet, --level, --threshold-rule, --threshold-mode, --extension, --noise-scaling",
                        bool),
    "outliers": ("--outliers", lambda v: v is not None),
    "exclude_outliers": ("--exclude-outliers", lambda v: v is not None),
    "robust": ("--robust", lambda v: v not in (None, "auto", "none")),
    "std": ("--std hac", lambda v: v not in (None, "model")),
    "noise": ("--noise gm / gmw", lambda v: v in ("gm", "gmw")),
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
            raise ValueError(f"{what} is not available with {'--radar' if cli else '`radar`'} (noise: white per "
                             "station and measurement type, sigma_range/sigma_angle in the station files, else "
                             "estimated; a time-tag error is the tracking model's time_bias); leave it out")
    for flag, value in dict(outputs or {}).items():
        if value:
            raise ValueError(f"{flag} is not available with --radar (the radar result writes --json and --report); "
                             "leave it out")


@dataclass(frozen=True)
class RadarResult:
    """The joint estimate and what goes with it."""

    result: EstimateResult
    linearised: LinearisedRadar
    summary: dict
    diagnostics: dict | None = None

    def to_dict(self) -> dict[str, Any]:
        """The result JSON with a ``radar`` section (``diagnostics.tracking_terms`` lists the station terms)."""
        d = self.result.to_dict()
        d["radar"] = {**self.summary, **({"diagnostics": self.diagnostics} if self.diagnostics else {})}
        return d

    def text(self) -> str:
        """What ``casep separate --radar`` prints: :meth:`table`."""
        return self.table()

    def table(self) -> str:
        """The result table, the noise and residuals per station and type, and the diagnostics."""
        from casep.estimators.result import format_number

        res = self.result
        base = res.table().replace(f"sigma {res.sigma:.4g} m/s", f"noise scale {res.sigma:.4g} (1: as estimated "
                                                                   "per group)").split("\n")
        w = max(12, *(len(n) for n in res.names))  # station terms are longer than instrument names
        rows = [f"{'coefficient':<{w}} {'unit':<10} {'estimate':>12} {'std':>12}  note"]
        for r in res.coefficient_rows():
            rows.append(f"{r['name']:<{w}} {r['unit']:<10} {format_number(r['estimate'])} "
                        f"{format_number(r['std'])}  {r.get('reason', '')}".rstrip())
        lines = [*rows, *base[base.index(""):],
                 "", f"telemetered position: {self.summary['telemetry_position']}",
                 f"linearisation: {len(self.summary['gauss_newton_steps'])} Gauss-Newton steps, last change "
                 f"{self.summary['gauss_newton_steps'][-1]:.2g} std"]
        lines.append("residual RMS: " + ", ".join(f"{k} {v:.4g} {TYPE_UNITS[k.split('.', 1)[1]][0]}"
                                                  for k, v in self.summary["residual_rms"].items()))
        if self.diagnostics:
            lines += ["", diagnostics_table(self.diagnostics)]
        return "\n".join(lines)

    @property
    def tracking_names(self) -> tuple[str, ...]:
        return tuple(self.summary["tracking_terms"])


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


def _inputs(telemetry, radars, model, tracking, site):
    if not isinstance(site, LaunchSite):
        raise ValueError("`site` (--launch-site LAT LON H AZ --launch-time T0) is required: it ties the "
                         "launch-inertial frame of the telemetry to the stations on the Earth")
    meas = read_radar_inputs(radars)  # station files first: the smallest inputs, the likeliest mistakes
    model = load_model(model)
    tracking = load_tracking_model(tracking)
    tel = telemetry if isinstance(telemetry, Telemetry) else read_telemetry(telemetry, site)
    return RadarRegression(tel, meas, model, tracking, site)


def separate_radar(telemetry: Telemetry | str | os.PathLike, radars: Sequence, site: LaunchSite,
                   model: Any = "platform36", tracking: Any = "radar_biases", method: str = "ols", *,
                   sigma: Mapping | None = None, options: Mapping | None = None,
                   diagnostics: bool = True) -> RadarResult:
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
        ``{(station, type): std}`` known noise, SI (m, rad, m/s); also read from the station
        files. The others are estimated per station and type.
    options : mapping, optional
        The method's options (``bounds``, ``prior`` with ``S1.range_bias``-style names, ...).
    diagnostics : bool
        Add the CRLB fixed/free, mixed groups and station gains (:mod:`casep.tracking.diagnostics`).
    """
    reg = _inputs(telemetry, radars, model, tracking, site)
    opts = dict(options or {})
    for k in opts:
        if k not in OPTIONS:
            raise ValueError(f"`options` has unknown option `{k}`; the options are {', '.join(OPTIONS)}")
    check_method_options(method, opts)
    if METHODS[method].needs_time and len(reg.stations) > 1:
        raise ValueError(f"--method {method} uses the sample times (one time series per axis); with several stations "
                         "the rows of different stations share times. Use: --method ols (white noise per station "
                         "and type), or one station")
    lin = reg.solve(sigma)
    pb = lin.estimation_problem()
    all_given = bool(lin.sigma_given.all())
    res = METHODS[method].solve(pb, sigma=1.0 if all_given else None, **opts)  # options checked above
    x = np.where(np.isfinite(res.estimate), res.estimate, 0.0)
    tracking_terms = list(reg.names[reg.nD:])
    summary = {
        "stations": [{**s.meas.station.to_dict(), "file": s.meas.source, "station_file": s.meas.station.source,
                      "n_samples": int(s.t.size), "types": list(s.types)} for s in reg.stations],
        "launch_site": reg.site.to_dict(), "telemetry": reg.telemetry.source,
        "telemetry_position": reg.telemetry.r_source, "instrument_model": reg.model.name,
        "tracking_model": reg.tracking.name, "tracking_terms": tracking_terms,
        "noise": lin.noise_table(), "residual_rms": lin.group_residual_rms(x),
        "gauss_newton_steps": [float(v) for v in lin.history],
        "noise_scale": float(res.sigma),
    }
    failed = [] if lin.converged else [lin.convergence_message]
    # residuals and station terms are checked at a converged linearisation only (else already failed)
    bad, suspicious = lin.residual_check(x) if lin.converged else ([], [])
    if bad:
        failed.append("radar residuals far above the noise: " + "; ".join(bad))
    big, large = _tracking_magnitude_check(reg, res) if lin.converged else ([], [])
    if big:
        failed.append("station terms far above their declared magnitudes: " + "; ".join(big))
    suspicious += large
    if suspicious:
        warnings.warn("radar residuals or station terms larger than expected: " + "; ".join(suspicious),
                      RadarResidualWarning, stacklevel=2)
    if failed:  # a probably wrong result is never a plain success
        res = dataclasses.replace(res, success=False, status=-1, message="; ".join(failed))
    res = dataclasses.replace(
        res, residuals=np.empty((0, 3)), stored_residual_rms=dict.fromkeys("xyz"),
        diagnostics={**res.diagnostics, "tracking_terms": tracking_terms, "tracking_model": reg.tracking.name},
        settings={**res.settings, "noise": "white per station and type, "
                  + ("given" if all_given else "estimated (REML-type iteration)")})
    diag = radar_diagnostics(lin, scales={**reg.model.scales, **{
        f"{s.meas.station.name}.{k}": v for s in reg.stations for k, v in reg.tracking.scales.items()}}) \
        if diagnostics else None
    return RadarResult(res, lin, summary, diag)


#: A station term estimated, by more than 3 std, above this many times its declared magnitude (the
#: tracking model's scale) fails the result: a time scale or station position that is wrong, not a
#: bias (10 times: a warning).
TERM_FAIL_RATIO, TERM_WARN_RATIO = 100.0, 10.0


def _tracking_magnitude_check(reg: RadarRegression, res: EstimateResult) -> tuple[list[str], list[str]]:
    """Station terms against the tracking model's declared magnitudes: ``(failures, warnings)``."""
    fail: list[str] = []
    warn: list[str] = []
    scales = reg.tracking.scales
    for j, name in enumerate(reg.names[reg.nD:], start=reg.nD):
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
                                                         "--launch-time)" if term == "time_bias" else ""))
            (fail if low > TERM_FAIL_RATIO else warn).append(txt)
    return fail, warn


def diagnose_radar(telemetry, radars: Sequence, site: LaunchSite, model: Any = "platform36",
                   tracking: Any = "radar_biases", *, sigma: Mapping | None = None) -> dict[str, Any]:
    """The diagnostics of :mod:`casep.tracking.diagnostics` for these inputs (noise estimated when not given)."""
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
    from casep.simulation.radar import simulate_radar, write_radar_simulation
    from casep.tracking.stations import Station

    stations = [s if isinstance(s, Station) else read_station(s) for s in stations]
    if truth is not None and isinstance(truth.get("coefficients"), dict):
        truth = truth["coefficients"]
    sim = simulate_radar(stations, site, truth=truth, tracking_truth=tracking_truth, **options)
    return sim, write_radar_simulation(sim, output)
