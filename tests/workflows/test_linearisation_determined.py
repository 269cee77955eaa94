"""Whether a linear result stands is judged on what the flight determines (linearisation_shift).

A synthetic problem with known columns and a pass whose rows hold a known second order: the remainder's shift of
the estimate is ``b = S^+ r`` exactly, and with orthogonal columns the shift of a determined coefficient in its std
is ``|b_j| / std_j``, computed here by hand. A second order in a coefficient the flight does not determine (its std
21 declared magnitudes, its estimate as large) is not the linear result's to answer for: the judgement steps along
the determined combinations only, as the iteration's first pass does, and finds nothing to shift.
"""

from __future__ import annotations

import types
import warnings

import numpy as np
import pytest

import casep
from casep.regression.problem import Problem
from casep.workflows.imu_separate import linearisation_shift

N = 400
K = 1e-3  # the second order's size, m/s per (declared magnitude)^2 along c0's column


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 40.0, N)
    S = np.zeros((N, 3, 3))
    S[:, 0, 0] = t  # determined
    S[:, 1, 1] = np.sin(t)  # determined
    S[:, 2, 2] = 1e-6 * t  # barely seen: std about 20 declared magnitudes
    y = np.einsum("ijk,k->ij", S, np.array([1.0, -0.5, 0.0])) + 0.01 * rng.standard_normal((N, 3))
    scales = {"c0": 1.0, "c1": 1.0, "c2": 1.0}
    pb = Problem.from_arrays(S, y, t, names=list(scales), magnitudes=scales)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the undetermined coefficient's warnings
        res = casep.separate(pb, None, method="ols", noise="white")
    flight = types.SimpleNamespace(meta={}, t=t, signals={})  # one tracking stretch, no IMU record
    return S, y, pb, res, flight, scales


def _run(S, y, j):
    """A pass's rows: the linear model's plus ``K x_j^2`` along c0's column."""
    return types.SimpleNamespace(rows=lambda x: y - np.einsum("ijk,k->ij", S, x) + S[:, :, 0] * K * x[j] ** 2)


def test_second_order_in_a_determined_coefficient_is_its_shift_in_std(fitted):
    S, y, pb, res, flight, scales = fitted
    assert res.std[0] < 1e-3 and res.std[2] > 10.0  # the set-up: c0 determined, c2 not
    expected = K * res.estimate[0] ** 2 / res.std[0]  # b = (K x0^2, 0, 0), C diagonal
    assert expected > 10.0
    assert linearisation_shift(_run(S, y, 0), res, pb, flight, scales).std == pytest.approx(expected, rel=1e-6)


def test_second_order_in_an_undetermined_coefficient_is_not_judged(fitted):
    """Its linear estimate (about 20 declared magnitudes) would shift c0 by K x2^2 / std0, thousands of std, if the
    judgement stepped along it."""
    S, y, pb, res, flight, scales = fitted
    assert K * res.estimate[2] ** 2 / res.std[0] > 1e3
    assert linearisation_shift(_run(S, y, 2), res, pb, flight, scales).std < 1e-9
