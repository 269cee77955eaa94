"""Are the std of ``casep separate --imu`` honest along what a MEMS rail launch determines? A seeded Monte Carlo.

The flight: a rail launch at Andoya (69.29 N, 16.02 E, 20 m), the rail at 84 deg elevation towards azimuth 340;
8 s on the pad, 12 s of boost at 6 g, 25 s of coast at -0.3 g; a roll programme up to 3 rad/s, a slow pitch
(-0.04 rad/s) and a yaw wobble; a 50 Hz IMU with MEMS-size errors of ``strapdown15_axial`` (biases of 10 mg
and 100 deg/h, scale factors and misalignments of 1000 ppm / arcsec, g-sensitivity of 100 deg/h/g); tracking at
10 Hz with Gauss-Markov (tau 1 s, 0.05 m/s) plus white (0.03 m/s) noise per axis, drawn per seed. The truth
trajectory is casep's own navigation of the clean record. Each seed is separated as ``casep separate --imu IMU
--tracking TRK --launch-site 69.29 16.02 20 340 --launch-time 8 --align 0 7.5 --heading 340 --model
strapdown15_axial`` (:func:`casep.workflows.imu_separate.separate_imu`, the defaults).

Printed per seed, with e = estimate - truth and C the result's covariance: the status, the passes, the
per-coefficient RMS of z = e / std and the share within 1.96 std, the chi-square ``e^T C^-1 e`` over all
15 coefficients, and the chi-square over the determined combinations: the principal directions of C with
the coefficients in their declared magnitudes (``e_s = e / scale``) whose std is below 1 (the rule of
:func:`casep.checks.tracking_quality.determined`), ``sum_i (v_i . e_s)^2 / lambda_i`` on as many degrees of
freedom. Then the pooled figures and the mean chi-square per degree of freedom.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/mems_rail_honesty.py [--seeds 1 2 3 4 5 6]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

#: The injected coefficients (natural units of strapdown15_axial).
TRUTH = dict(ba_x=12.0, ba_y=-8.0, ba_z=15.0, sa_x=-3000.0, ma_yx=900.0, ma_zx=1200.0, bg_x=-120.0, bg_y=300.0,
             bg_z=180.0, sg_x=2000.0, mg_yx=-700.0, mg_zx=500.0, gg_xx=80.0, gg_yx=150.0, gg_zx=-60.0)
MODEL = "strapdown15_axial"
#: Launch site (lat, lon, h, rail azimuth), launch time (s) and the pad window of the IMU (s).
SITE = (69.29, 16.02, 20.0, 340.0, 8.0)
ALIGN = (0.0, 7.5)


def clean_flight():
    """The clean 50 Hz record (t, w, f), its navigation (the truth) and the site."""
    from casep.frames import LaunchSite
    from casep.navigation import ImuData, check_imu, navigate
    from casep.simulation.strapdown import rail_launch

    site = LaunchSite(*SITE)
    t = np.round(np.arange(0.0, 45.0, 0.02), 10)
    w, f = rail_launch(site, t, elevation_deg=84.0, boost_g=6.0, burn_s=12.0, coast_g=-0.3, lateral=(0.05, 0.7),
                       roll=(3.0, 6.0), pitch_rate=-0.04, yaw=(0.02, 0.5))
    nav = navigate(check_imu(ImuData(t, w, f)), site, ALIGN, heading_deg=SITE[3])
    return t, w, f, nav, site


def write_seed(d: Path, seed: int, clean) -> tuple[Path, Path]:
    """The raw IMU (errors of :data:`TRUTH`) and the seed's noisy tracking, as CSV files in `d`."""
    import casep
    from casep.io.files import write_table
    from casep.model.strapdown import body_errors
    from casep.simulation.noise import ar1_noise, white_noise

    t, w, f, nav, _ = clean
    model = casep.load_model(MODEL)
    df, dw = body_errors(model, nav.q, f, w, t - t[0], np.array([TRUTH[n] for n in model.names]))
    imu, trk = d / f"s{seed}_imu.csv", d / f"s{seed}_trk.csv"
    write_table(imu, {"t": t, **{f"w_{c}": (w + dw)[:, i] for i, c in enumerate("xyz")},
                      **{f"fb_{c}": (f + df)[:, i] for i, c in enumerate("xyz")}})
    rng = np.random.default_rng(seed)
    tk = t[::5]
    v = nav.v[::5] + ar1_noise(tk, 0.05, 1.0, rng) + white_noise(tk.size, 0.03, rng)
    write_table(trk, {"t": tk, **{f"v_trk_{c}": v[:, i] for i, c in enumerate("xyz")}})
    return imu, trk


def figures(res) -> dict:
    """z, chi-square over every coefficient and over the determined combinations (module notes)."""
    from casep.model.loader import load_model

    names = list(res.names)
    scales = load_model(MODEL).scales
    e = res.estimate - np.array([TRUTH[n] for n in names])
    C = np.asarray(res.covariance)
    z = e / res.std
    s = np.array([scales[n] for n in names])
    lam, V = np.linalg.eigh(C / np.outer(s, s))
    proj = V.T @ (e / s)
    det = lam < 1.0
    last = res.diagnostics["iterations"]["passes"][-1]
    truth = np.array([TRUTH[n] for n in names]) / s  # declared magnitudes, as the stated combinations' weights
    stated = np.array([(c["estimate"] - np.dot(c["weights"], truth)) / c["std"] for c in last.get("determined", [])])
    return {"z": z, "chi2": float(e @ np.linalg.solve(C, e)), "chi2_det": float(np.sum(proj[det] ** 2 / lam[det])),
            "dof_det": int(det.sum()), "stated": stated}


def main() -> None:
    from casep.frames import LaunchSite
    from casep.workflows.imu_separate import separate_imu

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    clean = clean_flight()
    zs, chi, told, cpu = [], [], [], time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            imu, trk = write_seed(Path(tmp), seed, clean)
            out = separate_imu(imu, trk, LaunchSite(*SITE), ALIGN, MODEL, heading_deg=SITE[3])
            r = figures(out.result)
            zs.append(r["z"])
            told.append(r["stated"])
            chi.append((r["chi2_det"], r["dof_det"], r["chi2"]))
            it = out.result.diagnostics["iterations"]
            print(f"seed {seed}: status {out.status}, {len(it['passes'])} passes; "
                  f"RMS z {np.sqrt(np.mean(r['z']**2)):.3f}, coverage {np.mean(np.abs(r['z']) < 1.96):.3f}; "
                  f"chi2 determined {r['chi2_det']:.1f}/{r['dof_det']}, "
                  f"all {r['chi2']:.1f}/15; stated {r['stated'].size}, max |z| "
                  f"{np.max(np.abs(r['stated']), initial=0.0):.2f}; {out.message[:90]}", flush=True)
    z = np.concatenate(zs)
    c = np.array(chi)
    zt = np.concatenate(told)
    print(f"{len(args.seeds)} seeds, {time.process_time() - cpu:.0f} CPU s: RMS z {np.sqrt(np.mean(z**2)):.3f}, "
          f"coverage {np.mean(np.abs(z) < 1.96):.3f}; chi2/dof determined {c[:, 0].sum() / c[:, 1].sum():.2f} "
          f"(per seed {', '.join(f'{a / b:.2f}' for a, b in c[:, :2])}), all 15 {c[:, 2].mean() / 15:.2f}; the "
          f"combinations stated: {zt.size}, RMS z {np.sqrt(np.mean(zt**2)) if zt.size else np.nan:.3f}, "
          f"within 1.96 std {np.mean(np.abs(zt) < 1.96) if zt.size else np.nan:.3f}")


if __name__ == "__main__":
    main()
