"""``casep demo``: the paper's scenario end to end (Table 1, Figures 3-4, and what they mean).

Simulates the ``paper`` scenario and separates it with LS, RLS (p0 = 1e6, as the paper),
RELS (n_c = 1), wavelet + RELS (the paper's proposed method: sym8, symmetric extension,
universal soft threshold), ridge (GCV), bounded least squares (box = +- the spec-sheet
magnitude of each coefficient, :func:`casep.simulation.paper.demo_bounds`) and MAP (a
ground-calibration-like prior, :func:`casep.simulation.paper.demo_prior`). Prints Table 1 in the
paper's layout with the Cramer-Rao std, and with an output folder writes the figures and
a self-contained Markdown report.

Every method sees the rows :func:`casep.separate` would give it: the noise model and the robust
check are worked out once for the flight (:func:`casep.regression.rows.prepare_rows`) and shared
by the six methods on raw dv (:func:`casep.estimators.solve.fit`); wavelet + RELS, on
de-noised dv, goes through :func:`casep.separate`. The estimates are then judged against the
model's declared magnitudes as :func:`casep.separate` judges them
(:func:`casep.workflows.separate.judge_setup`).

With an output folder and a spare core, the figures are drawn in a worker process while the methods
run, each as soon as its data exist (:class:`casep.reporting.demo_figures.FigureJobs`): the methods whose
results the figures need (LS, RELS, wavelet + RELS) are computed first.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

import numpy as np

from casep.checks.diagnostics import GROUP_INDEX, Diagnostics, diagnose
from casep.checks.flight import flight_problem
from casep.estimators.registry import METHODS
from casep.estimators.result import EstimateResult
from casep.estimators.solve import fit
from casep.estimators.spec import FitSpec
from casep.exceptions import IllConditionedWarning
from casep.impact.miss import ImpactAnalysis, impact_analysis
from casep.model.error_model import ErrorModel
from casep.regression.problem import Problem
from casep.regression.rows import Rows, prepare_rows
from casep.reporting.demo_figures import (
    FigureJobs,
    plot_coefficient_errors,
    plot_demo_residuals,
    plot_rels_convergence,
    spare_core,
)
from casep.simulation.paper import demo_bounds, demo_prior
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import SimulatedFlight, simulate_flight
from casep.simulation.stored import stored_trajectory
from casep.workflows.separate import judge_setup, separate

__all__ = ["DemoResult", "run_demo", "DEMO_METHODS", "summary_lines", "impact_lines"]

#: (column label, method, options) of the demo, in table order.
DEMO_METHODS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("LS", "ols", {}),
    ("RLS", "rls", {}),
    ("RELS", "rels", {"noise_order": 1}),
    ("wavelet+RELS", "rels", {"noise_order": 1, "denoise": "wavelet"}),
    ("ridge", "ridge", {"lam": "gcv"}),
    ("bounded", "bounded", {}),
    ("MAP", "map", {}),
)


@dataclass(frozen=True)
class DemoResult:
    """Everything the demo computed (the result protocol of :mod:`casep.results`).

    Attributes
    ----------
    sim : SimulatedFlight
        The simulated ``paper`` flight and its true coefficients.
    results : dict
        Column label (:data:`DEMO_METHODS`) -> EstimateResult.
    diagnostics : Diagnostics
        Cramer-Rao std, condition numbers and identifiability at the scenario's noise sigma.
    table : str
        Table 1 as the command line prints it.
    files : tuple of Path
        Figures and ``report.md`` written (empty without an output folder).
    impact : dict
        Label ("LS", "MAP") -> the impact miss predicted from that result (:func:`casep.impact_analysis`).
    true_miss : (2,) ndarray or None
        The true instrument-error miss (linear, the true coefficients), m (downrange, crossrange).
    out : Path or None
        The output folder.
    """

    sim: SimulatedFlight
    results: dict[str, EstimateResult]
    diagnostics: Diagnostics
    table: str
    files: tuple[Path, ...] = ()
    impact: dict[str, ImpactAnalysis] = field(default_factory=dict)
    true_miss: np.ndarray | None = None
    out: Path | None = None

    def text(self) -> str:
        """What ``casep demo`` prints: the scenario, Table 1, the summary per method, the impact miss."""
        sim, d = self.sim, self.diagnostics
        lines = [f"casep demo: paper scenario, seed {sim.seed}, {sim.flight.n_samples} samples at "
                 f"{sim.scenario.rate:g} Hz, white noise {sim.scenario.noise.sigma:g} m/s", "", self.table, "",
                 f"equilibrated condition number {d.condition_number_equilibrated:.3g}; identifiable alone: "
                 + ", ".join(n for n, v in d.identifiability.items() if v == "identifiable")]
        lines += summary_lines(sim, self.results, d.crlb_std)
        if self.true_miss is not None:
            lines += [""] + impact_lines(self.impact, self.true_miss)
        if self.out is not None:
            lines += ["", f"report and figures in {self.out}/ (report.md)"]
        return "\n".join(lines)

    @property
    def success(self) -> bool:
        """Whether every method's estimate succeeded."""
        return all(bool(r.success) for r in self.results.values())

    @property
    def status(self) -> int:
        """0 when every method succeeded, else the status of the first that did not."""
        failed = [r for r in self.results.values() if not r.success]
        return int(failed[0].status) if failed else 0

    @property
    def message(self) -> str:
        """What was run, and the methods that did not succeed, with their messages."""
        failed = [f"{label}: {r.message}" for label, r in self.results.items() if not r.success]
        return (f"demo: {len(self.results)} methods on the paper flight"
                + ("; not successful: " + "; ".join(failed) if failed else ""))

    def to_dict(self) -> dict[str, Any]:
        """Plain data: the scenario, the truth, every method's result JSON, the diagnostics, the miss."""
        sim = self.sim
        return {
            "scenario": sim.scenario.name,
            "seed": int(sim.seed),
            "rate_hz": float(sim.scenario.rate),
            "n_samples": int(sim.flight.n_samples),
            "truth": {n: float(v) for n, v in zip(sim.model.names, sim.truth)},
            "results": {label: r.to_dict() for label, r in self.results.items()},
            "diagnostics": self.diagnostics.to_dict(),
            "impact": {label: ia.to_dict() for label, ia in self.impact.items()},
            "true_miss": None if self.true_miss is None else [float(v) for v in self.true_miss],
            "files": [str(p) for p in self.files],
        }




def _fmt(v: float) -> str:
    if not np.isfinite(v):
        return "-"
    return f"{v:.4g}"


def _table(sim: SimulatedFlight, results: Mapping[str, EstimateResult], crlb: np.ndarray, markdown: bool) -> str:
    labels = list(results)
    head = ["coefficient", "unit", "true"] + labels + ["CRLB std"]
    rows = []
    for j, (n, u) in enumerate(zip(sim.model.names, sim.model.units)):
        rows.append([n, u, _fmt(sim.truth[j])] + [_fmt(results[k].estimate[j]) for k in labels] + [_fmt(crlb[j])])
    if markdown:
        out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        out += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(out)
    widths = [max(len(r[i]) for r in rows + [head]) for i in range(len(head))]
    line = lambda r: "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths)))  # noqa: E731
    return "\n".join([line(head), "  ".join("-" * w for w in widths)] + [line(r) for r in rows])


def summary_lines(sim: SimulatedFlight, results: Mapping[str, EstimateResult], crlb: np.ndarray) -> list[str]:
    """One line per method: residual RMS per axis, median ``|estimate - true| / CRLB std`` and how many
    coefficients are within 2 CRLB std of the truth."""
    lines = []
    for label, r in results.items():
        z = np.abs(r.estimate - sim.truth) / crlb  # error in units of the Cramer-Rao std
        rms = r.residual_rms
        lines.append(f"{label:<13} residual RMS x {rms['x']:.3g} y {rms['y']:.3g} z {rms['z']:.3g} m/s; "
                     f"median |error|/CRLB {np.nanmedian(z):.2f}; within 2 CRLB std: "
                     f"{int(np.sum(z <= 2))}/{z.size}")
    return lines




#: The demo's figures, in the order the report shows them.
FIGURES = ("fig3_residuals_ls.png", "fig4_residuals_wavelet_rels.png", "coefficient_errors.png",
           "rels_convergence.png", "singular_values.png", "miss_budget.png", "impact_ellipse.png")


def _solve(problem: Problem, model: ErrorModel, rows: Rows, method: str, options: Mapping[str, Any]) -> EstimateResult:
    """:func:`casep.workflows.separate.separate` of a Problem, on rows prepared once for every method.

    The same steps as ``separate(problem, model, method, ...)``: the one entry point
    :func:`casep.estimators.solve.fit` on the shared rows (the method, the residual checks), then the
    set-up judgement.
    """
    res = fit(problem, FitSpec(method, options), rows=rows)
    return judge_setup(res, None, model, noise_free=problem.is_noise_free())


def _methods(problem: Problem, model: ErrorModel, labels: Sequence[str]) -> Iterator[EstimateResult]:
    """The results of the demo's methods `labels` (:data:`DEMO_METHODS`) in that order, one at a time.

    Every method but wavelet+RELS on the shared `rows`; wavelet+RELS, on de-noised rows, through
    :func:`casep.workflows.separate.separate`. The rows are prepared once, before the first method that needs
    them (separate's defaults: noise "auto", robust "auto"). The condition warnings are left out: the
    diagnostics report the conditioning once.
    """
    supplied: dict[str, Any] = {"bounds": demo_bounds(model.names), "prior": demo_prior(model.names)}  # required
    spec = {label: (method, opts) for label, method, opts in DEMO_METHODS}
    rows: Rows | None = None
    for label in labels:
        method, opts = spec[label]
        opts = {**opts, **{k: supplied[k] for k in METHODS[method].required}}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IllConditionedWarning)
            if opts.get("denoise"):
                res = separate(problem, model, method, **opts)
                assert isinstance(res, EstimateResult)  # no radar: an EstimateResult
            else:
                if rows is None:
                    rows = prepare_rows(problem, robust="auto")
                res = _solve(problem, model, rows, method, opts)
        yield res


def run_demo(out: str | os.PathLike | None = None, *, seed: int = 1, rate: float = 100.0,
             parallel: bool | None = None, jobs: FigureJobs | None = None) -> DemoResult:
    """Run the demo; write figures and ``report.md`` to `out` when given.

    Parameters
    ----------
    out : path, optional
        Output folder (created if missing).
    seed : int, optional
        Noise seed of the simulated flight.
    rate : float, optional
        Sample rate, Hz (the paper scenario uses 100).
    parallel : bool, optional
        With `out`: draw the figures in a worker process while the methods run, each as soon as its data
        exist (:class:`casep.reporting.demo_figures.FigureJobs`); default: when a core is spare (two or more
        usable cores, the 1-minute load average below their number: :func:`casep.reporting.demo_figures.spare_core`).
        The figures are the same either way.
    jobs : FigureJobs, optional
        With `out`: the figure jobs to draw with, made before this module was imported (``casep demo`` starts
        the worker first, so that it imports matplotlib while casep is imported); `parallel` is then theirs.

    Returns
    -------
    DemoResult
    """
    folder = None if out is None else Path(out)
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    if jobs is None:
        jobs = FigureJobs(folder is not None and (spare_core() if parallel is None else parallel))
    with jobs:  # the worker imports matplotlib while the flight is simulated
        # the paper vehicle's trajectory at 100 Hz is stored (casep.simulation.stored): not integrated again
        sim = simulate_flight("paper", seed=seed, rate=rate,
                              trajectory=stored_trajectory(get_scenario("paper").vehicle, rate))
        model = sim.model
        problem = flight_problem(sim.flight, model, keep_sv=True)  # S_V and its QR once, for every method
        diag = diagnose(problem, sigma=sim.scenario.noise.sigma, scales=model.scales)
        crlb = diag.crlb_std
        if folder is not None:
            _draw(jobs, folder, "diagnostics", sim, {}, {}, diag)
        S = problem.sv()
        burnout = (np.trapezoid(S, sim.flight.t, axis=0), S[-1])  # S_P(t_b) (trapezoid from 0), S_V(t_b)
        # the figures' data first: LS (Figure 3, the impact), RELS (its convergence), wavelet+RELS (Figure 4)
        order = ("LS", "RELS", "wavelet+RELS", "RLS", "ridge", "bounded", "MAP")
        got: dict[str, EstimateResult] = {}
        impact: dict[str, ImpactAnalysis] = {}
        for label, res in zip(order, _methods(problem, model, order)):
            got[label] = res
            if label in ("LS", "MAP"):
                impact[label] = impact_analysis(sim.flight, res, model, burnout_sensitivity=burnout)
            if folder is not None:
                _draw(jobs, folder, label, sim, got, impact, diag)
    results = {label: got[label] for label, _, _ in DEMO_METHODS}
    impact = {label: impact[label] for label in ("LS", "MAP")}
    table = _table(sim, results, crlb, markdown=False)
    true_miss = impact["LS"].sensitivity @ np.asarray(sim.truth, dtype=float)  # G D_true
    files: list[Path] = []
    if folder is not None:
        files = [folder / name for name in FIGURES]
        files.append(_write_report(folder, sim, results, diag, crlb, files, impact_lines(impact, true_miss)))
    return DemoResult(sim=sim, results=results, diagnostics=diag, table=table, files=tuple(files), impact=impact,
                      true_miss=true_miss, out=folder)


def _draw(jobs: FigureJobs, out: Path, label: str, sim: SimulatedFlight, results: Mapping[str, EstimateResult],
          impact: Mapping[str, ImpactAnalysis], diag: Diagnostics) -> None:
    """Submit the figures whose data the result `label` completes (:data:`FIGURES`); "diagnostics": the
    singular values, drawn from the diagnostics alone, before the methods."""
    from casep.reporting.plots import plot_impact_ellipse, plot_miss_budget, plot_spectrum

    t, crlb, truth = sim.flight.t, diag.crlb_std, np.asarray(sim.truth, dtype=float)
    if label == "diagnostics":  # plot_singular_values' figure from plain data: the worker imports no diagnostics
        jobs.draw(plot_spectrum, diag.singular_values, diag.condition_number_equilibrated, GROUP_INDEX,
                  out / FIGURES[4])
    elif label == "LS":
        jobs.draw(plot_demo_residuals, out / FIGURES[0], t, results["LS"].residuals,
                  "Figure 3 analogue: velocity residuals of LS")
        jobs.draw(plot_miss_budget, impact["LS"], out / FIGURES[5])
        jobs.draw(plot_impact_ellipse, impact["LS"], out / FIGURES[6])
    elif label == "RELS":
        rels = results["RELS"]
        assert rels.history is not None  # RELS keeps its history
        n = len(sim.model.names)
        th = t[np.arange(rels.history.shape[0]) * rels.extras.history_stride]  # the stride the recursion kept
        best = np.argsort(crlb / np.maximum(np.abs(truth), 1e-300))[:6]
        z = (rels.history[:, :n][:, best] - truth[best]) / crlb[best]  # in units of the final CRLB std
        jobs.draw(plot_rels_convergence, out / FIGURES[3], th, z, [sim.model.names[j] for j in best])
    elif label == "wavelet+RELS":
        jobs.draw(plot_demo_residuals, out / FIGURES[1], t, results[label].residuals,
                  "Figure 4 analogue: residuals of wavelet+RELS (w.r.t. the de-noised dv)")
    elif len(results) == len(DEMO_METHODS):  # every method: the errors of all, in table order
        jobs.draw(plot_coefficient_errors, out / FIGURES[2], sim.model.names,
                  {lb: np.abs(results[lb].estimate - truth) / crlb for lb, _, _ in DEMO_METHODS})


def impact_lines(impact: Mapping[str, ImpactAnalysis], true_miss: np.ndarray) -> list[str]:
    """The demo's impact-miss lines: true miss, and each result's prediction with its std."""
    lines = [f"instrument-error miss at impact (true coefficients): downrange {true_miss[0]:.0f} m, "
             f"crossrange {true_miss[1]:.0f} m"]
    for label, ia in impact.items():
        assert ia.cov is not None  # the demo's results have their covariance
        sd = np.sqrt(np.diag(ia.cov))
        z = (ia.miss - true_miss) / sd
        lines.append(f"{label:<4} predicts downrange {ia.miss[0]:.0f} +- {sd[0]:.0f} m, crossrange {ia.miss[1]:.0f} "
                     f"+- {sd[1]:.0f} m (error / std {z[0]:+.2f}, {z[1]:+.2f}): the miss is known although "
                     "most coefficients are not")
    return lines


def _write_report(out: Path, sim: SimulatedFlight, results: Mapping[str, EstimateResult], diag: Diagnostics,
                  crlb: np.ndarray, figures: list[Path], impact: list[str]) -> Path:
    from casep.io._atomic import atomic_open

    s = sim.trajectory.summary()
    ce = diag.condition_number_equilibrated
    lines = [
        "# casep demo: the paper's scenario",
        "",
        f"Simulated `paper` scenario (seed {sim.seed}, {sim.flight.n_samples} samples at {sim.scenario.rate:g} Hz): "
        f"{s['duration_s']:.0f} s powered flight, burnout {s['burnout_speed_m_s'] / 1e3:.2f} km/s at "
        f"{s['burnout_altitude_m'] / 1e3:.0f} km; Table 1 coefficients; white tracking noise 0.1 m/s; "
        f"yaw manoeuvre of 2 deg. Equilibrated condition number {ce:.3g}; "
        f"{sum(v == 'identifiable' for v in diag.identifiability.values())} of {len(diag.names)} coefficients "
        "identifiable alone at this noise level (CRLB std below their Table 1 magnitude).",
        "",
        "Methods: LS; RLS with P0 = 1e6 I (the paper's); RELS with an MA(1) noise model; wavelet + RELS "
        "(sym8, symmetric extension, universal soft threshold: the paper's proposal); ridge with GCV; "
        "bounded least squares with each coefficient within +- its spec-sheet magnitude; MAP with a "
        "ground-calibration-like prior (std half the spec magnitude, mean off the truth by half a std).",
        "",
        "## Table 1",
        "",
        _table(sim, results, crlb, markdown=True),
        "",
        "## What the columns say",
        "",
    ]
    lines += ["- " + ln for ln in summary_lines(sim, results, crlb)]
    lines += [
        "",
        "The residuals of wavelet + RELS are small (Figure 4 analogue) because they are taken against the "
        "de-noised data; that says nothing about the coefficients. RLS/RELS look better than LS on the badly "
        "determined coefficients because P0 = 1e6 I is a prior in natural units, not because of the recursion "
        "(see docs/results/cramer-rao.md). Single-flight errors scatter: judge methods by "
        "`casep montecarlo`.",
        "",
        "## Impact miss",
        "",
    ]
    lines += ["- " + ln for ln in impact]
    lines += [
        "",
        "The burnout-state error that the coefficients cause, and so the miss, is well determined even where "
        "the coefficients are not (`casep impact`; miss_budget.png: the contributions cancel within the "
        "near-dependency groups).",
        "",
        "## Figures",
        "",
    ]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    lines += ["", "Re-run: `casep demo --out DIR` (seed and rate: `--seed`, `--rate`).", ""]
    path = out / "report.md"
    with atomic_open(path) as fh:
        fh.write("\n".join(lines))
    return path
