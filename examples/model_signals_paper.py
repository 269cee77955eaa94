"""Model signals on the paper scenario: what a time offset and a lever arm cost and alias with.

Prints, for platform36 and platform36_timeoffset / platform36_leverarm on the `paper` flight
(100 Hz, white 0.1 m/s): the equilibrated condition number, the CRLB std of the new terms and
of the best-determined accelerometer terms, the variance inflation factor of the new terms and
the coefficients their estimates correlate with most; then the noise-free recovery of an
exactly injected 20 ms offset (v_trk(t) = v(t - 20 ms), not the model's first-order term).

Run:  python examples/model_signals_paper.py [--rate 100]
"""

#%% Imports and options
import argparse
import dataclasses

import numpy as np

import casep
from casep.simulation.noise import NoiseModel
from casep.simulation.scenarios import get_scenario
from casep.simulation.simulate import simulate_flight

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--rate", type=float, default=100.0, help="sample rate, Hz (default 100)")
ap.add_argument("--quick", action="store_true", help="20 Hz (for CI)")
args = ap.parse_args()
rate = 20.0 if args.quick else args.rate
sigma = 0.1  # m/s


def crlb(model, flight):
    """Equilibrated condition number, CRLB std (natural units) and correlation of the estimates."""
    S = casep.build_sv(model, flight.t, flight.f, signals=flight.model_signals(model.signals, model.name))
    A = S.reshape(-1, model.n_coefficients)
    c = np.linalg.norm(A, axis=0)
    s = np.linalg.svd(A / c, compute_uv=False)
    P = np.linalg.inv((A / c).T @ (A / c))
    std = sigma * np.sqrt(np.diag(P)) / c
    corr = P / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    return s[0] / s[-1], std, corr


#%% Condition, CRLB and aliasing
sim = simulate_flight("paper", seed=1, rate=rate)
base = casep.load_model("platform36")
cond0, std0, _ = crlb(base, sim.flight)
print(f"paper at {rate:g} Hz, sigma {sigma} m/s")
print(f"{'model':<24} {'cond (equil.)':>14} {'Ka0x':>7} {'Ka1x':>7} {'Ka0y':>7} {'Ka0z':>7}   new terms")
print(f"{'platform36':<24} {cond0:>14.3g} "
      + " ".join(f"{std0[base.index(n)]:>7.3g}" for n in ("Ka0x", "Ka1x", "Ka0y", "Ka0z")))
for name in ("platform36_timeoffset", "platform36_leverarm"):
    m = casep.load_model(name)
    cond, std, corr = crlb(m, sim.flight)
    A = casep.build_sv(m, sim.flight.t, sim.flight.f, signals=sim.flight.model_signals(m.signals, m.name))
    A = A.reshape(-1, m.n_coefficients)
    A = A / np.linalg.norm(A, axis=0)
    new = [j for j in range(m.n_coefficients) if m.names[j] not in base.names]
    words = []
    for j in new:
        others = [k for k in range(m.n_coefficients) if k != j]
        r = A[:, j] - A[:, others] @ np.linalg.lstsq(A[:, others], A[:, j], rcond=None)[0]
        vif = 1.0 / (r @ r)  # unit-norm column: VIF = 1 / (1 - R^2) = 1 / |residual|^2
        top = sorted(others, key=lambda k: -abs(corr[j, k]))[:3]
        words.append(f"{m.names[j]} {std[j]:.3g} {m.units[j]} (VIF {vif:.3g}; corr "
                     + ", ".join(f"{m.names[k]} {corr[j, k]:+.2f}" for k in top) + ")")
    print(f"{name:<24} {cond:>14.3g} " + " ".join(f"{std[m.index(n)]:>7.3g}" for n in ("Ka0x", "Ka1x", "Ka0y", "Ka0z"))
          + "   " + "; ".join(words))

#%% Noise-free recovery of an exactly injected 20 ms offset and of a lever arm
quiet = dataclasses.replace(get_scenario("paper"), noise=NoiseModel("white", 0.0))
truth = dict(get_scenario("paper").truth)
for label, kw, model in (("20 ms offset, exact v(t - dt)", {"time_offset": 0.02}, "platform36_timeoffset"),
                         ("lever arm (1.5, -0.4, 0.3) m", {"lever_arm": [1.5, -0.4, 0.3]}, "platform36_leverarm")):
    s = simulate_flight(quiet, seed=1, rate=rate, model=model, truth=truth, **kw)
    S = casep.build_sv(s.model, s.flight.t, s.flight.f, signals=s.flight.model_signals(s.model.signals, s.model.name))
    A = S.reshape(-1, s.model.n_coefficients)
    c = np.linalg.norm(A, axis=0)
    x = np.linalg.lstsq(A / c, s.flight.dv.reshape(-1), rcond=None)[0] / c
    _, std, _ = crlb(s.model, s.flight)
    j = s.model.index("Ka0y")
    print(f"noise-free, {label}: new terms {np.round(x[36:], 6).tolist()} "
          f"(CRLB std at {sigma} m/s {np.round(std[36:], 4).tolist()}); "
          f"Ka0y error {(x[j] - truth['Ka0y']) / std[j]:+.3f} std")
