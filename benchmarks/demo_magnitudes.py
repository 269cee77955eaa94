"""The demo's methods against the declared-magnitude check, seed by seed (100 Hz paper flight).

For each seed: which coefficients the plain check (``|estimate| - 5 std >= 100 x declared``, each
method with its own std) would flag, whether the demo warned (it judges ridge, PCR and bounded with the
least-squares std where theirs are smaller), and ridge's largest error in units of its own std and of
the least-squares std. See docs/results/performance.md ("The demo's magnitude warning").

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/demo_magnitudes.py [--seeds 6]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

from casep.estimators._base import MAGNITUDE_WARN, MAGNITUDE_Z
from casep.exceptions import MagnitudeWarning
from casep.workflows.demo import run_demo


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    print("| seed | demo warned | flagged by the plain check (method: coefficients) | ridge max error / own std "
          "| ridge max error / LS std |")
    print("|---|---|---|---|---|")
    for seed in range(1, args.seeds + 1):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", MagnitudeWarning)
            res = run_demo(None, seed=seed)
        model = res.sim.model
        declared = np.array([model.scales[n] for n in model.names])
        flagged = []
        for label, r in res.results.items():
            low = np.abs(r.estimate) - MAGNITUDE_Z * r.std  # what the data say at least, by the method's std
            names = [model.names[j] for j in np.flatnonzero(low >= MAGNITUDE_WARN * declared)]
            if names:
                flagged.append(f"{label}: {', '.join(names)}")
        err = np.abs(res.results["ridge"].estimate - res.sim.truth)
        warned = sum(isinstance(w.message, MagnitudeWarning) for w in caught)
        print(f"| {seed} | {warned} | {'; '.join(flagged) or '-'} | {np.max(err / res.results['ridge'].std):.1f} "
              f"| {np.max(err / res.results['LS'].std):.2f} |", flush=True)


if __name__ == "__main__":
    main()
