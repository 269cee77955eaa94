"""Windows of a long record: the consistency statistics against closed forms, and the chain on a real car drive.

The real data: a 70 s cut of rtklibexplorer's drive_0708 (tests/data/car_drive/README.md): 35 s at rest
with the engine running, then the car pulls out. Two windows of 15 s are navigated and separated with the
Gauss-Markov plus white noise model (``noise="gmw"``, no robust filter: the default ``auto`` selection
costs twice the CPU; the whole drive with the default path is benchmarks/car_drive.py).
"""

from __future__ import annotations

import gzip
import json
import math
import shutil
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_dist

from casep.frames import LaunchSite
from casep.workflows.windows import PHI0_LINEAR_RAD, Window, consider_rows, gain_rows, window_consistency

DATA = Path(__file__).resolve().parents[1] / "data" / "car_drive"


def _window(x, C, s_end=None):
    names = ("a", "b")
    res = SimpleNamespace(names=names, estimate=np.asarray(x, float), covariance=np.asarray(C, float),
                          std=np.sqrt(np.diag(C)), success=True)
    site = LaunchSite(0.0, 0.0, 0.0, 0.0, 0.0)
    return Window(0.0, 1.0, site, res, 1, None, np.zeros((3, 0)) if s_end is None else np.asarray(s_end, float), names)


def test_two_windows_chi2_and_prediction_closed_form():
    """Two windows: chi2 = d^T (C1 + C2)^-1 d, and the prediction z = s d / sqrt(s (C1 + C2) s^T)."""
    C1 = np.array([[2.0, 0.3], [0.3, 1.0]])
    C2 = np.array([[0.5, -0.1], [-0.1, 3.0]])
    x1, x2 = np.array([1.0, -2.0]), np.array([2.5, 0.5])
    s = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    out = window_consistency([_window(x1, C1, s), _window(x2, C2, s)], ("a", "b"))
    d = x1 - x2
    assert out["chi2"] == pytest.approx(d @ np.linalg.solve(C1 + C2, d), rel=1e-12)
    assert out["dof"] == 2
    assert out["p_value"] == pytest.approx(chi2_dist.sf(out["chi2"], 2), rel=1e-12)
    z = np.abs(s @ d / np.sqrt(np.einsum("ap,pq,aq->a", s, C1 + C2, s)))
    assert out["within_1_std"] == pytest.approx(np.mean(z <= 1.0))
    assert out["median_abs_z"] == pytest.approx(np.median(np.concatenate([z, z])))


def test_chi2_calibrated_on_consistent_windows():
    """Windows drawn from one truth with their own covariances: chi2/dof near 1, 5 % of p below 0.05 (seeded)."""
    rng = np.random.default_rng(7)
    pvals, ratios = [], []
    for _ in range(200):
        ws = []
        for _k in range(5):
            A = rng.normal(size=(2, 2))
            C = A @ A.T + 0.2 * np.eye(2)
            ws.append(_window(rng.multivariate_normal([3.0, -1.0], C), C))
        out = window_consistency(ws, ("a", "b"))
        pvals.append(out["p_value"])
        ratios.append(out["chi2"] / out["dof"])
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.1)  # std of the mean of 200: 0.035
    assert 0.02 < np.mean(np.array(pvals) < 0.05) < 0.09


def test_instability_calibrates_chi2_of_wandering_coefficients():
    """Windows whose true coefficients wander by a known std between windows: without it chi2/dof is far
    above 1, with it (the same std, given, not estimated) near 1 and p-values uniform (seeded)."""
    rng = np.random.default_rng(11)
    wander = {"a": 2.0, "b": 0.5}
    plain, given, pvals = [], [], []
    for _ in range(200):
        ws = []
        for _k in range(5):
            C = np.diag([0.3, 0.2]) ** 2
            truth = np.array([3.0, -1.0]) + rng.normal(size=2) * [wander["a"], wander["b"]]
            ws.append(_window(rng.multivariate_normal(truth, C), C))
        plain.append(window_consistency(ws, ("a", "b"))["chi2"] / 8)
        out = window_consistency(ws, ("a", "b"), instability=wander)
        given.append(out["chi2"] / out["dof"])
        pvals.append(out["p_value"])
    assert np.mean(plain) > 10.0
    assert np.mean(given) == pytest.approx(1.0, abs=0.1)  # std of the mean of 200: 0.035
    assert 0.02 < np.mean(np.array(pvals) < 0.05) < 0.09
    assert out["instability"] == wander
    with pytest.raises(ValueError, match="instability"):
        window_consistency(ws, ("a", "b"), instability={"a": -1.0})


def test_consider_two_windows_closed_form_and_common_gain_adds_nothing():
    """Two windows with left-out terms: chi2 = d^T (C1 + C2 + dA P dA^T)^-1 d (dA = A1 - A2), the prediction std
    the same; a gain common to both windows leaves chi2 as without it."""
    C1 = np.array([[2.0, 0.3], [0.3, 1.0]])
    C2 = np.array([[0.5, -0.1], [-0.1, 3.0]])
    x1, x2 = np.array([1.0, -2.0]), np.array([2.5, 0.5])
    s = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    A1, A2 = np.array([[1.0, 0.5, 0.0], [0.0, -1.0, 2.0]]), np.array([[-0.5, 0.0, 1.0], [1.5, 0.2, 0.0]])
    P = np.diag([0.4, 1.0, 0.25])
    ws = [_window(x1, C1, s), _window(x2, C2, s)]
    out = window_consistency(ws, ("a", "b"), consider=([A1, A2], P))
    d, dA = x1 - x2, A1 - A2
    Cd = C1 + C2 + dA @ P @ dA.T
    assert out["chi2"] == pytest.approx(d @ np.linalg.solve(Cd, d), rel=1e-10)
    z = np.abs(s @ d / np.sqrt(np.einsum("ap,pq,aq->a", s, Cd, s)))
    assert out["median_abs_z"] == pytest.approx(np.median(np.concatenate([z, z])), rel=1e-12)
    assert out["chi2_per_coefficient"]["a"] == pytest.approx(d[0] ** 2 / Cd[0, 0], rel=1e-10)
    same = window_consistency(ws, ("a", "b"), consider=([A1, A1], P))
    assert same["chi2"] == pytest.approx(window_consistency(ws, ("a", "b"))["chi2"], rel=1e-10)
    with pytest.raises(ValueError, match="consider"):
        window_consistency(ws, ("a", "b"), consider=([A1], P))


def test_consider_calibrates_chi2_of_left_out_terms():
    """Windows whose estimates carry left-out terms c (the same c in every window, a gain A_k per window): without
    the consider covariance chi2/dof is far above 1, with it near 1 and p-values uniform (seeded)."""
    rng = np.random.default_rng(13)
    gains = [rng.normal(size=(2, 3)) for _ in range(5)]
    P = np.diag([1.0, 0.5, 2.0]) ** 2
    C = np.diag([0.3, 0.2]) ** 2
    plain, given, pvals = [], [], []
    for _ in range(200):
        c = rng.multivariate_normal(np.zeros(3), P)
        ws = [_window(rng.multivariate_normal(np.array([3.0, -1.0]) + A @ c, C), C) for A in gains]
        plain.append(window_consistency(ws, ("a", "b"))["chi2"] / 8)
        out = window_consistency(ws, ("a", "b"), consider=(gains, P))
        given.append(out["chi2"] / out["dof"])
        pvals.append(out["p_value"])
    assert np.mean(plain) > 10.0
    assert np.mean(given) == pytest.approx(1.0, abs=0.1)  # std of the mean of 200: 0.035
    assert 0.02 < np.mean(np.array(pvals) < 0.05) < 0.09


def test_gain_rows_is_the_dense_gls_refit_of_the_left_out_terms():
    """The consider gain under Gauss-Markov (plus white) noise per axis on uneven times: against the GLS solution
    with the rows' covariance written out as a dense matrix (closed form), and a noise-free refit of data holding
    ``S_w x + S_c c`` moves the estimate from ``x`` by exactly ``A c``; white noise is ordinary least squares."""
    from casep.noise.model import NoiseModel

    rng = np.random.default_rng(5)
    N, n, m = 60, 4, 3
    t = np.cumsum(rng.uniform(0.05, 0.3, N))
    S_w, S_c = rng.normal(size=(N, 3, n)), rng.normal(size=(N, 3, m))
    S_w[:, :, 0] *= 1e3  # columns of very different sizes, as natural units give
    noise = NoiseModel.gauss_markov((0.4, 1.5, 0.8), scale=(1.0, 2.5, 0.5), share=(0.3, 0.0, 0.6))
    A = gain_rows(S_w, S_c, t, noise)
    Sigma = np.zeros((3 * N, 3 * N))  # rows in sample-major order (sample k, axis a) -> 3 k + a
    dt = np.abs(t[:, None] - t[None, :])
    for a in range(3):
        corr = (1.0 - noise.share[a]) * np.exp(-dt / noise.tau[a]) + noise.share[a] * np.eye(N)
        Sigma[a::3, a::3] = noise.scale[a] ** 2 * corr
    Sw, Sc = S_w.reshape(3 * N, n), S_c.reshape(3 * N, m)
    Si = np.linalg.inv(Sigma)
    dense = np.linalg.solve(Sw.T @ Si @ Sw, Sw.T @ Si @ Sc)
    assert np.allclose(A, dense, rtol=1e-8, atol=1e-12 * np.abs(dense).max())
    x, c = rng.normal(size=n), rng.normal(size=m)
    y = Sw @ x + Sc @ c
    refit = np.linalg.solve(Sw.T @ Si @ Sw, Sw.T @ Si @ y)
    assert np.allclose(refit - x, A @ c, rtol=1e-8, atol=1e-10)
    ols = np.linalg.lstsq(Sw, Sc, rcond=None)[0]
    assert np.allclose(gain_rows(S_w, S_c, t), ols, rtol=1e-8, atol=1e-12 * np.abs(ols).max())


@pytest.fixture(scope="module")
def car(tmp_path_factory):
    """The chain on the real cut: align 0-30 s, two 15 s windows from 36 s."""
    import pandas as pd

    from casep.navigation.imu import read_imu
    from casep.workflows.windows import separate_windows

    tmp = tmp_path_factory.mktemp("car")
    with gzip.open(DATA / "imu.csv.gz", "rb") as src, open(tmp / "imu.csv", "wb") as dst:
        shutil.copyfileobj(src, dst)
    trk = pd.read_csv(DATA / "tracking.csv")
    site = LaunchSite(float(trk.lat[0]), float(trk.lon[0]), float(trk.h[0]), 0.0, 0.0)
    imu = read_imu(tmp / "imu.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the fits' own warnings (noise, whiteness) are not what is tested here
        res = separate_windows(imu, DATA / "tracking.csv", site, (0.0, 30.0), length=15.0, start=36.0,
                               attitude_passes=2, fit_options={"noise": "gmw", "robust": None},
                               consider="strapdown33")
    return imu, site, res


def test_car_drive_cut(car):
    """One test on the cut (its fixture computed once, whichever xdist worker runs it): heading, agreement, pad."""
    _heading_from_the_course(car)
    _windows_agree(car)
    _vertical_accelerometer_bias_is_the_pads(car)
    _consider_gains_of_a_car_window(car)


def _heading_from_the_course(car):
    """The heading comes from the course in the first window; the initial attitude errors left are linear."""
    _, _, res = car
    assert len(res.windows) == 2
    assert res.windows[0].heading_from_course_deg is not None and res.windows[1].heading_from_course_deg is None
    for w in res.windows:
        est = dict(zip(w.result.names, w.result.estimate))
        sd = dict(zip(w.result.names, w.result.std))
        phi0 = np.radians(np.array([est[f"phi0_{i}"] for i in "xyz"]) / 3600.0)
        phi0_sd = np.radians(np.array([sd[f"phi0_{i}"] for i in "xyz"]) / 3600.0)
        assert np.all(np.abs(phi0) <= np.maximum(PHI0_LINEAR_RAD, 3.0 * phi0_sd)), (w.t_start, phi0, phi0_sd)
        rms = float(np.sqrt(np.nanmean(np.asarray(w.result.residuals) ** 2)))
        assert rms < 0.1, (w.t_start, rms)  # m/s: the RTK velocity noise is 0.04 m/s; a wrong heading leaves metres


def _windows_agree(car):
    """The two windows' biases agree by chi-square (6 dof) and predict each other's dv at the end within 2 std."""
    _, _, res = car
    c = res.consistency
    assert c["dof"] == 6 and c["used"] == 2
    assert res.success and res.status == 0 and "they agree" in res.message
    assert json.loads(json.dumps(res.to_dict()))["consistency"]["dof"] == 6
    assert len(res.text().splitlines()) == 3
    assert c["agree"] and c["p_value"] > 0.01, c
    assert c["within_2_std"] >= 4 / 6, c  # 2 ordered pairs x 3 axes
    acc = window_consistency(res.windows, ("ba_x", "ba_y", "ba_z"))
    assert acc["p_value"] > 0.01, acc


def _vertical_accelerometer_bias_is_the_pads(car):
    """The windows' bias along the pad's vertical is what the pad shows by itself: |f| - g (an independent figure)."""
    from casep.gravity import normal_gravity_ecef

    imu, site, res = car
    pad = imu.t <= 30.0
    f = imu.f[pad].mean(axis=0)
    excess_mg = (np.linalg.norm(f) - np.linalg.norm(normal_gravity_ecef(site.r_site))) / 9.80665e-3
    up = f / np.linalg.norm(f)
    for w in res.windows:
        est = dict(zip(w.result.names, w.result.estimate))
        sd = dict(zip(w.result.names, w.result.std))
        ba = np.array([est[f"ba_{i}"] for i in "xyz"])
        ba_sd = float(np.sqrt(np.sum((up * np.array([sd[f"ba_{i}"] for i in "xyz"])) ** 2)))
        # the pad's mean is known to ~0.002 m/s^2 (0.2 mg); engine vibration makes it 0.5 mg at most
        assert abs(up @ ba - excess_mg) < 3.0 * math.hypot(ba_sd, 0.5), (w.t_start, up @ ba, excess_mg, ba_sd)


def _consider_gains_of_a_car_window(car):
    """The windows' consider gains of strapdown33's other terms: with the specific force near g on z all along, the
    z accelerometer's scale factor is a bias of ``mean(fb_z) / g0`` (1e-3 mg per ppm) and the z gyro's sensitivity
    to fb_z a gyro bias of ``mean(fb_z) / g0`` (deg/h per deg/h/g); the gains go into the comparison's covariance."""
    imu, _, res = car
    for w in res.windows:
        assert w.consider_gain is not None and w.consider_gain.shape == (len(w.result.names), 27)
        assert "sa_z" in w.consider_names and "ba_z" not in w.consider_names
        sel = (imu.t >= w.t_start) & (imu.t <= w.t_end)
        fz = float(np.mean(imu.f[sel, 2])) / 9.80665
        gain = dict(zip(w.consider_names, w.consider_gain[list(w.result.names).index("ba_z")]))
        assert gain["sa_z"] == pytest.approx(fz * 1e-3, rel=0.01), (w.t_start, gain["sa_z"], fz)
        gain = dict(zip(w.consider_names, w.consider_gain[list(w.result.names).index("bg_z")]))
        assert gain["gg_zz"] == pytest.approx(fz, rel=0.03), (w.t_start, gain["gg_zz"], fz)
    names = ("ba_x", "ba_y", "ba_z")
    gains = consider_rows(res.windows, names)
    assert [g.shape for g in gains] == [(3, 27)] * 2
    out = window_consistency(res.windows, names, consider=(gains, np.diag(np.full(27, 1e-6))))
    assert out["chi2"] == pytest.approx(window_consistency(res.windows, names)["chi2"], rel=1e-3)


def test_vibration_power_is_the_band_s_share_of_the_specific_force():
    """:func:`vibration_power` on 30 s at 100 Hz: a 25 Hz sine of amplitude 0.4 m/s^2 on x (in the band) gives its
    power ``A^2 / 2`` = 0.08 (m/s^2)^2 to 2 %, a 2 Hz manoeuvre of 3 m/s^2 on y (below it) and gravity on z add less
    than 1e-3 of it; too few samples, or a band beyond the rate, are errors. And the pooled instability's options
    are checked before any work."""
    from casep.navigation.imu import ImuData
    from casep.workflows.windows import separate_windows, vibration_power

    t = np.arange(3000) * 0.01
    f = np.column_stack([0.4 * np.sin(2 * np.pi * 25.0 * t), 3.0 * np.sin(2 * np.pi * 2.0 * t), np.full(t.size, 9.81)])
    imu = ImuData(t, np.zeros((t.size, 3)), f)
    assert abs(vibration_power(imu, 0.0, 30.0) / 0.08 - 1.0) < 0.02
    calm = ImuData(t, np.zeros((t.size, 3)), f * [0.0, 1.0, 1.0])
    assert vibration_power(calm, 0.0, 30.0) < 0.08e-3
    with pytest.raises(ValueError, match="samples"):
        vibration_power(imu, 0.0, 0.3)
    with pytest.raises(ValueError, match="band"):
        vibration_power(imu, 0.0, 30.0, (10.0, 60.0))
    site = LaunchSite(0.0, 0.0, 0.0, 0.0, 0.0)
    for kw, said in (({"imu_instability_pool": True}, "correlation time"),
                     ({"imu_instability_measure": "speed"}, "imu_instability_pool=True"),
                     ({"imu_instability_tau": 20.0, "imu_instability_pool": True, "imu_instability_measure": "x"},
                      "'vibration', 'speed'")):
        with pytest.raises(ValueError, match=said):
            separate_windows(imu, "no_such_file.csv", site, (0.0, 10.0), **kw)


def _white_rows(rng, k: tuple[float, float], M: int = 100, dt: float = 0.25):
    """One simulated window's rows for a pooled white scale: a velocity random walk on x, y (the "accelerometers'"
    part, 10 mm/s per sqrt(s) per unit scale) and on z (the "gyros'", 10 mm/s), drawn at the scales `k`, under 0.02 m/s
    of white tracking noise, an offset and a ramp per axis fitted; its known states with both walks as parts."""
    from casep.noise.fit import Reml, estimable_basis
    from casep.noise.known import KnownStates, RemlRows, TrackingParameters
    from casep.regression.problem import Problem

    unit = [np.diag([0.01**2, 0.01**2, 0.0]) * dt, np.diag([0.0, 0.0, 0.01**2]) * dt]
    step = np.sqrt(k[0] * np.diag(unit[0]) + k[1] * np.diag(unit[1]))
    v = np.zeros((M, 3))
    v[1:] = np.cumsum(step * rng.standard_normal((M - 1, 3)), axis=0)
    t = dt * np.arange(M)
    S = np.zeros((M, 3, 6))
    S[:, :, :3] = np.eye(3)
    S[:, :, 3:] = t[:, None, None] * np.eye(3)
    pb = Problem.from_arrays(S, S @ rng.normal(size=6) + v + 0.02 * rng.standard_normal((M, 3)), t)
    parts = []
    for u in unit:
        Q = np.zeros((M, 3, 3))
        Q[1:] = u
        parts.append((Q, np.zeros((3, 3))))
    known = KnownStates(np.tile(np.eye(3), (M, 1, 1)), np.zeros((M, 3, 3)), np.tile(np.eye(3), (M, 1, 1)),
                        np.zeros((3, 3)), tuple(parts))
    start = TrackingParameters((0.0,) * 3, (None,) * 3, (1e-3,) * 3).model("white", "reml")
    return RemlRows(np.stack(Reml(pb, estimable_basis(pb)).Z, axis=1), t, start, known, (1.0, 1.0))


def test_a_pooled_white_scale_separates_every_window_again_at_its_densities():
    """``separate_windows(imu_white_pool=True)``'s pooling (:func:`casep.workflows.windows._pool_instability` with the
    densities at rest): three windows whose random walks are 2.5 and 0.5 times the densities given pool to scales
    whose 95 % intervals hold them (seeds 2-5 do, seed 1 misses the gyros' 0.5 with 0.76-2.8: the interval is the
    conditional one; seed 3 here), every window is separated again once, with the
    densities at rest times ``sqrt(k)`` per sensor and no instability, and the record states the scales, their
    intervals and ``-2 l_R`` at the densities at rest (above the best); a window that failed is left as it was. The
    gyros' scale alone (``imu_white_pool="gyro"``, the accelerometers' part in the known noise at the density given)
    holds its truth too, with the accelerometers' density left as given. The options' errors are checked before any
    work."""
    from casep.navigation.imu import ImuData
    from casep.workflows.windows import _pool_instability, separate_windows

    rng = np.random.default_rng(3)
    k = (2.5, 0.5)
    rows = [_white_rows(rng, k) for _ in range(3)]
    ok = SimpleNamespace(success=True)
    windows = [SimpleNamespace(result=ok, t_start=30.0 * j) for j in range(3)]
    windows.append(SimpleNamespace(result=SimpleNamespace(success=False), t_start=90.0))
    pooled = [(f"nav{j}", f"site{j}", r, 1.0) for j, r in enumerate(rows)] + [("nav3", "site3", None, 1.0)]
    calls = []
    at_rest = np.array([1e-2, 1e-2, 1e-2, 1e-4, 1e-4, 1e-4])

    def again(nav, site, given, noise):
        calls.append((nav, given, noise))
        return SimpleNamespace(success=True, again=True)

    out = _pool_instability(windows, pooled, None, None, again, at_rest)
    got = out["white_variance_scale"]
    for truth, (lo, hi) in zip(k, out["white_variance_scale_interval"]):
        assert lo <= truth <= hi, out
    assert [c[0] for c in calls] == ["nav0", "nav1", "nav2"] and all(c[1] is None for c in calls)
    for c in calls:
        np.testing.assert_array_equal(c[2], at_rest * np.sqrt(np.repeat(got, 3)))
    assert all(w.result.again for w in windows[:3]) and windows[3].result.success is False
    assert out["neg2_reml_at_rest_density"] > out["pooled"]["neg2_reml"] and out["not_pooled"] == [90.0]
    # the gyros' scale only ("gyro"): the rows hold the accelerometers' part at the density given, the scale 1
    from casep.noise.known import KnownStates, RemlRows

    one = [RemlRows(r.X, r.t, r.start, KnownStates(r.known.T, r.known.Q + r.known.parts[0][0], r.known.H,
                                                   r.known.P0, r.known.parts[1:]), (1.0,)) for r in rows]
    calls.clear()
    windows = [SimpleNamespace(result=ok, t_start=30.0 * j) for j in range(3)]
    out = _pool_instability(windows, [(f"nav{j}", "s", r, 1.0) for j, r in enumerate(one)], None, None, again,
                            at_rest, gyro_only=True)
    k_g = out["white_variance_scale"][1]
    assert out["white_variance_scale"][0] == 1.0 and out["white_variance_scale_interval"][0] == [1.0, 1.0]
    lo, hi = out["white_variance_scale_interval"][1]
    assert lo <= k[1] <= hi and len(calls) == 3, out
    np.testing.assert_array_equal(calls[0][2], at_rest * np.sqrt([1.0] * 3 + [k_g] * 3))
    imu = ImuData(np.arange(100) * 0.01, np.zeros((100, 3)), np.zeros((100, 3)))
    site = LaunchSite(0.0, 0.0, 0.0, 0.0, 0.0)
    for kw, said in (({"imu_white_pool": "accel"}, "'gyro' or False"),
                     ({"imu_white_pool": True, "imu_noise_from_pad": False}, "imu_noise_from_pad=True"),
                     ({"imu_white_pool": True, "imu_instability_tau": 20.0}, "imu_instability_pool=True")):
        with pytest.raises(ValueError, match=said):
            separate_windows(imu, "no_such_file.csv", site, (0.0, 0.5), **kw)
