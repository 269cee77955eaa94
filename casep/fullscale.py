"""Readings held at a sensor's full scale (saturation, clipping): the one rule of calibration, navigation, the
strapdown telemetry's saturation screen and its attitude check.

A sensor saturates when its reading reaches the end of its range; the reading is then the range, not the
motion. Quantised readings repeat values naturally (three equal counts at the smooth peak of a turn), so
a repeated value alone is no saturation. :func:`held_full_scale` looks at every column and each of its
sides (maximum, minimum):

- **a declared full scale** ``F`` (``--acc-range G``, ``--gyr-range DPS``; SI inside): a reading at or
  beyond ``(1 - CLIP_MARGIN) F`` on that side is at it (at or beyond: a reading past the declared range
  is no trustworthy reading either);
- **without one**, the column's extreme value ``e`` (its maximum or minimum) is at a full scale when it is

  - for raw counts, a limit of a ``b``-bit converter, ``b`` in :data:`ADC_BITS` (unsigned ``0`` /
    ``2^b - 1``, signed ``-2^(b-1)`` / ``2^(b-1) - 1``), within ``max(1, 2^b / 1000)`` counts and at
    least a tenth of the half range ``2^(b-1)`` from the column's median;
  - for a physical unit, a nominal range (:data:`casep.units.ACC_RANGES_G`,
    :data:`casep.units.GYR_RANGES_DPS`) within :data:`casep.units.FULL_SCALE_TOLERANCE`, on its side of
    zero, for an accelerometer a tenth of ``|e|`` or more from the column's median (a static
    accelerometer reads 1 g for ever without clipping; a gyro held at its range for most of a record is
    clipped all that time), in a column with noise off the rail (where :data:`HELD_FRACTION` or more of
    the consecutive samples not at ``e`` are equal, as in a noise-free simulation, a constant thrust
    near 4 g is held exactly without any clipping: declare the full scale there);
  - for a physical unit off every nominal range, the column's own extreme ``e`` (a full scale the data imply:
    a gyro clipped at 24 deg/s), when

    - **noise cannot hold it** (:func:`noise_cannot_hold`): the column's white noise ``sigma`` off ``+-e``
      (everywhere, its quietest stretch) is far above the step ``q`` its readings are resolved to
      (:data:`NOISE_STEPS` steps or more: rounding scatters a noise-free record by a step or two), and its
      longest run of ``L`` readings equal to ``e`` has the bound ``N (q / (sigma sqrt(2 pi)))^(L-1)`` below
      :data:`NOISE_ALPHA`: each reading of a noisy sensor lands in the one cell of width ``q`` of the reading
      before it with probability at most ``q`` times the largest density of its noise, ``1 / (sigma sqrt(2
      pi))``, whatever the motion, so ``L - 1`` in a row happen with probability at most that power, at any of
      the ``N`` samples at most ``N`` times it. Such a run is a clip whether it is left or lasts to the end of
      the record (a gyro saturated after apogee stays saturated), wherever the column's median lies;
    - or, in a column whose noise says nothing (noise-free, or quantised coarser than its noise), no two
      consecutive readings off ``+-e`` are equal (a continuous reading, noisy or smoothly moving, repeats to
      all digits only on a rail; a quantised or noise-free column repeats on a pad at 0 or a coast, so its
      held extreme says nothing), ``e`` lies a tenth of ``|e|`` or more from the column's median, and a run of
      :data:`CLIP_RUN` readings at ``e`` is entered and left (a value held from the first or to the last
      sample of a noise-free record is the state the record starts or ends in, as a pad);

  and the readings equal to ``e`` are at it (the converter holds its last code);

and a reading at full scale is saturated when it lies in a run of at least :data:`CLIP_RUN` consecutive
readings at full scale on the same side.

**The margin.** ``CLIP_MARGIN = 0.01`` of ``F``, which is 0.5 % of the span ``2F``: the two figures the
calibration and the navigation stated are this one band. A reading in a physical unit is counts times a
sensitivity; converted with the part's nominal sensitivity the rail reads ``F (1 - 2^(1-b))``, a few
parts per 10^5 below ``F``, but converted with a calibrated sensitivity it moves by the part's
sensitivity error, about 1 % on MEMS data sheets. 1 % of ``F`` still finds that rail where 0.5 % would
miss it; what it costs is that a motion held 3 samples within 1 % of the range is marked, a motion at the
edge of the part's range anyway.

What a saturated reading spoils is the caller's judgement: a turn of a calibration, a static pose's mean,
or a navigation from that sample on.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from casep._kernels import runs
from casep._special import MAD_SIGMA
from casep.units import ACC_RANGES_G, FULL_SCALE_TOLERANCE, G0, GYR_RANGES_DPS

__all__ = ["held_full_scale", "held_mask", "HeldFullScale", "FULL_SCALE_UNITS", "NOMINAL_RANGES", "ADC_BITS",
           "CLIP_RUN", "CLIP_MARGIN", "HELD_FRACTION", "NOISE_ALPHA", "NOISE_BLOCK", "NOISE_STEPS",
           "noise_cannot_hold", "white_noise", "resolution", "RESOLUTION_READINGS", "DECLARED_EXCEEDED",
           "beyond_declared"]

#: Word lengths of the converters raw counts come from.
ADC_BITS = (8, 10, 12, 14, 16, 18, 20, 24, 32)
#: A reading at full scale is saturated in a run of at least this many consecutive readings at it.
CLIP_RUN = 3
#: With a declared full scale F, a reading at or beyond (1 - CLIP_MARGIN) F is at it (module notes).
CLIP_MARGIN = 0.01
#: A reading beyond this many times the declared full scale is no clipped reading: the declared range (or the
#: column's unit) is wrong (:func:`beyond_declared`). Sensors read a little past their nominal range (a few per
#: cent, the scale factor's tolerance), not half as much again.
DECLARED_EXCEEDED = 1.5
#: Without a declared full scale: a physical column whose consecutive samples are equal this often has no
#: noise (a simulated record), so a value held at its extreme says nothing of the sensor's range.
HELD_FRACTION = 0.5
#: A run of equal readings is beyond a noisy column's noise when the bound on the chance that its noise makes one
#: anywhere in the record is below this (:func:`noise_cannot_hold`).
NOISE_ALPHA = 1e-6
#: Readings per stretch whose noise :func:`white_noise` estimates (the quietest stretch is the column's noise).
NOISE_BLOCK = 256
#: A column's noise says something of a run only when its std is this many resolution steps or more: rounding
#: (a noise-free record computed in floating point, written to a few digits) scatters readings by a step or two,
#: and a value held exactly there is a state, not a clip.
NOISE_STEPS = 100.0
#: Readings nearest the extreme in magnitude whose decimal cells say how finely a column is written
#: (:func:`resolution`).
RESOLUTION_READINGS = 64
#: The unit of each sensor's full scale at the edge (command line), and SI per that unit.
FULL_SCALE_UNITS = {"accelerometer": ("g", G0), "gyro": ("deg/s", math.pi / 180.0)}
#: The nominal ranges (+-) of each sensor, in the unit of FULL_SCALE_UNITS.
NOMINAL_RANGES = {"accelerometer": ACC_RANGES_G, "gyro": GYR_RANGES_DPS}


class HeldFullScale(NamedTuple):
    """One column's side at full scale: ``axis`` (column index), ``side`` (``maximum``/``minimum``), ``value``
    (the column's extreme on that side, readings' unit), ``why`` (which full scale), ``runs`` ((start, end)
    with end excluded, each at least :data:`CLIP_RUN` readings)."""

    axis: int
    side: str
    value: float
    why: str
    runs: list[tuple[int, int]]


def beyond_declared(x: np.ndarray, sensor: str, declared: float | None, si: float = 1.0
                    ) -> tuple[int, int, str] | None:
    """The first column of readings `x` (SI per unit `si`) that goes beyond :data:`DECLARED_EXCEEDED` times the
    declared full scale `declared` (SI; None: nothing declared, nothing to judge): ``(column, first row beyond, what
    it says)``, the text naming the largest reading, the ratio and the option; None when every column stays within.
    A sensor clipped at its range reads at it, not past it, so such a column says the declared range is wrong."""
    if declared is None:
        return None
    x = np.abs(np.asarray(x, float)) * si
    for j in range(x.shape[1]):
        over = np.flatnonzero(x[:, j] > DECLARED_EXCEEDED * declared)
        if over.size:
            unit, per = FULL_SCALE_UNITS[sensor]
            top = float(x[:, j].max())
            flag = "--gyr-range" if sensor == "gyro" else "--acc-range"
            return j, int(over[0]), (f"the {sensor} reads up to {top / per:.6g} {unit}, {top / declared:.3g} times "
                                     f"the declared full scale {declared / per:g} {unit} ({flag}): a sensor clipped "
                                     "at its range reads at it, not past it; declare the sensor's range (or check "
                                     "the column's unit)")
    return None


def held_full_scale(x: np.ndarray, sensor: str, *, si: float | None = 1.0, declared: float | None = None,
                    min_run: int = CLIP_RUN) -> list[HeldFullScale]:
    """Where the readings `x` are held at the sensor's full scale (module notes), per column and side.

    Parameters
    ----------
    x : (N, k) ndarray
        Readings of one sensor, one column per axis.
    sensor : str
        ``"accelerometer"`` or ``"gyro"`` (its nominal ranges, :data:`NOMINAL_RANGES`).
    si : float or None
        SI per unit of the readings (m/s^2 or rad/s per unit); None: raw counts (the converters' limits).
    declared : float, optional
        The declared full scale, SI (m/s^2, rad/s); not used for raw counts (their full scale is the
        converter's limit).
    min_run : int
        Readings in a row at full scale for a saturation (:data:`CLIP_RUN`).

    Returns
    -------
    list of HeldFullScale
        The sides with at least one run, in column order, maximum first.
    """
    x = np.asarray(x, float)
    out = []
    for j in range(x.shape[1]):
        col = x[:, j]
        for side, ext in (("maximum", float(col.max())), ("minimum", float(col.min()))):
            if si is not None and declared is not None:
                end = (declared if side == "maximum" else -declared) / si
                at = col >= (1 - CLIP_MARGIN) * end if end > 0 else col <= (1 - CLIP_MARGIN) * end
                why: str | None = f"the declared full scale {end:g}"
            else:
                at = col == ext
                why = _rail(ext, side, col, sensor, si) if at.sum() >= min_run else None
            long = [(a, b) for a, b in runs(at) if b - a >= min_run] if why else []
            if long:
                out.append(HeldFullScale(j, side, ext, str(why), long))
    return out


def held_mask(found: list[HeldFullScale], shape: tuple[int, int]) -> np.ndarray:
    """The (N, k) readings of :func:`held_full_scale`'s runs."""
    mask = np.zeros(shape, bool)
    for h in found:
        for a, b in h.runs:
            mask[a:b, h.axis] = True
    return mask


def _rail(ext: float, side: str, column: np.ndarray, sensor: str, si: float | None) -> str | None:
    """Why the column's extreme `ext` (its ``maximum`` or ``minimum``, `side`) is a full scale nobody declared, or
    None (module notes)."""
    top = side == "maximum"
    med = float(np.median(column))
    if si is None:  # raw counts: a converter's limit
        for b in ADC_BITS:
            for rail, kind in (((2 ** b - 1, "unsigned"), (2 ** (b - 1) - 1, "signed")) if top
                               else ((0, "unsigned"), (-(2 ** (b - 1)), "signed"))):
                if abs(ext - rail) <= max(1.0, 2.0 ** b / 1000) and abs(ext - med) >= 0.1 * 2.0 ** (b - 1):
                    return (f"the {kind} {b}-bit converter's limit {rail}" if rail else
                            "the unsigned converter's limit 0")
        return None
    if ext == 0.0 or (ext > 0) != top:
        return None  # a rail lies on its side of zero
    beyond = noise_cannot_hold(column, ext)
    if beyond is None and sensor == "accelerometer" and abs(ext - med) < 0.1 * abs(ext):
        return None  # an accelerometer's rail lies away from where the column spends its time
    off = (column[1:] != ext) & (column[:-1] != ext)  # the noise is judged off the rail (a gyro may sit on it)
    held = np.mean(column[1:][off] == column[:-1][off]) if off.any() else 1.0
    if beyond is None and held >= HELD_FRACTION:
        return None  # noise-free: every steady span is held exactly
    name, per = FULL_SCALE_UNITS[sensor]
    v = abs(ext) * si / per
    near = min(NOMINAL_RANGES[sensor], key=lambda r: abs(v / r - 1.0))
    if abs(v / near - 1.0) <= FULL_SCALE_TOLERANCE:
        return f"the nominal +-{near:g} {name} range"
    if beyond is None and not _held_off_noise(ext, column, med):
        return None
    flag = "--gyr-range" if sensor == "gyro" else "--acc-range"
    return (f"a full scale +-{v:.6g} {name} implied by identical readings at the column's extreme{beyond or ''}, no "
            f"nominal range: {flag} {v:.6g} declares it")


def _held_off_noise(ext: float, column: np.ndarray, med: float) -> bool:
    """In a column whose noise says nothing, whether its extreme `ext` is held as a rail (module notes): no exact
    repeat off the rails +-`ext`, `ext` far from the median `med`, and a run at it entered and left."""
    # A continuous reading, noisy or smoothly moving, never repeats to all digits off its rails, while a quantised
    # or noise-free column repeats on a pad or a coast, and its held extreme says nothing.
    free = (np.abs(column[1:]) != abs(ext)) & (np.abs(column[:-1]) != abs(ext))  # off both rails (+-e)
    if not free.any() or np.any(column[1:][free] == column[:-1][free]) or abs(ext - med) < 0.1 * abs(ext):
        return False
    # a clip is entered and left: a value held from the first or to the last sample is a state
    return any(a > 0 and b < column.size and b - a >= CLIP_RUN for a, b in runs(column == ext))


def white_noise(column: np.ndarray, ext: float) -> float:
    """The white noise of `column` off its rails ``+-ext``, its quietest stretch (std, the column's unit); 0 where
    some stretch holds its readings (noise-free, or quantised coarser than the noise) or none shows noise.

    Over every window of 5 consecutive readings not all on a rail ``+-ext`` (a reading at the rail now and then is
    the noise of a quiet quantised stretch; five in a row say nothing of it) the third and fourth differences; in
    stretches of :data:`NOISE_BLOCK` windows ``s_k = 1.4826 median |D^k x| / sqrt(C(2k, k))`` (white noise of std
    ``sigma`` has ``D^k x`` of std ``sigma sqrt(C(2k, k))``: 20 and 70). A stretch is noise where ``s_4 >= s_3 /
    2`` (white noise: ``s_4 = s_3``; a smooth motion ``x(t)`` sampled every ``h`` has ``D^k x ~ h^k x^(k)``, so
    ``s_4 / s_3 ~ 0.53 omega h``, small), motion elsewhere (it says nothing of the noise). The result is the
    smallest ``s_4`` of the noise stretches (the noise the sensor keeps everywhere, as at rest on a pad), 0 when a
    stretch has ``s_3 = 0``.
    """
    c = np.asarray(column, float)
    on = np.abs(c) == abs(ext)
    if c.size < 5 + NOISE_BLOCK:
        return 0.0
    ok = ~(on[:-4] & on[1:-3] & on[2:-2] & on[3:-1] & on[4:])  # a window held on a rail says nothing of the noise
    d3, d4 = np.abs(np.diff(c, 3)[:-1][ok]), np.abs(np.diff(c, 4)[ok])
    nb = d3.size // NOISE_BLOCK
    if nb == 0:
        return 0.0
    s3 = MAD_SIGMA * np.median(d3[:nb * NOISE_BLOCK].reshape(nb, -1), axis=1) / math.sqrt(20.0)  # D^k x of white
    s4 = MAD_SIGMA * np.median(d4[:nb * NOISE_BLOCK].reshape(nb, -1), axis=1) / math.sqrt(70.0)  # noise: C(2k, k)
    if np.any(s3 == 0.0):
        return 0.0
    noise = s4 >= 0.5 * s3
    return float(s4[noise].min()) if noise.any() else 0.0


def resolution(column: np.ndarray, ext: float) -> float:
    """The step `column`'s readings are resolved to at its extreme `ext`, at most: the largest of the decimal cell
    the column is written to near `ext`, the binary one (the spacing of doubles at `ext`) and the smallest gap
    between distinct readings (a column on a grid, as counts times a sensitivity, has no smaller one).

    The decimal cell of a reading ``v`` is ``10^(floor(log10 |v|) - d + 1)``, ``d`` the fewest significant digits
    that give ``v`` back. The column's cell near `ext` is the finest of the cells of the
    :data:`RESOLUTION_READINGS` readings off the rails ``+-ext`` nearest ``|ext|`` in magnitude, each raised to the
    decade of `ext` when it lies in a lower one (a column written to a fixed number of significant digits has a
    cell ten times coarser a decade up; one written to fixed decimals keeps it, and is overstated, the safe side).
    Not the cell of `ext` alone: a sensor clipped at a round value (exactly 1 rad/s) writes it in one digit while
    every other reading carries all of its digits; only a column with no other reading falls back on it."""
    c = np.asarray(column, float)
    off = c[(np.abs(c) != abs(ext)) & (c != 0.0) & np.isfinite(c)]
    decade = math.floor(math.log10(abs(ext)))
    if off.size:
        near = off[np.argsort(np.abs(np.abs(off) - abs(ext)), kind="stable")[:RESOLUTION_READINGS]]
        cell = min(_decimal_cell(float(v)) * 10.0 ** max(0, decade - math.floor(math.log10(abs(float(v)))))
                   for v in near)
    else:
        cell = _decimal_cell(ext)
    cell = max(cell, float(np.spacing(abs(ext))))
    u = np.unique(c[np.isfinite(c)])
    return max(cell, float(np.diff(u).min())) if u.size > 1 else cell


def _decimal_cell(v: float) -> float:
    """The decimal cell a nonzero reading `v` is written to: ``10^(floor(log10 |v|) - d + 1)``, ``d`` the fewest
    significant digits that give `v` back."""
    d = next(k for k in range(1, 18) if float(f"{v:.{k}g}") == v)
    return 10.0 ** (math.floor(math.log10(abs(v))) - d + 1)


def noise_cannot_hold(column: np.ndarray, ext: float) -> str | None:
    """Why the longest run of readings equal to `ext` in `column` is none its noise makes (module notes), or None.

    With ``sigma`` the column's white noise (:func:`white_noise`), ``q`` its resolution at `ext`
    (:func:`resolution`), ``N`` its length and ``L`` the run's: the chance that noise holds ``L`` readings in a
    row anywhere in the record is at most ``N (q / (sigma sqrt(2 pi)))^(L-1)`` (each reading falls in the cell of
    the one before with probability at most ``q`` times its noise's largest density); below
    :data:`NOISE_ALPHA` the run is a clip.
    """
    column = np.asarray(column, float)
    spans = [b - a for a, b in runs(column == ext)]
    L = max(spans, default=0)
    sigma = white_noise(column, ext) if L >= CLIP_RUN else 0.0
    if sigma == 0.0:
        return None
    q = resolution(column, ext)
    if sigma < NOISE_STEPS * q:
        return None  # noise at the rounding level, or quantised coarser than sigma >> q: it says nothing
    p = q / (sigma * math.sqrt(2.0 * math.pi))
    log_bound = math.log10(column.size) + (L - 1) * math.log10(p) if p < 1.0 else 0.0
    if log_bound > math.log10(NOISE_ALPHA):
        return None
    return (f" ({L} in a row, where noise of std {sigma:.3g} read to {q:.3g}, the readings' unit, holds as many with a "
            f"chance below 10^{math.ceil(log_bound):d})")
