"""The figure of an automatic segmentation (``casep calibrate --segments auto --figures DIR``).

The detector's statistic over time (:mod:`casep.calibration.segment`: the larger of the
accelerometers' window variance and the gyro's window mean square, each in units of the initial
period; a sample is static at or below the chosen multiplier ``k``), on a log scale with the
threshold ``k``; the static poses shaded green, the turns of a Ferraris session blue (named), static
runs not used grey, the rejected static runs hatched red.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plot_segmentation", "segmentation_intervals"]


def segmentation_intervals(segmentation: Any) -> dict:
    """The row intervals (start, end excluded) a figure of `segmentation` draws.

    Parameters
    ----------
    segmentation : Segmentation or FerrarisSegmentation

    Returns
    -------
    dict
        ``poses``: the static poses (a Ferraris session: its six named poses), ``turns``: the turns
        (name -> interval; empty for a hand-turned session, whose motions are not drawn), ``unused``: the
        detector's poses that are none of the named ones (a Ferraris session: a rest inside a turn's
        station), ``rejected``: the static runs too short or off every axis.
    """
    seg = getattr(segmentation, "segmentation", segmentation)
    named = getattr(segmentation, "segments", None)
    if named is None:
        poses = {f"pose {i + 1}": (int(a), int(b)) for i, (a, b) in enumerate(seg.poses)}
        turns: dict = {}
    else:
        poses, turns = {}, {}
        for s in named:
            (turns if s.kind == "rotation" else poses)[s.name] = (int(s.rows[0]), int(s.rows[-1]) + 1)
    used = list(poses.values()) + list(turns.values())
    unused = [(int(a), int(b)) for a, b in seg.poses if not any(a < hi and lo < b for lo, hi in used)]
    return {"poses": poses, "turns": turns, "unused": unused,
            "rejected": [(int(a), int(b)) for a, b, _ in seg.rejected]}


def plot_segmentation(segmentation: Any, path: str | os.PathLike) -> dict:
    """Write the figure of `segmentation` (module notes) to `path`; return the intervals drawn
    (:func:`segmentation_intervals`).

    Raises
    ------
    ValueError
        A segmentation without its statistic (made by hand, not by the detector).
    """
    from casep.reporting.plots import pyplot, save_figure

    seg = getattr(segmentation, "segmentation", segmentation)
    if seg.statistic is None:
        raise ValueError("this segmentation carries no detector statistic (it was not found by the detector): "
                         "nothing to plot")
    drawn = segmentation_intervals(segmentation)
    rate = seg.rate
    stat = np.maximum(np.asarray(seg.statistic, dtype=float), 1e-3)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 4), layout="constrained")
    ax.semilogy(np.arange(len(stat)) / rate, stat, color="black", lw=0.7, label="detector statistic")
    ax.axhline(seg.multiplier, color="tab:orange", ls="--", lw=1, label=f"threshold k = {seg.multiplier:g}")
    for i, (name, (a, b)) in enumerate(drawn["poses"].items()):
        ax.axvspan(a / rate, b / rate, color="tab:green", alpha=0.25, lw=0, label="static pose" if i == 0 else None)
        if not name.startswith("pose "):
            ax.text((a + b) / 2 / rate, 0.97, name, transform=ax.get_xaxis_transform(), ha="center", va="top",
                    fontsize=8)
    for i, (name, (a, b)) in enumerate(drawn["turns"].items()):
        ax.axvspan(a / rate, b / rate, color="tab:blue", alpha=0.2, lw=0, label="turn" if i == 0 else None)
        ax.text((a + b) / 2 / rate, 0.97, name, transform=ax.get_xaxis_transform(), ha="center", va="top",
                fontsize=8)
    for i, (a, b) in enumerate(drawn["unused"]):
        ax.axvspan(a / rate, b / rate, color="tab:gray", alpha=0.3, lw=0, label="static, not used" if i == 0 else None)
    for i, (a, b) in enumerate(drawn["rejected"]):
        ax.axvspan(a / rate, b / rate, facecolor="none", edgecolor="tab:red", hatch="///", lw=0.8,
                   label="rejected static run" if i == 0 else None)
    ax.set_xlabel("time, s")
    ax.set_ylabel("statistic / initial period's")
    turns = f"{len(drawn['turns'])} turns, " if drawn["turns"] else ""
    ax.set_title(f"Segmentation: {len(drawn['poses'])} poses, {turns}{len(drawn['rejected'])} rejected runs; "
                 f"window {seg.window} samples")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, Path(path))
    return drawn
