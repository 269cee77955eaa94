"""The command line runs with one BLAS thread unless the user set the thread count."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from casep.cli.blas import BLAS_THREAD_VARS, blas_threads_limited

_PROBE = """
from casep.cli.blas import blas_threads_limited
with blas_threads_limited():
    import numpy
    from threadpoolctl import threadpool_info
    print(*sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}))
"""


_PROBE_AFTER_NUMPY = """
import numpy
from casep.cli.blas import blas_threads_limited
with blas_threads_limited():
    import scipy.linalg
    from threadpoolctl import threadpool_info
    print(*sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}))
"""


def _blas_threads(probe: str = _PROBE, **env: str) -> str:
    clean = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARS}
    out = subprocess.run([sys.executable, "-c", probe], env={**clean, **env}, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip()


def test_before_numpy_loads_the_environment_gives_one_thread_unless_the_user_set_one():
    assert _blas_threads() == "1"
    assert _blas_threads(OPENBLAS_NUM_THREADS="2") == "2"  # the user's, even on one core


def test_after_numpy_loaded_a_blas_library_scipy_loads_within_is_limited_too():
    """casep.cli.main called from Python (numpy loaded, scipy not): SciPy's own OpenBLAS, which loads with
    scipy.linalg inside the block, runs one thread as well."""
    assert _blas_threads(_PROBE_AFTER_NUMPY) == "1"


def test_after_numpy_loaded_threadpoolctl_limits_and_the_users_setting_is_kept(monkeypatch):
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas() -> set[int]:
        return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}

    if not blas():
        pytest.skip("no BLAS library threadpoolctl can see")
    for v in BLAS_THREAD_VARS:
        monkeypatch.delenv(v, raising=False)
    with threadpool_limits(limits=2):
        before = blas()  # 2, or fewer where the library was loaded with fewer
        with blas_threads_limited():
            assert blas() == {1}
        assert blas() == before
        monkeypatch.setenv("MKL_NUM_THREADS", "2")
        with blas_threads_limited():
            assert blas() == before
