"""Figures of one separation (casep.reporting.plots)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import casep
from casep.reporting.plots import best_determined, estimate_scales, plot_history, separate_figures

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "data" / "example_flight.csv"
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def example_flight():
    return casep.read_flight(EXAMPLE)


def _is_png(p: Path) -> bool:
    return p.is_file() and p.stat().st_size > 1000 and p.read_bytes()[:8] == PNG


def test_separate_figures_rels_writes_three_pngs_in_new_folder(example_flight, tmp_path):
    res = casep.separate(example_flight, "platform36", "rels")
    out = tmp_path / "a" / "b"  # created, parents too
    files = separate_figures(res, out, example_flight.t)
    assert [f.name for f in files] == ["residuals.png", "estimates.png", "history.png"]
    assert all(_is_png(f) for f in files)


def test_separate_figures_ols_has_no_history(example_flight, tmp_path):
    res = casep.separate(example_flight, "platform36", "ols")
    files = separate_figures(res, tmp_path, example_flight.t)
    assert [f.name for f in files] == ["residuals.png", "estimates.png"]
    assert all(_is_png(f) for f in files)
    with pytest.raises(ValueError, match="no estimate and std history"):
        plot_history(res, tmp_path / "h.png")


def test_estimates_figure_against_prior_and_bounds(rng, tmp_path):
    S = rng.standard_normal((100, 3, 3))
    y = S @ np.array([1.0, -2.0, 0.5]) + 0.1 * rng.standard_normal((100, 3))
    res = casep.solve_ols(S, y, names=["a", "b", "c"])
    prior = {"a": {"mean": 1.0, "std": 0.5}}
    bounds = {"a": [0, 4], "b": [-3.0, -1.0], "c": [0.0, None]}
    scale, kind = estimate_scales(res, prior=prior, bounds=bounds)
    # prior std beats the box; the box half-width beats the own std; a one-sided box does not count
    np.testing.assert_allclose(scale, [0.5, 1.0, res.std[2]], rtol=1e-15)
    assert kind == ["prior std", "bound half-width", "own std"]
    files = separate_figures(res, tmp_path, None, prior=prior, bounds=bounds)
    assert all(_is_png(f) for f in files)


def test_best_determined_orders_by_t_ratio(rng):
    S = rng.standard_normal((200, 3, 4))
    y = S @ np.array([0.0, 5.0, -1.0, 0.2]) + 0.1 * rng.standard_normal((200, 3))
    res = casep.solve_ols(S, y)
    t = np.abs(res.estimate) / res.std
    np.testing.assert_array_equal(best_determined(res, 2), np.argsort(-t)[:2])
    assert list(best_determined(res, 2)) == [1, 2]
