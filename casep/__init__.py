"""casep: guidance instrumentation error separation for a platform inertial navigation system.

The difference between telemetered and tracked velocity, ``dv = v_tel - v_trk``, is
explained as a linear function of instrument error coefficients ``D``:
``dv(t) = S_V(t) D``. casep builds ``S_V`` exactly from a symbolic error model (CasADi),
estimates ``D``, says how well each coefficient can be known and shows it.

Conventions
-----------
Frames
    Platform frame = launch-inertial frame of the stabilised platform: x downrange
    (horizontal at launch), y up (local vertical at launch), z completes the right-handed
    triad (cross-range).
Inputs
    ``t`` in s (strictly increasing, need not be uniform); specific force ``f`` in m/s^2
    (what accelerometers sense: gravity is not in it); ``dv`` in m/s, telemetry minus
    tracking, used as given (never re-referenced to its first sample). Where tracking is
    absent (before it starts) dv is NaN and ``FlightData.observed`` is False: S_V is
    integrated from the first telemetry sample, the regression uses the observed rows.
Error model
    Inside the error equations the specific force is in g: ``W = f / G0``,
    ``G0 = 9.80665`` m/s^2. Platform drift ``phi(t) = phi0 + int phidot dt``; specific-force
    error ``dWdot = [f x] phi + Delta`` with
    ``[f x] = [[0, -f_z, f_y], [f_z, 0, -f_x], [-f_y, f_x, 0]]`` (i.e. ``f x phi``);
    ``dv = dv0 + int dWdot dt``.
Units
    SI inside every computation (rad, rad/s, m/s^2, m/s). Coefficients are declared,
    reported and read in natural units (deg/h, deg/h/g, mg, mg/g, ug/g, ug/g^2, arcsec):
    see :mod:`casep.units`. ``S_V`` columns are per natural unit.
Arrays
    A flight's ``S_V`` is ``(N, 3, n)``: sample, axis (x, y, z), coefficient in model order;
    ``S.reshape(3 * N, n)`` is the stacked regression with rows x, y, z per sample.
Column names (flight files)
    ``t, f_x, f_y, f_z`` and ``dv_x, dv_y, dv_z`` (or ``v_tel_x/y/z`` and ``v_trk_x/y/z``).

Main entry points
-----------------
:func:`load_model`, :func:`build_sv`, :func:`read_flight`, a flight's regression :class:`Problem`
(:func:`flight_problem`: built after the checks before estimation), the estimators
:func:`solve_ols`, :func:`solve_rls` (RLS/RELS), :func:`solve_ridge`, :func:`solve_bounded`,
:func:`solve_pcr`, :func:`solve_map`, :func:`solve_gls` (all returning :class:`EstimateResult`),
:func:`separate`; the impact miss of an estimate :func:`impact_analysis`
(:mod:`casep.impact`); the manoeuvre that would determine more coefficients
:func:`casep.design.design` (:mod:`casep.design`, ``casep design``); the checks :func:`check_flight` (before)
and :func:`check_fit` (after an estimate), whose warnings are :class:`CasepWarning` subclasses;
the command line ``casep`` (:mod:`casep.cli`).
"""

from casep._lazy import attach
from casep._version import __version__

# The public names are imported on first use (PEP 562), so that ``import casep.cli`` (and
# ``casep --help``) does not pay for CasADi, numba and SciPy: module -> names it provides.
_LAZY_MODULES: dict[str, tuple[str, ...]] = {
    "casep.io.flight": ("FlightData", "FlightDataError", "LateStartWarning"),
    "casep.io.files": ("apparent_velocity_to_force", "read_flight", "read_flight_pair", "write_flight"),
    "casep.regression.linalg": ("ReducedSystem", "analyze_rank", "reduce_qr"),
    "casep.regression.problem": ("Problem",),
    "casep.model.error_model": ("ErrorModel", "ModelDefinitionError"),
    "casep.model.loader": ("available_models", "build_model", "load_model", "model_dirs"),
    "casep.estimators.bounded": ("solve_bounded",),
    "casep.estimators.gls": ("solve_gls",),
    "casep.estimators.huber": ("solve_huber",),
    "casep.estimators.map": ("solve_map", "prior_from_result"),
    "casep.estimators.ols": ("solve_ols",),
    "casep.estimators.pcr": ("solve_pcr",),
    "casep.estimators.ridge": ("solve_ridge",),
    "casep.estimators.rls": ("solve_rls",),
    "casep.estimators.result": ("EstimateResult",),
    "casep.workflows.separate": ("separate",),
    "casep.estimators.spec": ("FitSpec", "NoiseSpec"),
    "casep.estimators.solve": ("fit",),
    "casep.workflows.flights": ("separate_flights", "diagnose_flights", "flights_summary"),
    "casep.workflows.fusion": ("fuse",),
    "casep.model.sv": ("SVBuilder", "build_sv"),
    "casep.units": ("G0",),
    "casep.impact.miss": ("ImpactAnalysis", "impact_analysis"),
    "casep.checks.plausibility": ("check_fit", "check_flight"),
    "casep.checks.flight": ("flight_problem",),
    "casep.frames": ("LaunchSite",),
    "casep.workflows.manifest": ("read_manifest", "Manifest"),
    "casep.calibration.calibrate": ("calibrate",),
    "casep.model.tracking": ("TrackingModel", "load_tracking_model", "build_tracking_model"),
    "casep.radar.stations": ("Station", "read_station", "read_radar"),
    "casep.workflows.radar": ("separate_radar", "diagnose_radar"),
    "casep.exceptions": ("CasepWarning", "IllConditionedWarning", "NoiseFreeWarning", "OutlierWarning",
                         "PlausibilityWarning", "TimeOffsetWarning", "SetupWarning", "MagnitudeWarning",
                         "NoiseLevelWarning", "ConsistencyWarning"),
}
__getattr__, __dir__ = attach(__name__, _LAZY_MODULES, globals(), (
    "noise", "regression", "checks", "analysis", "estimators", "io", "model", "reporting", "simulation", "workflows",
    "cli", "exceptions", "units", "impact", "design", "frames", "calibration", "radar"))

__all__ = [
    "__version__",
    "G0",
    "ErrorModel",
    "ModelDefinitionError",
    "build_model",
    "load_model",
    "available_models",
    "model_dirs",
    "SVBuilder",
    "build_sv",
    "FlightData",
    "FlightDataError",
    "read_flight",
    "write_flight",
    "read_flight_pair",
    "apparent_velocity_to_force",
    "Problem",
    "flight_problem",
    "ReducedSystem",
    "reduce_qr",
    "analyze_rank",
    "solve_ols",
    "solve_rls",
    "solve_ridge",
    "solve_bounded",
    "solve_pcr",
    "solve_map",
    "solve_gls",
    "solve_huber",
    "EstimateResult",
    "separate",
    "FitSpec",
    "NoiseSpec",
    "fit",
    "separate_flights",
    "diagnose_flights",
    "flights_summary",
    "fuse",
    "prior_from_result",
    "impact_analysis",
    "ImpactAnalysis",
    "check_flight",
    "check_fit",
    "CasepWarning",
    "IllConditionedWarning",
    "PlausibilityWarning",
    "TimeOffsetWarning",
    "ConsistencyWarning",
    "OutlierWarning",
    "NoiseFreeWarning",
    "LateStartWarning",
    "LaunchSite",
    "read_manifest",
    "Manifest",
    "SetupWarning",
    "MagnitudeWarning",
    "NoiseLevelWarning",
    "calibrate",
    "TrackingModel",
    "load_tracking_model",
    "build_tracking_model",
    "Station",
    "read_station",
    "read_radar",
    "separate_radar",
    "diagnose_radar",
]
