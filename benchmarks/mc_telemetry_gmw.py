"""Strapdown telemetry windows with Gauss-Markov plus white tracking noise: are the std of a short window honest?

The flight of ``benchmarks/mc_telemetry_iterate.py`` (the independent INS of ``tests/conftest.py``, strapdown12
errors of MEMS size, no IMU noise: the std rest on the tracking noise model alone), `--dur` s, tracking at
`--trk-rate` Hz with per-axis Gauss-Markov (`--gm` m/s, `--tau` s) plus white (`--white` m/s) noise drawn per seed.
Each seed is separated with casep's defaults (``casep.separate(flight, strapdown12)``: the noise model by REML,
iterated) twice: as casep states the std, and with the tracking noise's correlation-time uncertainty that the
raw-IMU path adds (:func:`casep.workflows.imu_separate.tau_spread`, which the strapdown telemetry path does not).
What it measures: whether the REML noise fit on a 30 s window (its degrees of freedom taken by the coefficients)
leaves the std too small. Printed: RMS of z = (estimate - truth) / std and the share within 1.96, pooled.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_telemetry_gmw.py [--seeds 1 .. 28] [--tau 3] [--gm 0.03]
      [--white 0.02]
(car-drive.md: tau 3 s, 0.03 + 0.02 m/s, 28 seeds: RMS z 0.978, 96.4 % within 1.96; tau 10 s, 0.05 + 0.01, 27 seeds:
1.020, 93.8 %; with the tau spread 0.880 and 0.961.)
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from mc_telemetry_iterate import mems_flights  # noqa: E402


def gauss_markov(t: np.ndarray, sd: float, tau: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary first-order Gauss-Markov series of std `sd` and correlation time `tau` at the times `t`."""
    g = np.empty(t.size)
    g[0] = rng.normal(0.0, sd)
    for k in range(1, t.size):
        p = math.exp(-(t[k] - t[k - 1]) / tau)
        g[k] = p * g[k - 1] + rng.normal(0.0, sd * math.sqrt(1.0 - p * p))
    return g


def gm_plus_white(trk: dict, *, rng: np.random.Generator, gm: float, tau: float, white: float) -> None:
    """Adds per-axis Gauss-Markov (`gm` m/s, `tau` s) plus white (`white` m/s) noise to the tracking columns."""
    for ax in "xyz":
        trk[f"v_trk_{ax}"] = (trk[f"v_trk_{ax}"] + gauss_markov(trk["t"], gm, tau, rng)
                              + rng.normal(0.0, white, trk["t"].size))


def main() -> None:
    import casep
    import casep.workflows.telemetry_iterate as ti
    from casep.workflows.imu_separate import with_imu_noise

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(1, 29)))
    ap.add_argument("--dur", type=float, default=30.0)
    ap.add_argument("--trk-rate", type=float, default=4.0)
    ap.add_argument("--gm", type=float, default=0.03)
    ap.add_argument("--tau", type=float, default=3.0)
    ap.add_argument("--white", type=float, default=0.02)
    a = ap.parse_args()
    model, truth, make_flight = mems_flights()
    stated = ti._TelemetryRun.with_noise

    def with_spread(self, res, problem, flight):
        return with_imu_noise(res, problem, flight, None, self.tau_profile(problem))

    z: dict[str, list] = {"as stated": [], "with the tau spread": []}
    c0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in a.seeds:
            rng = np.random.default_rng([seed, 99])
            flight = make_flight(seed, tmp, a.dur, a.trk_rate, 0.0,
                                 functools.partial(gm_plus_white, rng=rng, gm=a.gm, tau=a.tau, white=a.white))
            for key, how in (("as stated", stated), ("with the tau spread", with_spread)):
                ti._TelemetryRun.with_noise = how  # type: ignore[method-assign]
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        r = casep.separate(flight, model)
                finally:
                    ti._TelemetryRun.with_noise = stated  # type: ignore[method-assign]
                zk = (r.estimate - truth) / r.std
                z[key].append(zk)
                print(f"seed {seed} {key}: success {r.success}, iterated "
                      f"{r.diagnostics.get('linearisation', {}).get('iterated')}, RMS z {np.sqrt(np.mean(zk**2)):.2f}",
                      flush=True)
    for key, zs in z.items():
        v = np.concatenate(zs)
        print(f"{key}: {v.size} z, RMS {np.sqrt(np.mean(v**2)):.3f}, within 1.96 {np.mean(np.abs(v) < 1.96):.3f}, "
              f"largest {np.abs(v).max():.2f}")
    print(f"{time.process_time() - c0:.0f} CPU s")


if __name__ == "__main__":
    main()
