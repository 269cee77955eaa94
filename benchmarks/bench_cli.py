"""Benchmark: whole-process wall time of `casep separate` on the example flight against
`python -c "import numpy, pandas"` (issue 10's target: <= 3x), and of `casep demo` (target <= 4 s).

Each command runs once as a warm-up (numba's cache), then `--runs` times; medians and the ratio
of medians are printed as a Markdown table.

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


def wall(cmd: list[str], runs: int) -> float:
    subprocess.run(cmd, check=True, capture_output=True)  # warm-up
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    py = sys.executable
    base = wall([py, "-c", "import numpy, pandas"], args.runs)
    sep = wall([py, "-m", "casep", "separate", str(ROOT / "examples" / "data" / "example_flight.csv")], args.runs)
    with tempfile.TemporaryDirectory() as tmp:
        demo = wall([py, "-m", "casep", "demo", "--out", tmp], max(1, args.runs // 2))
    print("| command | median wall (s) | ratio | target |")
    print("|---|---|---|---|")
    print(f"| `python -c \"import numpy, pandas\"` | {base:.2f} | 1.0 | - |")
    print(f"| `casep separate examples/data/example_flight.csv` | {sep:.2f} | {sep / base:.2f} | <= 3 |")
    print(f"| `casep demo` | {demo:.2f} | {demo / base:.1f} | <= 4 s |")


if __name__ == "__main__":
    main()
