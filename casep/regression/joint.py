"""Several flights as one problem: the stacked, whitened reduction over the joint parameters.

Notes
-----
Flight k (k = 1..K) reduces its column-scaled regression once (:mod:`casep.regression.linalg`):
with ``Z_k = S_k diag(c_k)^-1`` and ``[Z_k | y_k] = Q_k [[R_k, q_k], [0, rho_k]]``::

    ||y_k - S_k D||^2 = ||q_k - R_k diag(c_k) D||^2 + rho_k^2

The coefficients are shared by all flights except the per-flight ones (``per_flight=True`` in the
model: time offset, initial velocity error, initial misalignment), which each flight has
separately. The joint parameter vector is ``theta = [D_shared, D_pf(1), ..., D_pf(K)]`` and flight
k's coefficients are ``D_k = P_k theta`` (a column selection). Each flight is weighted by its
noise variance, so the joint weighted least squares is::

    min_theta  sum_k ||y_k - S_k P_k theta||^2 / sigma_k^2
             = || A theta - b ||^2 + sum_k rho_k^2 / sigma_k^2,
    A = [R_k diag(c_k) P_k / sigma_k]_k  (K n x p),   b = [q_k / sigma_k]_k

``A`` has K n rows whatever the flights' lengths: the 3 N_k rows are never stacked. It is reduced
again (column-scaled QR) into the ``ReducedSystem`` every solver takes, with ``m = sum_k 3 N_k``
and the whitened residual ``sum_k rho_k^2 / sigma_k^2`` carried along, so the joint noise scale is
1 (the sigma_k are the weights).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from casep.regression.linalg import ReducedSystem, analyze_rank, least_squares_rss, reduce_qr
from casep.regression.problem import DEFAULT_BLOCK_ROWS, Problem

__all__ = ["JointLayout", "JointProblem", "Flights", "joint_reduction", "flight_rss"]


@dataclass(frozen=True)
class JointLayout:
    """Where each flight's coefficients sit in the joint parameter vector.

    Parameters
    ----------
    names : sequence of str
        The model's coefficient names, model order.
    per_flight : (n,) bool array_like
        Coefficients each flight has separately.
    labels : sequence of str
        One label per flight (file name); per-flight names become ``name[label]``.
    """

    names: tuple[str, ...]
    per_flight: np.ndarray
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        pf = np.asarray(self.per_flight, dtype=bool)
        if pf.shape != (len(self.names),):
            raise ValueError(f"`per_flight` has {pf.size} entries but the model has {len(self.names)} coefficients")
        if not self.labels:
            raise ValueError("no flight")
        if len(set(self.labels)) != len(self.labels):
            raise ValueError(f"flight labels repeat: {list(self.labels)}")
        object.__setattr__(self, "per_flight", pf)

    @property
    def n_flights(self) -> int:
        return len(self.labels)

    @property
    def shared(self) -> np.ndarray:
        """Model indices of the shared coefficients."""
        return np.flatnonzero(~self.per_flight)

    @property
    def n_params(self) -> int:
        """Length of theta: shared + K x per-flight."""
        return int(self.shared.size + self.n_flights * self.per_flight.sum())

    def columns(self, k: int) -> np.ndarray:
        """``P_k`` as an index array: model coefficient j of flight k -> its column of theta."""
        pf = np.flatnonzero(self.per_flight)
        cols = np.empty(len(self.names), dtype=int)
        cols[self.shared] = np.arange(self.shared.size)
        cols[pf] = self.shared.size + k * pf.size + np.arange(pf.size)
        return cols

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of theta: shared names, then ``name[label]`` per flight."""
        pf = [self.names[j] for j in np.flatnonzero(self.per_flight)]
        return tuple(self.names[j] for j in self.shared) + tuple(
            f"{name}[{label}]" for label in self.labels for name in pf)

    def expand(self, values: Sequence, k: int | None = None) -> list:
        """Model-order per-coefficient values (units, scales) repeated into theta order."""
        out: list = [None] * self.n_params
        for kk in range(self.n_flights) if k is None else (k,):
            for j, col in enumerate(self.columns(kk)):
                out[col] = values[j]
        return out


def flight_rss(red: ReducedSystem, rcond: float | None = None) -> tuple[float, int]:
    """A flight's own least-squares residual sum of squares and rank.

    ``RSS = rho^2 + ||U_{r+}^T q||^2`` (the part of q outside the range of R).
    """
    ra = analyze_rank(red, rcond)
    return least_squares_rss(red, ra), ra.rank


def joint_reduction(reds: Sequence[ReducedSystem], sigmas: Sequence[float], layout: JointLayout) -> ReducedSystem:
    """The weighted stacked least squares of several flights as one reduced system over theta.

    Parameters
    ----------
    reds : sequence of ReducedSystem
        Each flight's reduction (same model, model order).
    sigmas : sequence of float
        Each flight's noise std, m/s (its weight is 1 / sigma^2).
    layout : JointLayout

    Returns
    -------
    ReducedSystem
        Of ``A theta = b`` (see the module notes), with ``m`` the total number of rows of the
        flights and ``rho2`` the whitened residual outside every flight's range, so that
        ``||b - A theta||^2 + rho2 = sum_k ||y_k - S_k P_k theta||^2 / sigma_k^2``.
    """
    if len(reds) != layout.n_flights or len(sigmas) != layout.n_flights:
        raise ValueError(f"{len(reds)} reductions and {len(sigmas)} sigmas for {layout.n_flights} flights")
    n = len(layout.names)
    p = layout.n_params
    A = np.zeros((layout.n_flights * n, p))
    b = np.zeros(layout.n_flights * n)
    rho2 = 0.0
    for k, (red, sig) in enumerate(zip(reds, sigmas)):
        if red.n != n:
            raise ValueError(f"flight {layout.labels[k]}: {red.n} coefficients, the model has {n}")
        if not (np.isfinite(sig) and sig > 0):
            raise ValueError(f"flight {layout.labels[k]}: sigma must be finite and > 0, got {sig}")
        rows = slice(k * n, (k + 1) * n)
        A[rows, layout.columns(k)] = red.R * red.scale / sig  # R_k diag(c_k) P_k / sigma_k
        b[rows] = red.qty / sig  # q_k / sigma_k
        rho2 += red.rho2 / sig**2  # rho_k^2 / sigma_k^2
    joint = reduce_qr(A, b)
    return ReducedSystem(R=joint.R, qty=joint.qty, rho2=joint.rho2 + rho2, scale=joint.scale,
                         m=int(sum(r.m for r in reds)))


class JointProblem(Problem):
    """Several flights' problems as one whitened problem over the joint parameters.

    Parameters
    ----------
    problems : sequence of Problem
        One per flight, same model.
    sigmas : sequence of float
        Each flight's noise std, m/s: its rows are divided by it.
    layout : JointLayout
    raw : sequence of Problem, optional
        The flights as read, when `problems` are transformed (GLS: AR(1)-whitened); the summary's
        residuals are theirs.
    interpolated : sequence of bool, optional
        Flights whose tracking was interpolated onto telemetry times (correlated noise: the
        summary says its tests are optimistic); default none.
    """

    def __init__(self, problems: Sequence[Problem], sigmas: Sequence[float], layout: JointLayout,
                 raw: Sequence[Problem] | None = None, interpolated: Sequence[bool] | None = None) -> None:
        red = joint_reduction([p.red for p in problems], sigmas, layout)
        units = layout.expand(problems[0].units)
        si = layout.expand(list(problems[0].si_factors))
        ys = [p._need_rows().reshape(-1, 3) for p in problems]
        y = np.concatenate([yk / s for yk, s in zip(ys, sigmas)])  # whitened, (N, 3)
        super().__init__(names=layout.joint_names, units=units, si_factors=si, red=red, y=y,
                         model=problems[0].model, source=" + ".join(p.source for p in problems), row_unit="")
        self.problems = tuple(problems)
        # the flights' declared magnitudes (a per-flight name[label] finds its model name's): the rank analysis of
        # the joint reduction counts a column at the rounding level relative to them as zero, as one flight's does
        self.magnitudes = dict(problems[0].magnitudes)
        self.raw = tuple(raw) if raw is not None else self.problems
        self.interpolated = tuple(bool(v) for v in interpolated) if interpolated else (False,) * len(problems)
        self.sigmas = tuple(float(s) for s in sigmas)
        self.layout = layout
        sizes = [yk.shape[0] for yk in ys]
        # each flight is a segment: its first sample in the stacked rows (RELS restarts its noise memory there)
        self.segment_starts = tuple(int(v) for v in np.cumsum([0] + sizes[:-1]))

    @property
    def has_rows(self) -> bool:
        return all(p.has_rows for p in self.problems)

    def blocks(self, rows: int = DEFAULT_BLOCK_ROWS) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
        """Yield ``(row slice, S block, y block)``: flight after flight, each block
        ``S_k P_k / sigma_k`` (its coefficients placed in the joint columns, zero elsewhere) and
        ``y_k / sigma_k``. The S block is reused between yields."""
        n = self.n
        for k, (p, s, start) in enumerate(zip(self.problems, self.sigmas, self.segment_starts)):
            cols = self.layout.columns(k)
            for sl, S_b, y_b in p.blocks(rows):
                out = np.zeros(S_b.shape[:-1] + (n,))
                out[..., cols] = S_b / s  # S_k P_k / sigma_k
                yield slice(start + sl.start, start + sl.stop), out, y_b / s

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Each flight's ``(y_k - S_k P_k x) / sigma_k``, stacked: the joint fit's whitened residuals."""
        x = np.asarray(x, dtype=float)
        return np.concatenate([p.residuals(x[self.layout.columns(k)]).reshape(-1) / s
                               for k, (p, s) in enumerate(zip(self.problems, self.sigmas))])

    def flight_estimates(self, x: np.ndarray) -> list[np.ndarray]:
        """Flight k's coefficients in model order (shared + its own per-flight ones)."""
        x = np.asarray(x, dtype=float)
        return [x[self.layout.columns(k)] for k in range(self.layout.n_flights)]


@dataclass(frozen=True)
class Flights:
    """Several flights of one model as one problem to fit (:func:`casep.estimators.solve.fit`): the flights as read,
    before any noise model or weighting (the fit request decides those, on each flight as on one alone).

    Parameters
    ----------
    problems : sequence of Problem
        One per flight, same model (its per-flight coefficients each flight's own).
    layout : JointLayout
        Where each flight's coefficients sit in the joint parameter vector; its labels name the flights.
    interpolated : sequence of bool, optional
        Flights whose tracking was interpolated onto telemetry times (default none).
    """

    problems: tuple[Problem, ...]
    layout: JointLayout
    interpolated: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "problems", tuple(self.problems))
        if len(self.problems) != self.layout.n_flights:
            raise ValueError(f"{len(self.problems)} flights for {self.layout.n_flights} labels")
        flags = tuple(bool(v) for v in self.interpolated) or (False,) * len(self.problems)
        if len(flags) != len(self.problems):
            raise ValueError(f"`interpolated` has {len(flags)} entries for {len(self.problems)} flights")
        object.__setattr__(self, "interpolated", flags)
        for p in self.problems:
            if not p.has_rows:
                raise ValueError(f"flight `{p.source}` is a reduction-only Problem: a fit needs the flight's rows")
