"""The noise model, robust fit, removed samples and tracking gaps of a result, as lines of text.

A result's ``diagnostics`` (:class:`casep.estimators.result.EstimateResult`) record how the noise
was modelled (``noise``: white or Gauss-Markov per axis, the rule that chose it), what the robust
fit did (``robust``), which samples ``--exclude-outliers`` removed (``excluded``) and the gaps of
the tracking (``gaps``); :func:`noise_lines` says each in one line, as ``casep separate`` prints
them. A several-flight result holds ``noise`` per flight label; ``joint=True`` prints those.
"""

from __future__ import annotations

from typing import Any, Mapping

__all__ = ["noise_line", "robust_line", "noise_lines", "imu_noise_line"]

#: How many samples or gaps a line names before "...".
SHOWN = 6


def noise_line(nd: Mapping[str, Any]) -> str:
    """One line of a result's ``diagnostics["noise"]`` (:meth:`casep.noise.model.NoiseModel.line`)."""
    from casep.noise.model import NoiseModel

    axes = nd["axes"]
    if "note" in nd:
        return f"noise: {nd['note']}, tau {axes['x']['tau_s']:.3g} s ({nd['rule']})"
    return NoiseModel.from_dict(nd).line()


def robust_line(rb: Mapping[str, Any]) -> str:
    """One line of a result's ``diagnostics["robust"]``."""
    places = ", ".join(r["where"] for r in rb.get("rejected", [])[:SHOWN])
    auto = rb.get("automatic")
    gross = auto.get("gross") if auto else None
    why = (f", automatic: the filter found {auto['glitches_found']} glitch(es) where Gaussian noise gives "
           f"{auto['expected_from_noise']:.2g}"
           + (f", {gross} beyond {auto['gross_sigmas']:g} sigma" if gross else "") if auto else "")
    more = ", ..." if rb["rejected_count"] > SHOWN else ""
    return (f"robust ({rb['function']}{why}): {rb['rejected_count']} sample(s) rejected as glitches"
            + (f": {places}{more}" if places else "")
            + f", {rb['downweighted']} row(s) down-weighted, {rb['iterations']} iteration(s)")


def imu_noise_line(account: dict) -> str:
    """One line of what the IMU's own noise adds to the std (:func:`casep.workflows.imu_separate.imu_noise_budget`)."""
    acc, gyr = max(account["accelerometer_m_s2"]), max(account["gyro_rad_s"])
    factor = account["std_factor_max"]
    unseen = account.get("not_measured") or []
    on_pad = account.get("on_pad") or []
    if on_pad:
        a, b = account["pad_span_s"]
        where = f"measured at rest on the pad {a:.6g}..{b:.6g} s" + ("" if len(on_pad) == 6 else
                                                                   f" for {', '.join(on_pad)}, on the record else")
    else:
        where = "measured at rest" if str(account.get("source", "")).startswith("measured at rest") else \
            "measured on the record"
    if len(unseen) == 6:
        looked = "" if where == "measured on the record" else f" (looked for {where.removeprefix('measured ')})"
        return (f"IMU noise not measured{looked}: the IMU samples show none above their rounding (per sample at "
                f"most {acc:.3g} m/s^2 and {gyr:.3g} rad/s: noise-free, held or smoothed samples), so the std carry "
                "no IMU noise; an instrument's noise is stated as the flight's meta[IMU_NOISE_AT_REST] (Python: "
                "casep.checks.tracking_quality, rest_white_std of a stationary record)")
    head = (f"IMU noise ({where}, per sample up to {acc:.3g} m/s^2 and {gyr:.3g} rad/s at "
            f"{account['sample_step_s']:.3g} s"
            + (f"; not measured on {', '.join(unseen)}: no noise above their samples' rounding, none carried"
               if unseen else "") + ")")
    if account.get("carried") is False:  # a linear telemetry result's: below the share
        widen = 100 * (account["determined_std_factor_max"] - 1)
        return (f"{head}: not in the std: with the tracking noise as fitted its velocity and attitude random walks "
                f"widen the determined combinations' std by at most {widen:.2g} % (below {100 * account['share']:g} %)")
    return (head + ": its velocity and attitude random walks are in the std"
            + ("" if factor is None else f" (they raise them by up to {factor:.3g} x, {account['std_factor_worst']})")
            + ("" if not account.get("tracking_noise") else
               "; beside them the tracking " + noise_line(account["tracking_noise"])))


def noise_lines(diagnostics: Mapping[str, Any], joint: bool = False) -> list[str]:
    """The noise model, the robust fit, the removed samples and the gaps, one line each.

    Parameters
    ----------
    diagnostics : mapping
        A result's ``diagnostics``.
    joint : bool, optional
        A several-flight result: ``diagnostics["noise"]`` is ``{flight label: noise record}``; each
        line starts with the label.

    Returns
    -------
    list of str
        Empty when the diagnostics record none of these.
    """
    nd = diagnostics.get("noise")
    if joint:
        lines = []
        for label, d in (nd or {}).items():
            lines.append(f"{label}: {noise_line(d)}")
            if d.get("robust"):
                lines.append(f"{label}: {robust_line(d['robust'])}")
        return lines
    lines = [noise_line(nd)] if nd else []
    if nd and nd.get("imu"):
        lines.append(imu_noise_line(nd["imu"]))
    rb = diagnostics.get("robust")
    if rb:
        lines.append(robust_line(rb))
    ex = diagnostics.get("excluded")
    if ex:
        places = ", ".join(f"{r['where']} {r['axis']}" for r in ex["samples"][:SHOWN])
        lines.append(f"excluded: {ex['count']} sample(s) flagged at alpha {ex['alpha']:g} removed and the fit repeated"
                     + (f": {places}{', ...' if ex['count'] > SHOWN else ''}" if places else ""))
    gaps = diagnostics.get("gaps")
    if gaps:
        parts = ", ".join(f"{g['length']:.3g} s before {g['where']}" for g in gaps[:SHOWN])
        lines.append(f"tracking gaps: {len(gaps)} longer than 3 sample periods: {parts}"
                     f"{', ...' if len(gaps) > SHOWN else ''}")
    clock = diagnostics.get("clock_drift") or {}
    # read beside a turn about the vertical named first: its misfit reads as a drift
    beside = "; read beside the turn about the vertical named above, whose misfit it may be: judge it once the " \
        "turn is set right" if "beside_turn" in clock else ""
    if clock.get("telemetry"):
        from casep.checks.tracking_quality import telemetry_clock_line

        lines.append(telemetry_clock_line(clock["telemetry"], clock.get("carried")) + beside)
    halves = clock.get("halves")
    if halves:
        from casep.checks.tracking_quality import halves_line

        lines.append(halves_line(halves) + beside)
    return lines
