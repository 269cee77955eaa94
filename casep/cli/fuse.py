"""``casep fuse R1.json R2.json ...``: combine results saved earlier into one estimate
(casep.workflows.fuse_inputs, casep.workflows.fusion.fuse_with_ground)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import options, outputs


def add_parser(sub: Any) -> None:
    p = sub.add_parser("fuse", help="combine results saved earlier (JSON with covariance) into one estimate")
    p.add_argument("results", nargs="*", metavar="RESULT.json", help="two or more results of one model")
    p.add_argument("--manifest", metavar="FLIGHTS.toml", default=None,
                   help="fuse the results the manifest lists (each flight's `result`), instead of RESULT.json files")
    options.add_json(p, "the fused result JSON")
    options.add_model(p, None, "default: the one the results name")


def _manifest_results(args: argparse.Namespace) -> None:
    """`--manifest`: ``args.results`` from the flights' `result` keys (the files or the manifest, not both)."""
    if not getattr(args, "manifest", None):
        if len(args.results) < 2:
            raise ValueError(f"fuse needs two or more RESULT.json files (or --manifest), got {len(args.results)}")
        return
    if args.results:
        raise ValueError(f"--manifest {args.manifest} lists the results: leave out the RESULT.json files")
    from casep.workflows.manifest import read_manifest

    man = read_manifest(args.manifest)
    missing = [k + 1 for k, f in enumerate(man.flights) if f.result is None]
    if missing:
        raise ValueError(f"--manifest {args.manifest}: flight(s) {', '.join(map(str, missing))} have no `result` "
                         "(the result JSON of that flight) to fuse")
    args.results = [str(f.result) for f in man.flights]


def run(args: argparse.Namespace) -> int:
    _manifest_results(args)  # --manifest: each flight's `result`
    outputs.check({"--json": args.json}, list(args.results) + [args.model])
    from casep.workflows.fuse_inputs import read_results_to_fuse
    from casep.workflows.fusion import fuse_with_ground

    results = read_results_to_fuse(args.results, args.model)  # none failed, no input file counted twice
    # ground results: their flight-model part, tested against each flight; a disagreeing pair fails the fusion
    res, ground_text = fuse_with_ground(results, labels=list(args.results), model=args.model)
    if ground_text:
        print(ground_text + "\n")
    print(res.text())
    ov = res.diagnostics["consistency"]["overall"]
    print(f"consistency of the results: chi2 {ov['chi2']:.4g}, {ov['dof']} dof, p {ov['p_value']:.3g}")
    if args.json:
        prov = outputs.provenance(args, [], {f"result {k + 1}": p for k, p in enumerate(args.results)})
        outputs.write_json({**res.to_dict(), "provenance": prov}, args.json)
        print(f"result written to {args.json}")
    return outputs.status(res)
