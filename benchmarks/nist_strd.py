"""Digits of casep's least squares on the NIST StRD linear regression sets.

The eleven linear sets of the NIST Statistical Reference Datasets (Norris, Pontius, NoInt1,
NoInt2, Filip, Longley, Wampler1-5; data and certified values in
``tests/data/nist_strd/linear.json``) go through :func:`casep.solve_ols` as a plain ``(m, n)``
regression (an intercept column of ones where the model has one, powers ``x^k`` for a
polynomial model). For each set the log relative error of every estimate against its
certified value is

    LRE = -log10(|b - b_cert| / |b_cert|)       (|b - b_cert| when b_cert = 0)

capped at 15 (the certified digits); the set's figure is the smallest over its coefficients
(and, separately, over the standard deviations). Double precision with an error-free
algorithm on these sets reaches roughly 15 - log10(condition number).

A second column gives the digits without the extended-precision refinement of
:func:`casep.regression.linalg.refine_least_squares` (``--no-refine`` prints only those): the QR
solve alone. The ceiling of any double-precision method is the exact solution of the data as
doubles (decimal inputs such as Filip's are rounded on reading): ``tests/estimators/test_nist_strd.py``
computes it in rational arithmetic.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/nist_strd.py
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "nist_strd" / "linear.json"
MAX_LRE = 15.0  # the certified values carry 15 significant digits


def load_sets(path: Path = DATA) -> dict[str, dict]:
    """The sets as ``{name: {"X": (m, n), "y": (m,), "beta": (n,), "sd": (n,), "raw": the file's entry}}``."""
    raw = json.loads(Path(path).read_text())["sets"]
    out = {}
    for name, s in raw.items():
        y = np.asarray(s["y"], dtype=float)
        if "X" in s:  # several predictors and an intercept
            X = np.column_stack([np.ones(y.size), np.asarray(s["X"], dtype=float)])
        elif s.get("model") == "no-intercept":
            X = np.asarray(s["x"], dtype=float)[:, None]
        else:  # a line, or a polynomial of the stated degree: 1, x, ..., x^d
            X = np.vander(np.asarray(s["x"], dtype=float), int(s.get("degree", 1)) + 1, increasing=True)
        out[name] = {"X": X, "y": y, "beta": np.asarray(s["beta"]), "sd": np.asarray(s["sd"]),
                     "difficulty": s["difficulty"], "raw": s}
    return out


def lre(value: np.ndarray, certified: np.ndarray) -> np.ndarray:
    """Log relative error, ``-log10(|v - c| / |c|)`` (absolute where ``c = 0``), capped at 15."""
    value = np.asarray(value, dtype=float)
    certified = np.asarray(certified, dtype=float)
    err = np.abs(value - certified) / np.where(certified != 0, np.abs(certified), 1.0)
    with np.errstate(divide="ignore"):
        digits = -np.log10(err)
    return np.where(np.isfinite(value), np.minimum(digits, MAX_LRE), 0.0)


def measure(sets: dict[str, dict] | None = None, *, refine: bool = True) -> dict[str, dict[str, float]]:
    """``{set: {"beta": min LRE of the estimates, "sd": min LRE of the std (nan if certified 0)}}``."""
    import warnings

    import casep
    from casep.estimators import ols

    sets = load_sets() if sets is None else sets
    out = {}
    for name, s in sets.items():
        limit = ols.REFINE_ABOVE
        ols.REFINE_ABOVE = limit if refine else np.inf  # the threshold least_squares reads
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # these sets are ill-conditioned on purpose
                res = casep.solve_ols(s["X"], s["y"])
        finally:
            ols.REFINE_ABOVE = limit
        sd_lre = lre(res.std, s["sd"]) if np.all(s["sd"] > 0) else np.array([np.nan])
        out[name] = {"beta": float(lre(res.estimate, s["beta"]).min()), "sd": float(np.min(sd_lre))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--no-refine", action="store_true", help="the QR solve alone")
    args = ap.parse_args()
    fig = measure(refine=not args.no_refine)
    plain = measure(refine=False)
    if args.json:
        print(json.dumps({"refined": fig, "qr_only": plain}, indent=1))
        return
    print(f"{'set':10s} {'LRE beta':>9s} {'QR only':>8s} {'LRE std':>8s}")
    for name, f in fig.items():
        print(f"{name:10s} {f['beta']:9.2f} {plain[name]['beta']:8.2f} {f['sd']:8.2f}")
    for label, figs in (("", fig), (" (QR only)", plain)):
        worst = min(figs, key=lambda k: figs[k]["beta"])
        print(f"minimum LRE of the estimates{label}: {figs[worst]['beta']:.2f} ({worst})")


if __name__ == "__main__":
    main()
