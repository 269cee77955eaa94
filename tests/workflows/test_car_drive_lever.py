"""The lever-arm correction of benchmarks/car_drive_windows.py: each window's estimate less its consider gain on the
antenna's lever arm times the known arm, and the consider covariance of the left-out terms and the arm."""

from __future__ import annotations

import types

import numpy as np
import pytest


@pytest.fixture(scope="module")
def cdw():
    from conftest import benchmark_module

    with benchmark_module("car_drive_windows", prefix="car_drive") as mod:
        yield mod


def _window(names, estimate, gain, consider_names):
    res = types.SimpleNamespace(names=tuple(names), estimate=np.asarray(estimate, float),
                                covariance=np.eye(len(names)), success=True)
    return types.SimpleNamespace(result=res, sv_end=np.zeros((3, len(names))), sv_names=tuple(names), raw={},
                                 t_start=0.0, consider_gain=np.asarray(gain, float),
                                 consider_names=tuple(consider_names))


def test_noise_free_linear_fit_recovered_exactly(cdw):
    """Data that hold ``S_w x + S_l l`` (no noise): the least-squares fit of ``S_w`` alone gives ``x + A l`` with
    ``A`` the consider gain (:func:`casep.workflows.windows.gain_rows`); the correction returns ``x`` to 1e-10, and
    the consider covariance is LEFT_OUT_STD's for the left-out terms and LEVER_ARM_STD's for the arm, in the
    gain's column order. A run without lever-arm columns gives None."""
    from casep.workflows.windows import gain_rows

    rng = np.random.default_rng(3)
    names = ("ba_x", "ba_y", "ba_z", "bg_x", "bg_y", "bg_z", "phi0_x")
    terms = ("sa_x", "ka2_x", "l_x", "l_y", "l_z")  # ka2_x: held by the consider model, no P_c figure
    N = 40
    S_w, S_c = rng.normal(size=(N, 3, len(names))), rng.normal(size=(N, 3, len(terms)))
    x = rng.normal(size=len(names))
    arm = np.array(list(cdw.LEVER_ARM_IMU.values()))
    y = np.einsum("nap,p->na", S_w, x) + np.einsum("nap,p->na", S_c[:, :, 2:], arm)
    est = np.linalg.lstsq(S_w.reshape(-1, len(names)), y.ravel(), rcond=None)[0]
    A = gain_rows(S_w, S_c, np.arange(N, dtype=float))
    out = cdw.lever_arm_corrected([_window(names, est, A, terms)])
    assert out is not None
    ws, P_c = out
    np.testing.assert_allclose(ws[0].result.estimate, x, atol=1e-10)
    assert ws[0].consider_names == ("sa_x", "l_x", "l_y", "l_z")
    np.testing.assert_allclose(ws[0].consider_gain, A[:, [0, 2, 3, 4]], rtol=0, atol=0)
    np.testing.assert_allclose(np.diag(P_c), [cdw.LEFT_OUT_STD["sa_x"] ** 2] + [cdw.LEVER_ARM_STD**2] * 3)
    assert cdw.lever_arm_corrected([_window(names, est, A[:, :2], terms[:2])]) is None
