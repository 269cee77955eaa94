"""Benchmark: building S_V for a long flight (platform36), in one run.

Compares, on the same flight:
  casep      SVBuilder: CasADi function mapped over fixed chunks, evaluated through
             Function.buffer(), trapezoid recursions in a numba loop;
  numpy      a hand-written vectorised numpy build of the same 36 columns (full-size arrays);
  per-sample a Python loop calling the CasADi Jacobian functions sample by sample
             (timed on a slice, reported per sample).
Peak memory is measured with tracemalloc (numpy arrays are traced) relative to the size of
the S_V array itself. Target: N = 1e6 in <= 2 s, peak <= 1.5x the S_V array.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sv.py [--n 1000000]
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import casep  # noqa: E402
from casep.simulation.synthetic import excitation_force  # noqa: E402
from casep.units import DEG_PER_HOUR, G0  # noqa: E402


def numpy_build(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """platform36 S_V written out by hand with full-length numpy arrays."""
    N = t.size
    W = f / G0
    wx, wy, wz = W.T
    one = np.ones(N)
    g = np.zeros((N, 3, 15))  # d phidot / dD, gyro columns
    g[:, 0, 0:5] = np.column_stack([one, wx, wy, wz, wx**2])
    g[:, 1, 5:10] = np.column_stack([one, wy, wz, wx, wy**2])
    g[:, 2, 10:15] = np.column_stack([one, wz, wx, wy, wz**2])
    g *= DEG_PER_HOUR
    dt = np.diff(t)[:, None, None]
    phi = np.zeros_like(g)
    np.cumsum(0.5 * (g[1:] + g[:-1]) * dt, axis=0, out=phi[1:])
    del g
    integrand = np.zeros((N, 3, 36))
    fx, fy, fz = (f[:, i, None] for i in range(3))
    integrand[:, 0, :15] = fy * phi[:, 2] - fz * phi[:, 1]
    integrand[:, 1, :15] = fz * phi[:, 0] - fx * phi[:, 2]
    integrand[:, 2, :15] = fx * phi[:, 1] - fy * phi[:, 0]
    del phi
    mg, ug = 1e-3 * G0, 1e-6 * G0
    integrand[:, 0, 15:22] = np.column_stack([mg * one, mg * wx, ug * wy, ug * wz,
                                            ug * wx**2, ug * wx * wy, ug * wx * wz])
    integrand[:, 1, 22:29] = np.column_stack([mg * one, mg * wy, ug * wz, ug * wx,
                                            ug * wy**2, ug * wy * wz, ug * wy * wx])
    integrand[:, 2, 29:36] = np.column_stack([mg * one, mg * wz, ug * wx, ug * wy,
                                            ug * wz**2, ug * wz * wx, ug * wz * wy])
    S = np.zeros((N, 3, 36))
    np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * dt, axis=0, out=S[1:])
    return S


def per_sample_build(model: casep.ErrorModel, t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Python loop over samples calling the CasADi Jacobians with plain calls and .full()."""
    Gf, Af = model.functions["dphidot_dD"], model.functions["dDelta_dD"]
    n = model.n_coefficients
    S = np.zeros((t.size, 3, n))
    phi = np.zeros((3, n))
    Gp = Gf(f[0]).full()
    Ip = np.zeros((3, n))
    for k in range(1, t.size):
        h = 0.5 * (t[k] - t[k - 1])
        G = Gf(f[k]).full()
        phi += (Gp + G) * h
        I = np.cross(f[k][:, None], phi, axis=0) + Af(f[k]).full()
        S[k] = S[k - 1] + (Ip + I) * h
        Gp, Ip = G, I
    return S


def timed(fn, *args, repeat: int = 3) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best, out


def peak_ratio(fn, *args) -> float:
    tracemalloc.start()
    tracemalloc.reset_peak()
    out = fn(*args)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / out.nbytes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="samples (default 1e6)")
    ap.add_argument("--loop-n", type=int, default=20_000, help="samples for the per-sample loop")
    args = ap.parse_args()
    model = casep.load_model("platform36")
    t = np.arange(args.n) * 0.01
    f = excitation_force(t, duration=t[-1])
    builder = casep.SVBuilder(model)
    builder.build(t[:5000], f[:5000])  # JIT / cache warm-up
    t_casep, S = timed(builder.build, t, f)
    t_numpy, S_np = timed(numpy_build, t, f, repeat=1)
    err = np.abs(S - S_np).max() / np.abs(S).max()
    del S_np
    m = min(args.loop_n, args.n)
    t_loop, _ = timed(per_sample_build, model, t[:m], f[:m], repeat=1)
    t_loop_full = t_loop * args.n / m
    mem_casep = peak_ratio(builder.build, t, f)
    del S
    mem_numpy = peak_ratio(numpy_build, t, f)
    print(f"S_V build, platform36, N = {args.n:,} samples, S_V array {args.n * 3 * 36 * 8 / 1e6:.0f} MB, "
          f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")
    print(f"{'method':<34} {'time (s)':>10} {'samples/s':>12} {'time / casep':>13} {'peak mem / S_V':>15}")
    rows = [("casep (CasADi chunks + numba)", t_casep, mem_casep),
            ("hand-written numpy", t_numpy, mem_numpy),
            (f"per-sample loop (x{args.n / m:.0f} of {m:,})", t_loop_full, float("nan"))]
    for name, sec, mem in rows:
        mem_s = f"{mem:.2f}" if np.isfinite(mem) else "-"
        print(f"{name:<34} {sec:>10.3f} {args.n / sec:>12.3g} {sec / t_casep:>13.1f} {mem_s:>15}")
    print(f"max |casep - numpy| / max |S_V| = {err:.1e}")
    print(f"target: <= 2 s and <= 1.5x: {'met' if t_casep <= 2 and mem_casep <= 1.5 else 'NOT met'}")


if __name__ == "__main__":
    main()
