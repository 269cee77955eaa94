"""Benchmark: the default `casep separate` path on a long flight, against one QR of its stacked rows.

The flight: ``casep simulate --scenario paper-range-gm --rate 2000`` (195 s, 359k tracked samples,
Gauss-Markov noise tau 1 s, two dropouts). Timed in this process, one BLAS thread
(``OPENBLAS_NUM_THREADS=1``): the noise fit (REML, :func:`casep.noise.fit.fit_noise`
with ``auto``), the whole default ``casep.separate`` (noise ``auto``, robust ``auto``), and one
QR of the stacked rows ``[S_V dv]`` (3N x (n + 1), ``numpy.linalg.qr(mode="r")``) with S_V built
beforehand. Printed: seconds, samples per second, and the ratio of the default path to the QR.
CPU time is printed beside the wall time (a loaded machine inflates the wall time).

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/bench_reml_scale.py [--rate 2000] [--flight FILE]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path


def _timed(f):
    w0, c0 = time.perf_counter(), time.process_time()
    out = f()
    return out, time.perf_counter() - w0, time.process_time() - c0


def main() -> None:
    import numpy as np

    import casep
    from casep.cli.app import main as cli
    from casep.noise.fit import fit_noise
    from casep.regression.problem import Problem

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=2000.0)
    ap.add_argument("--flight", default=None, help="a flight file made before (default: simulated here)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        path = args.flight or str(Path(tmp) / "flight.csv")
        if args.flight is None:
            cli(["simulate", "--scenario", "paper-range-gm", "--rate", f"{args.rate:g}", "-o", path])
        flight = casep.read_flight(path)
        model = casep.load_model("platform36")
        pb, w_pb, c_pb = _timed(lambda: Problem.from_flight(flight, model))
        N = pb.n_samples
        nm, w_fit, c_fit = _timed(lambda: fit_noise(pb, "auto"))
        _, w_sep, c_sep = _timed(lambda: casep.separate(flight, model))
        S = pb.sv()
        A = np.concatenate([S.reshape(-1, S.shape[-1]), pb.y.reshape(-1, 1)], axis=1)
        _, w_qr, c_qr = _timed(lambda: np.linalg.qr(A, mode="r"))
    print(f"paper-range-gm at {args.rate:g} Hz: {N} samples, {S.shape[-1]} coefficients")
    print(f"noise model: {nm.line()}")
    for what, w, c in (("problem (S_V, reduction)", w_pb, c_pb), ("noise fit (REML, auto)", w_fit, c_fit),
                       ("casep.separate, default path", w_sep, c_sep), ("one QR of [S_V dv]", w_qr, c_qr)):
        print(f"{what:<32} wall {w:7.2f} s  cpu {c:7.2f} s  {N / w:12.0f} samples/s")
    print(f"default path / one QR: wall {w_sep / w_qr:.1f}x, cpu {c_sep / c_qr:.1f}x")


if __name__ == "__main__":
    main()
