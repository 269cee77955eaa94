"""``casep separate --imu IMU.csv --tracking TRK.csv ...``: a raw IMU record navigated, paired and separated
(casep.workflows.imu_separate)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import alignment, inputs, outputs
from casep.cli.capture import recorded, report_lines
from casep.cli.separate_output import figures_and_report, print_result
from casep.cli.types import finite_float

__all__ = ["imu_only", "separate_imu", "add_heading_std", "add_imu_stds"]


def add_heading_std(parser: Any) -> None:
    """``--heading-std DEG``: the std of ``--heading`` (casep.workflows.imu_separate.HEADING_STD_DEG by default)."""
    parser.add_argument("--heading-std", type=finite_float, default=None, metavar="DEG",
                        help="with --imu --heading: the heading's std, deg (default 0.1: a surveyed rail and the "
                             "IMU's mounting on it), carried into the std; 0: the heading exact. The data's own "
                             "estimate of the heading is tested against it: a heading they contradict fails the "
                             "result (status -10)")


def add_imu_stds(parser: Any) -> None:
    """``--heading-std DEG`` (:func:`add_heading_std`) and ``--clock-drift-std PPM``: the std of the IMU clock's drift
    (``--imu``, a strapdown telemetry's) beyond ``--clock-drift`` (casep.workflows.imu_separate.CLOCK_DRIFT_STD_PPM,
    CLOCK_GIVEN_STD_PPM by default)."""
    add_heading_std(parser)
    parser.add_argument("--clock-drift-std", type=finite_float, default=None, metavar="PPM",
                        help="with --imu, or a strapdown telemetry with --tracking: the std of the IMU's (the "
                             "INS's) clock drift against the tracking's beyond --clock-drift, ppm (default 50 "
                             "without --clock-drift: a flight computer's crystal; 2 with it: a drift measured against "
                             "GPS time), carried into the std; 0: the rate exact")


def imu_only(args: argparse.Namespace) -> None:
    """`--imu` with what it needs; its options without it: an error, not ignored."""
    if not args.imu:
        for flag, value in (("--align", args.align), ("--heading", args.heading), ("--heading-std", args.heading_std),
                            ("--max-iterations", args.max_iterations),
                            ("--accel-bias-tolerance", args.accel_bias_tolerance),
                            ("--gyro-bias-tolerance", args.gyro_bias_tolerance),
                            ("--heading-axis", None if args.heading_axis == "x" else args.heading_axis)):
            if value is not None:
                raise ValueError(f"{flag} is used only with --imu IMU.csv")
        if args.clock_drift_std is not None:  # a strapdown telemetry's clock too (casep.workflows.telemetry_clock)
            if not args.tracking:
                raise ValueError("--clock-drift-std is used only with --imu IMU.csv or a telemetry with --tracking")
            from casep.workflows.imu_separate import given_clock_std

            given_clock_std(args.clock_drift, args.clock_drift_std, "--clock-drift-std")
        return
    if args.flight or args.manifest:
        raise ValueError("--imu IMU.csv is the flight: give no FLIGHT file or --manifest with it")
    for flag, value in (("--tracking FILE", args.tracking), ("--launch-site LAT LON H AZ", args.launch_site),
                        ("--launch-time T0", args.launch_time), ("--align T1 T2", args.align)):
        if value is None:
            raise ValueError(f"--imu {args.imu} needs {flag}")
    from casep.workflows.imu_separate import given_clock_std, given_heading_std

    given_heading_std(args.heading, args.heading_std, ("--heading DEG", f"--heading-std {args.heading_std}"))
    given_clock_std(args.clock_drift, args.clock_drift_std, "--clock-drift-std")
    if len(args.tracking) != 1:
        raise ValueError(f"--tracking given {len(args.tracking)} times: --imu takes one tracking file")


def separate_imu(args: argparse.Namespace, spec: Any, ranges: dict) -> int:
    """``casep separate --imu IMU.csv --tracking TRK.csv ...``: casep.workflows.imu_separate.separate_imu."""
    from casep.workflows.imu_separate import iteration_lines, separate_imu

    site = inputs.launch_site(args.launch_site, args.launch_time)
    with recorded() as caught:
        out = separate_imu(args.imu, args.tracking[0], site, tuple(args.align), args.model, heading_deg=args.heading,
                           heading_axis=args.heading_axis, spec=spec, iterate=args.iterate is not False,
                           max_iterations=args.max_iterations, tracking_frame=args.tracking_frame,
                           grid=args.grid, time_offset=args.time_offset, time_shift=args.time_shift,
                           clock_drift=args.clock_drift, heading_std_deg=args.heading_std,
                           clock_drift_std=args.clock_drift_std,
                           **alignment.bias_tolerances(args), **ranges)
    res, flight = out.result, out.flight
    prov = outputs.provenance(args, [flight], {"imu": args.imu})
    if args.json:
        outputs.write_json({**out.to_dict(), "provenance": prov}, args.json)
    outputs.write_exports(res, args, t=flight.t[flight.observed], provenance=prov)
    print_result(res, args, flight.meta.get("time_alignment"), None, tuple(iteration_lines(res.diagnostics)))
    figures_and_report(args, res, flight, None, None, report_lines(caught), prov)
    return outputs.status(res)
