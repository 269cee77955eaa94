"""A self-contained HTML report of one separation (``casep separate --report FILE.html``).

The page holds everything inline: the coefficient table, the outcome, settings, diagnostics
summary and warnings as HTML, and the figures as base64 PNG ``data:`` URIs, so it can be
mailed or archived as one file and opened without a network or the files it came from.
"""

from __future__ import annotations

import base64
import html
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from casep.estimators.result import AXES, EstimateResult, format_number
from casep.impact.result import ImpactAnalysis
from casep.io._atomic import atomic_open, read_output, scratch_files
from casep.io.flight import FlightData

__all__ = ["write_report", "report_html", "impact_or_reason", "determined"]

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


def _text(v: Any) -> str:
    """A value as an analyst reads it: numbers to 4 significant digits, lists joined, groups bracketed."""
    if isinstance(v, bool) or v is None:
        return "-" if v is None else str(v).lower()
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        return format_number(x, 0) if not math.isfinite(x) or x == 0 or 1e-3 <= abs(x) < 1e6 else f"{x:.4g}"
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple)):
        if v and all(isinstance(x, (list, tuple)) for x in v):
            return "; ".join("[" + ", ".join(_text(x) for x in g) + "]" for g in v)
        return ", ".join(_text(x) for x in v)
    if isinstance(v, dict):
        return ", ".join(f"{k} {_text(x)}" for k, x in v.items())
    return str(v)


def _key_value_table(items: Mapping[str, Any], table_id: str) -> str:
    rows = [f"<table id=\"{table_id}\">"]
    for k, v in items.items():
        rows.append(f"<tr><th>{_esc(k)}</th><td>{_esc(_text(v))}</td></tr>")
    rows.append("</table>")
    return "\n".join(rows)


def determined(result: EstimateResult, scales: Mapping[str, float], top: int = 4) -> dict[str, Any]:
    """What the flight determines: the coefficients whose std is below their declared magnitude, and the
    best-determined combinations of the rest.

    With ``C_s = D^-1 C D^-1`` (covariance in units of the declared magnitudes ``D = diag(s)``) of the rest,
    its eigenvectors ``v`` with eigenvalue ``lambda < 1`` are combinations ``sum_j v_j x_j / s_j`` known to
    ``sqrt(lambda)`` of a declared magnitude although no single coefficient is.

    Returns
    -------
    dict
        ``{"determined": [names], "rest": [names], "combinations": [{"terms": {name: weight}, "std": s}]}``.
    """
    from casep.estimators.registry import not_determined

    names = list(result.names)
    std = result.std if result.std is not None else np.full(len(names), np.nan)
    has = [j for j, n in enumerate(names) if n in scales and np.isfinite(std[j])]
    rest = [j for j in not_determined(names, std, scales) if names[j] in scales]
    det = [names[j] for j in has if j not in rest]
    combos = []
    C = result.covariance
    if rest and C is not None and np.all(np.isfinite(C[np.ix_(rest, rest)])):
        s = np.array([scales[names[j]] for j in rest])
        lam, V = np.linalg.eigh(C[np.ix_(rest, rest)] / np.outer(s, s))
        resolved = lam > lam.max() * lam.size * np.finfo(float).eps  # below: rounding, not a std
        for k in np.flatnonzero((lam < 1.0) & resolved)[:top]:
            v = V[:, k] / np.max(np.abs(V[:, k]))
            order = np.argsort(-np.abs(v))[:5]
            combos.append({"terms": {names[rest[i]]: float(v[i]) for i in order if abs(v[i]) > 0.05},
                           "std": float(np.sqrt(max(lam[k], 0.0)))})
    return {"determined": det, "rest": [names[j] for j in rest], "combinations": combos}


def _headline(result: EstimateResult, model: Any = None) -> str:
    """The report's first lines: what the flight determines, against the model's declared magnitudes
    (of `model`, the result's :class:`~casep.model.ErrorModel` when the caller has it; else the model shipped with
    casep of that name: a result's name never runs a model file)."""
    scales: Mapping[str, float] = {}
    if model is not None and getattr(model, "name", None) == result.model:
        scales = model.scales
    else:
        try:
            from casep.model.loader import shipped_model

            found = shipped_model(result.model) if result.model else None  # never a file on the result's word
            scales = found.scales if found is not None else {}
        except Exception:  # a model file moved since: no headline rather than no report
            scales = {}
    if not result.success:  # a failed estimate determines nothing
        return (f"<p id=\"headline\"><b>This fit failed</b> (status {int(result.status)}): its estimates and std "
                "are not to be used; the status above says why.</p>")
    if not scales:
        return ""
    d = determined(result, scales)
    units = dict(zip(result.names, result.units))
    est = dict(zip(result.names, result.estimate))
    sd = dict(zip(result.names, result.std if result.std is not None else [np.nan] * len(result.names)))
    items = ", ".join(f"{n} {_text(float(est[n]))} &plusmn; {_text(float(sd[n]))} {_esc(units[n])}"
                      for n in d["determined"])
    out = [f"<p id=\"headline\"><b>This flight determines {len(d['determined'])} of {len(result.names)} "
           f"coefficients</b> to better than their declared magnitude"
           + (f": {items}." if items else ".") + "</p>"]
    if d["combinations"]:
        rows = "".join(
            "<li>" + " ".join(f"{'+' if w >= 0 else '&minus;'} {abs(w):.2g} {_esc(n)}/{scales[n]:g}"
                              for n, w in c["terms"].items())
            + f": std {c['std']:.2g} of the declared magnitudes</li>" for c in d["combinations"])
        out.append(f"<p>Of the other {len(d['rest'])} with a declared magnitude, no single coefficient is determined, "
                   "but these combinations "
                   f"(each coefficient divided by its declared magnitude) are:</p><ul id=\"combinations\">{rows}</ul>")
    return "\n".join(out)


def _provenance_html(prov: Mapping[str, Any]) -> str:
    """Input files with their SHA-256, per flight its frame, site, time alignment and exclusions, the options
    and the command line."""
    files = "".join(f"<tr><td>{_esc(f['role'])}</td><td>{_esc(f['file'])}</td><td class=\"num\">"
                    f"{_esc(_text(f.get('bytes')))}</td><td><code>{_esc(f.get('sha256') or '-')}</code></td></tr>"
                    for f in prov.get("inputs", []))
    parts = [f"<p>casep {_esc(prov.get('casep_version', ''))}; command: <code>{_esc(prov.get('command_line', ''))}"
             "</code></p>",
             "<table id=\"inputs\"><tr><th>role</th><th>file</th><th>bytes</th><th>SHA-256</th></tr>" + files
             + "</table>"]
    for k, f in enumerate(prov.get("flights", [])):
        items: dict[str, Any] = {"source": f.get("source"), "samples (observed)": f"{f.get('samples')} "
                                 f"({f.get('observed')})"}
        tf = f.get("tracking_frame") or {}
        if tf:
            items["tracking frame"] = tf.get("frame")
            if tf.get("site"):
                items["launch site"] = tf["site"]
        ta = f.get("time_alignment") or {}
        if ta:
            items["time alignment"] = {"applied shift (s)": ta.get("applied_s"), "coarse offset (s)": ta.get("tau_s")}
        if f.get("time_shift_s"):
            items["time scales: tracking - telemetry (s)"] = f["time_shift_s"]
        if f.get("clock_drift_ppm"):
            of = {"imu": "the IMU's time tags and steps", "telemetry": "the tracking time tags and the telemetry "
                  "INS's steps (its velocity)"}.get(f.get("clock_drift_of"), "the tracking time tags")
            items[f"clock drift taken out of {of} (ppm)"] = f["clock_drift_ppm"]
        if f.get("grid"):
            items["grid"] = f["grid"]
        if f.get("exclusions"):
            items["samples left out"] = f["exclusions"]
        sc = f.get("setup_checks")
        if sc:
            items["set-up checks"] = "; ".join(sc.get("problems") or []) or "passed"
        parts += [f"<h3>Flight {k + 1}</h3>", _key_value_table(items, f"provenance-flight-{k + 1}")]
    if prov.get("options"):
        parts += ["<h3>Options</h3>", _key_value_table(prov["options"], "options")]
    return "\n".join(parts)


def _diagnostics_summary(result: EstimateResult) -> dict[str, Any]:
    d = result.diagnostics
    keys = ("condition_number", "condition_number_equilibrated", "rank", "sigma", "unidentifiable", "groups",
            "effective_prior_std", "prior_consistency")
    out = {k: d[k] for k in keys if k in d}
    if all(result.residual_rms.get(a) is not None for a in AXES):  # a fused or radar result has no dv residuals
        out["residual RMS (m/s)"] = ", ".join(f"{a} {result.residual_rms[a]:.4g}" for a in AXES)
    return out


def _image(path: Path) -> str:
    data = base64.b64encode(read_output(path)).decode("ascii")  # also a figure of this command not yet renamed
    return f"<figure><img alt=\"{_esc(Path(path).stem)}\" src=\"data:image/png;base64,{data}\"></figure>"


def report_html(result: EstimateResult, figures: Sequence[str | os.PathLike] = (), *,
                warnings: Sequence[str] = (), source: str | None = None, impact: ImpactAnalysis | str | None = None,
                provenance: Mapping[str, Any] | None = None, model: Any = None) -> str:
    """The report page as a string (see :func:`write_report`); `impact`: an
    :class:`casep.impact.result.ImpactAnalysis` of the result, or a sentence why there is none;
    `model`: the result's model, for the headline's declared magnitudes (default: loaded by name)."""
    from casep._version import __version__

    # the status colour follows the warnings: green only for a success nothing was said against
    state = "failed" if not result.success else "warn" if warnings else "ok"
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
        + (f"noise scale {result.sigma:.4g} (rows whitened: dimensionless)</p>" if result.sigma_source == "whitened"
           else f"sigma {result.sigma:.4g} m/s</p>"),
        f"<p class=\"{state}\" id=\"status\">status {int(result.status)}: "
        + _esc(result.message).replace("\n", "<br>\n")  # a message of several lines (its findings), as written
        + (f" ({len(warnings)} warning(s) below)" if warnings and result.success else "") + "</p>",
        _headline(result, model),
    ]
    if warn:
        parts.append("<h2>Warnings</h2><ul>" + "".join(f"<li class=\"warn\">{_esc(w)}</li>" for w in warn) + "</ul>")
    parts += ["<h2>Coefficients</h2>", _coefficient_table(result),
              "<h2>Settings</h2>", f"<p>{_esc(result.settings_line())}</p>",
              _key_value_table(result.settings, "settings")]
    found = result.to_dict().get("extras") or {}
    if found:  # what the method found (the tau, lambda, components, active bounds, ...)
        parts += ["<h3>Found by the method</h3>", _key_value_table(found, "extras")]
    if result.denoise:
        parts += ["<h2>De-noising</h2>", _key_value_table(result.denoise, "denoise")]
    parts += ["<h2>Diagnostics</h2>", _key_value_table(_diagnostics_summary(result), "diagnostics")]
    if impact is not None:
        parts += ["<h2>Impact miss</h2>", _impact_html(impact)]
    if figures:
        parts.append("<h2>Figures</h2>")
        parts += [_image(Path(f)) for f in figures]
    if provenance:
        parts += ["<h2>Provenance</h2>", _provenance_html(provenance)]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def impact_or_reason(result: EstimateResult, flight: FlightData | None, model: Any = None,
                     **kwargs: Any) -> ImpactAnalysis | str | None:
    """The result's impact analysis on its flight (:func:`casep.impact.miss.impact_analysis`), or the sentence
    the report shows why there is none (the flight has no ``r_*``/``v_*`` burnout state); None without a flight.

    `model` (default: the model shipped with casep that the result names) and `kwargs` (e.g.
    ``burnout_sensitivity``) go to :func:`~casep.impact.miss.impact_analysis`. A caller that writes the report
    computes it once with this and hands it to :func:`write_report` (``impact=``).
    """
    if flight is None:
        return None
    from casep.impact.miss import STATE_COLUMNS, impact_analysis

    missing = [c for c in STATE_COLUMNS if c not in flight.signals]
    if missing:
        return (f"No impact miss: the flight has no {', '.join(missing)} columns (the burnout state); "
                "files from casep simulate have them.")
    if model is None:
        from casep.model.loader import shipped_model

        model = shipped_model(result.model) if result.model else None  # a result's name never runs a model file
        if model is None:
            return (f"No impact miss: the result's model `{result.model}` is not shipped with casep; give the model "
                    "(model=...) to compute it.")
    return impact_analysis(flight, result, model, **kwargs)


def _impact_html(ia: ImpactAnalysis | str) -> str:
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


_COMPUTE = object()  # `impact` not given: computed here from `flight`


def write_report(result: EstimateResult, path: str | os.PathLike, *, flight: FlightData | None = None,
                 figures: Sequence[str | os.PathLike] | None = None, prior: Mapping | None = None,
                 bounds: Mapping | None = None, warnings: Sequence[str] = (), source: str | None = None,
                 provenance: Mapping[str, Any] | None = None, impact: Any = _COMPUTE, model: Any = None) -> Path:
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
        Name of the flight (its files) for the title.
    provenance : mapping, optional
        :func:`casep.io.provenance.provenance` of the result: a "Provenance" section.
    impact : ImpactAnalysis, str or None, optional
        The result's impact miss as the caller computed it (:func:`impact_or_reason`: an
        :class:`~casep.impact.result.ImpactAnalysis`, or the sentence why there is none), shown as
        given; None: no impact section. Default: computed here from `flight` (:func:`impact_or_reason`,
        which integrates S_V over the flight once more), for callers that have not computed it.
    model : ErrorModel, optional
        The result's model, when the caller has it: used for the headline's declared magnitudes
        (and for the impact when it is computed here) instead of loading it again by name.

    Returns
    -------
    Path
        `path`.
    """
    path = Path(path)
    if impact is _COMPUTE:
        impact = impact_or_reason(result, flight, model)
    if impact is not None and not isinstance(impact, (str, ImpactAnalysis)):
        raise TypeError(f"`impact` must be an ImpactAnalysis, a sentence (str) or None, got {type(impact).__name__}")
    if figures is not None:
        text = report_html(result, figures, warnings=warnings, source=source, impact=impact, provenance=provenance,
                           model=model)
    else:
        from casep.reporting.plots import impact_figures, separate_figures

        t = None if flight is None else np.asarray(flight.t[flight.observed])  # the rows of the residuals
        with tempfile.TemporaryDirectory(prefix="casep-report-") as tmp, scratch_files():
            files = separate_figures(result, tmp, t, prior=prior, bounds=bounds)
            if impact is not None and not isinstance(impact, str):
                files += impact_figures(impact, tmp)
            text = report_html(result, files, warnings=warnings, source=source, impact=impact,
                               provenance=provenance, model=model)
    with atomic_open(path) as fh:
        fh.write(text)
    return path
