"""A ground-test session (a file of raw readings) and its segments (positions and rotations).

Session file: CSV or Parquet with three accelerometer and three gyro columns (default
``acc_x, acc_y, acc_z, gyr_x, gyr_y, gyr_z``) in any unit, and either a time column ``t`` (s)
or a sample rate (``rate``, Hz) with, optionally, a sample-index column (``samples`` or
``n_samples``: t = index / rate). Rows are used in time order.

Segments, as imucal and lab procedures record them:

- a JSON object keyed by segment name, ``{"x_p": {"start": 540, "end": 1271}, ...}`` (imucal's
  section list: 0-based row positions of the file, end excluded), or a JSON list of objects with
  ``name, start, end`` and for a segment outside the Ferraris set its description:
  ``"kind": "static"`` with ``"gravity": [gx, gy, gz]`` (direction of the specific force in the
  sensor frame, normalised) and optionally ``"omega_dps": [wx, wy, wz]`` (a known rate, e.g. the
  Earth's, deg/s); or ``"kind": "rotation"`` with ``"axis"``, ``"angle_deg"`` and ``"gravity"``
  (the position it turns in; the axis must be along gravity, so the specific force stays known);
- a label column (``part`` in imucal's annotated sessions): the rows of each label form a segment;
  empty labels are between segments.

imucal's names ``x_p, x_a, y_p, y_a, z_p, z_a`` (static, +1 g / -1 g along the axis) and
``x_rot, y_rot, z_rot`` (a turn about the axis in the ``_p`` position by the expected angle,
imucal's default -360 deg: clockwise, the gyro reads negative) are the Ferraris procedure; a
session that uses them must have all nine.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from casep.units import G0

__all__ = ["Session", "Segment", "SegmentError", "read_session", "read_segments", "segments_from_labels",
           "FERRARIS_SEGMENTS", "ferraris_segment", "ACC_COLUMNS", "GYR_COLUMNS", "ACC_UNITS", "GYR_UNITS",
           "RATE_TOLERANCE", "SESSION_RATES", "check_time_unit"]

#: Physical units of the session's columns: unit -> SI factor (``a.u.``, raw counts, is also accepted).
ACC_UNITS = {"m/s^2": 1.0, "g": G0, "mg": 1e-3 * G0}
GYR_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0, "deg/h": math.pi / 180.0 / 3600.0}
RAW_UNIT = "a.u."
#: A given sample rate and that of the ``t`` column may differ by this fraction.
RATE_TOLERANCE = 0.01
#: The sample rates an IMU session is recorded at, Hz: a ``t`` column outside them is in another unit.
SESSION_RATES = (1.0, 1e5)
#: Time units a ``t`` column may be in by mistake: (name, seconds per unit).
TIME_UNITS = (("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9), ("min", 60.0))

ACC_COLUMNS = ("acc_x", "acc_y", "acc_z")
GYR_COLUMNS = ("gyr_x", "gyr_y", "gyr_z")
#: imucal's segment names (FerrarisCalibration.FERRARIS_SECTIONS).
FERRARIS_SEGMENTS = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a", "x_rot", "y_rot", "z_rot")
_INDEX_COLUMNS = ("samples", "n_samples")


@dataclass(frozen=True)
class Segment:
    """One segment of a ground test.

    Attributes
    ----------
    name : str
    kind : {"static", "rotation"}
    rows : (k,) ndarray of int
        Row positions in the session (time order).
    gravity : (3,) ndarray
        Unit direction of the specific force in the sensor frame (the reading of a perfect
        accelerometer is ``g * gravity``).
    axis : (3,) ndarray or None
        Rotation axis (unit), sensor frame.
    angle_deg : float or None
        Rotation angle about `axis`, deg (right-handed).
    omega_dps : (3,) ndarray
        Known angular rate during a static segment (the Earth's, if given), deg/s.
    """

    name: str
    kind: str
    rows: np.ndarray
    gravity: np.ndarray
    axis: np.ndarray | None = None
    angle_deg: float | None = None
    omega_dps: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def where(self) -> str:
        """``segment `x_p` (rows 540-1270)`` for messages (file row positions)."""
        return f"segment `{self.name}` (rows {int(self.rows[0])}-{int(self.rows[-1])})"


class SegmentError(ValueError):
    """A segment list or label column is inconsistent: the message names the segment (and rows)."""


@dataclass
class Session:
    """Readings of one ground test, in time order.

    Attributes
    ----------
    t : (N,) ndarray
        Time, s.
    acc, gyr : (N, 3) ndarray
        Accelerometer and gyro readings as recorded (units `acc_unit`, `gyr_unit`).
    rate : float
        Sample rate, Hz (given, or from the median step of `t`).
    rows : (N,) ndarray of int
        The file row of each sample (for messages).
    labels : (N,) ndarray of object or None
        The label column, when read.
    t_column : bool
        True when `t` is the file's own time column; False when it was made from `rate` (then a
        wrong rate scales every turn integral, :func:`casep.calibration.checks.check_turn_angles`).
    columns : tuple of 6 str
        The file's accelerometer and gyro columns, x, y, z each (for messages).
    header_lines : int
        Lines above the first sample in the file (a CSV's header: 1; a headerless text file: 0), so that
        :meth:`file_row` gives the line a message names.
    """

    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    rate: float
    source: str = "<memory>"
    acc_unit: str = "a.u."
    gyr_unit: str = "a.u."
    rows: np.ndarray | None = None
    labels: np.ndarray | None = None
    t_column: bool = False
    columns: tuple[str, ...] = ("acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z")
    header_lines: int = 1

    def __post_init__(self) -> None:
        n = len(self.t)
        if self.rows is None:
            self.rows = np.arange(n)
        for nm, a in (("acc", self.acc), ("gyr", self.gyr)):
            if np.shape(a) != (n, 3):
                raise ValueError(f"{self.source}: `{nm}` must be ({n}, 3), got {np.shape(a)}")
        if not (np.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"{self.source}: the sample rate must be finite and > 0 Hz, got {self.rate}")

    @property
    def n_samples(self) -> int:
        return len(self.t)

    def file_row(self, i: int) -> int:
        """The file's line (1 the first) of sample `i` (time order), as the reader's messages count it."""
        assert self.rows is not None  # set by __post_init__
        return int(self.rows[i]) + 1 + self.header_lines


def ferraris_segment(name: str, rows: np.ndarray, angle_deg: float = -360.0) -> Segment:
    """The Segment of one of imucal's names (see the module notes)."""
    if name not in FERRARIS_SEGMENTS:
        raise SegmentError(f"segment `{name}` is not one of the Ferraris names {', '.join(FERRARIS_SEGMENTS)}")
    i = "xyz".index(name[0])
    e = np.zeros(3)
    e[i] = 1.0
    if name.endswith("_rot"):
        return Segment(name, "rotation", rows, gravity=e, axis=e.copy(), angle_deg=float(angle_deg))
    return Segment(name, "static", rows, gravity=e if name.endswith("_p") else -e)


def _read_table(path: str | os.PathLike):
    import pandas as pd

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"session file {path} does not exist")
    try:
        return pd.read_parquet(p) if p.suffix.lower() in (".parquet", ".pq") else pd.read_csv(p)
    except Exception as exc:  # noqa: BLE001 - pandas raises many kinds; one line naming the file
        raise ValueError(f"session file {path}: cannot be read ({type(exc).__name__}: {exc})") from None


def read_session(path: str | os.PathLike, *, rate: float | None = None, acc_columns=ACC_COLUMNS,
                 gyr_columns=GYR_COLUMNS, acc_unit: str = "a.u.", gyr_unit: str = "a.u.",
                 label_column: str | None = None, index_column: str | None = None) -> Session:
    """Read a session file (see the module notes).

    Parameters
    ----------
    rate : float, optional
        Sample rate, Hz; required without a ``t`` column.
    acc_columns, gyr_columns : sequence of 3 str
        Column names, x, y, z.
    acc_unit, gyr_unit : str
        Units of the columns (``a.u.`` for raw counts; ``m/s^2``, ``g``, ``mg``; ``deg/s``,
        ``rad/s``, ``deg/h``).
    label_column : str, optional
        Column of segment labels (kept in :attr:`Session.labels`).
    index_column : str, optional
        Sample-index column (default: ``samples`` or ``n_samples`` when present, with `rate`).

    Raises
    ------
    ValueError
        Naming the file, the column and the row (missing column, non-numeric or NaN value,
        time not increasing, no rate).
    """
    for what, unit, table in (("--acc-unit", acc_unit, ACC_UNITS), ("--gyr-unit", gyr_unit, GYR_UNITS)):
        if unit != RAW_UNIT and unit not in table:
            raise ValueError(f"{what} `{unit}` is not a known unit. Use one of: {RAW_UNIT} (raw counts), "
                             f"{', '.join(table)}")
    df = _read_table(path)
    src = str(path)
    cols = list(acc_columns) + list(gyr_columns)
    if len(acc_columns) != 3 or len(gyr_columns) != 3:
        raise ValueError("give three accelerometer and three gyro columns (x, y, z)")
    missing = [c for c in cols + ([label_column] if label_column else []) if c not in df.columns]
    if missing:
        raise ValueError(f"{src}: Missing column(s) {', '.join(missing)}; the file has "
                         f"{', '.join(map(str, df.columns))}. "
                         "Use: --acc-columns/--gyr-columns/--label-column NAME")
    data = {}
    for c in cols:
        v = np.asarray(df[c], dtype=object)
        try:
            x = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            bad = next(i for i, s in enumerate(v) if not _is_number(s))
            raise ValueError(f"{src}: column `{c}`, row {bad + 2}: not a number ({v[bad]!r})") from None
        nan = np.flatnonzero(~np.isfinite(x))
        if nan.size:
            raise ValueError(f"{src}: column `{c}`, row {nan[0] + 2}: not a finite number ({x[nan[0]]})")
        data[c] = x
    n = len(df)
    if n < 2:
        raise ValueError(f"{src}: {n} rows; a session needs many samples per segment")
    if "t" in df.columns:
        t = np.asarray(df["t"], dtype=float)
        step = np.diff(np.sort(t))
        rate_t = 1.0 / float(np.median(step)) if np.all(np.isfinite(t)) and np.median(step) > 0 else math.nan
        check_time_unit(rate_t, src)
        if rate is None:
            rate = rate_t
        elif np.isfinite(rate_t) and abs(float(rate) / rate_t - 1.0) > RATE_TOLERANCE:
            # the t column is the record of the sampling: a rate that contradicts it scales every turn integral
            raise ValueError(f"{src}: --rate {float(rate):.6g} Hz disagrees with the `t` column, whose median step "
                             f"{1.0 / rate_t:.6g} s is {rate_t:.6g} Hz (more than {RATE_TOLERANCE:.0%} apart). "
                             "Use: the right --rate, or leave it out (the t column gives the rate)")
    else:
        if rate is None:
            raise ValueError(f"{src}: no `t` column and no sample rate. Use: --rate HZ")
        idx_col = index_column or next((c for c in _INDEX_COLUMNS if c in df.columns), None)
        if index_column and index_column not in df.columns:
            raise ValueError(f"{src}: Missing sample-index column `{index_column}`")
        t = (np.asarray(df[idx_col], dtype=float) if idx_col else np.arange(n, dtype=float)) / float(rate)
    order = np.argsort(t, kind="stable")
    ts = t[order]
    dup = np.flatnonzero(np.diff(ts) <= 0)
    if dup.size:
        raise ValueError(f"{src}: time repeats at rows {order[dup[0]] + 2} and {order[dup[0] + 1] + 2} "
                         f"(t = {ts[dup[0]]:.6g} s): each sample needs its own time")
    labels = None
    if label_column:
        raw = df[label_column].to_numpy(dtype=object)[order]
        labels = np.array(["" if (s is None or (isinstance(s, float) and np.isnan(s))) else str(s).strip()
                           for s in raw], dtype=object)
    return Session(t=ts, acc=np.column_stack([data[c] for c in acc_columns])[order],
                   gyr=np.column_stack([data[c] for c in gyr_columns])[order], rate=float(rate), source=src,
                   acc_unit=acc_unit, gyr_unit=gyr_unit, rows=order, labels=labels, t_column="t" in df.columns,
                   columns=tuple(cols))


def check_time_unit(rate_t: float, src: str) -> None:
    """Refuse a ``t`` column whose median step gives a rate outside SESSION_RATES (1 Hz-100 kHz).

    ``rate_t = 1 / median(diff t)``; ``t`` in a unit of ``k`` seconds read as seconds gives
    ``rate_t = true rate / k`` (t in ms at 100 Hz: 0.1 Hz). The units of TIME_UNITS that bring the
    rate inside SESSION_RATES are named.
    """
    lo, hi = SESSION_RATES
    if not math.isfinite(rate_t) or lo <= rate_t <= hi:
        return
    fits = [(u, rate_t / k) for u, k in TIME_UNITS if lo <= rate_t / k <= hi]
    hint = (" or ".join(f"like {u} (then {r:.6g} Hz)" for u, r in fits) if fits else "not like seconds")
    raise ValueError(f"{src}: column `t`: median step {1.0 / rate_t:.6g} (read as s: {rate_t:.6g} Hz; an IMU "
                     f"session is sampled at {lo:g} Hz to {hi:g} Hz): the times look {hint}. Use: `t` in seconds")


def _is_number(s) -> bool:
    try:
        float(s)
    except (TypeError, ValueError):
        return False
    return True


def _vector(spec: dict, key: str, where: str, unit: bool) -> np.ndarray:
    v = spec.get(key)
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise SegmentError(f"{where}: `{key}` must be 3 finite numbers [x, y, z], got {v!r}")
    if unit:
        nrm = float(np.linalg.norm(a))
        if nrm == 0:
            raise SegmentError(f"{where}: `{key}` must not be zero")
        a = a / nrm
    return a


def _segment(name: str, spec: dict, rows: np.ndarray, angle_deg: float, where: str) -> Segment:
    """A Segment from a JSON spec (Ferraris defaults for imucal's names)."""
    kind = spec.get("kind")
    if kind is None:
        if name in FERRARIS_SEGMENTS:
            return ferraris_segment(name, rows, float(spec.get("angle_deg", angle_deg)))
        raise SegmentError(f"{where}: Missing: `kind` (not one of imucal's names {', '.join(FERRARIS_SEGMENTS)}). "
                           "Use: \"kind\": \"static\" with \"gravity\": [gx, gy, gz], or \"kind\": \"rotation\" "
                           "with \"axis\", \"angle_deg\" and \"gravity\"")
    if kind == "static":
        omega = _vector(spec, "omega_dps", where, False) if "omega_dps" in spec else np.zeros(3)
        return Segment(name, "static", rows, gravity=_vector(spec, "gravity", where, True), omega_dps=omega)
    if kind == "rotation":
        g = _vector(spec, "gravity", where, True)
        ax = _vector(spec, "axis", where, True)
        if abs(abs(float(g @ ax)) - 1.0) > 1e-6:
            raise SegmentError(f"{where}: the rotation axis {ax.round(4).tolist()} is not along gravity "
                               f"{g.round(4).tolist()}: the specific force during the turn is then not known. "
                               "Use: turns about the vertical")
        try:
            ang = float(spec["angle_deg"])
        except (KeyError, TypeError, ValueError):
            raise SegmentError(f"{where}: Missing: `angle_deg` (a number). Use: \"angle_deg\": -360") from None
        if not np.isfinite(ang) or ang == 0:
            raise SegmentError(f"{where}: `angle_deg` must be finite and non-zero, got {ang}")
        return Segment(name, "rotation", rows, gravity=g, axis=ax, angle_deg=ang)
    raise SegmentError(f"{where}: `kind` must be static or rotation, got {kind!r}")


def read_segments(path: str | os.PathLike, session: Session, *, angle_deg: float = -360.0) -> list[Segment]:
    """Segments from a JSON file: imucal's section list (an object keyed by name) or a list.

    ``start``/``end`` are 0-based row positions of the session file, ``end`` excluded.
    """
    from casep.io.result_json import load_json

    data = load_json(path, "--segments")
    if isinstance(data, dict):
        items = [{"name": k, **v} if isinstance(v, dict) else {"name": k, "bad": v} for k, v in data.items()]
    elif isinstance(data, list):
        items = data
    else:
        raise SegmentError(f"--segments {path}: must be an object keyed by segment name or a list of segments")
    pos = np.empty(session.n_samples, dtype=np.intp)  # file row -> time-order position
    pos[session.rows] = np.arange(session.n_samples)
    segs = []
    for k, spec in enumerate(items):
        if not isinstance(spec, dict) or "name" not in spec:
            raise SegmentError(f"--segments {path}: entry {k + 1} must be an object with name, start, end")
        name = str(spec["name"])
        where = f"--segments {path}: segment `{name}`"
        try:
            s, e = int(spec["start"]), int(spec["end"])
        except (KeyError, TypeError, ValueError):
            raise SegmentError(f"{where}: Missing: integer `start` and `end` (row positions, end excluded)") from None
        if not 0 <= s < e <= session.n_samples:
            raise SegmentError(f"{where}: rows {s}-{e} are not inside the session's {session.n_samples} rows "
                               "(0 <= start < end <= rows)")
        rows = np.sort(pos[s:e])
        segs.append(_segment(name, spec, rows, angle_deg, where))
    return check_segments(segs, session)


def segments_from_labels(session: Session, *, angle_deg: float = -360.0, specs: dict | None = None) -> list[Segment]:
    """Segments from the label column (imucal's annotated sessions: ``part``).

    Each label's rows must be one run of consecutive samples; empty labels are ignored. Labels
    outside imucal's names need a description in `specs` (name -> JSON spec as in
    :func:`read_segments`).
    """
    if session.labels is None:
        raise SegmentError(f"{session.source}: no label column was read. Use: --label-column NAME")
    lab = session.labels
    segs = []
    for name in dict.fromkeys(x for x in lab if x):
        rows = np.flatnonzero(lab == name)
        gaps = np.flatnonzero(np.diff(rows) > 1)
        if gaps.size:
            r = session.rows
            assert r is not None  # filled by Session.__post_init__
            raise SegmentError(f"{session.source}: label `{name}` occurs in {gaps.size + 1} separate runs (file rows "
                               f"{r[rows[0]] + 2}.. and {r[rows[gaps[0] + 1]] + 2}..): a segment is one run. Use: "
                               "distinct labels")
        segs.append(_segment(name, (specs or {}).get(name, {}), rows, angle_deg, f"{session.source}: label `{name}`"))
    return check_segments(segs, session)


def check_segments(segs: list[Segment], session: Session) -> list[Segment]:
    """Refuse duplicates, overlaps, too short segments and an incomplete Ferraris set."""
    names = [s.name for s in segs]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SegmentError(f"{session.source}: segment(s) {', '.join(sorted(dup))} given more than once")
    if not segs:
        raise SegmentError(f"{session.source}: no segments")
    for s in segs:
        if len(s.rows) < 2:
            raise SegmentError(f"{s.where}: {len(s.rows)} sample(s); a segment needs several")
    order = sorted(segs, key=lambda s: s.rows[0])
    for a, b in zip(order, order[1:]):
        if b.rows[0] <= a.rows[-1]:
            raise SegmentError(f"{a.where} and {b.where} overlap")
    used = [n for n in names if n in FERRARIS_SEGMENTS]
    if used:
        miss = [n for n in FERRARIS_SEGMENTS if n not in names]
        if miss:
            raise SegmentError(f"{session.source}: the Ferraris procedure needs the nine segments "
                               f"{', '.join(FERRARIS_SEGMENTS)}; Missing: {', '.join(miss)}")
    return segs
