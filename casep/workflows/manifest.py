"""A flight manifest: several flights from different ranges, each with its own files and set-up.

One TOML file (read by :mod:`tomllib`, validated by pydantic) lists per flight the telemetry file,
the tracking file, the tracking frame, the launch site, the launch time and how the time scales
relate. The command-line options ``--tracking-frame``, ``--launch-site`` and ``--launch-time`` apply
to one flight; a manifest gives each flight its own, so that an ECEF flight from one range and a
geodetic flight from another are estimated together::

    # flights.toml: paths relative to this file
    [[flight]]
    label = "A"                       # optional; default: the file names
    telemetry = "a_tel.csv"           # t, f_* or W_*, v_tel_* (or a one-file flight without tracking)
    tracking = "a_trk.csv"            # optional: t and the frame's columns
    frame = "ecef"                    # launch (default) | ecef | geodetic
    site = { lat_deg = 28.5, lon_deg = -80.6, h_m = 3.0, azimuth_deg = 90.0 }
    launch_time_s = 0.0               # in the tracking file's time scale

    [[flight]]
    telemetry = "b_tel.csv"
    tracking = "b_trk.csv"
    frame = "geodetic"
    site = { lat_deg = 34.7, lon_deg = -120.6, h_m = 100.0, azimuth_deg = 190.0 }
    launch_time_s = 43200.0           # tracking in seconds of day ...
    time_shift_s = 43200.0            # ... = telemetry time (from lift-off) + 43200 s
    time_offset_ms = "auto"           # optional: tracking latency, ms, or "auto"
    clock_drift_ppm = 0.0             # optional: tracking tags late by ppm 1e-6 t more at telemetry time t
    clock_drift_std_ppm = 50.0        # optional: a strapdown telemetry's, as --clock-drift-std PPM
    grid = "tracking"                 # optional: tracking (default) | telemetry

    [fit]                             # optional: the fit request (casep.FitSpec), as casep.separate's keywords
    method = "ridge"
    options = { lam = 0.1 }           # the method's options; prior/bounds files relative to this file
    noise = "auto"                    # noise, tau, robust, sigma, ... (casep separate's options)

Who does what: :mod:`tomllib` (standard library) parses the TOML; pydantic checks the types, the
allowed values, unknown keys (a misspelt key is an error, not ignored) and the rules between keys
(a site with an Earth-fixed frame only); :func:`read_manifest` turns its errors into one
``ValueError`` naming the file, the flight and the key; :func:`casep.io.files.read_flight_pair` reads
each flight as the single-flight options would. The ``[fit]`` table, when there, is the fit request:
:meth:`casep.FitSpec.build` makes it from its keys when the manifest is read (its one check, every error
naming the manifest and the table), :meth:`Manifest.spec` returns it.
"""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator, model_validator

from casep.io.pair import MAX_CLOCK_DRIFT_PPM

__all__ = ["Manifest", "ManifestFlight", "ManifestSite", "read_manifest"]


class ManifestSite(BaseModel):
    """Launch point and azimuth (the launch time is the flight's ``launch_time_s``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    lat_deg: float = Field(ge=-89.999, le=89.999, allow_inf_nan=False)
    lon_deg: float = Field(ge=-360.0, le=360.0, allow_inf_nan=False)
    h_m: float = Field(ge=-1e4, le=1e5, allow_inf_nan=False)
    azimuth_deg: float = Field(ge=-360.0, le=360.0, allow_inf_nan=False)


class ManifestFlight(BaseModel):
    """One flight of a manifest (module notes); paths are resolved against the manifest's folder."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    telemetry: Path
    tracking: Path | None = None
    label: str | None = None
    frame: Literal["launch", "ecef", "geodetic"] = "launch"
    site: ManifestSite | None = None
    launch_time_s: float | None = Field(default=None, allow_inf_nan=False)
    time_shift_s: float = Field(default=0.0, allow_inf_nan=False)
    clock_drift_ppm: float = Field(default=0.0, ge=-MAX_CLOCK_DRIFT_PPM, le=MAX_CLOCK_DRIFT_PPM, allow_inf_nan=False)
    clock_drift_std_ppm: float | None = None  # checked below by --clock-drift-std's rule (given_clock_std)
    time_offset_ms: float | Literal["auto"] | None = None  # finite: checked below (a Field constraint would
    # apply to "auto" too)
    grid: Literal["tracking", "telemetry"] = "tracking"
    result: Path | None = None

    @field_validator("time_offset_ms")
    @classmethod
    def _offset_range(cls, v):
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"must be finite, got {v}")
        if isinstance(v, float) and abs(v) > 1e5:
            raise ValueError(f"must be within +-1e5 ms, got {v:g}")
        return v

    @field_validator("clock_drift_std_ppm")
    @classmethod
    def _clock_std(cls, v):
        if v is not None:
            from casep.workflows.imu_separate import given_clock_std

            given_clock_std(0.0, v, "the std")  # the one rule of --clock-drift-std (its default: at the separation)
        return v

    @model_validator(mode="after")
    def _rules(self) -> ManifestFlight:
        earth_fixed = self.frame != "launch"
        if earth_fixed and (self.site is None or self.launch_time_s is None):
            raise ValueError(f"frame '{self.frame}' needs `site` and `launch_time_s` (in the tracking time scale)")
        if not earth_fixed and (self.site is not None or self.launch_time_s is not None):
            raise ValueError("`site` and `launch_time_s` are used only with frame 'ecef' or 'geodetic'")
        if self.tracking is None:
            for key, given in (("frame", earth_fixed), ("time_shift_s", self.time_shift_s != 0.0),
                               ("clock_drift_ppm", self.clock_drift_ppm != 0.0),
                               ("clock_drift_std_ppm", self.clock_drift_std_ppm is not None),
                               ("time_offset_ms", self.time_offset_ms is not None),
                               ("grid", self.grid != "tracking")):
                if given:
                    raise ValueError(f"`{key}` describes a tracking file: give `tracking` too")
        return self

    def launch_site(self):
        """The :class:`casep.frames.LaunchSite` of an Earth-fixed frame, or None."""
        if self.site is None:
            return None
        from casep.frames import LaunchSite

        s = self.site
        return LaunchSite(s.lat_deg, s.lon_deg, s.h_m, s.azimuth_deg, float(self.launch_time_s))

    def read(self):
        """The flight (:class:`~casep.io.flight.FlightData`): one file, or telemetry + tracking."""
        from casep.io.files import read_flight, read_flight_pair

        if self.tracking is None:
            return read_flight(self.telemetry)
        offset = self.time_offset_ms
        kw = {"tracking_frame": self.frame, "site": self.launch_site()} if self.frame != "launch" else {}
        return read_flight_pair(self.telemetry, self.tracking, grid=self.grid, time_shift=self.time_shift_s,
                                clock_drift=self.clock_drift_ppm, clock_drift_std=self.clock_drift_std_ppm,
                                time_offset=offset if offset in (None, "auto") else offset * 1e-3, **kw)

    def to_dict(self) -> dict:
        """The entry as recorded in a result's provenance (paths as strings)."""
        return self.model_dump(mode="json", exclude_none=True)


class Manifest(BaseModel):
    """A manifest: its flights (``[[flight]]`` tables) and the file it was read from."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)
    flights: list[ManifestFlight] = Field(alias="flight", min_length=1)
    fit: dict[str, Any] | None = None  # the [fit] table: keywords of casep.FitSpec.build
    source: str = "<memory>"
    _spec: Any = PrivateAttr(default=None)

    def spec(self) -> Any:
        """The fit request of the ``[fit]`` table (a checked :class:`casep.FitSpec`), or None without one."""
        if self.fit is None:
            return None
        if self._spec is None:
            from casep.estimators.spec import FitSpec

            try:
                self._spec = FitSpec.build(**self.fit)  # the one check of a request, as for keywords and arguments
            except (ValueError, TypeError) as exc:
                raise ValueError(f"manifest {self.source}: table [fit]: {exc}") from None
        return self._spec

    def read(self) -> list:
        """Every flight, read (:meth:`ManifestFlight.read`), in manifest order."""
        return [f.read() for f in self.flights]

    @property
    def labels(self) -> list[str]:
        return [f.label or f.telemetry.name for f in self.flights]


def _where(loc: tuple) -> str:
    """``flight 2, key `site.lat_deg``` from a pydantic error location."""
    parts = list(loc)
    out = []
    if len(parts) >= 2 and parts[0] == "flight" and isinstance(parts[1], int):
        out.append(f"flight {parts[1] + 1}")
        parts = parts[2:]
    parts = [p for p in parts if not (isinstance(p, str) and ("[" in p or p.startswith("function-")))]
    if parts:
        out.append("key `" + ".".join(str(p) for p in parts) + "`")
    return ", ".join(out)


def read_manifest(path: str | os.PathLike) -> Manifest:
    """Read and check a flight manifest (TOML, module notes).

    Parameters
    ----------
    path : path
        The manifest; relative file paths in it are taken from its folder.

    Returns
    -------
    Manifest
        ``flights`` (each with :meth:`~ManifestFlight.read`), and :meth:`Manifest.read` for all.

    Raises
    ------
    ValueError
        Naming the manifest, the flight (1-based) and the key: not TOML (with the line), a missing,
        unknown or mistyped key, a value out of range, a site without an Earth-fixed frame (or the
        reverse), a file that does not exist, the same telemetry file twice.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise ValueError(f"manifest {path}: cannot read ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"manifest {path}: not valid TOML ({exc})") from None
    if "flight" not in data:
        raise ValueError(f"manifest {path}: no [[flight]] table (keys: {', '.join(data) or 'none'}); list each "
                         "flight as [[flight]] with telemetry = ..., tracking = ...")
    try:
        man = Manifest.model_validate({**data, "source": str(path)})
    except ValidationError as exc:
        lines = [f"{_where(e['loc'])}: {e['msg']}" + (f" (got {e['input']!r})" if e["type"] != "missing"
                                                      and not isinstance(e.get("input"), dict) else "")
                 for e in exc.errors()]
        raise ValueError(f"manifest {path}: " + "; ".join(lines)) from None
    base = path.parent
    flights = []
    seen: dict[str, int] = {}
    for k, f in enumerate(man.flights):
        resolved = {key: (getattr(f, key) if getattr(f, key) is None or getattr(f, key).is_absolute()
                          else base / getattr(f, key)) for key in ("telemetry", "tracking", "result")}
        for key, p in resolved.items():  # a `result` is read (and named when missing) by fuse and impact only:
            if key != "result" and p is not None and not p.is_file():  # separate may be about to write it
                raise ValueError(f"manifest {path}: flight {k + 1}, key `{key}`: file {p} does not exist")
        real = os.path.realpath(resolved["telemetry"])
        if real in seen:
            raise ValueError(f"manifest {path}: flights {seen[real] + 1} and {k + 1} have the same telemetry file "
                             f"{resolved['telemetry']}: give each flight once")
        seen[real] = k
        flights.append(f.model_copy(update=resolved))
    fit = None
    if man.fit is not None:  # the options' files (prior, bounds) relative to the manifest too
        opts = {k: str(base / v) if k in ("prior", "bounds") and isinstance(v, str) and not Path(v).is_absolute()
                else v for k, v in (man.fit.get("options") or {}).items()}
        fit = {**man.fit, **({"options": opts} if "options" in man.fit else {})}
    out = man.model_copy(update={"flights": flights, "fit": fit})
    out.spec()  # the request checked now, with the manifest: an error names it and the table
    return out
