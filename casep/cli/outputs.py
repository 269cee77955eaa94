"""Outputs of a command: checked before any work, written all or none, the exit status of a result.

Every command names its outputs in :func:`check` first (a bad path, an output that is one of the
inputs, or two options naming one file: exit 2 before any computation, :func:`casep.io._atomic.check_outputs`);
:func:`casep.cli.main` runs the command inside :func:`casep.io._atomic.output_group`, so the
files appear together when it succeeds and none when it fails.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["check", "provenance", "status", "write_json", "write_exports", "folder"]


def check(files: dict[str, Any], inputs: Any = (), folders: dict[str, Any] | None = None) -> None:
    """Check the outputs ``{option: path or None}`` and output `folders` before any work (exit 2 on a bad one)."""
    from casep.io._atomic import check_outputs

    check_outputs(files, inputs=inputs, folders=folders)


def write_json(data: dict[str, Any], path: str, *, record_warnings: bool = True) -> None:
    """Write `data` as JSON to `path` (atomically; part of the command's output group).

    With `record_warnings` (not for a file in another program's format), the warnings the command raised
    so far (:func:`casep.cli.capture.raised_so_far`: units assumed, set-up checks, ...) go with it: into its
    ``provenance`` as ``warnings``, or as a top-level ``warnings`` list when it has no provenance.
    """
    from casep.cli.capture import raised_so_far
    from casep.io.result_files import write_json_atomic

    if record_warnings:
        lines = raised_so_far()
        prov = data.get("provenance")
        data = {**data, "provenance": {**prov, "warnings": lines}} if isinstance(prov, dict) else \
            {**data, "warnings": lines}
    write_json_atomic(data, path)


def folder(path: str) -> Path:
    """An output folder (``--figures DIR``), created."""
    p = Path(path)
    p.mkdir(parents=True, exist_ok=True)
    return p


def provenance(args: argparse.Namespace, flights: list[Any], extra_inputs: dict[str, Any] | None = None) -> dict:
    """The provenance record of a command's result (casep.io.provenance): files with SHA-256, frames, sites,
    time alignment, exclusions, the options as given and the command line."""
    from casep.io.provenance import provenance as record

    skip = {"command", "flight", "tracking", "manifest", "manifest_obj", "json", "mat", "csv", "report", "figures",
            "argv", "results"}
    options = {k: v for k, v in vars(args).items() if k not in skip and v is not None
               and isinstance(v, (str, int, float, bool, list))}
    model = getattr(args, "model", None)
    inputs = {"prior": getattr(args, "prior", None), "bounds": getattr(args, "bounds", None),
              "model": model if model and Path(str(model)).is_file() else None, **(extra_inputs or {})}
    return record(flights, inputs=inputs, options=options, argv=getattr(args, "argv", None),
                  manifest=getattr(args, "manifest_obj", None))


def write_exports(res: Any, args: argparse.Namespace, *, t: Any = None, provenance: dict | None = None) -> None:
    """`--mat` (with the residuals' times and the provenance) and `--csv` of `separate`."""
    from casep.estimators.result import write_csv, write_mat

    if args.mat:
        write_mat(res, args.mat, t=t, provenance=provenance)
    if args.csv:
        write_csv(res, args.csv)


def status(res: Any) -> int:
    """Exit status of a computed result: 0, or 1 (message on stderr) when it is not successful.

    The table and the JSON are still written: the JSON records ``success: false`` and the
    message, which is what a script or a later look at the run needs.
    """
    if res.success:
        return 0
    said = res.message.replace("\n", "\n  ")  # its reason first; each further line a finding, indented
    print(f"casep: result not successful: {said}", file=sys.stderr)
    return 1
