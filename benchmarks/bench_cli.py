"""Benchmark: whole-process wall time of `casep` commands against `python -c "import numpy, pandas"`.

Targets: `casep separate` on the 20k-sample example flight <= 3x the baseline,
`casep demo` <= 4 s. `casep --help` and `casep models` show what the lazy imports buy (the CLI
imports a command's modules only when it runs).

Each command runs once as a warm-up (numba's cache), then `--runs` times interleaved with the
baseline (A B A B ...), so that each ratio is taken pair by pair in one run of this script and a
drift of the machine's speed cancels; the table gives medians of the wall times and of the
pairwise ratios.

Run:  python benchmarks/bench_cli.py [--runs 5]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def wall(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def paired(cmd: list[str], base: list[str], runs: int) -> tuple[float, float, float]:
    """Median wall of `cmd`, of `base`, and median of the pairwise ratios cmd / base."""
    wall(cmd), wall(base)  # warm-up
    a, b = [], []
    for _ in range(runs):
        a.append(wall(cmd))
        b.append(wall(base))
    return statistics.median(a), statistics.median(b), statistics.median(x / y for x, y in zip(a, b))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    py = sys.executable
    base = [py, "-c", "import numpy, pandas"]
    casep = [py, "-m", "casep"]
    flight = ROOT / "examples" / "data" / "example_flight.csv"
    rows = [("`casep --help`", casep + ["--help"], "-"),
            ("`casep models`", casep + ["models"], "-"),
            ("`casep separate examples/data/example_flight.csv`", casep + ["separate", str(flight)], "<= 3x")]
    print(f"{args.runs} interleaved runs after a warm-up; medians")
    print("| command | wall (s) | baseline wall (s) | ratio to `import numpy, pandas` | target |")
    print("|---|---|---|---|---|")
    for label, cmd, target in rows:
        t, tb, r = paired(cmd, base, args.runs)
        print(f"| {label} | {t:.2f} | {tb:.2f} | {r:.2f} | {target} |", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        t, tb, r = paired(casep + ["demo", "--out", tmp], base, max(1, args.runs // 2))
    print(f"| `casep demo` | {t:.2f} | {tb:.2f} | {r:.1f} | <= 4 s |")


if __name__ == "__main__":
    main()
