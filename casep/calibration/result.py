"""The outcome of a ground test: :class:`Calibration` (the result protocol of :mod:`casep.results`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from casep.calibration.model import CalibrationModel
from casep.results import deprecated_alias

__all__ = ["Calibration"]


@dataclass(frozen=True)
class Calibration:
    """The outcome of :func:`casep.calibrate`: ``to_dict()`` (the calibration JSON) and ``text()`` (the report).

    Attributes
    ----------
    result : EstimateResult
        Every coefficient in model order: estimate, std, covariance (block diagonal: the two
        sensors are independent regressions), natural units; ``sigma`` NaN (each sensor has its
        own, :attr:`sensors`).
    sensors : dict
        ``"accelerometer"`` / ``"gyro"`` -> that regression's EstimateResult (its sigma in the
        reading unit, its diagnostics).
    segments : list of dict
        Per segment: name, kind, rows, samples, and per sensor the misfit of the segment's row
        (reading units), the noise std of that row from the sample scatter, their ratio.
    model : CalibrationModel
    settings : dict
    segmentation : FerrarisSegmentation or None
        The segments found without labels (``--segments auto``), else None.
    """

    result: Any
    sensors: dict
    segments: list
    model: CalibrationModel
    settings: dict = field(default_factory=dict)
    segmentation: Any = None

    @property
    def names(self) -> tuple[str, ...]:
        """Coefficient names, model order."""
        return tuple(self.result.names)

    def value(self, name: str) -> float:
        """Estimate of coefficient `name`, natural unit."""
        return float(self.result.estimate[self.model.index(name)])

    def std(self, name: str) -> float:
        """Standard deviation of coefficient `name`, natural unit."""
        return float(self.result.std[self.model.index(name)])

    @property
    def success(self) -> bool:
        """Whether every sensor's regression succeeded (the combined result's own success included)."""
        return bool(self.result.success) and all(bool(r.success) for r in self.sensors.values())

    @property
    def status(self) -> int:
        """The combined result's status (:class:`~casep.estimators.result.EstimateResult`), or the first
        failing sensor's."""
        failed = [r for r in self.sensors.values() if not r.success]
        return int(failed[0].status if failed else self.result.status)

    @property
    def message(self) -> str:
        """Each sensor's message, named: ``accelerometer: ...; gyro: ...``."""
        return "; ".join(f"{k}: {r.message}" for k, r in self.sensors.items()) or str(self.result.message)

    def to_dict(self) -> dict:
        """The calibration JSON: a casep result (``coefficients``, ``covariance``, ... usable as
        ``--prior``) plus ``calibration`` (model, flight model, per-sensor fits, segments)."""
        d = self.result.to_dict()
        d["calibration"] = {
            "model": self.model.name, "flight_model": self.model.flight_model, "readings": self.model.readings,
            "settings": self.settings,
            "sensors": {k: {"sigma": _f(r.sigma), "sigma_source": r.sigma_source, "status": r.status,
                            "message": r.message, "names": list(r.names), "diagnostics": r.diagnostics}
                        for k, r in self.sensors.items()},
            "segments": self.segments,
        }
        if self.segmentation is not None:
            d["calibration"]["segmentation"] = self.segmentation.to_dict()
        return d

    def text(self) -> str:
        """Readable terminal report: coefficients, per-sensor fit, misfit per segment."""
        from casep.estimators.result import format_number

        lines = [f"{'coefficient':<12} {'unit':<14} {'estimate':>14} {'std':>12}  note"]
        for row in self.result.coefficient_rows():
            lines.append(f"{row['name']:<12} {row['unit']:<14} {format_number(row['estimate'], 14)} "
                         f"{format_number(row['std'])}  {row.get('reason', '')}".rstrip())
        lines.append("")
        s = self.settings
        lines.append(f"model {self.model.name}, method {self.result.method}, weighting {s['weighting']}, "
                     f"g {s['gravity']:.6g} m/s^2, {s['rate_hz']:.6g} Hz, readings {s['acc_unit']} / {s['gyr_unit']}")
        for k, r in self.sensors.items():
            unit = s["acc_unit"] if k == "accelerometer" else s["gyr_unit"]
            cn = r.diagnostics.get("condition_number_equilibrated")
            whitened = s["weighting"] == "positions"
            what = "(rows whitened: 1 = the position and noise model)" if whitened else unit
            lines.append(f"{k}: sigma {r.sigma:.4g} {what} "
                         f"({r.sigma_source}, {r.diagnostics.get('rows', '?')} rows, rank {r.rank}/{len(r.names)})"
                         + (f", condition number {cn:.3g} (equilibrated)" if cn else "") + f"; {r.message}")
            if "position_error_deg" in r.diagnostics and k == "accelerometer":
                dof = r.diagnostics.get("position_error_dof")
                lines.append(f"  position error {r.diagnostics['position_error_deg']:.3g} deg rms (estimated from the "
                             f"misfit of the positions, {dof} degrees of freedom"
                             + ("; few: the std of the coefficients it drives are themselves uncertain)"
                                if dof is not None and dof < 10 else ")"))
            if r.diagnostics.get("groups"):
                lines.append("  near-dependencies: " + "; ".join("[" + ", ".join(g) + "]"
                                                                for g in r.diagnostics["groups"]))
        if self.segmentation is not None:
            lines += ["", self.segmentation.text()]
        lines.append("")
        lines.append("misfit per segment (row residual per axis; noise: std of the row from the sample scatter)")
        for seg in self.segments:
            for sensor, m in seg.get("misfit", {}).items():
                res = ", ".join(f"{v:+.4g}" for v in m["residual"])
                noise = ", ".join(f"{v:.3g}" for v in m["noise_std"])
                lines.append(f"  {seg['name']:<8} {seg['kind']:<8} {sensor:<13} residual [{res}]  noise [{noise}]"
                             f"  ratio {m['ratio']:.3g}")
        return "\n".join(lines)

    report = deprecated_alias("text", "report")


def _f(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None

