"""Clock-drift check under Gauss-Markov plus white tracking noise: false-alarm rate and detection.

Simulated ``dv = a(t) tau(t) + GM(tau_c 1 s, 0.05 m/s) + white 0.03 m/s`` at 10 Hz over 300 s, the
acceleration of a manoeuvring aircraft (sines of periods 7 to 40 s, a few m/s^2), the tags late by
``tau(t) = 40 ms + ppm 1e-6 t``. For each seed, :func:`casep.checks.tracking_quality.clock_drift`; an alarm as
in ``screen_tracking``'s warning: ``|drift| > max(DRIFT_MIN_PPM, 4 std)``. Prints, for drift 0 and 104 ppm,
the alarm rate, the RMS of (estimate - truth) / std and the median std.

    python benchmarks/mc_clock_drift.py [seeds]
"""

from __future__ import annotations

import sys

import numpy as np

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


def run(seeds: int, ppm: float) -> tuple[float, float, float]:
    """Alarm rate, RMS z and median std over `seeds` flights."""
    est = np.array([clock_drift(*flight(s, ppm)) for s in range(seeds)])
    alarm = np.abs(est[:, 0]) > np.maximum(DRIFT_MIN_PPM, 4 * est[:, 1])
    z = (est[:, 0] - ppm) / est[:, 1]
    return float(alarm.mean()), float(np.sqrt(np.mean(z**2))), float(np.median(est[:, 1]))


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    for ppm in (0.0, 104.0):
        rate, rms, sd = run(n, ppm)
        print(f"drift {ppm:5.0f} ppm, {n} seeds: alarm rate {rate:.3f}, RMS z {rms:.2f}, median std {sd:.3g} ppm")
