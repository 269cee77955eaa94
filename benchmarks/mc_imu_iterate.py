"""Monte Carlo of the iterated separation from raw IMU data: are the std honest once the errors are not linear?

The flight of ``tests/workflows/test_imu_separate.py``: a rail launch at Esrange, 10 s on the pad, then 30 s
of axial boost with a roll programme, MEMS-size errors of ``strapdown15_axial`` in the raw IMU (20 Hz),
tracking at 5 Hz with Gauss-Markov (tau 1 s, 0.09 m/s) plus white (0.045 m/s) noise per axis. Each run
draws the noise with its own seed and separates with :func:`casep.workflows.imu_separate.separate_imu`
(OLS, the default noise model) iterated, and in one linear pass for contrast. z = (estimate - truth) / std
over the 15 coefficients and the runs. ``tests/workflows/test_imu_separate.py`` runs a few draws.

``--model strapdown33`` (the default model of ``casep separate --imu``) separates the same flights with every
body-frame term: its coefficients fall in exactly dependent groups on this flight (none has a std of its own), so z
is taken over the combinations the result states as determined (``diagnostics["determined"]``: weights on ``D /
scale``, estimate, std; the truth's terms outside strapdown15_axial are 0).

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_imu_iterate.py [--runs 12] [--model strapdown33]
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
    ap.add_argument("--model", default=flight.MODEL, help=f"the model separated with (default {flight.MODEL})")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    truth = flight.truth_flight.__wrapped__()
    z = {"iterated": [], "one pass": []}
    passes, failed, rejected, t0 = [], 0, 0, time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.runs):
            imu, trk, D = flight.noisy_flight(Path(tmp), truth, seed)
            for name, iterate in (("iterated", True), ("one pass", False)):
                out = separate(flight, imu, trk, args.model, iterate)
                if not out.success:
                    failed += name == "iterated"
                    continue
                z[name].append(z_of(out.result, flight.TRUTH))
                if iterate:
                    record = out.result.diagnostics["iterations"]["passes"]
                    passes.append(record[-1]["iteration"])
                    rejected += sum(len(p.get("rejected", ())) for p in record)
    print(f"{args.runs} runs, model {args.model}, {time.process_time() - t0:.0f} CPU s; iterated: {failed} failed, "
          f"passes {min(passes, default=0)}-{max(passes, default=0)} (median {int(np.median(passes or [0]))}), "
          f"{rejected} steps rejected")
    for name, zs in z.items():
        zs = [v for v in zs if v.size]  # a success with nothing stated (one linear pass under strapdown33) has no z
        print(_line(name, np.concatenate(zs)) if zs else f"{name:<14} no successful run with a z")


def separate(flight, imu, trk, model: str, iterate: bool):
    """The test's separation (:func:`flight.separate_default`) with `model`."""
    from casep.workflows.imu_separate import separate_imu

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return separate_imu(imu, trk, flight.SITE, flight.ALIGN, model, heading_deg=flight.heading_of_x(),
                            iterate=iterate)


def z_of(res, truth: dict) -> np.ndarray:
    """(estimate - truth) / std: over the coefficients when each has a std, else over the combinations the result
    states as determined (their weights on ``D / scale``)."""
    import casep

    D = np.array([truth.get(n, 0.0) for n in res.names])
    if np.all(np.isfinite(res.std)):
        return (res.estimate - D) / res.std
    scales = casep.load_model(res.model).scales
    scale = np.array([scales[n] for n in res.names])
    combos = (res.diagnostics.get("determined") or {}).get("combinations") or []
    return np.array([(c["estimate"] - np.asarray(c["weights"]) @ (D / scale)) / c["std"] for c in combos])


if __name__ == "__main__":
    main()
