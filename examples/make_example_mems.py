"""Make ``examples/data/imu/mems_imu.csv`` and ``mems_tracking.csv``: the MEMS flight docs/guide/navigate.md separates.

#%% What it is
# A rocket on a rail at Esrange (67.89 N, 21.10 E, 330 m), body x along the rail at 80 deg elevation
# towards azimuth 30 deg. 10 s at rest on the pad, then 30 s of axial boost (4 g for 20 s, then -0.2 g
# of drag) with a roll programme rising to 2 rad/s and a slow pitch-over, at 20 Hz. Lift-off and burnout fall on
# samples: each is written as the mean of its two sides there (casep.navigation.imu.split_steps, as casep's
# simulator does), so the record has no step between samples whose place in the interval it leaves unknown. The
# clean record is navigated by casep itself (heading given), and that navigation is the truth: the tracking file is its
# launch-inertial velocity at 5 Hz plus Gauss-Markov (tau 1 s, 0.03 m/s) and white (0.02 m/s) noise; the
# IMU file is the clean record plus the errors of a MEMS IMU (strapdown15_axial: 10-20 mg biases, a 0.5 %
# scale factor, a quarter to half a degree of misalignment, 150-250 deg/h gyro biases, ...) by the model's
# own equations. The true coefficients are in the tracking file's header. A test record, not a flight.
#
# Run:  python examples/make_example_mems.py   (rewrites both files; the truth is navigated by casep, so the last
# digits may differ on another CPU or BLAS: tests/test_examples.py holds them equal to 1e-9)
"""

import argparse
from pathlib import Path

import numpy as np

SEED = 1
OUT = Path(__file__).resolve().parent / "data" / "imu"
TRUTH = dict(ba_x=20.0, ba_y=-15.0, ba_z=10.0, sa_x=5000.0, ma_yx=1500.0, ma_zx=-1000.0, bg_x=200.0, bg_y=-150.0,
             bg_z=250.0, sg_x=3000.0, mg_yx=1000.0, mg_zx=-800.0, gg_xx=200.0, gg_yx=-100.0, gg_zx=150.0)


def main() -> None:
    import casep
    from casep.frames import LaunchSite
    from casep.io.files import write_table
    from casep.model.strapdown import body_errors
    from casep.navigation import ImuData, check_imu, navigate
    from casep.navigation.imu import split_steps
    from casep.simulation.noise import ar1_noise, white_noise
    from casep.simulation.strapdown import rail_launch

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out-dir", type=Path, default=OUT, help="output folder (default examples/data/imu)")
    out = ap.parse_args().out_dir
    site = LaunchSite(67.89, 21.10, 330.0, 30.0, 10.0)  # launch azimuth 30 deg, lift-off at t = 10 s
    t = np.round(np.arange(0.0, 40.0, 0.05), 10)
    w, f = rail_launch(site, t, elevation_deg=80.0, boost_g=4.0, burn_s=20.0, coast_g=-0.2, roll=(2.0, 5.0))
    w, f = split_steps(t, w, f)  # lift-off and burnout at their samples: the record the navigation takes exactly
    nav = navigate(check_imu(ImuData(t, w, f)), site, (0.0, 9.0), heading_deg=30.0)  # the truth
    model = casep.load_model("strapdown15_axial")
    df, dw = body_errors(model, nav.q, f, w, t - t[0], np.array([TRUTH[n] for n in model.names]))
    write_table(out / "mems_imu.csv", {"t": t, **{f"w_{a}": (w + dw)[:, i] for i, a in enumerate("xyz")},
                                       **{f"fb_{a}": (f + df)[:, i] for i, a in enumerate("xyz")}},
                comments=["example MEMS IMU record (examples/make_example_mems.py): a rail launch, body x along the "
                          "rail"])
    rng = np.random.default_rng(SEED)
    k = slice(None, None, 4)
    v = nav.v[k] + ar1_noise(t[k], 0.03, 1.0, rng) + white_noise(t[k].size, 0.02, rng)
    write_table(out / "mems_tracking.csv", {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}},
                comments=["example tracking (examples/make_example_mems.py): launch-inertial velocity, 5 Hz",
                          "true strapdown15_axial coefficients: " + ", ".join(f"{n} {v:g}" for n, v in TRUTH.items())])
    print(f"wrote {out / 'mems_imu.csv'} ({t.size} samples) and {out / 'mems_tracking.csv'} ({v.shape[0]} samples)")


if __name__ == "__main__":
    main()
