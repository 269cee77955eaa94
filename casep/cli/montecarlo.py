"""``casep montecarlo``: seeded Monte Carlo of the estimators against the CRLB (casep.workflows.montecarlo)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from casep.cli import flight_options, inputs, options, outputs
from casep.cli.types import order, positive_float, positive_int, rate
from casep.estimators.registry import METHODS, OPTIONS


def add_parser(sub: Any) -> None:
    from casep.simulation.scenarios import SCENARIOS

    p = sub.add_parser("montecarlo", help="seeded Monte Carlo of the estimators against the CRLB")
    p.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="scenario (default paper)")
    p.add_argument("--runs", type=positive_int, default=100, help="noise draws, >= 1 (default 100)")
    p.add_argument("--methods", default="ols,rls,rels",
                   help=f"comma-separated: {', '.join(METHODS)}; <method>:<number> (its first option, ridge:<lambda>); "
                        "<method>:<option>=<value>[:<option>=<value>] (any option, e.g. rls:p0=1e6:forgetting=0.999); "
                        "wavelet+<method> (de-noised first) (default ols,rls,rels)")
    p.add_argument("--seed", type=order, default=0, help="root seed (default 0)")
    p.add_argument("--rate", type=rate, default=None, help="sample rate, Hz (default: scenario's)")
    p.add_argument("--workers", type=positive_int, default=None,
                   help="Dask LocalCluster worker processes, one thread each (default: the cores this process may use; "
                        "1: runs in this process)")
    p.add_argument("--json", metavar="OUT", default=None, help="write the Monte Carlo JSON here")
    p.add_argument("--csv", metavar="OUT", default=None, help="write a CSV table here")
    p.add_argument("--figure", metavar="PNG", default=None, help="write RMS/CRLB per coefficient here")
    takers = [m for o in ("prior", "bounds") for m, meth in METHODS.items() if o in meth.options]
    g = p.add_argument_group(f"{' / '.join(takers)} options (other methods: the registry's defaults)")
    options.add_option(g, OPTIONS["prior"], "default: the demo ground-calibration prior")
    options.add_option(g, OPTIONS["bounds"], "default: the demo spec-sheet box")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=True,
                   help="progress on stderr: a bar on a terminal, else a line with the ETA every 5 s (default on)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run on this running Dask cluster (tcp://host:8786) instead of a LocalCluster of --workers")
    p.add_argument("--dispersions", metavar="FILE", default=None,
                   help='JSON {"thrust_scale": {"dist": "normal", "mean": 1, "std": 0.01}, "launch_azimuth_deg": '
                        '{"dist": "uniform", "low": -2, "high": 2}, ...}: each run flies its own dispersed trajectory '
                        "(names: see casep.simulation.dispersions)")
    p.add_argument("--truth-from-prior", metavar="FILE", dest="truth_from_prior", default=None,
                   help='JSON {"Kg0x": {"mean": m, "std": s}, ...}, or a result file (its estimates and std): each '
                        "run draws its true coefficients from it (also map's prior unless --prior is given)")
    options.add_noise(p, outputs=False)  # casep separate's defaults: a campaign shows what separate gives
    p.add_argument("--tau", dest="noise_tau", type=positive_float, default=None, metavar="S",
                   help="Gauss-Markov correlation time the methods assume, s (with --noise gm; default REML)")
    p.add_argument("--out", metavar="DIR", default=None,
                   help="write runs.parquet/ (per-run results, one part per task) and summary.json here; a rerun "
                        "with the same settings resumes")
    flight_options.add_own_trajectory(p)


def _read_files(args: argparse.Namespace, names: Any, stages: int) -> dict[str, Any]:
    """--prior, --bounds, --dispersions and --truth-from-prior, read and checked."""
    from casep.io.files import read_json_table
    from casep.simulation.dispersions import parse_dispersions

    kw: dict[str, Any] = {"prior": inputs.coefficient_file(args, "prior", names),
                          "bounds": inputs.coefficient_file(args, "bounds", names),
                          "dispersions": None, "truth_prior": None}
    if args.dispersions:
        kw["dispersions"] = parse_dispersions(read_json_table(args.dispersions, "--dispersions"), stages,
                                              source=f"--dispersions {args.dispersions}")
    if args.truth_from_prior:  # a prior file of any form --prior reads (a result file: its posterior's marginals)
        from casep.workflows.coefficients import read_truth_prior

        kw["truth_prior"] = read_truth_prior(args.truth_from_prior, names, model=getattr(args, "model", None))
    return kw


def run(args: argparse.Namespace) -> int:
    from casep.io._atomic import output_group
    from casep.model.loader import load_model
    from casep.montecarlo import Terminated, run_montecarlo, sigterm_raises, write_figure
    from casep.simulation.scenarios import get_scenario

    outputs.check({"--json": args.json, "--csv": args.csv, "--figure": args.figure},
                  inputs.input_files(args, "prior", "bounds", "dispersions", "truth_from_prior", "flight", "truth"))
    sc = get_scenario(args.scenario)
    own_flight, own_truth, own_model = inputs.own_trajectory(args)  # --flight FILE --truth TRUTH.json
    kw = _read_files(args, load_model(own_model or sc.model).names, len(sc.vehicle.stages))
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise ValueError(f"--out {args.out}: exists and is not a folder")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    try:
        with sigterm_raises():
            res = run_montecarlo(args.scenario, runs=args.runs, methods=methods, seed=args.seed, rate=args.rate,
                                 workers=args.workers, progress=args.progress, scheduler=args.scheduler,
                                 out=args.out, flight=own_flight, truth=own_truth, noise=args.noise,
                                 tau=args.noise_tau, robust=args.robust, **kw)
    except (KeyboardInterrupt, Terminated) as exc:  # workers already ended; no report (--out: finished parts kept)
        print("casep: interrupted", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    print(res.text())
    if args.out:
        print(f"resumed {res.resumed} of {res.tasks} tasks from {args.out}" if res.resumed else
              f"{res.tasks} tasks, none resumed")
    with output_group():  # the report files together or none (the --out store keeps its parts regardless)
        if args.json:
            outputs.write_json(res.to_dict(), args.json)  # with the run's warnings
        if args.csv:
            res.write_csv(args.csv)
        if args.figure:
            write_figure(res, args.figure)
    for label, path in (("JSON", args.json), ("CSV", args.csv), ("figure", args.figure)):
        if path:
            print(f"{label} written to {path}")
    if args.out:
        print(f"per-run results in {Path(args.out) / 'runs.parquet'}, summary in {Path(args.out) / 'summary.json'}")
    return 0
