"""The car drive's windows, read back from saved runs (``car_drive.py --save``): what their disagreement looks like.

For each saved run, on the windows that succeeded in every run given (matched by start, so that runs compare on
the same spans):

- :func:`casep.workflows.windows.window_consistency` of the six biases (and of the run's other instrument terms),
  without and with the bias instability measured at rest, with the left-out terms' consider gains when the run
  saved them (``car_drive.py --consider``, P_c from ``car_drive.LEFT_OUT_STD``), and of ``dt_trk``;
- the structure of the disagreement in time: for each separation of k windows the mean of
  ``d^T (C_i + C_j)^-1 d / p`` over the pairs ``d = x_i - x_j`` (1 at every k for constant biases; rising with k
  for a bias that wanders slower than a window, a Gauss-Markov or random-walk bias), and per coefficient the mean
  ``z^2`` of adjacent pairs against pairs 4 or more windows apart;
- per window: the fit's residual RMS and lag-one autocorrelation (a white velocity noise gives 0, the
  velocity differenced from white positions -1/2, a misfit slower than the 0.25 s epochs near +1), the RMS of
  the vertical body rate and the RMS of the antenna's lever-arm velocity ``|w x l|`` (5 cm, not modelled);
- with ``--tracking``: each bias against the window's mean ground speed (the tracked horizontal speed smoothed by
  a first-order lag of time constant tau, tau = 0 the speed itself), a weighted line through the windows (weights
  their std): its chi-square against the weighted mean's, and the line fitted on every other window predicting
  the rest (a dependence found by the windows it is judged on would not predict the others).

    python benchmarks/car_drive_windows.py RUN.pkl [RUN2.pkl ...] --imu car_drive_out/imu.csv \
        --tracking car_drive_out/tracking.csv
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import types

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from car_drive import LEFT_OUT_STD, LEVER_ARM_CAR, LEVER_ARM_IMU, LEVER_ARM_STD, left_out_covariance  # noqa: E402

#: The bias instability measured at rest on this drive (``car_drive.py``'s print_rest: RMS change of the means
#: at the three stops from the first), deg/h and mg.
INSTABILITY_AT_REST = {"bg_x": 56.5, "bg_y": 57.7, "bg_z": 28.0, "ba_z": 0.5}
#: The horizontal accelerometer biases' instability at rest (``car_drive.horizontal_instability``: the largest Allan
#: deviation at a third of a stop, mg, of the specific force less the tilt the gyros measure), which the stops' changes
#: cannot give (slopes).
HORIZONTAL_AT_REST = {"ba_x": 0.45, "ba_y": 0.62}
#: The same with the car's rocking on its springs left in (``horizontal_instability(..., tilt=False)``): ``fb_y``
#: follows ``g`` times the roll angle the x gyro measures at rest (correlation 0.75 below 2 Hz on the pad).
HORIZONTAL_WITH_ROCKING = {"ba_x": 0.39, "ba_y": 1.54}
SIX = ("ba_x", "ba_y", "ba_z", "bg_x", "bg_y", "bg_z")


def _windows(run: dict, keep: set[int]) -> list:
    out = []
    for w in run["windows"]:
        if round(w["t_start"] / 30.0) in keep:
            res = types.SimpleNamespace(names=tuple(w["names"]), estimate=w["estimate"], covariance=w["covariance"],
                                        success=True)
            out.append(types.SimpleNamespace(result=res, sv_end=w["sv_end"], sv_names=tuple(w["sv_names"]),
                                             raw=w, t_start=w["t_start"], consider_gain=w.get("consider_gain"),
                                             consider_names=tuple(w.get("consider_names", ()))))
    return out


def lever_arm_corrected(ws: list) -> tuple[list, np.ndarray] | None:
    """The windows with the antenna's known lever arm taken out, and the consider covariance of the left-out terms
    and the lever arm; None when the run's consider model has no lever arm (``car_drive.py --consider
    strapdown42_extended`` has).

    Window k's fit, which has no lever arm, moves by ``A_k l`` (its consider gain on ``l_*``) when the tracking
    follows the antenna at ``C l`` from the IMU: each estimate less ``A_k l`` (:data:`car_drive.LEVER_ARM_IMU`,
    from the data's drive_config), and the gains restricted to the terms of :data:`car_drive.LEFT_OUT_STD` plus
    ``l_*`` at :data:`car_drive.LEVER_ARM_STD`, for ``window_consistency(..., consider=...)``.
    """
    names = ws[0].consider_names if ws else ()
    if not ws or not set(LEVER_ARM_IMU) <= set(names):
        return None
    lever = [names.index(n) for n in LEVER_ARM_IMU]
    held = [k for k, n in enumerate(names) if n in LEFT_OUT_STD] + lever
    l_vec = np.array(list(LEVER_ARM_IMU.values()))
    out = []
    for w in ws:
        G = np.asarray(w.consider_gain, float)
        res = types.SimpleNamespace(names=w.result.names, estimate=w.result.estimate - G[:, lever] @ l_vec,
                                    covariance=w.result.covariance, success=True)
        out.append(types.SimpleNamespace(result=res, sv_end=w.sv_end, sv_names=w.sv_names, raw=w.raw,
                                         t_start=w.t_start, consider_gain=G[:, held],
                                         consider_names=tuple(names[k] for k in held)))
    P_c = np.diag([LEFT_OUT_STD[names[k]] ** 2 for k in held[:-len(lever)]] + [LEVER_ARM_STD**2] * len(lever))
    return out, P_c


def per_window_z(ws: list, names: tuple[str, ...], inst: dict[str, float]) -> None:
    """Print each window's (x_k - weighted mean) / sqrt(C_k + instability^2) for `names`, one row a window."""
    print("    start  " + "  ".join(f"{n:>7s}" for n in names) + "   (z about the weighted mean, with the instability)")
    cols = []
    for n in names:
        x = np.array([w.result.estimate[w.result.names.index(n)] for w in ws])
        v = np.array([w.result.covariance[w.result.names.index(n), w.result.names.index(n)] for w in ws])
        v = v + inst.get(n, 0.0) ** 2
        m = np.sum(x / v) / np.sum(1.0 / v)
        cols.append((x - m) / np.sqrt(v))
    for k, w in enumerate(ws):
        print(f"    {w.raw['t_start']:5.0f}  " + "  ".join(f"{c[k]:+7.2f}" for c in cols))


def structure(ws: list, names: tuple[str, ...]) -> list[tuple[int, int, float]]:
    """(separation k, pairs, mean chi-square per coefficient of the pairs' differences) for k = 1 .. K-1."""
    X, C = [], []
    for w in ws:
        idx = [w.result.names.index(n) for n in names]
        X.append(w.result.estimate[idx])
        C.append(w.result.covariance[np.ix_(idx, idx)])
    out = []
    for k in range(1, len(ws)):
        v = [float((X[i] - X[i + k]) @ np.linalg.pinv(C[i] + C[i + k]) @ (X[i] - X[i + k])) / len(names)
             for i in range(len(ws) - k)]
        out.append((k, len(v), float(np.mean(v))))
    return out


def _lagged(t: np.ndarray, x: np.ndarray, tau: float) -> np.ndarray:
    """`x` through a first-order lag of time constant `tau` s (tau = 0: `x` itself)."""
    if tau <= 0.0:
        return x
    out = np.empty_like(x)
    out[0] = x[0]
    for k in range(1, x.size):
        a = 1.0 - np.exp(-(t[k] - t[k - 1]) / tau)
        out[k] = out[k - 1] + a * (x[k] - out[k - 1])
    return out


def _line_chi2(x: np.ndarray, y: np.ndarray, s: np.ndarray, fit: np.ndarray,
               test: np.ndarray) -> tuple[float, float, float]:
    """A weighted line through (x, y) on the windows `fit`; on `test`: the chi-square of y about its weighted mean,
    and of the line's residuals about theirs (a common offset is free: the speed term is judged, not the level);
    and the slope."""
    w = 1.0 / s[fit]
    X = np.column_stack([np.ones(fit.size), x[fit]])
    b = np.linalg.lstsq(X * w[:, None], y[fit] * w, rcond=None)[0]
    W = 1.0 / s[test] ** 2
    r = y[test] - b[1] * x[test]
    return (float(np.sum(W * (y[test] - np.average(y[test], weights=W)) ** 2)),
            float(np.sum(W * (r - np.average(r, weights=W)) ** 2)), float(b[1]))


def speed_dependence(ws: list, trk, names: tuple[str, ...] = SIX, taus: tuple[float, ...] = (0.0, 20.0, 80.0)) -> None:
    """Print each coefficient's dependence on the window's mean ground speed (module notes)."""
    t = trk.t.to_numpy()
    speed = np.hypot(trk.v_east.to_numpy(), trk.v_north.to_numpy())
    every, even, odd = np.arange(len(ws)), np.arange(0, len(ws), 2), np.arange(1, len(ws), 2)
    for tau in taus:
        lag = _lagged(t, speed, tau)
        x = np.array([lag[(t >= w.raw["t_start"]) & (t <= w.raw["t_end"])].mean() for w in ws])
        for n in names:
            y = np.array([w.result.estimate[w.result.names.index(n)] for w in ws])
            s = np.array([np.sqrt(w.result.covariance[w.result.names.index(n), w.result.names.index(n)]) for w in ws])
            c0, c1, b = _line_chi2(x, y, s, every, every)
            e0, e1, be = _line_chi2(x, y, s, even, odd)
            o0, o1, bo = _line_chi2(x, y, s, odd, even)
            print(f"    tau {tau:3.0f} s, {n}: slope {b:+.3g} per m/s, chi2 {c0:.1f} -> {c1:.1f} "
                  f"({len(ws) - 1} -> {len(ws) - 2} dof); fitted on even windows (slope {be:+.3g}) the odd ones "
                  f"{e0:.1f} -> {e1:.1f}, on odd (slope {bo:+.3g}) the even ones {o0:.1f} -> {o1:.1f}")


def main() -> None:
    from casep.workflows.windows import consider_rows, window_consistency

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="pickles written by car_drive.py --save")
    ap.add_argument("--imu", default=None, help="the converted IMU file (t, w_*, fb_*) for the rates per window")
    ap.add_argument("--tracking", default=None, help="the converted tracking file: each bias against the speed")
    args = ap.parse_args()
    runs = [pickle.load(open(p, "rb")) for p in args.runs]
    keep = set.intersection(*[{round(w["t_start"] / 30.0) for w in r["windows"] if w["success"]} for r in runs])
    print(f"{len(keep)} windows succeeded in every run: starts near " + ", ".join(f"{30 * k}" for k in sorted(keep)))
    imu = None
    if args.imu:
        import pandas as pd

        imu = pd.read_csv(args.imu)
    for path, run in zip(args.runs, runs):
        ws = _windows(run, keep)
        print(f"== {path}")
        sets = [SIX] + ([tuple(n for n in run["names"] if n not in ("dt_trk",))]
                        if tuple(run["names"]) != SIX else [])
        for names in sets:
            for inst in (None, INSTABILITY_AT_REST):
                c = window_consistency(ws, names, instability=inst)
                print(f"  {len(names)} coefficients, {'with' if inst else 'without'} the instability at rest: chi2 "
                      f"{c['chi2']:.1f} on {c['dof']} dof, p = {c['p_value']:.2g}; predictions within 1 / 2 std "
                      f"{c['within_1_std']:.2f} / {c['within_2_std']:.2f}")
        if ws and all(w.consider_gain is not None for w in ws):  # car_drive.py --consider: the left-out terms
            held = [k for k, n in enumerate(ws[0].consider_names) if n in LEFT_OUT_STD]  # those with a P_c figure
            P_c = left_out_covariance([ws[0].consider_names[k] for k in held])
            rows = [g[:, held] for g in consider_rows(ws, SIX)]
            for inst in (None, INSTABILITY_AT_REST):
                c = window_consistency(ws, SIX, instability=inst, consider=(rows, P_c))
                print(f"  six biases, the {len(P_c)} left-out terms as consider parameters (P_c from LEFT_OUT_STD), "
                      f"{'with' if inst else 'without'} the instability at rest: chi2 {c['chi2']:.1f} on {c['dof']} "
                      f"dof, p = {c['p_value']:.2g}; predictions within 1 / 2 std {c['within_1_std']:.2f} / "
                      f"{c['within_2_std']:.2f}; per coefficient "
                      + ", ".join(f"{n} {v:.0f}" for n, v in c["chi2_per_coefficient"].items()))
            both = {**INSTABILITY_AT_REST, **HORIZONTAL_AT_REST}
            lv = lever_arm_corrected(ws)
            cases = [("left-out terms, the instability at rest and the horizontal accelerometers' (HORIZONTAL_AT_REST)",
                      ws, rows, P_c, both),
                     ("the same with the car's rocking left in the horizontal figures (HORIZONTAL_WITH_ROCKING)",
                      ws, rows, P_c, {**INSTABILITY_AT_REST, **HORIZONTAL_WITH_ROCKING})]
            if lv is not None:
                lws, lP = lv
                lg = consider_rows(lws, SIX)
                cases += [(f"the lever arm {LEVER_ARM_IMU} m taken out (std {LEVER_ARM_STD} m), left-out terms, "
                           "the instability at rest", lws, lg, lP, INSTABILITY_AT_REST),
                          ("and the horizontal accelerometers' instability too", lws, lg, lP, both)]
            for label, w_, g_, P_, inst in cases:
                c = window_consistency(w_, SIX, instability=inst, consider=(g_, P_))
                print(f"  six biases, {label}: chi2 {c['chi2']:.1f} on {c['dof']} dof, p = {c['p_value']:.2g}; "
                      f"predictions within 1 / 2 std {c['within_1_std']:.2f} / {c['within_2_std']:.2f}; per "
                      "coefficient " + ", ".join(f"{n} {v:.0f}" for n, v in c["chi2_per_coefficient"].items()))
            if lv is not None:
                print("  the lever arm's shift of each window's biases, A_k l (mg, deg/h):")
                for w in ws:
                    G = np.asarray(w.consider_gain, float)
                    idx = [w.consider_names.index(n) for n in LEVER_ARM_IMU]
                    d = G[:, idx] @ np.array(list(LEVER_ARM_IMU.values()))
                    print(f"    {w.raw['t_start']:5.0f}  " + "  ".join(
                        f"{n} {d[w.result.names.index(n)]:+7.2f}" for n in SIX))
            per_window_z(ws, SIX, both)
        c = window_consistency(ws, ("dt_trk",))
        print(f"  dt_trk: chi2 {c['chi2']:.1f} on {c['dof']} dof, weighted mean {c['weighted_mean'][0]:.1f} ms")
        print("  structure in time (six biases): " + ", ".join(f"k={k} {m:.2f}" for k, _, m in structure(ws, SIX)))
        for n in SIX:
            x = np.array([w.result.estimate[w.result.names.index(n)] for w in ws])
            s2 = np.array([w.result.covariance[w.result.names.index(n), w.result.names.index(n)] for w in ws])
            near = [(x[k] - x[k + 1]) ** 2 / (s2[k] + s2[k + 1]) for k in range(len(x) - 1)]
            far = [(x[a] - x[b]) ** 2 / (s2[a] + s2[b]) for a in range(len(x)) for b in range(a + 4, len(x))]
            print(f"    {n}: adjacent pairs mean z^2 {np.mean(near):.2f}, pairs >= 4 windows apart {np.mean(far):.2f}")
        if args.tracking:
            import pandas as pd

            print("  each bias against the window's mean ground speed (a weighted line):")
            speed_dependence(ws, pd.read_csv(args.tracking))
        print("  start  resid RMS  lag-1 acf  |w_z| RMS deg/s  |w x l| RMS m/s")
        for w in ws:
            r = np.asarray(w.raw["residuals"], float).reshape(-1, 3)
            r = r[np.all(np.isfinite(r), axis=1)]
            rc = r - r.mean(axis=0)
            lag1 = np.sum(rc[1:] * rc[:-1]) / np.sum(rc**2)
            line = f"  {w.raw['t_start']:6.1f}  {np.sqrt(np.mean(r**2)):8.3f}  {lag1:+8.2f}"
            if imu is not None:
                m = (imu.t >= w.raw["t_start"]) & (imu.t <= w.raw["t_end"])
                om = imu[["w_x", "w_y", "w_z"]].to_numpy()[m]
                lever = np.cross(om, LEVER_ARM_CAR)  # the lever arm's size matters here, not its body axes
                line += (f"  {np.degrees(np.sqrt(np.mean(om[:, 2] ** 2))):14.1f}"
                         f"  {np.sqrt(np.mean(np.sum(lever**2, axis=1))):14.3f}")
            print(line)


if __name__ == "__main__":
    main()
