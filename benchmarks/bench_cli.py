"""Benchmark: whole-process wall and CPU time of `casep` commands against `python -c "import numpy, pandas"`.

Targets: `casep separate` on the 20k-sample example flight <= 3x the baseline,
`casep demo` <= 4 s wall. `casep --help` and `casep models` show what the lazy imports buy (the CLI
imports a command's modules only when it runs).

Each command runs once as a warm-up (numba's cache), then `--runs` times interleaved with the
baseline (A B A B ...), so that each ratio is taken pair by pair in one run of this script and a
drift of the machine's speed cancels; the table gives medians of the wall times and of the
pairwise ratios. CPU seconds (user + system of the finished child, `resource.getrusage`) are given
beside the wall times: on a shared machine the wall time of a single-threaded command grows with
the load and its CPU time much less, so a CPU ratio near the wall ratio says the machine was quiet.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_cli.py [--runs 5] [--only separate,demo]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and CPU seconds (user + system) of one whole run of `cmd`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def paired(cmd: list[str], base: list[str], runs: int) -> dict[str, float]:
    """Medians of `cmd`'s and `base`'s wall and CPU seconds and of the pairwise ratios cmd / base."""
    timed(cmd), timed(base)  # warm-up
    a, b = [], []
    for _ in range(runs):
        a.append(timed(cmd))
        b.append(timed(base))
    med = statistics.median
    return {"wall": med(x[0] for x in a), "cpu": med(x[1] for x in a),
            "base_wall": med(y[0] for y in b), "base_cpu": med(y[1] for y in b),
            "ratio": med(x[0] / y[0] for x, y in zip(a, b)), "cpu_ratio": med(x[1] / y[1] for x, y in zip(a, b)),
            "min": min(x[0] for x in a), "max": max(x[0] for x in a)}


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--only", default="help,models,separate,demo",
                    help="comma-separated rows to run (help, models, separate, demo)")
    args = ap.parse_args()
    only = set(args.only.split(","))
    py = sys.executable
    base = [py, "-c", "import numpy, pandas"]
    casep = [py, "-m", "casep"]
    flight = ROOT / "examples" / "data" / "example_flight.csv"
    print(f"{args.runs} interleaved runs after a warm-up; medians (wall, and CPU = user + system)")
    print("| command | wall (s) | CPU (s) | baseline wall (s) | ratio to `import numpy, pandas` (wall) "
          "| ratio (CPU) | target |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        rows = [("help", "`casep --help`", casep + ["--help"], "-"),
                ("models", "`casep models`", casep + ["models"], "-"),
                ("separate", "`casep separate examples/data/example_flight.csv`", casep + ["separate", str(flight)],
                 "<= 3x"),
                ("demo", "`casep demo`", casep + ["demo", "--out", tmp], "<= 4 s wall")]
        for key, label, cmd, target in rows:
            if key not in only:
                continue
            r = paired(cmd, base, args.runs)
            spread = f" (min {r['min']:.2f}, max {r['max']:.2f})" if key == "demo" else ""
            print(f"| {label} | {r['wall']:.2f}{spread} | {r['cpu']:.2f} | {r['base_wall']:.2f} | {r['ratio']:.2f} "
                  f"| {r['cpu_ratio']:.2f} | {target} |", flush=True)


if __name__ == "__main__":
    main()
