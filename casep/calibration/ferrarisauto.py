"""The segments of a Ferraris session found without labels (``--segments auto`` with model ``ferraris``).

A Ferraris session holds the sensor still with each axis up and down (six static poses) and turns it
once about each axis while that axis is vertical (three rotations). Without labels:

1. **Static runs**: the detector of :func:`casep.calibration.segment.detect_static` (window variance
   of the accelerometers and the gyro's window mean square about its initial reading, in units of
   the initial period; static: at most ``k``). A run of at least ``min_static_s`` is a pose; a shorter
   one is no pose but still separates two motions (at its midpoint).
2. **Which axis is vertical**: a pose's mean accelerometer reading ``abar`` centred per axis on the
   midpoint of the poses' extremes (``c_i = (max_k abar_ki + min_k abar_ki) / 2``, so a raw bias
   near mid-scale does not count); the axis ``i`` of the largest ``|abar_i - c_i|`` and its sign name
   the pose (``+x``: ``x_p``, ``-x``: ``x_a``). A pose more than ``AXIS_TOL_DEG`` from every axis is
   rejected (listed, with its angle). Every other sample takes the axis of its short-window mean
   (``window / 8``), or none.
3. **Stations and turns**: consecutive samples with the same vertical axis form a station. Its turn
   candidate is the gap between its poses (or its bounds) of the largest integrated gyro

       Theta = sum_i (w_i - b0) dt_i         (b0: the mean gyro reading of the poses)

   A gap that ends at the station's bound while the gyro still moves there (short-window mean
   square above ``QUIET`` times the poses') ends at the station's short static run nearest that
   bound instead; without one, :class:`TurnBoundaryWarning`. The candidate is a **turn** when
   ``|Theta|`` is at least ``ROTATION_FRACTION`` of the expected ``|angle|`` (physical units) or of
   the largest candidate's (raw counts, whose scale is not known yet). Its axis is that of the
   largest ``|Theta_i|``, which must hold at least ``cos(AXIS_TOL_DEG)`` of ``|Theta|`` and be the
   station's vertical axis (a Ferraris turn is about the vertical).
4. **Poses**: a station without a turn is the pose of its axis (the rows of its poses; stations of
   one axis with no other pose or turn between them are one pose); an axis whose only station holds
   its turn takes the longer pose before or after the turn.

The threshold multiplier ``k`` is chosen from the session as imu_tk chooses it: of every ``k`` of
:data:`casep.calibration.segment.MULTIPLIERS` whose segments are all identified, the one of the
smallest RMS misfit of the least-squares accelerometer fit ``abar_k = M_a g e_k + b_a`` to the six
poses (18 rows, 12 coefficients).

Errors (:class:`casep.calibration.session.SegmentError`, with the rows and the numbers): an axis
with no turn, a turn about no single axis or not about the vertical, two turns about one axis, two
stations with poses of the same vertical axis, an axis with no pose.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from casep.calibration.segment import MULTIPLIERS, Segmentation, detector, static_runs, window_mean
from casep.calibration.session import GYR_UNITS, RAW_UNIT, Segment, SegmentError, Session, ferraris_segment
from casep.exceptions import CasepWarning

__all__ = ["FerrarisSegmentation", "find_ferraris_segments", "TurnBoundaryWarning", "AXIS_TOL_DEG",
           "ROTATION_FRACTION", "QUIET"]

#: A static run or a rotation is along an axis if within this angle of it, deg.
AXIS_TOL_DEG = 30.0
#: A station's integrated gyro is a rotation from this fraction of the expected angle (raw: of the largest) on.
ROTATION_FRACTION = 0.5
#: The gyro is at rest at a sample when its short-window mean square is at most this many times the poses' mean.
QUIET = 25.0


class TurnBoundaryWarning(CasepWarning):
    """A turn not bracketed by rest: its gyro integral may include part of the next motion."""


@dataclass(frozen=True)
class FerrarisSegmentation:
    """What :func:`find_ferraris_segments` found.

    Attributes
    ----------
    segmentation : Segmentation
        The static runs (``poses``: every run along an axis, time order), the threshold, the rejected runs.
    segments : list of Segment
        The six static poses and the three rotations (imucal's names), as the labelled path builds them.
    turns : dict
        Rotation name -> integrated gyro ``Theta`` over it (reading unit s).
    """

    segmentation: Segmentation
    segments: list
    turns: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The detector's record and each segment's row interval (end excluded) and each turn's ``Theta``."""
        return {**self.segmentation.to_dict(),
                "segments": {s.name: [int(s.rows[0]), int(s.rows[-1]) + 1] for s in self.segments},
                "turns": {k: list(map(float, v)) for k, v in self.turns.items()}}

    def text(self) -> str:
        seg = self.segmentation
        lines = [f"segmentation (Ferraris, no labels): {len(seg.poses)} static runs; threshold {seg.multiplier:g} x "
                 f"the initial period's window variance; window {seg.window} samples"]
        for s in self.segments:
            a, b = int(s.rows[0]), int(s.rows[-1])
            what = (f"turn, integrated gyro [{', '.join(f'{v:.4g}' for v in self.turns[s.name])}]"
                    if s.kind == "rotation" else f"gravity along {_axis_text(s.gravity)}")
            lines.append(f"  {s.name:<6} rows {a}-{b} ({len(s.rows) / seg.rate:.3g} s): {what}")
        if seg.sweep:
            lines.append("  sweep (multiplier: static runs, RMS misfit of the six poses): " + "; ".join(
                f"{k:g}: {n}, {r:.3g}" for k, n, r in seg.sweep))
        if seg.rejected:
            lines.append(f"  rejected {len(seg.rejected)}: " + "; ".join(
                f"rows {a}-{b - 1} ({why})" for a, b, why in seg.rejected[:12]) + (" ..." if len(seg.rejected) > 12
                                                                                 else ""))
        return "\n".join(lines)


def _axis_text(e: np.ndarray) -> str:
    """``+x``, ``-y``, ...: the signed axis of the largest component of `e`."""
    i = int(np.argmax(np.abs(e)))
    return _label_text(2 * i + int(e[i] < 0))


def _runs(poses: list, rejected: list) -> list[tuple[int, int, int, int, bool]]:
    """Every static run, time order: ``(a, b, inner_start, inner_end, is_pose)``.

    A pose (a run long enough) is its rows; a shorter run still separates two motions, at its
    midpoint (``inner_start = inner_end``).
    """
    out = [(a, b, a, b, True) for a, b in poses]
    out += [(a, b, (a + b) // 2, (a + b) // 2, False) for a, b, _ in rejected]
    return sorted(out)


def _axis_label(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed axis label ``2 i + (m_i < 0)`` of the largest component of each row of `m`, -1 when that
    component is more than AXIS_TOL_DEG from the row; and that angle, deg."""
    i = np.argmax(np.abs(m), axis=1)
    big = np.abs(m[np.arange(len(m)), i])
    off = np.degrees(np.arccos(np.clip(big / np.maximum(np.linalg.norm(m, axis=1), 1e-300), 0.0, 1.0)))
    lab = 2 * i + (m[np.arange(len(m)), i] < 0)
    return np.where(off <= AXIS_TOL_DEG, lab, -1), off


def _label_samples(acc: np.ndarray, runs_: list, w: int) -> tuple[np.ndarray, list, list]:
    """Per sample its vertical axis label (module notes, step 2); the runs with their labels; the poses off
    every axis (rejected).

    A pose's samples take the label of its mean; the others that of the window mean of the readings.
    The centre is the midpoint of the poses' extremes per axis.
    """
    means = np.array([acc[r[0]:r[1]].mean(axis=0) for r in runs_])
    pm = means[[r[4] for r in runs_]]
    centre = (pm.max(axis=0) + pm.min(axis=0)) / 2
    L, _ = _axis_label(window_mean(acc, max(1, w // 8)) - centre)
    rl, off = _axis_label(means - centre)
    out, rejected = [], []
    for r, lab, o in zip(runs_, rl, off):
        pose = r[4] and lab >= 0
        if r[4] and lab < 0:
            rejected.append((r[0], r[1], f"gravity {o:.3g} deg from the nearest axis (> {AXIS_TOL_DEG:g})"))
        if pose:
            L[r[0]:r[1]] = lab
        out.append((r[0], r[1], r[2], r[3], pose, int(lab)))
    return L, out, rejected


def _stations(L: np.ndarray, runs_: list) -> list[tuple[int, int, int, list]]:
    """Runs of one vertical axis label: ``(label, start, end, [static runs whose inner part is inside])``."""
    d = np.flatnonzero(np.diff(L) != 0) + 1
    edges = np.concatenate([[0], d, [len(L)]])
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        if L[a] >= 0:
            out.append((int(L[a]), int(a), int(b), [r for r in runs_ if a <= r[2] and r[3] <= b]))
    return out


def _span(st, gyr, dt, b0, quiet) -> tuple[tuple[int, int], np.ndarray, tuple[bool, bool]]:
    """The turn candidate of a station: the gap between its poses (or its bounds) of the largest integrated
    gyro, that integral, and whether each end is open (module notes, step 3).

    A gap that ends at the station's bound while the gyro still moves there (`quiet` False) ends instead
    at the station's short static run nearest that bound; without one, the end is open.
    """
    lab, a, b, S = st

    def theta(lo, hi):
        return ((gyr[lo:hi] - b0) * dt[lo:hi, None]).sum(axis=0)

    poses = [r for r in S if r[4] and r[5] == lab]
    gaps = ([(a, poses[0][0])] + [(p[1], q[0]) for p, q in zip(poses, poses[1:])] + [(poses[-1][1], b)]
            if poses else [(a, b)])
    gaps = [g for g in gaps if g[1] > g[0]]
    if not gaps:
        return (a, a), np.zeros(3), (False, False)
    lo, hi = max(gaps, key=lambda g: float(np.linalg.norm(theta(*g))))
    shorts = [r[2] for r in S if not r[4] and lo <= r[2] < hi]
    opened = [False, False]
    if lo == a and not quiet[a]:
        lo, opened[0] = (shorts[0], False) if shorts else (lo, True)
    if hi == b and not quiet[b - 1]:
        hi, opened[1] = (shorts[-1], False) if shorts else (hi, True)
    return (lo, hi), theta(lo, hi), (opened[0], opened[1])


def _quiet(gyr: np.ndarray, b0: np.ndarray, poses: list, w: int) -> np.ndarray:
    """Per sample: the gyro's mean square about `b0` over a short window of `w` samples is at most
    QUIET times its mean over the poses (a few samples' mean square scatters: a wide margin)."""
    q = window_mean((gyr - b0) ** 2, w).sum(axis=1)
    level = float(np.mean(np.concatenate([q[a:b] for a, b in poses])))
    return q <= QUIET * max(level, 1e-300)


def _turns(cands: list, gyr_si, angle_deg, source) -> dict:
    """The rotations among the stations' candidates ``(station, span, Theta, open)``: ``{axis: (label, span,
    Theta, open)}`` (module notes, step 3)."""
    cand = [(c[0][0], *c[1:]) for c in cands if c[1][1] > c[1][0]]
    if not cand:
        raise SegmentError(f"{source}: no turn found: no station (samples with one axis vertical) moves between "
                           "its poses. Use: turn about each axis once while it is vertical, or give the segments")
    size = np.array([float(np.linalg.norm(c[2])) for c in cand])
    if gyr_si is not None:  # the expected angle in the reading unit s
        ref, what = math.radians(abs(angle_deg)) / gyr_si, f"of the expected {abs(angle_deg):g} deg"
    else:
        ref, what = float(size.max()), "of the largest station's (raw counts)"
    out: dict = {}
    for (lab, (a, b), th, opened), m in zip(cand, size):
        if m < ROTATION_FRACTION * ref:
            continue
        i = int(np.argmax(np.abs(th)))
        frac = abs(th[i]) / m
        where = f"{source}: the turn of rows {a}-{b - 1} (integrated gyro [{', '.join(f'{v:.4g}' for v in th)}])"
        if frac < math.cos(math.radians(AXIS_TOL_DEG)):
            raise SegmentError(f"{where} is about no single axis: its largest component, {'xyz'[i]}, is "
                               f"{frac:.3f} of its norm (one axis: at least {math.cos(math.radians(AXIS_TOL_DEG)):.3f},"
                               f" {AXIS_TOL_DEG:g} deg)")
        if i != lab // 2:
            raise SegmentError(f"{where} is about {'xyz'[i]} with gravity along {_label_text(lab)}: "
                               "a Ferraris turn is about the vertical axis")
        if i in out:
            raise SegmentError(f"{where} and the turn of rows {out[i][1][0]}-{out[i][1][1] - 1} are both about "
                               f"{'xyz'[i]} (size {m:.4g}, {m / ref:.3g} {what}): one turn per axis")
        out[i] = (lab, (a, b), th, opened)
    missing = [ax for k, ax in enumerate("xyz") if k not in out]
    if missing:
        largest = "" if gyr_si is None else (f"; the largest station's is {size.max() / ref:.3g} of it, "
                                             f"{math.degrees(size.max() * gyr_si):.4g} deg")
        raise SegmentError(f"{source}: no turn about {', '.join(missing)} found (turns found about: "
                           f"{', '.join('xyz'[k] for k in sorted(out)) or 'none'}; a turn: a station's integrated "
                           f"gyro of at least {ROTATION_FRACTION:g} {what}{largest}). Use: turn about each axis once "
                           "while it is vertical (and check --gyr-unit and --angle), or give the segments")
    return out


def _label_text(lab: int) -> str:
    """The text of an axis label ``2 i + (negative)``: ``+x``, ``-x``, ``+y``, ..."""
    return "+-"[lab % 2] + "xyz"[lab // 2]


def _station_poses(cands: list, turns: dict, source: str) -> dict:
    """Label -> the pose rows ``[(a, b), ...]`` (module notes, step 4).

    Stations of one axis with no other pose or turn between them (a bump that tilted the sensor
    past AXIS_TOL_DEG and back) are one pose.
    """
    poses: dict = {}
    spans = {t[1] for t in turns.values()}
    later, last = [], None  # last: the axis of the latest station with a pose (None after a turn)
    for (lab, _, _, S), span, _, _ in cands:
        long = [(r[0], r[1]) for r in S if r[4] and r[5] == lab]
        if span in spans:  # a rotation's station: its poses outside the turn, if the axis has no other
            later.append((lab, [p for p in long if p[1] <= span[0] or p[0] >= span[1]]))
            last = None
            continue
        if not long:
            continue
        if lab in poses and last != lab:
            prev = poses[lab]
            raise SegmentError(f"{source}: two static poses with gravity along {_label_text(lab)}: rows "
                               f"{prev[0][0]}-{prev[-1][1] - 1} and {long[0][0]}-{long[-1][1] - 1}, another pose "
                               "or a turn between them (the Ferraris procedure holds each axis up and down once)")
        poses.setdefault(lab, []).extend(long)
        last = lab
    for lab, long in later:
        if lab not in poses and long:  # the longest pose before or after the turn
            poses[lab] = [max(long, key=lambda p: p[1] - p[0])]
    return poses


def _assign(cands: list, turns: dict, source: str, angle_deg: float) -> list[Segment]:
    """The nine Segments from the stations and the rotations (module notes, step 4)."""
    poses = _station_poses(cands, turns, source)
    found = ", ".join(f"{_label_text(lb)} rows {rr[0][0]}-{rr[-1][1] - 1}" for lb, rr in sorted(poses.items()))
    segs = []
    for i, ax in enumerate("xyz"):
        for lab, suffix in ((2 * i, "p"), (2 * i + 1, "a")):
            if lab not in poses:
                raise SegmentError(f"{source}: no static pose with gravity along {_label_text(lab)} (found: "
                                   f"{found or 'none'}). Use: hold each axis up and down, or give the segments")
            rows = np.concatenate([np.arange(a, b) for a, b in poses[lab]])
            segs.append(ferraris_segment(f"{ax}_{suffix}", rows))
    for i, ax in enumerate("xyz"):
        lab, (a, b), _, _ = turns[i]
        e = np.zeros(3)
        e[i] = 1.0
        segs.append(Segment(f"{ax}_rot", "rotation", np.arange(a, b), gravity=(1 - 2 * (lab % 2)) * e, axis=e,
                            angle_deg=float(angle_deg)))
    return segs


def _misfit(acc: np.ndarray, segs: list[Segment]) -> float:
    """RMS misfit of ``abar_k = M g e_k + b`` over the six poses (18 rows, 12 coefficients), reading unit."""
    rows, obs = [], []
    for s in segs[:6]:
        m = acc[s.rows].mean(axis=0)
        for r in range(3):
            row = np.zeros(12)
            row[3 * r:3 * r + 3] = s.gravity
            row[9 + r] = 1.0
            rows.append(row)
            obs.append(m[r])
    A, y = np.array(rows), np.array(obs)
    res = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
    return float(np.sqrt(np.mean(res ** 2)))


def find_ferraris_segments(session: Session, *, angle_deg: float = -360.0, window_s: float = 0.5,
                           init_s: float = 5.0, min_static_s: float = 0.5,
                           multipliers=MULTIPLIERS) -> FerrarisSegmentation:
    """The six static poses and three rotations of a Ferraris session without labels (module notes).

    Parameters
    ----------
    session : Session
        Its ``gyr_unit`` says whether the turn angles are known before the fit (raw counts: not).
    angle_deg : float
        The turns' expected angle (``--angle``), deg.
    window_s, init_s, min_static_s : float
        Variance window, initial static period (the session must begin at rest), shortest static run, s.

    Raises
    ------
    SegmentError
        A pose or a rotation that cannot be identified (at every multiplier), with the rows and the numbers.
    """
    acc, gyr, rate = session.acc, session.gyr, session.rate
    w, init_end, min_len, v, v_init, vg_init = detector(acc, gyr, rate, window_s, init_s, min_static_s,
                                                        session.source)
    gyr_si = None if session.gyr_unit == RAW_UNIT else GYR_UNITS[session.gyr_unit]
    dt = np.diff(session.t, append=session.t[-1] + 1.0 / rate)
    sweep, best, errors = [], None, []
    for k in multipliers:
        poses, rejected = static_runs(v, k, init_end, min_len)
        L, runs_, off = _label_samples(acc, _runs(poses, rejected), w)
        b0 = np.concatenate([gyr[a:b] for a, b in poses]).mean(axis=0)
        quiet = _quiet(gyr, b0, poses, max(1, w // 8))
        cands = [(st, *_span(st, gyr, dt, b0, quiet)) for st in _stations(L, runs_)]
        try:
            turns = _turns(cands, gyr_si, angle_deg, session.source)
            segs = _assign(cands, turns, session.source, angle_deg)
        except SegmentError as exc:
            errors.append((float(k), len(poses), str(exc)))
            sweep.append((float(k), len(poses), math.nan))
            continue
        rms = _misfit(acc, segs)
        sweep.append((float(k), len(poses), rms))
        if best is None or rms < best[0]:
            best = (rms, k, poses, sorted(rejected + off), segs, turns)
    if best is None:
        k, nk, msg = max(errors, key=lambda e: e[1])
        raise SegmentError(f"{msg} [threshold multiplier {k:g}, {nk} static poses; no multiplier of "
                           f"{min(multipliers):g}..{max(multipliers):g} identifies the nine Ferraris segments]")
    _, k, poses, rejected, segs, turns = best
    off_axis = {(a, b) for a, b, _ in rejected}
    poses = [p for p in poses if p not in off_axis]  # a pose off every axis is listed as rejected only
    seg = Segmentation(init=(0, poses[0][1]), poses=poses, threshold=k * v_init, multiplier=float(k),
                       init_variance=v_init, window=w, rate=float(rate), rejected=rejected, sweep=sweep,
                       gyro_threshold=k * vg_init, statistic=v)
    _warn_open(turns, session.source)
    return FerrarisSegmentation(seg, segs, {f"{'xyz'[i]}_rot": turns[i][2] for i in range(3)})


def _warn_open(turns: dict, source: str) -> None:
    """:class:`TurnBoundaryWarning` for a turn whose end is neither a rest nor a static run."""
    for i, (_, (a, b), _, opened) in sorted(turns.items()):
        if any(opened):
            ends = " and ".join(e for e, o in (("start", opened[0]), ("end", opened[1])) if o)
            warnings.warn(f"{source}: the turn about {'xyz'[i]} (rows {a}-{b - 1}) has no rest at its {ends}: the gyro "
                          "still moves where its vertical axis changes, so its integral may hold part of the motion "
                          "next to it. Use: hold the sensor still for a moment before and after each turn",
                          TurnBoundaryWarning, stacklevel=3)
