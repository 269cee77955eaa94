"""Benchmark: `casep separate` on a loaded machine with one BLAS thread (the CLI's default) and with
OpenBLAS's own default (as many threads as cores, what the CLI did before it limited them).

A background load keeps every core busy (one spinning Python process per core, started here and
ended at the end), as other jobs do on a shared server. Each setting runs `--runs` times,
interleaved (A B A B ...), after a warm-up; the table gives median wall and CPU seconds. The
"default threads" row sets OPENBLAS_NUM_THREADS / OMP_NUM_THREADS / MKL_NUM_THREADS to the number
of cores, which the CLI respects (a user's setting is never overridden).

Flight: `casep simulate --scenario paper-range-gm --rate 100` (19 501 samples, Gauss-Markov
tracking noise and gaps), the default noise model and robust fit.

Run:  python benchmarks/bench_blas_threads.py [--runs 3] [--no-load]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_cli import timed  # noqa: E402

VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--no-load", action="store_true", help="no background load")
    args = ap.parse_args()
    cores = os.cpu_count() or 1
    clean = {k: v for k, v in os.environ.items() if k not in VARS}
    settings = {"one BLAS thread (CLI default)": clean,
                f"{cores} BLAS threads (OpenBLAS default; set by the user)": {**clean, **{v: str(cores) for v in VARS}}}
    casep = [sys.executable, "-m", "casep"]
    load = [] if args.no_load else [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(cores)]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            flight = str(Path(tmp) / "range.csv")
            subprocess.run(casep + ["simulate", "--scenario", "paper-range-gm", "--rate", "100", "--seed", "1",
                                    "-o", flight], check=True, capture_output=True, env=clean)
            cmd = casep + ["separate", flight]
            times: dict[str, list[tuple[float, float]]] = {k: [] for k in settings}
            for env in settings.values():
                timed(cmd, env)  # warm-up (numba's cache)
            for _ in range(args.runs):
                for k, env in settings.items():
                    times[k].append(timed(cmd, env))
    finally:
        for p in load:
            p.kill()
            p.wait()
    busy = "no load" if args.no_load else f"{cores} busy processes"
    print(f"`casep separate` 100 Hz range flight, {cores} cores, {busy}; medians of {args.runs}")
    print("| BLAS threads | wall (s) | CPU (s) | min wall | max wall |")
    print("|---|---|---|---|---|")
    for k, v in times.items():
        w = [x[0] for x in v]
        print(f"| {k} | {statistics.median(w):.2f} | {statistics.median(x[1] for x in v):.2f} | {min(w):.2f} "
              f"| {max(w):.2f} |")


if __name__ == "__main__":
    main()
