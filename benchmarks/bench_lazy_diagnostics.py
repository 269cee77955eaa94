"""What computing CRLB, VIF and near-dependency groups on first use saves a solve that does not read them.

A Monte Carlo run through a method's solver reads only the estimate and its std; the result's
diagnostics (casep.estimators.result.LazyDiagnostics) are then never computed. Run:

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lazy_diagnostics.py
"""

import time

import numpy as np

from casep.estimators.registry import run_method

RUNS = 40


def per_run(S: np.ndarray, y: np.ndarray, read: bool) -> float:
    t0 = time.perf_counter()
    for _ in range(RUNS):
        res = run_method("ols", S, y, None, {})
        if read:
            res.diagnostics["vif"]  # forces the CRLB, VIF and groups
    return (time.perf_counter() - t0) / RUNS


def main() -> None:
    rng = np.random.default_rng(0)
    S = rng.normal(size=(4000, 3, 36))  # 4000 samples x 3 axes, 36 coefficients
    y = S @ rng.normal(size=36) + rng.normal(size=(4000, 3))
    per_run(S, y, False)  # warm-up
    lazy, read = per_run(S, y, False), per_run(S, y, True)
    print(f"ols per run: {1e3 * lazy:.1f} ms diagnostics not read, {1e3 * read:.1f} ms read "
          f"({100 * (read - lazy) / read:.0f} % saved)")


if __name__ == "__main__":
    main()
