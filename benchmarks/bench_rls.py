"""Benchmark: recursive least squares on the paper flight (36 coefficients + RELS noise terms).

casep's RLS/RELS (Bierman U-D scalar updates, numba) against padasip ``FilterRLS``,
sysidentpy ``RecursiveLeastSquares`` and statsmodels ``RecursiveLS`` on the same scaled
regression (3 scalar rows per sample, P0 = p0 I, no forgetting), in one run. The slow
libraries run on the first `--sub` samples and their rate is reported per sample. Each
method's estimate on that subset is compared with the closed form
(I / p0 + Z^T Z)^-1 Z^T y (statsmodels starts from its own approximate diffuse prior).

Run:  pip install -e ".[bench]" && OPENBLAS_NUM_THREADS=1 python benchmarks/bench_rls.py
Target: >= 300k samples/s for 36 + 3 parameters.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import casep  # noqa: E402
from casep._kernels import rels_ud  # noqa: E402
from casep.simulation.simulate import simulate_flight  # noqa: E402


def casep_run(Z, y, p0, nc):
    N, _, n = Z.shape
    x = np.zeros(n + nc)
    U = np.zeros((n + nc, n + nc))
    D = np.full(n + nc, p0)
    rels_ud(Z, y, x, U, D, 1.0, 1.0, nc, True, 0, np.zeros((1, n + nc)), np.zeros((1, n + nc)), D.copy(),
            np.zeros((3, nc + 1)), 0)
    return x[:n]


def padasip_run(Z, y, p0):
    import padasip as pa

    rows, yy = Z.reshape(-1, Z.shape[-1]), y.reshape(-1)
    f = pa.filters.FilterRLS(rows.shape[1], mu=1.0, eps=1.0 / p0, w="zeros")
    f.run(yy, rows)
    return f.w


def sysidentpy_run(Z, y, p0):
    from sysidentpy.parameter_estimation.estimators import RecursiveLeastSquares

    rows, yy = Z.reshape(-1, Z.shape[-1]), y.reshape(-1, 1)
    return RecursiveLeastSquares(delta=1.0 / p0, lam=1.0).optimize(rows, yy).ravel()


def statsmodels_run(Z, y, p0):
    import statsmodels.api as sm

    rows, yy = Z.reshape(-1, Z.shape[-1]), y.reshape(-1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sm.RecursiveLS(yy, rows).fit().params


def timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return time.perf_counter() - t0, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sub", type=int, default=2000, help="samples for the slow libraries (default 2000)")
    ap.add_argument("--p0", type=float, default=1e6)
    args = ap.parse_args()
    sim = simulate_flight("paper", seed=1, rate=100.0)
    S = casep.build_sv(sim.model, sim.flight.t, sim.flight.f)
    c = np.linalg.norm(S.reshape(-1, 36), axis=0)
    Z = np.ascontiguousarray(S / c)  # scaled columns for every method
    y = np.ascontiguousarray(sim.flight.dv)
    N = Z.shape[0]
    casep_run(Z[:50], y[:50], args.p0, 3)  # JIT / cache warm-up
    m = min(args.sub, N)
    Zs, ys = Z[:m], y[:m]
    A = np.vstack([Zs.reshape(-1, 36), np.eye(36) / np.sqrt(args.p0)])
    ref = np.linalg.lstsq(A, np.concatenate([ys.reshape(-1), np.zeros(36)]), rcond=None)[0]
    rows = []
    t, _ = timed(casep_run, Z, y, args.p0, 0)
    rows.append(("casep RLS (36)", N, t, None))
    t, _ = timed(casep_run, Z, y, args.p0, 3)
    rows.append(("casep RELS (36 + 3)", N, t, None))
    _, xs = timed(casep_run, Zs, ys, args.p0, 0)
    rows[0] = rows[0][:3] + (np.abs(xs - ref).max() / np.abs(ref).max(),)
    for name, fn, r in (("padasip FilterRLS", padasip_run, ref),
                        ("sysidentpy RecursiveLeastSquares", sysidentpy_run, ref),
                        ("statsmodels RecursiveLS", statsmodels_run, ref)):
        try:
            t, x = timed(fn, Zs, ys, args.p0)
        except ImportError as exc:
            print(f"{name}: not installed ({exc.name}); pip install -e '.[bench]'")
            continue
        rows.append((name, m, t, np.abs(np.asarray(x) - r).max() / np.abs(r).max()))
    # casep's real problem: P0 = p0 I in natural units. casep scales internally; padasip's
    # covariance-form update runs on the unscaled natural-unit columns.
    Sn, natural = S[:m], casep.solve_rls(S[:m], ys, p0=args.p0).estimate
    try:
        t, x = timed(padasip_run, Sn, ys, args.p0)
        rows.append(("padasip FilterRLS, unscaled", m, t, np.abs(x - natural).max() / np.abs(natural).max()))
    except ImportError:
        pass
    base = rows[0][1] / rows[0][2]
    print(f"RLS on the paper flight ({N} samples at 100 Hz, 3 scalar rows each), p0 = {args.p0:g}, "
          f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")
    print(f"{'method':<34} {'samples':>8} {'time (s)':>9} {'samples/s':>11} "
          f"{'casep RLS / it':>15} {'max rel. dev.':>14}")
    for name, n, t, dev in rows:
        rate = n / t
        dev_s = "-" if dev is None else f"{dev:.1e}" if np.isfinite(dev) else "non-finite"
        print(f"{name:<34} {n:>8} {t:>9.3f} {rate:>11.3g} {base / rate:>15.1f} {dev_s:>14}")
    print(f"max rel. dev.: max |x - x_ref| / max |x_ref| on the first {m} samples, x_ref the closed form "
          "(I / p0 + Z^T Z)^-1 Z^T y; statsmodels ignores p0 (approximate diffuse start); 'unscaled': padasip "
          "on natural-unit columns vs casep.solve_rls (P0 = p0 I in natural units)")


if __name__ == "__main__":
    main()
