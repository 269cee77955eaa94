"""Cost of reading semicolon- and tab-separated flight files, against the comma file and against the
alternatives (pandas' separator sniffing, ``sep=None`` with the Python engine; ``csv.Sniffer``).

Run: ``python benchmarks/csv_separators.py [N_ROWS]`` (default 100000); prints a Markdown table.
"""

from __future__ import annotations

import csv
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from casep.io.files import read_flight


def best(fn, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main(n: int = 100_000) -> None:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.01
    cols = {"t": t, **{c: rng.normal(size=n) for c in ("f_x", "f_y", "f_z", "dv_x", "dv_y", "dv_z")}}
    df = pd.DataFrame(cols)
    with tempfile.TemporaryDirectory() as d:
        paths = {}
        for name, sep in (("comma", ","), ("semicolon", ";"), ("tab", "\t")):
            paths[name] = Path(d) / f"{name}.csv"
            df.to_csv(paths[name], sep=sep, index=False, float_format="%.17g")
        print(f"| {n} rows | read_flight, s | vs comma |")
        print("|---|---|---|")
        read_flight(paths["comma"])  # warm-up (imports, caches)
        times = {name: best(lambda p=p: read_flight(p)) for name, p in paths.items()}
        base = times["comma"]
        for name, v in times.items():
            print(f"| {name} | {v:.3f} | {v / base:.2f} |")
        v = best(lambda: pd.read_csv(paths["semicolon"], sep=None, engine="python"), repeat=2)
        print(f"| pandas sep=None (Python engine), semicolon | {v:.3f} | {v / base:.2f} |")
        head = paths["semicolon"].read_text()[:4096]
        v = best(lambda: csv.Sniffer().sniff(head, delimiters=",;\t"))
        print(f"| csv.Sniffer on 4 kB | {v:.6f} | - |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
