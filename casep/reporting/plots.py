"""Figures (matplotlib, non-interactive Agg backend). Each function writes one PNG and returns its path."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

if TYPE_CHECKING:  # imported where used: the demo's figure worker imports this module and none of casep's methods
    from casep.checks.diagnostics import Diagnostics
    from casep.estimators.result import EstimateResult

__all__ = ["plot_singular_values", "plot_spectrum", "plot_variance_decomposition", "plot_residuals", "plot_estimates",
           "plot_history", "separate_figures", "estimate_scales", "plot_flights_crlb", "plot_allan", "plot_miss_budget",
           "plot_impact_ellipse", "impact_figures", "plot_design", "pyplot", "save_figure", "set_margins",
           "text_width", "plain_log_ticks"]


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


#: zlib level of the PNG figures (lossless at every level; 1 is the fastest).
PNG_COMPRESS_LEVEL = 1


def save_figure(fig: Any, path: str | os.PathLike, *, layout: str | None = "constrained") -> Path:
    """Write `fig` to `path` (format from the extension, PNG by default) atomically, close it, return `path`.

    The figure keeps its size (``figsize`` at 120 dpi). Its labels, titles and legends stay inside it either
    by margins fixed when it was made (:func:`set_margins`; ``layout=None``) or by matplotlib's constrained
    layout, worked out while the figure is drawn (a figure given here without a layout engine gets it).
    Constrained layout measures every tick label before the figure is drawn, which costs about a third of
    the time of a figure; fixed margins cost nothing. (Saving with ``bbox_inches="tight"`` would draw every
    figure twice: once to find the bounding box.)
    """
    from casep.io._atomic import atomic_open

    if layout is not None and fig.get_layout_engine() is None:
        fig.set_layout_engine(layout)
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    # PNG: zlib level 1 (PIL's default is 6): the same pixels, about 10 % more bytes, half the encoding time
    extra = {"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}} if fmt == "png" else {}
    with atomic_open(path, binary=True) as fh:  # whole or not at all; with the command's other outputs
        fig.savefig(fh, format=fmt, dpi=120, **extra)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def set_margins(fig: Any, *, left: float, right: float, bottom: float, top: float, wspace: float = 0.0,
                hspace: float = 0.0) -> None:
    """Place the panels of `fig` (one grid of subplots) by fixed margins and gaps, in inches.

    For a figure whose texts have a known size (labels, titles, tick labels of bounded width): the panels
    fill what the margins leave, ``wspace`` between columns and ``hspace`` between rows. Save it with
    ``save_figure(fig, path, layout=None)``.
    """
    W, H = fig.get_size_inches()
    nrows, ncols = fig.axes[0].get_subplotspec().get_gridspec().get_geometry()
    width = (W - left - right - wspace * (ncols - 1)) / ncols  # one panel, inches
    height = (H - bottom - top - hspace * (nrows - 1)) / nrows
    fig.subplots_adjust(left=left / W, right=1.0 - right / W, bottom=bottom / H, top=1.0 - top / H,
                        wspace=wspace / width, hspace=hspace / height)  # gaps as fractions of a panel


def text_width(text: str, size: float) -> float:
    """Width in inches of one line of `text` at font size `size` (points), in matplotlib's default font."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    w, _, _ = TextToPath().get_text_width_height_descent(text, FontProperties(size=size), ismath=False)
    return float(w) / 72.0  # points -> inches


def plain_log_ticks(axis: Any) -> None:
    """Label the ticks of a log or symlog `axis` (``ax.xaxis``, ``ax.yaxis``) in plain text: ``1e-03``,
    ``0.1``, ``1``, ``100``, ``-1000``, ``1e+05``, instead of matplotlib's mathtext powers of ten, whose
    parse is about a tenth of the CPU time of a figure with log axes. The same ticks are labelled (the
    decades; on a log axis spanning few decades the minor ticks matplotlib labels too)."""
    from matplotlib.ticker import LogFormatter

    class PlainLogFormatter(LogFormatter):
        """matplotlib's LogFormatter with the sign of a negative symlog tick (its own drops it)."""

        def __call__(self, x: float, pos: Any = None) -> str:
            s = super().__call__(x, pos)
            return self.fix_minus("-" + s) if x < 0 and s else s

    base = axis.get_scale()
    axis.set_major_formatter(PlainLogFormatter())
    if base == "log":  # the minor ticks matplotlib labels when the axis spans few decades
        axis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False))


def plot_singular_values(diag: Diagnostics, path: str | os.PathLike) -> Path:
    """Singular-value spectrum of the equilibrated regression with condition indices."""
    from casep.checks.diagnostics import GROUP_INDEX

    return plot_spectrum(diag.singular_values, diag.condition_number_equilibrated, GROUP_INDEX, path)


def plot_spectrum(s: np.ndarray, ce: float | None, group_index: float, path: str | os.PathLike) -> Path:
    """:func:`plot_singular_values` from plain data: the singular values `s` of the equilibrated regression
    (largest first), its condition number `ce` (None: rank deficient) and the condition index
    `group_index` of :mod:`casep.checks.diagnostics` (its ``GROUP_INDEX``), drawn as the lines
    ``s[0] / group_index`` and ``s[0] / 1000``."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    set_margins(fig, left=0.85, right=0.12, bottom=0.5, top=0.3)  # one-line title, plain log ticks ("1e-05")
    ax.semilogy(np.arange(1, s.size + 1), s, "o-", ms=4)
    plain_log_ticks(ax.yaxis)
    ax.axhline(s[0] / group_index, color="tab:orange", ls="--", lw=1, label=f"condition index {group_index:g}")
    ax.axhline(s[0] / 1e3, color="tab:red", ls=":", lw=1, label="condition index 1000")
    ax.set_xlabel("dimension k")
    ax.set_ylabel("singular value s_k (unit-norm columns)")
    # y=1.0: where matplotlib would place it (a log axis has no offset text), without measuring the ticks first
    ax.set_title(f"Singular values; equilibrated condition number {ce:.3g}" if ce
                 else "Singular values (rank deficient)", y=1.0)
    ax.legend(loc="lower left")
    ax.grid(True, which="both", alpha=0.3)
    return save_figure(fig, path, layout=None)


def plot_variance_decomposition(diag: Diagnostics, path: str | os.PathLike) -> Path:
    """Heat map of Belsley-Kuh-Welsch variance-decomposition proportions."""
    plt = pyplot()
    P = np.nan_to_num(diag.proportions, nan=0.0)
    fig, ax = plt.subplots(figsize=(max(8, 0.28 * len(diag.names)), 6), layout="constrained")
    im = ax.imshow(P, aspect="auto", cmap="viridis", vmin=0, vmax=1, interpolation="nearest")
    ax.set_xticks(range(len(diag.names)), diag.names, rotation=90, fontsize=7)
    eta = diag.condition_indices
    ax.set_yticks(range(P.shape[0]), [f"{e:.0f}" if np.isfinite(e) else "inf" for e in eta], fontsize=7)
    ax.set_ylabel("condition index of dimension")
    ax.set_title("Variance-decomposition proportions (columns equilibrated, not centred)")
    fig.colorbar(im, ax=ax, label="proportion of Var(estimate)")
    return save_figure(fig, path)


def plot_flights_crlb(d: Mapping, path: str | os.PathLike, scales: Mapping | None = None) -> Path:
    """What each flight determines alone and what the flights determine jointly.

    One row per shared coefficient: the CRLB std of each flight alone and of all jointly
    (:func:`casep.workflows.flights.diagnose_flights`), divided by the coefficient's declared
    magnitude (`scales`; a ratio below 1 means the data know it to better than its typical size);
    log scale; undetermined bounds drawn at the right edge with a cross.
    """
    plt = pyplot()
    rows = d["coefficients"]
    k = len(d["flights"])
    names = [r["name"] for r in rows]
    scale = np.array([float((scales or {}).get(n, 1.0)) for n in names])
    alone = np.array([[np.nan if v is None else v for v in r["crlb_alone"]] for r in rows],
                     dtype=float) / scale[:, None]
    joint = np.array([np.nan if r["crlb_joint"] is None else r["crlb_joint"] for r in rows], dtype=float) / scale
    finite = np.concatenate([alone[np.isfinite(alone)], joint[np.isfinite(joint)]])
    hi = 10 ** np.ceil(np.log10(finite.max())) if finite.size else 10.0
    lo = 10 ** np.floor(np.log10(finite.min())) if finite.size else 0.1
    fig, ax = plt.subplots(figsize=(8, max(4, 0.22 * len(rows) + 1.5)), layout="constrained")
    y = np.arange(len(rows))
    h = 0.8 / (k + 1)
    for i in range(k):
        v = alone[:, i]
        ax.barh(y - 0.4 + h * (i + 0.5), np.where(np.isfinite(v), v, hi), height=h, left=lo, alpha=0.6,
                label=f"flight {i + 1} alone: {d['flights'][i]}")
        ax.plot(np.full(int((~np.isfinite(v)).sum()), hi), (y - 0.4 + h * (i + 0.5))[~np.isfinite(v)], "kx", ms=3)
    ax.barh(y - 0.4 + h * (k + 0.5), np.where(np.isfinite(joint), joint, hi), height=h, left=lo, color="k",
            label=f"{k} flights jointly")
    ax.axvline(1.0, color="tab:red", ls="--", lw=1, label="declared magnitude" if scales else "1")
    ax.set_xscale("log")
    ax.set_xlim(lo, hi * 1.5)
    ax.set_yticks(y, names, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("CRLB std / declared magnitude" if scales else "CRLB std (natural units)")
    ax.set_title(f"What each flight determines: identifiable alone {d['identifiable_alone']}, "
                 f"jointly {d['identifiable_joint']}")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    ax.grid(True, axis="x", which="both", alpha=0.3)
    return save_figure(fig, path)


def _sample_times(result: EstimateResult, t: np.ndarray | None) -> tuple[np.ndarray, str]:
    """Time of each residual row (s), or the sample index when `t` does not match."""
    n = np.asarray(result.residuals).reshape(-1, 3).shape[0]
    if t is not None and np.asarray(t).shape == (n,):
        return np.asarray(t, dtype=float), "time (s)"
    return np.arange(n, dtype=float), "sample"


def plot_residuals(result: EstimateResult, path: str | os.PathLike, t: np.ndarray | None = None) -> Path:
    """Residuals ``dv - S_V D_hat`` against time, one panel per axis, with +- 2 sigma lines."""
    from casep.estimators.result import AXES

    plt = pyplot()
    r = np.asarray(result.residuals).reshape(-1, 3)
    x, xlabel = _sample_times(result, t)
    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True, layout="constrained")
    rms = result.residual_rms
    for i, ax in enumerate(axes):
        ax.plot(x, r[:, i], lw=0.5)
        for sgn in (-2, 2):
            ax.axhline(sgn * result.sigma, color="tab:red", lw=0.8, ls="--")
        ax.set_ylabel(f"{AXES[i]} (m/s)")
        ax.set_title(f"RMS {rms[AXES[i]]:.4g} m/s", fontsize=8, loc="right")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{result.method} residuals dv - S_V D_hat (dashed: +- 2 sigma = {2 * result.sigma:.3g} m/s)",
                      fontsize=10, loc="left")
    axes[-1].set_xlabel(xlabel)
    return save_figure(fig, path)


def estimate_scales(result: EstimateResult, prior: Mapping | None = None,
                    bounds: Mapping | None = None) -> tuple[np.ndarray, list[str]]:
    """Per-coefficient scale for the normalised estimate plot and what it is.

    The prior std where a prior is given; else the half-width ``(hi - lo) / 2`` of a
    two-sided box; else the coefficient's own std (the estimate then plots as its t-ratio).
    NaN where none is defined.
    """
    n = len(result.names)
    scale = np.full(n, np.nan) if result.std is None else np.where(result.std > 0, result.std, np.nan)
    kind = ["own std"] * n
    if bounds is not None:
        from casep.estimators.bounded import parse_bounds

        lo, hi, _ = parse_bounds(bounds, result.names)
        box = np.isfinite(lo) & np.isfinite(hi) & (hi > lo)
        scale = np.where(box, (hi - lo) / 2, scale)  # half-width of the box
        kind = ["bound half-width" if box[j] else kind[j] for j in range(n)]
    if prior is not None:
        from casep.estimators.map import parse_prior

        _, tau = parse_prior(prior, result.names)
        has = np.isfinite(tau)
        scale = np.where(has, tau, scale)
        kind = ["prior std" if has[j] else kind[j] for j in range(n)]
    return scale, kind


def instrument_groups(names) -> dict[str, list[int]]:
    """Coefficient indices per instrument: ``gyro x``, ..., ``accelerometer z`` (names ``Kg<order><axis>...``,
    ``Ka<order><axis>...``), then ``other`` (tracking time offset, initial terms, lever arm, ...)."""
    import re

    out: dict[str, list[int]] = {}
    for j, n in enumerate(names):
        m = re.match(r"^K([ga])\d([xyz])", str(n))
        key = f"{'gyro' if m.group(1) == 'g' else 'accelerometer'} {m.group(2)}" if m else "other"
        out.setdefault(key, []).append(j)
    order = [f"{i} {a}" for i in ("gyro", "accelerometer") for a in "xyz"] + ["other"]
    return {k: out[k] for k in order if k in out}


def plot_estimates(result: EstimateResult, path: str | os.PathLike, *, prior: Mapping | None = None,
                   bounds: Mapping | None = None, scales: Mapping | None = None) -> Path:
    """Estimates +- 2 std against the declared magnitudes, one panel per instrument (:func:`instrument_groups`).

    Each coefficient is divided by its declared magnitude (``declare(Kg0x=("deg/h", 0.5))``; `scales`, default
    the result's model's), so the grey band +-1 is what the instrument's spec sheet allows and a bar well
    inside it a coefficient the flight determines; the natural unit of each coefficient is in its tick label.
    Coefficients without a declared magnitude use the prior std, the box half-width or their own std
    (:func:`estimate_scales`; the panel title says which). A panel whose values span more than 50 magnitudes
    has a symmetric-log axis, so that one large coefficient does not flatten the others.
    """
    plt = pyplot()
    n = len(result.names)
    if scales is None:
        try:
            from casep.model.loader import shipped_model

            found = shipped_model(result.model) if result.model else None  # never a file on the result's word
            scales = found.scales if found is not None else {}
        except Exception:  # a model file moved since: fall back on the other scales
            scales = {}
    fallback, kind = estimate_scales(result, prior, bounds)
    from casep.estimators.registry import declared_magnitude

    declared = np.array([np.nan if (d := declared_magnitude(scales, str(nm))) is None else d for nm in result.names],
                        float)
    scale = np.where(np.isfinite(declared), declared, fallback)
    kind = ["declared magnitude" if np.isfinite(declared[j]) else kind[j] for j in range(n)]
    z = result.estimate / scale
    err = None if result.std is None else 2 * result.std / scale
    mu: np.ndarray | None = None
    tau: np.ndarray | None = None
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    if prior is not None:
        from casep.estimators.map import parse_prior

        mu, tau = parse_prior(prior, result.names)
    if bounds is not None:
        from casep.estimators.bounded import parse_bounds

        lo, hi, _ = parse_bounds(bounds, result.names)
    groups = instrument_groups(result.names)
    ncol = min(3, len(groups))
    nrow = -(-len(groups) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow + 0.6), squeeze=False,
                             layout="constrained")
    for ax, (title, members) in zip(axes.ravel(), groups.items()):
        idx = np.asarray(members)
        x = np.arange(idx.size)
        ax.axhspan(-1.0, 1.0, color="0.88", zorder=0, label="declared magnitude")
        if mu is not None and tau is not None:
            has = np.isfinite(tau[idx])
            ax.errorbar(x[has] + 0.2, (mu / scale)[idx][has], yerr=(2 * tau / scale)[idx][has], fmt="s",
                        color="0.5", ms=3, capsize=2, label="prior mean +- 2 prior std")
        if lo is not None and hi is not None:
            for v, mk in ((lo, "^"), (hi, "v")):
                ok = np.isfinite(v[idx])
                ax.plot(x[ok], (v / scale)[idx][ok], mk, color="tab:red", ms=4, ls="none")
        ax.errorbar(x, z[idx], yerr=None if err is None else err[idx], fmt="o", ms=3, capsize=2,
                    label=f"{result.method} estimate +- 2 std")
        ax.axhline(0.0, color="k", lw=0.6)
        span = np.nanmax(np.abs(np.concatenate([z[idx], (z + err)[idx] if err is not None else z[idx]])))
        if np.isfinite(span) and span > 50:
            ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xticks(x, [f"{result.names[j]}\n{result.units[j]}" for j in idx], rotation=90, fontsize=6)
        kinds = sorted({kind[j] for j in idx})
        ax.set_title(f"{title}" + ("" if kinds == ["declared magnitude"] else f" (/ {', '.join(kinds)})"),
                     fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(groups):]:
        ax.set_visible(False)
    axes[0, 0].set_ylabel("estimate / declared magnitude")
    axes[0, 0].legend(fontsize=6, loc="best")
    fig.suptitle(f"{result.model} ({result.method}): estimate +- 2 std in units of the declared magnitude; grey: "
                 "+-1 declared magnitude; missing: not identifiable", fontsize=9, wrap=True)
    return save_figure(fig, path)


def best_determined(result: EstimateResult, count: int = 6) -> np.ndarray:
    """Indices of the `count` coefficients with the largest |estimate| / std."""
    if result.std is None:
        return np.array([], dtype=int)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(result.estimate) / result.std
    ratio = np.where(np.isfinite(ratio), ratio, -1.0)
    order = np.argsort(-ratio, kind="stable")
    return order[ratio[order] >= 0][:count]


def plot_history(result: EstimateResult, path: str | os.PathLike, t: np.ndarray | None = None,
                 count: int = 6) -> Path:
    """RLS/RELS estimate history of the best-determined coefficients with +- 2 std bands."""
    if result.history is None or result.history_std is None or result.std is None:
        raise ValueError(f"`result` of method {result.method} has no estimate and std history")
    plt = pyplot()
    stride = int(getattr(result.extras, "history_stride", None) or 1)  # the stride the history was kept at
    x_all, xlabel = _sample_times(result, t)
    rows = np.arange(result.history.shape[0]) * stride
    x = x_all[rows]
    idx = best_determined(result, count)
    ncol = 3
    nrow = max(1, -(-idx.size // ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(11, 2.6 * nrow), sharex=True, squeeze=False,
                             layout="constrained")
    for ax, j in zip(axes.flat, idx):
        h, s = result.history[:, j], result.history_std[:, j]
        ax.fill_between(x, h - 2 * s, h + 2 * s, color="tab:blue", alpha=0.2, lw=0)
        ax.plot(x, h, lw=1)
        e, sd = result.estimate[j], result.std[j]
        ax.set_ylim(e - 15 * sd, e + 15 * sd)  # the final +- 15 std: early P_0-sized bands are off scale
        ax.set_title(f"{result.names[j]} ({result.units[j]})", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[idx.size:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(xlabel)
    fig.suptitle(f"{result.method} estimate history +- 2 std (largest |estimate| / std)", fontsize=10)
    return save_figure(fig, path)


def separate_figures(result: EstimateResult, out: str | os.PathLike, t: np.ndarray | None = None, *,
                     prior: Mapping | None = None, bounds: Mapping | None = None) -> list[Path]:
    """The figures of one separation in folder `out` (created): residuals, estimates, history."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = [plot_residuals(result, out / "residuals.png", t),
             plot_estimates(result, out / "estimates.png", prior=prior, bounds=bounds)]
    if result.history is not None and result.history_std is not None:
        files.append(plot_history(result, out / "history.png", t))
    return files


# ----------------------------------------------------------------------------- impact
def plot_miss_budget(analysis, path: str | os.PathLike, top: int = 15) -> Path:
    """Miss budget: contribution of each coefficient to the downrange and crossrange miss (bars, m).

    The `top` largest coefficients (by |downrange| + |crossrange|), each with the 1-sigma error bar
    ``|G_j| std_j`` of its own estimate, then one bar per near-dependency group, then the total
    (linear prediction) with the std from ``G Cov G^T``. Contributions of strongly correlated
    coefficients cancel: the groups and the total are the numbers to read.
    """
    plt = pyplot()
    a = analysis
    c = np.nan_to_num(a.contributions, nan=0.0)
    order = np.argsort(-np.abs(c).sum(axis=0), kind="stable")[:top]
    sd = None
    if a.coefficient_std is not None:  # 1 sigma of each contribution alone: |G_j| std_j (0 without estimate)
        sd = np.abs(a.sensitivity) * np.nan_to_num(a.coefficient_std, nan=0.0)
    labels = [a.names[j] for j in order] + [_group_label(k, g.names) for k, g in enumerate(a.groups)] \
        + ["total (linear)"]
    W = 11.0
    fig, axes = plt.subplots(1, 2, figsize=(W, max(4.0, 0.32 * len(labels) + 1.5)), sharey=True)
    title = (f"Miss budget, {a.model} ({a.method}): blue coefficients, orange near-dependency groups, "
             "red total; bars 1 sigma")
    lines = int(np.ceil(text_width(title, 9) / (0.85 * W)))  # the suptitle wraps at the figure's width
    # left: the widest label (8 pt) and the tick; top: the suptitle's lines (9 pt) and the panel titles
    set_margins(fig, left=max(text_width(lb, 8) for lb in labels) + 0.25, right=0.3, bottom=0.65,
                top=0.1 + 0.17 * lines + 0.3, wspace=0.45)  # the last rotated tick label of the left panel
    y = np.arange(len(labels))[::-1]
    for i, (ax, what) in enumerate(zip(axes, ("downrange", "crossrange"))):
        vals = np.concatenate([c[i, order], [g.contribution[i] for g in a.groups], [a.miss[i]]])
        err = None
        if sd is not None:
            gsd = [np.nan if g.std is None else g.std[i] for g in a.groups]
            err = np.concatenate([sd[i, order], gsd, [a.std[i]]])
        colors = ["tab:blue"] * len(order) + ["tab:orange"] * len(a.groups) + ["tab:red"]
        ax.barh(y, vals, xerr=err, color=colors, ecolor="0.3", capsize=2)
        ax.axvline(0.0, color="0.3", lw=0.8)
        lin = max(1.0, float(np.nanmax(np.abs(vals))) * 1e-3)
        ax.set_xscale("symlog", linthresh=lin)
        _symlog_decade_ticks(ax, lin)
        plain_log_ticks(ax.xaxis)
        ax.set_xlabel(f"{what} miss, m")
        ax.tick_params(axis="x", labelrotation=30, labelsize=7)  # symlog ticks: keep them apart
        tot = f"{a.miss[i]:.4g}" + (f" +- {a.std[i]:.3g}" if a.std is not None else "")
        # y=1.0: where matplotlib would place it (no offset text on these axes), without measuring the ticks first
        ax.set_title(f"{what}: total {tot} m (nonlinear {a.nonlinear[i]:.4g} m)", fontsize=9, y=1.0)
        ax.grid(True, axis="x", alpha=0.3)
    axes[0].set_yticks(y, labels, fontsize=8)
    fig.suptitle(title, fontsize=9, wrap=True, y=1.0 - 0.08 / fig.get_size_inches()[1], va="top")
    return save_figure(fig, path, layout=None)


def _symlog_decade_ticks(ax: Any, linthresh: float) -> None:
    """Ticks of a symlog x axis at 0 and at the decades ``+-10^k >= linthresh / 2`` within its limits.

    On a symlog axis a decade below ``linthresh`` lies in the linear part, ``10^k / linthresh`` of a
    decade's width from 0: matplotlib's ticks at 1 and -1 beside 0 then overlap ("-1 0 1"); from
    ``linthresh / 2`` they are half a decade apart or more.
    """
    from matplotlib.ticker import FixedLocator

    top = max(abs(v) for v in ax.get_xlim())
    k0 = int(np.ceil(np.log10(linthresh / 2.0)))
    k1 = int(np.floor(np.log10(top))) if top > 0 else k0
    dec = [10.0 ** k for k in range(k0, k1 + 1)]
    ax.xaxis.set_major_locator(FixedLocator(sorted([-d for d in dec] + [0.0] + dec)))


def _group_label(k: int, names, width: int = 38) -> str:
    """``group 1: Kg0x, Kg1y, ...`` (its coefficients, cut to `width` characters)."""
    text = f"group {k + 1}: " + ", ".join(names)
    return text if len(text) <= width else text[: width - 3].rstrip(", ") + "..."


def plot_impact_ellipse(analysis, path: str | os.PathLike) -> Path:
    """Impact-point error: predicted miss (linear and nonlinear) with its 1-sigma and 95 % ellipses.

    Axes are the miss in downrange and crossrange (m) from the nominal impact point (the origin).
    Left: the miss against the nominal impact; right: zoomed on the prediction, where the ellipses
    are visible. The 95 % ellipse is ``sqrt(5.991)`` sigma (chi-square, 2 degrees of freedom).
    """
    plt = pyplot()
    a = analysis
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    set_margins(fig, left=0.95, right=0.12, bottom=0.5, top=0.3, wspace=0.95)  # tick labels up to 6 characters
    for k_ax, ax in enumerate(axes):
        if a.cov is not None:
            w, V = np.linalg.eigh(a.cov)
            th = np.linspace(0.0, 2 * np.pi, 241)
            circle = np.vstack([np.cos(th), np.sin(th)])
            for k, label, ls in ((1.0, "1 sigma", "-"), (np.sqrt(5.991), "95 %", "--")):
                e = V @ (np.sqrt(np.clip(w, 0.0, None))[:, None] * circle) * k  # V sqrt(L) unit circle
                ax.plot(a.miss[0] + e[0], a.miss[1] + e[1], ls, color="tab:blue", lw=1.2, label=label)
        ax.plot(*a.miss, "o", color="tab:blue", label="predicted (linear)")
        ax.plot(*a.nonlinear, "x", color="tab:red", ms=9, label="nonlinear (perturbed state flown)")
        if k_ax == 0:
            ax.plot(0.0, 0.0, "+", color="k", ms=12, label="nominal impact")
            ax.set_title(f"Impact point error, {a.model} ({a.method})", fontsize=10)
        else:
            ax.set_title("zoom on the prediction", fontsize=10)
        ax.set_xlabel("downrange miss, m")
        ax.set_ylabel("crossrange miss, m")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    return save_figure(fig, path, layout=None)


def impact_figures(analysis, out: str | os.PathLike) -> list[Path]:
    """`casep impact --figures DIR`: miss_budget.png and impact_ellipse.png in `out` (created)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_miss_budget(analysis, out / "miss_budget.png"),
            plot_impact_ellipse(analysis, out / "impact_ellipse.png")]


def plot_allan(noise, path: str | os.PathLike) -> Path:
    """Allan deviation of the residuals per axis with the fitted noise models
    (:func:`casep.noise.identification.identify_noise`); the chosen model drawn solid."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    for i, a in enumerate("xyz"[: noise.adev.shape[0]]):
        ax.loglog(noise.taus, noise.adev[i], "o", ms=3, alpha=0.6, label=f"residuals {a}")
    for k, style in (("white", ":"), ("gauss_markov", "--"), ("random_walk", "-.")):
        p = noise.fits[k]
        par = ", ".join(f"{n} {v:.3g}" for n, v in p.items() if n not in ("chi2", "bic"))
        ls = "-" if k == noise.choice else style
        lw = 2.0 if k == noise.choice else 1.0
        ax.loglog(noise.taus, np.sqrt(noise.model_avar(k)), ls, lw=lw, label=f"{k} ({par})")
    ax.set_xlabel("averaging time tau (s)")
    ax.set_ylabel("Allan deviation (m/s)")
    ax.set_title(f"Noise of the residuals: {noise.choice.replace('_', '-')}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return save_figure(fig, path)


def plot_design(result, path: str | os.PathLike) -> Path:
    """`casep design --figure`: the designed manoeuvre (offsets at the knots, deg, against time) and the
    CRLB std per coefficient before and after, as a ratio to the coefficient's declared magnitude
    (log scale; below 1 = identifiable; an undetermined coefficient is drawn at the top, hollow)."""
    plt = pyplot()
    r = result
    m = r.maneuver.to_dict(r.x)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(12, 8), gridspec_kw={"height_ratios": [1, 1.4]},
                                 layout="constrained")
    for axis, color in (("pitch", "tab:orange"), ("yaw", "tab:blue")):
        if axis in r.maneuver.axes:
            a1.plot(m["knots_s"], m[f"{axis}_deg"], "o-", color=color, label=f"{axis} offset")
    lim = r.constraints["max_angle_deg"]
    a1.axhline(lim, color="grey", ls="--", lw=0.8, label=f"+-{lim:g} deg")
    a1.axhline(-lim, color="grey", ls="--", lw=0.8)
    a1.set_xlabel("time, s")
    a1.set_ylabel("offset from nominal attitude, deg")
    a1.set_title(f"{r.objective}-optimal {r.maneuver.kind} manoeuvre: objective {r.before:.4g} -> {r.after:.4g}",
                 fontsize=10)
    a1.grid(True, alpha=0.3)
    a1.legend(fontsize=8)
    x = np.arange(len(r.names))
    before, after = r.crlb_before / r.scales, r.crlb_after / r.scales
    finite = np.concatenate([before[np.isfinite(before)], after[np.isfinite(after)]])
    top = 10 ** np.ceil(np.log10(finite.max())) if finite.size else 10.0
    for vals, off, color, label in ((before, -0.18, "tab:grey", "nominal flight"),
                                    (after, 0.18, "tab:green", "designed flight")):
        ok = np.isfinite(vals)
        a2.plot(x[ok] + off, vals[ok], "o", color=color, label=label)
        if np.any(~ok):
            a2.plot(x[~ok] + off, np.full((~ok).sum(), top), "o", mfc="none", color=color)
    a2.axhline(1.0, color="k", lw=0.8, ls="--", label="declared magnitude")
    a2.set_yscale("log")
    a2.set_xticks(x)
    a2.set_xticklabels(r.names, rotation=90, fontsize=8)
    a2.set_ylabel("CRLB std / declared magnitude")
    a2.set_title("Cramer-Rao bound per coefficient" + (" (Bayesian, with the prior)" if r.prior else ""), fontsize=10)
    a2.grid(True, alpha=0.3, which="both", axis="y")
    a2.legend(fontsize=8)
    return save_figure(fig, path)
