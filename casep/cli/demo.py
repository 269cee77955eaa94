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
    from casep.reporting.demo_figures import FigureJobs, spare_core

    # the figure worker first (a light import): it imports matplotlib while this process imports casep's methods
    jobs = FigureJobs(spare_core())
    from casep.workflows.demo import run_demo

    print(run_demo(args.out, seed=args.seed, rate=args.rate, jobs=jobs).text())
    return 0
