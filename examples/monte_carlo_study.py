"""A Monte Carlo study: which methods reach the Cramer-Rao bound on the paper scenario?

Seeded noise draws on the fixed paper trajectory; per method and coefficient the bias, RMS,
CRLB std, efficiency and 95 % coverage; writes JSON, CSV and a figure.

Run:  python examples/monte_carlo_study.py [--out DIR] [--runs N] [--quick]
"""

#%% Imports and options
import argparse
import tempfile
from pathlib import Path

import numpy as np

from casep.montecarlo import run_montecarlo, write_figure

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--out", default=None, help="folder for mc.json, mc.csv and mc.png")
ap.add_argument("--runs", type=int, default=200)
ap.add_argument("--quick", action="store_true", help="4 runs at 10 Hz (for CI)")
args = ap.parse_args()
out = Path(args.out or tempfile.mkdtemp(prefix="casep-mc-"))
runs, rate = (4, 10.0) if args.quick else (args.runs, None)

#%% Run: batched linear methods, per-run RELS and wavelet + RELS on all cores
res = run_montecarlo("paper", runs=runs, methods=["ols", "rls", "rels", "wavelet+rels", "map"], seed=1, rate=rate)
print(res.text())

#%% The coefficients the flight determines best
for n in ("Ka0x", "Ka1x", "Ka0y", "Ka0z"):
    j = res.names.index(n)
    line = "  ".join(f"{m} {1 / res.stats(m)['efficiency'][j]:.2f}" for m in res.estimates)
    print(f"{n}: RMS/CRLB  {line}")

#%% Save
res.write_json(out / "mc.json")
res.write_csv(out / "mc.csv")
write_figure(res, out / "mc.png")
print("written to", out, "- OLS median efficiency", f"{np.median(res.stats('ols')['efficiency']):.2f}")
