"""Score a ``casep separate --imu`` result of the shipped MEMS example against the truth in its tracking header.

The shipped example (``examples/data/imu/mems_imu.csv``, ``mems_tracking.csv``, written by
``examples/make_example_mems.py``) carries its true ``strapdown15_axial`` coefficients in the tracking file's
header (``# true strapdown15_axial coefficients: ba_x 20, ...``); terms of a larger model absent there are 0.
This reads a result JSON (``casep separate --imu ... --json RESULT``) and prints: the status and message's
first line, the passes and whether they converged, each coefficient's estimate, std and z = (estimate -
truth) / std where it has a finite std, their RMS, and for the combinations the passes stated
(``diagnostics.determined``: weights on the coefficients in their declared magnitudes) the RMS and largest
|z| of (estimate - weights . truth) / std and how many are within 1.96; then the heading test
(``diagnostics.heading.test``) when present.

Run (the documented commands of docs/guide/navigate.md, then the score)::

    OPENBLAS_NUM_THREADS=1 casep separate --imu examples/data/imu/mems_imu.csv \\
        --tracking examples/data/imu/mems_tracking.csv --launch-site 67.89 21.10 330 30 --launch-time 10 \\
        --align 0 9 --heading 30 --model strapdown15_axial --json OUT/m.json
    python benchmarks/mems_example_z.py OUT/m.json [OUT/d.json ...] [--tracking examples/data/imu/mems_tracking.csv]

``--run DIR`` runs both documented commands (``strapdown15_axial`` and the default model, each with
``--heading`` 30 unless ``--heading`` says otherwise) into DIR first and scores them.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent.parent
TRACKING = HERE / "examples" / "data" / "imu" / "mems_tracking.csv"
IMU = HERE / "examples" / "data" / "imu" / "mems_imu.csv"


def header_truth(tracking: str | Path) -> dict[str, float]:
    """The true coefficients (natural units) in the tracking file's ``# true ... coefficients:`` header line."""
    for line in Path(tracking).read_text().splitlines():
        if not line.startswith("#"):
            break
        if line.startswith("# true") and ":" in line:
            return {k: float(v) for k, v in re.findall(r"(\w+) (-?[\d.eE+]+)", line.split(":", 1)[1])}
    raise ValueError(f"{tracking}: no '# true ... coefficients:' header line")


def rms(z: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(z))))


def score(path: str | Path, truth: dict[str, float]) -> dict:
    """Print and return the scores of one result JSON against ``truth``."""
    import casep

    d = json.loads(Path(path).read_text())
    cs = d["coefficients"]
    names = [c["name"] for c in cs]
    out: dict = {"file": str(path), "model": d.get("model"), "status": d["status"], "success": d.get("success")}
    print(f"{path}: model {d.get('model')}, status {d['status']}, success {d.get('success')}")
    print("  " + d["message"].splitlines()[0][:200] if d.get("message") else "  (no message)")
    it = d["diagnostics"].get("iterations") or {}
    if it:
        out["passes"] = max(int(q.get("iteration", 0)) for q in it["passes"])
        print(f"  passes {out['passes']} ({len(it['passes'])} records), converged {it.get('converged')}")
    z = []
    for c in cs:
        est, std = c.get("estimate"), c.get("std")
        if est is None or std is None or not np.isfinite(std) or std <= 0:
            continue
        zi = (est - truth.get(c["name"], 0.0)) / std
        z.append(zi)
        print(f"  {c['name']:6s} {est:12.5g} +- {std:10.4g}  truth {truth.get(c['name'], 0.0):8g}  z {zi:6.2f}")
    if z:
        out["coef_rms_z"] = rms(np.array(z))
        print(f"  coefficients: RMS z {out['coef_rms_z']:.3f}, max |z| {np.abs(z).max():.2f} ({len(z)} z)")
    det = d["diagnostics"].get("determined")
    if det and det.get("combinations"):
        scales = det.get("scales") or casep.load_model(d["model"]).scales
        t_s = np.array([truth.get(n, 0.0) / scales[n] for n in names])
        zc = np.array([(c["estimate"] - np.asarray(c["weights"]) @ t_s) / c["std"] for c in det["combinations"]])
        out.update(comb_rms_z=rms(zc), comb_max_z=float(np.abs(zc).max()), comb_n=int(zc.size),
                   comb_within=int(np.sum(np.abs(zc) <= 1.96)))
        print(f"  stated combinations: RMS z {out['comb_rms_z']:.3f}, max |z| {out['comb_max_z']:.2f}, "
              f"{out['comb_within']} of {zc.size} within 1.96")
    test = (d["diagnostics"].get("heading") or {}).get("test")
    if test:
        out["heading_test"] = {k: test.get(k) for k in ("estimate_deg", "std_deg", "z", "conflict")}
        print(f"  heading test: {out['heading_test']}")
    return out


def run(directory: Path, heading: float) -> list[Path]:
    """Run the two documented commands into ``directory``; return their JSON paths."""
    from casep.cli import main

    directory.mkdir(parents=True, exist_ok=True)
    common = ["separate", "--imu", str(IMU), "--tracking", str(TRACKING), "--launch-site", "67.89", "21.10", "330",
              "30", "--launch-time", "10", "--align", "0", "9", "--heading", f"{heading:g}"]
    paths = []
    for tag, extra in (("strapdown15_axial", ["--model", "strapdown15_axial"]), ("default", [])):
        p = directory / f"mems_{tag}.json"
        main([*common, *extra, "--json", str(p)])
        paths.append(p)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="*", type=Path, help="result JSON files of casep separate --imu")
    ap.add_argument("--tracking", type=Path, default=TRACKING, help="tracking file whose header holds the truth")
    ap.add_argument("--run", type=Path, metavar="DIR", help="run the documented commands into DIR first")
    ap.add_argument("--heading", type=float, default=30.0, help="heading given with --run (deg; the rail: 30)")
    args = ap.parse_args()
    truth = header_truth(args.tracking)
    paths = list(args.results) + (run(args.run, args.heading) if args.run else [])
    if not paths:
        ap.error("give result JSON files or --run DIR")
    for p in paths:
        score(p, truth)


if __name__ == "__main__":
    main()
