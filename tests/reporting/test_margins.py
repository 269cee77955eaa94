"""Figures laid out by fixed margins (casep.reporting.plots.set_margins): every text inside, none on another."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from casep.reporting import demo_figures, plots
from casep.reporting.plots import pyplot, set_margins, text_width
from casep.workflows import demo


def clashes(fig) -> list[str]:
    """Each panel (ticks, labels, title, legend) and the suptitle that leaves `fig` or overlaps another."""
    fig.draw_without_rendering()
    r = fig.canvas.get_renderer()
    boxes = [(f"panel {i}", ax.get_tightbbox(r)) for i, ax in enumerate(fig.axes)]
    if fig.get_suptitle():
        boxes.append(("suptitle", fig._suptitle.get_window_extent(r)))
    fb = fig.bbox
    out = [f"{n} leaves the figure" for n, b in boxes
           if min(b.x0 - fb.x0, b.y0 - fb.y0, fb.x1 - b.x1, fb.y1 - b.y1) < -0.5]  # half a pixel
    out += [f"{a} overlaps {b}" for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1:] if ba.overlaps(bb)]
    return out


@pytest.fixture
def checked(monkeypatch):
    """Every figure given to save_figure is drawn and checked for clashes instead of written (writing a
    PNG is save_figure's own test); it must come laid out by fixed margins (``layout=None``)."""
    found: dict[str, list[str]] = {}

    def check(fig, path, *, layout="constrained"):
        found[path.name] = clashes(fig) + ([] if layout is None else [f"laid out by {layout}"])
        pyplot().close(fig)
        return path

    monkeypatch.setattr(plots, "save_figure", check)  # the demo's figures import it from plots when they draw
    return found


def test_set_margins_places_panels_in_inches():
    plt = pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(10, 6))
    set_margins(fig, left=1.0, right=0.5, bottom=0.8, top=0.4, wspace=0.3, hspace=0.6)
    b = np.array([ax.get_position().bounds for ax in axes.ravel()]) * [10, 6, 10, 6]  # inches
    plt.close(fig)
    np.testing.assert_allclose(b[0], [1.0, 0.8 + (6 - 1.2 - 0.6) / 2 + 0.6, (10 - 1.5 - 0.6) / 3,
                                      (6 - 1.2 - 0.6) / 2], rtol=1e-12)
    np.testing.assert_allclose(b[2, 0] + b[2, 2], 10 - 0.5, rtol=1e-12)  # right margin
    np.testing.assert_allclose(b[3, 1], 0.8, rtol=1e-12)  # bottom margin
    np.testing.assert_allclose(b[1, 0] - (b[0, 0] + b[0, 2]), 0.3, rtol=1e-12)  # gap between columns


def test_text_width_grows_with_text_and_size():
    w = text_width("Kg1xy", 8)
    assert 0.2 < w < 0.5  # five characters at 8 pt
    np.testing.assert_allclose(text_width("Kg1xy", 16), 2 * w, rtol=0.05)
    assert text_width("Kg1xy, Kg1xy", 8) > 2 * w


def test_demo_figures_keep_their_texts_apart(checked, tmp_path, rng):
    """The demo's figures (and the diagnostics and impact figures it writes) on data of its shapes with
    wider tick labels than the demo's (residuals of 0.001 m/s, misses of 1e6 m) and a long model name."""
    n, names, scale = 2001, [f"K{k}{a}" for k in ("a0", "a1y", "g2xy") for a in "xyz"], 1e-3
    t = np.linspace(0.0, 195.0, n)
    truth = rng.standard_normal(len(names))
    res = SimpleNamespace(residuals=scale * rng.standard_normal((n, 3)),
                          estimate=truth + rng.standard_normal(len(names)),
                          history=truth + rng.standard_normal((n // 10, len(names))),
                          extras=SimpleNamespace(history_stride=10))
    sim = SimpleNamespace(flight=SimpleNamespace(t=t), model=SimpleNamespace(names=names), truth=truth)
    results = {label: res for label, _, _ in demo.DEMO_METHODS}
    diag = SimpleNamespace(singular_values=np.logspace(0, -7, len(names)), condition_number_equilibrated=1e7,
                           crlb_std=np.ones(len(names)))
    G = 1e6 * rng.standard_normal((2, len(names)))
    groups = [SimpleNamespace(names=names[:6], contribution=G[:, :6].sum(axis=1), std=None)]
    cov = np.diag([4e6, 1e6])
    impact = SimpleNamespace(contributions=G, sensitivity=G, coefficient_std=np.ones(len(names)), names=names,
                             groups=groups, miss=G.sum(axis=1), std=np.sqrt(np.diag(cov)), cov=cov,
                             nonlinear=1.01 * G.sum(axis=1), model="a model with a long name", method="ols")
    with demo_figures.FigureJobs(parallel=False) as jobs:  # drawn here: the check replaces save_figure
        for label in ("diagnostics", "LS", "RELS", "wavelet+RELS", "MAP"):  # MAP: every method's result exists
            demo._draw(jobs, tmp_path, label, sim, results, {"LS": impact}, diag)
    assert set(checked) == {"fig3_residuals_ls.png", "fig4_residuals_wavelet_rels.png", "coefficient_errors.png",
                            "rels_convergence.png", "singular_values.png", "miss_budget.png", "impact_ellipse.png"}
    assert {k: v for k, v in checked.items() if v} == {}


def test_miss_budget_symlog_tick_labels_do_not_overlap(monkeypatch, tmp_path):
    """A downrange budget whose bars run from 1 m to 3500 m (the demo's): matplotlib's symlog ticks at -1, 0, 1
    sit in the linear part, a fraction of a decade apart, and their labels overlap; none of them may."""
    figs = []

    def keep(fig, path, *, layout="constrained"):
        figs.append(fig)
        return path

    monkeypatch.setattr(plots, "save_figure", keep)
    names = [f"K{j}" for j in range(8)]
    G = np.array([[3500.0, -1200.0, 150.0, -80.0, 12.0, -5.0, 1.5, -1.0],
                  [-1500.0, 9000.0, -300.0, 40.0, -7.0, 3.0, -2.0, 0.5]])
    impact = SimpleNamespace(contributions=G, sensitivity=G, coefficient_std=0.1 * np.ones(len(names)), names=names,
                             groups=[], miss=G.sum(axis=1), std=np.array([5.6, 3.6]), nonlinear=G.sum(axis=1),
                             model="platform36", method="ols")
    plots.plot_miss_budget(impact, tmp_path / "miss_budget.png")
    fig = figs[0]
    fig.draw_without_rendering()
    r = fig.canvas.get_renderer()
    for ax in fig.axes:
        boxes = [(t.get_text(), t.get_window_extent(r)) for t in ax.get_xticklabels() if t.get_text()]
        assert len(boxes) >= 3
        bad = [(a, b) for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1:] if ba.overlaps(bb)]
        assert bad == [], bad
    pyplot().close(fig)
