"""Size of the several-flight consistency test (Chow, F form) on coloured noise, through the default path.

Two same-truth flights (``paper`` and ``paper-azimuth``, Table 1 truth, platform36) with Gauss-Markov
(0.09 m/s, tau 1 s) plus white (0.045 m/s) tracking noise, fitted jointly by ``separate_flights`` with the
default noise model (``noise="auto"``: each flight's own noise model per axis, its rows whitened, the Chow
test on the whitened rows). Prints the rejection rates at 5 %, 1 % (the warning level), 1e-3 and 1e-6 (the
failure level), the share of results that are not a success, and the mean chi2 / dof (1 when honest).
Measured (load 10 on 2 cores, one BLAS thread): 100 draws at 5 Hz: 9 / 2 / 0 / 0, mean chi2/dof 0.990,
149 s CPU; 40 draws at 2 Hz: 7 / 2 / 1 / 0, mean 1.140 (the noise model of 400 samples a flight), 40 s CPU.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/mc_chow_size_gmw.py [DRAWS] [RATE_HZ]
"""

from __future__ import annotations

import dataclasses
import sys
import time
import warnings

import numpy as np

from casep.estimators.joint import FAIL_P, WARN_P
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight
from casep.workflows.flights import separate_flights


def gmw_flight(name: str, seed: int, rate: float):
    """The scenario with Gauss-Markov (0.09 m/s, 1 s) plus white (0.045 m/s) tracking noise."""
    sc = get_scenario(name)
    noise = dataclasses.replace(sc.noise, kind="ar1", sigma=0.09, tau=1.0, white_sigma=0.045)
    return simulate_flight(dataclasses.replace(sc, noise=noise), seed=seed, rate=rate).flight


def main(draws: int = 100, rate: float = 5.0) -> None:
    t0 = time.process_time()
    p, ok, ratio = [], [], []
    for s in range(draws):
        flights = [gmw_flight(name, 1000 + 2 * s + k, rate) for k, name in enumerate(("paper", "paper-azimuth"))]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res, _ = separate_flights(flights, "platform36", "ols")
        ov = res.diagnostics["consistency"]["overall"]
        p.append(ov["p_value"])
        ok.append(res.success)
        ratio.append(ov["chi2"] / ov["dof"])
    pv = np.array(p)
    print(f"{draws} draws at {rate:g} Hz, same truth, GM 0.09 m/s tau 1 s + white 0.045 m/s, noise auto:")
    for level in (0.05, WARN_P, 1e-3, FAIL_P):
        k = int(np.sum(pv < level))
        print(f"  p < {level:g}: {k}/{draws} = {k / draws:.3f} (nominal {level:g})")
    print(f"  not a success: {draws - sum(ok)}/{draws}; mean chi2/dof {np.mean(ratio):.3f}; "
          f"CPU {time.process_time() - t0:.1f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100, float(sys.argv[2]) if len(sys.argv) > 2 else 5.0)
