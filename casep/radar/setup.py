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

__all__ = ["check_setup", "launch_time_alias", "launch_time_nonlinearity", "alias_text", "POSITION_LIMIT", "SETUP_P"]

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


def _compressed(X: np.ndarray) -> np.ndarray:
    """The rows of `X` (m, k) replaced by the ``k`` of its triangular factor ``R`` (``X = Q R``, ``Q`` orthonormal
    columns): ``R^T R = X^T X``, so every least-squares fit of one of X's columns on others (:func:`_rss_fit`:
    its RSS, estimate and std) is the same on R's columns, at the cost of a k-column problem instead of an m-row
    one. X as it is when it has no more rows than columns."""
    if X.shape[0] <= X.shape[1]:
        return X
    R: np.ndarray = np.linalg.qr(X, mode="r")  # type: ignore[assignment]  # mode "r": the array R alone
    return R


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
    own = [_own_data_test(reg, i, Xw[:, :n], Xw[:, n], Xw[:, n + 1 + 3 * i:n + 4 + 3 * i])
           for i in range(len(reg.stations))]  # on row subsets: before the rows are compressed
    Xw = _compressed(Xw)  # every hypothesis below is a fit on these columns: one QR of the rows for all of them
    F, y = Xw[:, :n], Xw[:, n]
    G = [Xw[:, n + 1 + 3 * i:n + 4 + 3 * i] for i in range(len(reg.stations))]
    rss0, b0, std0 = _rss_fit(F, y)
    out: dict[str, Any] = {"launch_time": None, "stations": {}, "failures": [], "warnings": []}
    launch_warning = ""
    if aliased:
        out["aliased"], launch_warning = launch_time_alias(reg, F, y, Xw[:, -1], (rss0, b0, std0))
    if LAUNCH_TIME in reg.names:
        j = reg.names.index(LAUNCH_TIME)
        # the rows at a launch time moved by the regression's launch_shift carry that much: the correction is both
        b = float(b0[j]) + 1e3 * reg.launch_shift
        # the chi-square the whole correction explains, (estimate / std)^2 (at no shift: the rows' drop itself)
        d = _rss_fit(np.delete(F, j, axis=1), y)[0] - rss0 if reg.launch_shift == 0 else (b / std0[j]) ** 2
        out["launch_time"] = {"estimate_ms": b, "std_ms": float(std0[j]), "dchi2": float(d),
                              "p": float(chi2.sf(d, 1))}
        if abs(b) - 3 * std0[j] > LAUNCH_TIME_LIMIT and chi2.sf(d, 1) < SETUP_P:
            launch_warning = (
                f"the launch time given (--launch-time {reg.site.t0:.10g} s) is {-b:+.4g} +- {std0[j]:.2g} ms "
                f"off: the data place the launch at {reg.site.t0 + 1e-3 * b:.4f} s ({LAUNCH_TIME} = "
                f"{b:.4g} ms explains chi-square {d:.4g}, p = {chi2.sf(d, 1):.2g}; the stations' time tags "
                "and positions explain the rest); it is estimated with the other terms, so the instrument estimate "
                "accounts for it: correct --launch-time (or the telemetry's time scale)")
    out["stations"], out["failures"] = _station_positions(reg, F, y, G, (rss0, b0, std0), own)
    if launch_warning and not out["failures"]:  # a wrong station position also moves dt_launch: named alone
        out["warnings"].append(launch_warning)
    return out


def launch_time_nonlinearity(lin: Any, whiten: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                             dt_ms: float) -> float:
    """How far the linear ``dt_launch`` column's left-out term moves the estimates, in their std (the largest).

    A launch-time correction ``dt`` enters the rows as ``h(t0 + dt) - h(t0)``; the regression carries its
    first-order part ``(d h / d t0) dt``. The rest (:meth:`RadarRegression.launch_time_remainder`) goes into
    the estimates as the least-squares fit of it: ``delta = F^+ r`` on the rows whitened by the noise model
    (`whiten`, as :func:`check_setup`); returned ``max |delta_k| / std_k``. A launch time a few ms off moves
    the stations by metres and this is far below the std; 150 ms off (25 m at 69 deg latitude) near a station
    a few km away it moves the station terms by std.
    """
    n = lin.S.shape[1]
    X = np.column_stack([lin.S, lin.regression.launch_time_remainder(lin.D0, dt_ms)])
    Xw = whiten(X)[0].reshape(-1, X.shape[1])
    _, delta, std = _rss_fit(Xw[:, :n], Xw[:, n])
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(std > 0, np.abs(delta) / std, 0.0)
    return float(np.nanmax(z)) if z.size else 0.0


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


def _wrong(info: dict) -> bool:
    """Whether a station's position hypothesis is significant (p < SETUP_P) and beyond POSITION_LIMIT."""
    pos = info["position"]
    return pos["p"] < SETUP_P and float(np.linalg.norm([pos["east"], pos["north"], pos["up"]])) > POSITION_LIMIT


def _station_positions(reg: Any, F: np.ndarray, y: np.ndarray, G: list[np.ndarray], fit0: tuple,
                       own: list[dict[str, float]]) -> tuple[dict[str, dict], list[str]]:
    """The position hypothesis of every station and the failure messages of the significant ones.

    Each station's position is first fitted alone (with the fit's terms, the other stations' positions
    as in their files) and on its own rows alone. When one is significant: with two stations both are
    named as candidates with their numbers (a disagreement between two stations does not say which
    one is wrong: fitting one's position moves the other's error into its own terms and the
    instrument's, so the larger chi-square is not the wrong station's, see the module notes); with
    three or more the station whose position, fitted, explains most is named, then the others are
    tested again with it fitted (the station whose removal makes the others agree). `own`: each station's
    :func:`_own_data_test`.
    """
    rss0, b0, std0 = fit0
    names = [s.meas.station.name for s in reg.stations]
    alone = {i: _rss_fit(np.hstack([F, G[i]]), y) for i in range(len(G))}
    stations = {names[i]: _station_info(reg, i, rss0, alone[i], b0, std0) for i in alone}
    for i in alone:
        stations[names[i]]["own_data"] = own[i]
    if not any(_wrong(stations[n]) for n in names):
        return stations, []
    if len(G) == 2:
        rss_both = _rss_fit(np.hstack([F, *G]), y)[0]
        for i in (0, 1):  # what the other station's position still explains with this one's fitted
            stations[names[i]]["position"]["other_then"] = float(max(alone[i][0] - rss_both, 0.0))
        return stations, [_two_station_message(reg, stations)]
    return stations, _named_in_turn(reg, F, y, G, alone, stations, fit0)


def _named_in_turn(reg: Any, F: np.ndarray, y: np.ndarray, G: list[np.ndarray], fits: dict, stations: dict,
                   fit0: tuple) -> list[str]:
    """Three stations or more: the station whose position explains most is named, the others then tested with it
    fitted (its message gives the largest chi-square another station's position then explains); in turn."""
    from scipy.stats import chi2

    rss_base, b0, std0 = fit0
    base, remaining = F, list(range(len(G)))
    failures: list[str] = []
    while remaining:
        i = max(remaining, key=lambda k: rss_base - fits[k][0])
        info = _station_info(reg, i, rss_base, fits[i], b0, std0)
        if failures:  # the station named last: do the others agree once it is fitted?
            d, verdict = info["position"]["dchi2"], "still disagree" if _wrong(info) else "agree"
            failures[-1] += (f"; with its position fitted the other stations {verdict}"
                             f" (the most another station's position then explains: chi-square {d:.4g}, "
                             f"`{reg.stations[i].meas.station.name}`, 3 dof, p = {chi2.sf(d, 3):.2g})")
        if not _wrong(info):
            break
        info["own_data"] = stations[reg.stations[i].meas.station.name]["own_data"]
        stations[reg.stations[i].meas.station.name] = info
        failures.append(_position_message(reg.stations[i], info))
        base, rss_base = np.hstack([base, G[i]]), fits[i][0]
        remaining.remove(i)
        fits = {k: _rss_fit(np.hstack([base, G[k]]), y) for k in remaining}
    return failures


def _own_data_test(reg: Any, i: int, F: np.ndarray, y: np.ndarray, Gi: np.ndarray) -> dict[str, float]:
    """The position hypothesis of station `i` on its own rows alone (the instrument and its own terms fitted):
    ``{dchi2, p}``. One station's data alone rarely see its position (its terms and the instrument's absorb it);
    when they do, that breaks the symmetry of a two-station disagreement."""
    from scipy.stats import chi2

    prefix = f"{reg.stations[i].meas.station.name}."
    cols = [j for j, n in enumerate(reg.names) if n.startswith(prefix)]
    rows = np.any(Gi != 0, axis=1) | np.any(F[:, cols] != 0, axis=1)
    Fi = F[rows]
    Fi = Fi[:, np.any(Fi != 0, axis=0)]
    X = _compressed(np.column_stack([Fi, Gi[rows], y[rows]]))  # both fits on these columns (_compressed)
    k = Fi.shape[1]
    d = max(_rss_fit(X[:, :k], X[:, -1])[0] - _rss_fit(X[:, :-1], X[:, -1])[0], 0.0)
    return {"dchi2": float(d), "p": float(chi2.sf(d, 3))}


def _candidate_text(s: Any, info: dict) -> str:
    """One candidate of a two-station disagreement: the offset its position would need, with its std and chi-square."""
    pos, own = info["position"], info["own_data"]
    msg = (f"`{s.meas.station.name}` ({s.meas.station.source}): its position fitted moves it east {pos['east']:+.3g}, "
           f"north {pos['north']:+.3g}, up {pos['up']:+.3g} m (std {pos['std'][0]:.2g}, {pos['std'][1]:.2g}, "
           f"{pos['std'][2]:.2g} m) and lowers the whitened residual sum by {pos['dchi2']:.4g} (chi-square, 3 dof, "
           f"p = {pos['p']:.2g}), the other station's position then still explains {pos['other_then']:.4g}; on its "
           f"own data alone its position explains {own['dchi2']:.3g} (p = {own['p']:.2g})")
    return msg + _check_hint(s, info)


def _two_station_message(reg: Any, stations: dict) -> str:
    """The failure message of two stations that disagree: both candidates with their numbers, and what decides."""
    names = [s.meas.station.name for s in reg.stations]
    own = [n for n in names if stations[n]["own_data"]["p"] < SETUP_P]
    msg = ("a wrong station position: the two stations disagree about where the vehicle was, and two stations "
           "cannot say which of them is wrong (fitting one station's position moves the other's error into the "
           "station and instrument terms, so the larger chi-square is not evidence of which); candidates: "
           + "; ".join(_candidate_text(s, stations[s.meas.station.name]) for s in reg.stations))
    if len(own) == 1:
        msg += f"; only `{own[0]}`'s own data move its position significantly, which points to `{own[0]}`"
    return msg + ("; what decides: a third station, a surveyed check point (a target of known position tracked by "
                  "both), or a station's own survey: check both stations' lat, lon, h (WGS84, h above the ellipsoid)")


def _check_hint(s: Any, info: dict) -> str:
    """Which coordinate of station `s` to check: its height when that is the best-determined offset."""
    pos = info["position"]
    z = np.abs([pos["east"], pos["north"], pos["up"]]) / np.array(pos["std"])
    if z[2] > 3 and int(np.argmax(z)) == 2:  # the height is the best-determined offset
        return ("; check its height h: metres above the WGS84 ellipsoid, not above mean sea level "
                f"(h given {s.meas.station.h_m:g} m)")
    return ""


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
    return msg + (_check_hint(s, info) or "; check its lat, lon, h (WGS84, h above the ellipsoid)")
