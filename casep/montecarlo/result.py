"""The result of a Monte Carlo campaign: per-method, per-coefficient statistics.

Statistics per method and coefficient (natural units): ``bias`` = mean error, ``rms``,
``crlb_std`` (white: sigma^2 (S^T S)^-1; Gauss-Markov scenarios: the GLS bound; dispersed:
the RMS over the runs of each run's bound), ``efficiency`` = crlb_std / rms, ``coverage95`` =
share of runs with ``|error| <= 1.96 std`` among the runs that report a std for that
coefficient (bounded least squares reports none on a bound; null when the method gives none).
With a truth prior each run's error is against its own drawn truth and ``true`` is the prior
mean.

A coefficient is *determined* when its CRLB std is finite, the bound as ``casep separate`` and
``casep diagnose`` report it (:func:`casep.montecarlo.tasks.reported_crlb`: an exactly dependent
coefficient whose partners the flight barely excites has the bound of the solution of least size in
declared magnitudes); the others (a zero or exactly dependent column: only combinations of them are
determined, no method gives each an estimate) are listed as such and left out of the summary, which
pools over the determined ones: ``RMS z`` = ``sqrt(mean(((estimate - truth) / std)^2))`` and the 95 %
coverage over every run and determined coefficient with a std.
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from casep.io._atomic import atomic_open
from casep.results import Completed, deprecated_alias

__all__ = ["MonteCarloResult", "write_figure"]


@dataclass(frozen=True)
class MonteCarloResult(Completed):
    """Per-method, per-coefficient Monte Carlo statistics (see the module notes).

    Follows the result protocol of :mod:`casep.results`: :meth:`to_dict` (the Monte Carlo
    JSON), :meth:`text` (what ``casep montecarlo`` prints); a campaign that returns has completed
    (``success`` True, ``status`` 0: a run that fails stops the campaign with its error).
    """

    what: ClassVar[str] = "Monte Carlo campaign"

    scenario: str
    runs: int
    seed: int
    names: tuple[str, ...]
    units: tuple[str, ...]
    truth: np.ndarray
    crlb_std: np.ndarray
    estimates: dict[str, np.ndarray]  # method -> (runs, n)
    stds: dict[str, np.ndarray | None]
    seconds: dict[str, float] = field(default_factory=dict)
    truths: np.ndarray | None = None  # (runs, n) when each run drew its own (truth from a prior)
    dispersions: tuple[str, ...] = ()  # the dispersed vehicle/launch parameters (crlb_std: RMS over the runs)
    rate: float | None = None  # sample rate of the simulated flights, Hz
    resumed: int = 0  # tasks read back from --out (a resumed campaign) ...
    tasks: int = 0  # ... of this many
    draws: dict[str, np.ndarray] = field(default_factory=dict)  # dispersion parameter -> (runs,) drawn values
    # the noise: {"simulated": the runs' noise (casep.simulation.noise.NoiseModel.to_dict() plus "text"),
    # "fit": {"noise", "tau", "robust"} the methods assume}
    noise: dict[str, Any] = field(default_factory=dict)
    # the model's declared magnitudes (ErrorModel.scales): which coefficients the CRLB determines better than them
    magnitudes: dict[str, float] = field(default_factory=dict)

    def stats(self, method: str) -> dict[str, np.ndarray]:
        """bias, rms, efficiency, coverage95 arrays of one method (NaN where undefined)."""
        E = self.estimates[method] - (self.truth if self.truths is None else self.truths)
        with np.errstate(invalid="ignore", divide="ignore"):
            bias = np.mean(E, axis=0)
            rms = np.sqrt(np.mean(E**2, axis=0))
            eff = self.crlb_std / rms
            sd = self.stds.get(method)
            if sd is None:
                cov = np.full(E.shape[1], np.nan)
            else:  # over the runs that report an interval (bounded: not on a bound)
                has = np.isfinite(sd) & np.isfinite(E)
                hit = (np.abs(E) <= 1.96 * np.where(has, sd, 0.0)) & has
                cov = np.where(has.any(axis=0), hit.sum(axis=0) / np.maximum(has.sum(axis=0), 1), np.nan)
        return {"bias": bias, "rms": rms, "efficiency": eff, "coverage95": cov}

    @property
    def determined(self) -> np.ndarray:
        """(n,) bool: coefficients with a finite CRLB std (module notes); the others are unidentifiable."""
        return np.isfinite(self.crlb_std) & (self.crlb_std > 0)

    def pooled(self, method: str) -> dict[str, Any]:
        """RMS z and 95 % coverage of a method over every run and determined coefficient with a std (module
        notes); None where the method gives no std."""
        sd = self.stds.get(method)
        if sd is None:
            return {"rms_z": None, "coverage95": None, "count": 0}
        E = self.estimates[method] - (self.truth if self.truths is None else self.truths)
        has = np.isfinite(sd) & np.isfinite(E) & (sd > 0) & self.determined
        z = np.abs(E[has]) / sd[has]
        if not z.size:
            return {"rms_z": None, "coverage95": None, "count": 0}
        return {"rms_z": float(np.sqrt(np.mean(z**2))), "coverage95": float(np.mean(z <= 1.96)), "count": int(z.size)}

    def to_dict(self) -> dict[str, Any]:
        """The Monte Carlo JSON of ``docs/reference/file-formats.md``."""
        def f(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        methods: dict[str, Any] = {}
        for meth in self.estimates:
            st = self.stats(meth)
            methods[meth] = {"seconds": self.seconds.get(meth), "determined": self.pooled(meth), "coefficients": [
                {"name": n, "unit": u, "true": float(tr), "bias": f(st["bias"][j]), "rms": f(st["rms"][j]),
                 "crlb_std": f(self.crlb_std[j]), "efficiency": f(st["efficiency"][j]),
                 "coverage95": f(st["coverage95"][j])}
                for j, (n, u, tr) in enumerate(zip(self.names, self.units, self.truth))]}
        out: dict[str, Any] = {"scenario": self.scenario, "runs": self.runs, "seed": self.seed}
        if self.rate is not None:
            out["rate_hz"] = float(self.rate)
        if self.truths is not None:
            out["truth_from_prior"] = True  # "true": the prior mean; errors against each run's own draw
        if self.dispersions:
            out["dispersions"] = list(self.dispersions)
        if self.noise:
            out["noise"] = self.noise
        det = self.determined
        out["determined"] = [n for n, d in zip(self.names, det) if d]
        out["unidentifiable"] = [n for n, d in zip(self.names, det) if not d]
        out["not_determined"] = [self.names[j] for j in self._not_determined()]
        out["methods"] = methods
        return out

    def write_json(self, path: str | os.PathLike) -> None:
        """Write :meth:`to_dict` as JSON, atomically."""
        with atomic_open(path) as fh:
            fh.write(json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n")

    def write_csv(self, path: str | os.PathLike) -> None:
        """One row per method and coefficient (the columns of the JSON's coefficients), atomically."""
        with atomic_open(path) as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(["method", "name", "unit", "true", "bias", "rms", "crlb_std", "efficiency", "coverage95"])
            for meth, d in self.to_dict()["methods"].items():
                for row in d["coefficients"]:
                    w.writerow([meth] + ["" if row[k] is None else row[k] for k in
                                         ("name", "unit", "true", "bias", "rms", "crlb_std", "efficiency",
                                          "coverage95")])

    def text(self) -> str:
        """What ``casep montecarlo`` prints of the result: a line naming the campaign, then :meth:`method_table`."""
        head = f"scenario {self.scenario}, {self.runs} runs, seed {self.seed}"
        if self.noise:
            head += "\n" + self.noise_line()
        return head + "\n" + self.method_table()

    def noise_line(self) -> str:
        """The noise the runs were given and the noise model the methods fitted (what the coverage column means)."""
        fit = self.noise.get("fit") or {}
        kind, tau, robust = fit.get("noise"), fit.get("tau"), fit.get("robust")
        if kind == "white" and robust in (None, "auto"):  # run_montecarlo then runs the methods as they are
            assumed = "white noise, no robust fit (the methods as they are)"
        else:
            assumed = (f"noise {kind}" + ("" if tau is None else f", tau {tau} s") + f", robust {robust or 'none'}"
                       + (" (each run's own noise model, REML)" if tau is None and kind != "white" else ""))
        return f"noise: simulated {self.noise.get('simulated', {}).get('text', '?')}; the methods fit {assumed}"

    summary = deprecated_alias("method_table", "summary")

    def method_table(self) -> str:
        """The table of :meth:`text`: one line per method, median efficiency and coverage over the coefficients."""
        lines = [f"{'method':<18} {'median RMS/CRLB':>15} {'median efficiency':>17} {'median coverage95':>17}"
                 f" {'seconds':>8}"]
        for meth in self.estimates:
            st = self.stats(meth)
            ratio = 1.0 / st["efficiency"]
            cov = st["coverage95"]
            cov_s = f"{np.nanmedian(cov):.3f}" if np.any(np.isfinite(cov)) else "-"
            lines.append(f"{meth:<18} {np.nanmedian(ratio):>15.3f} {np.nanmedian(st['efficiency']):>17.3f} "
                         f"{cov_s:>17} {self.seconds.get(meth, float('nan')):>8.2f}")
        return "\n".join(lines + self._determined_lines())

    def _not_determined(self) -> list[int]:
        """The coefficients whose CRLB std is at or above their declared magnitudes: what ``casep separate`` calls
        not determined (:func:`casep.estimators._base.not_determined`, one rule)."""
        from casep.estimators.registry import not_determined

        return not_determined(self.names, self.crlb_std, self.magnitudes)

    def _determined_lines(self) -> list[str]:
        """Which coefficients the flights determine, and each method's RMS z and coverage over them."""
        det = self.determined
        if det.all():
            head = f"all {det.size} coefficients determined (a finite CRLB std)"
        else:
            bad = [n for n, d in zip(self.names, det) if not d]
            head = (f"determined {int(det.sum())} of {det.size} coefficients (the statistics are over these); "
                    f"unidentifiable {len(bad)} (only combinations of them are determined): {', '.join(bad)}")
        lines = [head]
        nd = self._not_determined()
        if nd:
            lines.append(f"  of these, {len(nd)} have a CRLB std at or above their declared magnitudes (casep separate "
                         f"says 'not determined' of them; the statistics include them): "
                         f"{', '.join(self.names[j] for j in nd)}")
        for meth in self.estimates:
            p = self.pooled(meth)
            if p["rms_z"] is not None:
                lines.append(f"  {meth}: RMS z {p['rms_z']:.3f}, 95 % coverage {p['coverage95']:.3f} "
                             f"({p['count']} z: runs x determined coefficients)")
        return lines


def write_figure(res: MonteCarloResult, path: str | os.PathLike) -> Path:
    """RMS error / CRLB std per coefficient and method (log scale; 1 = efficient), as `path`."""
    from casep.reporting.montecarlo_plots import plot_efficiency

    ratios = {m: 1.0 / res.stats(m)["efficiency"] for m in res.estimates}
    return plot_efficiency(res.names, ratios, path,
                           title=f"Monte Carlo, scenario {res.scenario}, {res.runs} runs (1 = efficient)")
