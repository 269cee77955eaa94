"""Coefficient files: a prior or bounds file of any accepted form, and a file of typical magnitudes.

A prior file (``casep separate --prior``, ``casep diagnose --prior``) may be

- a prior mapping ``{"Kg0x": {"mean": m, "std": s}, ...}`` (natural units; :func:`casep.estimators.map.parse_prior`),
- a ground calibration (``casep calibrate --json``): its coefficients mapped to the flight model
  (:func:`casep.calibration.consistency.ground_prior`),
- a result JSON of an earlier estimate (any result form): its posterior, mean = estimate and
  covariance = the result's (:func:`casep.estimators.map.prior_from_result`), so a later flight
  continues the estimate. A failed result (``success`` false) is refused, and a model it names
  runs only when the user names it (``--model``; :func:`casep.estimators.reading.read_result`).

A bounds file is ``{"Kg0x": [lo, hi] | value, ...}`` (:func:`casep.estimators.bounded.parse_bounds`).
Every form is checked against the model's coefficient names; errors name the option and the file.
"""

from __future__ import annotations

import math
import os
from typing import Any, Sequence

__all__ = ["read_coefficient_file", "read_truth_prior", "read_scales", "with_tables"]


def read_coefficient_file(path: str | os.PathLike, kind: str, names: Sequence[str], *,
                          model: Any = None, data_files: Sequence[str | os.PathLike] = (),
                          option: str | None = None) -> dict[str, Any]:
    """Read a ``prior`` or ``bounds`` file of any accepted form, checked against the model's coefficients.

    Parameters
    ----------
    path : str or path-like
        The JSON file.
    kind : {"prior", "bounds"}
        What the file is; the option named in messages is ``--<kind>``.
    names : sequence of str
        The model's coefficient names.
    model : str, path or ErrorModel, optional
        The flight model (a ground calibration is mapped to it, default ``platform36``; a result file
        is read with it, default: the model the result names).
    data_files : sequence of paths, optional
        The files of the flight the prior is for: a result estimated on them is refused
        (:func:`casep.io.provenance.check_not_estimated_on`: the same data counted twice).
    option : str, optional
        The option named in messages (default ``--<kind>``; ``--truth-from-prior`` reads a prior too).

    Returns
    -------
    dict
        The prior mapping (``{name: {"mean", "std"}}``, with ``correlation`` from a result's covariance)
        or the bounds mapping, as :func:`casep.separate` takes them.

    Raises
    ------
    ValueError
        A file that cannot be read, a coefficient the model does not have, a bad entry, or a failed
        result given as a prior.
    """
    from casep.estimators.bounded import parse_bounds
    from casep.estimators.map import parse_prior
    from casep.io.files import read_json_table
    from casep.io.result_json import looks_like_result

    if kind not in ("prior", "bounds"):
        raise ValueError(f"`kind` must be 'prior' or 'bounds', got {kind!r}")
    option = option or f"--{kind}"
    data = read_json_table(path, option)
    if kind == "prior" and "calibration" in data:  # a ground calibration: the flight model's coefficients
        from casep.calibration.consistency import ground_prior

        data = ground_prior(data, model or "platform36")
    elif kind == "prior" and looks_like_result(data):  # a result file (any form): its posterior
        from casep.estimators.map import prior_from_result
        from casep.estimators.reading import read_input_result
        from casep.io.provenance import check_not_estimated_on

        res, res_model = read_input_result(path, model, option=option)  # usable; its model never run on its word
        check_not_estimated_on(data.get("provenance"), data_files, f"{option} {path}")
        data = prior_from_result(res, model=res_model)  # per-flight coefficients (dt_trk) left flat
    (parse_prior if kind == "prior" else parse_bounds)(data, names, source=f"{option} {path}")
    return data


def read_scales(path: str | os.PathLike, names: Sequence[str]) -> dict[str, float]:
    """Read a file of typical coefficient magnitudes ``{"Kg0x": magnitude, ...}`` (natural units).

    Parameters
    ----------
    path : str or path-like
        The JSON file (``casep diagnose --scales``).
    names : sequence of str
        The model's coefficient names.

    Returns
    -------
    dict
        ``{name: magnitude}``, every magnitude a finite number > 0.

    Raises
    ------
    ValueError
        A name the model does not have, or a magnitude that is not a finite number > 0.
    """
    from casep.io.files import read_json_table
    from casep.model.error_model import unknown_coefficient_message

    scales = read_json_table(path, "--scales")
    for k, v in scales.items():
        if k not in names:
            raise ValueError(unknown_coefficient_message(k, names, f"--scales {path}"))
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not (v > 0 and math.isfinite(v)):
            raise ValueError(f"--scales {path}: `{k}` must be a finite number > 0, got {v!r}")
    return scales


def read_truth_prior(path: str | os.PathLike, names: Sequence[str], *, model: Any = None) -> dict[str, Any]:
    """The ``--truth-from-prior`` file: a prior of any form :func:`read_coefficient_file` reads (a result file: its
    estimates and std), marginals only (each run draws each coefficient on its own); a ``correlation`` entry of a
    plain prior file is refused."""
    from casep.estimators.map import parse_prior
    from casep.io.files import read_json_table
    from casep.io.result_json import looks_like_result

    option = "--truth-from-prior"
    where = f"{option} {path}"
    raw = read_json_table(path, option)
    if "correlation" in raw and "correlation" not in names and not looks_like_result(raw):
        raise ValueError(f"{where}: a `correlation` entry is not supported (marginal mean and std only)")
    table = read_coefficient_file(path, "prior", names, model=model, option=option)
    table = {k: v for k, v in table.items() if k != "correlation"}  # a result's covariance: its marginals
    parse_prior(table, names, source=where)
    return table


def with_tables(spec: Any, flight: Any, model: Any, data_files: Sequence[str] | None = None) -> Any:
    """`spec` (a :class:`~casep.estimators.spec.FitSpec`) with its ``bounds`` or ``prior`` read when given as a JSON
    file's path, as on the command line (:func:`read_coefficient_file`: a ground calibration, a result's posterior, a
    result of this very flight refused).

    Parameters
    ----------
    spec : FitSpec
        The fit request; returned itself when neither table is a path.
    flight : FlightData, Problem or None
        A Problem's coefficient names are the table's; otherwise `model`'s.
    model : ErrorModel
        The model the table is checked against (unless `flight` is a Problem).
    data_files : sequence of str, optional
        The flight's data files (a result estimated on them is refused); None: those a FlightData was read from.
    """
    import dataclasses

    from casep.io.flight import FlightData
    from casep.io.provenance import flight_files
    from casep.regression.problem import Problem

    if data_files is None:
        data_files = flight_files(flight) if isinstance(flight, FlightData) else ()
    opts = dict(spec.options)
    for k in ("bounds", "prior"):
        path = opts.get(k)
        if isinstance(path, (str, os.PathLike)):
            names = flight.names if isinstance(flight, Problem) else model.names
            opts[k] = read_coefficient_file(path, k, names, model=None if isinstance(flight, Problem) else model,
                                            data_files=data_files)
    return spec if opts == dict(spec.options) else dataclasses.replace(spec, options=opts)
