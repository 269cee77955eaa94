"""Result files read back as :class:`~casep.estimators.result.EstimateResult`, checked against their model.

The file is parsed and checked strictly by :mod:`casep.io.result_json` (every form of
``docs/guide/result-files.md``); here it becomes a result (a casep file of an earlier version in
today's form: each method's extras type says how its old form reads), its model is found (by name,
then by the ``model_file`` it records) and its coefficients and units are checked against that model.
"""

from __future__ import annotations

from casep.estimators import _from_data
from casep.estimators._from_data import check_result_units, tracking_terms
from casep.estimators.result import EstimateResult

__all__ = ["read_result", "resolve_result_model", "result_from_data", "check_result_units"]


def result_from_data(rd, model=None) -> EstimateResult:
    """An :class:`EstimateResult` of a checked result file (:class:`casep.io.result_json.ResultData`);
    `model` (ErrorModel or name): check names and units against it, and take the SI factors from it."""
    return _from_data.result_from_data(rd, model, EstimateResult)


def read_result(source, model=None, option: str = "result") -> tuple[EstimateResult, object]:
    """A result file read with its model: ``(result, model)``.

    The model is `model` when given (ErrorModel, name or path), else the one the result names:
    by name (built-in, or ``CASEP_MODEL_PATH``), then by the ``model_file`` the result records.
    A result whose model cannot be found is a ValueError saying exactly what to pass.
    """
    from casep.io.result_json import parse_result_data, read_result_data
    from casep.model.loader import load_model

    if isinstance(source, EstimateResult):
        rd, res = None, source
        where = "result <memory>"
    else:
        rd = parse_result_data(source, "result <memory>") if isinstance(source, dict) else \
            read_result_data(source, option)
        where = rd.source
    if model is None:
        name = (rd.model if rd is not None else source.model) or ""
        mfile = rd.fields.get("model_file") if rd is not None else source.model_file
        model = resolve_result_model(name, mfile, where)
    else:
        model = load_model(model)
        name = rd.model if rd is not None else source.model
        if name and name != model.name:
            raise ValueError(f"{where} is of model `{name}`, not of model `{model.name}`: give --model {name} "
                             f"(or leave it out), or a result of `{model.name}`")
    if rd is not None:
        res = result_from_data(rd, model)
    else:
        check_result_units(res.names, res.units, model, where, skip=tracking_terms(res.diagnostics))
    return res, model


def resolve_result_model(name: str, model_file: str | None, where: str):
    """The model a result names (see :func:`read_result`)."""
    from casep.model.loader import load_model

    if not name and not model_file:
        raise ValueError(f"{where} names no model (no `model` field): give the model (CLI --model NAME|FILE.py, "
                         "API model=...)")
    errors = []
    for cand in ([name] if name else []) + ([model_file] if model_file else []):
        try:
            return load_model(cand)
        except ValueError as exc:  # unknown name, missing file; a broken file names itself
            if "unknown model" not in str(exc) and "does not exist" not in str(exc):
                raise
            errors.append(cand)
    hint = f" (the result records model_file {model_file}, which does not exist)" if model_file else ""
    raise ValueError(f"{where} is of model `{name or model_file}`, which casep cannot find: it is not a built-in model "
                     f"nor in CASEP_MODEL_PATH{hint}. Give the model file: --model path/to/{name or 'model'}.py "
                     "(API: model='path/to/model.py')")
