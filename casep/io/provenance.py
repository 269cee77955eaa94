"""Provenance of a result: which files (with their SHA-256), frames, sites, time alignment, exclusions,
options, casep version and command line produced it.

:func:`provenance` collects it from the flights as read (their ``meta``, recorded by the readers of
:mod:`casep.io.files`) and the other inputs; ``casep separate`` writes it into the result JSON
(``provenance``), the ``.mat`` file (struct ``provenance``) and the HTML report (section
"Provenance"), so that a result found on a disk months later says what it was made of. The
checksums are of the files as they were read (:mod:`hashlib`, streamed in 1 MiB blocks).
"""

from __future__ import annotations

import hashlib
import os
import shlex
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

__all__ = ["provenance", "flight_provenance", "file_record", "file_sha256", "command_line", "DATA_ROLES",
           "flight_files", "check_estimated_on", "check_not_estimated_on"]

#: Roles of the files a flight is read from (:func:`flight_provenance`'s ``files``, and a raw IMU record that
#: was navigated into the telemetry): the data of a result.
DATA_ROLES = ("flight", "telemetry", "tracking", "imu")

#: FlightData.meta keys that say which samples were left out, and why.
_EXCLUSIONS = ("unobserved", "telemetry_dropped", "tracking_dropped", "gap_rows_left_out", "gaps_s", "inserted")


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks; OSError when it cannot be read."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def file_record(path: str | os.PathLike, role: str) -> dict[str, Any]:
    """``{"role", "file", "bytes", "sha256"}`` of an input file (sha256 None if it cannot be read)."""
    p = Path(path)
    digest, size = None, None
    try:
        digest, size = file_sha256(p), p.stat().st_size
    except OSError:
        pass
    return {"role": role, "file": str(p), "bytes": size, "sha256": digest}


def flight_provenance(flight) -> dict[str, Any]:
    """What a flight's reader recorded: files, grid, tracking frame and site, time alignment and shift,
    set-up checks, spans and the samples left out (``FlightData.meta``)."""
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    out: dict[str, Any] = {"source": flight.source, "samples": int(flight.n_samples),
                           "observed": int(flight.n_observed)}
    if meta.get("format") == "pair":
        out["files"] = {"telemetry": meta.get("telemetry"), "tracking": meta.get("tracking")}
        out["grid"] = meta.get("grid")
        out["tracking_frame"] = meta.get("tracking_frame", {"frame": "launch"})
        out["time_alignment"] = meta.get("time_alignment")
        out["time_shift_s"] = meta.get("time_shift_s", 0.0)
        out["clock_drift_ppm"] = meta.get("clock_drift_ppm", 0.0)
        if meta.get("clock_drift_of"):
            out["clock_drift_of"] = meta["clock_drift_of"]
        out["spans_s"] = {k: meta.get(f"{k}_span_s") for k in ("telemetry", "tracking", "observed")}
    else:
        out["files"] = {"flight": flight.source}
        out["format"] = meta.get("format")
    setup = meta.get("setup")
    if setup:
        out["setup_checks"] = {"problems": setup.get("problems", []), "pad": setup.get("pad"),
                               "first_tracked": setup.get("first_tracked"), "spans": setup.get("spans")}
    out["exclusions"] = {k: meta[k] for k in _EXCLUSIONS if k in meta}
    return out


def command_line(argv: Sequence[str] | None = None) -> str:
    """The command as typed (``casep separate ...``), shell-quoted; `argv` default ``sys.argv``."""
    args = list(sys.argv if argv is None else argv)
    if args and Path(args[0]).name in ("__main__.py", "cli.py", "casep"):
        args[0] = "casep"
    return " ".join(shlex.quote(str(a)) for a in args)


def provenance(flights: Sequence, *, inputs: Mapping[str, Any] | None = None, options: Mapping | None = None,
               argv: Sequence[str] | None = None, manifest=None) -> dict[str, Any]:
    """The provenance record of a result (module notes).

    Parameters
    ----------
    flights : sequence of FlightData
        The flights as read.
    inputs : mapping, optional
        Other input files by role (``{"prior": path, "bounds": path, "model": path}``; None skipped).
    options : mapping, optional
        The options used (method, model, sigma, ...), recorded as given.
    argv : sequence of str, optional
        The command line (default ``sys.argv``).
    manifest : casep.workflows.manifest.Manifest, optional
        The manifest the flights came from: its file and entries.

    Returns
    -------
    dict
        ``casep_version``, ``command_line``, ``inputs`` (role, file, bytes, sha256 of every file read),
        ``flights`` (:func:`flight_provenance`), ``options``, and ``manifest`` when given.
    """
    from casep._version import __version__

    files: list[dict] = []
    seen: set[str] = set()

    def add(path, role):
        if path and str(path) not in seen and Path(str(path)).is_file():
            seen.add(str(path))
            files.append(file_record(path, role))

    if manifest is not None:
        add(manifest.source, "manifest")
    recs = [flight_provenance(f) for f in flights]
    for r in recs:
        for role, path in r["files"].items():
            add(path, role)
    for role, path in (inputs or {}).items():
        for p in (path if isinstance(path, (list, tuple)) else [path]):
            add(p, role)
    out = {"casep_version": __version__, "command_line": command_line(argv), "inputs": files, "flights": recs,
           "options": dict(options or {})}
    if manifest is not None:
        out["manifest"] = {"file": manifest.source, "flights": [f.to_dict() for f in manifest.flights],
                           **({"fit": manifest.spec().to_dict()} if getattr(manifest, "fit", None) else {})}
    return out


def flight_files(flight) -> list[str]:
    """The files `flight` (a FlightData) was read from: its telemetry and tracking files, or its one file."""
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    files = [meta.get("telemetry"), meta.get("tracking")] if meta.get("format") == "pair" else [flight.source]
    return [str(f) for f in files if f and Path(str(f)).is_file()]


def check_estimated_on(record: Any, flight, where: str) -> None:
    """Refuse a result whose provenance says it was estimated on other data than `flight`.

    The result's ``provenance.inputs`` holds the SHA-256 of each data file it read (:data:`DATA_ROLES`);
    the flight's telemetry (or its one file) must be one of them. A result without such a record (written
    by hand, by the API or by an earlier casep) is not checked; a flight read from no file cannot be, and
    a :class:`~casep.exceptions.CasepWarning` says so.

    Parameters
    ----------
    record : dict or None
        The result's ``provenance``.
    flight : FlightData
        The flight the result is applied to as its own.
    where : str
        The result, as messages name it (``--result r.json``).

    Raises
    ------
    ValueError
        Naming the flight file and its SHA-256, and the data files the result records with theirs.
    """
    recorded = _recorded_data(record)
    if not recorded:
        return
    files = flight_files(flight)
    if not files:
        import warnings

        from casep.exceptions import CasepWarning

        warnings.warn(f"{where} was estimated on {', '.join(f for _, f in recorded)}; the flight {flight.source} "
                      "is read from no file, so casep cannot check that it is that flight", CasepWarning, stacklevel=3)
        return
    mine = file_record(files[0], "flight")["sha256"]
    if mine not in {d for d, _ in recorded}:
        theirs = "; ".join(f"{f} (sha256 {d})" for d, f in recorded)
        raise ValueError(f"{where} was estimated on other data: flight {files[0]} has sha256 {mine}, the result "
                         f"records {theirs}. Give the flight the result was estimated on (a flight not flown goes "
                         "to --trajectory)")


def _recorded_data(record: Any) -> list[tuple[str, str]]:
    """``(sha256, file)`` of the data files a result's ``provenance`` records (:data:`DATA_ROLES`)."""
    inputs = record.get("inputs") if isinstance(record, dict) else None
    return [(str(i.get("sha256")), str(i.get("file", ""))) for i in (inputs if isinstance(inputs, list) else [])
            if isinstance(i, dict) and i.get("role") in DATA_ROLES and i.get("sha256")]


def check_not_estimated_on(record: Any, files: Sequence[str | os.PathLike], where: str) -> None:
    """Refuse a prior estimated on the data of `flight` itself (the twin of :func:`check_estimated_on`).

    A prior from the same data counts it twice: the posterior std come out sqrt 2 too small (as
    :func:`casep.workflows.fusion.fuse` refuses two results of one input). Checked on the SHA-256 of the data
    files the prior's ``provenance`` records against `files`, the flight's (:func:`flight_files`); a prior
    without such a record, or a flight read from no file, is not checked.

    Raises
    ------
    ValueError
        Naming the file both share, its SHA-256, and the option.
    """
    recorded = _recorded_data(record)
    mine = {file_record(f, "flight")["sha256"]: str(f) for f in (files if recorded else [])
            if f and Path(f).is_file()}
    shared = [(d, f) for d, f in recorded if d in mine]
    if shared:
        d, f = shared[0]
        raise ValueError(f"{where} was estimated on this flight's own data: {mine[d]} has sha256 {d}, which the "
                         f"prior records as {f}. A prior from the same data counts it twice (every std about "
                         "sqrt 2 too small): give a prior from other data (ground calibration, another flight), "
                         "or fit the flights together (casep separate A B)")
