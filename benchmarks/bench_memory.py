"""Peak memory of `casep separate --method ols|rls` and `casep diagnose` on a long flight.

Target: on a 5e6-sample flight, each <= 1.5 GB. Before the Problem object (S_V held
whole, 5e6 x 3 x 36 doubles = 4.3 GB, plus copies) they took 5.0 / 13.2 / 9.0 GB.

The flight is written once (Parquet, deterministic): the analytic excitation of
`examples/make_example_flight.py` (:func:`casep.simulation.synthetic.excitation_force`) at the
rate that gives N samples over 180 s, dv = S_V D (Table 1 truth) + 0.1 m/s white noise, S_V
integrated block by block so that the writer itself stays small. Each command runs in its own
wrapper process whose ``RUSAGE_CHILDREN`` peak RSS is that command's.

    python benchmarks/bench_memory.py [--samples 5000000]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

TARGET_GB = 1.5
BEFORE_GB = {"separate --method ols": 5.0, "separate --method rls": 13.2, "diagnose": 9.0}
_WRAP = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL); "
         "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, r.returncode)")


def write_flight(path: Path, n_samples: int, seed: int = 1) -> None:
    import pandas as pd

    import casep
    from casep.model.sv import SVBuilder
    from casep.simulation.paper import TABLE1_TRUTH
    from casep.simulation.synthetic import excitation_force

    model = casep.load_model("platform36")
    D = np.array([TABLE1_TRUTH.get(n, 0.0) for n in model.names])
    t = np.linspace(0.0, 180.0, n_samples)
    f = excitation_force(t, duration=180.0)
    dv = np.empty((n_samples, 3))
    for s, e, S_b in SVBuilder(model).blocks(t, f, 65536):
        dv[s:e] = S_b @ D
    dv += 0.1 * np.random.default_rng(seed).standard_normal(dv.shape)
    frame = pd.DataFrame({"t": t, "f_x": f[:, 0], "f_y": f[:, 1], "f_z": f[:, 2],
                          "dv_x": dv[:, 0], "dv_y": dv[:, 1], "dv_z": dv[:, 2]})
    frame.to_parquet(path, index=False)


def peak_gb(args: list[str]) -> tuple[float, int]:
    out = subprocess.run([sys.executable, "-c", _WRAP, *args], capture_output=True, text=True, check=True)
    kb, rc = out.stdout.split()
    return int(kb) / 2**20, int(rc)  # ru_maxrss is in KiB on Linux


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=5_000_000)
    a = ap.parse_args()
    casep_cmd = str(Path(sys.executable).with_name("casep"))
    with tempfile.TemporaryDirectory() as tmp:
        flight = Path(tmp) / "long.parquet"
        write_flight(flight, a.samples)
        print(f"flight: {a.samples:.3g} samples, {flight.stat().st_size / 2**20:.0f} MB Parquet; "
              f"S_V whole would be {a.samples * 3 * 36 * 8 / 2**30:.1f} GB")
        print()
        print("| command | peak memory (GB) | target | before (GB) | exit |")
        print("|---|---|---|---|---|")
        base, _ = peak_gb([sys.executable, "-c", "import casep.workflows.separate"])
        print(f"| (python + casep imports) | {base:.2f} | | | 0 |")
        for label in ("separate --method ols", "separate --method rls", "diagnose"):
            cmd = [casep_cmd, *label.split()[:1], str(flight), *label.split()[1:]]
            gb, rc = peak_gb(cmd)
            ok = "met" if gb <= TARGET_GB else "NOT met"
            print(f"| `casep {label}` | {gb:.2f} | <= {TARGET_GB} ({ok}) | {BEFORE_GB[label]} | {rc} |")
    os.sys.stdout.flush()


if __name__ == "__main__":
    main()
