"""Benchmark: whole-process wall and CPU time of `casep` commands against `python -c "import numpy, pandas"`.

Targets: `casep separate` on the example flight (1 800 samples, 10 Hz) and on a 100 Hz range flight
(`casep simulate --scenario paper-range-gm --rate 100`: Gauss-Markov tracking noise, tracking gaps,
19 501 samples; the default noise model `auto` and robust fit) <= 3x the baseline, `casep demo` <= 4 s
wall. `casep --help` and `casep models` show what the lazy imports buy (the CLI
imports a command's modules only when it runs).

Each command runs once as a warm-up (numba's cache, and the bytecode of casep's modules: the commands run
without ``PYTHONDONTWRITEBYTECODE``, as an installed casep does), then `--runs` times interleaved with the
baseline (A B A B ...), so that each ratio is taken pair by pair in one run of this script and a
drift of the machine's speed cancels; the table gives medians of the wall times and of the
pairwise ratios. CPU seconds (user + system of the finished child, `resource.getrusage`) are given
beside the wall times: on a shared machine the wall time of a single-threaded command grows with
the load and its CPU time much less, so a CPU ratio near the wall ratio says the machine was quiet.

With ``--against CHECKOUT`` (another checkout of casep, e.g. ``git worktree add /tmp/casep-main main``)
each command is paired with the same command run on that checkout's code (``PYTHONPATH=CHECKOUT``)
instead of with the import baseline: the ratio is then new / old, measured under the same load.

Run:  python benchmarks/bench_cli.py [--runs 5] [--only separate,range,demo] [--against DIR]
(the CLI runs with one BLAS thread unless OPENBLAS/OMP/MKL_NUM_THREADS is set:
benchmarks/bench_blas_threads.py)
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall seconds and CPU seconds (user + system) of one whole run of `cmd` (environment `env`)."""
    # with bytecode, as an installed casep runs: PYTHONDONTWRITEBYTECODE would compile every module each run
    env = {k: v for k, v in (os.environ if env is None else env).items() if k != "PYTHONDONTWRITEBYTECODE"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # from a neutral folder: `python -m` puts the working folder first on sys.path, before PYTHONPATH
    subprocess.run(cmd, check=True, capture_output=True, env=env, cwd=tempfile.gettempdir())
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def paired(cmd: list[str], base: list[str], runs: int, base_env: dict[str, str] | None = None) -> dict[str, float]:
    """Medians of `cmd`'s and `base`'s wall and CPU seconds and of the pairwise ratios cmd / base."""
    timed(cmd), timed(base, base_env)  # warm-up
    a, b = [], []
    for _ in range(runs):
        a.append(timed(cmd))
        b.append(timed(base, base_env))
    med = statistics.median
    return {"wall": med(x[0] for x in a), "cpu": med(x[1] for x in a),
            "base_wall": med(y[0] for y in b), "base_cpu": med(y[1] for y in b),
            "ratio": med(x[0] / y[0] for x, y in zip(a, b)), "cpu_ratio": med(x[1] / y[1] for x, y in zip(a, b)),
            "min": min(x[0] for x in a), "max": max(x[0] for x in a)}


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--only", default="help,models,separate,range,demo",
                    help="comma-separated rows to run (help, models, separate, range, demo)")
    ap.add_argument("--against", metavar="CHECKOUT", help="pair each command with itself run on another checkout")
    args = ap.parse_args()
    only = set(args.only.split(","))
    py = sys.executable
    base = [py, "-c", "import numpy, pandas"]
    casep = [py, "-m", "casep"]
    flight = ROOT / "examples" / "data" / "example_flight.csv"
    against = None if args.against is None else dict(os.environ, PYTHONPATH=str(Path(args.against).resolve()))
    print(f"{args.runs} interleaved runs after a warm-up; medians (wall, and CPU = user + system)")
    versus = "`import numpy, pandas`" if against is None else f"the same command on {args.against}"
    print(f"| command | wall (s) | CPU (s) | baseline wall (s) | ratio to {versus} (wall) | ratio (CPU) | target |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        rows = [("help", "`casep --help`", casep + ["--help"], "-"),
                ("models", "`casep models`", casep + ["models"], "-"),
                ("separate", "`casep separate examples/data/example_flight.csv`", casep + ["separate", str(flight)],
                 "<= 3x"),
                ("range", "`casep separate` 100 Hz range flight (paper-range-gm)",
                 casep + ["separate", str(Path(tmp) / "range.csv")], "<= 3x"),
                ("demo", "`casep demo`", casep + ["demo", "--out", tmp], "<= 4 s wall")]
        if "range" in only:
            subprocess.run(casep + ["simulate", "--scenario", "paper-range-gm", "--rate", "100", "--seed", "1",
                                    "-o", str(Path(tmp) / "range.csv")], check=True, capture_output=True)
        for key, label, cmd, target in rows:
            if key not in only:
                continue
            r = paired(cmd, base, args.runs) if against is None else paired(cmd, cmd, args.runs, against)
            spread = f" (min {r['min']:.2f}, max {r['max']:.2f})" if key == "demo" else ""
            print(f"| {label} | {r['wall']:.2f}{spread} | {r['cpu']:.2f} | {r['base_wall']:.2f} | {r['ratio']:.2f} "
                  f"| {r['cpu_ratio']:.2f} | {target} |", flush=True)


if __name__ == "__main__":
    main()
