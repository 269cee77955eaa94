"""How the seeded Monte Carlo benchmarks print a pool of z = (estimate - truth) / std."""

from __future__ import annotations

import numpy as np


def z_figures(z) -> str:
    """``RMS r, within 1.96 std c, largest |z| m`` of the non-empty `z`: the RMS of z (near 1 when the std hold),
    the share within 1.96 std (near 0.95) and the largest |z|."""
    z = np.asarray(z, dtype=float)
    return (f"RMS {np.sqrt(np.mean(z**2)):.3f}, within 1.96 std {np.mean(np.abs(z) < 1.96):.3f}, "
            f"largest |z| {np.max(np.abs(z)):.2f}")
