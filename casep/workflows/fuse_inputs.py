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
    seen: dict[str, tuple[str, str, str]] = {}  # sha256 -> (result file, the file it names, that file's role)
    for path in paths:
        own = _digest(path)
        try:
            with open(path, encoding="utf-8") as fh:
                prov = json.load(fh).get("provenance") or {}
        except (OSError, ValueError, AttributeError):
            prov = {}  # read and checked by the result reader; a hand-written result has no provenance
        named = [(own, str(path), "result")] if own else []
        for inp in prov.get("inputs", []) if isinstance(prov, dict) else []:
            if isinstance(inp, dict) and inp.get("sha256") and inp.get("role", "") not in NOT_DATA:
                named.append((inp["sha256"], str(inp.get("file", "")), str(inp.get("role") or "input")))
        for d, name, role in named:
            if d in seen and seen[d][0] != str(path):
                earlier = [(e, f, r) for e, (q, f, r) in seen.items() if q == seen[d][0]]
                raise ValueError(_shared_message(seen[d], (str(path), name, role), d, earlier, named))
        for d, name, role in named:
            seen.setdefault(d, (str(path), name, role))


def _shared_message(first: tuple[str, str, str], second: tuple[str, str, str], digest: str,
                    named1: Sequence[tuple[str, str, str]], named2: Sequence[tuple[str, str, str]]) -> str:
    """Why two results are not fused: each result with the file it read (its own name and role) and the content
    they share; a shared data record makes them one flight's data counted twice whatever else differs."""
    (p1, f1, r1), (p2, f2, r2) = first, second
    what = r1 if r1 == r2 else f"{r1}/{r2}"
    if r1 == r2 == "result":
        shared = f"RESULT {p1} and {p2} are the same file content (one result given twice)"
    elif "result" in (r1, r2):
        own, holder, role = (p1, p2, r2) if r1 == "result" else (p2, p1, r1)
        shared = f"RESULT {holder} was made from RESULT {own} (its input, role {role})"
    elif f1 == f2:
        shared = f"RESULT {p1} and {p2} both read the {what} file {f1}"
    else:
        shared = (f"RESULT {p1} read the {r1} file {f1} and {p2} the {r2} file {f2}, and the two files have the "
                  "same content")
    d1, d2 = {d for d, _, _ in named1}, {d for d, _, _ in named2}
    own1 = [f"{r} {f}" for d, f, r in named1 if d not in d2 and r != "result"]
    own2 = [f"{r} {f}" for d, f, r in named2 if d not in d1 and r != "result"]
    differ = (f"; their other inputs differ ({p1}: {', '.join(own1) or '-'}; {p2}: {', '.join(own2) or '-'}), but "
              "the record they share makes them two estimates of one flight's data, not independent ones"
              if own1 or own2 else "")
    return (f"{shared} (sha256 {digest[:12]}...){differ}: fusing them counts its data twice (std too small by "
            "sqrt 2); give each flight's result once")


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
