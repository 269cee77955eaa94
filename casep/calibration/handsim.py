"""Synthetic hand-turned sessions: known poses, motions, noise, short pauses, a wobble (for tests and benchmarks).

The sensor starts at rest for ``init_s`` seconds, then is turned ``n_poses - 1`` times, each time
by a random angle in ``angle_deg`` about a random body axis with the smooth rate profile
``w(t) = theta / T (1 - cos(2 pi t / T))`` (a sample holds its rate over ``dt``; the samples'
rates sum to exactly ``theta / dt``), with a linear acceleration bump of ``lin_acc`` m/s^2 during it,
and held still for a random time in ``pose_s``. Options: one motion with a short pause in its
middle (``pause_s``: a hesitation shorter than a pose) and one pose with a wobble in its middle
(a 2-deg turn out and back in 0.5 s).

Readings (imu_tk's model inverted, :mod:`casep.calibration.multiposition`):
``a = (T_a K_a)^-1 f + b_a + noise``, ``w = (T_g K_g)^-1 omega + b_g + noise``, f = C^T (0, 0, g)
(+ the linear acceleration), C the body-to-world rotation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from casep.calibration.multiposition import acc_matrix, gyro_matrix, rotations

__all__ = ["HandSession", "simulate_hand_session", "TRUTH_SI"]

#: A typical MEMS truth, readings in SI (imu_tk's parameters, ACC_NAMES / GYRO_NAMES order; biases apart).
TRUTH_SI = {"acc": np.array([0.002, -0.003, 0.001, 0.996, 1.004, 0.992, 0.10, -0.08, 0.30]),
            "gyro": np.array([0.004, -0.002, 0.003, 0.001, -0.005, 0.002, 1.003, 0.995, 1.008]),
            "gyro_bias": np.array([0.02, -0.007, 0.012])}


@dataclass(frozen=True)
class HandSession:
    """A simulated session: readings, truth and where the sensor was really at rest.

    ``moving``: the samples of a turn (the wobble's included); ``steps``: each sample's rotation vector, rad.
    """

    acc: np.ndarray
    gyr: np.ndarray
    rate: float
    poses: list
    moving: np.ndarray
    steps: np.ndarray
    truth: dict
    gravity: float


def _profile(theta: float, n: int) -> np.ndarray:
    """Per-sample angle increments of the 1 - cos rate profile over n samples, summing to theta."""
    s = 1.0 - np.cos(2.0 * math.pi * (np.arange(n) + 0.5) / n)
    return theta * s / s.sum()


def simulate_hand_session(n_poses: int = 30, *, rate: float = 100.0, truth: dict | None = None,
                          acc_noise: float = 0.02, gyr_noise: float = 0.002, gravity: float = 9.80665,
                          init_s: float = 8.0, pose_s=(1.5, 3.0), motion_s=(1.0, 2.0), angle_deg=(60.0, 150.0),
                          lin_acc: float = 0.5, pause_s: float = 0.0, wobble: bool = False,
                          axis: np.ndarray | None = None, gm: tuple[float, float, float] | None = None,
                          seed: int | None = None) -> HandSession:
    """A hand-turned session (module notes); noise std per axis in the reading unit (SI with TRUTH_SI).

    `axis`: every turn about this body axis (default: a random axis per turn). `gm`: ``(acc std,
    gyro std, tau s)`` of a first-order Gauss-Markov noise added to the white noise of each axis,
    ``x_k+1 = e^(-dt/tau) x_k + sqrt(1 - e^(-2 dt/tau)) std n_k`` (stationary from the first sample).
    """
    rng = np.random.default_rng(seed)
    tr = TRUTH_SI if truth is None else truth
    dt = 1.0 / rate
    steps, lin, poses, moving = [], [], [], []  # per-sample rotation vectors, linear accelerations
    k = 0

    def hold(t):
        nonlocal k
        n = int(round(t * rate))
        steps.append(np.zeros((n, 3)))
        lin.append(np.zeros((n, 3)))
        moving.append(np.zeros(n, bool))
        k += n
        return n

    def turn(axis, theta, t, bump=True):
        nonlocal k
        n = int(round(t * rate))
        steps.append(_profile(theta, n)[:, None] * axis[None, :])
        d = rng.normal(size=3)
        lin.append((lin_acc * np.sin(math.pi * np.arange(n) / n))[:, None] * (d / np.linalg.norm(d)) * bump)
        moving.append(np.ones(n, bool))
        k += n

    a0 = k
    hold(init_s)
    poses.append((a0, k))
    wob = n_poses // 2 if wobble else -1
    pause = n_poses // 3 if pause_s > 0 else -1
    for j in range(1, n_poses):
        ax = rng.normal(size=3) if axis is None else np.asarray(axis, dtype=float)
        ax = ax / np.linalg.norm(ax)
        theta = math.radians(rng.uniform(*angle_deg)) * rng.choice([-1.0, 1.0])
        T = rng.uniform(*motion_s)
        if j == pause:
            turn(ax, theta / 2, T / 2)
            hold(pause_s)
            turn(ax, theta / 2, T / 2)
        else:
            turn(ax, theta, T)
        a0 = k
        tp = rng.uniform(*pose_s)
        if j == wob:
            hold(tp)
            poses.append((a0, k))
            e = rng.normal(size=3)
            e /= np.linalg.norm(e)
            turn(e, math.radians(2.0), 0.25, bump=False)
            turn(e, -math.radians(2.0), 0.25, bump=False)
            a0 = k
            hold(tp)
        else:
            hold(tp)
        poses.append((a0, k))
    phi, la, mv = np.vstack(steps), np.vstack(lin), np.concatenate(moving)
    R = rotations(phi)
    C = np.empty_like(R)
    c = np.eye(3)
    for i in range(len(R)):  # C_k: orientation at sample k; the rate of sample k turns it to C_{k+1}
        C[i] = c
        c = c @ R[i]
    f = np.einsum("kji,kj->ki", C, np.array([0.0, 0.0, gravity]) + la)  # C^T (g up + linear acceleration)
    w = phi / dt
    acc = np.linalg.solve(acc_matrix(tr["acc"]), f.T).T + tr["acc"][6:9] + acc_noise * rng.normal(size=f.shape)
    gyr = np.linalg.solve(gyro_matrix(tr["gyro"]), w.T).T + tr["gyro_bias"] + gyr_noise * rng.normal(size=w.shape)
    if gm is not None:
        acc = acc + _gauss_markov(rng, len(acc), gm[0], gm[2], dt)
        gyr = gyr + _gauss_markov(rng, len(gyr), gm[1], gm[2], dt)
    return HandSession(acc=acc, gyr=gyr, rate=float(rate), poses=poses, moving=mv, steps=phi, truth=tr, gravity=gravity)


def _gauss_markov(rng: np.random.Generator, n: int, std: float, tau: float, dt: float) -> np.ndarray:
    """(n, 3) first-order Gauss-Markov noise of stationary std `std` and correlation time `tau` (s)."""
    from scipy.signal import lfilter

    a = math.exp(-dt / tau)
    e = rng.normal(size=(n, 3)) * std * math.sqrt(1.0 - a * a)
    e[0] = rng.normal(size=3) * std  # stationary start
    return lfilter([1.0], [1.0, -a], e, axis=0)
