"""The regression of a flight, built once: S_V (or the means to regenerate it), its reduction, its rank.

A :class:`Problem` is what every solver and the diagnostics take (arrays still work). It is
built once per flight and model (``casep demo`` solves seven methods on one Problem). S_V is kept
whole when it fits in :data:`SV_KEEP_BYTES` (512 MB by default: a 100 Hz, 200 s flight of 36
coefficients is 17 MB, a 2 kHz one 310 MB), or when asked (``keep_sv=True``). Beyond that it is never whole: the scaled
QR reduction is accumulated block by block while S_V is integrated
(:meth:`casep.model.sv.SVBuilder.blocks`), and whatever needs the rows again (residuals, the
recursive methods, the residual checks) regenerates them block by block, so the memory of
``casep separate --method ols|rls`` and ``casep diagnose`` grows with ``N`` (the flight's own
columns and the residuals), not with ``N x 3 x n``; only the methods that need S whole
(:meth:`Problem.sv`: GLS, Huber, the batched Monte Carlo) materialise it.

Rows are ``(N, 3)`` samples x axes; ``S.reshape(3 N, n)`` is the stacked regression
(:mod:`casep` conventions).
"""

from __future__ import annotations

from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np

from casep.io.flight import FlightData
from casep.noise.model import NoiseModel, whiten, whiten_blocks
from casep.regression.linalg import (
    RankAnalysis,
    ReducedSystem,
    analyze_rank,
    least_squares_rss,
    reduce_qr,
    reduce_qr_blocks,
)

__all__ = ["Problem", "DEFAULT_BLOCK_ROWS", "SV_KEEP_BYTES", "NOISE_FREE", "is_rounding_level", "rounding_level"]

#: Samples per regenerated block of S_V (16384 x 3 x 36 doubles = 14 MB; the QR of a block and
#: its copies take a few times that).
DEFAULT_BLOCK_ROWS = 16384
#: S_V up to this many bytes is kept whole by default (a 100 Hz, 200 s flight of 36 coefficients
#: is 17 MB, a 2 kHz one 310 MB); beyond it, it is reduced block by block and regenerated when its
#: rows are needed. Kept, it is integrated once per fit; regenerated, the default path of `casep
#: separate` integrates it about 13 times (noise fit, robust check, residual checks): on the 2 kHz
#: flight 5.3x one QR of its rows (peak 1.3 GB) against 6.6x (peak 0.9 GB).
SV_KEEP_BYTES = 512 * 2**20
#: Residual RMS at or below this fraction of the largest |dv|: the data carry no noise, only rounding
#: (double precision rounds at ~1e-16 relative; S_V integration and file round trips add a few digits).
NOISE_FREE = 1e-9


def rounding_level(scale):
    """The rounding level of data whose largest magnitude is `scale`: ``NOISE_FREE * scale`` (elementwise).

    What casep takes for no noise: a residual RMS at or below it is rounding (:func:`is_rounding_level`),
    and a noise std estimated from such residuals is floored there (the radar groups,
    :meth:`casep.radar.regression.RadarRegression.solve`), so that no std, step or test is measured
    against a noise level of zero.
    """
    return NOISE_FREE * np.asarray(scale, dtype=float) if np.ndim(scale) else NOISE_FREE * float(scale)


def is_rounding_level(rms: float, scale: float, floor: float = 0.0) -> bool:
    """The noise-free rule: a residual RMS at the rounding level of data whose largest magnitude is `scale`,
    or at the interpolation floor of a pair of files (`floor`, m/s RMS: what carrying one file's velocity to the
    other's times errs by, known from the data: :func:`casep.io.pair.interpolation_floor`).

    ``rms <= max(NOISE_FREE * scale, floor)`` (:func:`rounding_level`; or no data at all: ``scale == 0``). Every part
    of casep that asks whether a flight carries noise (the noise model, the robust filter, the residual
    checks, the magnitude and prior checks, the radar groups) asks it through :meth:`Problem.is_noise_free`
    or this.
    """
    return bool(scale == 0.0 or rms <= max(rounding_level(scale), floor))


class Problem:
    """A validated regression ``y = S D + e`` with its scaled QR reduction and rank analysis.

    Build it with :meth:`from_flight`, :meth:`from_arrays` or :meth:`from_reduction`; pass it
    to any solver in place of ``S`` (``solve_ols(problem)``) or to
    :func:`casep.checks.diagnostics.diagnose`.

    Attributes
    ----------
    names, units : tuple of str
        Coefficient names and natural units, model order.
    si_factors : (n,) ndarray
        SI value of one natural unit per coefficient.
    model : str or None
        Model name (set on the results).
    y : ndarray or None
        Observed velocity error, ``(N, 3)`` (or ``(m,)`` for a 2-D ``S``); None for a
        reduction-only problem.
    t : (N,) ndarray or None
        Times of the rows, s.
    red : ReducedSystem
        The column-scaled QR reduction (computed once).
    source : str
        Where the rows came from (file name), for messages.
    segment_starts : tuple of int
        First sample of each segment of the rows (several flights stacked: one per flight).
    row_unit : str
        Unit of the rows ``y`` for messages: ``m/s`` (a flight's velocity error), a ground test's reading unit,
        or ``""`` for rows divided by their noise std (dimensionless).
    """

    def __init__(self, *, names: Sequence[str], units: Sequence[str], si_factors: Sequence[float] | np.ndarray,
                 red: ReducedSystem, y: np.ndarray | None = None, t: np.ndarray | None = None,
                 model: str | None = None, source: str = "<memory>", S: np.ndarray | None = None,
                 regenerate: Callable[[int], Iterator[tuple[slice, np.ndarray, np.ndarray]]] | None = None,
                 f: np.ndarray | None = None, row_unit: str = "m/s") -> None:
        self.names = tuple(names)
        self.units = tuple(units)
        self.si_factors = np.asarray(si_factors, dtype=float)
        self.red = red
        self.y = y
        self.t = t
        self.f = f
        self.model = model
        self.source = source
        #: Unit of the rows ``y`` (a flight's velocity error: m/s; a ground test's readings: their unit), for messages.
        self.row_unit = row_unit
        self._S = S
        self._regenerate = regenerate
        self._ranks: dict[tuple, RankAnalysis] = {}
        #: First row (sample) of each segment: flights stacked into one problem
        #: (:class:`casep.regression.joint.JointProblem`) are segments; one flight is one segment. A
        #: recursive method's noise memory restarts at each segment.
        self.segment_starts: tuple[int, ...] = (0,)
        #: The raw problem this one was derived from by :meth:`subset` or :meth:`whitened` (None: raw).
        self.parent: Problem | None = None
        #: Indices of this problem's samples among the parent's (None: all of them).
        self.sample_index: np.ndarray | None = None
        #: The noise model the rows are whitened for (None: raw rows).
        self.noise: NoiseModel | None = None
        self._unwhitened: Problem | None = None  # the same rows before whitening
        #: The interpolation floor of a pair of files, m/s RMS (:func:`is_rounding_level`; 0: none).
        self.interpolation_floor = 0.0
        #: The telemetry's gaps ``((start, end), ...)``, s: across each the telemetry's velocity error may jump
        #: (an INS navigated across lost samples; :func:`casep.checks.time_offset.gap_columns`).
        self.gaps: tuple[tuple[float, float], ...] = ()
        #: The model's declared magnitude per coefficient, natural units (``ErrorModel.scales``; empty: none known):
        #: what bounds an exactly dependent coefficient's share of its dependency
        #: (:func:`casep.estimators._base.finish`).
        self.magnitudes: dict[str, float] = {}
        #: Where rows come from (file, line, time): ``locate(rows)`` for indices of this problem's rows.
        self._locate_flight: tuple[FlightData, np.ndarray] | None = None  # (flight, observed samples) of a flight's
        n = red.n
        for label, seq in (("names", self.names), ("units", self.units), ("si_factors", self.si_factors)):
            if len(seq) != n:
                raise ValueError(f"`{label}` has {len(seq)} entries but `S` has {n} columns")

    # ----------------------------------------------------------------- constructors
    @classmethod
    def from_arrays(cls, S: np.ndarray, y: np.ndarray, t: np.ndarray | None = None, *,
                    names: Sequence[str] | None = None, units: Sequence[str] | None = None,
                    si_factors: Sequence[float] | np.ndarray | None = None, model: str | None = None,
                    f: np.ndarray | None = None, row_unit: str = "m/s",
                    magnitudes: Mapping[str, float] | None = None) -> "Problem":
        """A problem from ``S`` ``(N, 3, n)`` or ``(m, n)`` and ``y`` ``(N, 3)`` or ``(m,)`` (kept whole; `row_unit`:
        the unit of ``y``, for messages; `magnitudes`: the model's declared ones, :attr:`magnitudes`)."""
        S_arr = np.asarray(S, dtype=float)
        if S_arr.ndim not in (2, 3):
            raise ValueError(f"`S` must be (m, n) or (N, 3, n), got {S_arr.ndim}-D")
        n = S_arr.shape[-1]
        y_arr = np.asarray(y, dtype=float)
        shape = S_arr.shape[:-1]
        if y_arr.size != int(np.prod(shape)):
            raise ValueError(f"`y` has {y_arr.size} values but `S` has {int(np.prod(shape))} rows")
        y_arr = y_arr.reshape(shape)
        if t is not None:
            t = np.asarray(t, dtype=float)
            if t.shape != shape[:1]:
                raise ValueError(f"`t` must have shape {shape[:1]}, got {t.shape}")
        names = tuple(f"c{j}" for j in range(n)) if names is None else tuple(names)
        units = ("",) * n if units is None else tuple(units)
        si = np.ones(n) if si_factors is None else np.asarray(si_factors, dtype=float)
        pb = cls(names=names, units=units, si_factors=si, red=reduce_qr(S_arr, y_arr, names=names), y=y_arr, t=t,
                 model=model, S=S_arr, f=f, row_unit=row_unit)
        pb.magnitudes = dict(magnitudes or {})
        return pb

    @classmethod
    def from_reduction(cls, red: ReducedSystem, *, names: Sequence[str], units: Sequence[str],
                       si_factors: Sequence[float] | np.ndarray, model: str | None = None,
                       source: str = "<reduction>") -> "Problem":
        """A problem known only by its reduction (no rows: no residuals, no recursive methods)."""
        return cls(names=names, units=units, si_factors=si_factors, red=red, model=model, source=source)

    @classmethod
    def from_flight(cls, flight, model, *, keep_sv: bool | None = None,
                    block_rows: int = DEFAULT_BLOCK_ROWS) -> "Problem":
        """The regression of a flight for a set-up model, S_V integrated once; no check of the flight.

        The checks before estimation (too few samples, units, an all-zero dv, the set-up, a late
        start) are judgements of the data: :func:`casep.checks.flight.flight_problem` runs
        them and then builds the problem here, as every workflow and command does.

        S_V is integrated over every sample from the first telemetry sample (where the model
        has dv = 0 and phi = 0); the rows where tracking observes dv are the regression
        (:attr:`casep.io.flight.FlightData.observed`).

        Parameters
        ----------
        flight : FlightData
        model : ErrorModel
            Set up.
        keep_sv : bool, optional
            Keep S_V whole (True), or reduce it block by block and regenerate blocks when rows
            are needed (False: memory independent of N x n). Default: keep it when it takes at
            most :data:`SV_KEEP_BYTES`.
        block_rows : int, optional
            Samples per block.
        """
        from casep.model.sv import SVBuilder

        builder = SVBuilder(model)
        signals = flight.model_signals(model.signals, model.name)
        obs = flight.observed
        dv, t = flight.observed_rows(flight.t)[1:]  # dv[obs], t[obs] (views when contiguous)
        f_obs = flight.f[obs] if not obs.all() else flight.f
        if keep_sv is None:
            keep_sv = flight.n_samples * 3 * model.n_coefficients * 8 <= SV_KEEP_BYTES
        common = dict(names=model.names, units=model.units, si_factors=model.si_factors, model=model.name,
                      source=flight.source)
        if keep_sv:
            S = flight.observed_rows(builder.build(flight.t, flight.f, signals=signals))[0]
            pb = cls(red=reduce_qr(S, dv, names=model.names), y=dv, t=t, S=S, f=f_obs, **common)
            pb._locate_flight = (flight, np.flatnonzero(obs))
            pb.interpolation_floor = float(flight.meta.get("interpolation_floor_m_s") or 0.0)
            pb.gaps = _telemetry_gaps(flight.meta)
            pb.magnitudes = dict(model.scales)
            return pb

        def regenerate(rows: int) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
            k0 = 0  # observed rows before this block
            for s, e, blk in builder.blocks(flight.t, flight.f, rows, signals=signals):
                o = obs[s:e]
                S_obs = blk if o.all() else blk[o]
                k1 = k0 + S_obs.shape[0]
                if k1 > k0:
                    yield slice(k0, k1), S_obs, dv[k0:k1]
                k0 = k1

        red = reduce_qr_blocks(((S_b, y_b) for _, S_b, y_b in regenerate(block_rows)), model.n_coefficients,
                               names=model.names)
        pb = cls(red=red, y=dv, t=t, regenerate=regenerate, f=f_obs, **common)
        pb._locate_flight = (flight, np.flatnonzero(obs))
        pb.interpolation_floor = float(flight.meta.get("interpolation_floor_m_s") or 0.0)
        pb.gaps = _telemetry_gaps(flight.meta)
        pb.magnitudes = dict(model.scales)
        return pb

    def with_y(self, y: np.ndarray) -> "Problem":
        """The same regression with other observations (e.g. de-noised dv): reduced again, S shared."""
        y0 = self._need_rows()
        y = np.asarray(y, dtype=float).reshape(y0.shape)
        regenerate = None
        if self._S is None:
            base = self._regenerated

            def regenerate(rows: int) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
                for sl, S_b, _ in base(rows):
                    yield sl, S_b, y[sl]

        new = self._derived(red=self.red, y=y, t=self.t, S=self._S, regenerate=regenerate, f=self.f)
        new.red = reduce_qr_blocks(((S_b, y_b) for _, S_b, y_b in new.blocks()), self.n, names=self.names)
        return new

    def _derived(self, **rows: Any) -> "Problem":
        """A problem on other rows (`rows`: ``red``, ``y``, ``t``, ``S``, ``regenerate``, ``f``) with this one's
        coefficients, model, source and row unit."""
        new = Problem(names=self.names, units=self.units, si_factors=self.si_factors, model=self.model,
                      source=self.source, row_unit=self.row_unit, **rows)
        new.gaps = self.gaps
        new.magnitudes = self.magnitudes
        return new

    def subset(self, keep: np.ndarray) -> "Problem":
        """The regression on the samples where `keep` (N,) is True (time order kept; S shared).

        The parent (this problem, or its own parent) and the kept sample indices are recorded:
        residuals of the whole flight stay available through :attr:`parent`.
        """
        y0 = self._need_rows()
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != (self.n_samples,) or y0.ndim != 2:
            raise ValueError(f"`keep` must be a boolean mask of the {self.n_samples} samples, got shape {keep.shape}")
        idx = np.flatnonzero(keep)
        y = y0[idx]
        t = None if self.t is None else self.t[idx]
        f = None if self.f is None else self.f[idx]
        S: np.ndarray | None = None
        regenerate = None
        if self._S is not None:
            S = self._S[idx]
        else:
            base = self._regenerated

            def regenerate(rows: int) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
                k0 = 0
                for sl, S_b, _ in base(rows):
                    o = keep[sl]
                    k1 = k0 + int(o.sum())
                    if k1 > k0:
                        yield slice(k0, k1), S_b[o], y[k0:k1]
                    k0 = k1

        new = self._derived(red=reduce_qr(S, y) if S is not None else self.red, y=y, t=t, S=S, regenerate=regenerate,
                            f=f)
        if S is None:
            new.red = reduce_qr_blocks(((S_b, y_b) for _, S_b, y_b in new.blocks()), self.n)
        root = self.parent if self.parent is not None else self
        new.parent = root
        new.sample_index = idx if self.sample_index is None else self.sample_index[idx]
        return new

    def whitened(self, noise: NoiseModel, *, weights: np.ndarray | None = None) -> "Problem":
        """The regression on rows whitened for a noise model (:mod:`casep.noise.model`).

        Every estimator solves on the whitened rows as on any problem: least squares there is
        the GLS estimate, and the std follow the noise model. Residuals of the raw rows:
        ``problem.raw_residuals(x)``.

        Parameters
        ----------
        noise : NoiseModel
        weights : (N, 3) array_like, optional
            Robust row weights in (0, 1]: the whitened rows are multiplied by ``sqrt(w)``.
        """
        y0 = self._need_rows()
        if self.noise is not None:
            raise ValueError(f"problem `{self.source}` is whitened already")
        if self.t is None or y0.ndim != 2:
            raise ValueError(f"problem `{self.source}`: whitening needs rows (N, 3) with their times")
        w = None if weights is None else np.asarray(weights, dtype=float).reshape(y0.shape)
        t = self.t
        if self._S is not None:
            Sw, yw = whiten(self._S, y0, t, noise, w)
            new = self._derived(red=reduce_qr(Sw, yw), y=yw, t=t, S=Sw, f=self.f)
        else:
            base = self.blocks
            yw = np.empty_like(y0)
            for sl, _, y_b in whiten_blocks(base(), t, noise, w):
                yw[sl] = y_b

            def regenerate(rows: int) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
                yield from whiten_blocks(base(rows), t, noise, w)

            new = self._derived(red=self.red, y=yw, t=t, regenerate=regenerate, f=self.f)
            new.red = reduce_qr_blocks(((S_b, y_b) for _, S_b, y_b in new.blocks()), self.n)
        new.parent = self.parent if self.parent is not None else self
        new.sample_index = self.sample_index
        new.noise = noise
        new._unwhitened = self
        return new

    def locate(self, rows) -> list[dict]:
        """Where rows of this problem come from: ``{"sample", "t", "file", "row", "line"}`` each
        (:func:`casep.io.locate.locate_samples`; without a flight: the row and its time only)."""
        rows = np.asarray(rows, dtype=int).reshape(-1)
        root = self.parent if self.parent is not None else self
        idx = rows if self.sample_index is None else self.sample_index[rows]  # rows of the root problem
        if root._locate_flight is None:
            t = root.t
            return [{"sample": int(k), "t": float(t[k]) if t is not None else float("nan"), "file": None,
                     "row": None, "line": None} for k in idx]
        from casep.io.locate import locate_samples

        flight, obs = root._locate_flight
        out = locate_samples(flight, obs[idx])
        for d, k in zip(out, idx):
            d["sample"] = int(k)  # the problem's row, as the results count them
        return out

    def raw_residuals(self, x: np.ndarray, *, all_samples: bool = True) -> np.ndarray:
        """``dv - S x`` of the raw rows: of every sample of the parent (default), or of this problem's own."""
        return self.raw_problem(all_samples=all_samples).residuals(x)

    def raw_problem(self, *, all_samples: bool = True) -> Problem:
        """The problem of the raw rows (not whitened): the parent's every sample (default), or this one's own."""
        if all_samples and self.parent is not None:
            return self.parent
        return self._unwhitened if self._unwhitened is not None else self

    # ----------------------------------------------------------------- properties
    @property
    def n(self) -> int:
        """Number of coefficients."""
        return self.red.n

    @property
    def m(self) -> int:
        """Number of scalar rows (3 N)."""
        return self.red.m

    @property
    def has_rows(self) -> bool:
        """Whether the rows can be had (False for a reduction-only problem)."""
        return self.y is not None and (self._S is not None or self._regenerate is not None)

    @property
    def rows_in_memory(self) -> bool:
        """Whether the rows are held (S kept): a pass over them costs no regeneration of S_V."""
        return self.y is not None and self._S is not None

    @property
    def n_samples(self) -> int:
        """Number of samples (rows of ``y``'s first axis)."""
        return int(self.y.shape[0]) if self.y is not None and self.y.ndim == 2 else self.m

    def rank(self, rcond: float | None = None) -> RankAnalysis:
        """The rank analysis of the reduction (cached per `rcond`)."""
        # the declared magnitudes: a column at the rounding level relative to them is a zero one (cached with them:
        # a caller may clear them after a first look)
        mags = tuple(self.magnitudes.get(n, self.magnitudes.get(n.split("[")[0])) for n in self.names) \
            if self.magnitudes else None
        key = (rcond, mags)
        if key not in self._ranks:
            self._ranks[key] = analyze_rank(self.red, rcond, magnitudes=mags, rounding_level=rounding_level)
        return self._ranks[key]

    def ls_rss(self, rcond: float | None = None) -> float:
        """Least-squares residual sum of squares ``rho^2 + ||U_{r+}^T q||^2`` (the part of q off range R)."""
        return least_squares_rss(self.red, self.rank(rcond))

    def ls_rms(self) -> float:
        """Least-squares residual RMS over the rows, ``sqrt(rss / m)``."""
        return float(np.sqrt(self.ls_rss() / max(self.m, 1)))

    def is_noise_free(self, rms: float | None = None) -> bool:
        """Whether the rows carry no noise: least-squares residual RMS at the rounding level of ``y``.

        ``sqrt(rss / m) <= max(NOISE_FREE * max |y|, floor)`` (:func:`is_rounding_level`; the floor: the
        interpolation floor of the flight's pair of files, for raw rows); False for a reduction-only
        problem (no ``y`` to compare with). Such data have nothing to fit a noise model or a robust
        filter on, and their std reflect rounding only.

        With `rms` (m/s, RMS over the rows of residuals of another fit of these rows, e.g. a joint fit of
        several flights), whether that fit leaves these rows at their rounding level, by the same rule.
        """
        if self.y is None:
            return False
        scale = float(np.max(np.abs(self.y))) if self.y.size else 0.0
        return is_rounding_level(self.ls_rms() if rms is None else float(rms), scale, self._interpolation_floor())

    def _interpolation_floor(self) -> float:
        root = self.parent if self.parent is not None else self
        return root.interpolation_floor if self.noise is None else 0.0  # whitened rows: another scale

    def rounding_floor(self) -> float:
        """The residual level of these rows without noise, m/s: ``max(NOISE_FREE * max |y|, floor)``
        (:func:`is_rounding_level`: the rounding level of ``y`` or the interpolation floor of the pair of
        files); 0 without ``y``. No noise scale fitted to the rows is smaller."""
        if self.y is None or not self.y.size:
            return 0.0
        return max(float(rounding_level(float(np.max(np.abs(self.y))))), self._interpolation_floor())

    # ----------------------------------------------------------------- rows
    def _need_rows(self) -> np.ndarray:
        """The observations ``y``; ValueError for a reduction-only problem."""
        if not self.has_rows or self.y is None:
            raise ValueError(f"problem `{self.source}` holds only a reduction: this needs its rows "
                             "(build it with Problem.from_flight or Problem.from_arrays)")
        return self.y

    def _regenerated(self, rows: int) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
        """The rows from the regenerating function (S_V not kept)."""
        if self._regenerate is None:
            raise ValueError(f"problem `{self.source}` has neither S_V nor the means to regenerate it")
        return self._regenerate(rows)

    def blocks(self, rows: int = DEFAULT_BLOCK_ROWS) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
        """Yield ``(row slice, S block, y block)`` in time order; S_V regenerated when not kept.

        The S block may be reused between yields: copy it to keep it.
        """
        y = self._need_rows()
        if self._S is not None:
            N = self._S.shape[0]
            for s in range(0, N, rows):
                e = min(s + rows, N)
                yield slice(s, e), self._S[s:e], y[s:e]
        else:
            yield from self._regenerated(rows)

    def sv(self) -> np.ndarray:
        """S whole: kept, or integrated once now and kept (memory N x 3 x n doubles)."""
        y = self._need_rows()
        if self._S is None:
            S = np.empty(y.shape + (self.n,))
            for sl, S_b, _ in self.blocks():
                S[sl] = S_b
            self._S = S
        return self._S

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """``y - S x`` in the shape of ``y``, block by block (NaN in `x` count as 0)."""
        return self.residuals_and_product(x, None)[0]

    def residuals_and_product(self, x: np.ndarray, L: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`residuals` and, in the same pass over the blocks, ``S L`` (shape of ``y`` + ``(r,)``) of a matrix
        `L` (n, r) (None: not computed)."""
        y = self._need_rows()
        x = np.asarray(x, dtype=float)
        x = np.where(np.isnan(x), 0.0, x)  # NaN (no estimate) counts as 0; inf stays inf
        r = np.empty_like(y)
        SL = None if L is None else np.empty(y.shape + (L.shape[1],))
        for sl, S_b, y_b in self.blocks():
            r[sl] = y_b - S_b @ x
            if SL is not None:
                SL[sl] = S_b @ L
        return r, SL

    def __repr__(self) -> str:
        where = "kept" if self._S is not None else ("regenerated" if self._regenerate else "none")
        return (f"Problem({self.model or 'arrays'!s}, {self.n} coefficients, {self.m} rows, "
                f"source {self.source!r}, S_V {where})")


def _telemetry_gaps(meta: dict) -> tuple[tuple[float, float], ...]:
    """The telemetry's gaps a pair of files recorded (:func:`casep.io.pair.pair_flight`'s ``gaps_s``), s."""
    spans = (meta.get("gaps_s") or {}).get("telemetry") or ()
    return tuple((float(a), float(b)) for a, b in spans)
