"""``casep separate A B ...`` and ``casep diagnose A B ...``: several flights (casep.workflows.flights)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import inputs, outputs
from casep.cli.capture import recorded

__all__ = ["separate_flights", "diagnose_flights"]


def separate_flights(args: argparse.Namespace, model: Any, spec: Any) -> int:
    """Several flights in one estimate of the shared coefficients, as `spec` (a checked casep.FitSpec) asks."""
    from casep.reporting.noise_text import noise_lines
    from casep.workflows.flights import JOINT_METHODS, flights_summary, separate_flights
    from casep.workflows.joint_report import joint_result_dict, joint_summary_lines

    for flag, value in (("--figures", args.figures), ("--report", args.report), ("--mat", args.mat),
                        ("--csv", args.csv)):
        if value:
            raise ValueError(f"{flag} is not available with several flights yet; give one flight, or leave it out")
    if args.method not in JOINT_METHODS:
        raise ValueError(f"--method {args.method} cannot estimate several flights jointly yet. "
                         f"Use: --method {' | '.join(JOINT_METHODS)}")
    flights = inputs.read_all(args)
    man = getattr(args, "manifest_obj", None)
    with recorded():
        res, jp = separate_flights(flights, model, spec=spec,
                                   labels=[f.label for f in man.flights] if man is not None else None)
        summary = flights_summary(res, jp)
    print(res.text())
    for line in noise_lines(res.diagnostics, joint=True) + joint_summary_lines(summary):
        print(line)
    if "outliers_studentized" in res.diagnostics:  # --outliers: the flagged rows, by flight and sample
        from casep.regression.outliers import OutlierFlags

        o = res.diagnostics["outliers_studentized"]
        print("outliers: " + OutlierFlags(o["rows"], o["threshold"], o["rate"], o["rows_tested"]).text())
    if args.json:
        outputs.write_json({**joint_result_dict(res, jp, summary), "provenance": outputs.provenance(args, flights)},
                           args.json)
        print(f"result written to {args.json}")
    return outputs.status(res)


def diagnose_flights(args: argparse.Namespace, model: Any, prior: Any, scales: Any) -> int:
    """Per coefficient, the CRLB of each flight alone and of all jointly."""
    from casep.workflows.flights import diagnose_flights
    from casep.workflows.joint_report import flights_crlb_lines

    if args.tau:
        raise ValueError("--tau is not available with several flights yet; give one flight, or leave it out")
    flights = inputs.read_all(args)
    man = getattr(args, "manifest_obj", None)
    d = diagnose_flights(flights, model, sigma=args.sigma, prior=prior, scales=scales,
                         labels=[f.label for f in man.flights] if man is not None else None, noise=args.noise)
    for line in flights_crlb_lines(d, model.name, with_prior=prior is not None):
        print(line)
    if args.json:
        outputs.write_json({"model": model.name, **d, "provenance": outputs.provenance(args, flights)}, args.json)
        print(f"diagnostics written to {args.json}")
    if args.figures:
        from casep.reporting.plots import plot_flights_crlb

        fig = plot_flights_crlb(d, outputs.folder(args.figures) / "flights_crlb.png", scales=scales or model.scales)
        print(f"figure: {fig}")
    return 0
