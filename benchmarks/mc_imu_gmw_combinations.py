"""Do the combinations ``casep separate --imu`` states hold their std under Gauss-Markov plus white tracking noise?

The flight of ``tests/workflows/test_imu_separate_gmw.py`` at full size: a 20 s rail launch at 10 Hz (6 s on the pad
at 28.46 N, 80.53 W, rail azimuth 95 deg; 6 g for 10 s, a roll programme) with ``strapdown15_axial`` errors drawn
per seed at their declared magnitudes (tactical), tracked at 5 Hz with Gauss-Markov (`--gm` std, tau 1 s) plus
white (`--white`) noise per axis, drawn per seed after the errors. Each seed is separated with the defaults
(:func:`casep.workflows.imu_separate.separate_imu`: OLS, the noise model chosen by the data, iterated).

Printed per seed: the status and z = (estimate - truth) / std of every combination the result states
(``diagnostics.determined``); then the pooled RMS of z and the share within 1.96 (an honest std: near 1 and 0.95),
the same with the std of the coefficients' covariance along those combinations (``w^T C w``: the coefficients' and the
combinations' std follow one rule), and the same of the coefficients the record determines on their own (std below
their declared magnitude).

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mc_imu_gmw_combinations.py [--seeds 0 1 ... 11] [--gm 0.05]
      [--white 0.03]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from zfigures import z_figures  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(12)))
    ap.add_argument("--gm", type=float, default=0.05, help="Gauss-Markov std per axis, m/s (tau 1 s)")
    ap.add_argument("--white", type=float, default=0.03, help="white std per axis, m/s")
    args = ap.parse_args()

    import casep
    from casep.frames import LaunchSite
    from casep.io.files import write_table
    from casep.model.strapdown import body_errors
    from casep.navigation import ImuData, check_imu, navigate
    from casep.simulation.noise import ar1_noise, white_noise
    from casep.simulation.strapdown import rail_launch
    from casep.workflows.imu_separate import separate_imu

    site, align, heading, model = LaunchSite(28.46, -80.53, 3.0, 95.0, 6.0), (0.0, 5.5), 95.0, "strapdown15_axial"
    t = np.round(np.arange(0.0, 20.0, 0.1), 10)
    w, f = rail_launch(site, t, elevation_deg=84.0, boost_g=6.0, burn_s=10.0, coast_g=-0.3, roll=(1.5, 3.0))
    nav = navigate(check_imu(ImuData(t, w, f)), site, align, heading_deg=heading)
    m = casep.load_model(model)
    scale = np.array([m.scales[n] for n in m.names])
    pooled, coef, along = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            rng = np.random.default_rng(seed)
            truth = rng.standard_normal(len(m.names))  # declared magnitudes
            df, dw = body_errors(m, nav.q, f, w, t - t[0], truth * scale)
            imu, trk = Path(tmp) / f"imu{seed}.csv", Path(tmp) / f"trk{seed}.csv"
            write_table(imu, {"t": t, **{f"w_{a}": (w + dw)[:, i] for i, a in enumerate("xyz")},
                              **{f"fb_{a}": (f + df)[:, i] for i, a in enumerate("xyz")}})
            k = slice(None, None, 2)
            v = nav.v[k] + ar1_noise(t[k], args.gm, 1.0, rng) + white_noise(t[k].size, args.white, rng)
            write_table(trk, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # said by the result
                out = separate_imu(imu, trk, site, align, model, heading_deg=heading)
            combos = out.result.diagnostics.get("determined", {}).get("combinations", [])
            z = np.array([(c["estimate"] - np.dot(c["weights"], truth)) / c["std"] for c in combos])
            pooled.append(z)
            res = out.result
            at = [list(res.names).index(nm) for nm in m.names]
            std = np.full(len(m.names), np.nan) if res.std is None else np.asarray(res.std, dtype=float)[at] / scale
            own = np.isfinite(std) & (std < 1.0)
            zc = (np.asarray(res.estimate, dtype=float)[at] / scale - truth)[own] / std[own]
            C = None if res.covariance is None else np.asarray(res.covariance, dtype=float)[np.ix_(at, at)]
            if C is not None and combos:  # the coefficients' covariance along the combinations stated
                W = np.array([c["weights"] for c in combos], dtype=float)
                sc = np.sqrt(np.einsum("ij,jk,ik->i", W, C / np.outer(scale, scale), W))
                along.append(z * np.array([c["std"] for c in combos]) / sc)
            coef.append(zc)
            print(f"seed {seed:3d}: status {res.status:3d}, {z.size} combinations, z "
                  + " ".join(f"{v:+.2f}" for v in z) + f"; {zc.size} coefficients, z "
                  + " ".join(f"{v:+.2f}" for v in zc), flush=True)
    z = np.concatenate(pooled)
    print(f"pooled: {z.size} z from {len(pooled)} seeds, " + z_figures(z))
    za = np.concatenate(along)
    print(f"coefficients' covariance along the combinations stated: {za.size} z, " + z_figures(za))
    zc = np.concatenate(coef)
    if zc.size:
        print(f"coefficients: {zc.size} z from {len(coef)} seeds, " + z_figures(zc))


if __name__ == "__main__":
    main()
