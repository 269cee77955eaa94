"""Benchmark: where the wall time of `casep demo` can go on two cores, as CPU seconds (load-independent).

The demo's figures are drawn by a worker process while the methods run (casep.reporting.demo_figures.FigureJobs).
On a quiet two-core machine its wall time is about its critical path:

    max(max(main's CPU until the first figure is submitted,
            main's CPU when it starts the worker + the worker's CPU until it is ready)
            + the worker's CPU for all figures,
        main's CPU until its last result + the last figure's CPU)

(the worker's start-up, a new interpreter importing NumPy and matplotlib, runs beside the simulation; an idle
worker waiting for a figure's data in between is not counted), plus the two processes' exits. This script runs
the demo (100 Hz, figures written to a temporary folder) as the command does (the parser built, the worker
started, then the demo imported, ``jobs=``) and
in one process (``parallel=False``), interleaved, and prints those CPU seconds per run, with each run's wall time and
total CPU (main + worker). On a loaded machine the wall times mean little; the CPU seconds much more.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/demo_timeline.py [--runs 3]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any


def call(fn: Any, *args: Any) -> tuple[str, float, float]:
    """In the worker: draw one figure; its name, CPU seconds, and the worker's CPU seconds before it."""
    c = time.process_time()
    fn(*args)
    return fn.__name__, time.process_time() - c, c


def traced(out: str) -> dict[str, float]:
    """One run with the worker, as ``casep demo`` runs it (the parser built, the worker started, then the demo
    imported): main's CPU when the worker starts, at the first figure and at its last result, the figures' CPU."""
    import pickle

    from casep.cli.app import build_parser

    build_parser().parse_args(["demo", "--out", out])
    from casep.reporting import demo_figures

    me = sys.modules.get("demo_timeline") or __import__("demo_timeline")
    marks: dict[str, float] = {}
    jobs_seen: list[Any] = []

    def draw(self: Any, fn: Any, *args: Any) -> None:
        marks.setdefault("first", time.process_time())
        marks["last"] = time.process_time()
        self._queue.put((me.call, (fn,) + args))
        self._jobs.append(fn)
        if self not in jobs_seen:
            jobs_seen.append(self)

    original_exit = demo_figures.FigureJobs.__exit__
    figures: list[tuple[str, float]] = []

    def leave(self: Any, *exc: Any) -> None:
        for _ in self._jobs:
            figures.append(pickle.load(self._proc.stdout)[1])
        self._jobs = []
        original_exit(self, *exc)

    demo_figures.FigureJobs.draw = draw  # type: ignore[method-assign]
    demo_figures.FigureJobs.__exit__ = leave  # type: ignore[method-assign]
    w = time.perf_counter()
    jobs = demo_figures.FigureJobs(True)
    marks["popen"] = time.process_time()
    from casep.workflows import demo

    demo.run_demo(out, jobs=jobs).text()
    wall = time.perf_counter() - w
    demo_figures.FigureJobs.__exit__ = original_exit  # type: ignore[method-assign]
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_figs = sum(f[1] for f in figures)
    ready = figures[0][2]  # the worker's CPU before its first figure: start-up, imports, warm-up
    return {"wall": wall, "main_popen": marks["popen"], "main_first": marks["first"], "worker_ready": ready,
            "main_last": marks["last"], "figures": cpu_figs, "last_figure": figures[-1][1],
            "critical": max(max(marks["first"], marks["popen"] + ready) + cpu_figs, marks["last"] + figures[-1][1]),
            "total": s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime}


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    import subprocess

    here = Path(__file__).resolve().parent
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(here)] + os.environ.get("PYTHONPATH", "").split(os.pathsep)))
    code = ("import sys, json, tempfile, time, resource; import casep.cli.app; import demo_timeline as d; "
            "out = tempfile.mkdtemp(); "
            "r = d.traced(out) if sys.argv[1] == 'worker' else None\n"
            "if r is None:\n"
            "    from casep.workflows.demo import run_demo; w = time.perf_counter(); "
            "run_demo(out, parallel=False).text(); s = resource.getrusage(resource.RUSAGE_SELF); "
            "r = {'wall': time.perf_counter() - w, 'total': s.ru_utime + s.ru_stime}\n"
            "print(json.dumps(r))")
    import json

    rows: dict[str, list[dict[str, float]]] = {"worker": [], "serial": []}
    for _ in range(args.runs):
        for kind in rows:
            p = subprocess.run([sys.executable, "-c", code, kind], check=True, capture_output=True, text=True, env=env,
                               cwd=tempfile.gettempdir())
            rows[kind].append(json.loads(p.stdout.strip().splitlines()[-1]))
            print(kind, {k: round(v, 2) for k, v in rows[kind][-1].items()}, flush=True)
    med = statistics.median
    print("| run | wall (s) | CPU main + worker (s) | main CPU when the worker starts | main CPU to the first figure | "
          "worker CPU to ready | worker CPU, figures | main CPU to its last result | last figure CPU | "
          "critical path CPU (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    w = rows["worker"]
    print(f"| worker (median of {args.runs}) | {med(r['wall'] for r in w):.2f} | {med(r['total'] for r in w):.2f} | "
          f"{med(r['main_popen'] for r in w):.2f} | "
          f"{med(r['main_first'] for r in w):.2f} | {med(r['worker_ready'] for r in w):.2f} | "
          f"{med(r['figures'] for r in w):.2f} | "
          f"{med(r['main_last'] for r in w):.2f} | {med(r['last_figure'] for r in w):.2f} | "
          f"{med(r['critical'] for r in w):.2f} |")
    s = rows["serial"]
    print(f"| one process (median of {args.runs}) | {med(r['wall'] for r in s):.2f} | {med(r['total'] for r in s):.2f} "
          f"| - | - | - | - | - | - | {med(r['total'] for r in s):.2f} |")


if __name__ == "__main__":
    main()
