"""Results to fuse, read back from their files and checked: none failed, no input file counted twice.

:func:`read_results_to_fuse` reads each result JSON (any result form; a ground calibration is kept
as it is, to be mapped to its flight model by :func:`casep.workflows.fusion.fuse_with_ground`),
refuses a failed result, and refuses two results that were estimated from the same input file:
their provenance records name each input with its SHA-256 (:mod:`casep.io.provenance`), and
fusing two estimates of one data set would count its data twice (the fused std too small by
sqrt 2).
"""

from __future__ import annotations

import json
import os
from typing import Any, Sequence

__all__ = ["read_results_to_fuse", "check_distinct_inputs"]

#: Provenance roles that are not data: a shared prior, bounds or model file does not count twice.
NOT_DATA = ("prior", "bounds", "model")


def _digest(path: str | os.PathLike) -> str | None:
    from casep.io.provenance import file_sha256

    try:
        return file_sha256(path)
    except OSError:
        return None


def check_distinct_inputs(paths: Sequence[str | os.PathLike]) -> None:
    """Raise ValueError when two result files name the same input data file, or one result is another's input.

    Parameters
    ----------
    paths : sequence of path-like
        Result JSON files. A file without a provenance record (written by hand) is compared by its
        own SHA-256 only.

    Raises
    ------
    ValueError
        Naming both result files and the shared input with the start of its SHA-256.
    """
    seen: dict[str, tuple[str, str]] = {}  # sha256 -> (result file, the file it names)
    for path in paths:
        own = _digest(path)
        try:
            with open(path, encoding="utf-8") as fh:
                prov = json.load(fh).get("provenance") or {}
        except (OSError, ValueError, AttributeError):
            prov = {}  # read and checked by the result reader; a hand-written result has no provenance
        named = [(own, str(path))] if own else []
        for inp in prov.get("inputs", []) if isinstance(prov, dict) else []:
            if isinstance(inp, dict) and inp.get("sha256") and inp.get("role", "") not in NOT_DATA:
                named.append((inp["sha256"], str(inp.get("file", ""))))
        for d, name in named:
            if d in seen and seen[d][0] != str(path):
                raise ValueError(f"RESULT {path} and {seen[d][0]} were estimated from the same input file {name} "
                                 f"(sha256 {d[:12]}...): fusing them counts its data twice (std too small by sqrt 2); "
                                 "give each flight's result once")
        for d, name in named:
            seen.setdefault(d, (str(path), name))


def read_results_to_fuse(paths: Sequence[str | os.PathLike], model: Any = None) -> list[Any]:
    """Read result files for :func:`casep.workflows.fusion.fuse_with_ground`, each checked.

    Parameters
    ----------
    paths : sequence of path-like
        Result JSON files (two or more, of one model; ground calibrations allowed).
    model : str, path or ErrorModel, optional
        The model to read them with (default: the one each result names).

    Returns
    -------
    list of EstimateResult
        In the order of `paths`.

    Raises
    ------
    ValueError
        A file that is no result, a result of another model, a failed result, or two results from
        the same input file (:func:`check_distinct_inputs`).
    """
    from casep.calibration.calibrate import calibration_models
    from casep.estimators.reading import check_usable, read_input_result, result_from_data
    from casep.io.result_json import read_result_data

    grounds, results = set(calibration_models()), []
    for path in paths:  # every result form, checked against its model (or `model`), usable as an input
        rd = read_result_data(path, "RESULT")
        if rd.model in grounds:  # a ground calibration: mapped to its flight model by the fusion
            results.append(result_from_data(rd))
            check_usable(results[-1], f"RESULT {path}")
        else:
            results.append(read_input_result(path, model, option="RESULT")[0])
    check_distinct_inputs(list(paths))
    return results
