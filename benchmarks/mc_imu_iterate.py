"""Monte Carlo of the iterated separation from raw IMU data: are the std honest once the errors are not linear?

The flight of ``tests/workflows/test_imu_separate.py``: a rail launch at Esrange, 10 s on the pad, then 30 s
of axial boost with a roll programme, MEMS-size errors of ``strapdown15_axial`` in the raw IMU (20 Hz),
tracking at 5 Hz with Gauss-Markov (tau 1 s, 0.09 m/s) plus white (0.045 m/s) noise per axis. Each run
draws the noise with its own seed and separates with :func:`casep.workflows.imu_separate.separate_imu`
(OLS, the default noise model) iterated, and in one linear pass for contrast. z = (estimate - truth) / std
over the 15 coefficients and the runs. ``tests/workflows/test_imu_separate.py`` runs a few draws.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_imu_iterate.py [--runs 12]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "workflows"))


def main() -> None:
    import test_imu_separate as flight
    from mc_strapdown import _line  # the same summary line (benchmarks/ is the script's folder)

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=12)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    truth = flight.truth_flight.__wrapped__()
    z = {"iterated": [], "one pass": []}
    passes, failed, t0 = [], 0, time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.runs):
            imu, trk, D = flight.noisy_flight(Path(tmp), truth, seed)
            for name, iterate in (("iterated", True), ("one pass", False)):
                out = flight.separate_default(imu, trk, iterate=iterate)
                if not out.success:
                    failed += name == "iterated"
                    continue
                z[name].append((out.result.estimate - D) / out.result.std)
                if iterate:
                    passes.append(out.result.diagnostics["iterations"]["passes"][-1]["iteration"])
    print(f"{args.runs} runs, model {flight.MODEL}, {time.process_time() - t0:.0f} CPU s; iterated: {failed} failed, "
          f"passes {min(passes)}-{max(passes)} (median {int(np.median(passes))})")
    for name, zs in z.items():
        print(_line(name, np.concatenate(zs)))


if __name__ == "__main__":
    main()
