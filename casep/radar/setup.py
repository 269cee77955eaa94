"""Which set-up error do the radar residuals point to: launch time, a station's position, its time tags.

Each hypothesis is tested by what it explains: the drop of the whitened residual sum of squares
when its terms are in the least-squares fit against when they are not (the other terms fitted
in both), a chi-square with as many degrees of freedom as the hypothesis has terms when the
hypothesis is false and the noise std are right::

    dchi2_H = min_b |W (y - S b)|^2 - min_(b, c) |W (y - S b - G_H c)|^2  ~  chi2(dim c)

- **launch time**: the common term ``dt_launch`` (in the regression by default,
  :class:`casep.radar.regression.RadarRegression`); ``G`` its column;
- **station position**: ``G = d h / d (east, north, up)`` of one station
  (:meth:`casep.radar.geometry.RadarGeometry.setup_jacobian`), not in the regression; a
  height off by tens of metres is the classic mix-up of a height above mean sea level with one
  above the WGS84 ellipsoid;
- **time tags**: a station's ``time_bias`` (a term of the tracking model, when it has one).

A hypothesis whose terms explain a significant share (``p < 1e-6``) and whose estimate is beyond
its plausible size (a launch time 1 ms, a station position :data:`POSITION_LIMIT`) is named
with its numbers; a station position is not a term of the fit, so a significant one makes the
result a failure (its instrument estimate is biased), the others a warning.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

__all__ = ["check_setup", "launch_time_alias", "alias_text", "POSITION_LIMIT", "SETUP_P"]

#: A station position offset (norm, m) below this is a survey error the station terms absorb.
POSITION_LIMIT = 5.0
#: Significance of a hypothesis' chi-square drop.
SETUP_P = 1e-6
#: A launch-time correction beyond this (ms, and 3 std) is reported.
LAUNCH_TIME_LIMIT = 1.0


def _rss_fit(F: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Least squares ``min |y - F b|^2`` (whitened rows): ``(RSS, b, std of b)`` with unit noise."""
    Q, R = np.linalg.qr(F)
    b = np.linalg.lstsq(R, Q.T @ y, rcond=None)[0]
    r = y - F @ b
    Rinv = np.linalg.pinv(R)
    return float(r @ r), b, np.sqrt(np.sum(Rinv**2, axis=1))


def check_setup(lin: Any, whiten: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None
                ) -> dict[str, Any]:
    """The chi-square each set-up hypothesis explains, per station, with its estimate (see the module notes).

    Parameters
    ----------
    lin : casep.radar.linearised.LinearisedRadar
        The regression at its final linearisation point.
    whiten : callable, optional
        The noise model's whitening of regression rows ``X`` (m, k) -> ``(Xw (M, 3, k), t)``
        (:meth:`casep.workflows.radar_noise.RadarNoise.whiten`): the hypotheses are tested on the rows the fit
        solved, so that correlated noise does not inflate their chi-square. Default: the rows divided
        by their group std (white noise).

    Returns
    -------
    dict
        ``launch_time`` ({estimate_ms, std_ms, dchi2, p} or None), ``stations``
        ({name: {position: {east, north, up, std (m), dchi2, p}, time_bias: {...} or None}}),
        ``failures`` and ``warnings`` (messages with the numbers).
    """
    from scipy.stats import chi2

    from casep.radar.regression import LAUNCH_TIME

    reg = lin.regression
    n = lin.S.shape[1]
    aliased = LAUNCH_TIME not in reg.names  # one station: dt_launch tested, not fitted (launch_time_alias)
    X = np.column_stack([lin.S, lin.y, *_position_columns(lin)]
                        + ([reg.launch_time_rows(lin.D0)] if aliased else []))
    Xw = X * lin.weights[:, None] if whiten is None else whiten(X)[0].reshape(-1, X.shape[1])
    F, y = Xw[:, :n], Xw[:, n]
    G = [Xw[:, n + 1 + 3 * i:n + 4 + 3 * i] for i in range(len(reg.stations))]
    rss0, b0, std0 = _rss_fit(F, y)
    out: dict[str, Any] = {"launch_time": None, "stations": {}, "failures": [], "warnings": []}
    launch_warning = ""
    if aliased:
        out["aliased"], launch_warning = launch_time_alias(reg, F, y, Xw[:, -1], (rss0, b0, std0))
    if LAUNCH_TIME in reg.names:
        j = reg.names.index(LAUNCH_TIME)
        rss_without = _rss_fit(np.delete(F, j, axis=1), y)[0]
        d = rss_without - rss0  # = (estimate / std)^2
        out["launch_time"] = {"estimate_ms": float(b0[j]), "std_ms": float(std0[j]), "dchi2": float(d),
                              "p": float(chi2.sf(d, 1))}
        if abs(b0[j]) - 3 * std0[j] > LAUNCH_TIME_LIMIT and chi2.sf(d, 1) < SETUP_P:
            launch_warning = (
                f"the launch time given (--launch-time {reg.site.t0:.10g} s) is {-b0[j]:+.4g} +- {std0[j]:.2g} ms "
                f"off: the data place the launch at {reg.site.t0 + 1e-3 * b0[j]:.10g} s ({LAUNCH_TIME} = "
                f"{b0[j]:.4g} ms explains chi-square {d:.4g}, p = {chi2.sf(d, 1):.2g}; the stations' time tags "
                "and positions explain the rest); it is estimated with the other terms, so the instrument estimate "
                "accounts for it: correct --launch-time (or the telemetry's time scale)")
    base, rss_base, remaining = F, rss0, list(range(len(reg.stations)))
    while remaining:  # the station that explains most first; the others then tested with it corrected
        fits = {i: _rss_fit(np.hstack([base, G[i]]), y) for i in remaining}
        i = max(remaining, key=lambda k: rss_base - fits[k][0])
        for k in remaining:
            out["stations"][reg.stations[k].meas.station.name] = _station_info(reg, k, rss_base, fits[k], b0, std0)
        info = out["stations"][reg.stations[i].meas.station.name]
        pos = info["position"]
        off = np.array([pos["east"], pos["north"], pos["up"]])
        if not (pos["p"] < SETUP_P and float(np.linalg.norm(off)) > POSITION_LIMIT):
            break
        out["failures"].append(_position_message(reg.stations[i], info))
        base, rss_base = np.hstack([base, G[i]]), fits[i][0]
        remaining.remove(i)
    if launch_warning and not out["failures"]:  # a wrong station position also moves dt_launch: named alone
        out["warnings"].append(launch_warning)
    return out


def launch_time_alias(reg: Any, F: np.ndarray, y: np.ndarray, g: np.ndarray, fit0: tuple) -> tuple[dict, str]:
    """What a launch-time error does to a fit that does not estimate it (one station), and whether the data see one.

    With one station ``dt_launch`` and the station's own terms (its time tags, angle and range biases)
    are nearly one combination, so it is left out of the fit. Left out, a true correction ``d`` moves
    every estimate by ``c d`` with ``c = (F^T F)^-1 F^T g`` (``g`` the whitened column ``d h / d t0``):
    what the fit determines is ``b + c dt_launch``. Said here with the numbers: ``dt_launch`` estimated
    alone with the others (its estimate, std, the chi-square it explains), the shift per ms of the
    station terms it moves most, and the largest shift of an instrument coefficient for a launch-time
    error of :data:`~casep.radar.regression.LAUNCH_TIME_SCALE` ms, in its std. Returns the record and a
    warning text ("" when the launch time is not significantly off).
    """
    from scipy.stats import chi2

    from casep.radar.regression import LAUNCH_TIME, LAUNCH_TIME_SCALE

    rss0, b0, std0 = fit0
    rss1, b1, std1 = _rss_fit(np.column_stack([F, g]), y)
    c = np.linalg.lstsq(F, g, rcond=None)[0]  # shift of each estimate per ms of true launch-time correction
    d, est, sd = rss0 - rss1, float(b1[-1]), float(std1[-1])
    p = float(chi2.sf(max(d, 0.0), 1))
    nD = reg.nD
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = np.where(std0[:nD] > 0, np.abs(c[:nD]) * LAUNCH_TIME_SCALE / std0[:nD], 0.0)
    k = int(np.argmax(shift)) if nD else 0
    terms = sorted(range(nD, len(reg.names)), key=lambda j: -abs(c[j]) / std0[j] if std0[j] > 0 else 0.0)[:2]
    rec = {"term": LAUNCH_TIME, "estimated": False, "estimate_ms": est, "std_ms": sd, "dchi2": float(d), "p": p,
           "absorbed_per_ms": {reg.names[j]: float(c[j]) for j in terms},
           "units": {reg.names[j]: reg.units[j] for j in terms},
           "instrument_shift_std": float(shift[k]) if nD else 0.0, "instrument_most_moved": reg.names[k],
           "scale_ms": LAUNCH_TIME_SCALE}
    warn = ""
    if abs(est) - 3 * sd > LAUNCH_TIME_LIMIT and p < SETUP_P:
        warn = (f"the launch time given (--launch-time {reg.site.t0:.10g} s) looks {-est:+.4g} +- {sd:.2g} ms off "
                f"({LAUNCH_TIME} fitted with the one station's terms explains chi-square {d:.4g}, p = {p:.2g}); with "
                "one station it is not estimated (it aliases with the station's time tags and biases), so the "
                f"instrument estimate is moved by it (up to {shift[k] * abs(est) / LAUNCH_TIME_SCALE:.3g} std, "
                f"{reg.names[k]}): correct --launch-time, or add a second station")
    return rec, warn


def alias_text(rec: dict) -> str:
    """The console line of :func:`launch_time_alias`'s record: the combination the fit determines, with its numbers."""
    from casep.radar.regression import LAUNCH_TIME

    moved = ", ".join(f"{n} {v:+.3g} {rec['units'][n]}" for n, v in rec["absorbed_per_ms"].items())
    return (f"launch time: not estimated with one station (it aliases with the station's terms: {LAUNCH_TIME} "
            f"fitted with them would be {rec['estimate_ms']:.4g} +- {rec['std_ms']:.3g} ms, chi-square "
            f"{rec['dchi2']:.3g}); the fit determines the station terms plus the launch-time error: per ms of it "
            f"{moved}; a {rec['scale_ms']:g} ms error moves the instrument coefficients by up to "
            f"{rec['instrument_shift_std']:.2g} std ({rec['instrument_most_moved']})")


def _position_columns(lin: Any) -> list[np.ndarray]:
    """Per station, the columns ``d h / d (east, north, up)`` of its rows (zero elsewhere), (m, 3), SI rows."""
    reg = lin.regression
    rows = reg.group_rows(all_rows=True)
    m = lin.y.size
    used = np.zeros(m, dtype=bool)  # the keyhole's azimuth rows are zero rows of the fit
    used[np.concatenate(reg.group_rows())] = True
    out, g = [], 0
    for s in reg.stations:
        k = len(s.types)
        J = s.geometry.setup_jacobian(s.t, s.r - s.SP @ lin.D0, s.v - s.SV @ lin.D0, s.a)[:, :k, 1:]  # (N, k, 3)
        G = np.zeros((m, 3))
        for j in range(k):
            G[rows[g + j]] = J[:, j, :]
        G[~used] = 0.0
        out.append(G)
        g += k
    return out


def _station_info(reg: Any, i: int, rss_base: float, fit: tuple, b0: np.ndarray, std0: np.ndarray) -> dict:
    """The position hypothesis of station `i` (its fit `fit` = ``_rss_fit`` with its columns last) and its time bias."""
    from scipy.stats import chi2

    rss1, b1, std1 = fit
    d = rss_base - rss1
    off, sd = b1[-3:], std1[-3:]
    name = reg.stations[i].meas.station.name
    info: dict[str, Any] = {"position": {"east": float(off[0]), "north": float(off[1]), "up": float(off[2]),
                                         "std": [float(v) for v in sd], "dchi2": float(d),
                                         "p": float(chi2.sf(d, 3))}, "time_bias": None}
    tb = f"{name}.time_bias"
    if tb in reg.names:
        jt = reg.names.index(tb)
        info["time_bias"] = {"name": tb, "estimate": float(b0[jt]), "std": float(std0[jt]), "unit": reg.units[jt],
                             "with_position": float(b1[jt]), "std_with_position": float(std1[jt])}
    return info


def _position_message(s: Any, info: dict) -> str:
    """The failure message of a station whose position the data move (numbers, and which coordinate to check)."""
    pos = info["position"]
    off, sd = np.array([pos["east"], pos["north"], pos["up"]]), np.array(pos["std"])
    msg = (f"station `{s.meas.station.name}` ({s.meas.station.source}): a wrong station position: the data place it "
           f"east {off[0]:+.3g}, north {off[1]:+.3g}, up {off[2]:+.3g} m from its file's position (std {sd[0]:.2g}, "
           f"{sd[1]:.2g}, {sd[2]:.2g} m); fitting it lowers the whitened residual sum by {pos['dchi2']:.4g} "
           f"(chi-square, 3 dof, p = {pos['p']:.2g})")
    tbi = info["time_bias"]
    if tbi is not None:
        msg += (f"; {tbi['name']} is {tbi['estimate']:.3g} +- {tbi['std']:.2g} {tbi['unit']} without it and "
                f"{tbi['with_position']:.3g} +- {tbi['std_with_position']:.2g} {tbi['unit']} with it")
    z = np.abs(off) / sd
    if z[2] > 3 and int(np.argmax(z)) == 2:  # the height is the best-determined offset
        return msg + ("; check its height h: metres above the WGS84 ellipsoid, not above mean sea level "
                      f"(h given {s.meas.station.h_m:g} m)")
    return msg + "; check its lat, lon, h (WGS84, h above the ellipsoid)"
