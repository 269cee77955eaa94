"""The HTML report of a radar separation (``casep separate ... --radar ... --report FILE.html``).

The separation report of :func:`casep.reporting.report.report_html` (coefficients, outcome,
settings, warnings) with a radar section appended: the stations, the noise and residual RMS per
station and measurement type, and the diagnostics of :mod:`casep.radar.diagnostics` (CRLB
with the station errors fixed and free, mixed near-dependencies, the gain of each station).
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Sequence

from casep.io._atomic import atomic_open
from casep.reporting.report import report_html

__all__ = ["write_radar_report"]


def write_radar_report(radar_result, path: str | os.PathLike, *, warnings: Sequence[str] = (),
                       source: str | None = None) -> Path:
    """Write the report of a :class:`casep.workflows.radar.RadarResult` (whole or not at all)."""
    from casep.radar.diagnostics import diagnostics_table

    path = Path(path)
    rr = radar_result
    text = report_html(rr.result, [], warnings=warnings, source=source)
    s = rr.summary
    rows = "".join(f"<tr><td>{html.escape(st['name'])}</td><td class=\"num\">{st['lat']:.6f}</td>"
                   f"<td class=\"num\">{st['lon']:.6f}</td><td class=\"num\">{st['h']:.2f}</td>"
                   f"<td class=\"num\">{st['n_samples']}</td><td>{html.escape(', '.join(st['types']))}</td></tr>"
                   for st in s["stations"])
    rms = ", ".join(f"{k} {v:.4g}" for k, v in s["residual_rms"].items())
    section = [
        "<h2>Radar stations</h2>",
        "<table><tr><th>station</th><th>lat, deg</th><th>lon, deg</th><th>h, m</th><th>samples</th>"
        f"<th>types</th></tr>{rows}</table>",
        f"<p>Telemetered position: {html.escape(s['telemetry_position'])}; tracking model "
        f"{html.escape(s['tracking_model'])}; {len(s['gauss_newton_steps'])} Gauss-Newton steps.</p>",
        f"<p>Residual RMS (m, arcsec, m/s): {html.escape(rms)}</p>",
    ]
    if rr.diagnostics:
        section.append("<h2>Instrument terms with the station errors fixed and free</h2>")
        section.append(f"<pre>{html.escape(diagnostics_table(rr.diagnostics))}</pre>")
    text = text.replace("</body></html>", "\n".join(section) + "\n</body></html>")
    with atomic_open(path) as fh:
        fh.write(text)
    return path
