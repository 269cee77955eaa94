"""The miss budget of an estimate on one trajectory: :class:`ImpactAnalysis` (``docs/reference/file-formats.md``
"Impact JSON"), computed by :func:`casep.impact.miss.impact_analysis`.

It follows the result protocol (:mod:`casep.results`): ``to_dict()`` is the impact JSON,
``text()`` the table ``casep impact`` prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from casep.results import Completed, deprecated_alias

__all__ = ["ImpactAnalysis", "Group"]


def _f(v: Any) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


@dataclass(frozen=True)
class Group:
    """A near-dependency group's share of the miss: members, contribution and its std, m."""

    names: tuple[str, ...]
    contribution: np.ndarray  # (2,) downrange, crossrange; over the members with an estimate
    std: np.ndarray | None  # (2,) from the members' covariance block

    def to_dict(self) -> dict[str, Any]:
        return {"names": list(self.names), "downrange": _f(self.contribution[0]),
                "crossrange": _f(self.contribution[1]),
                "std_downrange": None if self.std is None else _f(self.std[0]),
                "std_crossrange": None if self.std is None else _f(self.std[1])}


@dataclass(frozen=True)
class ImpactAnalysis(Completed):
    """The miss budget of an estimate on one trajectory (``docs/reference/file-formats.md`` "Impact JSON").

    ``success``, ``status`` and ``message`` of the result protocol: a success (status 0) unless the miss is
    not determined by the result (status -1: coefficients the data determine only in a combination whose
    miss sensitivity is not in the row space of S_V, said in ``undetermined_note``); coefficients without an
    estimate are in ``coefficient_status``.

    Attributes
    ----------
    names, units, coefficient_status : tuple of str
        Coefficients (model order), natural units, and ``"estimated"``, ``"no estimate"`` or
        ``"per-flight"`` (a per-flight coefficient absent from a several-flight result: its
        value given or 0).
    estimate : (n,) ndarray
        Coefficients used, natural units (NaN: no estimate, contributes nothing).
    t_b, r_b, v_b
        Burnout time (s), position (m) and velocity (m/s), launch-inertial frame.
    nominal : (2,) ndarray
        Impact of the burnout state: downrange, crossrange, m.
    jacobian : (2, 6) ndarray
        ``d(downrange, crossrange) / d(r_b, v_b)`` (exact, CasADi).
    sp, sv : (3, n) ndarray
        ``S_P(t_b)`` (m per unit) and ``S_V(t_b)`` (m/s per unit).
    sensitivity : (2, n) ndarray
        Miss per natural unit of each coefficient, m: ``G = -J [S_P; S_V]``.
    contributions : (2, n) ndarray
        ``G_j D_j``, m; NaN where there is no estimate.
    miss : (2,) ndarray
        Linear predicted miss ``G D``, m: the sum of the contributions, or where coefficients are determined
        only in combination ``G x`` with the solver's solution (:mod:`casep.estimators.solution`); NaN where
        not determined.
    cov : (2, 2) ndarray or None
        ``G Cov G^T`` over the estimated coefficients, m^2.
    nonlinear : (2,) ndarray
        ``impact(x_b - dx_b) - impact(x_b)``, m.
    groups : tuple of Group
        Contributions per near-dependency group (a coefficient may be in several groups).
    coefficient_std : (n,) ndarray or None
        Std of each coefficient used (natural units; NaN without estimate, 0 for a per-flight value).
    determined : (2,) bool ndarray
        Whether the downrange and crossrange miss are determined by the result.
    undetermined_note : str
        Why not, with the numbers ("" when determined).
    """

    what: ClassVar[str] = "impact miss budget"

    names: tuple[str, ...]
    units: tuple[str, ...]
    coefficient_status: tuple[str, ...]
    estimate: np.ndarray
    t_b: float
    r_b: np.ndarray
    v_b: np.ndarray
    nominal: np.ndarray
    impact_point: np.ndarray
    jacobian: np.ndarray
    sp: np.ndarray
    sv: np.ndarray
    sensitivity: np.ndarray
    contributions: np.ndarray
    miss: np.ndarray
    cov: np.ndarray | None
    nonlinear: np.ndarray
    groups: tuple[Group, ...]
    group_source: str
    covariance_source: str
    model: str
    method: str
    flight: str
    coefficient_std: np.ndarray | None = None
    trajectory: str | None = None
    result: str = "<memory>"
    reasons: dict = field(default_factory=dict)
    determined: np.ndarray = field(default_factory=lambda: np.ones(2, dtype=bool))
    undetermined_note: str = ""

    @property
    def success(self) -> bool:
        """False when the miss is not determined by the result."""
        return bool(np.all(self.determined))

    @property
    def status(self) -> int:
        """0, or -1 when the miss is not determined."""
        return 0 if self.success else -1

    @property
    def message(self) -> str:
        """What the result is, or why its miss is not determined."""
        return self.what if self.success else self.undetermined_note

    @property
    def std(self) -> np.ndarray | None:
        """Std of the predicted miss (downrange, crossrange), m."""
        from casep.regression.linalg import covariance_std

        return None if self.cov is None else covariance_std(self.cov)

    @property
    def dx_b(self) -> np.ndarray:
        """Navigation error at burnout ``(dr_b, dv_b)`` of the coefficients with a value, (6,)."""
        D = np.nan_to_num(self.estimate, nan=0.0)
        return np.concatenate([self.sp @ D, self.sv @ D])

    def to_dict(self) -> dict[str, Any]:
        """The impact JSON of ``docs/reference/file-formats.md`` (plus labels, the Jacobian, groups and sources)."""
        std = self.std
        sens = [{"name": n, "unit": u, "dr": [_f(x) for x in self.sp[:, j]], "dv": [_f(x) for x in self.sv[:, j]],
                 "downrange": _f(self.sensitivity[0, j]), "crossrange": _f(self.sensitivity[1, j])}
                for j, (n, u) in enumerate(zip(self.names, self.units))]
        contrib = []
        for j, n in enumerate(self.names):
            row: dict[str, Any] = {"name": n, "downrange": _f(self.contributions[0, j]),
                                   "crossrange": _f(self.contributions[1, j]), "estimate": _f(self.estimate[j]),
                                   "status": self.coefficient_status[j]}
            if self.coefficient_status[j] == "no estimate":
                row["note"] = "no estimate" + (
                    f" ({self.reasons[n]})" if n in self.reasons else "")
            elif self.coefficient_status[j] == "per-flight":
                row["note"] = "per-flight coefficient not in the result: value given, or 0"
            contrib.append(row)
        return {
            "model": self.model, "method": self.method, "flight": self.flight, "trajectory": self.trajectory,
            "result": self.result,
            "burnout": {"t": _f(self.t_b), "r": [_f(x) for x in self.r_b], "v": [_f(x) for x in self.v_b]},
            "nominal_impact": {"downrange": _f(self.nominal[0]), "crossrange": _f(self.nominal[1]),
                               "point": [_f(x) for x in self.impact_point]},
            "jacobian": [[_f(x) for x in row] for row in self.jacobian],
            "sensitivity": sens,
            "miss": {"downrange": _f(self.miss[0]), "crossrange": _f(self.miss[1]),
                     "std_downrange": None if std is None else _f(std[0]),
                     "std_crossrange": None if std is None else _f(std[1]),
                     "cov": None if self.cov is None else [[_f(x) for x in row] for row in self.cov],
                     "nonlinear": {"downrange": _f(self.nonlinear[0]), "crossrange": _f(self.nonlinear[1])},
                     "covariance_source": self.covariance_source},
            "contributions": contrib,
            "no_estimate": [n for n, s in zip(self.names, self.coefficient_status) if s == "no estimate"],
            "groups": [g.to_dict() for g in self.groups],
            "group_source": self.group_source,
            "success": self.success, "status": self.status, "message": self.message,
        }

    to_json = deprecated_alias("to_dict", "to_json")
    table = deprecated_alias("text", "table")

    def text(self, top: int | None = None) -> str:
        """Terminal text: burnout, nominal impact, miss with std, budget per coefficient and per group.

        `top`: only the `top` (>= 1) largest contributions (by ``|downrange| + |crossrange|``); default all.
        """
        from casep.estimators.result import format_number

        if top is not None and (isinstance(top, bool) or not isinstance(top, (int, np.integer)) or top < 1):
            raise ValueError(f"`top` must be an integer >= 1 (or None for all), got {top!r}")

        std = self.std
        lines = [f"impact of {self.trajectory or self.flight}: model {self.model}, result of method {self.method}"
                 + (f" (estimated on {self.flight})" if self.trajectory else ""),
                 f"burnout t {self.t_b:.3f} s, r [{', '.join(f'{x:.1f}' for x in self.r_b)}] m, "
                 f"v [{', '.join(f'{x:.2f}' for x in self.v_b)}] m/s",
                 f"nominal impact: downrange {self.nominal[0]:.1f} m, crossrange {self.nominal[1]:.1f} m", ""]
        def pm(i: int) -> str:
            if not self.determined[i]:
                return "not determined"
            return f"{self.miss[i]:.4g}" + (f" +- {std[i]:.4g}" if std is not None else "") + " m"

        lines.append(f"predicted miss (linear): downrange {pm(0)}, crossrange {pm(1)}")
        lines.append(f"nonlinear miss (perturbed burnout state flown): downrange {self.nonlinear[0]:.4g} m, "
                     f"crossrange {self.nonlinear[1]:.4g} m")
        lines.append(f"std from {self.covariance_source}")
        lines.append("")
        lines.append(f"{'coefficient':<12} {'unit':<10} {'estimate':>12} {'m/unit down':>12} {'m/unit cross':>12} "
                     f"{'miss down m':>12} {'miss cross m':>12}")
        order = np.argsort(-np.nan_to_num(np.abs(self.contributions).sum(axis=0), nan=-1.0), kind="stable")
        if top is not None:
            order = order[:top]
        for j in order:
            note = "  no estimate" if self.coefficient_status[j] == "no estimate" else (
                "  per-flight" if self.coefficient_status[j] == "per-flight" else "")
            lines.append(f"{self.names[j]:<12} {self.units[j]:<10} {format_number(_f(self.estimate[j]))} "
                         f"{format_number(self.sensitivity[0, j])} {format_number(self.sensitivity[1, j])} "
                         f"{format_number(_f(self.contributions[0, j]))} {format_number(_f(self.contributions[1, j]))}"
                         f"{note}")
        if self.groups:
            lines.append("")
            lines.append(f"per near-dependency group ({self.group_source}):")
            for g in self.groups:
                s = "" if g.std is None else f" (std {g.std[0]:.4g}, {g.std[1]:.4g})"
                lines.append(f"  down {g.contribution[0]:.4g} m, cross {g.contribution[1]:.4g} m{s}: "
                             + ", ".join(g.names))
        missing = [n for n, s in zip(self.names, self.coefficient_status) if s == "no estimate"]
        if missing:
            lines.append("")
            lines.append(f"no estimate one by one: {', '.join(missing)}" + (
                " (the miss holds what the data determine of their combinations)" if self.success else ""))
        if not self.success:
            lines.append("")
            lines.append(f"FAILED: {self.undetermined_note}")
        return "\n".join(lines)
