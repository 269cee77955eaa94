"""Write the result files of an earlier casep that tests/estimators/test_result_settings.py reads back.

Run with that casep first on the path (its package extracted by ``git archive``)::

    git archive 7ab7873 casep models | tar -x -C /tmp/old && PYTHONPATH=/tmp/old python make_old_results.py
    git archive e3ad04e~1 casep models | tar -x -C /tmp/o1 && PYTHONPATH=/tmp/o1 python make_old_results.py --older

7ab7873 kept found values in ``settings`` (GLS tau, ridge lambda, OLS rcond) and facts twice
(``diagnostics`` and ``extras``); e3ad04e~1 also Huber's and PCR's found values in ``settings``. The
covariance and the flat arrays are left out (optional in a result file) to keep the files small.
"""

import argparse
import json
import warnings
from pathlib import Path

import casep
from casep.simulation.simulate import simulate_flight
from casep.workflows.flights import separate_flights

CASES = {
    "ols": {}, "gls": {}, "ridge": {}, "rels": {"noise_order": 1, "p0": 1e4},
    "bounded": {"bounds": {"Kg0x": [-0.01, 0.01], "Ka0y": 0.0}}, "huber": {}, "pcr": {},
}
OLDER = ("huber", "pcr")


def _small(d: dict) -> dict:
    for key in ("names", "units", "estimates", "std", "si_factors"):
        d.pop(key, None)
    d["covariance"] = None
    d["casep_version"] = "old"  # the version string of a checkout is not reproducible
    return d


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--older", action="store_true", help="write the Huber and PCR files only (e3ad04e~1)")
    args = ap.parse_args()
    here = Path(__file__).parent
    a = simulate_flight("paper-ar1", seed=5, rate=5.0).flight
    b = simulate_flight("paper-ar1", seed=6, rate=5.0).flight
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for method, opts in CASES.items():
            if args.older != (method in OLDER):
                continue
            res = casep.separate(a, "platform36", method, **opts)
            (here / f"{method}.json").write_text(json.dumps(_small(res.to_dict()), indent=1) + "\n")
        if not args.older:
            res, _ = separate_flights([a, b], "platform36", "gls")
            (here / "gls_flights.json").write_text(json.dumps(_small(res.to_dict()), indent=1) + "\n")


if __name__ == "__main__":
    main()
