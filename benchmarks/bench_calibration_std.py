"""The std of casep calibrate checked by a seeded simulation of imucal's real Ferraris session.

Truth: casep's calibration of tests/data/imucal/annotated_session.csv (turns taken as +360 deg, the
way they went). Each run simulates the same test: the real segment lengths at 204.8 Hz, white
sample noise per axis as measured in the static segments, and every static position tilted by a
rotation vector of std ``--tilt`` deg per component (default 0.42: what casep estimates on the real
session). Per coefficient group: RMS of (estimate - truth) / std, the coverage of the t(6) 95 %
interval, and the RMS error itself, for the three weightings.

    .venv/bin/python benchmarks/bench_calibration_std.py --runs 200 --tilt 0.42
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import stats

from casep import calibrate
from casep.calibration import load_calibration_model
from casep.calibration.session import read_session, segments_from_labels
from casep.calibration.simulate import simulate_session

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "imucal"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--tilt", type=float, default=0.42, help="position error std per component, deg")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    m = load_calibration_model("ferraris")
    ses = read_session(DATA / "annotated_session.csv", rate=204.8, label_column="part")
    segs = segments_from_labels(ses, angle_deg=360.0)
    real = calibrate(ses, segs, m, gravity=9.81)
    truth = real.result.estimate
    design = [{"name": s.name, "samples": len(s.rows), **({"angle_deg": 360.0} if s.kind == "rotation" else {})}
              for s in segs]
    noise = (np.array(real.sensors["accelerometer"].diagnostics["sample_noise"]),
             np.array(real.sensors["gyro"].diagnostics["sample_noise"]))
    q = stats.t.ppf(0.975, 6)
    u = {"positions": [], "segments": [], "samples": []}
    err = {w: [] for w in u}
    sig = []
    t0 = time.time()
    for k in range(a.runs):
        s, g = simulate_session(m, dict(zip(m.names, truth)), design, rate=204.8, noise=noise,
                                position_error_deg=a.tilt, gravity=9.81, seed=a.seed + k)
        for w in u:
            c = calibrate(s, g, m, gravity=9.81, weighting=w)
            u[w].append((c.result.estimate - truth) / c.result.std)
            err[w].append(c.result.estimate - truth)
            if w == "positions":
                sig.append(c.sensors["accelerometer"].diagnostics["position_error_deg"])
    print(f"{a.runs} runs, tilt {a.tilt} deg rms per component, {time.time() - t0:.0f} s; position error estimated "
          f"on the real session {real.sensors['accelerometer'].diagnostics['position_error_deg']:.3g} deg, on the "
          f"simulated ones median {np.median(sig):.3g} deg")
    print(f"{'group':<6} {'weighting':<9} {'RMS(err/std)':>13} {'coverage t6 95%':>16} {'RMS err':>10}  "
          "per coefficient RMS(err/std)")
    for grp in ("Ma_", "ba_", "Mg_", "Kga_", "bg_"):
        idx = [i for i, n in enumerate(m.names) if n.startswith(grp)]
        for w, vals in u.items():
            x = np.asarray(vals)[:, idx]
            per = " ".join(f"{v:.2f}" for v in np.sqrt(np.mean(x**2, axis=0)))
            e = np.asarray(err[w])[:, idx]
            print(f"{grp:<6} {w:<9} {np.sqrt(np.mean(x**2)):>13.3f} {np.mean(np.abs(x) < q):>16.3f} "
                  f"{np.sqrt(np.mean(e**2)):>10.3g}  {per}")


if __name__ == "__main__":
    main()
