"""The result type shared by every estimator, with its table and JSON forms."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._io import atomic_open

__all__ = ["EstimateResult", "write_json_atomic", "format_number"]

AXES = ("x", "y", "z")


def format_number(v: float | None, width: int = 12) -> str:
    """Right-aligned ``%.6g`` with ``-`` for a missing value."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-".rjust(width)
    return f"{v:.6g}".rjust(width)


def _json_float(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


@dataclass(frozen=True)
class EstimateResult:
    """Estimated error coefficients with their uncertainty and how they were obtained.

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
        The options used.
    diagnostics : dict
        Condition numbers and identifiability (see ``interfaces.md``).
    model : str
        Model name.
    n_samples : int
        Samples used.
    denoise : dict or None
        De-noising settings and per-axis noise sigma, or None.
    history : ndarray or None
        Estimate after each sample for recursive methods, natural units.
    history_std : ndarray or None
        Standard deviation at the ``history`` rows (recursive methods), natural units,
        ``sqrt(diag(sigma^2 w P_k))`` with the final ``sigma``.
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

    @property
    def identifiable(self) -> np.ndarray:
        """True where an estimate is reported."""
        return np.isfinite(self.estimate)

    @property
    def estimate_si(self) -> np.ndarray:
        """Estimates in SI (rad/s, m/s^2, rad, m/s per the model's SI factors)."""
        return self.estimate * self.si_factors

    @property
    def residual_rms(self) -> dict[str, float]:
        """RMS of the residuals per axis, m/s."""
        r = np.asarray(self.residuals).reshape(-1, 3)
        return {a: float(np.sqrt(np.mean(r[:, i] ** 2))) for i, a in enumerate(AXES)}

    def coefficient_rows(self) -> list[dict[str, Any]]:
        """One dict per coefficient: name, unit, estimate, std (None where undefined), reason."""
        rows = []
        for j, (name, unit) in enumerate(zip(self.names, self.units)):
            est = _json_float(self.estimate[j])
            std = None if self.std is None or est is None else _json_float(self.std[j])
            row: dict[str, Any] = {"name": name, "unit": unit, "estimate": est, "std": std}
            if name in self.reasons:
                row["reason"] = self.reasons[name]
            rows.append(row)
        return rows

    def to_dict(self) -> dict[str, Any]:
        """The result JSON of ``interfaces.md`` as a dict."""
        from . import __version__

        return {
            "casep_version": __version__,
            "model": self.model,
            "method": self.method,
            "denoise": self.denoise,
            "n_samples": int(self.n_samples),
            "coefficients": self.coefficient_rows(),
            "residual_rms": self.residual_rms,
            "sigma": _json_float(self.sigma),
            "rank": int(self.rank),
            "status": int(self.status),
            "success": bool(self.success),
            "message": self.message,
            "settings": self.settings,
            "diagnostics": self.diagnostics,
        }

    def to_pandas(self):
        """Coefficient table as a :class:`pandas.DataFrame` indexed by name."""
        import pandas as pd

        return pd.DataFrame(self.coefficient_rows()).set_index("name")

    def table(self) -> str:
        """Readable fixed-width table: name, unit, estimate, std, and why a value is missing."""
        lines = [f"{'coefficient':<12} {'unit':<10} {'estimate':>12} {'std':>12}  note"]
        for row in self.coefficient_rows():
            note = row.get("reason", "")
            lines.append(f"{row['name']:<12} {row['unit']:<10} {format_number(row['estimate'])} "
                         f"{format_number(row['std'])}  {note}".rstrip())
        rms = self.residual_rms
        lines.append("")
        lines.append(f"method {self.method}, model {self.model}, {self.n_samples} samples, rank {self.rank}/"
                     f"{len(self.names)}, sigma {self.sigma:.4g} m/s")
        lines.append("residual RMS (m/s): " + ", ".join(f"{a} {rms[a]:.4g}" for a in AXES))
        if self.denoise:
            d = self.denoise
            lines.append(f"de-noised: {d.get('wavelet')} level {d.get('level')}, {d.get('threshold_rule')} "
                         f"{d.get('threshold_mode')}, {d.get('extension')} extension; raw noise sigma "
                         + ", ".join(f"{a} {d['sigma'][a]:.4g}" for a in AXES)
                         + " m/s (residuals after de-noising understate the noise)")
        cn = self.diagnostics.get("condition_number_equilibrated")
        if cn is not None:
            lines.append(f"condition number: {self.diagnostics.get('condition_number') or float('inf'):.3g} "
                         f"(natural units), {cn:.3g} (columns equilibrated)")
        lines.append(self.message)
        if self.diagnostics.get("warning"):
            lines.append("warning: " + self.diagnostics["warning"])
        return "\n".join(lines)


def write_json_atomic(data: dict[str, Any], path: str | os.PathLike) -> None:
    """Write JSON to `path` through a temporary file and a rename: never half-written."""
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    with atomic_open(path) as fh:
        fh.write(text)
