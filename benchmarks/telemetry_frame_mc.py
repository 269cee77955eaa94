"""How often a strapdown telemetry's dv-sign and frame tests (:mod:`casep.workflows.telemetry_frame`) fire.

Correct ``casep simulate --scenario strapdown-boost`` flights (Gauss-Markov plus white tracking noise) at several
rates and seeds, separated with ``strapdown15_axial``; and the same flights mutated: one ``dv`` axis negated (the axis
``seed % 3``), the attitude ``q_*`` premultiplied by a rotation of 3 and 10 deg about the launch frame's y (up: an
azimuth) and 5 deg about x. Printed per flight: the status, the sign test's largest log-evidence and what it named,
the frame test's rotation (deg) and largest z, and ``sa_x``'s z against the truth (strapdown33's truth; the model
fitted is its axial part). A false naming is a correct flight whose result names a sign or a rotation; a false
warning one whose rotation is beyond ``FRAME_WARN_Z`` std (``diagnostics["frame"]["warn"]``).

Run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/telemetry_frame_mc.py --rates 10 20 50 --seeds 6 [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np


def _mutated(src: Path, dst: Path, how: str, seed: int) -> None:
    """`src` with one dv axis negated (``neg``) or the attitude turned (``rot:AXIS:DEG``), written to `dst`."""
    import pandas as pd
    from scipy.spatial.transform import Rotation

    lines = src.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    d = pd.read_csv(src, comment="#")
    if how == "neg":
        col = f"dv_{'xyz'[seed % 3]}"
        d[col] = -d[col]
    else:
        _, ax, deg = how.split(":")
        q = d[["q_x", "q_y", "q_z", "q_w"]].to_numpy()
        qq = (Rotation.from_euler(ax, float(deg), degrees=True) * Rotation.from_quat(q)).as_quat()
        d[["q_x", "q_y", "q_z", "q_w"]] = qq * np.where(qq[:, 3:] < 0, -1.0, 1.0)
    with open(dst, "w") as fh:
        fh.write("\n".join(head) + "\n")
        d.to_csv(fh, index=False, float_format="%.15g")


def _run(path: Path, truth: dict) -> dict:
    import casep

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = casep.separate(str(path), model="strapdown15_axial")
    sg = res.diagnostics.get("dv_signs") or {}
    fr = res.diagnostics.get("frame") or {}
    j = res.names.index("sa_x")
    return {"status": res.status, "sign_ln_max": max(sg.get("ln_ratio") or [float("nan")]),
            "sign_named": sg.get("named"), "frame_deg": [round(v, 2) for v in fr.get("rotation_deg", [])],
            "frame_z_max": max(fr.get("z") or [float("nan")]), "frame_conflict": fr.get("conflict"),
            "frame_warn": fr.get("warn"),
            "sa_x_z": (res.estimate[j] - truth.get("sa_x", 0.0)) / res.std[j]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[10.0, 20.0, 50.0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--mutations", nargs="*", default=["neg", "rot:y:3", "rot:y:10", "rot:x:5"])
    ap.add_argument("--out", default="/tmp/telemetry_frame_mc")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for rate in args.rates:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            base = out / f"sd_{rate:g}_{seed}.csv"
            if not base.exists():
                subprocess.run([sys.executable, "-m", "casep", "simulate", "--scenario", "strapdown-boost", "--rate",
                                f"{rate:g}", "--seed", str(seed), "-o", str(base)], check=True, capture_output=True)
            truth = json.loads(base.with_suffix(".truth.json").read_text())
            truth = truth.get("coefficients", truth) if isinstance(truth, dict) else {}
            for how in ["correct", *args.mutations]:
                path = base if how == "correct" else out / f"{base.stem}_{how.replace(':', '_')}.csv"
                if how != "correct" and not path.exists():
                    _mutated(base, path, how, seed)
                r = {"rate": rate, "seed": seed, "case": how, **_run(path, truth)}
                rows.append(r)
                print(json.dumps(r), flush=True)
    print("\nsummary (named sign / frame conflict / frame warned / failed, of flights):")
    for how in ["correct", *args.mutations]:
        sel = [r for r in rows if r["case"] == how]
        print(f"{how:10s} n {len(sel):3d}  sign named {sum(r['sign_named'] is not None for r in sel):3d}  frame "
              f"{sum(bool(r['frame_conflict']) for r in sel):3d}  frame warned "
              f"{sum(bool(r['frame_warn']) for r in sel):3d}  "
              f"failed {sum(r['status'] < 0 for r in sel):3d}  "
              f"|sa_x z| max {max(abs(r['sa_x_z']) for r in sel):.2f}")


if __name__ == "__main__":
    main()
