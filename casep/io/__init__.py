"""Flight data in and out: the validated :class:`FlightData`, flight files, atomic writing.

Depends only on :mod:`casep.exceptions`.

- :mod:`casep.io.flight`: :class:`FlightData` (validated arrays, observed-row mask, late start)
- :mod:`casep.io.files`: CSV/Parquet/NPZ flight files, telemetry + tracking pairs
- :mod:`casep.io._atomic`: output checks and all-or-nothing file writing
- :mod:`casep.io.manifest`: the TOML flight manifest (several flights, each with its own set-up)
- :mod:`casep.io.result_json`: result files (casep's and other tools'), read strictly (pydantic)
"""

from casep.io.files import apparent_velocity_to_force, read_flight, read_flight_pair, write_flight
from casep.io.flight import FlightData, FlightDataError, LateStartWarning

__all__ = ["FlightData", "FlightDataError", "LateStartWarning", "read_flight", "read_flight_pair",
           "write_flight", "apparent_velocity_to_force"]
