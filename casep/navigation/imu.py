"""Raw IMU files: body rates and specific forces, or angle and velocity increments, checked at the edge.

Two layouts (CSV or Parquet, one row per sample, body axes):

- **rates**: ``t`` (s), ``w_x, w_y, w_z`` (body rate, rad/s), ``fb_x, fb_y, fb_z`` (body specific
  force, m/s^2), each sampled at ``t``;
- **increments**: ``t`` (s), ``dth_x, dth_y, dth_z`` (angle increment, rad: the integral of the
  body rate), ``dvb_x, dvb_y, dvb_z`` (velocity increment, m/s: the integral of the body specific
  force), each over the sample period that ends at ``t``.

Checks: a missing column, a bad cell or time that does not increase is an error naming the file,
column and row (:class:`casep.io.tables.Table`). Lost samples (a step over 1.5 times the median) are
integrated across, with a :class:`~casep.exceptions.GapWarning` giving their count and the longest
gap; an increment after a gap covers one nominal period and stands for the whole step (the rate
held over the lost samples). Rates beyond any gyro's full scale (200 rad/s) are an error (deg/s
declared rad/s), rates over 35 rad/s (2000 deg/s) or specific forces over 50 g a
:class:`~casep.exceptions.PlausibilityWarning`, with the numbers. The gap warning also states what
the lost samples leave unknown (:func:`bridge_gaps`, the largest bound given with its time).

Across a gap of rate samples (:func:`bridge_gaps`) the rate and the specific force are bridged by one
cubic fitted by least squares to the samples on both sides, on each side as many as half the gap
holds (``M = h / (2 h_med)``, at least 2, at most :data:`BRIDGE_MAX`, never across another gap), and
integrated over the gap: the cubic through the four neighbouring samples for a short gap, and for a
long one a fit whose noise averages out (the cubic through four noisy samples 1 s apart would
amplify their noise a hundredfold). What the bridge leaves unknown, per gap: the motion (any path
between the two sides fits: ``|x_b - x_a| h / 2`` with ``x_a``, ``x_b`` the fit at the gap's ends)
plus three times the noise of the bridge's integral, ``sqrt(sum_axes s^2 (a^T (X^T X)^-1 a + h
h_med))``: the fit's own (``a`` the integral of the cubic's basis over the gap, ``X`` the fitted
samples' basis, ``s`` their residual std) and that of the lost samples themselves. For the rate this
is the attitude across the gap, rad (after it a velocity error grows by up to ``|f|`` times it per
second); for the specific force the velocity across it, m/s.

Steps between consecutive rate samples (:func:`sample_steps`: lift-off, staging, a pitch kick): a sampled record
does not say where in the interval the step fell, and the integration (a straight line between samples) leaves the
velocity and attitude across it unknown within ``|x_k+1 - x_k| h / 2``. They are found when the record is read
(``ImuData.steps``), printed by ``casep navigate`` (:func:`steps_said`) and carried in the std of ``casep separate
--imu`` (:func:`casep.workflows.imu_separate.step_rows`).

Clipped samples (:func:`clipped_samples`): a reading at the sensor's full scale is not the motion. The
rule is :func:`casep.fullscale.held_full_scale`, the one calibration uses too: a run of
:data:`~casep.fullscale.CLIP_RUN` (3) samples or more at a full scale: with a declared one
(``gyr_range`` rad/s, ``acc_range`` m/s^2) a component at or beyond 99 % of it
(:data:`~casep.fullscale.CLIP_MARGIN`); without one, the column's extreme value held, where it lies
within :data:`casep.units.FULL_SCALE_TOLERANCE` of a nominal range (:data:`casep.units.GYR_RANGES_DPS`,
:data:`casep.units.ACC_RANGES_G`), a tenth of it or more from the column's median (a static accelerometer
reads 1 g for ever without clipping), in a column with noise (in a noise-free record a constant thrust near
4 g is held exactly without any clipping: declare the full scale there); off every nominal range, a full scale
the data imply (a run of equal readings the column's noise cannot make, left or held to the end, or in a
column without noise a run entered and left). Increments are judged as the IMU gave them, each over its
period (rad, m/s; compared with a full scale times the median step), not divided by the steps of ``t``,
whose rounding would make a value held exactly look like noise. The attitude and velocity
integrated through a clipped sample stay wrong for the rest of the record, so everything from the
first clipped sample on is marked (``ImuData.clipped``; the navigation writes ``ins_valid = 0``
there, and the separation leaves those rows out), with a :class:`~casep.exceptions.SaturationWarning`
naming the columns, the rows, the times and the full scale.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass

import numpy as np

from casep.checks.saturation import (
    CLIP_MARGIN,
    FULL_SCALE_UNITS,
    beyond_declared,
    check_full_scale,
    held_full_scale,
    held_mask,
)
from casep.exceptions import GapWarning, PlausibilityWarning, SaturationWarning
from casep.io.flight import LOST_SAMPLE_FACTOR, STEP_FACTOR, gap_steps, signal_steps

__all__ = ["ImuData", "read_imu", "check_imu", "RATE_COLUMNS", "FORCE_COLUMNS", "DTHETA_COLUMNS", "DV_COLUMNS",
           "GAP_FACTOR", "BRIDGE_MAX", "IMU_STEP_RANGE", "time_step_problem", "GapBridge", "bridge_gaps",
           "gap_steps", "clipped_samples", "sample_periods", "with_rates", "regular_time", "single_sample_spikes",
           "SPIKE_BLOCK", "SPIKE_ROUNDING", "SampleSteps", "sample_steps", "split_steps", "STEP_FACTOR", "steps_said",
           "on_clock"]

RATE_COLUMNS = ("w_x", "w_y", "w_z")
FORCE_COLUMNS = ("fb_x", "fb_y", "fb_z")
DTHETA_COLUMNS = ("dth_x", "dth_y", "dth_z")
DV_COLUMNS = ("dvb_x", "dvb_y", "dvb_z")
#: A step longer than this many median steps has lost samples (:data:`casep.io.flight.LOST_SAMPLE_FACTOR`).
GAP_FACTOR = LOST_SAMPLE_FACTOR
#: Samples on each side of a gap its bridge is fitted to, at most (:func:`bridge_gaps`).
BRIDGE_MAX = 400
#: The median time steps of an IMU record, s: 1 MHz to 5 Hz (IMUs sample at 10 Hz-100 kHz); outside, `t` is
#: in another unit (:func:`check_imu` refuses it).
IMU_STEP_RANGE = (1e-6, 0.2)
#: Rates beyond this are refused (no gyro's full scale reaches it: deg/s declared rad/s), rad/s.
MAX_RATE = 200.0
#: Rates beyond this (2000 deg/s, the largest common full scale) and specific forces beyond 50 g are warned about.
WARN_RATE = 35.0
WARN_FORCE = 50 * 9.80665


@dataclass
class ImuData:
    """IMU samples in SI units, body axes.

    Attributes
    ----------
    t : (N,) ndarray
        Times, s, increasing.
    w, f : (N, 3) ndarray
        Body rate (rad/s) and specific force (m/s^2): measured (rates) or the increments over their
        sample period divided by it (increments).
    kind : str
        ``"rates"`` or ``"increments"``.
    dtheta, dv : (N, 3) ndarray or None
        Increments: each row over the period ending at ``t`` (after a gap: scaled to the whole step).
    source : str
        The file, for messages.
    gaps : int
        Steps with lost samples.
    clipped : (N,) ndarray of bool or None
        Samples at or after the first clipped one (:func:`clipped_samples`); None: none checked or none found.
    """

    t: np.ndarray
    w: np.ndarray
    f: np.ndarray
    kind: str = "rates"
    dtheta: np.ndarray | None = None
    dv: np.ndarray | None = None
    source: str = "<memory>"
    gaps: int = 0
    clipped: np.ndarray | None = None
    #: The steps between consecutive rate samples (:func:`sample_steps`; None: increments, or none checked).
    steps: SampleSteps | None = None


def read_imu(path: str | os.PathLike, *, gyr_range: float | None = None, acc_range: float | None = None) -> ImuData:
    """Read and check an IMU file (layout by its columns: rates, else increments); see the module docstring.

    `gyr_range` (rad/s) and `acc_range` (m/s^2): the sensors' declared full scales (:func:`clipped_samples`).
    """
    from casep.io.tables import Table

    tab = Table(path)
    if tab.has(("t",) + DTHETA_COLUMNS + DV_COLUMNS) and not tab.has(RATE_COLUMNS):
        tab.require(("t",) + DTHETA_COLUMNS + DV_COLUMNS)
        t = tab.time()
        return check_imu(ImuData(t, np.zeros((len(t), 3)), np.zeros((len(t), 3)), "increments",
                                 tab.vectors(DTHETA_COLUMNS), tab.vectors(DV_COLUMNS), tab.src),
                         gyr_range=gyr_range, acc_range=acc_range)
    tab.require(("t",) + RATE_COLUMNS + FORCE_COLUMNS,
                "; an IMU file holds t, w_x..w_z (rad/s), fb_x..fb_z (m/s^2), or t, dth_x..dth_z (rad), "
                "dvb_x..dvb_z (m/s)")
    t = tab.time()
    return check_imu(ImuData(t, tab.vectors(RATE_COLUMNS), tab.vectors(FORCE_COLUMNS), "rates", source=tab.src),
                     gyr_range=gyr_range, acc_range=acc_range)


def time_step_problem(h: float) -> str | None:
    """Why an IMU's median time step `h` (read as s) is not one, with the unit that would make it one, or None.

    IMUs sample at 10 Hz-100 kHz; a median step outside :data:`IMU_STEP_RANGE` is a time column in ms, us or
    ns (a 100 Hz IMU with t in ms has a step of 10 "s"), or not a time."""
    lo, hi = IMU_STEP_RANGE
    if lo <= h <= hi:
        return None
    fits = [u for u, k in (("ms (divide by 1000)", 1e-3), ("us (divide by 1e6)", 1e-6), ("ns (divide by 1e9)", 1e-9))
            if lo <= h * k <= hi]
    hint = f": is t in {fits[0]}?" if fits else ": is t in seconds?"
    return (f"median time step {h:.4g} s ({1 / h:.4g} Hz), outside the {1 / hi:g} Hz-{1 / lo:.0e} Hz an IMU "
            f"samples at{hint}")


def check_imu(imu: ImuData, *, gyr_range: float | None = None, acc_range: float | None = None) -> ImuData:
    """Check an IMU record (gaps, units, clipped samples) and, for increments, fill ``w``, ``f``; returns it.

    `gyr_range` (rad/s), `acc_range` (m/s^2): declared full scales (:func:`clipped_samples`), else nominal ranges.

    Raises
    ------
    ValueError
        Fewer than 3 samples, time not increasing, a rate beyond :data:`MAX_RATE`, or a full scale that is
        not a finite number > 0 (:func:`casep.checks.saturation.check_full_scale`).
    """
    for name, value, unit in (("gyr_range", gyr_range, "rad/s"), ("acc_range", acc_range, "m/s^2")):
        if value is not None:
            check_full_scale(value, name, "--" + name.replace("_", "-"), unit)
    t = np.asarray(imu.t, float)
    if t.ndim != 1 or len(t) < 3:
        raise ValueError(f"{imu.source}: an IMU record needs at least 3 samples, got {t.size}")
    h = np.diff(t)
    if np.any(h <= 0):
        k = int(np.flatnonzero(h <= 0)[0]) + 1
        raise ValueError(f"{imu.source}: column t, row {k + 1}: time {t[k]:.10g} s does not increase")
    h_med = float(np.median(h))
    why = time_step_problem(h_med)
    if why is not None:
        raise ValueError(f"{imu.source}: column t: {why}")
    lost = gap_steps(t)
    raw = None  # the increments as the IMU gave them, each over its period: the clip is judged on these
    if imu.kind == "increments":
        raw = (np.asarray(imu.dtheta, float), np.asarray(imu.dv, float))
        cover = np.concatenate([[h_med], np.where(h > GAP_FACTOR * h_med, h_med, h)])  # what each row integrates
        scale = np.concatenate([[1.0], h])[:, None] / cover[:, None]
        scale[0] = 1.0
        imu.dtheta = np.asarray(imu.dtheta, float) * scale  # after a gap: the rate held over the whole step
        imu.dv = np.asarray(imu.dv, float) * scale
        step = sample_periods(t)[:, None]
        imu.w, imu.f = imu.dtheta / step, imu.dv / step
    if lost.size:
        _warn_gaps(imu, lost, h, h_med)
    imu.gaps = int(lost.size)
    _check_units(imu, declared=gyr_range is not None and float(np.abs(imu.w).max()) <= (1 + CLIP_MARGIN) * gyr_range)
    imu.clipped = _check_clipped(imu, gyr_range, acc_range, raw, h_med)
    _warn_spikes(imu, h_med)
    if imu.kind == "rates":
        imu.steps = sample_steps(t, imu.w, imu.f)
    return imu


@dataclass
class GapBridge:
    """The bridge of each gap of a rate record (:func:`bridge_gaps`; module notes).

    Attributes
    ----------
    steps : (G,) ndarray of int
        The step ``t[k] -> t[k+1]`` of each gap.
    h : (G,) ndarray
        Gap lengths, s.
    dtheta, dv : (G, 3) ndarray
        The bridge's integrals of the body rate (rad) and specific force (m/s) over each gap.
    attitude, velocity : (G,) ndarray
        What each gap leaves unknown of the attitude (rad) and of the velocity (m/s): the motion term plus
        three times the noise of the integral.
    motion : (G, 2) ndarray
        The motion terms of `attitude` and `velocity`.
    noise : (G, 2) ndarray
        The rate's (rad/s) and the specific force's (m/s^2) sample noise near each gap (residual std of
        the fits, largest axis).
    """

    steps: np.ndarray
    h: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    attitude: np.ndarray
    velocity: np.ndarray
    motion: np.ndarray
    noise: np.ndarray


def _bridge_one(t: np.ndarray, x: np.ndarray, k: int, lo: int, hi: int,
                h_med: float) -> tuple[np.ndarray, float, float, float]:
    """(integral over the gap (3,), its bound, the bound's motion term, the residual std) of the cubic fitted
    to ``x[lo:k+1]`` and ``x[k+1:hi]`` (module notes)."""
    idx = np.r_[lo:k + 1, k + 1:hi]
    mid, half = 0.5 * (t[k] + t[k + 1]), 0.5 * (t[k + 1] - t[k])
    u = (t[idx] - mid) / half  # the gap is [-1, 1]
    order = min(3, idx.size - 1)
    X = u[:, None] ** np.arange(order + 1)
    a = half * np.array([(1.0 - (-1.0) ** (j + 1)) / (j + 1) for j in range(order + 1)])  # int over the gap
    coef, *_ = np.linalg.lstsq(X, x[idx], rcond=None)
    dof = idx.size - order - 1
    s = np.sqrt(np.sum((x[idx] - X @ coef) ** 2, axis=0) / dof) if dof > 0 else np.zeros(3)
    var_fit = float(a @ np.linalg.pinv(X.T @ X) @ a)
    noise = 3.0 * float(np.sqrt(np.sum(s**2) * (var_fit + 2.0 * half * h_med)))
    ends = np.array([[1.0, -1.0, 1.0, -1.0][: order + 1], np.ones(order + 1)]) @ coef  # x at the gap's ends
    motion = float(np.linalg.norm(ends[1] - ends[0])) * half  # |x_b - x_a| h / 2
    return a @ coef, motion + noise, motion, float(s.max())


def bridge_gaps(t: np.ndarray, w: np.ndarray, f: np.ndarray) -> GapBridge:
    """The bridge of each gap of body rates `w` (rad/s) and specific forces `f` (m/s^2) at times `t` (module notes)."""
    t, w, f = np.asarray(t, float), np.asarray(w, float), np.asarray(f, float)
    steps = gap_steps(t)
    h_med = float(np.median(np.diff(t)))
    n, G = t.size, steps.size
    out = GapBridge(steps, t[steps + 1] - t[steps], np.zeros((G, 3)), np.zeros((G, 3)), np.zeros(G), np.zeros(G),
                    np.zeros((G, 2)), np.zeros((G, 2)))
    edges = np.r_[-1, steps, n - 1]  # the gaps around each one: its fit stops at them
    for g, k in enumerate(steps):
        m = int(np.clip(round(0.5 * out.h[g] / h_med), 2, BRIDGE_MAX))
        lo, hi = max(k - m + 1, edges[g] + 1), min(k + 1 + m, edges[g + 2] + 1)
        out.dtheta[g], out.attitude[g], out.motion[g, 0], out.noise[g, 0] = _bridge_one(t, w, int(k), lo, hi, h_med)
        out.dv[g], out.velocity[g], out.motion[g, 1], out.noise[g, 1] = _bridge_one(t, f, int(k), lo, hi, h_med)
    return out


@dataclass
class SampleSteps:
    """The steps between consecutive rate samples (:func:`sample_steps`) and what each leaves unknown.

    Attributes
    ----------
    k : (S,) ndarray of int
        The interval ``t[k] -> t[k+1]`` holding each step.
    h : (S,) ndarray
        Its length, s.
    dw, df : (S, 3) ndarray
        The step of the body rate (rad/s) and of the body specific force (m/s^2), body axes.
    attitude, velocity : (S,) ndarray
        The bounds ``|dw| h / 2`` (rad) and ``|df| h / 2`` (m/s) of what the integration over the interval leaves
        unknown.
    """

    k: np.ndarray
    h: np.ndarray
    dw: np.ndarray
    df: np.ndarray
    attitude: np.ndarray
    velocity: np.ndarray


def sample_steps(t: np.ndarray, w: np.ndarray, f: np.ndarray) -> SampleSteps:
    """The steps of the body rate `w` (rad/s) and specific force `f` (m/s^2) sampled at `t` (module notes).

    A rate record samples the rate and the specific force; it does not say how they went between two samples, and
    the integration takes them as straight lines (the trapezoid). Where a signal steps between ``t_k`` and
    ``t_{k+1}`` (thrust at lift-off, staging, a pitch kick) the step happened somewhere in the interval; its
    integral over it is then anywhere within ``(x_{k+1} - x_k) h / 2`` of the trapezoid's (the step at either
    end), the same bound as a gap's motion term (:func:`bridge_gaps`). A step is a jump
    :func:`casep.io.flight.signal_steps` finds beyond :data:`STEP_FACTOR` times the column's sample-to-sample noise
    (the robust scatter of its second differences, ``1.4826 MAD``: a white noise's jumps stay within about 5 of it),
    beyond a millionth of the sensor's largest reading and beyond half the interval's own difference (a sample at a
    step's middle splits it over two intervals, and the trapezoid integrates the pair exactly); the intervals
    touching a gap are the bridge's (:func:`bridge_gaps`)."""
    t, w, f = np.asarray(t, float), np.asarray(w, float), np.asarray(f, float)
    found, _, jumps = _step_axes(t, w, f)
    h = np.diff(t)
    k = np.flatnonzero(found)
    dw, df = jumps[0][k], jumps[1][k]
    return SampleSteps(k, h[k], dw, df, np.linalg.norm(dw, axis=1) * h[k] / 2, np.linalg.norm(df, axis=1) * h[k] / 2)


def _step_axes(t: np.ndarray, w: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """:func:`sample_steps`'s rule: ``(found (N-1,), [axes of w, of f] (N-1, 3) bool, [jumps of w, of f])``."""
    found = np.zeros(t.size - 1, bool)
    jumps, axes = [], []
    for x in (w, f):
        big, J = signal_steps(t, x)
        found |= np.any(big, axis=1)
        jumps.append(J)
        axes.append(big)
    return found, axes, jumps


def split_steps(t: np.ndarray, w: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`w`, `f` with the sample after each step between samples (:func:`sample_steps`) holding the mean of it and the
    sample before, on the axes that step: for a simulated record whose truth steps exactly at a sample time ``t_k+1``
    (ignition, a pitch kick) and which samples the value after it, so that the integration takes the step exactly.
    With ``m = (x_k + x_k+1) / 2`` the two trapezoids around the sample sum to ``(x_k + m) h / 2 + (m + x_k+2) h / 2 =
    x_k h + (x_k+1 + x_k+2) h / 2``: the value before the step held up to it, then the trapezoid (exact for a constant
    before the step; the velocity is off by ``|dx| h / 4`` at ``t_k+1`` alone); read as is, the sample after the
    step leaves it off by ``|dx| h / 2`` for the rest of the record. Not for a real record: where its steps fell is
    unknown (:func:`casep.workflows.imu_separate.step_rows` carries that)."""
    t, w, f = np.asarray(t, float), np.asarray(w, float).copy(), np.asarray(f, float).copy()
    if t.size < 4:
        return w, f
    _, axes, _ = _step_axes(t, w, f)
    for x, big in zip((w, f), axes):
        k, c = np.nonzero(big)
        x[k + 1, c] = 0.5 * (x[k, c] + x[k + 1, c])  # the right side is evaluated before the assignment
    return w, f


#: The steps a warning lists one by one, at most (the largest bounds first).
STEPS_LISTED = 3


def steps_said(imu: ImuData) -> str | None:
    """What the steps between samples of `imu` (:func:`sample_steps`) leave unknown: their count, and the largest
    (:data:`STEPS_LISTED`) with time, rows, size and bounds; None without one. ``casep navigate`` prints it, and
    ``casep separate --imu`` says it with the std that carry them (:func:`casep.workflows.imu_separate.step_rows`)."""
    st = imu.steps
    if st is None or not st.k.size:
        return None
    fmax = float(np.linalg.norm(imu.f, axis=1).max())
    order = np.argsort(-(st.velocity + fmax * st.attitude))[:STEPS_LISTED]
    each = "; ".join(
        f"t = {imu.t[st.k[i]]:.10g} .. {imu.t[st.k[i] + 1]:.10g} s (rows {st.k[i] + 1}-{st.k[i] + 2}): specific force "
        f"step {np.linalg.norm(st.df[i]):.4g} m/s^2, body rate step {np.linalg.norm(st.dw[i]):.4g} rad/s: the velocity "
        f"across it unknown within +-{st.velocity[i]:.3g} m/s, the attitude within +-{st.attitude[i]:.3g} rad (a "
        f"velocity error growing by up to {fmax * st.attitude[i]:.3g} m/s per s)" for i in order)
    n = st.k.size
    return (f"{imu.source}: {n} step{'s' if n > 1 else ''} between consecutive samples of fb_*/w_* (a jump beyond "
            f"{STEP_FACTOR:g} times the sample-to-sample noise): a sampled record does not say where in the interval "
            "a step happened, and the integration takes the signal as a straight line between the samples, so the "
            f"velocity and attitude across each are known within half the step times the interval only; {each}"
            + (f"; and {n - len(order)} more" if n > len(order) else "")
            + " (increments, dth_* and dvb_*, leave no such ambiguity)")


def _warn_gaps(imu: ImuData, lost: np.ndarray, h: np.ndarray, h_med: float) -> None:
    """The GapWarning: count, samples lost, the longest gap and where, and what the largest leaves unknown."""
    t = imu.t
    k = int(lost[np.argmax(h[lost])])
    missing = int(np.sum(np.round(h[lost] / h_med) - 1))
    br = bridge_gaps(t, imu.w, imu.f)
    fmax = float(np.linalg.norm(imu.f, axis=1).max())
    gaps = f"{lost.size} gap{'s' if lost.size > 1 else ''}"
    how = ("the rate and specific force bridged by a cubic fitted to the samples either side" if imu.kind == "rates"
           else "the increment after it held over it")

    def known(m: int) -> str:  # what the bridge of gap m (an index of br.steps) leaves unknown
        return (f"the velocity across it is known to about {br.velocity[m]:.3g} m/s only (any path of the specific "
                f"force between the two sides of its {br.h[m]:.4g} s: {br.motion[m, 1]:.3g} m/s; the rest, "
                f"{br.velocity[m] - br.motion[m, 1]:.3g} m/s, from the samples' scatter about the bridge, "
                f"{br.noise[m, 1]:.3g} m/s^2 per sample), the attitude to about {br.attitude[m]:.3g} rad (gyro noise "
                f"{br.noise[m, 0]:.3g} rad/s included; after it a velocity error grows by up to "
                f"{fmax * br.attitude[m]:.3g} m/s per s)")

    said = (f"{imu.source}: {gaps} in t (about {missing} samples lost at the median step "
            f"{h_med:.4g} s); the longest {h[k]:.4g} s after t = {t[k]:.10g} s (row {k + 1}): "
            f"integrated across it, {how}")
    at = np.flatnonzero(br.steps == k)
    if at.size:
        said += f"; {known(int(at[0]))}"
    worst = int(np.argmax(br.velocity)) if br.steps.size else -1
    if worst >= 0 and (not at.size or (worst != int(at[0]) and br.velocity[worst] > br.velocity[at[0]])):
        said += (f"; the velocity is least known across the {br.h[worst]:.4g} s gap after t = "
                 f"{t[br.steps[worst]]:.10g} s: {known(worst)}")
    warnings.warn(said,
                  GapWarning, stacklevel=3)


def clipped_samples(x: np.ndarray, full_scale: float | None, sensor: str, period: float | None = None) -> np.ndarray:
    """The (N, 3) readings of `x` at the sensor's full scale (:func:`casep.fullscale.held_full_scale`).

    Parameters
    ----------
    x : (N, 3) ndarray
        Body rates (rad/s) or specific forces (m/s^2); with `period`, their increments over it (rad, m/s).
    full_scale : float or None
        The declared full scale, rad/s or m/s^2; None: the nominal ranges of `sensor`.
    sensor : str
        ``"gyro"`` or ``"accelerometer"``.
    period : float, optional
        The period each increment of `x` integrates, s (the readings' SI factor is ``1 / period``).

    Returns
    -------
    (N, 3) ndarray of bool
    """
    x = np.asarray(x, float)
    si = 1.0 if period is None else 1.0 / period
    return held_mask(held_full_scale(x, sensor, si=si, declared=full_scale), x.shape)


def _check_clipped(imu: ImuData, gyr_range: float | None, acc_range: float | None,
                   raw: tuple[np.ndarray, np.ndarray] | None = None, period: float = 1.0) -> np.ndarray | None:
    """Samples from the first clipped one on (None when none is), with a SaturationWarning.

    Rates are screened as read; increments as read too (`raw`: each over the IMU's `period`, s), not divided by
    the steps of ``t``, whose rounding would make a reading held exactly look like noise."""
    found = []
    inc = raw is not None
    for (cols, x, fs, sensor), r in zip(((DTHETA_COLUMNS if inc else RATE_COLUMNS, imu.w, gyr_range, "gyro"),
                                         (DV_COLUMNS if inc else FORCE_COLUMNS, imu.f, acc_range, "accelerometer")),
                                        raw or (None, None)):
        unit, per = FULL_SCALE_UNITS[sensor]
        x, si = (np.asarray(r, float), 1.0 / period) if r is not None else (x, 1.0)
        beyond = beyond_declared(x, sensor, fs, si)
        if beyond is not None:
            j, row, said = beyond
            raise ValueError(f"{imu.source}: column `{cols[j]}`, row {row + 1} (t = {imu.t[row]:.10g} s): {said}")
        col_unit = ("rad" if sensor == "gyro" else "m/s") if inc else ("rad/s" if sensor == "gyro" else "m/s^2")
        for h in held_full_scale(x, sensor, si=si, declared=fs):
            rows = np.flatnonzero(held_mask([h], x.shape)[:, h.axis])
            why = f"the declared {fs / per:g} {unit}" if fs is not None else h.why
            over = f" over {period:.6g} s" if inc else ""
            found.append((int(rows[0]), f"{cols[h.axis]}: {rows.size} samples at full scale ({why}), its {h.side} "
                                        f"{h.value:.6g} {col_unit}{over} = {h.value * si / per:.6g} {unit}, rows "
                                        f"{rows[0] + 1}..{rows[-1] + 1}, t = {imu.t[rows[0]]:.10g} .. "
                                        f"{imu.t[rows[-1]]:.10g} s"))
    if not found:
        return None
    first = min(k for k, _ in found)
    warnings.warn(f"{imu.source}: the IMU clipped: " + "; ".join(m for _, m in sorted(found)) + ". The attitude and "
                  f"velocity are wrong from t = {imu.t[first]:.10g} s (row {first + 1}) on: the navigation marks "
                  "them (ins_valid = 0) and the separation leaves them out", SaturationWarning, stacklevel=3)
    clipped = np.zeros(imu.t.size, bool)
    clipped[first:] = True
    return clipped


def regular_time(t: np.ndarray, *, tolerance: float = 0.25) -> np.ndarray | None:
    """The uniform grid a fixed-rate IMU's samples lie on, when their time tags only jitter about it; else None.

    A MEMS IMU samples at its own output data rate; a logger that stamps each sample with its own
    clock when it reads it (an integer millisecond counter, say) adds jitter to the tags, not to the
    samples. Integrating ``w_k h_k`` with the tags' steps ``h_k`` then turns the jitter into angle
    errors, ``sum_k w_k (e_k - e_{k-1})`` for tag errors ``e_k``: with vibration rates of several deg/s
    a random walk in attitude. The grid ``t_k = a + b k`` is the least-squares line of the tags on the
    sample index; it is returned when every tag lies within ``tolerance`` steps of it (a lost sample
    would shift all later tags by a whole step, so none was lost and the rate did not change).

    Parameters
    ----------
    t : (N,) array_like
        Time tags, s, increasing.
    tolerance : float
        Largest distance of a tag from the grid, in steps ``b``.

    Returns
    -------
    (N,) ndarray or None
        The grid (its mean and mean step are the tags'), or None when a tag is farther from it.
    """
    t = np.asarray(t, float)
    k = np.arange(t.size, dtype=float)
    b, a = np.polyfit(k, t, 1)
    grid = a + b * k
    return grid if float(np.max(np.abs(t - grid))) <= tolerance * b else None


def sample_periods(t: np.ndarray) -> np.ndarray:
    """The period each increment row is divided by to give a rate, s: the step ending at its time (the
    median step for the first row)."""
    h = np.diff(t)
    return np.concatenate([[float(np.median(h))], h])


def with_rates(imu: ImuData, w: np.ndarray, f: np.ndarray) -> ImuData:
    """A copy of `imu` with body rate `w` (rad/s) and specific force `f` (m/s^2) in place of its own; increments
    become them times :func:`sample_periods` (the inverse of :func:`check_imu`'s division)."""
    import dataclasses

    out = dataclasses.replace(imu, w=np.asarray(w, float), f=np.asarray(f, float))
    if imu.kind == "increments":
        step = sample_periods(imu.t)[:, None]
        out.dtheta, out.dv = out.w * step, out.f * step
    return out


def on_clock(imu: ImuData, drift_ppm: float, about: float = 0.0) -> ImuData:
    """`imu` with its time tags at the tracking clock's rate: ``about + (t - about) (1 + drift_ppm 1e-6)``
    (:func:`casep.io.pair.tracking_time` without its shift, about IMU time 0 by default; `drift_ppm` as
    ``clock_drift``: the tracking time tags late by ``drift_ppm 1e-6 t`` more at IMU time ``t``).

    An IMU clock running fast by ``d`` tags true time ``t`` as ``t (1 + d)``: its samples are right each (a rate
    or specific force as sensed, an increment over the true interval) and only its tags and steps are stretched,
    so a navigation on them integrates every rate over steps ``(1 + d)`` too long (a common scale factor ``d`` on
    every gyro and accelerometer, gravity's integral too) and its states sit ``d t`` late against the tracking.
    Rates keep their readings; increments keep theirs, divided by the steps anew (:func:`sample_periods`); the
    record itself when `drift_ppm` is 0."""
    import dataclasses

    from casep.io.pair import tracking_time

    if drift_ppm == 0.0:
        return imu
    t = tracking_time(imu.t - about, 0.0, drift_ppm) + about
    out = dataclasses.replace(imu, t=t)
    if imu.kind == "increments":
        step = sample_periods(t)[:, None]
        out.w, out.f = np.asarray(imu.dtheta, float) / step, np.asarray(imu.dv, float) / step
    else:
        out.steps = sample_steps(t, imu.w, imu.f)
    return out


#: Rows per block whose scatter is the yardstick of a single-sample spike (:func:`single_sample_spikes`).
SPIKE_BLOCK = 64
#: The yardstick is at least this fraction of the column's largest reading: a noise-free record's rounding (rates from
#: increments divided by steps of ``t`` written to a few digits) scatters readings by parts in 10^10, no spike.
SPIKE_ROUNDING = 1e-9


def single_sample_spikes(x: np.ndarray) -> list[tuple[int, int, float, float]]:
    """Single-sample spikes of readings `x` (N, k): ``(row, column, size, z)``, largest ``z`` first.

    A spike is a reading off both neighbours on the same side, by ``a_k = s min(|x_k - x_{k-1}|, |x_k - x_{k+1}|)``
    (both differences of sign ``s``), standing alone: higher above them than they differ from each other
    (``|a_k| > |x_{k+1} - x_{k-1}|``) and than twice the steps just beyond them (``|x_{k-1} - x_{k-2}|``,
    ``|x_{k+2} - x_{k+1}|``: the sampled peak of a smooth pulse stands a third of those above its neighbours, a
    spike in a quiet or noisy stretch many times them), and alone in its neighbourhood (no other such reading of
    half its bar, ``OUTLIER_Z / 2``, within two rows: a burst of vibration is motion, not one bad sample). A step
    (thrust on or off), a ramp or a corner of the motion leaves one difference near zero, or the neighbours apart:
    the change persists. ``a_k`` is judged against the record's local sample-to-sample variation over blocks of
    :data:`SPIKE_BLOCK` rows: the larger of the white-noise sigma ``1.4826 MAD(d) / sqrt(1.5)`` of the spike
    statistic ``d_k = x_k - (x_{k-1} + x_{k+1}) / 2`` (the one :func:`casep.checks.plausibility.check_fit` judges
    dv outliers by) and ``1.4826 median |x_k - x_{k-1}| / sqrt(2)`` (both sigma for white noise; the second the
    step of a smooth motion), at each row the largest of its block and the two beside it (a vibrating flight next
    to a quiet pad is judged by the flight's), and at least the column's resolution (the smallest gap between its
    distinct readings: a one-count step of a quantised sensor is no spike) and :data:`SPIKE_ROUNDING` of its
    largest reading. A spike is ``|a_k| > OUTLIER_Z`` (10) times that (:data:`casep.checks.plausibility.OUTLIER_Z`:
    Gaussian noise gives two differences of that size at one sample with a chance below 1e-23)."""
    from casep._special import MAD_SIGMA
    from casep.checks.plausibility import OUTLIER_Z

    x = np.asarray(x, float)
    out: list[tuple[int, int, float, float]] = []
    if x.shape[0] < 3:
        return out
    d1, d2 = x[1:-1] - x[:-2], x[1:-1] - x[2:]
    a = np.where(np.sign(d1) == np.sign(d2), np.sign(d1) * np.minimum(np.abs(d1), np.abs(d2)), 0.0)
    step = np.abs(np.diff(x, axis=0))  # |x_k - x_{k-1}|, row k - 1
    outer = np.maximum(np.vstack([np.zeros((1, x.shape[1])), step[:-2]]),  # the steps just outside the neighbours
                       np.vstack([step[2:], np.zeros((1, x.shape[1]))]))
    # higher above its neighbours than they differ, and than twice the steps beyond them (a smooth peak: a third)
    alone = (np.abs(a) > np.abs(x[2:] - x[:-2])) & (np.abs(a) > 2.0 * outer)
    d = x[1:-1] - 0.5 * (x[:-2] + x[2:])
    nb = -(-d.shape[0] // SPIKE_BLOCK)
    for j in range(x.shape[1]):
        blocks = [d[i * SPIKE_BLOCK:(i + 1) * SPIKE_BLOCK, j] for i in range(nb)]
        steps = [d1[i * SPIKE_BLOCK:(i + 1) * SPIKE_BLOCK, j] for i in range(nb)]
        s = np.maximum([MAD_SIGMA * np.median(np.abs(b - np.median(b))) / math.sqrt(1.5) for b in blocks],
                       [MAD_SIGMA * np.median(np.abs(b)) / math.sqrt(2.0) for b in steps])
        s = np.maximum(s, np.maximum(np.r_[s[1:], 0.0], np.r_[0.0, s[:-1]]))  # with the blocks beside it
        u = np.unique(x[:, j])
        q = float(np.diff(u).min()) if u.size > 1 else 0.0
        floor = max(q, SPIKE_ROUNDING * float(np.abs(x[:, j]).max()))
        scale = np.maximum(np.repeat(s, SPIKE_BLOCK)[:d.shape[0]], floor)
        z_all = np.abs(a[:, j]) / np.where(scale > 0, scale, np.inf)
        z_all[(scale == 0) & (a[:, j] != 0)] = np.inf
        near = alone[:, j] & (z_all > OUTLIER_Z / 2)  # half the bar: a burst's quieter members count
        crowd = np.zeros_like(near)
        for m in (1, 2):  # another such reading within two rows
            crowd[m:] |= near[:-m]
            crowd[:-m] |= near[m:]
        hit = alone[:, j] & ~crowd & (z_all > OUTLIER_Z)
        for k in np.flatnonzero(hit):
            out.append((int(k) + 1, j, float(a[k, j]), float(z_all[k])))
    return sorted(out, key=lambda r: -r[3])


def _warn_spikes(imu: ImuData, h_med: float, top: int = 5) -> None:
    """An :class:`~casep.exceptions.OutlierWarning` naming the single-sample spikes of the rates and specific forces
    (:func:`single_sample_spikes`): column, row, time, size, and what the navigation takes from each (the
    velocity a specific-force spike adds, the attitude a rate spike turns and the velocity error it grows per
    second). The samples are navigated as read."""
    from casep.exceptions import OutlierWarning

    inc = imu.kind == "increments"
    found = [(z, k, "w", j, size) for k, j, size, z in single_sample_spikes(imu.w)]
    found += [(z, k, "f", j, size) for k, j, size, z in single_sample_spikes(imu.f)]
    if not found:
        return
    found.sort(reverse=True)
    said = []
    for z, k, kind, j, size in found[:top]:
        step = float(imu.t[k] - imu.t[k - 1])
        if kind == "f":
            col = DV_COLUMNS[j] if inc else FORCE_COLUMNS[j]
            what = f"{size:+.4g} m/s^2 off both neighbours, adding {size * step:+.3g} m/s to the velocity"
        else:
            col = DTHETA_COLUMNS[j] if inc else RATE_COLUMNS[j]
            turn = abs(size) * step
            what = (f"{size:+.4g} rad/s ({math.degrees(size):+.4g} deg/s) off both neighbours, turning the attitude "
                    f"by {math.degrees(turn):.3g} deg (a velocity error growing by "
                    f"{turn * float(np.linalg.norm(imu.f[k])):.3g} m/s per s)")
        said.append(f"{col} row {k + 1} (t = {imu.t[k]:.10g} s): {what}, {z:.3g} times the local noise")
    more = f" and {len(found) - top} more" if len(found) > top else ""
    warnings.warn(f"{imu.source}: {len(found)} single-sample spike(s) in the IMU record: " + "; ".join(said) + more
                  + ". A change that persists (thrust on or off) is no spike; these samples are navigated as read: "
                  "each is a glitch (replace it by the mean of its neighbours) or a shock shorter than the sample "
                  "period (keep it)", OutlierWarning, stacklevel=3)


def _check_units(imu: ImuData, declared: bool = False) -> None:
    """Rates beyond any full scale: error; beyond 2000 deg/s (unless within a `declared` gyro range) or forces
    beyond 50 g: warning; with the numbers."""
    wn = np.linalg.norm(imu.w, axis=1)
    k = int(np.argmax(wn))
    cols = "dth_*" if imu.kind == "increments" else "w_*"
    if wn[k] > MAX_RATE:
        raise ValueError(f"{imu.source}: columns {cols}, row {k + 1}: body rate {wn[k]:.4g} rad/s "
                         f"({math.degrees(wn[k]):.4g} deg/s) is beyond any gyro's full scale: the rates look like "
                         "deg/s (give rad/s)")
    if wn[k] > WARN_RATE and not declared:
        warnings.warn(f"{imu.source}: columns {cols}, row {k + 1}: body rate {wn[k]:.4g} rad/s "
                      f"({math.degrees(wn[k]):.4g} deg/s), beyond the 2000 deg/s of common gyros: deg/s given as "
                      "rad/s?", PlausibilityWarning, stacklevel=3)
    fn = np.linalg.norm(imu.f, axis=1)
    k = int(np.argmax(fn))
    if fn[k] > WARN_FORCE:
        cols = "dvb_*" if imu.kind == "increments" else "fb_*"
        warnings.warn(f"{imu.source}: columns {cols}, row {k + 1}: specific force {fn[k]:.4g} m/s^2 "
                      f"({fn[k] / 9.80665:.3g} g) is beyond 50 g: units?", PlausibilityWarning, stacklevel=3)
