"""Principal-component regression (casep.estimators.pcr)."""

from __future__ import annotations

import numpy as np
import pytest

import casep


def test_all_components_equal_ols(paper_problem):
    S, y, _ = paper_problem
    ols = casep.solve_ols(S, y)
    pcr = casep.solve_pcr(S, y, n_components=36)
    assert np.max(np.abs(pcr.estimate - ols.estimate) / ols.std) < 1e-8
    np.testing.assert_allclose(pcr.std, ols.std, rtol=1e-9)


def test_truncation_rule_and_dropped_directions(paper_problem):
    S, y, _ = paper_problem
    res = casep.solve_pcr(S, y, max_condition_index=100.0)
    ci = [d["condition_index"] for d in res.extras.dropped_directions]
    k = res.extras.n_components
    assert len(ci) == 36 - k and all(c > 100.0 for c in ci)
    s = np.linalg.svd(casep.reduce_qr(S, y).R, compute_uv=False)
    assert k == int(np.sum(s[0] / s <= 100.0))
    assert all(d["combination"] for d in res.extras.dropped_directions)
    assert np.all(res.std <= casep.solve_ols(S, y).std * (1 + 1e-9))


def test_bad_arguments(paper_problem):
    S, y, _ = paper_problem
    with pytest.raises(ValueError, match="exceeds the rank"):
        casep.solve_pcr(S, y, n_components=37)
    with pytest.raises(ValueError, match=r"\(`n_components`\) must be an int >= 1"):
        casep.solve_pcr(S, y, n_components=0)
