"""Smooth analytic specific-force profiles and error injection for tests and examples.

These are test signals, not trajectories (the boost-phase simulator is separate): they
excite all three axes with several incommensurate frequencies so that every column of the
36-coefficient model is non-zero, and they are analytic so that an independent ODE
integration can evaluate them at any time.
"""

from __future__ import annotations

import numpy as np

from casep.model.error_model import ErrorModel
from casep.model.sv import build_sv
from casep.units import G0

__all__ = ["excitation_force", "inject_errors"]


def excitation_force(t: np.ndarray, duration: float = 180.0, *, cross_range: bool = True) -> np.ndarray:
    """Boost-like specific force, m/s^2, shape (N, 3), analytic in `t`.

    Axial load grows from about 1.6 g to about 5 g, pitched over from y (up) towards x
    (downrange), with slow oscillations on every axis; `cross_range` False sets f_z = 0
    (a pitch-plane flight).

    Parameters
    ----------
    t : (N,) array_like
        Times, s.
    duration : float, optional
        Length of the profile, s (sets the ramps).
    cross_range : bool, optional
        Whether f_z is excited.
    """
    t = np.asarray(t, dtype=float)
    if not np.isfinite(duration) or duration <= 0:
        raise ValueError(f"`duration` must be finite and > 0, got {duration}")
    u = t / duration
    fx = 0.15 + 2.6 * u**2 + 0.25 * np.cos(0.07 * t + 0.3) + 0.05 * np.sin(0.31 * t)
    fy = 1.6 + 2.2 * u**1.5 - 0.5 * u**3 + 0.15 * np.sin(0.11 * t)
    fz = (0.12 * np.sin(0.05 * t) + 0.08 * np.sin(0.23 * t + 1.0) + 0.05) if cross_range else 0.0 * t
    return G0 * np.column_stack([fx, fy, fz])


def inject_errors(
    model: ErrorModel,
    t: np.ndarray,
    f: np.ndarray,
    coefficients: np.ndarray,
    *,
    sigma: float = 0.0,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Velocity error of a model with given coefficients plus white noise.

    Parameters
    ----------
    model : ErrorModel
        Set-up model.
    t, f : array_like
        Times (s) and specific force (N, 3) in m/s^2.
    coefficients : (n,) array_like
        True coefficients, natural units, model order.
    sigma : float, optional
        White noise standard deviation per axis, m/s.
    rng : numpy.random.Generator, optional
        Required when `sigma` > 0.

    Returns
    -------
    (N, 3) ndarray
        dv = S_V D + noise, m/s.
    """
    D = np.asarray(coefficients, dtype=float)
    if D.shape != (model.n_coefficients,):
        raise ValueError(f"`coefficients` must have shape ({model.n_coefficients},), got {D.shape}")
    if not np.isfinite(sigma) or sigma < 0:
        raise ValueError(f"`sigma` must be finite and >= 0, got {sigma}")
    dv = build_sv(model, t, f) @ D
    if sigma > 0:
        if rng is None:
            raise ValueError("`rng` is required when `sigma` > 0 (no global random state)")
        dv = dv + sigma * rng.standard_normal(dv.shape)
    return dv
