"""Radar stations and their measurement files: reading and validation.

A station is a JSON file ``{"name": "S1", "lat": deg, "lon": deg, "h": m}`` (geodetic WGS84
latitude and longitude in degrees, height above the ellipsoid in metres; optional
``"sigma_range"`` (m), ``"sigma_angle"`` (arcsec) and ``"sigma_range_rate"`` (m/s): the
measurement noise std when known). pydantic validates it (missing field, wrong type, out of
range), and the error names the file and the field.

Its measurements are a CSV or Parquet file (read by :mod:`casep.io.files`' table reader, which
names file, column and row of a bad cell) with ``t`` (s, the launch-time scale of
``--launch-time``), ``range`` (m), ``azimuth`` (deg from north, clockwise), ``elevation`` (deg
above the local horizon, the plane normal to the WGS84 ellipsoid normal at the station) and
optionally ``range_rate`` (m/s). Inside casep the angles are radians.

Legal but suspicious: station coordinates or measured angles that look like radians (every
azimuth within +-2 pi and every elevation within +-pi/2) give a :class:`RadianAnglesWarning` with
the numbers; a station whose first predicted range is more than 1 km from the first measured
one is refused later (:func:`casep.radar.regression.check_first_sample`).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from casep.exceptions import CasepWarning

__all__ = ["Station", "RadarMeasurements", "read_station", "read_radar", "RadianAnglesWarning",
           "MEASUREMENT_TYPES", "RADAR_COLUMNS"]

#: Measurement types, in the order of the rows of H and T.
MEASUREMENT_TYPES = ("range", "azimuth", "elevation", "range_rate")
#: Columns of a measurement file (range_rate optional).
RADAR_COLUMNS = ("t", "range", "azimuth", "elevation")


class RadianAnglesWarning(CasepWarning):
    """Angles that look like radians where degrees are expected: the message gives the numbers."""


@dataclass(frozen=True)
class Station:
    """A tracking station (WGS84 geodetic position) and its known noise, if any.

    Attributes
    ----------
    name : str
        Used in the coefficient names (``S1.range_bias``).
    lat_deg, lon_deg, h_m : float
    sigma : dict
        Known noise std per measurement type, SI (m, rad, m/s); a type not in it is estimated.
    source : str
        The station file (for messages).
    min_elevation_deg : float
        The station's elevation mask, deg (default 0: the horizon): it tracks nothing below it
        (the simulator drops those samples).
    """

    name: str
    lat_deg: float
    lon_deg: float
    h_m: float
    sigma: dict = field(default_factory=dict)
    source: str = "<memory>"
    min_elevation_deg: float = 0.0

    @property
    def r_ecef(self) -> np.ndarray:
        """Station position, ECEF (WGS84), m (pymap3d.geodetic2ecef)."""
        import pymap3d

        return np.array(pymap3d.geodetic2ecef(self.lat_deg, self.lon_deg, self.h_m), dtype=float)

    @property
    def enu_rows(self) -> np.ndarray:
        """ECEF -> station ENU rotation, (3, 3): rows are east, north, up in ECEF (pymap3d.enu2ecefv)."""
        import pymap3d

        rows = [pymap3d.enu2ecefv(*e, self.lat_deg, self.lon_deg) for e in np.eye(3)]
        return np.array(rows, dtype=float)

    def to_dict(self) -> dict:
        from casep.units import ARCSEC

        d = {"name": self.name, "lat": self.lat_deg, "lon": self.lon_deg, "h": self.h_m}
        if self.min_elevation_deg != 0.0:
            d["min_elevation"] = self.min_elevation_deg
        for k, v in self.sigma.items():
            d[{"range": "sigma_range", "azimuth": "sigma_angle", "elevation": "sigma_angle",
               "range_rate": "sigma_range_rate"}[k]] = v / ARCSEC if k in ("azimuth", "elevation") else v
        return d


def _station_schema() -> Any:  # the pydantic model class, built (and pydantic imported) on first use
    from pydantic import BaseModel, ConfigDict, Field, field_validator

    class StationFile(BaseModel):
        """The JSON of a station file."""

        model_config = ConfigDict(extra="forbid", strict=False)
        name: str = Field(min_length=1, max_length=40, pattern=r"^[A-Za-z][A-Za-z0-9_-]*$")
        lat: float = Field(ge=-90.0, le=90.0)
        lon: float = Field(ge=-360.0, le=360.0)
        h: float = Field(ge=-1e4, le=1e5)
        sigma_range: float | None = Field(default=None, gt=0.0, le=1e4)
        sigma_angle: float | None = Field(default=None, gt=0.0, le=3.6e4)
        sigma_range_rate: float | None = Field(default=None, gt=0.0, le=1e3)
        min_elevation: float = Field(default=0.0, ge=-10.0, lt=90.0)
        description: str = ""

        @field_validator("lat", "lon", "h", "sigma_range", "sigma_angle", "sigma_range_rate", "min_elevation")
        @classmethod
        def _finite(cls, v: float | None) -> float | None:
            if v is not None and not math.isfinite(v):
                raise ValueError("must be finite")
            return v

    return StationFile


def read_station(path: str | os.PathLike | dict, *, source: str | None = None) -> Station:
    """Read and validate a station file (or its dict).

    Raises
    ------
    ValueError
        ``<file>: field `lat`: <what>`` for a missing, mistyped or out-of-range field, or a file
        that is not JSON.
    """
    from pydantic import ValidationError

    from casep.io.result_json import load_json
    from casep.units import ARCSEC

    if isinstance(path, dict):
        data, src = path, source or "<station dict>"
    else:
        src = str(path)
        p = Path(path)
        if not p.is_file():
            raise ValueError(f"station file {src}: does not exist")
        data = load_json(p, "station file")
        if not isinstance(data, dict):
            raise ValueError(f"station file {src}: must be a JSON object "
                             '{"name": "S1", "lat": deg, "lon": deg, "h": m}')
    try:
        s = _station_schema().model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        fld = ".".join(str(x) for x in err["loc"]) or "(object)"
        what = "missing (a station needs name, lat (deg), lon (deg), h (m))" if err["type"] == "missing" \
            else f"{err['msg']} (got {err.get('input')!r})"
        raise ValueError(f"station file {src}: field `{fld}`: {what}") from None
    if 0.0 < abs(s.lat) <= math.pi / 2 and 0.0 < abs(s.lon) <= math.pi and abs(s.lat) + abs(s.lon) < 3.0:
        warnings.warn(f"station file {src}: lat {s.lat:g}, lon {s.lon:g} look like radians "
                      f"({math.degrees(s.lat):.4g} deg, {math.degrees(s.lon):.4g} deg); the file must give degrees",
                      RadianAnglesWarning, stacklevel=2)
    sigma = {}
    if s.sigma_range is not None:
        sigma["range"] = s.sigma_range
    if s.sigma_angle is not None:
        sigma["azimuth"] = sigma["elevation"] = s.sigma_angle * ARCSEC
    if s.sigma_range_rate is not None:
        sigma["range_rate"] = s.sigma_range_rate
    return Station(s.name, s.lat, s.lon, s.h, sigma, src, s.min_elevation)


@dataclass(frozen=True)
class RadarMeasurements:
    """One station's measurements, SI: t (s), range (m), azimuth, elevation (rad), range_rate (m/s) or None."""

    station: Station
    t: np.ndarray
    range: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    range_rate: np.ndarray | None = None
    source: str = "<memory>"

    def __post_init__(self) -> None:
        n = np.asarray(self.t).size
        for k in ("range", "azimuth", "elevation") + (("range_rate",) if self.range_rate is not None else ()):
            v = np.asarray(getattr(self, k), dtype=float)
            if v.shape != (n,):
                raise ValueError(f"{self.source}: `{k}` must have {n} values (one per time), got shape {v.shape}")
            object.__setattr__(self, k, v)
        object.__setattr__(self, "t", np.asarray(self.t, dtype=float))

    @property
    def types(self) -> tuple[str, ...]:
        """Measurement types present."""
        return MEASUREMENT_TYPES if self.range_rate is not None else MEASUREMENT_TYPES[:3]

    def values(self) -> np.ndarray:
        """``(N, k)`` measurements in :attr:`types` order, SI."""
        cols = [self.range, self.azimuth, self.elevation] + ([self.range_rate] if self.range_rate is not None else [])
        return np.column_stack(cols)

    @property
    def n_samples(self) -> int:
        return int(self.t.size)


def read_radar(path: str | os.PathLike, station: Station | str | os.PathLike) -> RadarMeasurements:
    """Read a station's measurement file (CSV or Parquet): ``t, range, azimuth, elevation[, range_rate]``.

    Raises
    ------
    FlightDataError
        Naming file, column and row: a missing column, a bad cell, time not increasing, a
        negative range, an elevation outside [-90, 90] deg.
    """
    from casep.io.tables import Table

    if not isinstance(station, Station):
        station = read_station(station)
    tab = Table(path)
    tab.require(RADAR_COLUMNS, ". Use: t (s), range (m), azimuth, elevation (deg), optional range_rate (m/s)")
    t = tab.time()
    rng = tab.numeric("range")
    az = tab.numeric("azimuth")
    el = tab.numeric("elevation")
    bad = np.flatnonzero(rng <= 0)
    if bad.size:
        raise tab.error(f"range {rng[bad[0]]:g} m is not positive", "range", int(bad[0]) + 1)
    bad = np.flatnonzero(np.abs(el) > 90.0)
    if bad.size:
        raise tab.error(f"elevation {el[bad[0]]:g} deg is outside [-90, 90]", "elevation", int(bad[0]) + 1)
    bad = np.flatnonzero((az < -360.0) | (az > 360.0))
    if bad.size:
        raise tab.error(f"azimuth {az[bad[0]]:g} deg is outside [-360, 360]", "azimuth", int(bad[0]) + 1)
    # radians read as degrees: every azimuth within +-2 pi and every elevation within +-pi/2 "deg" (a
    # track in degrees that stays within 6.3 deg of north and 1.6 deg of the horizon is rare)
    if t.size >= 2 and np.all(np.abs(az) <= 2 * math.pi) and np.all(np.abs(el) <= math.pi / 2):
        warnings.warn(f"{tab.src}: azimuth {az.min():.4g}..{az.max():.4g}, elevation {el.min():.4g}..{el.max():.4g} "
                      "look like radians (every value within +-2 pi and +-pi/2); the file must give degrees",
                      RadianAnglesWarning, stacklevel=2)
    rr = tab.numeric("range_rate") if "range_rate" in tab.columns else None
    return RadarMeasurements(station, t, rng, np.radians(az), np.radians(el), rr, tab.src)


def check_station_names(stations) -> None:
    """Station names must be unique (they name the coefficients)."""
    seen: dict[str, str] = {}
    for s in stations:
        if s.name in seen:
            raise ValueError(f"station name `{s.name}` used twice ({seen[s.name]} and {s.source}): "
                             "names must be unique, they name the tracking coefficients")
        seen[s.name] = s.source
