"""Several flights: the joint result as JSON, and the consistency and bound tables as text.

:func:`joint_result_dict` is the result JSON of ``casep separate A B ...`` (format:
docs/reference/file-formats.md, "Several flights"): ``coefficients`` of the shared coefficients
(the model's own names) with their covariance, and a ``flights`` list holding each flight's
per-flight coefficients and noise. :func:`joint_summary_lines` and :func:`flights_crlb_lines`
are what ``casep separate`` and ``casep diagnose`` print for several flights.
"""

from __future__ import annotations

from typing import Any, Mapping

__all__ = ["joint_result_dict", "joint_summary_lines", "flights_crlb_lines"]


def joint_result_dict(res: Any, jp: Any, summary: Mapping[str, Any]) -> dict[str, Any]:
    """The result JSON of a several-flight estimate.

    Parameters
    ----------
    res : EstimateResult
        :func:`casep.workflows.flights.separate_flights`'s result.
    jp : JointProblem
        Its joint problem (``jp.layout.names``: the shared coefficients).
    summary : mapping
        :func:`casep.workflows.flights.flights_summary` of the two.

    Returns
    -------
    dict
        ``res.to_dict()`` restricted to the shared coefficients (names, units, estimates, std, SI
        factors and the covariance's rows and columns), with ``flights`` and ``consistency``; the per-flight
        coefficients (``name[flight]``: names, units, estimates, std) under ``per_flight``.
    """
    d = res.to_dict()
    keep = [i for i, n in enumerate(res.names) if n in jp.layout.names]  # shared: the model's own names
    own = [i for i in range(len(res.names)) if i not in set(keep)]  # per flight: ``name[flight]``
    d["per_flight"] = {key: [d[key][i] for i in own] for key in ("names", "units", "estimates", "std")
                       if d.get(key) is not None}
    for key in ("coefficients", "names", "units", "estimates", "std", "si_factors"):
        if d.get(key) is not None:
            d[key] = [d[key][i] for i in keep]
    if d.get("covariance") is not None:
        d["covariance"] = [[d["covariance"][i][j] for j in keep] for i in keep]
    d["flights"] = summary["flights"]
    d["consistency"] = summary["consistency"]
    if isinstance(d.get("diagnostics"), dict):  # said once, at the top level
        d["diagnostics"] = {k: v for k, v in d["diagnostics"].items() if k != "consistency"}
    return d


def joint_summary_lines(summary: Mapping[str, Any]) -> list[str]:
    """Each flight's samples and noise std, and the flights' consistency (Chow test, or for noise-free flights the
    joint fit's residuals against their rounding level), one line each; the verdict is the result's message
    (:func:`casep.workflows.flights.judge_consistency`)."""
    from casep.estimators.joint import FAIL_P, WARN_P

    lines = [f"{f['file']}: {f['n_samples']} samples, sigma {f['sigma']:.4g} m/s" for f in summary["flights"]]
    cons = summary["consistency"]
    ov, nf = cons["overall"], cons.get("noise_free")
    if ov:
        lines.append(f"consistency of the flights (Chow test, F form): chi2 {ov['chi2']:.4g}, {ov['dof']} dof, "
                     f"p {ov['p_value']:.3g}"
                     + ("  <- the flights disagree" if ov["p_value"] < FAIL_P
                        else f"  <- below {WARN_P:g}: do the flights agree?" if ov["p_value"] < WARN_P else ""))
    if nf:
        lines.append("consistency of the noise-free flights: joint least-squares residual RMS "
                     + ", ".join(f"{lab} {v:.3g} m/s" for lab, v in nf["residual_rms"].items())
                     + ("  (at their rounding level: they agree)" if nf["agree"]
                        else "  <- above their rounding level: the flights disagree"))
    if cons.get("note"):
        lines.append("note: " + cons["note"])
    return lines


def flights_crlb_lines(d: Mapping[str, Any], model_name: str, with_prior: bool = False) -> list[str]:
    """The table of :func:`casep.workflows.flights.diagnose_flights`: per coefficient, the CRLB std of each
    flight alone and of all jointly, with the verdicts (``+`` identifiable, ``~`` weak, ``-`` unidentifiable)."""
    from casep.estimators.result import format_number

    k = len(d["flights"])
    mark = {"identifiable": "+", "weak": "~", "unidentifiable": "-"}
    lines = [f"model {model_name}, {k} flights: CRLB std alone and jointly (verdict: + identifiable, ~ weak, "
             "- unidentifiable)" + ("; joint bound with the prior" if with_prior else ""),
             f"{'coefficient':12s} {'unit':9s}" + "".join(f" {'flight ' + str(i + 1):>14s}" for i in range(k))
             + f" {'joint':>14s}"]
    for r in d["coefficients"]:
        cells = [f"{format_number(v, 12)} {mark[w]}" for v, w in zip(r["crlb_alone"], r["verdict_alone"])]
        lines.append(f"{r['name']:12s} {r['unit']:9s}" + "".join(f" {c:>14s}" for c in cells)
                     + f" {format_number(r['crlb_joint'], 12)} {mark[r['verdict_joint']]}")
    for i, (f, s) in enumerate(zip(d["flights"], d["sigmas"])):
        lines.append(f"flight {i + 1}: {f}, sigma {s:.4g} m/s, identifiable alone {d['identifiable_alone'][i]}"
                     + (f"; {d['noise'][i]}" if d.get("noise") else ""))
    lines.append(f"identifiable jointly: {d['identifiable_joint']} of {len(d['coefficients'])}")
    return lines
