"""Radar station errors in the same estimate: radar stations, their measurements and biases.

Layer 5 (above :mod:`casep.checks`): imports the model layer, :mod:`casep.io`, :mod:`casep.frames`,
:mod:`casep.regression` and :mod:`casep.checks` (the Cramer-Rao bound); the workflows run the
estimators on what it builds.

- :mod:`casep.radar.stations`: station files (JSON, pydantic) and measurement files
- :mod:`casep.radar.geometry`: the predicted measurement h(r, v) and H = dh/d(r, v) (CasADi)
- :mod:`casep.radar.telemetry`: telemetry files and their interpolation to the radar times
- :mod:`casep.radar.regression`: the joint measurement-domain regression [-H S_P | T]
- :mod:`casep.radar.groups`: noise std per station and measurement type
- :mod:`casep.radar.linearised`: the regression at its final linearisation point, its residual checks
- :mod:`casep.radar.diagnostics`: CRLB with tracking terms fixed and free, mixed
  near-dependencies, the gain of each station
- :mod:`casep.radar.setup`: which set-up error the residuals point to (launch time, a station's
  position, its time tags), each tested by the chi-square it explains
"""

from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy: `import casep.radar` loads neither CasADi nor pydantic.
__getattr__, __dir__ = attach(__name__, {
    "casep.radar.stations": ("Station", "RadarMeasurements", "read_station", "read_radar", "RadianAnglesWarning",
                             "MEASUREMENT_TYPES", "RADAR_COLUMNS"),
    "casep.radar.geometry": ("RadarGeometry", "wrap_angle", "GEOMETRY_COLUMNS"),
    "casep.radar.telemetry": ("Telemetry", "read_telemetry"),
    "casep.radar.groups": ("estimate_group_sigmas",),
    "casep.radar.linearised": ("TYPE_UNITS",),
    "casep.radar.regression": ("RadarRegression", "FIRST_RANGE_LIMIT", "RadarCoverageWarning",
                               "RadarConvergenceWarning", "RadarResidualWarning"),
    "casep.radar.diagnostics": ("radar_diagnostics", "diagnostics_table"),
    "casep.radar.setup": ("check_setup",),
}, globals())

__all__ = ["Station", "RadarMeasurements", "read_station", "read_radar", "RadianAnglesWarning", "MEASUREMENT_TYPES",
           "RADAR_COLUMNS", "RadarGeometry", "wrap_angle", "GEOMETRY_COLUMNS", "Telemetry", "read_telemetry",
           "RadarRegression", "estimate_group_sigmas", "FIRST_RANGE_LIMIT", "TYPE_UNITS", "RadarCoverageWarning",
           "RadarConvergenceWarning", "radar_diagnostics", "diagnostics_table", "check_setup"]
