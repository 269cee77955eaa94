"""The result type shared by every estimator, with its table and JSON forms."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from casep.estimators._meanings import (
    AXES,
    EXTRAS_TYPES,
    SIGMA_FOUND,
    SIGMA_SOURCE_MEANINGS,
    SIGMA_SOURCES,
    STD_KIND_MEANINGS,
    extras_type,
)
from casep.estimators.solution import Solution
from casep.io.result_files import (
    jsonable,
    write_coefficients_csv,
    write_mat_fields,
)
from casep.results import deprecated_alias

__all__ = ["EstimateResult", "EXTRAS_TYPES",
           "SIGMA_SOURCES", "SIGMA_SOURCE_MEANINGS", "STD_KIND_MEANINGS", "extras_type",
           "write_mat", "write_csv", "format_number"]

def format_number(v: float | None, width: int = 12, fmt: str = ".6g") -> str:
    """Right-aligned ``%.6g`` (or `fmt`) with ``-`` for a missing value (None, NaN, inf)."""
    if v is None or not math.isfinite(float(v)):
        return "-".rjust(width)
    return f"{v:{fmt}}".rjust(width)


def _json_float(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _sigma_text(v: Any, source: str = "estimated", sigma: float = math.nan) -> str:
    """The settings line's sigma: the one given (``settings["sigma"]``, the input), or how it was found."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return f"sigma given {v:.4g} m/s"
    if (v is None or v == "estimated") and source in SIGMA_FOUND and math.isfinite(sigma):
        return f"sigma {sigma:.4g} m/s ({SIGMA_FOUND[source]})"
    if v is None or v == "estimated":
        return "sigma estimated from the residuals"
    return f"sigma {v}"


@dataclass(frozen=True)
class EstimateResult:
    """Estimated error coefficients with their uncertainty and how they were obtained.

    Follows the result protocol (:mod:`casep.results`): :meth:`to_dict` (the result JSON) and
    :meth:`text` (what the command line prints); ``diagnostics`` computes its Cramer-Rao std,
    variance inflation factors and near-dependency groups on first use
    (:class:`casep.estimators._lazydict.LazyDiagnostics`).

    Attributes
    ----------
    method : str
        ``"ols"``, ``"rels"``, ...
    names, units : tuple of str
        Coefficient names and natural units, model order.
    estimate : (n,) ndarray
        Estimates in natural units; NaN where the coefficient is not identifiable.
    std : (n,) ndarray or None
        Standard deviations in natural units (NaN where not identifiable), or None when
        the method defines none.
    covariance : (n, n) ndarray or None
        Covariance in natural units (NaN rows/columns where not identifiable).
    reasons : dict
        ``name -> reason`` for every coefficient reported without an estimate.
    residuals : (N, 3) ndarray
        ``dv - S_V D_hat`` per sample and axis, m/s.
    sigma : float
        Noise standard deviation used for ``std`` (estimated or given), m/s.
    rank : int
        Numerical rank of the regression.
    status, message, success
        Outcome, as scipy.optimize results.
    si_factors : (n,) ndarray
        SI value of one natural unit per coefficient.
    settings : dict
        The inputs of the computation only: the method's options as given or by their defaults
        (``"auto"``, ``"gcv"``, a given value), ``sigma`` as given (or ``"estimated"``), the noise model
        asked. What the method found (a REML tau, a GCV lambda, the rank threshold used, ...) is in
        ``extras`` (and in the settings line of :meth:`text`).
    diagnostics : dict
        What every method's result has: condition numbers and identifiability, the noise model, the
        checks (see ``docs/reference/file-formats.md``).
    model : str
        Model name.
    n_samples : int
        Samples used.
    denoise : dict or None
        De-noising settings and per-axis noise sigma, or None; several flights: ``{"flights": {label: ...}}``.
    history : ndarray or None
        Estimate after each sample for recursive methods, natural units.
    history_std : ndarray or None
        Standard deviation at the ``history`` rows (recursive methods), natural units,
        ``sqrt(diag(sigma^2 w P_k))`` with the final ``sigma``. Columns named by
        :attr:`history_names` (the coefficients, then the RELS MA terms ``ma1``, ...).
    sigma_source : str
        Where ``sigma`` came from (:data:`SIGMA_SOURCE_MEANINGS`).
    stored_residual_rms : dict or None
        Residual RMS per axis read from a JSON (which holds no per-sample residuals).
    std_kind : str
        What ``std`` mean (:data:`STD_KIND_MEANINGS`): set by the solver, by default the
        registry's ``Method.std_kind``.
    extras : dataclass or None
        Typed per-method outputs, an instance of ``EXTRAS_TYPES[method]`` (e.g.
        ``res.extras.lam`` for ridge); None for a result of no registered method (fused).
    model_file : str or None
        The model's file when the model is not shipped with casep: written to the JSON so that a
        message of ``impact``, ``fuse`` or ``--prior`` can say which file to give with ``--model``.
    model_sha256 : str or None
        SHA-256 of the model file that ran (``docs/guide/model-files.md``): a model file given to read
        the result must have it.
    solution : Solution or None
        Where some coefficient has no estimate (exactly dependent columns): the solver's whole coefficient
        vector, its covariance and the null space of S_V (:mod:`casep.estimators.solution`); None when
        every coefficient is estimated.
    """

    method: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    estimate: np.ndarray
    std: np.ndarray | None
    covariance: np.ndarray | None
    reasons: dict[str, str]
    residuals: np.ndarray
    sigma: float
    rank: int
    status: int
    message: str
    success: bool
    si_factors: np.ndarray
    settings: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    model: str = ""
    n_samples: int = 0
    denoise: dict[str, Any] | None = None
    history: np.ndarray | None = None
    history_std: np.ndarray | None = None
    sigma_source: str = "estimated"
    # from a JSON (which has no residuals); None per axis: a result with no residuals (fused, ground calibration)
    stored_residual_rms: dict[str, float | None] | None = None
    std_kind: str = "sampling"
    extras: Any = None
    model_file: str | None = None
    model_sha256: str | None = None
    solution: Solution | None = None

    def __post_init__(self) -> None:
        if self.std_kind not in STD_KIND_MEANINGS:
            raise ValueError(f"`std_kind` must be one of {', '.join(STD_KIND_MEANINGS)}, got {self.std_kind!r}")
        if self.sigma_source not in SIGMA_SOURCES:
            raise ValueError(f"`sigma_source` must be one of {', '.join(SIGMA_SOURCES)}, got {self.sigma_source!r}")
        cls = extras_type(self.method) if self.extras is not None else None
        if self.extras is not None and cls is not None and not isinstance(self.extras, cls):
            raise ValueError(f"`extras` of a {self.method} result must be {cls.__name__}, "
                             f"got {type(self.extras).__name__}")

    @property
    def history_names(self) -> tuple[str, ...] | None:
        """Names of the ``history`` columns: the coefficients, then the RELS MA terms ``ma1``, ..."""
        if self.history is None:
            return None
        extra = np.asarray(self.history).shape[1] - len(self.names)
        return tuple(self.names) + tuple(f"ma{j + 1}" for j in range(extra))

    @property
    def identifiable(self) -> np.ndarray:
        """True where an estimate is reported."""
        return np.isfinite(self.estimate)

    def fitted_coefficients(self) -> np.ndarray:
        """The coefficient vector whose fitted values the fit reports (natural units, finite where the fit
        has one): the estimate, or where some coefficient has none the solver's solution
        (:mod:`casep.estimators.solution`: it reproduces the determined combinations; 0 in place of a
        missing estimate would not). A result without a solution (a file of another tool) keeps NaN."""
        if self.solution is not None:
            return np.asarray(self.solution.x, dtype=float)
        return np.asarray(self.estimate, dtype=float)

    @property
    def estimate_si(self) -> np.ndarray:
        """Estimates in SI (rad/s, m/s^2, rad, m/s per the model's SI factors)."""
        return self.estimate * self.si_factors

    @property
    def residual_rms(self) -> dict[str, float | None]:
        """RMS of the residuals per axis, m/s."""
        if self.stored_residual_rms is not None and np.asarray(self.residuals).size == 0:
            return dict(self.stored_residual_rms)
        r = np.asarray(self.residuals).reshape(-1, 3)
        return {a: float(np.sqrt(np.mean(r[:, i] ** 2))) for i, a in enumerate(AXES)}

    @property
    def withheld(self) -> tuple[str, ...]:
        """The coefficients the data do not determine whose solver value is beyond what a linear error model can
        describe (``diagnostics["undetermined_beyond_linear"]``, :func:`casep.estimators._base.check_magnitudes`):
        presented without an estimate, std or covariance (:meth:`presented`), like a coefficient not
        identifiable; the value stays in that record and in ``estimate`` (the fit's own vector)."""
        rows = (self.diagnostics or {}).get("undetermined_beyond_linear") or ()
        return tuple(r["name"] for r in rows if isinstance(r, dict) and "name" in r)

    def presented(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The estimate and std as the text, the JSON, the CSV and the MAT file give them: NaN for the
        coefficients :attr:`withheld` (and for those not identifiable)."""
        est = np.array(self.estimate, dtype=float)
        std = None if self.std is None else np.array(self.std, dtype=float)
        off = [j for j, n in enumerate(self.names) if n in set(self.withheld)]
        est[off] = np.nan
        if std is not None:
            std[off] = np.nan
        return est, std

    def coefficient_rows(self) -> list[dict[str, Any]]:
        """One dict per coefficient: name, unit, estimate, std (None where undefined or :attr:`withheld`),
        reason."""
        rows = []
        estimate, sd = self.presented()
        for j, (name, unit) in enumerate(zip(self.names, self.units)):
            est = _json_float(estimate[j])
            std = None if sd is None or est is None else _json_float(sd[j])
            row: dict[str, Any] = {"name": name, "unit": unit, "estimate": est, "std": std}
            if name in self.reasons:
                row["reason"] = self.reasons[name]
            rows.append(row)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """The result JSON (``docs/guide/result-files.md``, form 3: both forms) as a dict.

        Besides ``coefficients`` (one object per coefficient), the flat parallel arrays
        ``names``, ``units``, ``estimates`` and ``std`` (null only where a value is missing)
        decode as numeric arrays with NaN in MATLAB/Octave ``jsondecode``, where null inside
        the array of objects turns ``coefficients`` into a cell array.
        """
        from casep._version import __version__

        rows = self.coefficient_rows()
        return {
            "casep_version": __version__,
            "model": self.model,
            "method": self.method,
            "denoise": self.denoise,
            "n_samples": int(self.n_samples),
            "coefficients": rows,
            "names": [r["name"] for r in rows],
            "units": [r["unit"] for r in rows],
            "si_factors": [_json_float(v) for v in np.asarray(self.si_factors, dtype=float)],
            "estimates": [r["estimate"] for r in rows],
            "std": [r["std"] for r in rows],
            "std_kind": self.std_kind,
            "sigma_source": self.sigma_source,
            "covariance": self.covariance_rows(),
            "residual_rms": self.residual_rms,
            "sigma": _json_float(self.sigma),
            "rank": int(self.rank),
            "status": int(self.status),
            "success": bool(self.success),
            "message": self.message,
            "settings": self.settings,
            "diagnostics": self.diagnostics,
            "extras": jsonable(dataclasses.asdict(self.extras)) if self.extras is not None else None,
            "history_names": list(self.history_names) if self.history_names is not None else None,
            **({"model_file": self.model_file} if self.model_file else {}),
            **({"model_sha256": self.model_sha256} if self.model_sha256 else {}),
            **({"solution": self.solution.to_dict()} if self.solution is not None else {}),
        }

    @classmethod
    def from_json(cls, source: "str | os.PathLike | dict", model=None) -> "EstimateResult":
        """A result back from its JSON (a file or the dict of :meth:`to_dict`), or from a result file
        of another tool in one of the forms of ``docs/guide/result-files.md``.

        Everything casep's JSON holds comes back (estimates, std, covariance, labels, sigma and its
        source, status, settings, diagnostics); the per-sample residuals and the history are not
        in the JSON, so the result has none (``residual_rms`` then reads the stored values). A file
        of another tool that holds only coefficients gets ``method`` "external", ``sigma`` NaN and
        ``success`` true unless it says otherwise.

        Parameters
        ----------
        source : path or dict
        model : ErrorModel or str, optional
            Check the result against this model: every coefficient one of its (or a several-flight
            result's ``name[file]``), in its unit (ValueError naming coefficient and both units).

        Raises
        ------
        ValueError
            Naming the file and the field: a missing or wrongly typed field, the two forms
            disagreeing, a covariance that is not one (:mod:`casep.io.result_json`).
        """
        from casep.estimators._from_data import result_from_data
        from casep.io.result_json import parse_result_data, read_result_data

        if isinstance(source, dict):
            rd = parse_result_data(source, "result")
        else:
            rd = read_result_data(source, "result")
        return result_from_data(rd, model, cls)

    def covariance_rows(self) -> list[list[float | None]] | None:
        """The n x n covariance in natural units, model order, as nested lists for JSON.

        Rows and columns of coefficients without an estimate (or :attr:`withheld`; and any entry that
        is not finite) are null; None when the method defines no covariance
        (``docs/guide/result-files.md``).
        """
        if self.covariance is None:
            return None
        C = np.array(self.covariance, dtype=float)
        shown = np.isfinite(self.presented()[0])
        C[~shown, :] = np.nan
        C[:, ~shown] = np.nan
        return [[_json_float(v) for v in row] for row in C]

    def to_pandas(self):
        """Coefficient table as a :class:`pandas.DataFrame` indexed by name."""
        import pandas as pd

        return pd.DataFrame(self.coefficient_rows()).set_index("name")

    def settings_line(self) -> str:
        """One line with what the method was given and what it chose (tau, lambda, MA model, ...): its
        extras' ``describe``; for a result without extras (another tool's, fused), its plain settings."""
        describe = getattr(self.extras, "describe", None)
        if describe is not None:
            parts = list(describe(self))
        else:
            parts = [f"{k} {v}" for k, v in self.settings.items() if isinstance(v, (int, float, str)) and k != "sigma"]
        parts.append("sigma not stated (a result file of another tool)" if self.sigma_source == "external"
                     else _sigma_text(self.settings.get("sigma"), self.sigma_source, self.sigma))
        parts.append(f"std {self.std_kind}" + (" on the active set (understated)"
                                                 if self.std_kind == "conditional" else ""))
        return "settings: " + "; ".join(parts)

    table = deprecated_alias("text", "table")

    def text(self) -> str:
        """What the command line prints (the result protocol, :mod:`casep.results`): a fixed-width table
        (name, unit, estimate, std, and why a value is missing), the settings line and the outcome."""
        lines = [f"{'coefficient':<12} {'unit':<10} {'estimate':>12} {'std':>12}  note"]
        for row in self.coefficient_rows():
            note = row.get("reason", "")
            lines.append(f"{row['name']:<12} {row['unit']:<10} {format_number(row['estimate'])} "
                         f"{format_number(row['std'])}  {note}".rstrip())
        rms = self.residual_rms
        lines.append("")
        whitened = self.sigma_source == "whitened"  # several flights: rows divided by their sigma, no unit
        sigma = ("-" if not math.isfinite(self.sigma) else f"{self.sigma:.4g}" if whitened
                 else f"{self.sigma:.4g} m/s")
        lines.append(f"method {self.method}, model {self.model}, {self.n_samples} samples, rank {self.rank}/"
                     f"{len(self.names)}, sigma {sigma}" + (" (whitened, dimensionless)" if whitened else ""))
        lines.append(self.settings_line())
        if all(rms[a] is not None for a in AXES):  # a fused result has no residuals
            lines.append(f"residual RMS ({'whitened, dimensionless' if whitened else 'm/s'}): "
                         + ", ".join(f"{a} {format_number(rms[a], 0, '.4g')}" for a in AXES))
        denoised = {} if not self.denoise else self.denoise.get("flights", {"": self.denoise})  # several: per flight
        for label, d in denoised.items():
            lines.append(f"de-noised{' ' + label if label else ''}: {d.get('wavelet')} level {d.get('level')}, "
                         f"{d.get('threshold_rule')} {d.get('threshold_mode')}, {d.get('extension')} extension; raw "
                         "noise sigma " + ", ".join(f"{a} {d['sigma'][a]:.4g}" for a in AXES)
                         + " m/s (residuals after de-noising understate the noise)")
        cn = self.diagnostics.get("condition_number_equilibrated")
        if cn is not None:
            lines.append(f"condition number: {self.diagnostics.get('condition_number') or float('inf'):.3g} "
                         f"(natural units), {cn:.3g} (columns equilibrated)")
        lines.append(self.message)
        if self.diagnostics.get("warning"):
            lines.append("warning: " + self.diagnostics["warning"])
        return "\n".join(lines)


def write_mat(res: EstimateResult, path: str | os.PathLike, *, t: np.ndarray | None = None,
              provenance: Mapping[str, Any] | None = None) -> None:
    """Write the result as a MATLAB/Octave ``.mat`` file (:func:`casep.io.result_files.write_mat_fields`).

    With `t` (the times of the residual rows, s) the file holds ``t_residuals`` beside ``residuals``;
    the near-dependency groups are ``groups`` (a cell array of cellstr); with `provenance`
    (:func:`casep.io.provenance.provenance`) ``provenance_json`` holds it whole (``jsondecode`` in
    MATLAB) and ``input_files``, ``input_sha256``, ``input_roles`` (cellstr) and ``command_line`` the
    essentials.

    Variables: ``names``, ``units`` (cellstr); ``estimates``, ``std`` (n x 1 double, NaN
    where missing or :attr:`EstimateResult.withheld`), ``covariance`` (n x n, NaN rows/columns there), ``residuals``
    (N x 3, m/s), ``history`` (recursive methods), scalars ``sigma``, ``rank``, ``status``,
    ``success``, strings ``method``, ``model``, ``message``, ``std_kind``, ``reasons``
    (cellstr, "" where none) and the structs ``settings``, ``diagnostics``, ``denoise``, ``extras``
    where their fields are simple (numbers, strings, flat lists, nested such structs).
    """
    n = len(res.names)
    estimate, sd = res.presented()
    cov = res.covariance_rows()
    data: dict[str, Any] = {
        "names": np.array(res.names, dtype=object),
        "units": np.array(res.units, dtype=object),
        "estimates": estimate,
        "std": np.full(n, np.nan) if sd is None else sd,
        "covariance": np.full((n, n), np.nan) if cov is None else np.array(cov, dtype=float),
        "residuals": np.asarray(res.residuals, dtype=float).reshape(-1, 3),
        "reasons": np.array([res.reasons.get(nm, "") for nm in res.names], dtype=object),
        "sigma": float(res.sigma), "rank": float(res.rank), "status": float(res.status),
        "success": bool(res.success), "n_samples": float(res.n_samples),
        "method": res.method, "model": res.model, "message": res.message, "std_kind": res.std_kind,
    }
    if res.history is not None:
        data["history"] = np.asarray(res.history, dtype=float)
    if t is not None:
        t = np.asarray(t, dtype=float).reshape(-1)
        if t.size != data["residuals"].shape[0]:
            raise ValueError(f"`t` has {t.size} times for {data['residuals'].shape[0]} residual rows")
        data["t_residuals"] = t
    groups = res.diagnostics.get("groups") or []
    cell = np.empty((len(groups),), dtype=object)
    for k, g in enumerate(groups):
        cell[k] = np.array(list(g), dtype=object)
    data["groups"] = cell
    if provenance is not None:
        data["provenance_json"] = json.dumps(jsonable(provenance))
        data["command_line"] = str(provenance.get("command_line", ""))
        files = provenance.get("inputs", [])
        for key, field_name in (("input_files", "file"), ("input_sha256", "sha256"), ("input_roles", "role")):
            data[key] = np.array([str(f.get(field_name) or "") for f in files], dtype=object)
    structs = {k: getattr(res, k) for k in ("settings", "diagnostics", "denoise")}
    structs["extras"] = jsonable(dataclasses.asdict(res.extras)) if res.extras is not None else None
    write_mat_fields(data, path, structs=structs)


def write_csv(res: EstimateResult, path: str | os.PathLike) -> None:
    """Write one row per coefficient (name, unit, estimate, std, reason) atomically
    (:func:`casep.io.result_files.write_coefficients_csv`)."""
    write_coefficients_csv(res.coefficient_rows(), path)
