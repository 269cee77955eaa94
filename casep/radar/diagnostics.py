"""What the radar data say about the instrument coefficients once the station errors are free.

For the whitened joint regression ``F = W [A | T_1 | ... | T_s]`` (rows divided by their group
noise std) the Cramer-Rao covariance is ``(F^T F)^-1``. Three questions a range engineer asks:

- **tracking fixed vs free**: the CRLB std of each instrument coefficient with the station errors
  known (the ``A`` columns alone) and with them estimated (all columns); their ratio is the price
  of not knowing the stations (1: no aliasing; 10: the tracking terms take 99 % of the information);
All of them from the per-group reductions ``R_g`` (``S_g = Q_g R_g``, so ``F^T F = sum R_g^T R_g / sigma_g^2``
on any subset of rows by group and of columns): a few (G n x n) matrices instead of the full rows.

- **mixed near-dependencies**: the Belsley-Kuh-Welsch groups of the joint regression
  (:func:`casep.checks.diagnostics.diagnose`) that hold both instrument and tracking terms
  (a platform misalignment and an elevation bias that look alike, by name), and for each tracking
  term the instrument terms it is most correlated with at the bound (|rho| >= 0.5) and its own CRLB
  with the instrument terms known;
- **the gain of each station**: the CRLB of the instrument coefficients with the station's rows
  and its own terms removed, divided by the CRLB with every station; a ratio of 1 means the
  station adds nothing, inf that some coefficient is not identifiable without it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from casep.checks.diagnostics import crlb_covariance, diagnose

__all__ = ["radar_diagnostics", "diagnostics_table"]

#: Free/fixed CRLB ratio above which an instrument coefficient is said to alias with the tracking terms.
ALIAS_RATIO = 2.0


#: |correlation| at the bound above which a tracking term and an instrument term are named together.
CORRELATION_NAMED = 0.5


def _std(F: np.ndarray) -> np.ndarray:
    return np.sqrt(np.diag(crlb_covariance(F, 1.0)))


def radar_diagnostics(lin, *, scales: dict | None = None, noise: list[dict] | None = None) -> dict[str, Any]:
    """The three diagnostics of the module notes for a :class:`~casep.radar.regression.LinearisedRadar`.

    Parameters
    ----------
    lin : LinearisedRadar
    scales : dict, optional
        Declared magnitudes of the coefficients (the equilibration of the near-dependency groups).
    noise : list of dict, optional
        The noise per group that the fit used (one record per group of ``lin.regression.groups``, in that
        order, ``sigma`` in the group's natural unit, as
        :meth:`casep.workflows.radar_noise.RadarNoise.group_records` gives them): the rows are divided
        by these std and the table shows them, so that a result reports one noise per group. Default: the
        group std of the linearisation (:meth:`LinearisedRadar.noise_table`, each group's weighted
        least-squares residual std at its leverages).

    Returns
    -------
    dict
        ``instrument`` (name, unit, crlb_std_tracking_fixed, crlb_std_tracking_free, ratio,
        aliased), ``tracking`` (name, unit, crlb_std), ``mixed_groups``, ``groups``,
        ``station_gain`` ({station: {median_ratio, max_ratio, ratio: {name: r}}}), ``noise``.
    """
    from dataclasses import replace

    from casep.radar.linearised import TYPE_UNITS
    from casep.regression.problem import Problem

    reg = lin.regression
    if noise is not None:  # one noise per group: the fit's, in SI, as the std the CRLB rows are divided by
        if [(g["station"], g["type"]) for g in noise] != [tuple(gr) for gr in reg.groups]:
            raise ValueError("noise: one record per group of the regression, in its order")
        lin = replace(lin, sigma=np.array([g["sigma"] * TYPE_UNITS[g["type"]][1] for g in noise]))
    nD = reg.nD
    F = lin.stacked()  # [R_g / sigma_g]: the information of every row in G n rows
    cov = crlb_covariance(F, 1.0)
    free = np.sqrt(np.diag(cov))
    fixed = _std(F[:, :nD])
    trk_alone = _std(F[:, nD:])  # the station terms with the instrument terms known
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(free, free)

    def f(v):
        return float(v) if np.isfinite(v) else None

    inst = []
    for j in range(nD):
        ratio = free[j] / fixed[j] if np.isfinite(free[j]) and np.isfinite(fixed[j]) and fixed[j] > 0 else np.inf
        inst.append({"name": reg.names[j], "unit": reg.units[j], "crlb_std_tracking_fixed": f(fixed[j]),
                     "crlb_std_tracking_free": f(free[j]), "ratio": f(ratio),
                     "aliased": bool(not np.isfinite(ratio) or ratio > ALIAS_RATIO)})
    trk = []
    for j in range(nD, reg.n):
        row = corr[j, :nD]
        top = [int(k) for k in np.argsort(-np.nan_to_num(np.abs(row)))[:3] if abs(row[k]) >= CORRELATION_NAMED]
        trk.append({"name": reg.names[j], "unit": reg.units[j], "crlb_std": f(free[j]),
                    "crlb_std_instrument_fixed": f(trk_alone[j - nD]),
                    "correlated_with": {reg.names[k]: round(float(row[k]), 4) for k in top}})
    diag = diagnose(Problem.from_arrays(F, np.zeros(F.shape[0]), names=reg.names, units=reg.units,
                                        si_factors=reg.si_factors), sigma=1.0, scales=scales)
    tracking_names = set(reg.names[nD:])
    mixed = [g for g in diag.groups if any(n in tracking_names for n in g) and any(n not in tracking_names for n in g)]
    gain: dict[str, Any] = {}
    for i, s in enumerate(reg.stations):
        name = s.meas.station.name
        if len(reg.stations) == 1:
            gain[name] = {"median_ratio": None, "max_ratio": None, "ratio": {},
                          "note": "the only station: without it nothing is observed"}
            continue
        others = [g for g, (st, _) in enumerate(reg.groups) if st != name]
        keep_cols = [j for j in range(reg.n) if j < nD or not (nD + i * reg.nT <= j < nD + (i + 1) * reg.nT)]
        without = _std(lin.stacked(others, keep_cols))[:nD]
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where(np.isfinite(without), without / free[:nD], np.inf)
        ok = np.isfinite(free[:nD])
        gain[name] = {"median_ratio": f(np.median(r[ok])) if ok.any() else None,
                      "max_ratio": f(np.max(r[ok])) if ok.any() else None,
                      "ratio": {reg.names[j]: f(r[j]) for j in range(nD)}}
    return {"instrument": inst, "tracking": trk, "mixed_groups": mixed, "groups": diag.groups,
            "station_gain": gain, "noise": list(noise) if noise is not None else lin.noise_table(),
            "condition_number_equilibrated": diag.condition_number_equilibrated}


def diagnostics_table(d: dict[str, Any]) -> str:
    """Readable report of :func:`radar_diagnostics`."""
    lines = ["noise per station and type (the std the CRLB rows are divided by):"]
    for g in d["noise"]:
        kind = f"{g['kind']}, " if g.get("kind", "white") != "white" else ""
        lines.append(f"  {g['station']}.{g['type']:<11} {g['sigma']:10.4g} {g['unit']:<7} "
                     f"({kind}{g['source']}, {g['n']} samples)")
    lines += ["", f"{'coefficient':<12} {'unit':<10} {'CRLB fixed':>12} {'CRLB free':>12} {'ratio':>8}  "
                  "(tracking terms known / estimated)"]
    for r in d["instrument"]:
        fx, fr, ra = r["crlb_std_tracking_fixed"], r["crlb_std_tracking_free"], r["ratio"]
        lines.append(f"{r['name']:<12} {r['unit']:<10} {fx if fx is not None else float('inf'):>12.4g} "
                     f"{fr if fr is not None else float('inf'):>12.4g} {ra if ra is not None else float('inf'):>8.3g}"
                     + ("  <- aliases with the tracking terms" if r["aliased"] else ""))
    lines.append("")
    lines.append(f"{'tracking term':<22} {'unit':<8} {'CRLB std':>12} {'instr. known':>12}  correlated (|rho| >= "
                 f"{CORRELATION_NAMED:g}) with")
    for r in d["tracking"]:
        sd = r["crlb_std"] if r["crlb_std"] is not None else float("inf")
        sk = r["crlb_std_instrument_fixed"] if r["crlb_std_instrument_fixed"] is not None else float("inf")
        cw = ", ".join(f"{k} {v:+.3f}" for k, v in r["correlated_with"].items())
        lines.append(f"{r['name']:<22} {r['unit']:<8} {sd:>12.4g} {sk:>12.4g}  {cw}".rstrip())
    if d["mixed_groups"]:
        lines.append("near-dependencies between tracking and instrument terms:")
        lines += ["  " + ", ".join(g) for g in d["mixed_groups"]]
    else:
        lines.append("no near-dependency group mixes tracking and instrument terms")
    for st, g in d["station_gain"].items():
        if g["median_ratio"] is None:
            lines.append(f"station {st}: {g.get('note', '')}")
        else:
            lines.append(f"station {st}: without it the instrument CRLB grow by a median factor "
                         f"{g['median_ratio']:.3g} (max {g['max_ratio']:.3g})")
    return "\n".join(lines)
