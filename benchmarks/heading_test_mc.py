"""The heading test against the data (:func:`casep.workflows.imu_separate.heading_conflict`) on seeded flights.

Two flights, each separated with ``casep separate --imu``'s defaults
(:func:`casep.workflows.imu_separate.separate_imu`) at the true heading and at headings off by ``--offsets`` deg:

- ``rail``: the rail launch of ``tests/workflows/test_imu_separate_heading.py`` (28.46 N, rail azimuth 95 deg,
  84 deg elevation, lift-off at 6 s, 10 s of 6 g boost, 20 s in all, a 10 Hz IMU; lift-off and burn-out split at
  their samples, as the test does, so that the tracking, this record's own navigation, has no step ambiguity),
  ``--model`` errors (default ``strapdown15_axial``) drawn at their declared magnitudes per seed, tracking at
  5 Hz with white noise of 0.03 m/s (``--gm`` adds Gauss-Markov noise, tau 1 s, 0.03 m/s);
- ``aircraft``: the tactical aircraft of ``benchmarks/aircraft_flight.py`` cut to ``--minutes`` (default 2.8:
  one turn), the IMU at ``--imu-hz`` (default 25), ``strapdown12`` errors (the strapdown33 draw with only the
  biases and scale factors kept; ``--model strapdown33`` keeps them all), geodetic GNSS tracking.

Printed per seed and offset, one JSON line: the status, the test's estimate of the heading's error and its std
(deg), its z and whether it found a conflict (status -10), and the CPU seconds.

Run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/heading_test_mc.py rail --seeds 1 2 3 4 5 --offsets 0 2 [--gm]
    OPENBLAS_NUM_THREADS=1 python benchmarks/heading_test_mc.py aircraft --seeds 1 2 3 4 5 --offsets 0 2

``--out DIR`` keeps the IMU and tracking files (default: a temporary directory, removed).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

RAIL_SITE = (28.46, -80.53, 3.0, 95.0, 6.0)
RAIL_ALIGN, RAIL_HEADING = (0.0, 5.5), 95.0
KEEP_12 = ("ba_", "sa_", "bg_", "sg_")


def rail_files(seed: int, model_name: str, gm: bool, directory: Path) -> tuple[Path, Path]:
    """The rail launch's IMU and tracking files for one seed (errors drawn at the declared magnitudes)."""
    import casep
    from casep.frames import LaunchSite
    from casep.io.files import write_table
    from casep.navigation import ImuData, check_imu, navigate
    from casep.navigation.imu import split_steps
    from casep.simulation.noise import ar1_noise, white_noise
    from casep.simulation.strapdown import rail_launch, with_drawn_errors

    site = LaunchSite(*RAIL_SITE)
    t = np.round(np.arange(0.0, 20.0, 0.1), 10)
    w, f = rail_launch(site, t, elevation_deg=84.0, boost_g=6.0, burn_s=10.0, coast_g=-0.3, roll=(1.5, 3.0))
    w, f = split_steps(t, w, f)
    nav = navigate(check_imu(ImuData(t, w, f)), site, RAIL_ALIGN, heading_deg=RAIL_HEADING)
    rng = np.random.default_rng(seed)
    w_m, f_m, _ = with_drawn_errors(casep.load_model(model_name), nav.q, w, f, t, rng)
    imu, trk = directory / f"rail_imu{seed}.csv", directory / f"rail_trk{seed}.csv"
    write_table(imu, {"t": t, **{f"w_{a}": w_m[:, i] for i, a in enumerate("xyz")},
                      **{f"fb_{a}": f_m[:, i] for i, a in enumerate("xyz")}})
    k = slice(None, None, 2)
    v = nav.v[k] + white_noise(t[k].size, 0.03, rng)
    if gm:
        v = v + ar1_noise(t[k], 0.03, 1.0, rng)
    write_table(trk, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    return imu, trk


def aircraft_files(seed: int, minutes: float, imu_hz: int, model_name: str, directory: Path) -> tuple[Path, Path]:
    """The aircraft flight's IMU and GNSS files for one seed (strapdown12: only biases and scale factors)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import aircraft_flight as af

    if model_name == "strapdown12":
        full = af.with_errors

        def kept(fb, wb, c):
            return full(fb, wb, {k: (v if k.startswith(KEEP_12) else 0.0) for k, v in c.items()})

        af.with_errors = kept
        try:
            imu, trk, _ = af.flight(seed, minutes, imu_hz, directory)
        finally:
            af.with_errors = full
    else:
        imu, trk, _ = af.flight(seed, minutes, imu_hz, directory)
    return imu, trk


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("flight", choices=("rail", "aircraft"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--offsets", type=float, nargs="+", default=[0.0, 2.0], help="heading errors given, deg")
    ap.add_argument("--model", help="default: strapdown15_axial (rail), strapdown12 (aircraft)")
    ap.add_argument("--gm", action="store_true", help="rail: Gauss-Markov tracking noise beside the white")
    ap.add_argument("--minutes", type=float, default=2.8, help="aircraft: the flight's length")
    ap.add_argument("--imu-hz", type=int, default=25, help="aircraft: the IMU rate")
    ap.add_argument("--out", type=Path, help="keep the files here (default: a temporary directory)")
    args = ap.parse_args()
    model = args.model or ("strapdown15_axial" if args.flight == "rail" else "strapdown12")

    from casep.frames import LaunchSite
    from casep.workflows.imu_separate import separate_imu

    with tempfile.TemporaryDirectory() as tmp:
        directory = args.out or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        for seed in args.seeds:
            if args.flight == "rail":
                imu, trk = rail_files(seed, model, args.gm, directory)
                site, align, heading, kw = LaunchSite(*RAIL_SITE), RAIL_ALIGN, RAIL_HEADING, {}
            else:
                sys.path.insert(0, str(Path(__file__).resolve().parent))
                import aircraft_flight as af

                imu, trk = aircraft_files(seed, args.minutes, args.imu_hz, model, directory)
                site, align, heading = LaunchSite(*af.SITE, af.T_REST), (1.0, af.T_REST - 5.0), af.SITE[3]
                kw = {"tracking_frame": "geodetic"}
            for off in args.offsets:
                t0 = time.process_time()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # said by the result
                    out = separate_imu(imu, trk, site, align, model, heading_deg=heading + off, **kw)
                test = (out.result.diagnostics.get("heading") or {}).get("test") or {}
                print(json.dumps({"flight": args.flight, "model": model, "seed": seed, "offset_deg": off,
                                  "success": out.success, "status": out.result.status,
                                  **{k: test.get(k) for k in ("estimate_deg", "std_deg", "z", "conflict")},
                                  "cpu_s": round(time.process_time() - t0, 1)}), flush=True)


if __name__ == "__main__":
    main()
