"""Result files read back as :class:`~casep.estimators.result.EstimateResult`, checked against their model.

The file is parsed and checked strictly by :mod:`casep.io.result_json` (every form of
``docs/guide/result-files.md``); here it becomes a result (a casep file of an earlier version in
today's form: each method's extras type says how its old form reads), its model is found without
running code on the file's word (:func:`casep.model.loader.load_recorded_model`: a model shipped
with casep by its name, any other only when the user names it, with the SHA-256 the result records)
and its coefficients and units are checked against that model.

:func:`check_usable` is the one rule for "may this result be an input" (``impact --result``,
``fuse``, ``--prior``, ``montecarlo``/``design --prior``): :func:`read_input_result` reads and applies it.
"""

from __future__ import annotations

from typing import Any

from casep.estimators import _from_data
from casep.estimators._from_data import check_result_units, tracking_terms
from casep.estimators.result import EstimateResult

__all__ = ["read_result", "read_input_result", "check_usable", "warn_biased_std", "resolve_result_model",
           "result_from_data", "check_result_units"]


def result_from_data(rd, model=None) -> EstimateResult:
    """An :class:`EstimateResult` of a checked result file (:class:`casep.io.result_json.ResultData`);
    `model` (ErrorModel or name): check names and units against it, and take the SI factors from it."""
    return _from_data.result_from_data(rd, model, EstimateResult)


def read_result(source, model=None, option: str = "result",
                model_option: str = "--model") -> tuple[EstimateResult, object]:
    """A result file read with its model: ``(result, model)``.

    The model is `model` when given (ErrorModel, name or path: the user's, which may run), else the
    model shipped with casep that the result names. A result of any other model is a ValueError saying
    to give it with `model_option`: a result file never runs code. A model file whose SHA-256 differs
    from the one the result records is a ValueError naming both (:func:`resolve_result_model`).
    """
    if isinstance(source, EstimateResult):  # in memory: no file to parse (nor pydantic to import)
        rd, res = None, source
        where = "result <memory>"
    else:
        from casep.io.result_json import parse_result_data, read_result_data

        rd = parse_result_data(source, "result <memory>") if isinstance(source, dict) else \
            read_result_data(source, option)
        where = rd.source
    if rd is not None:
        rec = (rd.model, rd.fields.get("model_sha256"), rd.fields.get("model_file"))
    else:
        rec = (source.model, source.model_sha256, source.model_file)
    model = resolve_result_model(*rec, where, given=model, option=model_option)
    if rd is not None:
        res = result_from_data(rd, model)
    else:
        check_result_units(res.names, res.units, model, where, skip=tracking_terms(res.diagnostics))
    return res, model


def resolve_result_model(name: str, sha256: str | None, model_file: str | None, where: str, *, given=None,
                         option: str = "--model"):
    """The model of a result (see :func:`read_result`; :func:`casep.model.loader.load_recorded_model`)."""
    from casep.model.loader import load_recorded_model

    return load_recorded_model(name or None, sha256=sha256, model_file=model_file, given=given, where=where,
                               option=option)


def check_usable(result: Any, where: str) -> None:
    """Raise ValueError when `result` may not be an input of another step (fuse, impact, a prior).

    A failed result (``success`` false) is refused: its estimate and std are what a failed fit left.

    Parameters
    ----------
    result : EstimateResult
        A result, read back from a file or in memory.
    where : str
        What to name in the message (``"--prior FILE"``).
    """
    if not result.success:
        raise ValueError(f"{where}: a failed result (status {result.status}: {result.message}); its estimate and std "
                         "are not usable as an input. Fix what failed and estimate again")


def warn_biased_std(result: Any, where: str) -> None:
    """Warn when `result` is of a regularised method whose std leave out its bias (ridge's shrinkage, PCR's
    truncation, active bounds): a miss, fused or prior std computed from them can be far too small.

    The std are of the kind the method declares for its regularised estimate (``Method.std_kind``, not
    ``posterior``); a bounded fit with no bound active reports plain sampling std and is not warned about.
    """
    import warnings

    from casep.estimators.registry import METHODS
    from casep.exceptions import BiasedStdWarning

    meth = METHODS.get(result.method)
    if meth is None or not meth.regularised or result.std_kind == "posterior" or result.std_kind != meth.std_kind:
        return
    warnings.warn(f"{where}: a result of method {result.method}, whose std ({result.std_kind}) leave out the bias its "
                  "regularisation brings: what is computed from them (a miss std, a fused std, a prior) can be far "
                  "too small. For an error budget use a method whose std hold (ols, gls, or map with a stated prior)",
                  BiasedStdWarning, stacklevel=3)


def read_input_result(source, model=None, option: str = "result",
                      model_option: str = "--model") -> tuple[EstimateResult, object]:
    """:func:`read_result` and :func:`check_usable`: a result to use as an input, with its model."""
    res, model = read_result(source, model, option, model_option)
    where = f"{option} {source}" if not isinstance(source, (dict, EstimateResult)) else f"{option} <memory>"
    check_usable(res, where)
    warn_biased_std(res, where)
    return res, model
