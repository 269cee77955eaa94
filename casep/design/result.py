"""The result of a manoeuvre design (:func:`casep.design.optimize.design`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.design.maneuver import Maneuver
from casep.results import deprecated_alias

__all__ = ["DesignResult"]


@dataclass
class DesignResult:
    """A designed manoeuvre, its objective before/after and the CRLB per coefficient.

    ``crlb_before`` / ``crlb_after``: std per coefficient (natural units; NaN = undetermined) of the
    nominal and the designed flight, exact (their S_V at the scenario's rate) when verified, else the
    design model's prediction (``predicted``).
    """

    objective: str
    maneuver: Maneuver
    x: np.ndarray
    names: tuple[str, ...]
    units: tuple[str, ...]
    scales: np.ndarray
    before: float
    after: float
    crlb_before: np.ndarray
    crlb_after: np.ndarray
    predicted_before: np.ndarray
    predicted_after: np.ndarray
    constraints: dict
    solver: dict
    scenario: Any  # the designed Scenario (simulate it with casep.simulation.simulate.simulate_flight)
    prior: bool
    timing: dict
    coefficients: tuple[str, ...] | None = None
    verification: dict = field(default_factory=dict)
    #: The nominal scenario's name (of a registered scenario) and one's own trajectory file, if any.
    nominal: str | None = None
    own_flight: str | None = None

    @property
    def profile(self):
        return self.maneuver.profile(self.x)

    def identifiable(self, which: str = "after") -> list[str]:
        """Coefficients whose CRLB std is below their declared magnitude."""
        c = self.crlb_after if which == "after" else self.crlb_before
        return [n for n, v, s in zip(self.names, c, self.scales) if np.isfinite(v) and v < s]

    @property
    def success(self) -> bool:
        """Whether the optimiser solved the design problem from its best start."""
        return bool(self.solver.get("success", False))

    @property
    def status(self) -> int:
        """0: solved; 1: the optimiser did not converge from any start (the best iterate is reported)."""
        return 0 if self.success else 1

    @property
    def message(self) -> str:
        """The optimiser's return status of the best start, and what it means for the design."""
        how = self.solver.get("return_status", "no status")
        return (f"manoeuvre designed ({how})" if self.success else
                f"the optimiser did not converge ({how}): the design is its best iterate, not an optimum")

    def text(self) -> str:
        """What ``casep design`` prints (:func:`casep.design.flown.design_lines`)."""
        from casep.design.flown import design_lines

        return "\n".join(design_lines(self, scenario=str(self.nominal or getattr(self.scenario, "name", "?")),
                                       maneuver=self.maneuver.kind, own_flight=self.own_flight))

    def to_dict(self) -> dict:
        """The ``casep design --json`` document (``docs/reference/file-formats.md`` "Design JSON"; null for NaN)."""
        return _finite(self._json())

    to_json = deprecated_alias("to_dict", "to_json")

    def _json(self) -> dict:
        def d(a):
            return {n: (None if not np.isfinite(v) else float(v)) for n, v in zip(self.names, a)}

        v = self.verification or {}
        from casep.design.objective import REGULARISATION

        return {
            # before/after: exact on the re-simulated flights when verified; the design model's values in `predicted`
            "objective": self.objective, "before": v.get("before", self.before), "after": v.get("after", self.after),
            "objective_source": "re-simulated flights" if v else "design model",
            "regularisation": None if self.prior else {
                "information": REGULARISATION,
                "note": "without --prior the objective adds information eps I in coefficients scaled by their declared "
                        "magnitude (a vague prior of std 10 magnitudes), so unidentifiable coefficients are finite"},
            "coefficients": None if self.coefficients is None else list(self.coefficients),
            "maneuver": self.maneuver.to_dict(self.x),
            "crlb_before": d(self.crlb_before), "crlb_after": d(self.crlb_after),
            "constraints": self.constraints,
            "predicted": {"before": self.before, "after": self.after,
                          "crlb_before": d(self.predicted_before), "crlb_after": d(self.predicted_after),
                          "note": "design model: nominal specific force rotated by the offsets on the design grid "
                                  "(the manoeuvre's effect on the trajectory neglected)"},
            "units": dict(zip(self.names, self.units)),
            "scales": d(self.scales),
            "identifiable_before": self.identifiable("before"), "identifiable_after": self.identifiable("after"),
            "bound": "Bayesian (prior)" if self.prior else "Cramer-Rao (white noise)",
            "solver": self.solver, "verification": self.verification, "timing_s": self.timing,
            "scenario": {"name": self.scenario.name, "rate_hz": self.scenario.rate,
                         "noise_sigma": self.scenario.noise.sigma},
        }

    def worse(self, factor: float = 1.05) -> list[str]:
        """Coefficients whose bound grows by more than `factor` (a design trades some for others)."""
        r = self.crlb_after / self.crlb_before
        return [n for n, v in zip(self.names, r) if np.isfinite(v) and v > factor]

    table = deprecated_alias("crlb_table", "table")

    def crlb_table(self) -> str:
        """The bound per coefficient before and after the design, and their ratio (part of :meth:`text`)."""
        kind = "post. std" if self.prior else "CRLB"
        lines = [f"{'name':<8} {'unit':<10} {'scale':>9} {kind + ' before':>12} {kind + ' after':>12} {'ratio':>7}"]
        for n, u, s, b, a in zip(self.names, self.units, self.scales, self.crlb_before, self.crlb_after):
            r = a / b if np.isfinite(a) and np.isfinite(b) and b > 0 else math.nan
            lines.append(f"{n:<8} {u:<10} {s:>9.3g} {b:>12.4g} {a:>12.4g} {r:>7.3f}")
        return "\n".join(lines)


def _finite(v: Any) -> Any:
    """JSON-safe: non-finite floats -> None, numpy scalars and arrays -> Python."""
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_finite(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if np.isfinite(v) else None
    return v
