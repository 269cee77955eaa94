"""The Ljung-Box p-value: scipy.stats' chi2 survival function (the oracle), without importing scipy.stats
on the default path of ``casep separate`` (0.5 s of its start-up since the whiteness test runs for every
noise kind)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.stats import chi2

from casep.noise.whiteness import ljung_box


@pytest.mark.parametrize("lags", [1, 5, 10, 40])
def test_ljung_box_p_value_is_the_chi2_survival_function(lags):
    x = np.random.default_rng(lags).normal(size=400)
    x[1:] += 0.3 * x[:-1]  # correlated: small p too
    q, p = ljung_box(x, lags)
    assert p == pytest.approx(chi2.sf(q, lags), rel=1e-12, abs=1e-300)


def test_ljung_box_does_not_import_scipy_stats():
    code = ("import sys, numpy as np; from casep.noise.whiteness import ljung_box; "
            "ljung_box(np.random.default_rng(0).normal(size=200), 5); "
            "assert 'scipy.stats' not in sys.modules, 'scipy.stats imported'")
    subprocess.run([sys.executable, "-c", code], check=True)
