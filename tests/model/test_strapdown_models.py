"""The strapdown models: S_V against an independent nonlinear strapdown integration, the quaternion
matrix against SciPy, the shipped models' names and units."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import casep
from casep.model.strapdown import STRAPDOWN_COLUMNS
from casep.model.sv import build_sv

G0 = 9.80665
ARCSEC = math.pi / 180 / 3600
DEG_H = math.pi / 180 / 3600
SI = {"ba": 1e-3 * G0, "sa": 1e-6, "ma": ARCSEC, "bg": DEG_H, "sg": 1e-6, "mg": ARCSEC, "gg": DEG_H}


# ---------------------------------------------------------------- an independent strapdown INS (plain numpy)
def true_rate(t):
    """Body rate, rad/s: a roll of 2 rad/s with pitch and yaw wobbles (so every gyro axis sees rate)."""
    return np.stack([2.0 + 0.3 * np.sin(0.9 * t), 0.4 * np.sin(0.5 * t), 0.3 * np.cos(0.35 * t)], -1)


def true_force(t):
    """Body specific force, m/s^2: axial thrust plus lateral components on every axis."""
    return np.stack([30.0 + 8.0 * np.sin(0.2 * t), 3.0 * np.sin(0.7 * t), -2.5 * np.cos(0.45 * t) + 1.0], -1)


def sensitivities(names, fb, w):
    """Per natural unit of each coefficient, the accelerometer and gyro errors of strapdown33 written out
    from its docstring: (3, n) each, delta_f = Ea D, delta_w = Eg D (SI)."""
    gyro, row, k, s, source, axis = _layout(tuple(names))
    signal = np.stack([np.ones(3), fb, w, fb / G0])  # what each kind multiplies: 1, fb, w, fb / g0
    E = np.zeros((2, 3, len(names)))
    E[gyro, row, k] = s * signal[source, axis]
    return E[0], E[1]


@functools.lru_cache
def _layout(names: tuple):
    """Where each coefficient's term goes (accelerometer 0 or gyro 1, the axis i it acts on, its column) and what it
    multiplies (``ba``, ``bg``: 1; ``sa``: fb_i; ``ma``: fb_j; ``sg``: w_i; ``mg``: w_j; ``gg``: fb_j / g0), times
    its natural unit in SI: the loop of the docstring's terms once, the products at each time step."""
    rows = []
    for k, name in enumerate(names):
        kind, axes = name.split("_")
        i = "xyz".index(axes[0])
        j = "xyz".index(axes[1]) if len(axes) > 1 else i
        source, axis = {"ba": (0, i), "sa": (1, i), "ma": (1, j), "bg": (0, i), "sg": (2, i), "mg": (2, j),
                        "gg": (3, j)}[kind]
        rows.append((int(kind not in ("ba", "sa", "ma")), i, k, SI[kind], source, axis))
    return tuple(np.array(c) for c in zip(*rows))


def qmul(a, b):
    """Hamilton product, scalar first, broadcast over leading axes."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def rotate(q, v):
    """C(q) v for body-to-navigation quaternions q (scalar first)."""
    qv = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], -1)
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    return qmul(qmul(q, qv), conj)[..., 1:]


def navigate(D_batch, names, T=12.0, h=2e-3, every=5):
    """Velocity of an INS fed with the erroneous IMU, minus the true velocity, for each row of `D_batch`.

    RK4 on q_dot = q (0, w) / 2 and v_dot = C(q) fb (gravity is the same for the INS and the truth and
    cancels in the difference), step `h`; returns the times, dv (B, M, 3) and the INS signals at the
    samples (every `every` steps) for D = 0.
    """
    B = D_batch.shape[0]
    n = int(round(T / h))
    q = np.tile([1.0, 0.0, 0.0, 0.0], (B + 1, 1))  # row B: the truth (no errors)
    v = np.zeros((B + 1, 3))
    Ds = np.vstack([D_batch, np.zeros(len(names))])

    def rates(t, q):
        w, fb = true_rate(t), true_force(t)
        Ea, Eg = sensitivities(names, fb, w)
        wm, fm = w + Ds @ Eg.T, fb + Ds @ Ea.T  # (B + 1, 3): row B has D = 0
        qdot = 0.5 * qmul(q, np.concatenate([np.zeros((B + 1, 1)), wm], -1))
        return qdot, rotate(q, fm)

    ts, dvs, qs = [0.0], [np.zeros((B, 3))], [q[0].copy()]
    for k in range(n):
        t = k * h
        k1q, k1v = rates(t, q)
        k2q, k2v = rates(t + h / 2, q + h / 2 * k1q)
        k3q, k3v = rates(t + h / 2, q + h / 2 * k2q)
        k4q, k4v = rates(t + h, q + h * k3q)
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        if (k + 1) % every == 0:
            ts.append((k + 1) * h)
            dvs.append(v[:B] - v[B])
            qs.append(q[B].copy())
    return np.array(ts), np.stack(dvs, 1), np.array(qs)


@pytest.fixture(scope="module")
def strapdown33():
    return casep.load_model("strapdown33")


def test_sv_matches_finite_differences_of_an_independent_strapdown_integration(strapdown33):
    """S_V (trapezoid on 100 Hz samples of the INS's attitude, measured fb and w) against central
    differences of an RK4 quaternion strapdown integration (500 Hz) of each coefficient perturbed."""
    m = strapdown33
    names = m.names
    n = len(names)
    eps = np.array([{"ba": 0.5, "sa": 300.0, "ma": 60.0, "bg": 30.0, "sg": 300.0, "mg": 60.0, "gg": 30.0}
                    [nm.split("_")[0]] for nm in names])
    D = np.vstack([np.diag(eps), -np.diag(eps)])  # +eps e_j, -eps e_j
    t, dv, q = navigate(D, names)
    fd = (dv[:n] - dv[n:]) / (2 * eps[:, None, None])  # (n, M, 3): d dv / dD_j, per natural unit
    fd = np.moveaxis(fd, 0, -1)  # (M, 3, n)
    w, fb = true_rate(t), true_force(t)
    signals = dict(zip(STRAPDOWN_COLUMNS, np.column_stack([q, fb, w]).T))
    f_nav = rotate(q, fb)
    S = build_sv(m, t, f_nav, signals=signals)
    scale = np.abs(fd).max(axis=(0, 1))
    assert np.all(scale > 0)
    rel = np.abs(S - fd).max(axis=(0, 1)) / scale
    print(f"S_V against the independent integration: worst column {rel.max():.2e} relative")
    assert rel.max() < 2e-4, dict(zip(names, rel.round(7)))


def test_quaternion_matrix_matches_scipy():
    from scipy.spatial.transform import Rotation

    from casep.model.strapdown import quaternion_dcm

    rng = np.random.default_rng(5)
    for q in rng.standard_normal((6, 4)):
        q /= np.linalg.norm(q)
        C = np.array(quaternion_dcm(*q))  # a CasADi DM of numbers
        assert np.allclose(C, Rotation.from_quat(q, scalar_first=True).as_matrix(), atol=1e-14)
        assert np.allclose(np.array(quaternion_dcm(*(-q))), C, atol=1e-14)  # q and -q: one attitude


def test_symbolic_quaternion_matrix_is_the_numpy_one():
    """CasADi's C(q) (divided by |q|^2) equals casep.rotations.quat_to_dcm of q/|q|, non-unit q too."""
    from casep.model.strapdown import quaternion_dcm
    from casep.rotations import quat_to_dcm

    rng = np.random.default_rng(6)
    q = rng.standard_normal((8, 4)) * rng.uniform(0.1, 10.0, (8, 1))  # |q| from ~0.1 to ~20
    for qk in q:
        C = np.array(quaternion_dcm(*qk))
        assert np.abs(C - quat_to_dcm(qk / np.linalg.norm(qk))).max() < 1e-14


@pytest.mark.parametrize("name, n, extra", [("strapdown33", 33, ()), ("strapdown12", 12, ()),
                                            ("strapdown15_phi0", 15, ("phi0_x", "phi0_z")),
                                            ("strapdown42_extended", 42, ("ka2_x", "phi0_x", "l_x"))])
def test_shipped_strapdown_models(name, n, extra):
    m = casep.load_model(name)
    assert m.n_coefficients == n
    assert set(m.signals) == set(STRAPDOWN_COLUMNS)
    units = dict(zip(m.names, m.units))
    for nm, unit in (("ba_x", "mg"), ("sa_y", "ppm"), ("bg_z", "deg/h"), ("sg_x", "ppm")):
        assert units[nm] == unit
    if n >= 33:
        assert units["ma_xy"] == "arcsec" and units["mg_zy"] == "arcsec" and units["gg_yx"] == "deg/h/g"
    for nm in extra:
        assert nm in units
