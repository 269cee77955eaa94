"""Clock-drift check under Gauss-Markov plus white tracking noise: false-alarm rate and detection.

Simulated ``dv = a(t) tau(t) + GM(tau_c 1 s, 0.05 m/s) + white 0.03 m/s`` at 10 Hz over 300 s, the
acceleration of a manoeuvring aircraft (sines of periods 7 to 40 s, a few m/s^2), the tags late by
``tau(t) = 40 ms + ppm 1e-6 t``. For each seed, :func:`casep.checks.tracking_quality.clock_drift`; an alarm as
in ``screen_tracking``'s warning: ``|drift| > max(DRIFT_MIN_PPM, 4 std)``. Prints, for drift 0 and 104 ppm,
the alarm rate, the RMS of (estimate - truth) / std and the median std.

With ``--instrument``, the dv also holds instrument errors (:func:`instrument`: scale factors, biases, the tilt of
a gyro bias, whose dv follows the specific force), and the drift is measured twice: on
the raw dv (as the tracking screen does before any fit) and on the residuals of the least-squares fit of those
terms and one time offset (as ``casep separate`` does after its fit,
:func:`casep.checks.tracking_quality.fit_clock_drift`).

    python benchmarks/mc_clock_drift.py [seeds] [--instrument]
"""

from __future__ import annotations

import sys

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.checks.tracking_quality import DRIFT_MIN_PPM, clock_drift


def gm_white(rng: np.random.Generator, n: int, dt: float, tau_c: float = 1.0, s_gm: float = 0.05,
             s_w: float = 0.03) -> np.ndarray:
    """(n, 3) first-order Gauss-Markov (std `s_gm`, correlation time `tau_c`) plus white (std `s_w`) noise."""
    phi = np.exp(-dt / tau_c)
    e = rng.normal(0.0, s_gm * np.sqrt(1 - phi**2), (n, 3))
    x = np.empty((n, 3))
    x[0] = rng.normal(0.0, s_gm, 3)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + e[k]
    return x + rng.normal(0.0, s_w, (n, 3))


def flight(seed: int, ppm: float, span: float = 300.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, dv, a)`` of one simulated flight with drift `ppm`."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, span, 0.1)
    a = np.column_stack([3 * np.sin(2 * np.pi * t / 7), 2 * np.cos(2 * np.pi * t / 13), 4 * np.sin(2 * np.pi * t / 40)])
    tau = 0.040 + ppm * 1e-6 * t
    return t, a * tau[:, None] + gm_white(rng, t.size, 0.1), a


def instrument(t: np.ndarray, a: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) instrument-error dv and the columns (n, 3, 13) of the fit that takes it: per axis a scale factor
    ``s_j int a_j dt`` (2000 ppm), a bias ``b_j t`` (1 mm/s^2) and a constant; the tilt of a gyro bias ``w``
    (100 deg/h per axis), ``int f x (w t) dt`` with ``f = a + (0, 0, 9.81)``; and the shared time offset ``a``.
    Signs by the seed."""
    rng = np.random.default_rng(10_000 + seed)

    def integral(x: np.ndarray) -> np.ndarray:
        return cumulative_trapezoid(x, t)

    f = a + np.array([0.0, 0.0, 9.81])
    cols = np.zeros((t.size, 3, 13))
    for j in range(3):
        cols[:, j, 3 * j], cols[:, j, 3 * j + 1], cols[:, j, 3 * j + 2] = integral(a)[:, j], t, 1.0
        cols[:, :, 9 + j] = integral(np.cross(f, np.eye(3)[j] * t[:, None]))
        cols[:, j, 12] = a[:, j]
    x = np.concatenate([np.column_stack([rng.choice([-1.0, 1.0], 3) * 2e-3, rng.choice([-1.0, 1.0], 3) * 1e-3,
                                         np.zeros(3)]).reshape(-1),
                        rng.choice([-1.0, 1.0], 3) * np.radians(100.0) / 3600.0, [0.0]])
    return cols @ x, cols


def residuals(dv: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``dv - S x`` of the least-squares fit of the columns `cols` (n, 3, m) to `dv` (n, 3)."""
    S, y = cols.reshape(-1, cols.shape[2]), dv.reshape(-1)
    x, *_ = np.linalg.lstsq(S, y, rcond=None)
    return (y - S @ x).reshape(dv.shape)


def run(seeds: int, ppm: float, mode: str = "plain") -> tuple[float, float, float]:
    """Alarm rate, RMS z and median std over `seeds` flights; `mode`: ``plain`` (no instrument errors), ``raw``
    (instrument errors, the drift on the raw dv), ``residuals`` (on the fit's residuals)."""
    est = []
    for s in range(seeds):
        t, dv, a = flight(s, ppm)
        if mode != "plain":
            inst, cols = instrument(t, a, s)
            dv = dv + inst
            if mode == "residuals":
                dv = residuals(dv, cols)
        est.append(clock_drift(t, dv, a))
    e = np.array(est)
    alarm = np.abs(e[:, 0]) > np.maximum(DRIFT_MIN_PPM, 4 * e[:, 1])
    z = (e[:, 0] - ppm) / e[:, 1]
    return float(alarm.mean()), float(np.sqrt(np.mean(z**2))), float(np.median(e[:, 1]))


if __name__ == "__main__":
    args = [x for x in sys.argv[1:] if not x.startswith("--")]
    n = int(args[0]) if args else 200
    modes = ("raw", "residuals") if "--instrument" in sys.argv else ("plain",)
    for mode in modes:
        for ppm in (0.0, 104.0):
            rate, rms, sd = run(n, ppm, mode)
            print(f"{mode:9s} drift {ppm:5.0f} ppm, {n} seeds: alarm rate {rate:.3f}, RMS z {rms:.2f}, "
                  f"median std {sd:.3g} ppm")
