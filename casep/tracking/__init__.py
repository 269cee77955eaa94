"""Tracking-system errors in the same estimate: radar stations, their measurements and biases.

Layer 2 (beside :mod:`casep.analysis`): imports the model layer, :mod:`casep.io`,
:mod:`casep.frames` and :mod:`casep.analysis`; the workflows run the estimators on what it builds.

- :mod:`casep.tracking.stations`: station files (JSON, pydantic) and measurement files
- :mod:`casep.tracking.geometry`: the predicted measurement h(r, v) and H = dh/d(r, v) (CasADi)
- :mod:`casep.tracking.telemetry`: telemetry files and their interpolation to the radar times
- :mod:`casep.tracking.regression`: the joint measurement-domain regression [-H S_P | T]
- :mod:`casep.tracking.groups`: noise std per station and measurement type
- :mod:`casep.tracking.linearised`: the regression at its final linearisation point, its residual checks
- :mod:`casep.tracking.diagnostics`: CRLB with tracking terms fixed and free, mixed
  near-dependencies, the gain of each station
"""

from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy: `import casep.tracking` loads neither CasADi nor pydantic.
__getattr__, __dir__ = attach(__name__, {
    "casep.tracking.stations": ("Station", "RadarMeasurements", "read_station", "read_radar", "RadianAnglesWarning",
                                "MEASUREMENT_TYPES", "RADAR_COLUMNS"),
    "casep.tracking.geometry": ("RadarGeometry", "wrap_angle", "GEOMETRY_COLUMNS"),
    "casep.tracking.telemetry": ("Telemetry", "read_telemetry"),
    "casep.tracking.groups": ("estimate_group_sigmas",),
    "casep.tracking.linearised": ("TYPE_UNITS",),
    "casep.tracking.regression": ("RadarRegression", "FIRST_RANGE_LIMIT", "RadarCoverageWarning",
                                  "RadarConvergenceWarning", "RadarResidualWarning"),
    "casep.tracking.diagnostics": ("radar_diagnostics", "diagnostics_table"),
}, globals())

__all__ = ["Station", "RadarMeasurements", "read_station", "read_radar", "RadianAnglesWarning", "MEASUREMENT_TYPES",
           "RADAR_COLUMNS", "RadarGeometry", "wrap_angle", "GEOMETRY_COLUMNS", "Telemetry", "read_telemetry",
           "RadarRegression", "estimate_group_sigmas", "FIRST_RANGE_LIMIT", "TYPE_UNITS", "RadarCoverageWarning",
           "RadarConvergenceWarning", "radar_diagnostics", "diagnostics_table"]
