"""Figures of Monte Carlo campaigns (``casep montecarlo --figure``), from plain arrays.

:func:`casep.montecarlo.write_figure` draws a :class:`casep.montecarlo.MonteCarloResult` with
:func:`plot_efficiency`; nothing here imports the Monte Carlo package.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from casep.reporting.plots import pyplot, save_figure

__all__ = ["plot_efficiency"]


def plot_efficiency(names: Sequence[str], ratios: Mapping[str, np.ndarray], path: str | os.PathLike,
                    title: str = "Monte Carlo") -> Path:
    """RMS error / CRLB std per coefficient, one line per method (log scale; 1 = efficient).

    Parameters
    ----------
    names : sequence of str
        The coefficients (x axis).
    ratios : mapping
        Method -> RMS error / CRLB std per coefficient, ``(len(names),)`` (NaN: not shown).
    path : path
        Image file; its suffix gives the format (written atomically).
    title : str
        Figure title.

    Returns
    -------
    Path
        `path`.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(max(9, 0.3 * len(names)), 4.5))
    x = np.arange(len(names))
    for meth, ratio in ratios.items():
        ax.semilogy(x, ratio, "o-", ms=3, lw=1, label=meth)
    ax.axhline(1.0, color="k", lw=1, ls="--")
    ax.set_xticks(x, list(names), rotation=90, fontsize=7)
    ax.set_ylabel("RMS error / CRLB std")
    ax.set_title(title)
    ax.legend(fontsize=8, ncol=3)
    ax.grid(True, which="both", alpha=0.3)
    return save_figure(fig, path)
