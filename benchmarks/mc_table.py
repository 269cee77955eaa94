"""Format a `casep montecarlo --json` file as the Markdown table of docs/results/cramer-rao.md.

Run:  casep montecarlo --scenario paper --runs 200 --seed 1 \\
          --methods ols,rls,rels,wavelet+rels,ridge,pcr,map,bounded --json mc.json
      python benchmarks/mc_table.py mc.json
"""

from __future__ import annotations

import json
import sys

import numpy as np

KEY = ("Ka0x", "Ka1x", "Ka0y", "Ka0z", "Kg0z")


def main(path: str) -> None:
    data = json.loads(open(path, encoding="utf-8").read())
    print(f"scenario {data['scenario']}, {data['runs']} runs, seed {data['seed']}\n")
    print("| method | median RMS/CRLB | " + " | ".join(KEY) + " | median coverage95 | worst coverage95 |")
    print("|---|---|" + "---|" * len(KEY) + "---|---|")
    for meth, d in data["methods"].items():
        rows = {r["name"]: r for r in d["coefficients"]}
        ratio = [r["rms"] / r["crlb_std"] for r in d["coefficients"] if r["rms"] is not None and r["crlb_std"]]
        cov = [r["coverage95"] for r in d["coefficients"] if r["coverage95"] is not None]
        key = [rows[k]["rms"] / rows[k]["crlb_std"] for k in KEY]
        cov_s = f"{np.median(cov):.2f} | {min(cov):.2f}" if cov else "- | -"
        print(f"| {meth} | {np.median(ratio):.3f} | " + " | ".join(f"{v:.2f}" for v in key) + f" | {cov_s} |")


if __name__ == "__main__":
    main(sys.argv[1])
