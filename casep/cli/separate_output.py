"""What ``casep separate`` prints and draws of one flight's result (a flight file, or a raw IMU record)."""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["print_result", "figures_and_report"]


def print_result(res: Any, args: argparse.Namespace, align: Any, cons: Any, extra: tuple[str, ...] = ()) -> None:
    from casep.reporting.noise_text import noise_lines

    print(res.text())
    for line in [*noise_lines(res.diagnostics), *extra]:
        print(line)
    if args.outliers is not None:
        from casep.regression.outliers import OutlierFlags

        o = res.diagnostics["outliers_studentized"]
        print("outliers: " + OutlierFlags(o["rows"], o["threshold"], o["rate"], o["rows_tested"]).text())
    if align and align.get("applied_s"):
        dt = [res.estimate[i] for i, n in enumerate(res.names) if n == "dt_trk"]
        total = f"; the flight's offset = shift + dt_trk = {align['applied_s'] * 1e3 + dt[0]:.4g} ms" if dt else ""
        print(f"tracking time tags shifted back by {align['applied_s'] * 1e3:.4g} ms before the fit{total}")
    if cons is not None:
        print(cons.text())
    for label, path in (("result", args.json), ("MAT file", args.mat), ("CSV", args.csv)):
        if path:
            print(f"{label} written to {path}")


def figures_and_report(args: argparse.Namespace, res: Any, flight: Any, bounds: Any, prior: Any,
                        warned: list[str], prov: dict) -> None:
    """`--figures DIR` and `--report FILE` (matplotlib imported only when asked)."""
    if not (args.figures or args.report):
        return
    from casep.reporting.plots import separate_figures
    from casep.reporting.report import write_report

    files = None
    if args.figures:
        files = separate_figures(res, args.figures, flight.t[flight.observed], prior=prior, bounds=bounds)
        print(f"figures: {', '.join(str(f) for f in files)}")
    if args.report:
        write_report(res, args.report, flight=flight, figures=files, prior=prior, bounds=bounds, warnings=warned,
                     source=flight.source, provenance=prov)
        print(f"report written to {args.report}")
