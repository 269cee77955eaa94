"""``casep methods``: the estimators, their options and capabilities (casep.estimators.registry.describe)."""

from __future__ import annotations

import argparse
import json
from typing import Any


def add_parser(sub: Any) -> None:
    p = sub.add_parser("methods", help="list the estimators, their options and capabilities")
    p.add_argument("--json", action="store_true", help="print the registry as JSON")


def run(args: argparse.Namespace) -> int:
    from casep.estimators.registry import describe

    table = describe()
    if args.json:
        print(json.dumps(table, indent=2))
        return 0
    for m in table:
        caps = [c for c, on in (("recursive", m["recursive"]), ("needs time", m["needs_time"]),
                                ("batched in montecarlo", m["batched_in_montecarlo"])) if on]
        print(f"{m['name']:<8} {m['summary']}; std {m['std_kind']}" + (f"; {', '.join(caps)}" if caps else ""))
        for o in m["options"]:
            d = o["default"]
            req = (f" (needed by --method {m['name']})" if o["name"] in m["required"]
                   else f" (default {d:g})" if isinstance(d, float) else f" (default {d})")
            print(f"    {o['flag']:<14} {o['rule']}{req}: {o['help']}")
    return 0
