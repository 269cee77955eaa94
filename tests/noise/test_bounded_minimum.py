"""The noise fit's bounded scalar search against scipy's (the same algorithm: the same points, bit for bit)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from casep.noise.fit import bounded_minimum


def _recorded(func):
    calls: list[float] = []

    def f(x):
        calls.append(float(x))
        return func(x)

    return f, calls


@pytest.mark.parametrize("func, a, b, xatol", [
    (lambda x: (x - 0.3) ** 2, -2.0, 5.0, 5e-3),
    (lambda x: np.cos(3 * x) + 0.1 * x, -4.0, 4.0, 1e-5),  # several local minima
    (lambda x: abs(x - 1.0), 0.0, 3.0, 5e-3),  # a kink: parabolic steps refused
    (lambda x: np.exp(x), -1.0, 2.0, 5e-3),  # minimum on the lower bound
    (lambda x: -x, -1.0, 2.0, 5e-3),  # on the upper bound
    (lambda x: 1e300 if x < 0.5 else (x - 0.7) ** 2, 0.0, 1.0, 5e-3),  # a plateau of non-likelihood
    (lambda x: 0.0, -1.0, 1.0, 5e-3),  # flat
])
def test_bounded_minimum_takes_scipys_steps(func, a, b, xatol):
    f1, ours = _recorded(func)
    f2, theirs = _recorded(func)
    x = bounded_minimum(f1, a, b, xatol)
    r = minimize_scalar(f2, bounds=(a, b), method="bounded", options={"xatol": xatol})
    assert ours == theirs  # every evaluation at the same point
    assert float(x) == float(r.x)


def test_bounded_minimum_stops_at_maxfun():
    f, calls = _recorded(lambda x: np.cos(3 * x))
    bounded_minimum(f, -4.0, 4.0, 1e-12, maxfun=7)
    assert len(calls) == 7
