"""``strapdown9_vehicle_window``: noise-free recovery on a simulated car window.

A level car (body z up) drives 30 s with braking, accelerating and turns both ways at up to 40 deg/s, plus a
small pitch and roll oscillation. Its clean IMU record is navigated by casep from the true state (the truth); the
IMU then gets the model's body errors at known coefficients (:func:`casep.model.strapdown.body_errors`, the
model's own forward law), the start a known attitude error ``phi0`` and velocity error ``dv0``, and is navigated
again. The tracked velocity is the clean navigation's. casep's separation must give the coefficients back: the
data follow the model to second order in the errors, which are small here (tactical sizes), so one linear pass
recovers them to a small fraction of their std at a stated tracking noise.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.estimators.spec import FitSpec
from casep.frames import LaunchSite
from casep.gravity import normal_gravity_ecef
from casep.io.files import read_flight_pair, write_table
from casep.model.strapdown import body_errors, corrected_attitude
from casep.navigation import ImuData
from casep.navigation.navigator import navigate_from
from casep.navigation.strapdown import dcm_to_quat
from casep.workflows.separate import separate

MODEL = "strapdown9_vehicle_window"
SITE = LaunchSite(40.1, -105.1, 1600.0, 0.0, 0.0)
RATE, TRK_RATE, T_END = 100.0, 4.0, 30.0
#: small errors (the linear model then holds to well below the tolerance): 1 mg, 0.3 % cross-axis, 20 deg/h,
#: 0.2 % yaw scale, 0.05 deg attitude, 2 cm/s
TRUTH = dict(ba_x=1.0, ba_y=-0.8, ba_z=0.6, bg_x=20.0, bg_y=-15.0, bg_z=10.0,
             mg_xz=500.0, mg_yz=-700.0, sg_z=2000.0, phi0_x=150.0, phi0_y=-120.0, phi0_z=200.0,
             dv0_x=0.02, dv0_y=-0.01, dv0_z=0.015)
NOISE_FREE = FitSpec.build("ols", noise="white", sigma=0.01, robust="none")


def car_record() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``t, w, f, speed`` of a level car: forward acceleration, turns both ways (lateral force v w_z), a body
    oscillation."""
    t = np.arange(0.0, T_END, 1.0 / RATE)
    a_fwd = 2.0 * np.sin(2 * np.pi * t / 12.0) - 1.0 * np.sin(2 * np.pi * t / 5.0)
    speed = 8.0 + np.cumsum(a_fwd) / RATE
    w_z = np.radians(40.0) * np.sin(2 * np.pi * t / 9.0) * np.exp(-((t - 15.0) / 10.0) ** 2)
    w = np.column_stack([0.02 * np.sin(2 * np.pi * t / 1.7), 0.03 * np.cos(2 * np.pi * t / 2.3), w_z])
    f = np.column_stack([a_fwd, speed * w_z, np.full_like(t, 9.8)])
    return t, w, f, speed


def separate_car_window(tmp_path, model_name: str, truth: dict[str, float], errors=None, **options):
    """The car window with `truth`'s errors, separated noise-free by `model_name`. The body errors are the model's
    own law (``body_errors``) unless `errors(t, w, f, speed) -> (df, dw)` gives them; the flight carries the car's
    speed as ``ground_speed``."""
    t, w, f, speed = car_record()
    g = SITE.C.T @ normal_gravity_ecef(SITE.r_site)
    up = -g / np.linalg.norm(g)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    C_lb = np.column_stack([east, np.cross(up, east), up])  # body x, y level, z up
    r0, v0 = np.zeros(3), 8.0 * east
    clean = navigate_from(ImuData(t, w, f), SITE, dcm_to_quat(C_lb), r0, v0)
    model = casep.load_model(model_name)
    D = np.array([truth.get(n, 0.0) for n in model.names])
    instrument = np.array([0.0 if n.startswith(("phi0", "dv0")) else v for n, v in zip(model.names, D)])
    df, dw = body_errors(model, clean.q, f, w, t, instrument) if errors is None else errors(t, w, f, speed)
    phi0 = model.numeric("phi0") @ D
    C_ins = np.linalg.inv(corrected_attitude(np.eye(3), phi0)) @ C_lb  # INS = R(phi0)^-1 true
    dv0 = model.numeric("dv0") @ D
    nav = navigate_from(ImuData(t, w + dw, f + df), SITE, dcm_to_quat(C_ins), r0, v0 + dv0)
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    write_table(tel, {**nav.columns(), "ground_speed": speed})
    k = slice(None, None, int(RATE / TRK_RATE))
    write_table(trk, {"t": t[k], **{f"v_trk_{a}": clean.v[k][:, i] for i, a in enumerate("xyz")}})
    flight = read_flight_pair(tel, trk)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # noise-free: the given sigma far off
        return separate(flight, model_name, spec=NOISE_FREE, **options)


@pytest.fixture(scope="module")
def window(tmp_path_factory):
    """The car window with `TRUTH`'s errors separated by `MODEL`, once per module (the tests read it, never change
    it): the recovery test's result and the next test's model without the vertical accelerometer's cross-axis terms."""
    return separate_car_window(tmp_path_factory.mktemp("window"), MODEL, TRUTH)


def test_noise_free_recovery_on_a_simulated_car_window(window):
    res = window
    est = dict(zip(res.names, res.estimate))
    sd = dict(zip(res.names, res.std))
    z = {n: (est[n] - TRUTH[n]) / sd[n] for n in TRUTH}
    rel = {n: abs(est[n] - TRUTH[n]) / abs(TRUTH[n]) for n in TRUTH}
    # every coefficient determined (std below its truth at 1 cm/s), and recovered to the second-order remainder
    assert all(sd[n] < abs(TRUTH[n]) for n in TRUTH), sd
    assert max(abs(v) for v in z.values()) < 0.05, z
    assert max(rel.values()) < 0.01, rel


#: the window model with the vertical accelerometer's response to the horizontal specific force as well
WITH_MA_Z = '''"""strapdown9_vehicle_window + ma_zx, ma_zy."""
import casadi as ca

import casep
from casep.model.strapdown import strapdown_inputs


def build():
    m = casep.build_model("strapdown9_vehicle_window")
    m.name = "strapdown11_with_ma_z"
    C, fb, _w = strapdown_inputs(m)
    c = m.declare(ma_zx=("arcsec", 2000.0), ma_zy=("arcsec", 2000.0))
    m.set_accel_error(m.output("accel_error") + C @ ca.vertcat(0, 0, c.ma_zx * fb[0] + c.ma_zy * fb[1]))
    return m
'''


def test_the_vertical_accelerometer_cross_axis_terms_are_nearly_a_rotation_of_the_imu(tmp_path, window):
    """With ma_zx, ma_zy added, the same window is nearly singular: a rotation of the whole IMU about a level axis
    (mg_xz = e, ma_zx = -e, ba_x = e g, an attitude error) is seen only through the small pitch and roll rates and
    the horizontal force's own terms, so ma_zx, mg_xz and phi0_z get std hundreds of times those without it
    (the model file says why it leaves them out). The std of the one linear pass (``iterate=False``): the design's,
    which the singularity is about (ma_zx, mg_xz, phi0_z 2.04e4, 2.04e4, 2.04e4 against 89 and 78 without; iterated,
    the curvature of its draws doubles them, 4.0e4, for 6 times the CPU)."""
    path = tmp_path / "strapdown11_with_ma_z.py"
    path.write_text(WITH_MA_Z)
    res = separate_car_window(tmp_path, str(path), {**TRUTH, "ma_zx": 600.0, "ma_zy": -500.0}, iterate=False)
    without = window
    sd, sd0 = dict(zip(res.names, res.std)), dict(zip(without.names, without.std))
    assert sd["ma_zx"] > 1e4 and sd["mg_xz"] > 100.0 * sd0["mg_xz"] and sd["phi0_z"] > 100.0 * sd0["phi0_z"], sd


def test_speed_window_noise_free_recovery():
    """``strapdown7_speed_window``: the vertical accelerometer's error ``ba_z + kv_z speed`` written here from its
    definition (mg, deg/h converted by hand, not by the model), the car speeding up and slowing down between 6.5 and
    16 m/s: every coefficient back within 2 % and 0.15 std (deterministic: the largest, 0.10 std, is dv0_y, the same
    size with kv_z four times larger: the linearisation's remainder of the other errors on this record, which a
    model with fewer columns correlated with dv0_y leaves smaller)."""
    import math
    import tempfile
    from pathlib import Path

    truth = dict(ba_x=1.0, ba_y=-0.8, ba_z=0.6, kv_z=-0.05, bg_x=20.0, bg_y=-15.0, bg_z=10.0, phi0_x=150.0,
                 phi0_y=-120.0, phi0_z=200.0, dv0_x=0.02, dv0_y=-0.01, dv0_z=0.015)
    mg, deg_h = 9.80665e-3, math.pi / 180.0 / 3600.0

    def errors(t, w, f, speed):
        df = np.column_stack([np.full_like(t, truth["ba_x"]), np.full_like(t, truth["ba_y"]),
                              truth["ba_z"] + truth["kv_z"] * speed]) * mg
        dw = np.tile([truth["bg_x"], truth["bg_y"], truth["bg_z"]], (t.size, 1)) * deg_h
        return df, dw

    speed = car_record()[3]
    assert speed.min() < 7.0 and speed.max() > 15.0, (speed.min(), speed.max())
    for iterate in (False, True):  # the iteration corrects the record with the speed column too
        with tempfile.TemporaryDirectory() as d:
            res = separate_car_window(Path(d), "strapdown7_speed_window", truth, errors, iterate=iterate)
        assert res.success, res.message
        est, sd = dict(zip(res.names, res.estimate)), dict(zip(res.names, res.std))
        assert all(sd[n] < abs(truth[n]) for n in truth), sd
        assert max(abs(est[n] - truth[n]) / sd[n] for n in truth) < 0.15, (iterate, est)
        assert max(abs(est[n] - truth[n]) / abs(truth[n]) for n in truth) < 0.02, (iterate, est)
