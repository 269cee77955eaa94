"""Scaled QR reduction of the stacked regression and its rank analysis.

Every solver works on the column-scaled system ``Z = S / c`` (``c_j`` = Euclidean norm of
column j in natural units; a zero column keeps ``c_j = 0`` and is reported as such). The
tall problem (3N x n) is reduced once, by Householder QR of ``[Z | y]`` processed in row
blocks (TSQR: ``R <- qr([R; block])``, orthogonal at every step, so as accurate as one QR):

    [Z | y] = Q [[R, q], [0, rho]]      =>   ||y - Z x||^2 = ||q - R x||^2 + rho^2

so every later solve (OLS, ridge, bounded QP, PCR, MAP) works on the n x n system
``(R, q)`` and never touches the 3N rows again. The rank analysis is an SVD of the small
``R = U diag(s) V^T``: columns with ``s_i <= rcond * s_0`` span the exact null space; a
coefficient is *estimable* iff its unit vector is orthogonal to that null space (the
classical estimable-function criterion), i.e. iff its row of ``V_null`` is zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Iterator, Sequence, cast

import numpy as np

from casep._special import chi2_sf

__all__ = ["ReducedSystem", "reduce_qr", "reduce_qr_blocks", "RankAnalysis", "analyze_rank", "rounding_columns",
           "least_squares_rss", "covariance_std", "undetermined_nan",
           "DEFAULT_BLOCK_ROWS", "qr_forward_error", "refine_least_squares", "REFINE_ABOVE"]

#: Rows per TSQR block: bounds the temporary copy to ~block x (n + 1) doubles.
DEFAULT_BLOCK_ROWS = 65536
_NULL_ROW_TOL = 1e-8  # a coefficient is in the null space when its V_null row norm exceeds this


@dataclass(frozen=True)
class ReducedSystem:
    """The n x n equivalent of a tall column-scaled least-squares problem.

    Attributes
    ----------
    R : (n, n) ndarray
        Upper-triangular factor of ``Z = S / scale`` (zero columns left at zero).
    qty : (n,) ndarray
        ``Q^T y`` restricted to the span of Q's first n columns.
    rho2 : float
        ``||y||^2 - ||Q^T y||^2``: residual sum of squares outside that span.
    scale : (n,) ndarray
        Column norms of S in natural units (0 for a zero column).
    m : int
        Number of rows of S (3N).
    """

    R: np.ndarray
    qty: np.ndarray
    rho2: float
    scale: np.ndarray
    m: int

    @property
    def n(self) -> int:
        """Number of coefficients."""
        return int(self.scale.size)


def covariance_std(C: np.ndarray) -> np.ndarray:
    """The std of the entries of a covariance `C` (n, n): the square root of its diagonal, a rounding's negative
    variance read as 0 and NaN kept (an undetermined coefficient's); the one rule of casep's std."""
    return np.sqrt(np.clip(np.diag(C), 0.0, None))


def undetermined_nan(cov: np.ndarray, und: np.ndarray) -> np.ndarray:
    """`cov` (n, n) with the rows and columns of the coefficients `und` (n, bool) NaN, in place (returned): what a
    result states of the coefficients it does not determine (their std then NaN: :func:`covariance_std`)."""
    cov[und, :] = np.nan
    cov[:, und] = np.nan
    return cov


def _column(j: int, names: Sequence[str] | None) -> str:
    """``column 2 (Kg1xy)``: the S column and, when known, its coefficient."""
    return f"column {j}" + (f" ({names[j]})" if names is not None and j < len(names) else "")


def _first_bad(S_blk: np.ndarray, names: Sequence[str] | None, row0: int) -> str:
    """Where the first non-finite entry of an S block is: ``row r, column j (name)``."""
    r, j = np.argwhere(~np.isfinite(S_blk.reshape(S_blk.shape[0], -1)))[0]
    return f"`S` is not finite at row {row0 + int(r)}, {_column(int(j), names)}"


def reduce_qr(S: np.ndarray, y: np.ndarray, *, block_rows: int = DEFAULT_BLOCK_ROWS,
              names: Sequence[str] | None = None) -> ReducedSystem:
    """Column-scale ``S`` and reduce ``min ||y - S x||`` to an n x n triangular system.

    Parameters
    ----------
    S : (m, n) or (N, 3, n) array_like
        Regression matrix in natural units; (N, 3, n) is flattened to (3N, n).
    y : (m,) or (N, 3) array_like
        Observations (dv), flattened the same way.
    block_rows : int, optional
        Rows per TSQR block.

    Returns
    -------
    ReducedSystem
    """
    S = np.asarray(S, dtype=float)
    y = np.asarray(y, dtype=float)
    if S.ndim == 3:
        S = S.reshape(-1, S.shape[-1])
    if S.ndim != 2:
        raise ValueError(f"`S` must be 2-D (m, n) or 3-D (N, 3, n), got {S.ndim}-D")
    y = y.reshape(-1)
    m, n = S.shape
    if y.size != m:
        raise ValueError(f"`y` has {y.size} values but `S` has {m} rows")
    if n < 1:
        raise ValueError("`S` has no columns")
    if not isinstance(block_rows, (int, np.integer)) or block_rows < 1:
        raise ValueError(f"`block_rows` must be a positive int, got {block_rows!r}")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"`y` is not finite at row {int(np.flatnonzero(~np.isfinite(y))[0])}")
    # Column norms by blocks (avoids a second full-size temporary).
    sq = np.zeros(n)
    for s in range(0, m, block_rows):
        blk = S[s : s + block_rows]
        sq += np.einsum("ij,ij->j", blk, blk)
    if not np.all(np.isfinite(sq)):
        for s in range(0, m, block_rows):
            if not np.all(np.isfinite(S[s : s + block_rows])):
                raise ValueError(_first_bad(S[s : s + block_rows], names, s))
        j = int(np.flatnonzero(~np.isfinite(sq))[0])  # finite entries whose squares overflow
        raise ValueError(f"`S` {_column(j, names)} is too large: its sum of squares overflows")
    scale = np.sqrt(sq)
    inv = np.where(scale > 0, 1.0 / np.where(scale > 0, scale, 1.0), 0.0)
    Racc = np.zeros((0, n + 1))
    # Fortran order, LAPACK's: numpy.linalg.qr copies its input into that layout, column by column, which from a
    # C-ordered array is a strided read of every row per column (the same R bit for bit; 16 % less CPU at 11703 x 37,
    # 37 % at 200000 x 37)
    work = np.empty((min(block_rows, m) + n + 1, n + 1), order="F")
    for s in range(0, m, block_rows):
        blk = S[s : s + block_rows]
        k0 = Racc.shape[0]
        k = k0 + blk.shape[0]
        M = work[:k]
        M[:k0] = Racc
        np.multiply(blk, inv, out=M[k0:, :n])  # Z = S / c
        M[k0:, n] = y[s : s + blk.shape[0]]
        Racc = cast(np.ndarray, np.linalg.qr(M, mode="r"))  # Householder; R of [R_prev; block] (an array)
    Rfull = np.zeros((n + 1, n + 1))
    Rfull[: Racc.shape[0]] = Racc[: n + 1]
    return ReducedSystem(R=np.triu(Rfull[:n, :n]), qty=Rfull[:n, n].copy(), rho2=float(Rfull[n, n] ** 2),
                         scale=scale, m=m)


def reduce_qr_blocks(blocks: Iterable[tuple[np.ndarray, np.ndarray]], n: int,
                     names: Sequence[str] | None = None) -> ReducedSystem:
    """:func:`reduce_qr` of a regression given block by block (rows never held whole).

    Parameters
    ----------
    blocks : iterable of (S_block, y_block)
        Row blocks in natural units, ``(k, n)`` or ``(k, 3, n)`` with ``(k,)`` or ``(k, 3)``.
    n : int
        Number of columns.

    Notes
    -----
    One pass: TSQR of the unscaled ``[S | y]`` (``R <- qr([R; block])``), then the column
    scaling afterwards. Householder QR commutes with column scaling (``S = Q R`` gives
    ``S diag(c)^-1 = Q (R diag(c)^-1)``) and is column-wise backward stable, so the scaled
    factor is as accurate as scaling first; the column norms of S are those of R.
    """
    Racc = np.zeros((0, n + 1))
    m = 0
    for S_blk, y_blk in blocks:
        S_blk = np.asarray(S_blk, dtype=float).reshape(-1, n)
        y_blk = np.asarray(y_blk, dtype=float).reshape(-1)
        if y_blk.size != S_blk.shape[0]:
            raise ValueError(f"a block has {y_blk.size} values of `y` for {S_blk.shape[0]} rows of `S`")
        if not np.all(np.isfinite(y_blk)):
            raise ValueError(f"`y` is not finite at row {m + int(np.flatnonzero(~np.isfinite(y_blk))[0])}")
        if not np.all(np.isfinite(S_blk)):
            raise ValueError(_first_bad(S_blk, names, m))
        M = np.empty((Racc.shape[0] + S_blk.shape[0], n + 1), order="F")  # LAPACK's layout, as reduce_qr's
        M[: Racc.shape[0]] = Racc
        M[Racc.shape[0]:, :n] = S_blk
        M[Racc.shape[0]:, n] = y_blk
        Racc = cast(np.ndarray, np.linalg.qr(M, mode="r"))  # Householder; R of [R_prev; block] (an array)
        m += S_blk.shape[0]
    if m == 0:
        raise ValueError("`S` has no rows")
    Rfull = np.zeros((n + 1, n + 1))
    Rfull[: Racc.shape[0]] = Racc[: n + 1]
    R = np.triu(Rfull[:n, :n])
    scale = np.linalg.norm(R, axis=0)  # ||S e_j|| = ||R e_j||
    inv = np.where(scale > 0, 1.0 / np.where(scale > 0, scale, 1.0), 0.0)
    R = R * inv  # R diag(c)^-1: the factor of Z = S / c
    R[:, scale == 0] = 0.0
    return ReducedSystem(R=R, qty=Rfull[:n, n].copy(), rho2=float(Rfull[n, n] ** 2), scale=scale, m=m)


#: The least coupling of two coefficients in the null space that puts them in one exactly dependent group
#: (:meth:`RankAnalysis.exact_groups`).
GROUP_SHARE = 0.1


@dataclass(frozen=True)
class RankAnalysis:
    """SVD-based rank analysis of a :class:`ReducedSystem`.

    Attributes
    ----------
    U, s, Vt : ndarray
        SVD of ``R`` (scaled coordinates).
    rank : int
        Number of singular values above ``rcond * s[0]``, less the directions at the rounding level relative to the
        declared magnitudes (:func:`rounding_directions`; their rows of `Vt` keep only their members).
    rcond : float
        Relative threshold used.
    zero : (n,) bool ndarray
        Columns that are identically zero in S.
    dependent : (n,) bool ndarray
        Non-zero columns that take part in an exact linear dependency.
    partners : dict[int, list[int]]
        For each dependent column, the other columns of its dependency, strongest first.
    rounding : (n,) bool ndarray
        Non-zero columns at the rounding level (:func:`rounding_columns`): counted in `zero`, left out of the SVD.
    """

    U: np.ndarray
    s: np.ndarray
    Vt: np.ndarray
    rank: int
    rcond: float
    zero: np.ndarray
    dependent: np.ndarray
    partners: dict
    rounding: np.ndarray | None = None

    def exact_groups(self) -> list[list[int]]:
        """The exactly dependent coefficients in groups, each sorted, in the order of their first member: the
        coefficients tied by a coupling ``|P_jk| / sqrt(P_jj P_kk)`` of at least :data:`GROUP_SHARE` of the
        null-space projector ``P = V_null V_null^T`` (scaled coordinates), and those tied to them. The closure of
        `partners` reaches further: a rotation of the IMU about one body axis takes an initial attitude error mostly
        about one navigation axis and a little (~1e-3) about the others, which ties each such group to the next."""
        Vnull = self.Vt[self.rank:].T
        member = self.dependent & ~self.zero
        P = Vnull @ Vnull.T
        d = np.sqrt(np.clip(np.diag(P), 0.0, None))
        tied = (np.abs(P) >= GROUP_SHARE * np.outer(d, d)) & member[:, None] & member[None, :]
        groups: list[list[int]] = []
        seen: set[int] = set()
        for j in map(int, np.flatnonzero(member)):
            if j in seen:
                continue
            group, todo = {j}, [j]
            while todo:
                for k in map(int, np.flatnonzero(tied[todo.pop()])):
                    if k not in group:
                        group.add(k)
                        todo.append(k)
            seen |= group
            if len(group) > 1:
                groups.append(sorted(group))
        return groups

    @property
    def estimable(self) -> np.ndarray:
        """Coefficients that the data determine individually."""
        return ~(self.zero | self.dependent)

    def pinv_factors(self) -> tuple[np.ndarray, np.ndarray]:
        """``(V_r, 1 / s_r)``: the rank-r pseudo-inverse ``R^+ = V_r diag(1/s_r) U_r^T``."""
        r = self.rank
        return self.Vt[:r].T, 1.0 / self.s[:r]


def rounding_columns(red: ReducedSystem, magnitudes: Sequence[float | None],
                     rounding_level: Callable[[float], float]) -> np.ndarray:
    """The non-zero columns that are rounding noise relative to their declared magnitudes: whose effect at the
    magnitude, ``||S_j|| s_j`` (m/s over the rows), is at or below the rounding level
    (:func:`casep.regression.problem.rounding_level`) of the largest such effect. A column the flight excites only
    through numbers at the rounding level (a misalignment times a lateral specific force of 1e-15 m/s^2) carries
    no information on its coefficient: its direction is the rounding's, independent of every other column, so it
    would get a plain estimate of any size. A column without a declared magnitude is never one. `rounding_level`:
    :func:`casep.regression.problem.rounding_level` (passed in: the problem module builds on this one)."""
    s = np.array([np.nan if m is None else m for m in magnitudes], dtype=float)
    effect = red.scale * np.abs(s)
    known = np.isfinite(effect) & (red.scale > 0)
    if not known.any():
        return np.zeros(red.n, dtype=bool)
    return known & (effect <= rounding_level(float(np.max(effect[known]))))


#: Relative singular value (columns equilibrated) at or below which a direction at the rounding level of the
#: declared magnitudes is an exact dependency (:func:`rounding_directions`): half the digits of double precision,
#: what a dependency exact in the model keeps of its exactness through the numerical integration of S_V (the
#: strapdown IMU rotated against the body: 7e-11), four orders below the worst real collinearity of a flight
#: (equilibrated condition numbers up to ~1e6: those directions are small at the declared magnitudes when a
#: member's column is small, and stay estimable on noise-free data).
DEPENDENT_SINGULAR = float(np.sqrt(np.finfo(float).eps))

#: A member of a direction at the rounding level (:func:`rounding_directions`) moves the data at its declared
#: magnitude by more than this fraction of the largest member; the others are that level's leak (~1e-7), no part
#: of the dependency.
ROUNDING_MEMBER = 1e-3


#: A direction at the rounding level is needed by the data (:func:`direction_needed`) when dropping it raises the
#: residual sum of squares by more than the noise gives with this chance: the likelihood-ratio test of the
#: coefficient along it being zero, one degree of freedom.
NEEDED_ALPHA = 1e-3


def direction_needed(growth: float, sigma2: float, level: float) -> bool:
    """Whether the data need a singular direction: the residual sum of squares grows by `growth` without it
    (``(u_k^T Q^T y)^2``, the fit's part along it) beyond both what its own rounding explains (`level` squared: the
    most the direction moves the data at the declared magnitudes, :func:`rounding_directions`) and the noise:
    ``chi2_1 sf(growth / sigma2) < NEEDED_ALPHA`` (`sigma2` the noise variance per row). A direction the flight
    cannot separate from the others gets only noise along it; one that carries an error beyond the declared
    magnitudes (the reason it was small at them) gets the error, far above the noise."""
    if growth <= level**2:
        return False
    if sigma2 <= 0.0:
        return True
    return chi2_sf(1, growth / sigma2) < NEEDED_ALPHA


def member_null_direction(R: np.ndarray, v: np.ndarray, member: np.ndarray, tol: float,
                          found: Sequence[np.ndarray]) -> np.ndarray | None:
    """The direction on the `member` columns alone closest to the singular direction `v` that the data cannot
    see: `v` restricted to the members and projected on the right singular vectors of ``R[:, member]`` whose
    singular values are at most `tol`, orthogonal to the directions already `found`; None when that leaves nothing
    (the members alone are not dependent: the direction's bulk lay on the other columns).

    Unit, on the members only, ``||R n|| <= tol``: exactly the direction the warning names, so that the null space
    downstream (:func:`null_space`, :class:`PartnerBound`) is one of the data."""
    idx = np.flatnonzero(member)
    _, sm, Wt = np.linalg.svd(R[:, idx])
    basis = Wt[sm <= tol]  # (j, |members|): R is square, so there are as many singular values as members
    if basis.shape[0] == 0:
        return None
    for f in found:  # orthogonal to the directions already found (n is zero off the members: f . n = f_m . n_m)
        fm = f[idx]
        norm_f = float(np.linalg.norm(fm))
        if norm_f > 0.0:
            basis = basis - np.outer(basis @ fm, fm) / norm_f**2
    _, sv, bt = np.linalg.svd(basis, full_matrices=False)
    basis = bt[sv > 0.5]  # an orthonormal basis of what is left
    if basis.shape[0] == 0:
        return None
    x = basis.T @ (basis @ v[idx])
    norm = float(np.linalg.norm(x))
    if norm == 0.0:
        return None
    n = np.zeros_like(v)
    n[idx] = x / norm
    return n


def constraint_growth(s: np.ndarray, Vt: np.ndarray, b: np.ndarray, n: np.ndarray) -> float:
    """How much the residual sum of squares grows when the fit is kept from moving along `n` (scaled
    coordinates): ``(n^T z)^2 / (n^T (R^T R)^-1 n)`` with ``z`` the least-squares solution, the likelihood-ratio
    statistic (times the noise variance) of ``n^T z = 0``. From the SVD ``R = U diag(s) V^T`` (over the numerical
    rank: `s`, the first rows of `Vt`) and ``b = U^T Q^T y``: with ``a_i = (v_i . n) / s_i``, ``(a . b)^2 / (a . a)``;
    ``b_k^2`` for ``n = v_k``."""
    a = (Vt[: s.size] @ n) / s
    aa = float(a @ a)
    return float(a @ b[: s.size]) ** 2 / aa if aa > 0 else 0.0


def rounding_directions(red: ReducedSystem, U: np.ndarray, s: np.ndarray, Vt: np.ndarray,
                        magnitudes: Sequence[float | None], rounding_level: Callable[[float], float],
                        rounding: np.ndarray, sigma2: float) -> np.ndarray:
    """The smallest singular directions (`s`, `Vt` of the scaled ``R``, largest first) that are rounding noise
    relative to the declared magnitudes: :func:`rounding_columns`' rule for a combination of columns.

    A direction ``v`` is the change ``x = v / c`` of the coefficients (natural units); scaled so that its largest
    member is at its declared magnitude (``max_j |x_j| / s_j = 1``) it moves the data by ``s_k / max_j |x_j| / s_j``
    (m/s over the rows). At or below the rounding level of the largest column effect ``||S_j|| s_j`` it carries no
    information: an exact dependency of the model (the whole IMU rotated against the body, taken up by an initial
    attitude error) that the discretisation of S_V leaves at 1e-11 of the largest singular value instead of
    1e-16. Only at or below :data:`DEPENDENT_SINGULAR` of the largest singular value. Counted from the smallest
    up, stopping at the first that is not; a direction with a member (a component above :data:`NULL_ROUNDING`)
    without a declared magnitude is never one.

    And only when the direction on its members alone is still one the data cannot see
    (:func:`member_null_direction`: the direction the warning names is a dependency, not the leftover of one whose
    bulk lies on well-excited columns) and the data do not need it (:func:`direction_needed` of
    :func:`constraint_growth`): small at the declared magnitudes is not small on a record whose errors are far
    beyond them (a MEMS unit under a tactical model).

    Parameters
    ----------
    red : ReducedSystem
    U, s, Vt : ndarray
        The SVD of the scaled ``R`` over the numerical rank (``U`` its first columns, ``s`` largest first).
    magnitudes, rounding_level, rounding
        As :func:`analyze_rank` and :func:`rounding_columns`.
    sigma2 : float
        The noise variance per row (the residual mean square of the fit at the numerical rank).

    Returns
    -------
    (k, n) ndarray
        The k directions found (in place of the last k rows of `Vt`), each on its members only
        (:data:`ROUNDING_MEMBER`, :func:`member_null_direction`), orthonormal.
    """
    mags = np.array([np.nan if m is None else m for m in magnitudes], dtype=float)
    effect = red.scale * np.abs(mags)
    known = np.isfinite(effect) & (effect > 0) & ~rounding
    if not known.any():
        return np.zeros((0, red.n))
    level = rounding_level(float(np.max(effect[known])))
    b = U.T @ red.qty  # the fit's part along each direction: dropping direction k raises the RSS by b_k^2
    found: list[np.ndarray] = []
    for k in range(s.size - 1, -1, -1):
        v = np.abs(Vt[k])
        member = v > NULL_ROUNDING
        if not member.any() or not np.all(known[member]):
            break
        w = np.where(member, v / np.where(known, effect, 1.0), 0.0)  # in units of the declared magnitudes
        if s[k] > DEPENDENT_SINGULAR * s[0] or s[k] / float(w.max()) > level:
            break
        n = member_null_direction(red.R, Vt[k], w > ROUNDING_MEMBER * w.max(), DEPENDENT_SINGULAR * s[0], found)
        if n is None or direction_needed(constraint_growth(s, Vt, b, n), sigma2, level):
            break
        found.append(n)
    if not found:
        return np.zeros((0, red.n))
    return np.linalg.qr(np.array(found[::-1]).T)[0].T


def analyze_rank(red: ReducedSystem, rcond: float | None = None,
                 magnitudes: Sequence[float | None] | None = None,
                 rounding_level: Callable[[float], float] | None = None) -> RankAnalysis:
    """Find the numerical rank, the zero columns and the exactly dependent ones.

    Parameters
    ----------
    red : ReducedSystem
    rcond : float, optional
        Singular values ``<= rcond * s_max`` count as zero. Default ``max(m, n) * eps``,
        as LAPACK's rank rules: exact dependencies computed in floating point land near
        1e-16 * s_max, while the worst real collinearity of a boost flight (equilibrated
        condition number ~1e6) is ten orders of magnitude above it.
    magnitudes : sequence of float or None, optional
        The declared magnitude of each coefficient (natural units): the columns at the rounding level relative to
        them (:func:`rounding_columns`, with `rounding_level`, required with them) count as zero columns.
    """
    n, m = red.n, red.m
    if rcond is None:
        rcond = max(m, n) * np.finfo(float).eps
    elif not np.isfinite(rcond) or rcond < 0 or rcond >= 1:
        raise ValueError(f"`rcond` must be in [0, 1), got {rcond}")
    if magnitudes is not None and rounding_level is None:
        raise ValueError("`rounding_level` is required with `magnitudes`")
    rounding = np.zeros(n, dtype=bool) if magnitudes is None or rounding_level is None \
        else rounding_columns(red, magnitudes, rounding_level)
    R = red.R
    if rounding.any():
        R = R.copy()
        R[:, rounding] = 0.0  # a zero column from here on: no estimate, no part of a dependency
    U, s, Vt = np.linalg.svd(R)
    smax = s[0] if s.size else 0.0
    rank = int(np.sum(s > rcond * smax)) if smax > 0 else 0
    if magnitudes is not None and rounding_level is not None:
        sigma2 = (red.rho2 + float(np.sum((U[:, rank:].T @ red.qty) ** 2))) / max(m - rank, 1)
        at_rounding = rounding_directions(red, U[:, :rank], s[:rank], Vt[:rank], magnitudes, rounding_level,
                                          rounding, sigma2)
        if at_rounding.shape[0]:
            Vt = Vt.copy()
            Vt[rank - at_rounding.shape[0]:rank] = at_rounding
            rank -= at_rounding.shape[0]
    zero = (red.scale == 0.0) | rounding
    Vnull = Vt[rank:].T  # (n, n - rank): exact null space of Z
    row_norm = np.linalg.norm(Vnull, axis=1) if Vnull.size else np.zeros(n)
    dependent = (row_norm > _NULL_ROW_TOL) & ~zero
    partners: dict[int, list[int]] = {}
    for j in np.flatnonzero(dependent):
        w = Vnull @ Vnull[j]  # null-space component tied to coefficient j
        w[j] = 0.0
        w[zero] = 0.0
        big = np.flatnonzero(np.abs(w) > 1e-6 * max(np.abs(w).max(), 1e-300))
        partners[int(j)] = [int(k) for k in big[np.argsort(-np.abs(w[big]))]]
    return RankAnalysis(U=U, s=s, Vt=Vt, rank=rank, rcond=float(rcond), zero=zero,
                        dependent=dependent, partners=partners, rounding=rounding)


#: Components of a unit null vector of the scaled columns below this are the SVD's rounding (a zero column's
#: null vector leaks ~1e-12 into the others), not part of a dependency.
NULL_ROUNDING = 1e-9

#: An exactly dependent coefficient is determined in practice when its partners, each within its declared
#: magnitude, move the combination that stands for it by at most this fraction of its std (the bias then adds at
#: most 0.5 % to its mean square error).
PARTNER_SHARE = 0.1

#: The start of the note of an exactly dependent coefficient determined in practice (its partners follow).
PARTNERS_NOTE = "exactly dependent on"


def null_space(red: ReducedSystem, ra: RankAnalysis) -> np.ndarray:
    """A basis of the null space of S in natural units, (n, k): ``S N = 0``.

    ``S = Z diag(c)``: a null vector ``v`` of the scaled ``Z`` is ``v / c`` in natural units; on a zero column
    (``c = 0``) any value is a null direction, kept as ``v``.
    """
    v = ra.Vt[ra.rank:].T  # (n, k): Z v = 0, unit columns
    v = np.where(np.abs(v) > NULL_ROUNDING, v, 0.0)  # rounding of the SVD: not a part of the dependency
    scaled = (red.scale > 0) & ~ra.zero  # a column at the rounding level is a zero one (analyze_rank)
    return np.where(scaled[:, None], v / np.where(scaled, red.scale, 1.0)[:, None], v)


@dataclass(frozen=True)
class PartnerBound:
    """What the declared magnitudes ``s`` say of exactly dependent coefficients.

    With ``D = diag(s)`` and ``Q`` an orthonormal basis of the null space in units of the magnitudes
    (``D^-1 N``), the least-squares solution of least size in those units is ``Pi x`` for any least-squares
    solution ``x``: ``Pi = I - D Q Q^T D^-1`` (``S Pi = S``, ``Pi N = 0``: each row of ``Pi`` is a determined
    combination, so ``Pi C Pi^T`` is its exact covariance for the solver's covariance ``C``). Its entry ``j`` is
    the combination ``(Pi^T e_j) . D``, which differs from ``D_j`` by ``-s_j (Q Q^T D^-1 D)_j``: with every
    coefficient within its declared magnitude, by at most ``bound_j = s_j sum_i |(Q Q^T)_ji|`` (0 for a
    coefficient outside every dependency: its row of ``Q`` is zero).

    Attributes
    ----------
    Pi : (n, n) ndarray
    bound : (n,) ndarray
        Natural units.
    partners : dict[int, list[int]]
        As :attr:`RankAnalysis.partners`.
    s, P : ndarray
        The declared magnitudes (1 outside every dependency) and ``Q Q^T``.
    """

    Pi: np.ndarray
    bound: np.ndarray
    partners: dict
    s: np.ndarray
    P: np.ndarray

    @classmethod
    def of(cls, red: ReducedSystem, ra: RankAnalysis, magnitudes: Sequence[float | None]) -> PartnerBound | None:
        """The bound of a rank-deficient reduction; None when it has no exact dependency or a member of one has no
        declared magnitude (a zero column needs none: its null vector is its own)."""
        N = null_space(red, ra)
        if N.shape[1] == 0 or not (ra.dependent.any()):
            return None
        s = np.array([np.nan if m is None else m for m in magnitudes], dtype=float)
        member = np.any(N != 0.0, axis=1) & ~ra.zero
        if not np.all(np.isfinite(s[member]) & (s[member] > 0)):
            return None
        s = np.where(member, s, 1.0)
        Q = np.linalg.qr(N / s[:, None])[0]  # the null space in units of the declared magnitudes, orthonormal
        P = Q @ Q.T
        Pi = np.eye(red.n) - (s[:, None] * P) / s[None, :]  # Pi = I - D Q Q^T D^-1
        return cls(Pi=Pi, bound=s * np.sum(np.abs(P), axis=1), partners=ra.partners, s=s, P=P)

    def covariance(self, C: np.ndarray) -> np.ndarray:
        """``Pi C Pi^T`` (symmetrised)."""
        Cw = self.Pi @ C @ self.Pi.T
        return 0.5 * (Cw + Cw.T)

    def determined(self, dependent: np.ndarray, std: np.ndarray) -> np.ndarray:
        """Which of the `dependent` coefficients (bool mask) are determined in practice: ``bound_j <= PARTNER_SHARE
        std_j``, `std` from :meth:`covariance`."""
        return np.asarray(dependent, dtype=bool) & (self.bound <= PARTNER_SHARE * np.asarray(std, dtype=float))

    def reported(self, C: np.ndarray, dependent: np.ndarray, names: Sequence[str], units: Sequence[str]
                 ) -> tuple[np.ndarray, np.ndarray, dict[str, str]]:
        """``(Pi C Pi^T, determined, notes)`` for the solver's covariance `C` (rows exact for determined
        combinations): which of the `dependent` coefficients are determined in practice (:meth:`determined`)
        and the note of each (:meth:`note`)."""
        Cw = self.covariance(C)
        std = covariance_std(Cw)
        now = self.determined(dependent, std)
        return Cw, now, {names[j]: self.note(j, float(std[j]), names, units[j]) for j in map(int, np.flatnonzero(now))}

    def note(self, j: int, std: float, names: Sequence[str], unit: str) -> str:
        """The note of coefficient `j` determined in practice: the partners that move it (each one's share
        ``s_j |(Q Q^T)_ji|`` at least 1 % of the bound, largest first) and how far."""
        share = self.s[j] * np.abs(self.P[j])
        share[j] = 0.0
        order = [k for k in np.argsort(-share) if share[k] >= 0.01 * self.bound[j] and share[k] > 0.0]
        partners = [names[k] for k in order] or [names[k] for k in self.partners.get(int(j), [])]
        listed = ", ".join(partners[:4]) + (", ..." if len(partners) > 4 else "")
        return (f"{PARTNERS_NOTE} {listed}, which move it by <= {self.bound[j]:.2g} {unit} "
                f"({self.bound[j] / std:.2g} of its std) within their declared magnitudes")


def condition_numbers(red: ReducedSystem, ra: RankAnalysis) -> dict[str, float | None]:
    """2-norm condition numbers of S over its non-zero columns.

    ``condition_number`` is for S in natural units, ``condition_number_equilibrated`` for
    the columns scaled to unit norm (never centred: the model has no intercept). Zero
    columns are left out (they are reported as unidentifiable); ``None`` stands for an
    infinite value: exactly dependent non-zero columns as `ra` decides (its rank below their count), the one
    rule of the rank, so that a full rank never stands beside an infinite condition number.
    """
    keep = ~ra.zero
    if not np.any(keep) or ra.rank < int(np.sum(keep)):  # the rank analysis' dependency: the one rule
        return {"condition_number": None, "condition_number_equilibrated": None}
    out: dict[str, float | None] = {}
    for key, M in (("condition_number", red.R[:, keep] * red.scale[keep]),
                   ("condition_number_equilibrated", red.R[:, keep])):
        s = np.linalg.svd(M, compute_uv=False)
        out[key] = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    return out


def unidentifiable_reasons(ra: RankAnalysis, names: tuple[str, ...] | list[str]) -> dict[str, str]:
    """Why each zero or exactly dependent coefficient gets no estimate, keyed by name."""
    reasons: dict[str, str] = {}
    rounding = ra.rounding if ra.rounding is not None else np.zeros(len(names), dtype=bool)
    for j in np.flatnonzero(ra.zero):
        reasons[names[j]] = ("column at the rounding level: at its declared magnitude its effect on dv is at the "
                             "rounding level of the largest term's, so this flight does not excite the term"
                             if rounding[j] else "zero column: this flight does not excite the term")
    for j in np.flatnonzero(ra.dependent):
        twins = [names[k] for k in ra.partners.get(int(j), [])]
        with_ = ", ".join(twins[:6]) + (", ..." if len(twins) > 6 else "")
        reasons[names[j]] = ("exactly dependent on " + with_ + ": only their combination is determined"
                             if twins else "exactly dependent columns: only a combination is determined")
    return reasons


def least_squares_rss(red: ReducedSystem, ra: RankAnalysis) -> float:
    """Least-squares residual sum of squares of a reduction at the rank of `ra`.

    ``RSS = rho^2 + ||U_{r+}^T q||^2``: the part of ``y`` outside the columns (``rho^2``) plus the
    part of ``q = Q^T y`` outside the range of ``R`` (``U`` from the SVD of the scaled ``R``).
    """
    Uq = ra.U.T @ red.qty
    return red.rho2 + float(np.sum(Uq[ra.rank:] ** 2))


#: Refine a least-squares solution when the predicted relative error of the QR solve exceeds this
#: (five of the sixteen digits of a double lost; a well-conditioned fit stays below it and pays nothing).
REFINE_ABOVE = 1e-11
#: Refinement converges when ``kappa^2 u`` is below 1 (each step multiplies the error by it); beyond
#: this bound it is not attempted.
_REFINE_CONTRACTION = 0.1
_REFINE_BLOCK_SAMPLES = 4096  # rows per extended-precision block: ~4096 x 3 x n x 16 bytes


def qr_forward_error(red: ReducedSystem, ra: RankAnalysis, z: np.ndarray) -> float:
    """Predicted relative error of the QR least-squares solution ``z`` of the scaled system.

    ``u (kappa + kappa^2 ||r|| / (||R|| ||z||))`` (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed., Thm 20.3, without its modest ``m n`` factor): ``kappa = s_0 / s_{r-1}`` over
    the numerical rank, ``||r||^2`` the residual sum of squares. The ``kappa^2`` term is the loss of a
    large-residual fit: a backward-stable solve cannot beat it, a residual in extended precision can.
    Infinite when ``z`` is zero or the rank is 0.
    """
    r = ra.rank
    z_norm = float(np.linalg.norm(z))
    if r == 0 or z_norm == 0.0:
        return float("inf")
    kappa = float(ra.s[0] / ra.s[r - 1])
    res = float(np.sqrt(max(least_squares_rss(red, ra), 0.0)))
    return float(np.finfo(float).eps * (kappa + kappa**2 * res / (ra.s[0] * z_norm)))


def refine_least_squares(red: ReducedSystem, ra: RankAnalysis, x: np.ndarray,
                         blocks: Callable[[int], Iterator[tuple[slice, np.ndarray, np.ndarray]]]) -> np.ndarray:
    """One step of iterative refinement of a least-squares solution, residual in extended precision.

    Parameters
    ----------
    red, ra : ReducedSystem, RankAnalysis
        The reduction of the rows and its rank analysis (``R = U diag(s) V^T``, scaled columns).
    x : (n,) ndarray
        Solution in natural units (the minimum-norm one at rank ``r``).
    blocks : callable
        ``blocks(rows)`` yields ``(slice, S block, y block)`` of the rows the reduction stands for
        (:meth:`casep.regression.problem.Problem.blocks`).

    Returns
    -------
    (n,) ndarray
        ``x`` corrected; ``x`` itself when the refinement would not converge.

    Notes
    -----
    The corrected semi-normal equations (Bjorck, *Numerical Methods for Least Squares Problems*,
    section 2.5.3) in scaled coordinates ``z = c x``::

        r   = y - S x                                (np.longdouble, row block by row block)
        g   = diag(1/c) S^T r                        (np.longdouble, then rounded once)
        dz  = V_r diag(1/s_r^2) V_r^T g              ((R^T R)^+ g, R from the QR reduction)
        x  <- x + dz / c

    ``R^T R = Z^T Z + E`` with ``||E|| ~ u ||Z||^2``, so the correction is right to a relative
    ``kappa^2 u`` and the step multiplies the error by that: it converges for ``kappa^2 u < 1``
    (attempted up to 0.1) and ends at the error of ``g``, ``kappa^2 u_ext ||r||`` with
    ``u_ext = 2^-64`` on x86 (80-bit long double; where long double is a double the step still
    removes the error of the solve but not the ``kappa^2 ||r||`` term). The correction stays in
    ``range(V_r)``, so a minimum-norm solution stays minimum-norm.
    """
    r = ra.rank
    if r == 0 or float(ra.s[0] / ra.s[r - 1]) ** 2 * np.finfo(float).eps > _REFINE_CONTRACTION:
        return x
    n = red.n
    xl = np.where(np.isnan(x), 0.0, x).astype(np.longdouble)
    g = np.zeros(n, dtype=np.longdouble)
    for _, S_b, y_b in blocks(_REFINE_BLOCK_SAMPLES):
        Sl = np.asarray(S_b, dtype=np.longdouble).reshape(-1, n)
        res = np.asarray(y_b, dtype=np.longdouble).reshape(-1) - np.einsum("ij,j->i", Sl, xl)  # r = y - S x
        g += np.einsum("ij,i->j", Sl, res)  # S^T r (einsum: a third faster than matmul in long double)
    inv_c = np.where(red.scale > 0, 1.0 / np.where(red.scale > 0, red.scale, 1.0), 0.0)
    gz = (g * inv_c).astype(float)  # Z^T r = diag(1/c) S^T r
    V = ra.Vt[:r].T
    dz = V @ ((V.T @ gz) / ra.s[:r] ** 2)  # (R^T R)^+ Z^T r on range(V_r)
    return x + dz * inv_c
