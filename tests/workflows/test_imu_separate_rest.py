"""Raw-IMU separation: what the passes leave undetermined, where the first pass put it.

A 45 s MEMS rail launch (50 Hz; 8 s on the pad, 12 s at 6 g, a roll programme to 3 rad/s), ``strapdown15_axial``
errors of 10 mg, 100 deg/h, 1000 ppm/arcsec, 100 deg/h/g; tracking at 10 Hz with Gauss-Markov (0.05 m/s, tau 1 s)
plus white (0.03 m/s) noise: seed 6 of ``benchmarks/mems_rail_honesty.py``, whose first pass, its estimates
mostly linearisation error, put ``bg_x`` at -9380 deg/h (the truth -120).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.frames import LaunchSite
from casep.io.files import write_table
from casep.model.strapdown import body_errors
from casep.navigation import ImuData, check_imu, navigate
from casep.simulation.noise import ar1_noise, white_noise
from casep.simulation.strapdown import rail_launch
from casep.workflows.imu_separate import separate_imu

TRUTH = dict(ba_x=12.0, ba_y=-8.0, ba_z=15.0, sa_x=-3000.0, ma_yx=900.0, ma_zx=1200.0, bg_x=-120.0, bg_y=300.0,
             bg_z=180.0, sg_x=2000.0, mg_yx=-700.0, mg_zx=500.0, gg_xx=80.0, gg_yx=150.0, gg_zx=-60.0)
MODEL = "strapdown15_axial"
SITE = LaunchSite(69.29, 16.02, 20.0, 340.0, 8.0)
ALIGN = (0.0, 7.5)


@pytest.fixture(scope="module")
def rail(tmp_path_factory):
    """IMU and tracking files of the launch (tracking noise of seed 6) and the truth in declared magnitudes."""
    t = np.round(np.arange(0.0, 45.0, 0.02), 10)
    w, f = rail_launch(SITE, t, elevation_deg=84.0, boost_g=6.0, burn_s=12.0, coast_g=-0.3, lateral=(0.05, 0.7),
                       roll=(3.0, 6.0), pitch_rate=-0.04, yaw=(0.02, 0.5))
    nav = navigate(check_imu(ImuData(t, w, f)), SITE, ALIGN, heading_deg=SITE.azimuth_deg)
    model = casep.load_model(MODEL)
    df, dw = body_errors(model, nav.q, f, w, t - t[0], np.array([TRUTH[n] for n in model.names]))
    d = tmp_path_factory.mktemp("rail")
    imu, trk = d / "imu.csv", d / "trk.csv"
    write_table(imu, {"t": t, **{f"w_{c}": (w + dw)[:, i] for i, c in enumerate("xyz")},
                      **{f"fb_{c}": (f + df)[:, i] for i, c in enumerate("xyz")}})
    rng = np.random.default_rng(6)
    tk = t[::5]
    v = nav.v[::5] + ar1_noise(tk, 0.05, 1.0, rng) + white_noise(tk.size, 0.03, rng)
    write_table(trk, {"t": tk, **{f"v_trk_{c}": v[:, i] for i, c in enumerate("xyz")}})
    return imu, trk, np.array([TRUTH[n] / model.scales[n] for n in model.names])


def test_what_the_passes_leave_undetermined_is_not_left_where_the_first_pass_put_it(rail):
    """Before, the later passes left the undetermined combinations where the first pass put them (thousands of
    declared magnitudes out), and the 13 combinations stated, gradients about that point with their std drawn at the
    plausible size about it, were up to 16.4 std off the truth; the covariance's 6 directions better than their
    declared magnitudes gave a chi-square of 254. Now that part is taken back to the prior where the record fits as
    well there (``_Run.back_to_prior``), and the curvature draws the rest out to the prior as well
    (``_Run.determined_curvature``, its covariance ``rho^2 Q Q^T + u u^T``): each stated combination within 3.5 std
    (largest 2.8), and each of the covariance's well-determined directions too (largest 2.7; chi-square 19.6 on 6).
    """
    imu, trk, truth = rail
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = separate_imu(imu, trk, SITE, ALIGN, MODEL, heading_deg=SITE.azimuth_deg)
    assert out.success, out.message
    res = out.result
    scale = np.array([casep.load_model(MODEL).scales[n] for n in res.names])
    last = res.diagnostics["iterations"]["passes"][-1]
    assert last["curvature"]["checked"], last["curvature"]
    combos = last["determined"]
    assert len(combos) >= 10, len(combos)
    z = np.array([(c["estimate"] - np.dot(c["weights"], truth)) / c["std"] for c in combos])
    assert np.all(np.abs(z) < 3.5), z
    lam, V = np.linalg.eigh(np.asarray(res.covariance) / np.outer(scale, scale))
    good = lam < 1.0  # the directions the covariance says are better than their declared magnitudes
    zc = V[:, good].T @ (res.estimate / scale - truth) / np.sqrt(lam[good])
    assert good.sum() >= 4 and np.all(np.abs(zc) < 3.5), zc


def test_the_rest_shift_widens_the_solution_and_the_consider_total():
    """``_Run.with_rest_shift`` adds the rest's mean square shift ``R`` through
    :func:`casep.workflows.row_estimators.with_extra_covariance`, the one place a consider term widens a result: on a
    fit with 9 coefficients exactly dependent (``platform39_misalignment``, 1 Hz), the solution's covariance (what
    the iteration's step reads) gains ``R``, the coefficients without an estimate keep their NaN, the std the rest
    ``sqrt(std^2 + R_ii)``, and the running total of the consider terms is the one added before plus ``R``. Before,
    a covariance with a NaN was left as it was (no widening at all), and a finite one was widened beside the
    solution's and the total, which a covariance set anew then lost. The stated combinations, whose std hold the
    shift already (``curvature_shift``), gain the earlier consider term only, not ``R`` twice."""
    from types import SimpleNamespace

    from casep.simulation.simulate import simulate_flight
    from casep.workflows.imu_separate import _Run
    from casep.workflows.row_estimators import added_covariance, combinations_with_consider, with_extra_covariance

    truth = {"Kg0x": 3.0, "Ka0x": 1.2, "Ka1xy": 60.0, "Ka1yx": 40.0, "phi0z": 20.0, "phi0x": -10.0}
    sim = simulate_flight("paper", seed=4, rate=1.0, model="platform39_misalignment", truth=truth)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioning: not what this tests
        fit = casep.separate(sim.flight, sim.model)
    assert np.isnan(fit.std).sum() == 9 and fit.solution is not None
    sd = np.sqrt(np.nan_to_num(np.diag(fit.solution.covariance)))
    g0 = 0.3 * sd
    before = with_extra_covariance(fit, np.outer(g0, g0))  # a consider term added earlier (the omitted terms)
    rng = np.random.default_rng(5)
    B = rng.normal(size=(sd.size, 4)) * sd[:, None]  # four draws' shifts: R = mean(b b^T), rank 4
    R = B @ B.T / 4
    out = _Run.with_rest_shift(SimpleNamespace(rest_shift=R), before)
    np.testing.assert_allclose(out.solution.covariance - before.solution.covariance, R, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(added_covariance(out), np.outer(g0, g0) + R, rtol=1e-12)
    assert np.array_equal(np.isnan(out.std), np.isnan(fit.std))
    own = np.isfinite(fit.std)
    np.testing.assert_allclose(out.std[own], np.sqrt(before.std[own] ** 2 + np.diag(R)[own]), rtol=1e-10)
    factor = out.diagnostics["rest_shift_std_factor"]
    np.testing.assert_allclose([factor[n] for n in np.array(fit.names)[own]], out.std[own] / before.std[own])
    assert all(factor[n] is None for n in np.array(fit.names)[~own])  # JSON: null, not NaN
    # a stated combination (weights on D / scale) whose std hold the shift: only the earlier term is added
    scales = {n: 1.0 for n in fit.names}
    w = np.zeros(len(fit.names))
    w[list(fit.names).index("Kg0x")] = 1.0
    shift = float(np.sqrt(w @ R @ w))
    combo = {"weights": w.tolist(), "std": float(np.hypot(0.01, shift)), "curvature_shift": shift}
    got = combinations_with_consider([combo], out, scales)[0]["std"]
    assert got == pytest.approx(np.sqrt(combo["std"] ** 2 + (w @ g0) ** 2), rel=1e-12)
