"""The telemetry clock's drift test on seeded strapdown boosts: its z, false warnings, and a drift found.

Each seed: ``casep simulate --scenario strapdown-boost --rate RATE --seed S --rotating-earth`` (raw IMU, geodetic
tracking with Gauss-Markov plus white noise), the IMU's tags stretched by ``1 + PPM 1e-6`` (an IMU clock PPM fast),
``casep navigate`` (levelled on the pad, the simulation's heading given), ``casep separate`` of the telemetry and
the tracking (the default model). The record ``diagnostics["clock_drift"]["telemetry"]``
(:mod:`casep.workflows.telemetry_clock`) against the truth, ``-PPM`` in casep's sign: its z, whether the rule
warned (``determined``), whether the 2-std interval the report line gives holds the truth.

    python benchmarks/telemetry_clock_mc.py [--seeds 21 22 ...] [--ppm 0] [--rate 50] [--given PPM] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SITE = ["--launch-site", "32.4", "-106.5", "1200", "20"]
LAUNCH = [*SITE, "--launch-time", "0"]


def casep(*args: str, cwd: Path) -> None:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    subprocess.run([sys.executable, "-m", "casep", *args], cwd=cwd, env=env, check=False,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def one(seed: int, ppm: float, rate: int, given: float, d: Path) -> dict | None:
    casep("simulate", "--scenario", "strapdown-boost", "--rate", str(rate), "--seed", str(seed), "-o", "s.csv",
          "--imu-output", "imu.csv", "--imu-pad", "30", "--rotating-earth", *SITE, "--tracking-frame", "geodetic",
          "--tracking-output", "trk.csv", cwd=d)
    if ppm:
        lines = (d / "imu.csv").read_text().splitlines()
        head = [x for x in lines if x.startswith("#")]
        rows = [x for x in lines if not x.startswith("#")]
        out = [rows[0]] + [",".join([repr(float(r.split(",")[0]) * (1 + ppm * 1e-6)), *r.split(",")[1:]])
                           for r in rows[1:]]
        (d / "imu.csv").write_text("\n".join(head + out) + "\n")
    casep("navigate", "imu.csv", *LAUNCH, "--align", "-30", "-1", "--heading", "200.067", "--heading-axis", "y",
          "-o", "tel.csv", cwd=d)
    casep("separate", "tel.csv", "--tracking", "trk.csv", "--tracking-frame", "geodetic", *LAUNCH,
          "--clock-drift", repr(given), "--json", "sep.json", cwd=d)
    if not (d / "sep.json").exists():
        return None
    rec = ((json.loads((d / "sep.json").read_text()).get("diagnostics") or {}).get("clock_drift") or {})
    return rec.get("telemetry")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=list(range(21, 33)))
    p.add_argument("--ppm", type=float, default=0.0, help="the IMU clock fast by this, ppm")
    p.add_argument("--given", type=float, default=0.0, help="--clock-drift given to the separation")
    p.add_argument("--rate", type=int, default=50)
    p.add_argument("--keep", default=None, help="directory to keep each seed's files in")
    a = p.parse_args()
    truth = (1.0 / (1.0 + a.ppm * 1e-6) - 1.0) * 1e6  # casep's sign: the tracking tags late against the IMU's
    z, warned, inside = [], 0, 0
    for s in a.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            d = Path(a.keep) / f"s{s}" if a.keep else Path(tmp)
            d.mkdir(parents=True, exist_ok=True)
            rec = one(s, a.ppm, a.rate, a.given, d)
        if rec is None:
            print(f"seed {s}: no record")
            continue
        zi = (rec["ppm"] - truth) / rec["std_ppm"]
        b, sd = rec["beyond_given_ppm"], rec["std_ppm"]
        within = b - 2 * sd <= truth - a.given <= b + 2 * sd
        z.append(zi)
        warned += bool(rec["determined"])
        inside += bool(within)
        print(f"seed {s}: {rec['ppm']:.4g} +- {sd:.3g} ppm (truth {truth:.4g}), z {zi:+.2f}, "
              f"{'warned' if rec['determined'] else 'not determined'}, 2-std interval holds the truth: {within}",
              flush=True)
    z_a = np.asarray(z)
    print(f"{z_a.size} flights: RMS z {np.sqrt(np.mean(z_a**2)):.3f}, mean z {np.mean(z_a):+.3f}, "
          f"determined (warned or failed) {warned}, 2-std interval holds the truth {inside} of {z_a.size}")


if __name__ == "__main__":
    main()
