"""S_V: the regression matrix dv(t) = S_V(t) D, integrated from the model's Jacobians.

With G(t) = d phidot / dD and A(t) = d Delta / dD evaluated at the telemetered specific
force f(t) (CasADi functions of the model), and the constant initial-term Jacobians
Phi0 = d phi0 / dD and V0 = d dv0 / dD::

    Phi(t) = Phi0 + int_{t0}^{t} G dt              (3 x n, d phi / dD)
    I(t)   = [f(t) x] Phi(t) + A(t)                 (3 x n, d dWdot / dD)
    S_V(t) = V0 + int_{t0}^{t} I dt + V_d(t)        (3 x n, d dv / dD)

with V_d(t) = d dv_d / dD the Jacobian of the model's direct velocity error (added per
sample, not integrated). G, A and V_d may depend on the time since the first sample
``t - t_0`` and on flight columns (the model's ``signals``), which are evaluated with f in
the same chunks.

Both integrals use the cumulative trapezoid rule on the sample times (need not be uniform),
with dt_k = t_k - t_{k-1}::

    Phi_k = Phi_{k-1} + (G_{k-1} + G_k) dt_k / 2
    S_k   = S_{k-1}   + (I_{k-1} + I_k) dt_k / 2

Its error is O(dt^2) per unit time (relative error about (omega dt)^2 / 12 for a component
of angular frequency omega): below 1e-5 for boost-phase signals at >= 20 Hz.

Evaluation is chunked: the model's ``sv_rates`` CasADi function is mapped over a fixed
chunk of samples once (``Function.map(chunk)``) and evaluated through
``Function.buffer()`` straight into numpy arrays; a kernel
(:func:`casep._kernels.sv_integrate_chunk`: numpy on a short flight, numba on a long one) then runs
both trapezoid recursions over the chunk, carrying the running integrals to the next chunk. Memory beyond the
(N, 3, n) result is a few chunk-sized arrays.
"""

from __future__ import annotations

import warnings
from typing import Any, Iterator, Mapping

import numpy as np

from casep._kernels import cumulative_trapezoid, sv_integrate_chunk
from casep.exceptions import GapWarning
from casep.model.error_model import ErrorModel

__all__ = ["build_sv", "SVBuilder", "DEFAULT_CHUNK", "cumulative_sp", "evaluate_samples"]

#: Samples per CasADi evaluation. Large enough to amortise the call, small enough for cache.
DEFAULT_CHUNK = 2048


def _check_time_force(t: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float)
    f = np.asarray(f, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"`t` must be 1-D, got shape {t.shape}")
    if f.shape != (t.size, 3):
        raise ValueError(f"`f` must have shape (N, 3) = ({t.size}, 3), got {f.shape}")
    if t.size < 1:
        raise ValueError("`t` is empty")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"`t` is not finite at row {bad[0]}")
    bad_rows = np.flatnonzero(~np.all(np.isfinite(f), axis=1))
    if bad_rows.size:
        r = bad_rows[0]
        raise ValueError(f"`f` is not finite at row {r} (column {'xyz'[np.flatnonzero(~np.isfinite(f[r]))[0]]})")
    step = np.flatnonzero(np.diff(t) <= 0)
    if step.size:
        raise ValueError(f"`t` is not strictly increasing at row {step[0] + 1}")
    return t, np.ascontiguousarray(f)


def _bind(setter: Any, i: int, array: np.ndarray) -> None:
    """Bind the C-contiguous `array` as input or output `i` of a CasADi FunctionBuffer (``set_arg`` / ``set_res``).

    The binding takes the byte size from the memoryview; casadi's type stubs ask for it as a third
    argument, which the binding refuses, and do not know that an ndarray is a buffer.
    """
    setter(i, memoryview(array))  # type: ignore[arg-type]


#: :func:`evaluate_samples`' mapped functions by (function, n), the function held so that its id stays its own: CasADi
#: keeps a map only while a reference to it lives, and a model's outputs are evaluated at the same sample counts
#: many times (each coefficient's body errors over the pad window). At most 64 kept.
_MAPPED: dict[tuple[int, int], tuple[Any, Any]] = {}


def evaluate_samples(fn: Any, values: Mapping[str, np.ndarray], n: int) -> np.ndarray:
    """The one-output CasADi function `fn` at each of `n` samples: ``(n, rows)``, row k the output at sample k.

    `values` holds each input of `fn` by name, one column per sample (``(rows_i, n)``). The same numbers as
    ``np.array(fn.map(n)(*inputs)).T`` (the same mapped function evaluated), through ``Function.buffer()``
    straight from and into numpy arrays, as :class:`SVBuilder` evaluates: the call's conversions of the inputs
    and output to CasADi matrices cost about eight times the evaluation (a strapdown model's ``Delta`` at 800
    samples: 2.8 ms against 0.35 ms). An output with structural zeros (a model without that term) goes through
    the call (a buffer holds the nonzeros only).
    """
    held = _MAPPED.get((id(fn), n))
    if held is None or held[0] is not fn:
        if len(_MAPPED) >= 64:
            _MAPPED.clear()
        held = _MAPPED[(id(fn), n)] = (fn, fn.map(n))
    mapped = held[1]
    if not mapped.sparsity_out(0).is_dense():  # a buffer holds the output's nonzeros only: the plain call
        return np.array(mapped(*(values[name] for name in fn.name_in()))).T
    buf, evaluate = mapped.buffer()
    # CasADi's (rows, n) column-major is numpy's (n, rows) C order
    args = [np.ascontiguousarray(np.asarray(values[name], dtype=float).reshape(-1, n).T) for name in fn.name_in()]
    for i, a in enumerate(args):
        if a.size:  # an input of no rows (a model without signals) has nothing to bind
            _bind(buf.set_arg, i, a)
    out = np.zeros((n, mapped.size1_out(0)))
    _bind(buf.set_res, 0, out)
    evaluate()
    return out


class SVBuilder:
    """Reusable chunked evaluator of S_V for one set-up model.

    Parameters
    ----------
    model : ErrorModel
        A set-up model.
    chunk : int, optional
        Samples per CasADi call (default :data:`DEFAULT_CHUNK`).

    Notes
    -----
    The mapped CasADi function and its buffers are created once here, so building S_V for
    many flights (Monte Carlo) pays the set-up once.
    """

    def __init__(self, model: ErrorModel, chunk: int = DEFAULT_CHUNK) -> None:
        if not isinstance(model, ErrorModel):
            raise TypeError(f"`model` must be an ErrorModel, got {type(model).__name__}")
        if not model.is_setup:
            raise ValueError(f"`model` `{model.name}` is not set up. Use: model.setup()")
        if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
            raise ValueError(f"`chunk` must be a positive int, got {chunk!r}")
        self.model = model
        self.chunk = int(chunk)
        self._gcols = model.numeric("gyro_columns")
        self._acols = model.numeric("accel_columns")
        self._vcols = model.numeric("velocity_columns")
        self._phi0 = model.numeric("phi0")[:, self._gcols]  # (3, ng)
        self._dv0 = model.numeric("dv0")  # (3, n)
        ng, na = self._gcols.size, self._acols.size
        C = self.chunk
        mapped = model.functions["sv_rates"].map(C)
        self._buf, self._eval = mapped.buffer()
        self._fin = np.zeros((C, 3))  # CasADi sees 3 x C column-major
        self._G = np.zeros((C, 3, ng))  # per sample (dphidot/dD)^T, ng x 3 column-major
        self._A = np.zeros((C, 3, na))
        self._V = np.zeros((C, 3, self._vcols.size))  # direct velocity-error Jacobian
        self._tin = np.zeros(C)  # t - t_0, s
        self._sin = np.zeros((C, len(model.signals)))  # signal columns, file units
        _bind(self._buf.set_arg, 0, self._fin)
        _bind(self._buf.set_arg, 1, self._tin)
        if self._sin.shape[1]:
            _bind(self._buf.set_arg, 2, self._sin)
        _bind(self._buf.set_res, 0, self._G)
        _bind(self._buf.set_res, 1, self._A)
        _bind(self._buf.set_res, 2, self._V)

    def build(self, t: np.ndarray, f: np.ndarray, out: np.ndarray | None = None, *,
              signals: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """Integrate S_V over a flight.

        Parameters
        ----------
        t : (N,) array_like
            Sample times, s, strictly increasing.
        f : (N, 3) array_like
            Platform specific force, m/s^2.
        out : (N, 3, n) ndarray, optional
            Where to write the result (float64, C-contiguous).
        signals : mapping of str -> (N,) array_like, optional
            Flight columns by name (file units): every one of ``model.signals`` is required.

        Returns
        -------
        (N, 3, n) ndarray
            ``S[k, i, j]`` = d dv_i(t_k) / d D_j, per natural unit of coefficient j.
            ``S.reshape(3 * N, n)`` is the stacked regression matrix (x, y, z per sample).
        """
        t, f = _check_time_force(t, f)
        sig = _signal_matrix(self.model, signals, t.size)
        N, n = t.size, self.model.n_coefficients
        if out is None:
            out = np.empty((N, 3, n))
        elif out.shape != (N, 3, n) or out.dtype != np.float64 or not out.flags.c_contiguous:
            raise ValueError(f"`out` must be a C-contiguous float64 array of shape {(N, 3, n)}")
        for _ in self._integrate(t, f, sig, max(N, 1), out):  # one block: the whole flight, into `out`
            pass
        return out

    def blocks(self, t: np.ndarray, f: np.ndarray, rows: int = 65536, *,
               signals: Mapping[str, np.ndarray] | None = None) -> Iterator[tuple[int, int, np.ndarray]]:
        """Integrate S_V over a flight block by block, never holding it whole.

        Yields ``(start, stop, S[start:stop])`` in time order. The block array is reused between
        yields (copy it to keep it). Same numbers as :meth:`build`: same recursion, same chunks
        (`rows` is rounded to whole chunks).
        """
        t, f = _check_time_force(t, f)
        sig = _signal_matrix(self.model, signals, t.size)
        if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or rows < 1:
            raise ValueError(f"`rows` must be a positive int, got {rows!r}")
        rows = max(self.chunk, int(rows) // self.chunk * self.chunk)
        buf = np.empty((min(rows, t.size), 3, self.model.n_coefficients))
        yield from self._integrate(t, f, sig, rows, buf)

    def _integrate(self, t: np.ndarray, f: np.ndarray, sig: np.ndarray, rows: int,
                   buf: np.ndarray) -> Iterator[tuple[int, int, np.ndarray]]:
        """The trapezoid recursions over CasADi chunks, `rows` samples per yield, written into `buf`."""
        N, n = t.size, self.model.n_coefficients
        dt = np.empty(N)
        dt[0] = 0.0  # S_V(t0) = V0, Phi(t0) = Phi0
        np.subtract(t[1:], t[:-1], out=dt[1:])
        half_dt = 0.5 * dt
        _warn_gaps(dt, t)
        # Carries between chunks: running integrals and the last integrands.
        phi = self._phi0.copy()  # (3, ng)
        G_prev = np.zeros_like(phi)
        I_prev = np.zeros((3, n))
        S_prev = self._dv0.copy()  # (3, n)
        C = self.chunk
        integrate_chunk = sv_integrate_chunk(N)  # numpy or compiled, by the flight's length
        for b0 in range(0, N, rows):
            b1 = min(b0 + rows, N)
            for s in range(b0, b1, C):
                e = min(s + C, b1)
                k = e - s
                o = buf[s - b0:e - b0]
                self._fin[:k] = f[s:e]  # also the kernel's f: writable, as every caller's (one compiled signature)
                self._tin[:k] = t[s:e] - t[0]  # m.t: time since the first sample
                self._sin[:k] = sig[s:e]
                if k < C:
                    self._fin[k:] = 0.0
                self._eval()  # CasADi: G, A of the chunk into self._G, self._A
                integrate_chunk(self._G[:k], self._A[:k], self._fin[:k], half_dt[s:e], self._gcols,
                                self._acols, phi, G_prev, I_prev, S_prev, o)
                if self._vcols.size:
                    o[:, :, self._vcols] += self._V[:k]  # + V_d: direct term, not integrated
            yield b0, b1, buf[: b1 - b0]


def _signal_matrix(model: ErrorModel, signals: Mapping[str, np.ndarray] | None, n: int) -> np.ndarray:
    """(N, n_signals) float array of the model's signal columns, checked (present, shape, finite)."""
    names = model.signals
    signals = {} if signals is None else signals
    missing = [c for c in names if c not in signals]
    if missing:
        raise ValueError(f"model `{model.name}` needs flight column(s) {', '.join(f'`{c}`' for c in missing)}, "
                         f"which the flight lacks (it has: {', '.join(signals) or 'no extra columns'})")
    out = np.empty((n, len(names)))
    for j, c in enumerate(names):
        v = np.asarray(signals[c], dtype=float)
        if v.shape != (n,):
            raise ValueError(f"signal `{c}` must have shape ({n},), got {v.shape}")
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise ValueError(f"model `{model.name}`: signal column `{c}` is not finite at row {bad[0] + 1} "
                             f"(value {v[bad[0]]:g}; rows count from 1)")
        out[:, j] = v
    return out


#: A step longer than this many times the median step counts as a data gap.
GAP_FACTOR = 10.0


def _warn_gaps(dt: np.ndarray, t: np.ndarray) -> None:
    if dt.size < 3:
        return
    med = float(np.median(dt[1:]))
    big = np.flatnonzero(dt[1:] > GAP_FACTOR * med) + 1
    if big.size:
        k = int(big[np.argmax(dt[big])])
        warnings.warn(
            f"`t` has {big.size} gap(s) longer than {GAP_FACTOR:g}x the median step {med:.3g} s (largest "
            f"{dt[k]:.3g} s before sample {k + 1}, t = {t[k]:.6g} s): S_V is integrated across them by the "
            "trapezoid rule, which is inaccurate where the specific force changes inside a gap",
            GapWarning, stacklevel=3)


def build_sv(model: ErrorModel, t: np.ndarray, f: np.ndarray, *, chunk: int = DEFAULT_CHUNK,
             signals: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
    """S_V of a flight for a set-up model: ``(N, 3, n)`` array, see :class:`SVBuilder`."""
    return SVBuilder(model, chunk).build(t, f, signals=signals)


def cumulative_sp(S: np.ndarray, t: np.ndarray) -> np.ndarray:
    """S_P = cumulative trapezoid of S_V over `t`, zero at the first sample: ``(N, 3, n)``
    (:func:`casep._kernels.cumulative_trapezoid`).

    Notes
    -----
    ``S_P[0] = 0``, ``S_P[k] = S_P[k-1] + (S_V[k-1] + S_V[k]) (t_k - t_{k-1}) / 2``.
    """
    return cumulative_trapezoid(S, t)
