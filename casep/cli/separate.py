"""``casep separate FLIGHT [...]``: estimate the error coefficients of a flight (several: jointly; radar)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import alignment, flight_options, inputs, options, outputs
from casep.cli.capture import recorded, report_lines
from casep.cli.radar import radar_only
from casep.cli.separate_imu import add_imu_stds, imu_only, separate_imu
from casep.cli.separate_output import figures_and_report, print_result
from casep.cli.types import order, positive_int, ranged
from casep.estimators.registry import METHODS


def add_parser(sub: Any) -> None:
    from casep.estimators.spec import DENOISE_CHOICES
    from casep.noise.denoise import EXTENSIONS, MODES, RULES, SCALINGS

    p = sub.add_parser("separate", help="estimate the error coefficients of a flight file")
    p.add_argument("flight", nargs="*", help="flight CSV or Parquet file (t, f_x.., dv_x.. or v_tel_x.., v_trk_x..); "
                   "several files: one estimate of the shared coefficients, per-flight ones per flight "
                   "(every method of `casep methods`)")
    options.add_model(p)
    p.add_argument("--imu", metavar="IMU.csv", default=None,
                   help="a raw IMU record instead of FLIGHT (t, w_*, fb_* or t, dth_*, dvb_*, as casep navigate "
                        "reads it): navigated, paired with --tracking and separated; needs --launch-site, "
                        "--launch-time (the tracking file's time scale) and --align")
    alignment.add_alignment(p, what="with --imu: ")
    add_imu_stds(p)
    flight_options.add_full_scales(p, "with --imu, or a strapdown telemetry file (w_*, fb_*): the rows from the "
                                   "first clipped sample on are left out")
    p.add_argument("--iterate", action=argparse.BooleanOptionalAction, default=None,
                   help="with --imu: correct the IMU by the estimate, re-navigate, rebuild S_V and solve again "
                        "until the correction of every determined combination is below a tenth of its std "
                        "(the stop rule of "
                        "casep.workflows.imu_separate; default with --imu); --no-iterate: one linear pass. With a "
                        "strapdown telemetry file (q_*, fb_*, w_*) the same on its corrected record "
                        "(casep.workflows.telemetry_iterate; default: when the linear estimate's second-order "
                        "remainder moves it by more than a tenth of its std); --no-iterate: the linear pass, "
                        "warned (failed beyond 3 std) when that remainder is larger")
    p.add_argument("--max-iterations", type=positive_int, default=None, metavar="N",
                   help="with --imu: passes before an iteration that has not converged is a failed result "
                        "(default: casep.workflows.imu_separate.MAX_ITERATIONS, 20)")
    p.add_argument("--method", default="ols", choices=METHODS, help="estimator (default ols)")
    p.add_argument("--sigma", type=ranged("sigma"), default=None,
                   help="noise std, m/s (default: estimated from the residuals)")
    p.add_argument("--denoise", choices=DENOISE_CHOICES, default="none", help="de-noise dv first (default none)")
    p.add_argument("--wavelet", default=None, help="wavelet (default sym8)")
    p.add_argument("--level", type=order, default=None, help="decomposition level (default: largest "
                   "without boundary domination)")
    p.add_argument("--threshold-rule", choices=RULES, default=None, help="threshold rule (default sqtwolog)")
    p.add_argument("--threshold-mode", choices=MODES, default=None, help="threshold mode (default soft)")
    p.add_argument("--extension", choices=tuple(EXTENSIONS), default=None,
                   help="boundary extension (default symmetric)")
    p.add_argument("--noise-scaling", choices=SCALINGS, default=None, help="noise scaling (default sln)")
    options.add_json(p, "the result JSON")
    p.add_argument("--mat", metavar="OUT", default=None,
                   help="write the result as a MATLAB/Octave .mat file (names, estimates, std, covariance, ...)")
    p.add_argument("--csv", metavar="OUT", default=None,
                   help="write one row per coefficient here (name, unit, estimate, std, reason)")
    p.add_argument("--figures", metavar="DIR", default=None,
                   help="write residuals, estimates (and RLS/RELS history) PNG figures into DIR (created)")
    p.add_argument("--outliers", type=float, nargs="?", const=0.01, default=None, metavar="ALPHA",
                   help="flag rows by their studentized least-squares residual, with chance ALPHA (default 0.01) of "
                        "any false flag in a clean flight (white noise); rows named, in the JSON diagnostics")
    p.add_argument("--report", metavar="FILE", default=None,
                   help="write a self-contained HTML report (table, settings, diagnostics, figures) here")
    flight_options.add_tracking(p, "tracking file (t, v_trk_*) at its own rate; FLIGHT is then the telemetry file "
                                   "(t, f_* or W_*, v_tel_*); several flights: once per flight, in their order")
    flight_options.add_grid(p)  # --grid, --time-offset, --time-shift, --manifest
    flight_options.add_frames(p)  # --tracking-frame, --launch-site, --launch-time
    options.add_noise(p)  # --noise, --robust, --std, --exclude-outliers
    flight_options.add_radar(p)  # --radar STATION.json MEAS.csv, --tracking-model
    options.method_option_groups(p)


def run(args: argparse.Namespace) -> int:
    wopts = {k: v for k, v in (("wavelet", args.wavelet), ("level", args.level), ("rule", args.threshold_rule),
                                ("mode", args.threshold_mode), ("extension", args.extension),
                                ("scaling", args.noise_scaling)) if v is not None}
    flight_options.flight_model(args, bool(args.imu))  # the default model: one for every path, radar included
    if args.radar:
        from casep.cli.radar import separate_radar

        return separate_radar(args, wopts)
    radar_only(args, ("tracking_model",))
    ranges = flight_options.full_scales(args)
    imu_only(args)
    if not args.imu:
        inputs.use_manifest(args)  # --manifest FLIGHTS.toml, or the flight files
    outputs.check({"--json": args.json, "--mat": args.mat, "--csv": args.csv, "--report": args.report},
                  inputs.input_files(args, "flight", "tracking", "bounds", "prior") + ([args.imu] if args.imu else []),
                  {"--figures": args.figures})
    from casep.model.loader import load_model

    model = load_model(args.model)
    # Options of the method only (casep.estimators.registry): one given for another method is an error.
    given = options.method_options(args)  # files: their names
    if wopts and args.denoise != "wavelet":
        raise ValueError(f"wavelet options ({', '.join(wopts)}) need --denoise wavelet")
    spec = options.fit_spec(args, given, sigma=args.sigma, denoise=args.denoise, wavelet_options=wopts or None,
                            outliers=args.outliers)  # the one check of the request
    bounds = inputs.coefficient_file(args, "bounds", model.names)
    prior = inputs.coefficient_file(args, "prior", model.names, fitted=True)
    tables = {k: v for k, v in (("bounds", bounds), ("prior", prior)) if v is not None}
    if tables:  # the files read and checked against the model: the tables themselves
        import dataclasses

        spec = dataclasses.replace(spec, options={**spec.options, **tables})
    if args.imu:
        return separate_imu(args, spec, ranges)
    if len(args.flight) > 1:
        from casep.cli.separate_flights import separate_flights

        for flag, value in (("--acc-range", args.acc_range), ("--gyr-range", args.gyr_range),
                            ("--iterate" if args.iterate else "--no-iterate", args.iterate)):
            if value is not None:
                raise ValueError(f"{flag} is used with --imu IMU.csv or one strapdown telemetry file, not with "
                                 f"{len(args.flight)} flights: separate each flight")

        return separate_flights(args, model, spec)
    args.flight = args.flight[0]
    flight = inputs.read_one(args)
    if ranges["acc_range"] is not None or ranges["gyr_range"] is not None:
        from casep.checks.saturation import with_full_scales

        flight = with_full_scales(flight, **ranges)  # the telemetry's w_*, fb_* screened against them
    from casep.workflows.separate import separate

    with recorded() as caught:  # passed on to main(), which prints them; the report quotes them
        res = separate(flight, model, spec=spec, iterate=args.iterate)
    cons = None
    if prior is not None:  # the prior (a ground calibration) against the flight estimated alone
        from casep.workflows.prior_consistency import with_prior_consistency

        res, cons = with_prior_consistency(res, flight, model, prior, spec=spec, iterate=args.iterate)
    align = flight.meta.get("time_alignment") if isinstance(flight.meta, dict) else None
    prov = outputs.provenance(args, [flight])
    if args.json:
        outputs.write_json({**res.to_dict(), **({"time_alignment": align} if align else {}), "provenance": prov},
                           args.json)
    outputs.write_exports(res, args, t=flight.t[flight.observed], provenance=prov)
    flips = (flight.meta.get("strapdown") or {}).get("sign_flips", 0) if isinstance(flight.meta, dict) else 0
    print_result(res, args, align, cons, (f"attitude: {flips} quaternion sign flip(s) (q and -q are the same "
                                          "attitude) removed before the checks and the fit",) if flips else ())
    figures_and_report(args, res, flight, bounds, prior, report_lines(caught), prov)
    return outputs.status(res)
