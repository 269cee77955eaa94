"""How often the omitted-terms test (:mod:`casep.workflows.omitted_terms`) fails a correct model, and what the
consider parameters do to the Mahalanobis distance of the error.

``casep simulate --scenario strapdown-boost`` flights (Gauss-Markov plus white tracking noise) fitted with
``strapdown15_axial``: ``limited`` draws only the model's 15 terms (the scenario's values: a correct model), ``full``
every strapdown33 term (the scenario as shipped). Printed per flight: the Wald chi-square of what the rows determine
of strapdown33's 18 further terms, its dof and p, the status, how far those terms at their declared magnitudes move
the best-determined combination (in its std), and the Mahalanobis distance of the error (15 dof) under the fit's
own covariance and under the covariance with the consider parameters. Then the share of p below 1e-2 and 1e-6.

Run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/omitted_terms_mc.py --rate 5 --seeds 20 [--kinds limited full]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np

LIMITED = {"ba_x": 0.8, "sa_x": 250.0, "ba_y": -0.5, "ma_yx": 20.0, "ba_z": 0.6, "ma_zx": -40.0, "bg_x": 1.0,
           "sg_x": 80.0, "gg_xx": 0.5, "bg_y": -0.8, "mg_yx": 40.0, "gg_yx": 0.4, "bg_z": 0.5, "mg_zx": 20.0,
           "gg_zx": -0.2}


def main() -> None:
    from casep.estimators.solve import fit
    from casep.estimators.spec import FitSpec
    from casep.simulation.simulate import simulate_flight, write_simulation
    from casep.workflows.omitted_terms import judge_omitted
    from casep.workflows.separate import _problem

    ap = argparse.ArgumentParser()
    ap.add_argument("--rate", type=float, default=5.0)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first", type=int, default=100)
    ap.add_argument("--kinds", nargs="+", default=["limited", "full"])
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp())
    for kind in args.kinds:
        ps = []
        for seed in range(args.first, args.first + args.seeds):
            path = tmp / f"{kind}{seed}.csv"
            write_simulation(simulate_flight("strapdown-boost", seed=seed, rate=args.rate,
                                             truth=LIMITED if kind == "limited" else None), path)
            truth = json.loads(path.with_name(f"{kind}{seed}.truth.json").read_text())["coefficients"]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                flight, problem, model = _problem(path, "strapdown15_axial", False)
                res = fit(problem, FitSpec.build())
                out = judge_omitted(res, flight, problem, model)
            rec = out.diagnostics.get("omitted_terms") or {}
            e = np.asarray(res.estimate) - np.array([truth.get(n, 0.0) for n in res.names])
            m0 = float(e @ np.linalg.solve(np.asarray(res.covariance), e))
            m1 = float(e @ np.linalg.solve(np.asarray(out.covariance), e))
            ps.append(rec.get("p_value", np.nan))
            print(f"{kind} seed {seed}: chi2 {rec.get('chi2', np.nan):.3g} on {rec.get('dof')} dof, p "
                  f"{rec.get('p_value', np.nan):.3g}, status {out.status}, alias "
                  f"{(rec.get('alias') or {}).get('combination_std', np.nan):.3g} std; Mahalanobis (15 dof) fit "
                  f"{m0:.4g}, with the consider parameters {m1:.4g}", flush=True)
        p = np.asarray(ps, float)
        print(f"{kind}: {p.size} flights, p < 1e-2: {np.mean(p < 1e-2):.3f}, p < 1e-6: {np.mean(p < 1e-6):.3f}; "
              f"mean chi2/dof-implied p {np.nanmean(p):.3f} (uniform under the null: 0.5)")


if __name__ == "__main__":
    main()
