"""Flight data: the :class:`FlightData` type and its error.

A flight is sample times ``t`` (s, strictly increasing, need not be uniform), the platform
specific force ``f`` (N x 3, m/s^2, from telemetry) and the velocity error ``dv`` (N x 3, m/s,
telemetry minus tracking). Files are read and written by :mod:`casep.io.files`.

Telemetry and tracking need not cover the same time: S_V is integrated from the first
telemetry sample (where the model puts dv = 0 and phi = 0), while the regression uses dv
only at the ``observed`` samples, where tracking exists (:meth:`FlightData.observed_rows`).

A flight is checked here as data (shapes, finite values, magnitudes, increasing time); what it
can tell a model is checked before estimation by :mod:`casep.checks.plausibility` (plausibility,
enough samples, set-up) and :mod:`casep.checks.late_start` (a flight that starts after lift-off:
:class:`LateStartWarning`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from casep.exceptions import CasepWarning

#: A jump between consecutive samples beyond this many times the column's sample-to-sample noise is a step
#: (:func:`signal_steps`).
STEP_FACTOR = 10.0
#: ... and beyond this fraction of the sensor's largest reading in the record (a noise-free record has no noise),
#: and this share of the interval's own difference (a step split over two intervals by a sample at its middle,
#: which the integration takes exactly, is none).
STEP_FLOOR, STEP_SHARE = 1e-6, 0.5


def _jumps(x: np.ndarray) -> np.ndarray:
    """Per interval ``k`` (N-1, 3): the part of the difference ``d_k = x[k+1] - x[k]`` that neither neighbour's
    difference shares, ``sign(a) min(|a|, |b|)`` with ``a = d_k - d_{k-1}``, ``b = d_k - d_{k+1}`` when they have
    one sign, else 0 (0 at the record's ends). A step of size ``D`` gives ``D``; a ramp, a smooth curve and a kink
    (one of ``a``, ``b`` about 0, or of opposite signs) give none."""
    d = np.diff(x, axis=0)
    out = np.zeros_like(d)
    a, b = d[1:-1] - d[:-2], d[1:-1] - d[2:]
    out[1:-1] = np.where(np.sign(a) == np.sign(b), np.sign(a) * np.minimum(np.abs(a), np.abs(b)), 0.0)
    return out


def signal_steps(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The steps of a signal `x` (N, 3) sampled at `t` between consecutive samples: ``(axes (N-1, 3) bool, jumps
    (N-1, 3))``, a jump :func:`_jumps` finds beyond :data:`STEP_FACTOR` times the column's sample-to-sample noise (the
    robust scatter of its second differences, ``1.4826 MAD``), beyond :data:`STEP_FLOOR` of its largest reading and
    beyond :data:`STEP_SHARE` of the interval's own difference; the intervals touching a gap (:func:`gap_steps`)
    are none (a gap's neighbours' differences span it). The rule of an IMU record's steps
    (:func:`casep.navigation.imu.sample_steps`) and of a strapdown telemetry's rate steps."""
    x = np.asarray(x, float)
    J = _jumps(x)
    d2 = np.diff(x, 2, axis=0)
    scale = 1.4826 * np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) if len(x) > 3 else np.zeros(3)
    floor = STEP_FLOOR * float(np.max(np.abs(x))) if x.size else 0.0
    big = (np.abs(J) > STEP_FACTOR * np.maximum(scale, floor)) \
        & (np.abs(J) > STEP_SHARE * np.abs(np.diff(x, axis=0))) & (float(np.max(np.abs(x))) > 0)
    for g in gap_steps(t):
        big[max(g - 1, 0):g + 2] = False
    return big, J


#: The kinematic acceleration signals of a tracking time offset's term ``a(t) dt_trk``, m/s^2.
ACCELERATION_SIGNALS = ("a_x", "a_y", "a_z")

__all__ = ["FlightData", "FlightDataError", "LateStartWarning", "MAX_ABS_VALUE", "DUPLICATE_STEP", "too_large",
           "LOST_SAMPLE_FACTOR", "gap_steps", "STEP_LOW", "STEP_HIGH", "STEP_IMPOSSIBLE", "DURATION_HIGH",
           "time_unit_factors", "STEP_FACTOR", "STEP_FLOOR", "STEP_SHARE", "signal_steps"]

AXES = ("x", "y", "z")
FORCE_COLUMNS = tuple(f"f_{a}" for a in AXES)
DV_COLUMNS = tuple(f"dv_{a}" for a in AXES)

#: A time step below this fraction of the median step is a near-duplicate time tag: the plausibility
#: check warns on one (:func:`casep.checks.plausibility.check_flight`), and a telemetry + tracking merge
#: (:func:`casep.io.pair.pair_flight`) takes a tracking epoch that close to a telemetry sample for that
#: sample, so the grid casep builds never holds one.
DUPLICATE_STEP = 1e-3
#: A step longer than this many median steps has lost samples (an IMU record's, and a strapdown telemetry's
#: rates integrated alike: :func:`gap_steps`).
LOST_SAMPLE_FACTOR = 1.5
# Time: telemetry is sampled at 1 Hz .. 10 kHz; nothing is sampled at 1 MHz; boosts last < 1 h.
STEP_LOW, STEP_HIGH, STEP_IMPOSSIBLE, DURATION_HIGH = 1e-4, 1.0, 1e-6, 3600.0


def gap_steps(t: np.ndarray) -> np.ndarray:
    """Indices ``k`` of the steps ``t[k] -> t[k+1]`` that lost samples (over :data:`LOST_SAMPLE_FACTOR` median
    steps)."""
    h = np.diff(np.asarray(t, float))
    return np.flatnonzero(h > LOST_SAMPLE_FACTOR * float(np.median(h)))


def time_unit_factors(h: float, T: float) -> list[tuple[str, float]]:
    """The units of t, with the factor to seconds, that bring a median step `h` and a duration `T` (both read as s)
    into the range of boost telemetry (:data:`STEP_LOW` .. :data:`STEP_HIGH`, below :data:`DURATION_HIGH`), when
    they are out of it; [] when in range or when none fits."""
    if STEP_LOW <= h <= STEP_HIGH and T <= DURATION_HIGH:
        return []
    scales = (("ms (divide by 1000)", 1e-3), ("us (divide by 1e6)", 1e-6), ("ns (divide by 1e9)", 1e-9),
              ("min (multiply by 60)", 60.0), ("h (multiply by 3600)", 3600.0))
    return [(u, k) for u, k in scales if STEP_LOW <= h * k <= STEP_HIGH and T * k <= DURATION_HIGH]

#: Largest magnitude accepted in any flight column (t, f, W, dv, v_tel, v_trk), SI units.
#: S_V holds products up to third order in f (the [f x] Phi term with Phi ~ int W^2 dt) and
#: least squares squares them: |f|^6 must stay far below the float limit 1.8e308 after
#: sums over samples and time factors. 1e30^6 = 1e180 leaves 1e128 of margin, and no
#: quantity of a boost flight in SI units comes within twenty orders of magnitude of it.
#: Larger values would end in inf or NaN deep inside the computation.
MAX_ABS_VALUE = 1e30


class LateStartWarning(CasepWarning):
    """The flight seems to start after lift-off and the model lacks the initial terms."""


class FlightDataError(ValueError):
    """Bad flight data. Attributes `source`, `column` and `row` locate the problem.

    Parameters
    ----------
    source : str
        File name (or ``"<memory>"``).
    message : str
        What is wrong.
    column : str, optional
        Offending column (several: their names separated by commas).
    row : int or str, optional
        1-based data row (after the header), or ``"header"``.
    line : int, optional
        1-based line of the file.
    """

    def __init__(self, source: str, message: str, column: str | None = None,
                 row: int | str | None = None, line: int | None = None) -> None:
        self.source, self.column, self.row, self.line = source, column, row, line
        where = []
        if column is not None:  # several, comma-separated: "columns `fb_x`, `fb_y`, `fb_z`"
            names = [c.strip() for c in column.split(",")]
            where.append(f"column `{column}`" if len(names) == 1 else
                         "columns " + ", ".join(f"`{c}`" for c in names))
        if row is not None:
            where.append((f"row {row}" if row != "header" else "header")
                         + (f" (line {line})" if line is not None else ""))
        super().__init__(f"{source}: {', '.join(where) + ': ' if where else ''}{message}")


def _first_bad_row(values: np.ndarray) -> int | None:
    bad = np.flatnonzero(~np.isfinite(values))
    return int(bad[0]) if bad.size else None


def too_large(values: np.ndarray) -> tuple[int, str] | None:
    """First (0-based row, message) of a finite value above :data:`MAX_ABS_VALUE`, or None."""
    big = np.flatnonzero(np.abs(values) > MAX_ABS_VALUE)
    if not big.size:
        return None
    r = int(big[0])
    return r, (f"value {values[r]:g} exceeds the magnitude limit {MAX_ABS_VALUE:g} "
               "(SI units; the computation would overflow)")


def _check_column(src: str, col: str, values: np.ndarray, rows: np.ndarray | None = None) -> None:
    """Finite and within :data:`MAX_ABS_VALUE` (only at `rows`, a boolean mask, when given)."""
    sel = values if rows is None else np.where(rows, values, 0.0)
    r = _first_bad_row(sel)
    if r is not None:
        raise FlightDataError(src, f"value {values[r]:g} is not finite", col, r + 1)
    big = too_large(sel)
    if big is not None:
        raise FlightDataError(src, big[1], col, big[0] + 1)


@dataclass(frozen=True)
class FlightData:
    """One flight: time, specific force and velocity error, validated on creation.

    Parameters
    ----------
    t : (N,) array_like
        Time, s, strictly increasing.
    f : (N, 3) array_like
        Platform specific force, m/s^2 (x downrange, y up, z cross-range).
    dv : (N, 3) array_like
        Velocity error telemetry minus tracking, m/s.
    source : str, optional
        Where the data came from (used in error messages and reports).
    meta : dict, optional
        What the reader recorded (format, columns used, spans, ``start_speed_m_s``).
    observed : (N,) array_like of bool, optional
        Samples where dv is observed (tracking exists); default all. S_V is integrated over
        every sample, the regression uses the observed ones. dv may be NaN elsewhere.
    signals : dict of str -> (N,) array_like, optional
        Other numeric flight columns by name, in the file's unit (``a_*``, ``r_*``, ``v_*``,
        attitude, temperature, ...): what model files read with ``m.signal(name)``. Stored
        as read (NaN allowed); checked when a model uses them (:meth:`model_signals`).
    """

    t: np.ndarray
    f: np.ndarray
    dv: np.ndarray
    source: str = "<memory>"
    meta: dict = field(default_factory=dict, compare=False)
    # None (the default) means every sample; after the checks of __post_init__ always the (N,) boolean mask
    observed: np.ndarray = None  # type: ignore[assignment]
    signals: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        src = self.source
        t = np.array(self.t, dtype=float)
        f = np.array(self.f, dtype=float)
        dv = np.array(self.dv, dtype=float)
        if t.ndim != 1:
            raise FlightDataError(src, f"`t` must be 1-D, got shape {t.shape}", "t")
        obs = self._observed_mask(t.size)
        for name, arr, cols in (("f", f, FORCE_COLUMNS), ("dv", dv, DV_COLUMNS)):
            if arr.shape != (t.size, 3):
                raise FlightDataError(src, f"`{name}` must have shape ({t.size}, 3), got {arr.shape}", name)
            for i, col in enumerate(cols):
                _check_column(src, col, arr[:, i], obs if name == "dv" else None)
        _check_column(src, "t", t)
        step = np.flatnonzero(np.diff(t) <= 0)
        if step.size:
            k = int(step[0]) + 1
            raise FlightDataError(src, f"time {t[k]:.10g} s does not increase (previous row: {t[k - 1]:.10g} s)",
                                  "t", k + 1)
        for name, arr in (("t", t), ("f", f), ("dv", dv), ("observed", obs)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "signals", self._checked_signals(t.size))

    def _checked_signals(self, n: int) -> dict[str, np.ndarray]:
        if not isinstance(self.signals, dict):
            raise FlightDataError(self.source, f"`signals` must be a dict of column name -> array, got "
                                               f"{type(self.signals).__name__}", "signals")
        out = {}
        for name, values in self.signals.items():
            arr = np.array(values, dtype=float)
            if not isinstance(name, str) or arr.shape != (n,):
                raise FlightDataError(self.source, f"signal must be a named array of shape ({n},), got "
                                                   f"{arr.shape}", str(name))
            arr.setflags(write=False)
            out[name] = arr
        return out

    def model_signals(self, names: tuple[str, ...], model: str) -> dict[str, np.ndarray]:
        """The columns `names` that model `model` uses, checked: present and finite.

        Raises
        ------
        FlightDataError
            Naming the file, the model and the column that is missing, or the first row where
            a column is not finite.
        """
        out = {}
        derived = self._kinematic_acceleration(names)
        for c in names:
            if c in derived:
                out[c] = derived[c]
                continue
            if c not in self.signals:
                have = ", ".join(self.signals) or "none"
                raise FlightDataError(self.source, f"missing column that model `{model}` needs (the flight's "
                                                   f"extra columns: {have})", c)
            values = self.signals[c]
            r = _first_bad_row(values)
            if r is not None:
                raise FlightDataError(self.source, f"value {values[r]:g} is not finite (a signal that model "
                                                   f"`{model}` uses)", c, r + 1)
            out[c] = values
        return out

    def _kinematic_acceleration(self, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The kinematic acceleration signals ``a_x, a_y, a_z`` a model asks for (a tracking time offset's
        ``a(t) dt_trk``) when a one-file flight has none of them: ``f + g`` with flat-Earth gravity
        (:func:`casep.gravity.kinematic_acceleration`, the time-offset test's own ``a``). A pair
        derives them from its telemetry velocity when it reads the files (:func:`casep.io.files.read_flight_pair`)."""
        wanted = [c for c in ACCELERATION_SIGNALS if c in names]
        pair = isinstance(self.meta, dict) and self.meta.get("format") == "pair"
        if not wanted or pair or any(c in self.signals for c in ACCELERATION_SIGNALS):
            return {}
        from casep.gravity import kinematic_acceleration

        a = kinematic_acceleration(self.t, self.f)
        return {c: a[:, i] for i, c in enumerate(ACCELERATION_SIGNALS) if c in wanted}

    def _observed_mask(self, n: int) -> np.ndarray:
        if self.observed is None:
            return np.ones(n, dtype=bool)
        obs = np.array(self.observed)
        if obs.dtype != bool or obs.shape != (n,):
            raise FlightDataError(self.source, f"`observed` must be a boolean array of shape ({n},), got "
                                               f"{obs.dtype} of shape {obs.shape}", "observed")
        if n and not obs.any():
            raise FlightDataError(self.source, "no sample is observed (tracking covers none)", "observed")
        return obs

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t.size)

    @property
    def n_observed(self) -> int:
        """Number of samples where dv is observed."""
        return int(np.count_nonzero(self.observed))

    def observed_index(self) -> slice | np.ndarray:
        """The observed rows: a slice when they are contiguous (numpy views, no copy)."""
        idx = np.flatnonzero(self.observed)
        if idx.size and idx[-1] - idx[0] + 1 == idx.size:
            return slice(int(idx[0]), int(idx[-1]) + 1)
        return idx

    def observed_rows(self, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(S[obs], dv[obs], t[obs])``: the regression rows of an S_V built on all samples.

        Parameters
        ----------
        S : (N, 3, n) ndarray
            S_V integrated over every sample (from the first telemetry sample).
        """
        S = np.asarray(S)
        if S.shape[:1] != (self.n_samples,):
            raise ValueError(f"`S` must have {self.n_samples} samples, got shape {S.shape}")
        k = self.observed_index()
        return S[k], self.dv[k], self.t[k]
