"""``casep navigate IMU.csv --launch-site LAT LON H AZ --launch-time T0 --align T1 T2 -o TEL.csv``: the strapdown
navigation solution in the launch-inertial frame from raw IMU data (casep.navigation)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import alignment, flight_options, inputs, options, outputs


def add_parser(sub: Any) -> None:
    p = sub.add_parser("navigate", help="strapdown navigation from raw IMU data: the strapdown telemetry "
                                        "(attitude, body rate and specific force, launch-inertial velocity)")
    p.add_argument("imu", help="IMU file: t, w_x..w_z (rad/s), fb_x..fb_z (m/s^2); or t, dth_x..dth_z (rad), "
                               "dvb_x..dvb_z (m/s), each over the sample period ending at t")
    flight_options.add_launch_site(p, required=True, scale="the IMU's")
    alignment.add_alignment(p, required=True)
    flight_options.add_full_scales(p, "the solution from the first clipped sample on is marked ins_valid = 0 (and left "
                               "out of a separation)")
    p.add_argument("-o", "--output", metavar="TEL.csv", required=True,
                   help="the strapdown telemetry: t, q_w..q_z, fb_*, w_*, v_tel_*, r_tel_* (CSV, or Parquet for "
                        ".parquet)")
    options.add_json(p, "the navigation summary JSON (alignment, pad check, end state)")


def run(args: argparse.Namespace) -> int:
    from casep.io.files import write_table
    from casep.navigation.imu import read_imu
    from casep.navigation.navigator import navigate

    ranges = flight_options.full_scales(args)
    outputs.check({"--output": args.output, "--json": args.json}, [args.imu])
    site = inputs.launch_site(args.launch_site, args.launch_time)
    res = navigate(read_imu(args.imu, **ranges), site, tuple(args.align), heading_deg=args.heading,
                   heading_axis=args.heading_axis, **alignment.bias_tolerances(args))
    write_table(args.output, res.columns(), comments=res.comments(args.imu))
    if args.json:
        outputs.write_json(res.to_dict(), args.json)
    print(res.text())
    print(f"telemetry written to {args.output}")
    return outputs.status(res)
