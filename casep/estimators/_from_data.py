"""A checked result file (:class:`casep.io.result_json.ResultData`) made into an estimate.

A casep file of an earlier version reads in today's form (each method's extras type says how its old
form reads); the coefficients and units are checked against the model when one is given. Used by
:meth:`casep.estimators.result.EstimateResult.from_json` and :mod:`casep.estimators.reading`, and kept
apart from both so that neither imports the other.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from casep.estimators._meanings import AXES, SIGMA_FOUND, SIGMA_SOURCE_MEANINGS, STD_KIND_MEANINGS, extras_type
from casep.estimators.solution import Solution

__all__ = ["result_from_data", "check_result_units", "tracking_terms"]


def _old_form(method: str, settings: dict, diagnostics: dict, extras: dict | None, source: str | None = None
              ) -> tuple[dict, dict, dict | None]:
    """Settings, diagnostics and extras of a result file in today's form: a file of an earlier casep kept
    found values in ``settings`` or twice (``diagnostics`` and ``extras``); each method's extras type says how
    its old form reads (``old_form``), and a file in today's form passes unchanged."""
    sigma = settings.get("sigma")
    if (source in SIGMA_FOUND and not isinstance(sigma, bool) and isinstance(sigma, (int, float))
            or isinstance(sigma, str) and sigma.startswith("wavelet estimate ")):
        settings = {**settings, "sigma": "estimated"}  # the robust or wavelet sigma found (the result's sigma)
    convert = getattr(extras_type(method), "old_form", None)
    if convert is None:
        return settings, diagnostics, extras
    return convert(settings, diagnostics, extras)


def _extras_from_dict(method: str, d: dict | None):
    """The typed extras of `method` back from their JSON object (lists -> declared tuples)."""
    cls = extras_type(method)
    if d is None or cls is None:
        return None
    kw = {f.name: (tuple(d[f.name]) if str(f.type).startswith("tuple") else d[f.name])
          for f in dataclasses.fields(cls) if f.name in d}
    return cls(**kw)


def result_from_data(rd: Any, model: Any, cls: type) -> Any:
    """An :class:`EstimateResult` of a checked result file (:class:`casep.io.result_json.ResultData`).

    `model` (ErrorModel or name): check names and units against it, and take the SI factors from it.
    `cls`: the result class (:class:`~casep.estimators.result.EstimateResult`, which imports this module).
    """
    f = rd.fields
    si = None
    if model is not None:  # the caller's model: of the result's name, and of its recorded SHA-256
        from casep.model.loader import load_recorded_model

        model = load_recorded_model(rd.model or None, sha256=f.get("model_sha256"), model_file=f.get("model_file"),
                                    given=model, where=rd.source)
        skip = tracking_terms(f.get("diagnostics"))
        check_result_units(rd.names, rd.units, model, rd.source, skip=skip)
        if not skip:
            base = [n.split("[", 1)[0] for n in rd.names]
            si = np.array([model.si_factors[model.names.index(b)] for b in base], dtype=float)
    if si is None and f.get("si_factors") is not None and len(f["si_factors"]) == len(rd.names):
        si = np.array([np.nan if v is None else v for v in f["si_factors"]], dtype=float)
    if si is None:
        from casep.units import si_factor

        vals = []
        for u in rd.units:
            try:
                vals.append(si_factor(u))
            except (KeyError, ValueError):
                vals.append(math.nan)
        si = np.array(vals, dtype=float)
    method = f.get("method") or "external"
    try:
        settings, diagnostics, extras_d = _old_form(method, f.get("settings") or {}, f.get("diagnostics") or {},
                                                    f.get("extras"), f.get("sigma_source"))
        extras = _extras_from_dict(method, extras_d)
    except (TypeError, KeyError, ValueError, IndexError) as exc:
        raise ValueError(f"{rd.source}: field `extras` does not fit method `{method}` ({exc})") from None
    rrms = f.get("residual_rms")
    n_est = int(np.isfinite(rd.estimate).sum())
    for key, allowed in (("std_kind", STD_KIND_MEANINGS), ("sigma_source", SIGMA_SOURCE_MEANINGS)):
        if f.get(key) is not None and f[key] not in allowed:
            raise ValueError(f"{rd.source}: field `{key}` must be one of {', '.join(allowed)}, got {f[key]!r}")
    return cls(
        method=method, names=rd.names, units=rd.units, estimate=rd.estimate, std=rd.std,
        covariance=rd.covariance, reasons=dict(rd.reasons), residuals=np.zeros((0, 3)),
        sigma=math.nan if f.get("sigma") is None else float(f["sigma"]),
        rank=n_est if f.get("rank") is None else int(f["rank"]),
        status=0 if f.get("status") is None else int(f["status"]),
        message=f.get("message") or f"read from {rd.source}",
        success=True if f.get("success") is None else bool(f["success"]),
        si_factors=si, settings=settings, diagnostics=diagnostics,
        model=f.get("model") or (model.name if model is not None else ""),
        n_samples=int(f.get("n_samples") or 0), denoise=f.get("denoise"),
        sigma_source=f.get("sigma_source") or ("estimated" if f.get("sigma") is not None else "external"),
        stored_residual_rms=rrms if rrms is not None else {a: None for a in AXES},
        std_kind=f.get("std_kind") or "sampling", extras=extras, model_file=f.get("model_file"),
        model_sha256=f.get("model_sha256"),
        solution=Solution.from_dict(f.get("solution"), len(rd.names), rd.source))


def tracking_terms(diagnostics: Any) -> set[str]:
    """Coefficients of a radar-tracked result that belong to its tracking model (station errors), not to
    the instrument model: ``diagnostics["tracking_terms"]``."""
    terms = (diagnostics or {}).get("tracking_terms") if isinstance(diagnostics, dict) else None
    return {str(t) for t in terms} if isinstance(terms, (list, tuple)) else set()


def check_result_units(names, units, model, source: str, skip: set[str] | frozenset[str] = frozenset()) -> None:
    """Every coefficient of a result is the model's (a several-flight result's ``name[file]``: its base
    name) and in the model's unit; ValueError naming the coefficient and both units. Names in `skip`
    (a radar-tracked result's tracking-model terms) are not the instrument model's and are left out."""
    from casep.model.error_model import unknown_coefficient_message

    for n, u in zip(names, units):
        if n in skip:
            continue
        base = n.split("[", 1)[0]
        if base not in model.names:
            raise ValueError(unknown_coefficient_message(base, model.names, f"{source} (model {model.name})"))
        mu = model.units[model.names.index(base)]
        if u.strip() != mu:
            raise ValueError(f"{source}: `{n}` is in {u!r}, but model `{model.name}` declares it in {mu!r}: convert "
                             "the estimate, std and covariance to the model's unit")
