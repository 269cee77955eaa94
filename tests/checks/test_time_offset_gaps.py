"""The time-offset rule across a telemetry gap: the velocity and attitude jump an INS navigated across lost
IMU samples may carry is not an offset, even at a burnout inside the gap; a real offset is still found."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from casep.checks.plausibility import OFFSET_T, check_fit
from casep.checks.time_offset import GRAVITY_LAUNCH, gap_columns, time_offset_test
from casep.exceptions import CasepWarning, TimeOffsetWarning
from casep.regression.problem import Problem
from casep.units import G0

GAP = (19.45, 20.55)  # the rows inside are left out (the telemetry has none); burnout at t = 20 s
OFFSET = 0.040  # s


def _flight(offset: float = 0.0, seed: int = 3) -> tuple[Problem, np.ndarray]:
    """Tracking rows at 10 Hz from lift-off (t = 8 s: a 6 g boost to 20 s, then -0.3 g, a lateral wobble), the
    rows of the gap left out; S: an initial velocity error, accelerometer biases and the scale factor along the
    thrust; dv: white noise 0.03 m/s, the jump a bridged gap leaves (1 m/s along the thrust, whose step the
    bridge cannot place, and 1 mrad about z), and the offset's ``a(t) dt``. ``a(t)`` is then a constant and a
    step at the burnout: the jump is an offset to a rule that does not know the gap."""
    t = np.round(np.arange(8.0, 45.0, 0.1), 10)
    t = t[(t <= GAP[0]) | (t >= GAP[1])]
    up = np.array([0.1, 0.99, 0.0]) / np.linalg.norm([0.1, 0.99, 0.0])
    f = np.where(t < 20.0, 6.0 * G0, -0.3 * G0)[:, None] * up
    f[:, 2] += 2.0 * np.sin(0.7 * t)
    F = np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t)[:, None], axis=0)])
    S = np.zeros((t.size, 3, 7))
    S[:, :, :3] = np.eye(3)  # initial velocity error
    S[:, :, 3:6] = (t - t[0])[:, None, None] * np.eye(3)  # accelerometer biases: dv = b t
    S[:, :, 6] = np.einsum("ki,i->k", F, up)[:, None] * up  # scale factor along the thrust
    jump = gap_columns(t, f, [GAP]) @ np.r_[1.0 * up, 0.0, 0.0, 1e-3]  # the thrust's integral across the gap
    a = f + GRAVITY_LAUNCH
    dv = 0.03 * np.random.default_rng(seed).standard_normal((t.size, 3)) + jump + a * offset
    return Problem.from_arrays(S, dv, t, f=f), f


def test_gap_columns_are_the_velocity_and_attitude_jump():
    """Against the integral of dv_dot = f x phi, by a finer trapezoid of a known f (closed form of a ramp)."""
    t = np.linspace(0.0, 10.0, 1001)
    f = np.column_stack([t, 2.0 + 0 * t, -t ** 2 / 10])  # integral from b: [t^2/2, 2 t, -t^3/30] - at b
    C = gap_columns(t, f, [(4.0, 5.0)])
    after = t >= 5.0
    assert C.shape == (t.size, 3, 6) and not C[~after].any()
    phi = np.array([1e-3, -2e-3, 5e-4])
    tt = t[after]
    F = np.column_stack([(tt ** 2 - 25) / 2, 2 * (tt - 5), -(tt ** 3 - 125) / 30])
    assert np.allclose(C[after] @ np.r_[0.1, 0.2, 0.3, phi], [0.1, 0.2, 0.3] + np.cross(F, phi), atol=2e-6)


def test_a_jump_at_a_gap_is_not_an_offset():
    pb, f = _flight()
    plain = time_offset_test(pb, pb.y, pb.t, f, gaps=())
    assert abs(plain.offset_t) > OFFSET_T  # the rule without the gaps reads the jump at burnout as an offset
    pb.gaps = (GAP,)
    test = time_offset_test(pb, pb.y, pb.t, f)
    assert abs(test.offset_t) < 4.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimeOffsetWarning)
        check_fit(pb, pb.y, _Zero(pb), t=pb.t, f=f, outliers_handled=True)  # the offset rule alone


def test_a_real_offset_is_still_found_across_a_gap():
    pb, f = _flight(OFFSET)
    pb.gaps = (GAP,)
    test = time_offset_test(pb, pb.y, pb.t, f)
    assert abs(test.offset - OFFSET) < 4 * test.offset_std and test.offset_std < OFFSET / 20
    with pytest.warns(TimeOffsetWarning, match="tracking time offset of 40"):
        check_fit(pb, pb.y, _Zero(pb), t=pb.t, f=f, outliers_handled=True)


class _Zero:
    """An estimate of zeros (the test reads the residuals' part off span S, whatever the estimate)."""

    def __init__(self, pb: Problem) -> None:
        self.names = pb.names

    def fitted_coefficients(self) -> np.ndarray:
        return np.zeros(len(self.names))


def test_a_pairs_telemetry_gap_reaches_the_problem_and_its_subsets(platform36):
    """The pair records the telemetry's gap; the Problem built from the flight carries it, and so do the problems
    derived from it (a subset, the whitened rows), so the offset rule of every fit sees it."""
    from casep.io.pair import pair_flight
    from casep.noise.model import NoiseModel

    t = np.round(np.arange(0.0, 20.0, 0.05), 10)
    t = t[(t < 12.0) | (t > 13.0)]
    f = np.tile([30.0, 0.0, 0.0], (t.size, 1)) - GRAVITY_LAUNCH
    t_trk = np.arange(0.05, 20.0, 0.1)
    v_tel = np.outer(t, [30.0, 0.0, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the gap's own warning
        flight = pair_flight(t, f, v_tel, t_trk, np.outer(t_trk, [30.0, 0.0, 0.0]), source="tel + trk")
    with pytest.warns(CasepWarning, match="S_V is integrated across them"):
        pb = Problem.from_flight(flight, platform36)
    assert len(pb.gaps) == 1 and pb.gaps[0][0] == pytest.approx(11.95) and pb.gaps[0][1] == pytest.approx(13.05)
    keep = np.ones(pb.n_samples, bool)
    keep[::7] = False
    assert pb.subset(keep).gaps == pb.gaps and pb.whitened(NoiseModel.white()).gaps == pb.gaps
