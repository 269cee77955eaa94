"""Steps between consecutive rate samples: found, bounded in closed form, and carried as a velocity / attitude step.

A sampled record does not say where in ``[t_k, t_k+1]`` a step of the signal fell; the trapezoid takes the middle,
and the truth is anywhere within ``(x_k+1 - x_k) h / 2`` of it. The bound is checked against an exact integral of a
step at the interval's end, and the consider column of the separation (:func:`casep.workflows.imu_separate.step_rows`)
against an independent navigation of the record sampled 50 times finer.
"""

from __future__ import annotations

import math
import re
from types import SimpleNamespace

import numpy as np
import pytest

from casep.frames import LaunchSite
from casep.navigation.imu import ImuData, check_imu, sample_steps
from casep.navigation.navigator import navigate_from

SITE = LaunchSite(28.5, -80.6, 10.0, 90.0, 0.0)
H = 0.05
F0, F1 = np.array([9.8, 0.0, 0.0]), np.array([27.5, 0.3, -0.2])  # body specific force before / after, m/s^2
W0, W1 = np.zeros(3), np.array([0.0, 0.01, -0.03])  # body rate before / after, rad/s


def _record(h: float, t_end: float, t_step: float, mid: bool) -> ImuData:
    """Body rate and specific force stepping at `t_step` (a sample time), sampled every `h`: the sample at the step
    reads the value after it (`mid` False, a simulator's right-continuous sampling) or the mean of both sides."""
    n = int(round(t_end / h)) + 1
    t = np.arange(n) * h
    after = t >= t_step - 1e-9
    f = np.where(after[:, None], F1, F0)
    w = np.where(after[:, None], W1, W0)
    at = np.abs(t - t_step) < 1e-9
    if mid:
        f[at], w[at] = 0.5 * (F0 + F1), 0.5 * (W0 + W1)
    return ImuData(t, w, f, "rates", source="<step>")


def test_trapezoid_across_a_step_is_within_the_closed_form_bound():
    """The trapezoid's integral of a step over one interval differs from the exact one (the step at either end) by
    exactly ``|x_k+1 - x_k| h / 2``, the bound :func:`sample_steps` states."""
    h, x0, x1 = 0.05, 9.8, 27.5
    trapezoid = 0.5 * (x0 + x1) * h
    for exact in (x0 * h, x1 * h):  # the step at the interval's end, or at its start
        assert abs(trapezoid - exact) == pytest.approx(abs(x1 - x0) * h / 2, rel=1e-12)
    rec = _record(H, 2.0, 1.0, mid=False)
    st = sample_steps(rec.t, rec.w, rec.f)
    assert st.k.tolist() == [19]  # the interval 0.95 .. 1.0 s
    assert st.velocity[0] == pytest.approx(np.linalg.norm(F1 - F0) * H / 2, rel=1e-12)
    assert st.attitude[0] == pytest.approx(np.linalg.norm(W1 - W0) * H / 2, rel=1e-12)
    np.testing.assert_allclose(st.df[0], F1 - F0, rtol=1e-12)


def test_noise_ramps_and_kinks_are_not_steps():
    """White noise (20 000 samples), a ramp, a kink and a smooth curve hold no step; a step in noise is found."""
    rng = np.random.default_rng(5)
    n = 20000
    t = np.arange(n) * 0.00125
    f = np.column_stack([9.8 + 0.05 * rng.standard_normal(n), 0.05 * rng.standard_normal(n),
                         np.where(t > 10, 3.0 * (t - 10), 0.0) + np.sin(t)])  # a kink at 10 s, then a ramp
    w = 0.002 * rng.standard_normal((n, 3))
    assert sample_steps(t, w, f).k.size == 0
    f[12000:, 0] += 2.0  # 40 times the noise
    st = sample_steps(t, w, f)
    assert st.k.tolist() == [11999]
    assert st.velocity[0] == pytest.approx(2.0 * 0.00125 / 2, rel=0.2)


def test_a_sample_at_the_mean_is_no_step():
    """The sample at the step holding the mean of both sides is what the trapezoid integrates exactly: no step."""
    rec = _record(H, 2.0, 1.0, mid=True)
    assert sample_steps(rec.t, rec.w, rec.f).k.size == 0


def test_step_column_against_a_finer_navigation():
    """A step at the end of a sampled interval (the sample after it reads the new value) is the bound's extreme,
    ``s = -1`` in :func:`step_rows`: the coarse navigation less a navigation of the same motion sampled 50 times
    finer (the step at a sample holding the mean: integrated exactly) is ``-sqrt(3)`` times the step's consider
    column (velocity step plus the attitude step turning the specific force integrated since), to 1 % of it."""
    from casep.workflows.imu_separate import step_rows

    t_step, t_end = 1.0, 20.0
    coarse = check_imu(_record(H, t_end, t_step, mid=False))
    # the coarse record's truth: the step right after t = 0.95 s, sampled finely with the mean at that sample
    fine = check_imu(_record(H / 50, t_end, t_step - H, mid=True))
    q0, r0, v0 = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), np.zeros(3)
    nav_c = navigate_from(coarse, SITE, q0, r0, v0)
    nav_f = navigate_from(fine, SITE, q0, r0, v0)
    assert nav_f.steps_said is None
    assert re.search(r"1 step .*t = 0.95 .. 1 s .*within \+-0.44\d* m/s", nav_c.steps_said)  # |F1 - F0| h / 2
    assert "steps      " in nav_c.text()
    t = nav_c.t[nav_c.t > 1.5]
    diff = nav_c.v[nav_c.t > 1.5] - np.column_stack([np.interp(t, nav_f.t, nav_f.v[:, c]) for c in range(3)])
    cols = step_rows(coarse, nav_c, SimpleNamespace(t=t))
    assert cols is not None and cols.shape == (t.size, 3, 1)
    predicted = -math.sqrt(3.0) * cols[:, :, 0]
    assert float(np.linalg.norm(predicted[-1] - predicted[0])) > 0.3  # the attitude step's part grows, m/s
    np.testing.assert_allclose(diff, predicted, atol=0.01 * float(np.max(np.abs(predicted))))


def test_split_steps_makes_a_simulated_step_exact():
    """A record sampled right-continuous at a step that falls on a sample (a simulator's lift-off): read as is, its
    navigation is off by ``|dF| h / 2`` for the rest of the record; with :func:`split_steps` (the sample after the step
    the mean of its sides) it holds no step and navigates to the finer navigation of the same motion within 1e-3 of
    that (the attitude step too), and the record without steps is left as it was."""
    from casep.navigation.imu import split_steps

    rec = _record(H, 20.0, 1.0, mid=False)
    w, f = split_steps(rec.t, rec.w, rec.f)
    assert sample_steps(rec.t, w, f).k.size == 0
    assert np.count_nonzero(np.any(w != rec.w, axis=1) | np.any(f != rec.f, axis=1)) == 1  # the sample at 1.0 s
    fine = check_imu(_record(H / 50, 20.0, 1.0, mid=True))  # the step at 1.0 s exactly
    q0, r0, v0 = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), np.zeros(3)
    nav_f = navigate_from(fine, SITE, q0, r0, v0)
    ref = np.column_stack([np.interp(rec.t, nav_f.t, nav_f.v[:, c]) for c in range(3)])[rec.t > 1.5]
    as_is = navigate_from(check_imu(_record(H, 20.0, 1.0, mid=False)), SITE, q0, r0, v0).v[rec.t > 1.5]
    split = navigate_from(check_imu(ImuData(rec.t, w, f, "rates")), SITE, q0, r0, v0).v[rec.t > 1.5]
    bound = np.linalg.norm(F1 - F0) * H / 2
    assert np.linalg.norm(as_is[0] - ref[0]) == pytest.approx(bound, rel=0.02)
    assert float(np.max(np.linalg.norm(split - ref, axis=1))) < 1e-3 * bound
    same = _record(H, 20.0, 1.0, mid=True)
    w2, f2 = split_steps(same.t, same.w, same.f)
    assert np.array_equal(w2, same.w) and np.array_equal(f2, same.f)
