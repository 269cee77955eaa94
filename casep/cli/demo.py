"""``casep demo``: the paper's scenario end to end (casep.workflows.demo)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli.types import order, rate


def add_parser(sub: Any) -> None:
    p = sub.add_parser("demo", help="the paper's scenario end to end: Table 1, figures, report")
    p.add_argument("--out", metavar="DIR", default="casep-demo", help="output folder (default ./casep-demo)")
    p.add_argument("--seed", type=order, default=1, help="noise seed (default 1)")
    p.add_argument("--rate", type=rate, default=100.0, help="sample rate, Hz (default 100)")


def run(args: argparse.Namespace) -> int:
    from casep.workflows import demo

    # summary_lines: public name of the demo module (its former name _summary_lines until that rename is merged)
    summary_lines = getattr(demo, "summary_lines", None) or demo._summary_lines
    res = demo.run_demo(args.out, seed=args.seed, rate=args.rate)
    sim = res.sim
    print(f"casep demo: paper scenario, seed {sim.seed}, {sim.flight.n_samples} samples at {sim.scenario.rate:g} Hz, "
          f"white noise 0.1 m/s")
    print()
    print(res.table)
    print()
    d = res.diagnostics
    print(f"equilibrated condition number {d.condition_number_equilibrated:.3g}; "
          f"identifiable alone: {', '.join(n for n, v in d.identifiability.items() if v == 'identifiable')}")
    for line in summary_lines(sim, res.results, d.crlb_std):
        print(line)
    print()
    for line in demo.impact_lines(res.impact, res.true_miss) if res.true_miss is not None else []:
        print(line)
    print()
    print(f"report and figures in {args.out}/ (report.md)")
    return 0
