"""The movement rule of benchmarks/car_drive_drift.py: the std of an independent offset per value that brings the
values' chi-square about their weighted mean to its dof (the stops' movement, what the windows would need)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def drift():
    from conftest import benchmark_module

    with benchmark_module("car_drive_drift", prefix="car_drive") as mod:
        yield mod


def test_excess_std_closed_form_and_zero(drift):
    """Two values of equal std s: chi2(tau) = d^2 / (2 (s^2 + tau^2)) = 1 gives tau^2 = d^2 / 2 - s^2 (to 1e-9
    relative); values that already agree within their std give 0."""
    s, d = 1.5, 7.0
    tau = drift.excess_std(np.array([0.0, d]), np.array([s, s]))
    assert tau == pytest.approx(np.sqrt(d**2 / 2 - s**2), rel=1e-9)
    assert drift.excess_std(np.array([0.0, 1.0, -0.5]), np.array([1.0, 1.0, 1.0])) == 0.0


def test_excess_std_recovers_a_drawn_offset(drift):
    """Values drawn with unequal std and an independent offset of std 3 (seeded, 400 values): the rule gives 3
    within 20 % (over 300 seeds the estimate's mean is 3.002 and its std 5.3 %: the bound is about 4 std)."""
    rng = np.random.default_rng(11)
    s = rng.uniform(0.5, 4.0, 400)
    x = 10.0 + rng.normal(0.0, 3.0, s.size) + rng.normal(0.0, s)
    assert drift.excess_std(x, s) == pytest.approx(3.0, rel=0.20)
