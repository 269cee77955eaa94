"""casep.reporting.montecarlo_plots: the Monte Carlo figure from plain arrays."""

from __future__ import annotations

import numpy as np

from casep.reporting.montecarlo_plots import plot_efficiency


def test_efficiency_figure_from_plain_arrays(tmp_path):
    path = plot_efficiency(["a", "b", "c"], {"ols": np.array([1.0, 1.1, 0.9]), "rels": np.array([2.0, np.nan, 3.0])},
                           tmp_path / "mc.png", title="three coefficients")
    assert path == tmp_path / "mc.png" and path.read_bytes()[:4] == b"\x89PNG"
    svg = plot_efficiency(["a"], {"ols": np.array([1.0])}, tmp_path / "mc.svg")
    assert b"<svg" in svg.read_bytes()[:1000]
