"""Each sensor's biases compared across the car drive's windows, read back from a saved run (``car_drive.py --save``).

For the windows that succeeded: :func:`casep.workflows.windows.window_consistency` of the six biases, of the
accelerometers' three and of the gyros' three, with the left-out terms' consider gains (P_c from
``car_drive.LEFT_OUT_STD``), and with a bias movement measured at the stops added to the comparison's covariance
(never fitted to it): none; the stops' movement beyond their means' own std (:data:`STOPS_BEYOND_NOISE`, by
``car_drive_drift.py``'s ``excess_std``); that and the horizontal accelerometers' Allan deviation at rest
(``car_drive_windows.HORIZONTAL_AT_REST``); the stops' RMS change from the start (``car_drive_windows
.INSTABILITY_AT_REST``, which counts the means' noise as movement: generous). Chi-square, p and the held-out
predictions within 1 / 2 std.

    python benchmarks/car_drive_sensors.py RUN.pkl [RUN2.pkl ...]
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys

sys.path.insert(0, os.path.dirname(__file__))
from car_drive import LEFT_OUT_STD, left_out_covariance  # noqa: E402
from car_drive_windows import HORIZONTAL_AT_REST, INSTABILITY_AT_REST, SIX, _windows  # noqa: E402

#: The stops' movement beyond their means' own std (deg/h, mg): docs/results/car-drive.md, "How much do the biases
#: move during the drive?" (``bg_x`` 0, ``bg_y`` 7, ``bg_z`` 10, ``ba_z`` 0.3).
STOPS_BEYOND_NOISE = {"bg_x": 0.0, "bg_y": 7.0, "bg_z": 10.0, "ba_z": 0.3}


def main() -> None:
    from casep.workflows.windows import consider_rows, window_consistency

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="pickles written by car_drive.py --save (with its consider gains)")
    args = ap.parse_args()
    cases = {"no movement": None, "the stops beyond their noise": STOPS_BEYOND_NOISE,
             "that and the horizontal accelerometers at rest": {**STOPS_BEYOND_NOISE, **HORIZONTAL_AT_REST},
             "the stops' RMS change": INSTABILITY_AT_REST}
    for path in args.runs:
        run = pickle.load(open(path, "rb"))
        ws = _windows(run, {round(w["t_start"] / 30.0) for w in run["windows"] if w["success"]})
        held = [k for k, n in enumerate(ws[0].consider_names) if n in LEFT_OUT_STD]
        P_c = left_out_covariance([ws[0].consider_names[k] for k in held])
        gains = [g[:, held] for g in consider_rows(ws, SIX)]
        print(f"== {path}: {len(ws)} windows, the {len(held)} left-out terms as consider parameters")
        for label, inst in cases.items():
            out = []
            for names in (SIX, SIX[:3], SIX[3:]):
                idx = [SIX.index(n) for n in names]
                c = window_consistency(ws, names, consider=([g[idx] for g in gains], P_c),
                                       instability=None if inst is None else
                                       {n: v for n, v in inst.items() if n in names})
                out.append(f"{c['chi2']:.1f} on {c['dof']} (p {c['p_value']:.2g}; {c['within_1_std']:.2f} / "
                           f"{c['within_2_std']:.2f})")
            print(f"  {label}: six {out[0]}; accelerometers {out[1]}; gyros {out[2]}")


if __name__ == "__main__":
    main()
