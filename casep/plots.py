"""Figures (matplotlib, non-interactive Agg backend). Each function writes one PNG and returns its path."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .diagnostics import GROUP_INDEX, Diagnostics

__all__ = ["plot_singular_values", "plot_variance_decomposition"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | os.PathLike) -> Path:
    path = Path(path)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def plot_singular_values(diag: Diagnostics, path: str | os.PathLike) -> Path:
    """Singular-value spectrum of the equilibrated regression with condition indices."""
    plt = _pyplot()
    s = diag.singular_values
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.semilogy(np.arange(1, s.size + 1), s, "o-", ms=4)
    ax.axhline(s[0] / GROUP_INDEX, color="tab:orange", ls="--", lw=1, label=f"condition index {GROUP_INDEX:g}")
    ax.axhline(s[0] / 1e3, color="tab:red", ls=":", lw=1, label="condition index 1000")
    ax.set_xlabel("dimension k")
    ax.set_ylabel("singular value s_k (unit-norm columns)")
    ce = diag.condition_number_equilibrated
    ax.set_title(f"Singular values; equilibrated condition number {ce:.3g}" if ce else "Singular values (rank deficient)")
    ax.legend(loc="lower left")
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def plot_variance_decomposition(diag: Diagnostics, path: str | os.PathLike) -> Path:
    """Heat map of Belsley-Kuh-Welsch variance-decomposition proportions."""
    plt = _pyplot()
    P = np.nan_to_num(diag.proportions, nan=0.0)
    fig, ax = plt.subplots(figsize=(max(8, 0.28 * len(diag.names)), 6))
    im = ax.imshow(P, aspect="auto", cmap="viridis", vmin=0, vmax=1, interpolation="nearest")
    ax.set_xticks(range(len(diag.names)), diag.names, rotation=90, fontsize=7)
    eta = diag.condition_indices
    ax.set_yticks(range(P.shape[0]), [f"{e:.0f}" if np.isfinite(e) else "inf" for e in eta], fontsize=7)
    ax.set_ylabel("condition index of dimension")
    ax.set_title("Variance-decomposition proportions (columns equilibrated, not centred)")
    fig.colorbar(im, ax=ax, label="proportion of Var(estimate)")
    return _save(fig, path)
