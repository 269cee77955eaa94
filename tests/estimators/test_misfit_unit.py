"""The misfit failure names the rows' unit: a flight's m/s, a ground test's reading unit."""

from __future__ import annotations

import numpy as np

from casep.estimators._base import finish, prepare
from casep.regression.problem import Problem


def _rows(seed: int = 4):
    rng = np.random.default_rng(seed)
    S = rng.standard_normal((200, 3, 3))
    return S, S @ np.array([1.0, -1.0, 0.5]) + 0.1 * rng.standard_normal((200, 3))


def test_a_misfit_failure_names_the_unit_of_the_rows_and_derived_problems_keep_it():
    S, y = _rows()
    t = np.arange(200) * 0.01
    for unit, pb in (("m/s", Problem.from_arrays(S, y, t)),
                     ("rad/s", Problem.from_arrays(S, y, t, row_unit="rad/s")),
                     ("m/s^2", Problem.from_arrays(S, y, t, row_unit="m/s^2").subset(np.arange(200) % 7 != 0))):
        res = finish(prepare(pb, None, None, None, None, None), "test", np.array([1e3, -1.0, 0.5]), np.eye(3), 0.1,
                     settings={})
        assert res.status == -3 and f" {unit} is " in res.message and "std " in res.message, res.message
        assert res.message.count(f" {unit}") == 2, res.message
