"""save_figure: its fast PNG encoding keeps the pixels of matplotlib's default encoding."""

from __future__ import annotations

import numpy as np
from PIL import Image

from casep.reporting.plots import pyplot, save_figure


def test_png_pixels_are_those_of_the_default_encoding(tmp_path):
    plt = pyplot()
    x = np.linspace(0.0, 10.0, 500)
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.semilogy(x, np.exp(x), label="exp")
    ax.set_title("a title")
    ax.legend()
    fig.savefig(tmp_path / "default.png", dpi=120)  # PIL's default zlib level
    save_figure(fig, tmp_path / "fast.png")
    a = np.asarray(Image.open(tmp_path / "default.png"))
    b = np.asarray(Image.open(tmp_path / "fast.png"))
    assert a.shape == b.shape == (360, 480, 4)
    assert np.array_equal(a, b)
    assert (tmp_path / "fast.png").stat().st_size != (tmp_path / "default.png").stat().st_size  # other zlib level
