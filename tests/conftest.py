"""Shared fixtures: seeded rng, set-up models, the paper's truth and a synthetic flight."""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import casep
from casep.simulation.paper import TABLE1_TRUTH
from casep.simulation.synthetic import excitation_force


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture(scope="session")
def platform36() -> casep.ErrorModel:
    return casep.load_model("platform36")


@pytest.fixture(scope="session")
def platform39() -> casep.ErrorModel:
    return casep.load_model("platform39_misalignment")


@pytest.fixture(scope="session")
def truth36(platform36) -> np.ndarray:
    return np.array([TABLE1_TRUTH[n] for n in platform36.names])


@pytest.fixture(scope="session")
def flight_tf() -> tuple[np.ndarray, np.ndarray]:
    """180 s at 20 Hz of the analytic excitation (all three axes)."""
    t = np.arange(0.0, 180.0, 0.05)
    return t, excitation_force(t)


@pytest.fixture(scope="session")
def paper_problem(platform36):
    """S_V, dv and truth of the paper scenario at 20 Hz (seed 1)."""
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=1, rate=20.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    return S, np.array(sim.flight.dv), sim.truth


def augmented_lstsq(S2: np.ndarray, y: np.ndarray, prior_precision_sqrt: np.ndarray,
                    prior_mean: np.ndarray) -> np.ndarray:
    """Independent reference: argmin ||y - S x||^2 + ||diag(p) (x - mu)||^2 on unit-norm columns."""
    c = np.linalg.norm(S2, axis=0)
    A = np.vstack([S2 / c, np.diag(prior_precision_sqrt / c)])
    b = np.concatenate([y, prior_precision_sqrt * prior_mean])
    return np.linalg.lstsq(A, b, rcond=None)[0] / c


def dishonest_methods(stats: dict, rms=(0.85, 1.15), coverage=(0.92, 0.98)) -> dict:
    """``{method: (RMS z, 95 % coverage)}`` of the methods whose z (Monte Carlo, method -> z values)
    fall outside the honest ranges."""
    bad = {}
    for m, z in stats.items():
        r, cov = float(np.sqrt(np.mean(z**2))), float(np.mean(np.abs(z) <= 1.96))
        if not (rms[0] <= r <= rms[1] and coverage[0] <= cov <= coverage[1]):
            bad[m] = (round(r, 3), round(cov, 3))
    return bad


def whitened_error(err: np.ndarray, cov: np.ndarray, rank: int | None = None) -> np.ndarray:
    """One draw's error ``e`` (estimate - reference) whitened by its stated covariance ``C``: ``w`` with
    ``w ~ N(0, I_r)`` when ``e ~ N(0, C)``, so ``w^T w = e^T C^+ e ~ chi2_r``.

    The coefficients with a finite, positive std only. In correlation units (``z = e / std``,
    ``R = D^-1 C D^-1 = U diag(lam) U^T``) the `rank` (default: all) largest eigenvalues:
    ``w = diag(lam_r)^-1/2 U_r^T z``. A rank-deficient covariance (pcr: ``rank = n_components``)
    states zero variance outside ``U_r``; an error there is a wrong covariance, so it is refused
    (more than 1e-8 of ``|z|``) rather than left out.
    """
    err, cov = np.asarray(err, dtype=float), np.asarray(cov, dtype=float)
    sd = np.sqrt(np.diag(cov))
    keep = np.isfinite(sd) & (sd > 0) & np.isfinite(err)
    z = err[keep] / sd[keep]
    lam, U = np.linalg.eigh(cov[np.ix_(keep, keep)] / np.outer(sd[keep], sd[keep]))
    r = z.size if rank is None else rank
    lam, U = lam[::-1][:r], U[:, ::-1][:, :r]  # the r largest
    u = U.T @ z
    outside = np.linalg.norm(z - U @ u)
    assert outside <= 1e-8 * np.linalg.norm(z), f"error outside the covariance's range: {outside:.3g}"
    return u / np.sqrt(lam)


def dishonest_whitened(stats: dict, rms: tuple[float, float] | None = (0.85, 1.15), false_alarm: float = 1e-3) -> dict:
    """``{method: (RMS w, draws over their chi2 95 % point, the largest count allowed)}`` of the methods
    whose whitened errors (method -> one :func:`whitened_error` per draw) say the stated covariance is
    not honest.

    Two checks. The RMS of all ``w`` in `rms`: with an honest covariance ``sum w^2 ~ chi2_dof`` (dof:
    draws x rank), so the RMS has std ``~ 1 / sqrt(2 dof)`` (0.026 at 20 draws of 36): the band is a
    tolerance on the std (15 %), not the statistic's scatter; a std 2x too small gives RMS 2, 1.25x too
    small gives 1.25 (above 1.15 by ~3 of its std). Unlike the per-coefficient ``z``, whose 36 values
    in one draw are strongly correlated, the ``w`` are independent, so few draws suffice. And the
    number of draws whose ``w^T w`` passes its chi2_r 95 % point, Binomial(draws, 0.05) when honest:
    at most the count exceeded with probability `false_alarm` (5 of 20): a few draws with a grossly
    wrong covariance fail it where the pooled RMS may not.

    `rms` None, for a reduced run whose draws are too few for the 15 % band: the band from the statistic's
    own scatter, ``sqrt(chi2_dof quantile / dof)`` at ``false_alarm / 4`` each side (at 4 draws of 36,
    ``false_alarm`` 1e-4: [0.769, 1.245]), and the count at ``false_alarm / 2``: an honest covariance
    fails the two together with probability at most `false_alarm`.
    """
    from scipy.stats import binom, chi2

    bad = {}
    for m, ws in stats.items():
        q = np.array([w @ w for w in ws])
        dof = sum(w.size for w in ws)
        r = float(np.sqrt(q.sum() / dof))
        over = int(sum(qk > chi2.ppf(0.95, w.size) for qk, w in zip(q, ws)))
        p_count = false_alarm if rms is not None else false_alarm / 2
        limit = int(binom.isf(p_count, len(ws), 0.05))  # P(count > limit) <= p_count
        lo, hi = rms if rms is not None else (float(np.sqrt(chi2.ppf(false_alarm / 4, dof) / dof)),
                                              float(np.sqrt(chi2.isf(false_alarm / 4, dof) / dof)))
        if not (lo <= r <= hi and over <= limit):
            bad[m] = (round(r, 3), over, limit)
    return bad


def gm_white_noise(t: np.ndarray, rng: np.random.Generator, tau: float, gm: float, white: float) -> np.ndarray:
    """``(N, 3)`` Gauss-Markov (std `gm`, correlation time `tau`; exact discretisation, stationary start) plus white
    (std `white`) noise per axis at times `t`, written independently of casep's simulation."""
    phi = np.exp(-np.diff(t) / tau)
    e = rng.standard_normal((t.size, 3))
    g = np.empty((t.size, 3))
    g[0] = gm * e[0]
    for k in range(1, t.size):
        g[k] = phi[k - 1] * g[k - 1] + gm * np.sqrt(1.0 - phi[k - 1] ** 2) * e[k]
    return g + white * rng.standard_normal((t.size, 3))


def bias_scale_rows(t: np.ndarray, f: np.ndarray, up: np.ndarray) -> np.ndarray:
    """``S (N, 3, 7)`` of a boost with specific force `f`: initial velocity errors, accelerometer biases and the
    scale factor along the unit thrust direction `up` (its column the integral of ``f . up`` along `up`)."""
    F = np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t)[:, None], axis=0)])
    S = np.zeros((t.size, 3, 7))
    S[:, :, :3] = np.eye(3)
    S[:, :, 3:6] = t[:, None, None] * np.eye(3)
    S[:, :, 6] = np.einsum("ki,i->k", F, up)[:, None] * up
    return S


def noise_free_errors(flight, model, truth, sigma: float = 0.1):
    """Separate a noise-free flight with platform36 OLS (its ill-conditioning warning expected) and
    return ``(result, |estimate - truth| / CRLB std at noise sigma)``: how exactly the pipeline recovers
    the truth, in units of what noise would allow."""
    from casep.checks.diagnostics import crlb_covariance
    from casep.exceptions import IllConditionedWarning
    from casep.workflows.separate import regression_rows

    with pytest.warns(IllConditionedWarning):
        res = casep.separate(flight, "platform36")
    S, _, _ = regression_rows(flight, model)
    crlb = np.sqrt(np.diag(crlb_covariance(S, sigma)))
    est = np.asarray(res.estimate)[[res.names.index(n) for n in model.names]]  # an Earth-fixed flight adds dt_trk
    return res, np.abs(est - np.asarray(truth)) / crlb


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread_per_xdist_worker():
    """With pytest-xdist (`-n 2`), each worker process uses one BLAS thread: two workers on two
    cores, not four threads fighting for them (oversubscription made a Monte Carlo 30x slower).

    threadpoolctl limits the libraries loaded when it is called: SciPy's own OpenBLAS (scipy.libs, not NumPy's)
    loads with scipy.linalg, which the first test may not have imported yet, and then kept its default threads
    (2 on 2 cores) for the whole run. It is loaded first."""
    import os

    if not os.environ.get("PYTEST_XDIST_WORKER"):
        yield
        return
    import scipy.linalg  # noqa: F401  (SciPy's BLAS library loaded, so that the limit reaches it)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


#: numba's kernels (casep._compiled) with the argument types casep's callers give them (casep._kernels: C-contiguous
#: float64 arrays, int64 column indices), compiled into numba's on-disk cache by :func:`pytest_configure`.
_COMPILE_KERNELS = """
import pathlib, sys
try:
    from numba import types as T
    from casep import _compiled as c
    A1, A2, A3 = (T.Array(T.float64, d, "C") for d in (1, 2, 3))
    I1, f8, i8 = T.Array(T.int64, 1, "C"), T.float64, T.int64
    c.sv_integrate_chunk.compile((A3, A3, A2, A1, I1, I1, A2, A2, A2, A2, A3))
    c.gmw_filter.compile((A2, A1, f8, f8, A1, A1, A2))
    c.all_pole_filter.compile((A1, A2, A2))
    c.rels_ud.compile((A3, A2, A1, A2, A1, f8, f8, i8, T.boolean, i8, A2, A2, A1, A2, i8))
finally:
    pathlib.Path(sys.argv[1]).touch()
"""


#: The test files that take the most CPU, most first (measured on the whole suite, CPU seconds per file: 65 for
#: test_noise_model down to 10): :func:`pytest_collection_modifyitems` runs them first. With ``--dist loadfile``
#: (pyproject) a file runs whole on one worker and the next file goes to the first worker free, so the long files
#: are spread over both workers at the start and the short ones fill the end (no worker left alone with a long
#: file at the end). A file not listed runs after these, in collection order.
SLOW_FILES_FIRST = (
    "noise/test_noise_model.py", "radar/test_radar.py", "radar/test_radar_setup.py", "docs/test_console_blocks.py",
    "montecarlo/test_montecarlo_dask.py", "test_examples.py", "design/test_design.py", "workflows/test_imu_separate.py",
    "workflows/test_imu_separate_heading.py",
    "workflows/test_imu_clock_drift.py", "workflows/test_telemetry_frame.py", "workflows/test_flights.py",
    "reporting/test_report.py",
    "radar/test_radar_noise.py", "checks/test_setup_checks.py",
    "montecarlo/test_montecarlo.py", "checks/test_plausibility.py", "calibration/test_multiposition_cli.py",
    "estimators/test_gls.py", "workflows/test_noise_mixture_mc.py", "model/test_model_signals.py",
    "calibration/test_ferraris_auto.py", "calibration/test_multiposition.py", "checks/test_late_start.py",
    "calibration/test_multiposition_review.py", "radar/test_radar_review.py", "workflows/test_demo.py",
    # then the other files over about 4 s (of a --durations run under load), longest first: alphabetical, the
    # workflows' long files came last, and the worker that took the last of them finished alone, seconds late
    "checks/test_saturation_telemetry.py", "estimators/test_conformance.py", "cli/test_cli.py",
    "workflows/test_imu_separate_gmw.py",
    "simulation/test_strapdown_noise_free_default.py", "model/test_vehicle_window.py",
    "workflows/test_telemetry_clock.py", "io/test_range_io.py", "workflows/test_windows.py",
    "workflows/test_imu_instability.py", "simulation/test_strapdown_sim.py", "io/test_flight_io.py",
    "workflows/test_telemetry_iterate.py", "noise/test_denoise.py", "model/test_strapdown_models.py",
    "reporting/test_plots.py", "workflows/test_imu_separate_rest.py", "workflows/test_rocket_separation.py",
    "checks/test_tracking_quality.py", "io/test_velocity_columns.py", "workflows/test_telemetry_heading.py",
    "test_frames.py", "estimators/test_fitspec.py", "io/test_files_run_no_code.py",
    "workflows/test_imu_separate_correlated.py", "estimators/test_result_settings.py", "workflows/test_manifest.py",
    "workflows/test_imu_separate_strapdown33.py", "io/test_strapdown_io.py", "checks/test_tracking_excursions.py",
    "navigation/test_navigate.py", "workflows/test_imu_noise_budget.py",
)


def pytest_collection_modifyitems(config, items):
    """The files of :data:`SLOW_FILES_FIRST` first, in its order; the order of the tests within a file kept."""
    tests = Path(__file__).resolve().parent
    rank = {name: k for k, name in enumerate(SLOW_FILES_FIRST)}

    def key(item) -> int:
        try:
            name = Path(str(item.path)).resolve().relative_to(tests).as_posix()
        except ValueError:
            return len(rank)
        return rank.get(name, len(rank))

    items.sort(key=key)  # stable


def _compile_casep_bytecode() -> None:
    """casep's bytecode written once (``compileall``, into __pycache__ beside the sources, as Python does by itself
    unless PYTHONDONTWRITEBYTECODE is set): with that variable set, every CLI command a test runs in a new
    interpreter compiled again every casep module it imports. Python reads the bytecode whatever the variable."""
    import compileall

    root = Path(__file__).resolve().parents[1]
    for folder in ("casep", "models"):
        compileall.compile_dir(root / folder, quiet=1, workers=1)


def pytest_configure(config):
    """casep's bytecode first (:func:`_compile_casep_bytecode`). With pytest-xdist (`-n 2`), the controller then
    compiles numba's kernels once, in a process of its own started
    before the workers, into numba's cache (``cache=True``, beside casep/_compiled.py): on a fresh clone each worker
    compiled them itself, about 6 s of CPU each, both at once. The workers wait for it
    (:func:`_kernels_compiled_once`) while they only collect; they then load the cached machine code (the same
    code numba would have compiled in each of them). A signature not listed is compiled where it is first called, as
    without this."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    _compile_casep_bytecode()
    if not getattr(config.option, "numprocesses", None):
        return
    folder = tempfile.mkdtemp(prefix="casep-kernels-")
    done = os.path.join(folder, "done")
    config._casep_kernels = (subprocess.Popen([sys.executable, "-c", _COMPILE_KERNELS, done],
                                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), folder)
    os.environ["CASEP_TEST_KERNELS_DONE"] = done  # the workers, started after this, inherit it


def pytest_unconfigure(config):
    started = getattr(config, "_casep_kernels", None)
    if started is not None:
        started[0].wait()
        import shutil

        shutil.rmtree(started[1], ignore_errors=True)


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once():
    """A worker's first test waits (at most 120 s) for the controller's compilation of numba's kernels."""
    done = os.environ.get("CASEP_TEST_KERNELS_DONE")
    if done and os.environ.get("PYTEST_XDIST_WORKER"):
        end = time.monotonic() + 120.0
        while not os.path.exists(done) and time.monotonic() < end:
            time.sleep(0.05)
    yield


def finite_json(path) -> dict:
    """The JSON file, refusing any non-finite number (Infinity/NaN) anywhere in it."""

    def refuse(token):
        raise AssertionError(f"non-finite number {token} in {path}")

    data = json.loads(path.read_text(), parse_constant=refuse)

    def walk(x, where="$"):
        if isinstance(x, dict):
            for k, v in x.items():
                walk(v, f"{where}.{k}")
        elif isinstance(x, list):
            for i, v in enumerate(x):
                walk(v, f"{where}[{i}]")
        elif isinstance(x, float):
            assert math.isfinite(x), where

    walk(data)
    return data


#: Python's warning filters when no -W option or PYTHONWARNINGS is given (a fresh interpreter's), first to last.
_PYTHON_DEFAULT_FILTERS = (("default", DeprecationWarning, "__main__"), ("ignore", DeprecationWarning, ""),
                           ("ignore", PendingDeprecationWarning, ""), ("ignore", ImportWarning, ""),
                           ("ignore", ResourceWarning, ""))


def run_forked(program: Callable[[], int | None], argv: list[str], cwd: Path, env: dict[str, str] | None = None,
               path0: str | None = None, timeout: int = 300) -> tuple[int, str, str]:
    """``program()`` run as a new interpreter would run it, in a forked child of this test process:
    ``(exit status, stdout, stderr)``.

    The child has `argv` as ``sys.argv`` (`path0`, when given, as ``sys.path[0]``: a script's folder), works in
    `cwd` with the environment `env` (default: this one's), writes its stdout and stderr to files, has
    Python's default warning filters (pytest's ``error`` filter is this process's), and ends as the
    interpreter would: ``program``'s return value or ``sys.exit``'s status, 1 with the traceback for an
    uncaught exception, killed (SIGALRM) after `timeout` s. It saves a command the 1.2-1.5 s of CPU of a new
    interpreter importing casep, NumPy, SciPy and CasADi, which this process has loaded already.
    """
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            status = 1
            try:
                signal.alarm(timeout)
                os.chdir(cwd)
                if env is not None:
                    os.environ.clear()
                    os.environ.update(env)
                os.dup2(out.fileno(), 1)
                os.dup2(err.fileno(), 2)
                sys.stdout = open(1, "w", encoding="utf-8", closefd=False)
                sys.stderr = open(2, "w", encoding="utf-8", closefd=False)
                sys.argv = list(argv)
                if path0 is not None:
                    sys.path[0] = path0
                warnings.resetwarnings()
                for action, category, module in reversed(_PYTHON_DEFAULT_FILTERS):
                    warnings.filterwarnings(action, category=category, module=module)
                returned = program()
                status = returned if isinstance(returned, int) else 0
            except SystemExit as exc:
                if exc.code is None or isinstance(exc.code, int):
                    status = exc.code or 0
                else:
                    print(exc.code, file=sys.stderr)
            except BaseException:
                traceback.print_exc()
            finally:  # never back into pytest: the child ends here, whatever happened
                try:
                    sys.stdout.flush()
                    sys.stderr.flush()
                finally:
                    os._exit(status & 0xFF if isinstance(status, int) else 1)
        _, wait_status = os.waitpid(pid, 0)
        texts = []
        for f in (out, err):
            f.seek(0)
            texts.append(f.read().decode("utf-8", errors="replace"))
    return os.waitstatus_to_exitcode(wait_status), texts[0], texts[1]


# ---------------------------------------------------------------- an independent strapdown INS (telemetry + tracking)
#: The INS simulation's defaults: duration (s), telemetry rate (Hz), integration steps per telemetry sample, tracking
#: rate (Hz), tracking noise (m/s).
DUR, RATE, SUB, TRK_RATE, NOISE = 60.0, 25.0, 8, 5.0, 0.02
DEGH = math.pi / 180 / 3600


def _qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _dcm(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _qexp(r):
    a = float(np.linalg.norm(r))
    return np.array([1.0, *(r / 2)]) if a < 1e-15 else np.array([math.cos(a / 2), *(math.sin(a / 2) * r / a)])


def _ins_rate(t, growth):  # rad/s: a roll whose amplitude grows by `growth` rad/s per s
    return np.array([0.3 + (0.6 + growth * t) * math.sin(2 * math.pi * t / 7), 0.3 * math.sin(2 * math.pi * t / 13),
                     0.2 * math.cos(2 * math.pi * t / 17)])


def _ins_acc(t):  # kinematic acceleration, launch frame (y up), m/s^2
    return np.array([3 * math.sin(2 * math.pi * t / 30) + 1, 2 * math.sin(2 * math.pi * t / 11),
                     2.5 * math.cos(2 * math.pi * t / 23)])


def ins_telemetry(clip_dps: float = math.inf, seed: int = 3, *, errors: dict | None = None, noise: float = NOISE,
                  imu_noise: bool = True, growth: float = 0.03, dur: float = DUR, trk_rate: float = TRK_RATE,
                  spike: tuple[float, float] | None = None, integrates_clip: bool = True,
                  bias_noise: tuple[float, float, float] | None = None):
    """Telemetry (t, q_*, fb_*, w_*, v_tel_*), tracking (t, v_trk_*), the truth of strapdown12's coefficients and the
    gyro samples held at the full scale `clip_dps`.

    An INS written here, independent of casep's: quaternions integrated at the midpoint rate, :data:`SUB` steps per
    telemetry sample, from the measured rates (``w (1 + sg) + bg``, clipped) and body specific force
    (``fb (1 + sa) + ba``). The truth drawn from `seed` (ba ~ 1 mg, sa ~ 200 ppm, bg ~ 3 deg/h, sg ~ 300 ppm),
    `errors` (natural units) replacing any of it; `dur` (s) and `trk_rate` (Hz) the flight's length and tracking
    rate; `imu_noise`: white noise on the written rates (1e-3 rad/s off the
    rail) and forces (1e-2 m/s^2) the INS did not integrate; `noise`: white tracking noise, m/s; `integrates_clip`
    False: the INS integrates the measured rates unclipped (its own gyro did not clip), while the written ``w_*``
    are clipped at `clip_dps` (a logger's channel of narrower range than the INS's); `bias_noise` ``(s_a, s_g, tau)``:
    a bias instability the INS integrates and writes, a first-order Gauss-Markov bias per body axis (stationary std
    `s_a` m/s^2 and `s_g` rad/s, correlation time `tau` s; :func:`casep.simulation.noise.ar1_noise`) on every sample
    and integration step, drawn from ``(seed, 17)``.
    """
    from casep.units import G0

    rng = np.random.default_rng(seed)
    D = {**{f"ba_{a}": rng.normal(0, 1) for a in "xyz"}, **{f"sa_{a}": rng.normal(0, 200) for a in "xyz"},
         **{f"bg_{a}": rng.normal(0, 3) for a in "xyz"}, **{f"sg_{a}": rng.normal(0, 300) for a in "xyz"}}
    D.update(errors or {})
    ba = np.array([D[f"ba_{a}"] for a in "xyz"]) * 1e-3 * G0
    sa = np.array([D[f"sa_{a}"] for a in "xyz"]) * 1e-6
    bg = np.array([D[f"bg_{a}"] for a in "xyz"]) * DEGH
    sg = np.array([D[f"sg_{a}"] for a in "xyz"]) * 1e-6
    fs = math.radians(clip_dps)

    def rate(t):
        w = _ins_rate(t, growth)
        if spike is not None and abs(t - spike[0]) < 0.3:  # (1 - x^2)^2 bump, x = (t - t_s) / 0.3 s
            w[0] += math.radians(spike[1]) * (1 - ((t - spike[0]) / 0.3) ** 2) ** 2
        return w

    g = np.array([0.0, -G0, 0.0])
    h, n = 1 / (RATE * SUB), int(round(dur * RATE * SUB))
    wander = np.zeros((2 * n + 1, 6))  # the bias instability at the steps and their midpoints (index 2 t / h)
    if bias_noise is not None:
        from casep.simulation.noise import ar1_noise

        brng = np.random.default_rng([seed, 17])
        half = np.arange(2 * n + 1) * h / 2
        wander = np.column_stack([ar1_noise(half, bias_noise[0], bias_noise[2], brng),
                                  ar1_noise(half, bias_noise[1], bias_noise[2], brng)])
    at = [0]  # the index of the time the sensors are read at

    def gyro(w):
        return np.clip(w * (1 + sg) + bg + wander[at[0], 3:], -fs, fs)

    def integrated(w):
        return gyro(w) if integrates_clip else w * (1 + sg) + bg + wander[at[0], 3:]

    def accel(f):
        return f * (1 + sa) + ba + wander[at[0], :3]

    q = qi = _qexp(np.array([0.0, 0.0, 0.3]))
    v, vi = np.zeros(3), np.zeros(3)
    rows, truth_v = [], []
    for k in range(n + 1):
        t = k * h
        if k % SUB == 0:
            at[0] = 2 * k
            fb = _dcm(q).T @ (_ins_acc(t) - g)
            rows.append([t, *qi, *accel(fb), *gyro(rate(t)), *vi])
            truth_v.append([t, *v])
        if k == n:
            break
        tm = t + h / 2
        at[0] = 2 * k + 1
        wm = rate(tm)
        fbm = _dcm(_qmul(q, _qexp(wm * h / 2))).T @ (_ins_acc(tm) - g)
        qim = _qmul(qi, _qexp(integrated(wm) * h / 2))
        v = v + h * _ins_acc(tm)
        vi = vi + h * (_dcm(qim) @ accel(fbm) + g)
        q, qi = _qmul(q, _qexp(wm * h)), _qmul(qi, _qexp(integrated(wm) * h))
        q, qi = q / np.linalg.norm(q), qi / np.linalg.norm(qi)
    R, V = np.array(rows), np.array(truth_v)
    held = np.abs(R[:, 8:11]) >= fs * (1 - 1e-12)
    if imu_noise:
        R[:, 8:11] += np.where(held, 0.0, rng.normal(0, 1e-3, (R.shape[0], 3)))  # gyro noise off the rail
        R[:, 5:8] += rng.normal(0, 1e-2, (R.shape[0], 3))
    tel = {c: R[:, i] for i, c in enumerate(["t", "q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z", "w_x", "w_y",
                                              "w_z", "v_tel_x", "v_tel_y", "v_tel_z"])}
    tt = np.arange(0.0, dur + 1e-9, 1 / trk_rate)
    trk = {"t": tt, **{f"v_trk_{a}": np.interp(tt, V[:, 0], V[:, i + 1]) + (rng.normal(0, noise, tt.size) if noise
                                                                           else 0.0)
                       for i, a in enumerate("xyz")}}
    return tel, trk, D, held


@contextlib.contextmanager
def benchmark_module(name: str, prefix: str | None = None):
    """The module ``benchmarks/<name>.py``, loaded for a test; afterwards ``sys.path`` as it was and the modules it
    imported whose names start with `prefix` (default `name`) forgotten (a benchmark puts its folder on the path and
    imports its siblings)."""
    import importlib.util

    path, modules = list(sys.path), set(sys.modules)
    spec = importlib.util.spec_from_file_location(name, Path(__file__).resolve().parents[1] / "benchmarks"
                                                  / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    try:
        yield mod
    finally:
        sys.path[:] = path
        for other in set(sys.modules) - modules:
            if other.startswith(prefix or name):
                del sys.modules[other]
