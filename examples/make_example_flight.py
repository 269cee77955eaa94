"""Make ``examples/data/example_flight.csv``: the flight docs/guide/first-flight.md separates.

#%% What it is
# An analytic boost-like specific force (casep.simulation.synthetic.excitation_force: 1.6 g rising to
# ~5 g, pitched over, small cross-range oscillation) for 180 s at 10 Hz, the paper's Table 1
# error coefficients (platform36) and white tracking noise of 0.1 m/s per axis, seed 1.
# It is a test signal, not a trajectory.
#
# Run:  python examples/make_example_flight.py   (rewrites the file byte for byte)
"""

import argparse
from pathlib import Path

import numpy as np

import casep
from casep.simulation.paper import TABLE1_NOISE_SIGMA, TABLE1_TRUTH
from casep.simulation.synthetic import excitation_force, inject_errors

#%% Build and write
SEED = 1
OUT = Path(__file__).resolve().parent / "data" / "example_flight.csv"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT, help=f"output file (default {OUT.name} in examples/data)")
    out = ap.parse_args().out
    model = casep.load_model("platform36")
    t = np.round(np.arange(0.0, 180.0 + 1e-9, 0.1), 10)
    f = excitation_force(t, duration=180.0)
    truth = np.array([TABLE1_TRUTH[n] for n in model.names])
    dv = inject_errors(model, t, f, truth, sigma=TABLE1_NOISE_SIGMA, rng=np.random.default_rng(SEED))
    out.parent.mkdir(parents=True, exist_ok=True)
    casep.write_flight(
        casep.FlightData(t, f, dv),
        out,
        comments=[
            "casep example flight: analytic excitation (casep.simulation.synthetic.excitation_force), 180 s at 10 Hz",
            f"truth: paper Table 1 (platform36); white noise {TABLE1_NOISE_SIGMA} m/s per axis; seed {SEED}",
            "made by examples/make_example_flight.py",
        ],
    )
    print(f"wrote {out} ({t.size} samples)")


if __name__ == "__main__":
    main()
