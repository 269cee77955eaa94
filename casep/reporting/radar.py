"""The HTML report of a radar separation (``casep separate ... --radar ... --report FILE.html``).

The separation report of :func:`casep.reporting.report.report_html` (headline against the
declared magnitudes of every term, coefficients, outcome, settings, warnings, figures, impact,
provenance) with a radar section: the stations, the noise and residual RMS per station and
measurement type, the launch-time estimate, and the diagnostics of :mod:`casep.radar.diagnostics`
(CRLB with the station errors fixed and free, mixed near-dependencies, the gain of each station).
Figures: the estimates against their declared magnitudes (:func:`casep.reporting.plots.plot_estimates`)
and the whitened residuals of every station and type against time (:func:`plot_radar_residuals`).
"""

from __future__ import annotations

import html
import os
import tempfile
from pathlib import Path
from types import SimpleNamespace
from typing import Sequence

from casep.io._atomic import atomic_open, scratch_files
from casep.reporting.report import report_html

__all__ = ["write_radar_report", "plot_radar_residuals", "radar_figures"]


def plot_radar_residuals(radar_result, path: str | os.PathLike) -> Path:
    """Residuals ``(z - h - T theta) / sigma_group`` of every station and type against time, one panel per type.

    Whitened by the group's noise std, so every panel reads against +-3 (dashed); a drift or a step is
    a misfit (a set-up error or a term the tracking model lacks), not noise. Keyhole azimuth rows
    (left out of the fit) are not drawn.
    """
    from casep.reporting.plots import pyplot, save_figure

    plt = pyplot()
    lin = radar_result.linearised
    reg = lin.regression
    x = radar_result.result.fitted_coefficients()
    res = (lin.y - lin.S @ x) * lin.weights
    types = [ty for ty in ("range", "azimuth", "elevation", "range_rate") if any(g[1] == ty for g in reg.groups)]
    fig, axes = plt.subplots(len(types), 1, figsize=(8, 2.2 * len(types)), sharex=True, layout="constrained",
                             squeeze=False)
    for (st, ty), rows in zip(reg.groups, reg.group_rows()):
        ax = axes[types.index(ty), 0]
        ax.plot(lin.t[rows], res[rows], ".", ms=1.5, label=st)
    for ax, ty in zip(axes[:, 0], types):
        ax.axhline(3.0, color="grey", ls="--", lw=0.8)
        ax.axhline(-3.0, color="grey", ls="--", lw=0.8)
        ax.set_ylabel(f"{ty} / sigma")
        ax.legend(loc="upper right", fontsize=7, markerscale=4)
    axes[-1, 0].set_xlabel("t, s")
    axes[0, 0].set_title("radar residuals per station and type, whitened (dimensionless)")
    return save_figure(fig, path)


def radar_figures(radar_result, out: str | os.PathLike) -> list[Path]:
    """The report's figures in folder `out`: the estimates against their declared magnitudes, the residuals."""
    from casep.reporting.plots import plot_estimates

    out = Path(out)
    return [plot_estimates(radar_result.result, out / "radar_estimates.png", scales=radar_result.scales),
            plot_radar_residuals(radar_result, out / "radar_residuals.png")]


def _impact_reason(radar_result, source: str | None) -> str:
    if not radar_result.success:
        return "No impact miss: the result failed (see its status); a failed estimate predicts no miss."
    return ("The impact miss of this estimate (its instrument terms; the station terms play no part): "
            f"casep impact {source or 'TELEMETRY.csv'} --result RESULT.json (a telemetry file with the burnout "
            "state r_*, v_*, as casep simulate writes it).")


def write_radar_report(radar_result, path: str | os.PathLike, *, warnings: Sequence[str] = (),
                       source: str | None = None, figures: bool = True) -> Path:
    """Write the report of a :class:`casep.workflows.radar.RadarResult` (whole or not at all)."""
    from casep.radar.diagnostics import diagnostics_table

    path = Path(path)
    rr = radar_result
    model = SimpleNamespace(name=rr.result.model, scales=rr.scales)  # every term's declared magnitude
    with tempfile.TemporaryDirectory(prefix="casep-report-") as tmp, scratch_files():
        figs = radar_figures(rr, tmp) if figures else []
        text = report_html(rr.result, figs, warnings=warnings, source=source, impact=_impact_reason(rr, source),
                           provenance=rr.provenance, model=model)
    s = rr.summary
    rows = "".join(f"<tr><td>{html.escape(st['name'])}</td><td class=\"num\">{st['lat']:.6f}</td>"
                   f"<td class=\"num\">{st['lon']:.6f}</td><td class=\"num\">{st['h']:.2f}</td>"
                   f"<td class=\"num\">{st['n_samples']}</td><td>{html.escape(', '.join(st['types']))}</td></tr>"
                   for st in s["stations"])
    rms = ", ".join(f"{k} {v:.4g}" for k, v in s["residual_rms"].items())
    noise = ", ".join(f"{g['station']}.{g['type']} {g['sigma']:.4g} {g['unit']} ({g['source']})" for g in s["noise"])
    section = [
        "<h2>Radar stations</h2>",
        "<table><tr><th>station</th><th>lat, deg</th><th>lon, deg</th><th>h, m</th><th>samples</th>"
        f"<th>types</th></tr>{rows}</table>",
        f"<p>Telemetered position: {html.escape(s['telemetry_position'])}; tracking model "
        f"{html.escape(s['tracking_model'])}; {len(s['gauss_newton_steps'])} Gauss-Newton steps.</p>",
        f"<p>Noise std per station and type: {html.escape(noise)}. The rows are divided by them: the result's "
        f"noise scale {s['noise_scale']:.4g} is dimensionless (1 when they are right).</p>",
        f"<p>Residual RMS (m, arcsec, m/s): {html.escape(rms)}</p>",
    ]
    lt = (s.get("setup") or {}).get("launch_time")
    if lt:
        section.append(f"<p>Launch time: correction {lt['estimate_ms']:.4g} &plusmn; {lt['std_ms']:.2g} ms to the "
                       f"given {s['launch_site']['t0']:.10g} s (estimated with the other terms).</p>")
    if rr.diagnostics:
        section.append("<h2>Instrument terms with the station errors fixed and free</h2>")
        section.append(f"<pre>{html.escape(diagnostics_table(rr.diagnostics))}</pre>")
    text = text.replace("</body></html>", "\n".join(section) + "\n</body></html>")
    with atomic_open(path) as fh:
        fh.write(text)
    return path
