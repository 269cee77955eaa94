"""The demo's figure worker (casep.reporting.demo_figures.FigureJobs): the same pixels as drawn here, errors back."""

from __future__ import annotations

import numpy as np
import pytest

from casep.reporting.demo_figures import FigureJobs, plot_demo_residuals


def test_worker_draws_the_same_png_and_returns_a_figure_error(tmp_path, rng):
    t = np.linspace(0.0, 20.0, 201)
    resid = 0.1 * rng.standard_normal((t.size, 3))
    with FigureJobs(parallel=False) as jobs:
        jobs.draw(plot_demo_residuals, tmp_path / "here.png", t, resid, "drawn here")
    with pytest.raises(IndexError):  # the second figure's error, raised here after the first is written
        with FigureJobs(parallel=True) as jobs:
            jobs.draw(plot_demo_residuals, tmp_path / "worker.png", t, resid, "drawn here")
            jobs.draw(plot_demo_residuals, tmp_path / "bad.png", t, resid[:, :2], "two axes only")
    assert (tmp_path / "worker.png").read_bytes() == (tmp_path / "here.png").read_bytes()
    assert not (tmp_path / "bad.png").exists()  # nothing half-written


def test_an_error_in_the_caller_stops_the_worker(tmp_path):
    with pytest.raises(KeyError):
        with FigureJobs(parallel=True) as jobs:
            proc = jobs._proc
            raise KeyError("the demo failed")
    assert proc.poll() is not None  # stopped and reaped, not left behind


def test_a_worker_only_beside_a_spare_core(monkeypatch):
    from casep.reporting import demo_figures

    monkeypatch.setattr(demo_figures, "usable_cores", lambda: 2)
    monkeypatch.setattr(demo_figures.os, "getloadavg", lambda: (0.5, 0.5, 0.5))
    assert demo_figures.spare_core()
    monkeypatch.setattr(demo_figures.os, "getloadavg", lambda: (2.0, 0.5, 0.5))  # both cores busy
    assert not demo_figures.spare_core()
    monkeypatch.setattr(demo_figures, "usable_cores", lambda: 1)
    monkeypatch.setattr(demo_figures.os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    assert not demo_figures.spare_core()


def test_the_worker_starts_on_matplotlib_alone():
    """`casep demo` starts the worker before it imports NumPy, and the worker's start-up (its imports and warm-up,
    on the demo's critical path) imports matplotlib and casep's figure modules, none of casep's methods: the
    figure jobs carry plain arrays and results."""
    import subprocess
    import sys

    code = ("import sys\n"
            "import casep.reporting.demo_figures as d\n"
            "print('numpy' in sys.modules)\n"
            "d.warm_up()\n"
            "print(' '.join(sorted(m for m in sys.modules if m.startswith('casep'))))\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout.split("\n")
    assert out[0] == "False"  # numpy: imported by the figures
    assert set(out[1].split()) <= {"casep", "casep._cores", "casep._lazy", "casep._version", "casep.reporting",
                                   "casep.reporting.demo_figures", "casep.reporting.plots"}, out[1]
