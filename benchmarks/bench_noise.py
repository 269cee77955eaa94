"""Benchmark: `casep separate --noise auto --robust` against plain `--noise white` (whole process).

Target: on a 200 s flight with 20 Hz tracking, ``--noise auto --robust`` takes at most 1.5x the
wall time of ``--noise white`` least squares. Two flights: white tracking noise (``paper`` at
20 Hz: the white fit is plain least squares) and the range scenario (``paper-range``:
Gauss-Markov noise, gaps, glitches; the white fit there also runs its whiteness test and the
warning's Gauss-Markov comparison). Each pair runs interleaved after a warm-up; medians of the
wall times and of the pairwise ratios.

Run:  python benchmarks/bench_noise.py [--runs 5]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def wall(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    casep = [sys.executable, "-m", "casep"]
    with tempfile.TemporaryDirectory() as tmp:
        flights = {}
        for scenario, rate in (("paper", "20"), ("paper-range", "20")):
            path = Path(tmp) / f"{scenario}.csv"
            subprocess.run(casep + ["simulate", "--scenario", scenario, "--rate", rate, "--seed", "3", "-o",
                                    str(path)], check=True, capture_output=True)
            flights[scenario] = path
        print(f"{args.runs} interleaved runs after a warm-up; medians")
        print("| flight | `--noise white` wall (s) | `--noise auto --robust` wall (s) | ratio | target |")
        print("|---|---|---|---|---|")
        for scenario, path in flights.items():
            base = casep + ["separate", str(path), "--noise", "white"]
            cmd = casep + ["separate", str(path), "--noise", "auto", "--robust"]
            wall(base), wall(cmd)  # warm-up (numba's cache)
            a, b = [], []
            for _ in range(args.runs):
                a.append(wall(cmd))
                b.append(wall(base))
            ratio = statistics.median(x / y for x, y in zip(a, b))
            print(f"| `{scenario}` 20 Hz | {statistics.median(b):.2f} | {statistics.median(a):.2f} | {ratio:.2f} "
                  f"| <= 1.5 |", flush=True)


if __name__ == "__main__":
    main()
