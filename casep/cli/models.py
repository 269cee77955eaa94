"""``casep models``: the available error models; a file that fails to load is a ``warning:`` line naming it.

Exit 0 when at least one model loads (the broken ones are reported), 2 when none does.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from typing import Any

from casep.exceptions import CasepWarning


def add_parser(sub: Any) -> None:
    p = sub.add_parser("models", help="list the available error models")
    p.add_argument("--verbose", "-v", action="store_true", help="list each model's coefficients")


def _tracking_model(name: str, error: str, verbose: bool) -> bool:
    """A model file that is a tracking model is listed as such (True), not as broken."""
    if "it is a tracking model" not in error:
        return False
    from casep.model.tracking import load_tracking_model

    m = load_tracking_model(name)
    print(f"{name:<28} {m.n_coefficients:>3} terms per station (tracking model, --tracking-model)  {m.description}")
    if verbose:
        for nm, unit in zip(m.names, m.units):
            print(f"    {nm:<16} {unit}")
    return True


def _details(model: Any) -> None:
    """`--verbose`: the model file's docstring, each coefficient, the signals and the file."""
    doc = getattr(model, "source_doc", "")
    if doc:  # the model file's docstring: its equations and conventions
        print("\n".join("    | " + line if line.strip() else "    |" for line in doc.splitlines()))
    scales = model.scales
    print(f"    {'coefficient':<12} {'unit':<10} {'magnitude':>10}  description")
    for nm, unit, own, what in zip(model.names, model.units, model.per_flight, model.descriptions):
        mag = f"{scales[nm]:.3g}" if nm in scales else "-"
        note = "; ".join(x for x in (what, "per flight" if own else "") if x)
        print(f"    {nm:<12} {unit:<10} {mag:>10}  {note}".rstrip())
    if model.signals:
        print(f"    signals: {', '.join(model.signals)}")
    if getattr(model, "source_file", None):
        print(f"    file: {model.source_file}")


def run(args: argparse.Namespace) -> int:
    from casep.model import ModelDefinitionError
    from casep.model.loader import available_models, load_model

    names = available_models()
    broken = 0
    for name in names:
        try:
            model = load_model(name)
        except ModelDefinitionError as exc:
            if _tracking_model(name, str(exc), args.verbose):
                continue
            broken += 1
            warnings.warn(f"model `{name}` not listed: {exc}", CasepWarning, stacklevel=1)
            continue
        print(f"{name:<28} {model.n_coefficients:>3} coefficients  {model.description}")
        if args.verbose:
            _details(model)
    if broken and broken == len(names):
        print(f"casep: error: none of the {broken} model files loads (see the warnings)", file=sys.stderr)
        return 2
    return 0
