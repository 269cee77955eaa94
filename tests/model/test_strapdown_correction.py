"""The IMU correction of a strapdown model (:func:`casep.model.strapdown.corrected_imu`) against the closed form.

strapdown33's errors are affine in the inputs: with ``M_a`` (scale factors on the diagonal, misalignments
off it), ``M_g`` likewise and ``G`` the g-sensitivity, written here from the model's docstring::

    fb_m = (I + M_a) fb + b_a,      w_m = (I + M_g) w + b_g + G fb / g0

so the clean record is ``fb = (I + M_a)^-1 (fb_m - b_a)``, ``w = (I + M_g)^-1 (w_m - b_g - G fb / g0)``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import casep
from casep.model.strapdown import CORRECTION_GROWING, CORRECTION_MAX_STEPS, body_errors, corrected_imu
from casep.navigation.imu import ImuData, sample_periods, with_rates
from casep.units import G0

AX = "xyz"
ARCSEC = math.pi / 180 / 3600
DEG_H = math.pi / 180 / 3600


@pytest.fixture(scope="module")
def strapdown33():
    return casep.load_model("strapdown33")


def _mems(model, rng):
    """Coefficients of a consumer MEMS IMU (natural units): 30 mg, 1 %, 0.5 deg, 0.3 deg/s, 2 %, 0.1 deg/s/g."""
    size = {"ba": 30.0, "sa": 1e4, "ma": 1800.0, "bg": 1000.0, "sg": 2e4, "mg": 1800.0, "gg": 400.0}
    return np.array([rng.normal(scale=size[n[:2]]) for n in model.names])


def _closed_form(model, D):
    c = dict(zip(model.names, D))
    Ma, Mg, G = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    for a, i in enumerate(AX):
        Ma[a, a], Mg[a, a] = c[f"sa_{i}"] * 1e-6, c[f"sg_{i}"] * 1e-6
        for b, j in enumerate(AX):
            G[a, b] = c[f"gg_{i}{j}"] * DEG_H / G0
            if j != i:
                Ma[a, b], Mg[a, b] = c[f"ma_{i}{j}"] * ARCSEC, c[f"mg_{i}{j}"] * ARCSEC
    ba = np.array([c[f"ba_{i}"] * 1e-3 * G0 for i in AX])
    bg = np.array([c[f"bg_{i}"] * DEG_H for i in AX])
    return Ma, Mg, G, ba, bg


def _record(rng, n=400):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    fb = rng.normal(scale=30.0, size=(n, 3))
    w = rng.normal(scale=3.0, size=(n, 3))
    return q, fb, w, np.arange(n) * 0.01


def test_forward_errors_are_the_closed_form(strapdown33, rng):
    q, fb, w, t = _record(rng)
    D = _mems(strapdown33, rng)
    Ma, Mg, G, ba, bg = _closed_form(strapdown33, D)
    df, dw = body_errors(strapdown33, q, fb, w, t, D)
    assert np.allclose(df, fb @ Ma.T + ba, rtol=0, atol=1e-12 * np.abs(fb).max())
    assert np.allclose(dw, w @ Mg.T + bg + fb @ G.T, rtol=0, atol=1e-12 * np.abs(w).max())


def test_the_correction_recovers_the_clean_record_to_rounding(strapdown33, rng):
    q, fb, w, t = _record(rng)
    D = _mems(strapdown33, rng)
    Ma, Mg, G, ba, bg = _closed_form(strapdown33, D)
    fb_m = fb @ (np.eye(3) + Ma).T + ba  # measured by the closed form, not by the model
    w_m = w @ (np.eye(3) + Mg).T + bg + fb @ G.T
    fb_c, w_c = corrected_imu(strapdown33, q, fb_m, w_m, t, D)
    fb_inv = np.linalg.solve(np.eye(3) + Ma, (fb_m - ba).T).T  # the closed-form inverse
    w_inv = np.linalg.solve(np.eye(3) + Mg, (w_m - bg - fb_inv @ G.T).T).T
    for got, want, clean in ((fb_c, fb_inv, fb), (w_c, w_inv, w)):
        scale = np.abs(clean).max()
        assert np.abs(got - want).max() <= 1e-14 * scale * 8
        assert np.abs(got - clean).max() <= 1e-14 * scale * 8
    assert np.abs(fb_m - fb).max() > 0.1  # the errors were there to remove


def test_no_errors_no_correction_and_too_large_errors_refused(strapdown33, rng):
    q, fb, w, t = _record(rng, 50)
    D0 = np.zeros(strapdown33.n_coefficients)
    fb_c, w_c = corrected_imu(strapdown33, q, fb, w, t, D0)
    assert np.array_equal(fb_c, fb) and np.array_equal(w_c, w)
    D = D0.copy()
    D[strapdown33.index("sa_x")] = -1.5e6  # a scale factor of -150 %: the record cannot be inverted by iteration
    with pytest.raises(ValueError, match="do not invert") as refused:  # the steps grow x1.5 each: said at once
        corrected_imu(strapdown33, q, fb, w, t, D)
    assert f"after {CORRECTION_GROWING + 1} steps" in str(refused.value)


def test_an_axis_the_record_barely_excites_converges_at_its_sensors_rounding():
    """A rail launch's body z force is ~1e-6 m/s^2 while x carries 59: the misalignments mix x into z's error,
    whose rounding is then 4.5e-12 of z's own largest value. Measured against z alone the steps stalled there and
    this correction (a pass of ``casep separate --imu`` on a tactical record: its coefficients at full precision,
    the stall depends on the last bits) was refused after 60 steps ("do not invert"); measured against the rounding
    of the forces that form the step it converges, to a fixed point of ``x + delta(x) = x_measured`` within rounding."""
    from casep.frames import LaunchSite
    from casep.navigation import check_imu, navigate
    from casep.simulation.strapdown import rail_launch

    site = LaunchSite(32.9, -106.4, 1200.0, 10.0, 6.0)
    t = np.round(np.arange(0.0, 20.0, 0.1), 10)
    w, fb = rail_launch(site, t, elevation_deg=84.0, boost_g=6.0, burn_s=10.0, coast_g=-0.3, roll=(1.5, 3.0))
    assert np.abs(fb[:, 2]).max() < 1e-5 < 50.0 < np.abs(fb[:, 0]).max()
    q = navigate(check_imu(ImuData(t, w, fb)), site, (0.0, 5.5), heading_deg=10.0).q
    model = casep.load_model("strapdown15_axial")
    small = dict(ba_x=0.5, ba_y=-0.4, bg_x=2.0, bg_y=-1.5, sg_x=100.0)  # the record's own errors
    df, dw = body_errors(model, q, fb, w, t, np.array([small.get(n, 0.0) for n in model.names]))
    fb_m, w_m = fb + df, w + dw
    D = np.array([-2.9031074287021674, 4.885374715126661, -4.261493305524318, 1009.0587254554495, 5687.199394038325,
                  495.72776716534656, -6.617375023755446, 53.109150793048244, 63.429369639026035, 1094.7975331165342,
                  5872.031329992448, 135.94586462202938, -4.831269300732123, -15.041528817474443, 50.8690726975223])
    fb_c, w_c = corrected_imu(model, q, fb_m, w_m, t, D)
    ef, ew = body_errors(model, q, fb_c, w_c, t, D)
    assert np.abs(fb_c + ef - fb_m).max() <= 1e-14 * np.abs(fb_m).max()
    assert np.abs(w_c + ew - w_m).max() <= 1e-14 * np.abs(w_m).max()


def test_a_lateral_force_measured_near_zero_converges_to_rounding(strapdown33, rng):
    """A tactical boost: the lateral specific forces measured at 1e-9 m/s^2, the misalignments turning 0.15 m/s^2
    of the axial force into them. The corrected lateral force is 0.15, whose last digit (2e-17) is 1e-8 of the
    measured column: the inversion converges to the rounding of the forces it forms, and is accepted (relative to
    the measured column alone, its last digit's flicker read as "does not invert" on 8 of 8 seeds)."""
    q, fb_m, w_m, t = _record(rng, 2000)
    fb_m[:, 1:] *= 1e-10
    D = np.zeros(strapdown33.n_coefficients)
    for name, value in (("ma_zx", 1000.0), ("ma_yx", -700.0), ("sa_x", 2000.0), ("ba_z", 5.0), ("gg_zx", 300.0)):
        D[strapdown33.index(name)] = value
    Ma, Mg, G, ba, bg = _closed_form(strapdown33, D)
    fb_c, w_c = corrected_imu(strapdown33, q, fb_m, w_m, t, D)
    fb_inv = np.linalg.solve(np.eye(3) + Ma, (fb_m - ba).T).T
    w_inv = np.linalg.solve(np.eye(3) + Mg, (w_m - bg - fb_inv @ G.T).T).T
    assert np.abs(fb_c[:, 1:]).max() > 0.1  # the lateral forces corrected far from their measured 1e-9
    assert np.abs(fb_c - fb_inv).max() <= 8e-15 * np.abs(fb_inv).max()
    assert np.abs(w_c - w_inv).max() <= 8e-15 * np.abs(w_inv).max()


def test_a_map_that_does_not_contract_is_refused(strapdown33, rng):
    """A scale factor of -100 %: the measured force is no longer a function of the true one, each step moves the
    record by the measured force again (gain 1, no contraction): refused after the steps allowed, not accepted at
    a rounding floor. A slow contraction (-99 %: gain 0.99) does not reach rounding in them either."""
    q, fb, w, t = _record(rng, 50)
    for sa in (-1e6, -0.99e6):
        D = np.zeros(strapdown33.n_coefficients)
        D[strapdown33.index("sa_x")] = sa
        with pytest.raises(ValueError, match="do not invert") as refused:
            corrected_imu(strapdown33, q, fb, w, t, D)
        assert f"after {CORRECTION_MAX_STEPS} steps" in str(refused.value)


def test_increments_take_the_corrected_rates_times_their_periods(rng):
    t = np.array([0.0, 0.01, 0.02, 0.05, 0.06])  # a gap: the period of the fourth row is 0.03 s
    dth, dv = rng.normal(size=(5, 3)) * 1e-3, rng.normal(size=(5, 3)) * 0.1
    step = sample_periods(t)[:, None]
    imu = ImuData(t, dth / step, dv / step, "increments", dth, dv)
    w, f = imu.w * 1.01, imu.f - 0.2
    out = with_rates(imu, w, f)
    assert np.allclose(out.dtheta, w * np.array([0.01, 0.01, 0.01, 0.03, 0.01])[:, None], rtol=1e-14, atol=0)
    assert np.allclose(out.dv / step, f, rtol=1e-14, atol=0) and out.kind == "increments"


def test_the_corrected_attitude_is_the_rotation_by_phi():
    """true = R(phi) INS: a rotation, equal to (I + [phi x]) INS to first order, and undone by R(-phi)."""
    from scipy.spatial.transform import Rotation

    from casep.model.strapdown import corrected_attitude

    C = Rotation.from_euler("zyx", [30.0, -50.0, 80.0], degrees=True).as_matrix()
    phi = np.array([2e-4, -1e-4, 3e-4])
    K = np.array([[0.0, -phi[2], phi[1]], [phi[2], 0.0, -phi[0]], [-phi[1], phi[0], 0.0]])
    out = corrected_attitude(C, phi)
    np.testing.assert_allclose(out, (np.eye(3) + K) @ C, atol=2 * np.dot(phi, phi))  # second order
    big = np.radians([3.0, -4.0, 5.0])
    np.testing.assert_allclose(corrected_attitude(C, big), Rotation.from_rotvec(big).as_matrix() @ C, atol=1e-14)
    np.testing.assert_allclose(corrected_attitude(corrected_attitude(C, big), -big), C, atol=1e-14)


def test_the_errors_of_the_correction_are_its_derivative(strapdown33):
    """:func:`correction_errors` at MEMS coefficients D: the linearised model's body errors per unit coefficient are
    minus the derivative of :func:`corrected_imu` with respect to D (central differences of the inversion, step 1e-3
    of each coefficient's size: the inverse is smooth, so O(h^2) ~ 1e-8 relative); they differ from the model's own
    errors by the factor (I + d delta / d x)^-1, a percent at these sizes; at D = 0 they are the model's own."""
    from casep.model.loader import build_model
    from casep.model.strapdown import correction_errors

    rng = np.random.default_rng(5)
    D = _mems(strapdown33, rng)
    q, fb_m, w_m, t = _record(rng, 50)
    fb, w = corrected_imu(strapdown33, q, fb_m, w_m, t, D)
    lin, own = build_model("strapdown33"), build_model("strapdown33")
    correction_errors(lin, D)
    correction_errors(own, np.zeros(D.size))
    lin.setup(), own.setup()
    unit = np.eye(D.size)
    for name in ("ba_x", "sa_y", "ma_zx", "bg_z", "mg_xy", "gg_yz"):
        j = strapdown33.names.index(name)
        h = 1e-3 * abs(D[j])
        plus, minus = (corrected_imu(strapdown33, q, fb_m, w_m, t, D + s * h * unit[j]) for s in (1, -1))
        fd = np.hstack([(plus[0] - minus[0]) / (2 * h), (plus[1] - minus[1]) / (2 * h)])
        eff = np.hstack(body_errors(lin, q, fb, w, t, unit[j]))
        base = np.hstack(body_errors(strapdown33, q, fb, w, t, unit[j]))
        np.testing.assert_allclose(-fd, eff, rtol=1e-6, atol=1e-6 * np.abs(eff).max(), err_msg=name)
        assert np.abs(eff - base).max() > 1e-4 * np.abs(base).max(), name
        np.testing.assert_allclose(np.hstack(body_errors(own, q, fb, w, t, unit[j])), base, rtol=1e-12,
                                   atol=1e-15 * np.abs(base).max(), err_msg=name)


def test_a_refusal_names_the_columns_and_the_coefficients_that_scale_them(strapdown33, rng):
    """The fixed point ``x = x_m - s x`` of a scale factor ``s`` alone diverges along its own axis only (gain
    ``|s|`` > 1); a bias only shifts the record (the map's derivative does not depend on it). So with sa_x at
    -150 % beside biases far beyond any plausible size, the refusal names the column fb_x alone, and sa_x, not the
    biases, as the coefficient beyond what a linear error model can describe."""
    q, fb, w, t = _record(rng, 50)
    D = np.zeros(strapdown33.n_coefficients)
    for name, value in (("sa_x", -1.5e6), ("ba_x", 5e6), ("bg_y", 1e7)):
        D[strapdown33.index(name)] = value
    with pytest.raises(ValueError, match="do not invert") as refused:
        corrected_imu(strapdown33, q, fb, w, t, D)
    said = str(refused.value)
    moved = said.split("still moved ")[1].split(" (of the largest")[0]
    assert [part.split(" by ")[0] for part in moved.split(", ")] == ["fb_x"]
    assert "beyond what a linear error model can describe: sa_x -1.5e+06 ppm (limit 1e+05)" in said
    assert "ba_x" not in said and "bg_y" not in said
