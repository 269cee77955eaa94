"""S_V against an independent forward simulation and hand-derived columns (casep.model.sv)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import casep
from casep.simulation.synthetic import excitation_force
from casep.units import ARCSEC, DEG_PER_HOUR, G0

MG, UG = 1e-3 * G0, 1e-6 * G0


def _phidot_delta(D: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (1) and (3) of docs/reference/model.md written out in numpy (SI out), independent of casep."""
    wx, wy, wz = f / G0
    g = D[:15].reshape(3, 5) * DEG_PER_HOUR
    phidot = np.array([
        g[0, 0] + g[0, 1] * wx + g[0, 2] * wy + g[0, 3] * wz + g[0, 4] * wx**2,
        g[1, 0] + g[1, 1] * wy + g[1, 2] * wz + g[1, 3] * wx + g[1, 4] * wy**2,
        g[2, 0] + g[2, 1] * wz + g[2, 2] * wx + g[2, 3] * wy + g[2, 4] * wz**2,
    ])
    a = D[15:36].reshape(3, 7)
    units = np.array([MG, MG, UG, UG, UG, UG, UG])
    a = a * units
    delta = np.array([
        a[0, 0] + a[0, 1] * wx + a[0, 2] * wy + a[0, 3] * wz + a[0, 4] * wx**2 + a[0, 5] * wx * wy + a[0, 6] * wx * wz,
        a[1, 0] + a[1, 1] * wy + a[1, 2] * wz + a[1, 3] * wx + a[1, 4] * wy**2 + a[1, 5] * wy * wz + a[1, 6] * wy * wx,
        a[2, 0] + a[2, 1] * wz + a[2, 2] * wx + a[2, 3] * wy + a[2, 4] * wz**2 + a[2, 5] * wz * wx + a[2, 6] * wz * wy,
    ])
    return phidot, delta


def _simulate(D: np.ndarray, t: np.ndarray, phi0: np.ndarray | None = None) -> np.ndarray:
    """dv(t) by integrating phi' = phidot, dv' = f x phi + Delta with an adaptive ODE solver."""
    if phi0 is None:
        phi0 = np.zeros(3)

    def rhs(tt, x):
        f = excitation_force(np.array([tt]))[0]
        phidot, delta = _phidot_delta(D, f)
        return np.concatenate([phidot, np.cross(f, x[:3]) + delta])

    sol = solve_ivp(rhs, (t[0], t[-1]), np.concatenate([phi0, np.zeros(3)]), method="DOP853",
                    t_eval=t, rtol=1e-12, atol=1e-15)
    assert sol.success
    return sol.y[3:].T


@pytest.mark.parametrize("part", ["all", "gyro"])
def test_sv_times_D_equals_forward_simulation(platform36, truth36, part):
    # "gyro": accelerometer terms dominate dv, so check the [f x] phi path on its own too.
    D = truth36 if part == "all" else np.where(np.arange(36) < 15, truth36, 0.0)
    t = np.arange(0.0, 120.0, 0.01)  # 100 Hz
    S = casep.build_sv(platform36, t, excitation_force(t))
    dv_sv = S @ D
    idx = np.arange(0, t.size, 50)  # compare every 0.5 s
    dv_ode = _simulate(D, t[idx])
    err = np.abs(dv_sv[idx] - dv_ode).max() / np.abs(dv_ode).max()
    assert err <= 1e-6, err


def test_sv_platform39_phi0_matches_simulation(platform39, truth36):
    D = np.concatenate([truth36, [20.0, -35.0, 12.0]])  # phi0 in arcsec
    t = np.arange(0.0, 60.0, 0.01)
    dv_sv = casep.build_sv(platform39, t, excitation_force(t)) @ D
    idx = np.arange(0, t.size, 100)
    dv_ode = _simulate(truth36, t[idx], phi0=D[36:] * ARCSEC)
    assert np.abs(dv_sv[idx] - dv_ode).max() / np.abs(dv_ode).max() <= 1e-6


# Constant specific force: phi and the integrand are polynomials in t of degree <= 1, so the
# trapezoid rule is exact and each column has a closed form.
F = np.array([2.0, 3.0, -1.5]) * G0


@pytest.fixture(scope="module")
def const_S(platform39):
    t = np.linspace(0.0, 10.0, 41)
    return t, casep.build_sv(platform39, t, np.tile(F, (t.size, 1)))


def _col(platform39, const_S, name):
    t, S = const_S
    return t, S[:, :, platform39.index(name)]


@pytest.mark.parametrize(
    "name, phi_axis, rate",
    [("Kg0x", 0, DEG_PER_HOUR), ("Kg1yz", 1, DEG_PER_HOUR * F[2] / G0),
     ("Kg2z", 2, DEG_PER_HOUR * (F[2] / G0) ** 2), ("Kg1zx", 2, DEG_PER_HOUR * F[0] / G0)],
)
def test_gyro_columns_by_hand(platform39, const_S, name, phi_axis, rate):
    # phi = rate * t e_axis; dv = int f x phi = (t^2 / 2) rate (f x e_axis).
    # f x e_x = (0, f_z, -f_y), f x e_y = (-f_z, 0, f_x), f x e_z = (f_y, -f_x, 0).
    t, col = _col(platform39, const_S, name)
    fxe = {0: [0.0, F[2], -F[1]], 1: [-F[2], 0.0, F[0]], 2: [F[1], -F[0], 0.0]}[phi_axis]
    expect = np.outer(t**2 / 2 * rate, fxe)
    np.testing.assert_allclose(col, expect, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize(
    "name, axis, value",
    [("Ka1x", 0, MG * F[0] / G0), ("Ka2yz", 1, UG * F[1] * F[2] / G0**2),
     ("Ka1zy", 2, UG * F[1] / G0), ("Ka0z", 2, MG)],
)
def test_accel_columns_by_hand(platform39, const_S, name, axis, value):
    t, col = _col(platform39, const_S, name)  # dv_axis = value * t
    expect = np.zeros((t.size, 3))
    expect[:, axis] = value * t
    np.testing.assert_allclose(col, expect, rtol=1e-12, atol=1e-18)


def test_misalignment_column_by_hand(platform39, const_S):
    t, col = _col(platform39, const_S, "phi0y")  # phi = ARCSEC e_y: dv = t ARCSEC (f x e_y)
    np.testing.assert_allclose(col, np.outer(t * ARCSEC, [-F[2], 0.0, F[0]]), rtol=1e-12, atol=1e-18)


def test_chunking_and_nonuniform_time_do_not_change_S(platform39, rng):
    t = np.cumsum(rng.uniform(0.005, 0.02, 5000))
    f = excitation_force(t)
    ref = casep.SVBuilder(platform39, chunk=5000).build(t, f)
    for chunk in (1, 7, 512):
        np.testing.assert_allclose(casep.SVBuilder(platform39, chunk=chunk).build(t, f), ref,
                                   rtol=1e-13, atol=1e-13 * np.abs(ref).max())


def test_bad_arguments(platform36):
    with pytest.raises(ValueError, match="`t` is not strictly increasing at row 2"):
        casep.build_sv(platform36, [0.0, 1.0, 1.0], np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"`f` must have shape \(N, 3\)"):
        casep.build_sv(platform36, [0.0, 1.0], np.zeros((3, 3)))
    with pytest.raises(ValueError, match="`f` is not finite at row 1"):
        casep.build_sv(platform36, [0.0, 1.0], np.array([[0, 0, 0], [0, np.nan, 0.0]]))
    with pytest.raises(ValueError, match="`chunk` must be a positive int"):
        casep.SVBuilder(platform36, chunk=0)
    m = casep.build_model("platform36")
    with pytest.raises(ValueError, match="not set up"):
        casep.SVBuilder(m)


def test_data_gap_warns_with_numbers(platform36):
    from casep.exceptions import CasepWarning

    t = np.r_[np.arange(0.0, 10.0, 0.01), np.arange(12.0, 20.0, 0.01)]  # 2 s dropout
    with pytest.warns(CasepWarning,
                      match=r"1 gap\(s\) longer than 10x the median step 0.01 s \(largest 2.01 s before sample 1001, "
                      r"t = 12 s\)"):
        casep.build_sv(platform36, t, excitation_force(t))


@pytest.mark.parametrize("name", ["strapdown15_axial", "platform36_leverarm"])
def test_evaluate_samples_is_the_mapped_call_bit_for_bit(name):
    """evaluate_samples (a buffer over the mapped function) returns the numbers of ``fn.map(n)(...)``, transposed:
    a model's outputs (dense), and a function whose output has structural zeros (the plain call)."""
    import casadi as ca

    from casep.model.sv import evaluate_samples

    rng = np.random.default_rng(5)
    fn = casep.load_model(name).functions
    x = ca.SX.sym("x", 2)
    sparse = ca.Function("sparse", [x], [ca.vertcat(x[0] * x[1], ca.SX(1, 1), x[0])], ["x"], ["y"])
    assert not sparse.sparsity_out(0).is_dense()
    for f in (fn["Delta"], fn["phidot"], fn["velocity_error"], sparse):
        n = 37
        values = {a: rng.standard_normal((f.size_in(i)[0], n)) for i, a in enumerate(f.name_in())}
        ref = np.array(f.map(n)(*(values[a] for a in f.name_in()))).T
        got = evaluate_samples(f, values, n)
        assert got.shape == ref.shape == (n, f.size1_out(0))
        assert np.array_equal(got, ref)
