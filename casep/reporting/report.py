"""A self-contained HTML report of one separation (``casep separate --report FILE.html``).

The page holds everything inline: the coefficient table, the outcome, settings, diagnostics
summary and warnings as HTML, and the figures as base64 PNG ``data:`` URIs, so it can be
mailed or archived as one file and opened without a network or the files it came from.
"""

from __future__ import annotations

import base64
import html
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from casep.estimators.result import AXES, EstimateResult, format_number
from casep.io._atomic import atomic_open

__all__ = ["write_report", "report_html"]

_STYLE = """body{font-family:sans-serif;max-width:1100px;margin:1em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:2px 6px}
td.num{text-align:right;font-family:monospace}th{background:#eee}
.failed{color:#b00;font-weight:bold}.ok{color:#070}.warn{color:#a60}
img{max-width:100%;border:1px solid #ddd;margin:0.5em 0}pre{background:#f6f6f6;padding:0.5em;overflow-x:auto}"""


def _esc(v: Any) -> str:
    return html.escape(str(v), quote=True)


def _coefficient_table(result: EstimateResult) -> str:
    rows = ["<table id=\"coefficients\"><tr><th>coefficient</th><th>unit</th><th>estimate</th><th>std</th>"
            "<th>note</th></tr>"]
    for r in result.coefficient_rows():
        rows.append(f"<tr><td>{_esc(r['name'])}</td><td>{_esc(r['unit'])}</td>"
                    f"<td class=\"num\">{_esc(format_number(r['estimate'], 0))}</td>"
                    f"<td class=\"num\">{_esc(format_number(r['std'], 0))}</td>"
                    f"<td>{_esc(r.get('reason', ''))}</td></tr>")
    rows.append("</table>")
    return "\n".join(rows)


def _key_value_table(items: Mapping[str, Any], table_id: str) -> str:
    rows = [f"<table id=\"{table_id}\">"]
    for k, v in items.items():
        text = v if isinstance(v, str) else json.dumps(v, default=str)
        rows.append(f"<tr><th>{_esc(k)}</th><td>{_esc(text)}</td></tr>")
    rows.append("</table>")
    return "\n".join(rows)


def _diagnostics_summary(result: EstimateResult) -> dict[str, Any]:
    d = result.diagnostics
    keys = ("condition_number", "condition_number_equilibrated", "rank", "sigma", "unidentifiable", "groups",
            "effective_prior_std", "noise_model", "active_bounds")
    out = {k: d[k] for k in keys if k in d}
    out["residual RMS (m/s)"] = ", ".join(f"{a} {result.residual_rms[a]:.4g}" for a in AXES)
    return out


def _image(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return f"<figure><img alt=\"{_esc(Path(path).stem)}\" src=\"data:image/png;base64,{data}\"></figure>"


def report_html(result: EstimateResult, figures: Sequence[str | os.PathLike] = (), *,
                warnings: Sequence[str] = (), source: str | None = None, impact=None) -> str:
    """The report page as a string (see :func:`write_report`); `impact`: an
    :class:`casep.impact.miss.ImpactAnalysis` of the result, or a sentence why there is none."""
    from casep._version import __version__

    state = "ok" if result.success else "failed"
    warn = list(warnings)
    if result.diagnostics.get("warning"):
        warn.append(str(result.diagnostics["warning"]))
    title = f"casep {result.method} separation" + (f" of {source}" if source else "")
    parts = [
        "<!DOCTYPE html>", "<html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<title>{_esc(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{_esc(title)}</h1>",
        f"<p>casep {_esc(__version__)}, model {_esc(result.model)}, method {_esc(result.method)}, "
        f"{int(result.n_samples)} samples, rank {int(result.rank)}/{len(result.names)}, "
        f"sigma {result.sigma:.4g} m/s</p>",
        f"<p class=\"{state}\">status {int(result.status)}: {_esc(result.message)}</p>",
    ]
    if warn:
        parts.append("<h2>Warnings</h2><ul>" + "".join(f"<li class=\"warn\">{_esc(w)}</li>" for w in warn) + "</ul>")
    parts += ["<h2>Coefficients</h2>", _coefficient_table(result),
              "<h2>Settings</h2>", _key_value_table(result.settings, "settings")]
    if result.denoise:
        parts += ["<h2>De-noising</h2>", _key_value_table(result.denoise, "denoise")]
    parts += ["<h2>Diagnostics</h2>", _key_value_table(_diagnostics_summary(result), "diagnostics")]
    if impact is not None:
        parts += ["<h2>Impact miss</h2>", _impact_html(impact)]
    if figures:
        parts.append("<h2>Figures</h2>")
        parts += [_image(Path(f)) for f in figures]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _impact_of(result: EstimateResult, flight):
    """The result's impact analysis on its flight, or why there is none (no flight, no r_*/v_*)."""
    if flight is None:
        return None
    from casep.impact.miss import STATE_COLUMNS, impact_analysis

    missing = [c for c in STATE_COLUMNS if c not in flight.signals]
    if missing:
        return (f"No impact miss: the flight has no {', '.join(missing)} columns (the burnout state); "
                "files from casep simulate have them.")
    return impact_analysis(flight, result, result.model or None)


def _impact_html(ia) -> str:
    """The predicted miss, its std, the nonlinear miss and the group contributions."""
    if isinstance(ia, str):
        return f"<p>{_esc(ia)}</p>"
    sd = ia.std if ia.std is not None else np.full(2, np.nan)
    rows = [("predicted (linear)", ia.miss, sd), ("nonlinear (perturbed burnout state flown)", ia.nonlinear, None)]
    rows += [(f"group {', '.join(g.names)}", g.contribution, g.std) for g in ia.groups]
    body = "".join(
        f"<tr><td>{_esc(label)}</td><td>{m[0]:.1f}</td><td>{'' if s is None else f'{s[0]:.1f}'}</td>"
        f"<td>{m[1]:.1f}</td><td>{'' if s is None else f'{s[1]:.1f}'}</td></tr>" for label, m, s in rows)
    return (f"<p>The instrument-error miss that this estimate implies at impact (vacuum ballistic flight from "
            f"the burnout state at t = {ia.t_b:.3f} s; <code>casep impact</code>), metres; std: "
            f"{_esc(ia.covariance_source)}.</p>"
            "<table><tr><th></th><th>downrange</th><th>std</th><th>crossrange</th><th>std</th></tr>"
            + body + "</table>")


def write_report(result: EstimateResult, path: str | os.PathLike, *, flight=None,
                 figures: Sequence[str | os.PathLike] | None = None, prior: Mapping | None = None,
                 bounds: Mapping | None = None, warnings: Sequence[str] = (), source: str | None = None) -> Path:
    """Write a self-contained HTML report of one separation.

    Parameters
    ----------
    result : EstimateResult
        The separation.
    path : path
        The HTML file (written whole or not at all).
    flight : FlightData, optional
        Its time axis for the figures when `figures` is None.
    figures : sequence of path, optional
        PNG files to embed; default: :func:`casep.reporting.plots.separate_figures` drawn in a
        temporary folder (removed afterwards).
    prior, bounds : mapping, optional
        The MAP prior or the box, shown on the estimates figure.
    warnings : sequence of str
        Warning lines to list.
    source : str, optional
        Name of the flight file for the title.

    Returns
    -------
    Path
        `path`.
    """
    path = Path(path)
    impact = _impact_of(result, flight)
    if figures is not None:
        text = report_html(result, figures, warnings=warnings, source=source, impact=impact)
    else:
        from casep.reporting.plots import impact_figures, separate_figures

        t = None if flight is None else np.asarray(flight.t[flight.observed])  # the rows of the residuals
        with tempfile.TemporaryDirectory(prefix="casep-report-") as tmp:
            files = separate_figures(result, tmp, t, prior=prior, bounds=bounds)
            if impact is not None and not isinstance(impact, str):
                files += impact_figures(impact, tmp)
            text = report_html(result, files, warnings=warnings, source=source, impact=impact)
    with atomic_open(path) as fh:
        fh.write(text)
    return path
