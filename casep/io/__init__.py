"""Flight data in and out: the validated :class:`FlightData`, flight files, atomic writing.

Depends only on :mod:`casep.exceptions`, :mod:`casep.units` and :mod:`casep.frames`.

- :mod:`casep.io.flight`: :class:`FlightData` (validated arrays, observed-row mask)
- :mod:`casep.io.files`: CSV/Parquet flight files, telemetry + tracking pairs (reading, writing)
- :mod:`casep.io.tables`: a file's columns (CSV separators, Parquet), errors naming file, column, row
- :mod:`casep.io.pair`: a telemetry + tracking pair in arrays (tracking frames, time scales, gaps)
- :mod:`casep.io.setup`: the set-up evidence of Earth-fixed tracking, measured when it is read
- :mod:`casep.io.locate`: the file row and line of a flight's samples, for messages
- :mod:`casep.io.trajectory`: a trajectory file for the impact analysis
- :mod:`casep.io._atomic`: output checks and all-or-nothing file writing
- :mod:`casep.io.result_json`: result files (casep's and other tools'), read strictly (pydantic)
"""

from casep._lazy import attach

# The public names are imported on first use (PEP 562): ``casep.io._atomic`` (every command's file writing, the
# demo's figure worker) does not import the flight files' readers.
__getattr__, __dir__ = attach(__name__, {
    "casep.io.files": ("apparent_velocity_to_force", "read_flight", "read_flight_pair", "write_flight"),
    "casep.io.flight": ("FlightData", "FlightDataError", "LateStartWarning"),
}, globals())

__all__ = ["FlightData", "FlightDataError", "LateStartWarning", "read_flight", "read_flight_pair",
           "write_flight", "apparent_velocity_to_force"]
