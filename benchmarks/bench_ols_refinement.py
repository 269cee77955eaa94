"""Benchmark: what the extended-precision refinement of least squares costs on a flight.

OLS on a simulated 100 Hz flight (the ``paper`` scenario, platform36) through
:func:`casep.solve_ols` on its :class:`~casep.regression.problem.Problem` (S_V built once, outside
the timing), with refinement as casep decides it (``auto``: only when the predicted error of the
QR solve exceeds :data:`casep.regression.linalg.REFINE_ABOVE`), never, and always; the median of
`--repeat` runs each, and the predicted error of the flight. The same on a well-conditioned
regression of the same size (Gaussian S, condition number ~1): there ``auto`` must cost nothing.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_ols_refinement.py
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from casep.estimators import ols  # noqa: E402
from casep.model import load_model  # noqa: E402
from casep.regression import linalg  # noqa: E402
from casep.regression.problem import Problem  # noqa: E402
from casep.simulation.simulate import simulate_flight  # noqa: E402


def timed(pb: Problem, repeat: int) -> tuple[float, np.ndarray]:
    """Median seconds of ``solve_ols(pb)`` and its estimate."""
    times = []
    for _ in range(repeat + 1):  # the first call warms the caches and is not counted
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = ols.solve_ols(pb)
        times.append(time.perf_counter() - t0)
    return float(np.median(times[1:])), res.estimate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=100.0, help="sample rate, Hz")
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    sim = simulate_flight("paper", seed=0, rate=args.rate)
    flight = Problem.from_flight(sim.flight, load_model("platform36"), keep_sv=True)
    rng = np.random.default_rng(0)
    S = rng.standard_normal((flight.n_samples, 3, flight.n))
    y = S @ rng.standard_normal(flight.n) + 0.1 * rng.standard_normal((flight.n_samples, 3))
    for label, pb in ((f"paper flight, {args.rate:g} Hz", flight),
                      ("well-conditioned Gaussian S", Problem.from_arrays(S, y))):
        print(label)
        compare(pb, args.repeat)


def compare(pb: Problem, repeat: int) -> None:
    """Time OLS on `pb` with refinement auto, never and always; print the change of the estimate."""
    prep = ols.prepare(pb, None, None, None, None, None)
    V, inv_s = prep.ra.pinv_factors()
    x_Z = V @ (inv_s * (prep.ra.U.T @ prep.red.qty)[: prep.ra.rank])
    eta = linalg.qr_forward_error(prep.red, prep.ra, x_Z)
    kappa = prep.ra.s[0] / prep.ra.s[prep.ra.rank - 1]
    print(f"  {pb.m} rows x {pb.n} coefficients, kappa {kappa:.3g}; predicted error of the QR solve {eta:.2e} "
          f"(refined above {linalg.REFINE_ABOVE:g})")
    results = {}
    for label, limit in (("auto", linalg.REFINE_ABOVE), ("never", np.inf), ("always", -1.0)):
        ols.REFINE_ABOVE = limit  # the threshold least_squares reads
        results[label] = timed(pb, repeat)
        print(f"  solve_ols {label:6s}: {1e3 * results[label][0]:8.2f} ms (median of {repeat})")
    ols.REFINE_ABOVE = linalg.REFINE_ABOVE
    d = np.abs(results["always"][1] - results["never"][1]) / np.maximum(np.abs(results["never"][1]), 1e-300)
    print(f"  largest relative change of an estimate by the refinement: {np.nanmax(d):.2e}")


if __name__ == "__main__":
    main()
