"""``casep calibrate SESSION``: instrument error coefficients from a ground test (casep.calibration)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import drift_options, flight_options, options, outputs
from casep.cli.types import positive_float as _pos
from casep.estimators.registry import METHODS, OPTIONS


def add_parser(sub: Any) -> None:
    p = sub.add_parser("calibrate", help="identify instrument error coefficients from a ground test "
                       "(static positions and rotations)")
    p.add_argument("session", help="session CSV or Parquet: raw accelerometer and gyro columns (any units), "
                   "and `t` (s) or a sample-index column with --rate")
    p.add_argument("--rate", type=float, default=None, metavar="HZ", help="sample rate, Hz (required without `t`)")
    seg = p.add_mutually_exclusive_group(required=True)
    seg.add_argument("--segments", metavar="FILE", default=None,
                     help="segments JSON: imucal's section list {name: {start, end}} or a list of segments; "
                          "or `auto`: find the segments (model multiposition: a hand-turned session's poses; "
                          "--model ferraris: the six poses and three turns of a Ferraris session)")
    seg.add_argument("--label-column", metavar="NAME", default=None, dest="label_column",
                     help="column labelling each row's segment (imucal's annotated sessions: part)")
    p.add_argument("--model", default=None, help="calibration model name (models/calibration) or .py file "
                   "(default ferraris, with --segments auto multiposition; platform36_ground: the flight model's "
                   "names and units, SI readings)")
    p.add_argument("--method", default="ols", choices=[m for m, meth in METHODS.items()
                                                        if not (meth.needs_time or meth.noise_in_time)],
                   help="estimator (default ols)")
    for name in ("prior", "bounds", "lam", "n_components", "p0", "weight", "forgetting", "noise_order"):
        options.add_option(p, OPTIONS[name])
    p.add_argument("--prior-rel-std", type=float, default=None, dest="prior_rel_std", metavar="R",
                   help="with an imucal or imu_tk --prior: its relative std (they state none)")
    p.add_argument("--sigma", type=float, default=None, help="noise std of the rows (default estimated per sensor): "
                   "reading units with --weighting segments|samples, 1 = as modelled with positions")
    p.add_argument("--acc-columns", default="acc_x,acc_y,acc_z", help="accelerometer columns x,y,z")
    p.add_argument("--gyr-columns", default="gyr_x,gyr_y,gyr_z", help="gyro columns x,y,z")
    p.add_argument("--acc-unit", default="a.u.", help="accelerometer unit: a.u. (raw), m/s^2, g, mg")
    p.add_argument("--gyr-unit", default="a.u.", help="gyro unit: a.u. (raw), deg/s, rad/s, deg/h")
    p.add_argument("--gravity", type=float, default=None, metavar="M_S2",
                   help="gravity at the stand, m/s^2 (default 9.80665; imucal uses 9.81)")
    p.add_argument("--angle", type=float, default=-360.0, metavar="DEG",
                   help="angle of imucal's x_rot/y_rot/z_rot turns, deg (default -360: clockwise, imucal's)")
    p.add_argument("--weighting", choices=("positions", "segments", "samples"), default="positions",
                   help="rows: segment means weighted by a position-error (tilt) and noise model (default), "
                        "segment means of equal weight, or every sample (exact positions)")
    auto = p.add_argument_group("--segments auto (no labels: a hand-turned session, or a Ferraris one with --model)")
    auto.add_argument("--latitude", type=float, default=None, metavar="DEG",
                      help="local gravity from the WGS84 normal gravity at this latitude (instead of --gravity)")
    auto.add_argument("--height", type=float, default=0.0, metavar="M", help="ellipsoidal height with --latitude, m")
    auto.add_argument("--window", type=_pos, default=0.5, metavar="S", help="variance window, s (default 0.5)")
    auto.add_argument("--init", type=_pos, default=5.0, metavar="S",
                      help="initial static period the session starts with, s (default 5)")
    auto.add_argument("--min-static", type=_pos, default=0.5, metavar="S", help="shortest static pose, s (default 0.5)")
    flight_options.add_full_scales(auto, "a gyro saturated inside a turn fails the calibration, a pose with a clipped "
                                  "accelerometer is left out (raw counts: the full scale the fit implies is checked "
                                  "against the declared one)")
    drift_options.add_drift_priors(auto)
    auto.add_argument("--imu-tk", metavar="PREFIX", default=None, dest="imu_tk",
                      help="also write PREFIX_acc.calib and PREFIX_gyro.calib (imu_tk's text format)")
    auto.add_argument("--figures", metavar="DIR", default=None,
                      help="write segmentation.png (the detector's statistic, the poses, turns and rejected runs) "
                           "into DIR (created)")
    p.add_argument("--json", metavar="OUT", default=None, help="write the calibration JSON (a casep result)")
    p.add_argument("--imucal", metavar="OUT", default=None, help="also write imucal's calibration JSON (ferraris)")


def run(args: argparse.Namespace) -> int:
    """One call of casep.calibration.calibrate_files, the report, the files (all or none)."""
    if args.model == "multiposition" or (args.segments == "auto" and args.model is None):
        return _run_auto(args)
    from casep.calibration.calibrate import calibrate_files
    from casep.calibration.imucal import to_imucal
    from casep.units import G0

    if args.figures and args.segments != "auto":
        raise ValueError("--figures draws the segments found by --segments auto; give --segments auto")
    given = [f for f, v in (("--acc-range", args.acc_range), ("--gyr-range", args.gyr_range),
                            ("--acc-drift", args.acc_drift), ("--gyr-drift", args.gyr_drift)) if v is not None]
    if given:
        raise ValueError(f"{', '.join(given)}: used by model multiposition (--segments auto on a hand-turned session) "
                         "only: leave them out")
    outputs.check({"--json": args.json, "--imucal": args.imucal},
                  [args.session, args.segments if args.segments != "auto" else None, args.prior, args.bounds],
                  {"--figures": args.figures})
    cal = calibrate_files(args.session, rate=args.rate, segments=args.segments, label_column=args.label_column,
                          model=args.model or "ferraris", method=args.method, options=options.method_options(args),
                          acc_columns=args.acc_columns.split(","), gyr_columns=args.gyr_columns.split(","),
                          acc_unit=args.acc_unit, gyr_unit=args.gyr_unit,
                          gravity=G0 if args.gravity is None else args.gravity, angle_deg=args.angle,
                          weighting=args.weighting, sigma=args.sigma, prior_rel_std=args.prior_rel_std,
                          window_s=args.window, init_s=args.init, min_static_s=args.min_static)
    imucal = to_imucal(cal) if args.imucal else None  # before any file: all outputs or none
    print(cal.text())
    _figure(args, cal.segmentation)
    if args.json:
        outputs.write_json(cal.to_dict(), args.json)
        print(f"calibration written to {args.json}")
    if imucal is not None:
        outputs.write_json(imucal, args.imucal, record_warnings=False)  # imucal's format
        print(f"imucal calibration written to {args.imucal}")
    return outputs.status(cal)


def _run_auto(args: argparse.Namespace) -> int:
    """--segments auto: one call of casep.calibration.handturned.calibrate_multiposition_file, the report, the files."""
    from casep.calibration.handturned import calibrate_multiposition_file
    from casep.calibration.imutk import imu_tk_files, write_imu_tk

    if args.segments != "auto":
        raise ValueError(f"model multiposition takes --segments auto (got --segments {args.segments})")
    unused = [OPTIONS[k].flag for k in options.method_options(args)] + [f for f, given in (
        ("--method", args.method != "ols"), ("--weighting", args.weighting != "positions"),
        ("--sigma", args.sigma is not None), ("--prior-rel-std", args.prior_rel_std is not None),
        ("--angle", args.angle != -360.0), ("--label-column", args.label_column is not None)) if given]
    if unused:  # they would be ignored silently: the multiposition fit is its own (Levenberg-Marquardt, per pose)
        raise ValueError(f"{', '.join(unused)}: not used by model multiposition (--segments auto on a hand-turned "
                         "session is a Levenberg-Marquardt fit of its own, every pose weighted by its noise): leave "
                         "them out, or calibrate a labelled or Ferraris session (--model ferraris) to use them")
    files = {"--json": args.json, **(dict(zip(("--imu-tk (acc)", "--imu-tk (gyro)"), imu_tk_files(args.imu_tk)))
                                     if args.imu_tk else {})}
    fs = flight_options.full_scales(args)
    outputs.check(files, [args.session], {"--figures": args.figures})
    cal = calibrate_multiposition_file(args.session, rate=args.rate, acc_columns=args.acc_columns.split(","),
                                       gyr_columns=args.gyr_columns.split(","), acc_unit=args.acc_unit,
                                       gyr_unit=args.gyr_unit, gravity=args.gravity, latitude=args.latitude,
                                       height=args.height, window_s=args.window, init_s=args.init,
                                       min_static_s=args.min_static, acc_full_scale=fs["acc_range"],
                                       gyr_full_scale=fs["gyr_range"], **drift_options.drift_priors(args))
    print(cal.text())
    _figure(args, cal.segmentation)
    if args.json:
        outputs.write_json(cal.to_dict(), args.json)
        print(f"calibration written to {args.json}")
    if args.imu_tk:
        for path in write_imu_tk(cal, args.imu_tk):
            print(f"imu_tk calibration written to {path}")
    return outputs.status(cal)


def _figure(args: argparse.Namespace, segmentation) -> None:
    """`--figures DIR`: segmentation.png (matplotlib imported only when asked)."""
    if args.figures and segmentation is not None:
        from casep.reporting.segmentation import plot_segmentation

        path = outputs.folder(args.figures) / "segmentation.png"
        plot_segmentation(segmentation, path)
        print(f"figure: {path}")
