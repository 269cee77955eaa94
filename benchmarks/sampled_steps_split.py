"""A simulated strapdown boost separated with its steps at samples split (as simulated) or kept (as sampled).

``casep simulate --scenario strapdown-boost --rotating-earth`` writes its raw IMU with a step that falls on a
sample (lift-off, a pitch kick) split as the mean of its sides (:func:`casep.navigation.imu.split_steps`), which
the integration takes exactly, so the record navigates back to its truth. ``--keep-steps`` writes it as a
sampled record would hold it (the step within one interval), whose velocity across the step the integration
knows only within ``|df| h / 2``: ``casep separate --imu`` then carries each step in the std as consider
parameters (:func:`casep.workflows.imu_separate.step_rows`). Printed: the exit code and CPU seconds, the first
``--show`` coefficients' estimate, std and z = (estimate - truth) / std against the simulation's truth, and the
result's ``diagnostics.sampled_steps``.

Run (in a directory of one's own; files are written there)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/sampled_steps_split.py OUTDIR [--keep-steps] [--seed 3] [--rate 10]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

SITE = ["--launch-site", "28.5", "-80.6", "10", "90"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="directory the simulated files and the result are written to")
    ap.add_argument("--keep-steps", action="store_true", help="write the steps as sampled (not split)")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--rate", type=float, default=10.0, help="IMU rate, Hz")
    ap.add_argument("--show", type=int, default=4, help="coefficients printed")
    args = ap.parse_args()

    import casep.simulation.strapdown as sim
    from casep.cli import main as cli

    if args.keep_steps:
        sim.split_steps = lambda t, w, f: (w, f)  # type: ignore[assignment]
    args.out.mkdir(parents=True, exist_ok=True)
    os.chdir(args.out)
    assert cli(["simulate", "--scenario", "strapdown-boost", "--rotating-earth", *SITE, "--tracking-frame", "ecef",
                "--imu-pad", "10", "--rate", f"{args.rate:g}", "--seed", str(args.seed), "-o", "r.csv",
                "--imu-output", "imu.csv"]) == 0
    t0 = time.process_time()
    rc = cli(["separate", "--imu", "imu.csv", "--tracking", "r.tracking.csv", "--tracking-frame", "ecef", *SITE,
              "--launch-time", "0", "--align", "-9", "-1", "--heading", "180", "--heading-axis", "z", "--model",
              "strapdown15_axial", "--json", "o.json"])
    print(f"steps {'kept' if args.keep_steps else 'split'}: exit {rc}, {time.process_time() - t0:.1f} s CPU")
    r = json.loads(Path("o.json").read_text())
    truth = json.loads(Path("r.truth.json").read_text())["coefficients"]
    for c in r["coefficients"][: args.show]:
        print(f"  {c['name']:6s} {c['estimate']:12.5g} +- {c['std']:10.4g}  truth {truth[c['name']]:10.4g}  "
              f"z {(c['estimate'] - truth[c['name']]) / c['std']:6.2f}")
    print("  sampled_steps:", json.dumps(r.get("diagnostics", {}).get("sampled_steps")))


if __name__ == "__main__":
    main()
