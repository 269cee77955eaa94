"""Is a window's std too small because its noise model misses low-frequency power? Measured on the residuals.

Runs ``car_drive.py`` (same arguments) with a hook on :func:`casep.workflows.imu_separate.with_imu_noise` that keeps,
for each window's last pass, the rows' times, the GLS estimators ``A`` (n, 3N) of the pass, the design ``S``, the
pass's rows ``y``, the noise the std were formed with (``Sigma = Sigma_track(refit) + Sigma_imu``, dense: 3N = 360)
and the tau profile's extra covariance (:func:`casep.workflows.imu_separate.tau_spread`, which the raw-IMU path adds
and the strapdown telemetry path does not). Then, pooled over the windows, with the fit's absorption of the noise
taken into account exactly (the residuals ``e = M y``, ``M = I - S A``, have ``E e e^T = M Sigma M^T`` under the
stated noise, whatever it is):

* the residuals' Allan variance per axis at 0.5-10 s against its expectation under the stated noise;
* a model-free (HAC, Bartlett) variance of each coefficient from the residuals' influence series ``u_k = A_k e_k``
  with a bandwidth of 2.5-10 s, against the same HAC's expectation under the stated noise: the ratio is how much
  more (or less) power the residuals have, along what each estimator weighs, than the stated noise gives them;
* casep's std against the std with the tau profile's spread.

    OPENBLAS_NUM_THREADS=1 python benchmarks/car_drive_noise.py --imu-time uniform --velocity positions \\
        --imu-clock arrivals --imu-shift -0.245 --noise-out noise.pkl
    OPENBLAS_NUM_THREADS=1 python benchmarks/car_drive_noise.py --simulate 1 --noise-out twin_noise.pkl
    python benchmarks/car_drive_noise.py --read noise.pkl
"""

from __future__ import annotations

import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

RECORDS: list[dict] = []
#: ``--pool-instability TAU``: each record also holds the IMU's bias instability of that correlation time per unit
#: variance (:func:`casep.checks.tracking_quality.imu_bias_effect`), which ``--compare`` sizes pooled over the windows
POOL_TAU: list[float] = []
#: the pooled scan's grids: the instability's stationary std (mg, deg/h) and the tracking part's scale
POOL_MG = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
POOL_DEGH = (0.0, 5.0, 10.0, 20.0, 30.0, 50.0, 75.0, 100.0, 150.0, 200.0, 300.0)
POOL_KT = (0.71, 1.0, 1.41)
TAUS_S = (0.5, 1.0, 2.5, 5.0, 10.0)
BANDWIDTHS_S = (0.0, 2.5, 5.0, 10.0)
#: the tracking noise's part of the covariance scaled by these: the residuals' Allan excess at 5-10 s (3), and the
#: std of a REML fit on a 20 s record found 1.30 times too small by ``benchmarks/mc_short_window.py`` (1.69)
TRACKING_FACTORS = (1.69, 3.0)


def _record(res, problem, flight, out) -> None:
    """What the analysis needs from one pass (module notes)."""
    from casep.checks.tracking_quality import imu_noise_states
    from casep.noise.known import tracking_covariance_times
    from casep.noise.model import NoiseModel
    from casep.workflows.row_estimators import combination_estimators, tau_spread

    imu = (out.diagnostics.get("noise") or {}).get("imu") if out is not res else None
    if imu is None or imu.get("tracking_noise") is None or problem.t is None:
        return
    t = np.asarray(problem.t, float)
    N, n = t.size, len(res.names)
    A = combination_estimators(np.eye(n), np.ones(n), res, problem)
    S = problem.sv().reshape(3 * N, n)
    y = np.asarray(problem.y, float).reshape(3 * N)
    refit = NoiseModel.from_dict(imu["tracking_noise"])
    Sig_trk = tracking_covariance_times(np.eye(3 * N).reshape(N, 3, 3 * N), t, refit).reshape(3 * N, 3 * N)
    known = imu_noise_states(flight, t)
    Sig_imu = known.dense()
    try:
        import warnings

        from casep.noise.fit import tau_profile

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            spread = tau_spread(A, problem, tau_profile(problem))
    except ValueError:
        spread = np.full((n, n), np.nan)
    rec = {"t": t, "names": list(res.names), "A": A, "S": S, "y": y, "Sig_trk": Sig_trk, "Sig_imu": Sig_imu,
           "cov": np.asarray(out.covariance, float), "spread": spread, "t0": float(flight.t[0])}
    if POOL_TAU:  # the IMU's bias instability per unit variance, accelerometers' and gyros' (dense: 3N = 360)
        from casep.checks.tracking_quality import imu_bias_effect

        G_a, G_g = imu_bias_effect(flight, t, np.eye(3 * N), POOL_TAU[0])
        rec.update({"Sig_a": G_a @ G_a.T, "Sig_g": G_g @ G_g.T, "pool_tau": POOL_TAU[0]})
    RECORDS.append(rec)


def _install() -> None:
    import casep.workflows.imu_separate as ims

    original = ims.with_imu_noise

    def hooked(res, problem, flight, *args, **kw):
        out = original(res, problem, flight, *args, **kw)
        _record(res, problem, flight, out)
        return out

    ims.with_imu_noise = hooked


def _allan_matrix(N: int, m: int) -> np.ndarray:
    """Q (N, N) with ``x^T Q x`` the Allan variance of the series x at blocks of m samples (non-overlapping)."""
    K = N // m
    B = np.zeros((K, N))
    for k in range(K):
        B[k, k * m:(k + 1) * m] = 1.0 / m
    D = B[1:] - B[:-1]
    return D.T @ D / (2.0 * (K - 1))


def _bartlett(N: int, L: int) -> np.ndarray:
    lag = np.abs(np.subtract.outer(np.arange(N), np.arange(N)))
    return np.clip(1.0 - lag / (L + 1.0), 0.0, None)


def hac(w: dict, L: float) -> tuple[np.ndarray, np.ndarray]:
    """The HAC (Bartlett, bandwidth `L` s) covariance of a window's coefficients from its residuals, and its
    expectation under the stated noise, both (n, n): ``sum_jk A_j e_j W_jk e_k A_k^T`` with ``W_jk`` the weight of
    the lag between the epochs of rows j and k, and the same with ``e_j e_k`` replaced by ``R_jk``, ``R = M Sigma M^T``
    the residuals' covariance under the stated noise (``M = I - S A``: the fit's absorption, exactly)."""
    t, A, S, y = w["t"], w["A"], w["S"], w["y"]
    N = t.size
    h = float(np.median(np.diff(t)))
    M = np.eye(3 * N) - S @ A
    e = M @ y
    R = M @ (w["Sig_trk"] + w["Sig_imu"]) @ M.T
    Wfull = np.kron(_bartlett(N, int(round(L / h))), np.ones((3, 3)))  # the weight of a pair of rows: their lag
    Ae = A * e
    return Ae @ Wfull @ Ae.T, A @ (Wfull * R) @ A.T


def analyse(windows: list[dict], truth: dict | None = None) -> None:
    """The pooled figures of the module notes over `windows` (each the last pass's record of a window)."""
    h = float(np.median(np.diff(windows[0]["t"])))
    allan_obs = {(a, tau): 0.0 for a in range(3) for tau in TAUS_S}
    allan_exp = dict(allan_obs)
    names = windows[0]["names"]
    n = len(names)
    hac_obs = {L: np.zeros(n) for L in BANDWIDTHS_S}
    hac_exp = {L: np.zeros(n) for L in BANDWIDTHS_S}
    std_ratio = []
    per_window = []
    for w in windows:
        N = w["t"].size
        A, S, y = w["A"], w["S"], w["y"]
        M = np.eye(3 * N) - S @ A
        e = M @ y
        Sig = w["Sig_trk"] + w["Sig_imu"]
        R = M @ Sig @ M.T
        for tau in TAUS_S:
            m = max(1, int(round(tau / h)))
            if N // m < 3:
                continue
            Q = _allan_matrix(N, m)
            for a in range(3):
                ea, Ra = e[a::3], R[a::3, a::3]
                allan_obs[(a, tau)] += float(ea @ Q @ ea)
                allan_exp[(a, tau)] += float(np.sum(Q * Ra))
        row = []
        for L in BANDWIDTHS_S:
            obs, exp = hac(w, L)
            hac_obs[L] += np.diag(obs)
            hac_exp[L] += np.diag(exp)
            row.append(np.diag(obs) / np.diag(exp))
        per_window.append((w["t0"], row))
        cov = w["cov"]
        std_ratio.append(np.sqrt((np.diag(cov) + np.diag(w["spread"])) / np.diag(cov)))
    print(f"{len(windows)} windows, rows every {h:.3f} s; under the stated noise (Sigma_track refit + Sigma_imu), "
          "the fit's absorption included exactly")
    print("residuals' Allan variance, observed / expected, per axis (pooled):")
    for tau in TAUS_S:
        print(f"  tau {tau:5.1f} s: " + "  ".join(
            f"{'xyz'[a]} {allan_obs[(a, tau)] / allan_exp[(a, tau)]:.2f}" for a in range(3) if allan_exp[(a, tau)] > 0))
    print("HAC variance of each coefficient from the residuals, observed / expected under the stated noise (pooled; "
          "the square root is the factor the std would need):")
    print("  bandwidth " + "  ".join(f"{nm:>8s}" for nm in names))
    for L in BANDWIDTHS_S:
        print(f"  {L:5.1f} s   " + "  ".join(f"{v:8.2f}" for v in hac_obs[L] / hac_exp[L]))
    print("  per window, bandwidth 5 s, the six biases (observed / expected):")
    bias = [i for i, nm in enumerate(names) if nm.startswith(("ba_", "bg_"))]
    for t0, row in per_window:
        print(f"    {t0:6.1f}: " + " ".join(f"{row[2][i]:6.2f}" for i in bias))
    sr = np.array(std_ratio)
    print("std with the tau profile's spread / std without it, per coefficient, median and largest over the windows:")
    print("  " + ", ".join(f"{nm} {np.nanmedian(sr[:, i]):.2f} / {np.nanmax(sr[:, i]):.2f}"
                           for i, nm in enumerate(names)))


def restricted_scan(windows: list[dict], k_trk: np.ndarray, k_imu: np.ndarray) -> np.ndarray:
    """``-2 l_R`` (Gaussian restricted likelihood of each window's rows, summed over `windows`) on the grid of the
    rows' covariance ``k_t Sigma_track + k_i Sigma_imu`` (the stated noise: k_t = k_i = 1), shape (k_trk, k_imu): how
    the windows' own rows weigh the two parts (the IMU's density measured on the pad, the tracking noise refitted
    beside it). ``-2 l_R = ln det Sigma + ln det(Z^T Sigma^-1 Z) + y^T P y``, ``Z`` an orthonormal basis of ``S``."""
    out = np.zeros((k_trk.size, k_imu.size))
    for r in windows:
        U, s, _ = np.linalg.svd(r["S"], full_matrices=False)
        Z, y = U[:, s > s[0] * 1e-10], r["y"]
        for a, kt in enumerate(k_trk):
            for b, ki in enumerate(k_imu):
                C = np.linalg.cholesky(kt * r["Sig_trk"] + ki * r["Sig_imu"])
                Zw, yw = np.linalg.solve(C, Z), np.linalg.solve(C, y)
                Cg = np.linalg.cholesky(Zw.T @ Zw)
                q = np.linalg.solve(Cg, Zw.T @ yw)
                out[a, b] += 2 * np.sum(np.log(np.diag(C))) + 2 * np.sum(np.log(np.diag(Cg))) + yw @ yw - q @ q
    return out


def instability_scan(windows: list[dict]) -> tuple[np.ndarray, tuple]:
    """``-2 l_R`` of the windows' rows (pooled, as :func:`restricted_scan`) over ``k_t Sigma_track + Sigma_imu +
    q_a Sigma_a + q_g Sigma_g`` on the grids POOL_KT x POOL_MG x POOL_DEGH: one bias instability for the whole drive,
    its size from every window's rows at once (each window's own tracking refit scaled by k_t, not refitted)."""
    from casep.units import G0

    q_a = (np.array(POOL_MG) * 1e-3 * G0) ** 2
    q_g = np.radians(np.array(POOL_DEGH) / 3600.0) ** 2
    out = np.zeros((len(POOL_KT), q_a.size, q_g.size))
    for r in windows:
        U, s, _ = np.linalg.svd(r["S"], full_matrices=False)
        Z, y = U[:, s > s[0] * 1e-10], r["y"]
        for a, kt in enumerate(POOL_KT):
            for b, qa in enumerate(q_a):
                for c, qg in enumerate(q_g):
                    C = np.linalg.cholesky(kt * r["Sig_trk"] + r["Sig_imu"] + qa * r["Sig_a"] + qg * r["Sig_g"])
                    Zw, yw = np.linalg.solve(C, Z), np.linalg.solve(C, y)
                    Cg = np.linalg.cholesky(Zw.T @ Zw)
                    q = np.linalg.solve(Cg, Zw.T @ yw)
                    out[a, b, c] += (2 * np.sum(np.log(np.diag(C))) + 2 * np.sum(np.log(np.diag(Cg))) + yw @ yw
                                     - q @ q)
    best = np.unravel_index(np.argmin(out), out.shape)
    return out, (POOL_KT[best[0]], q_a[best[1]], q_g[best[2]], best)


def compare(run_path: str, noise_path: str) -> None:
    """The windows' comparison of ``car_drive_windows.py`` (six biases, the left-out terms, the instability at rest and
    the horizontal accelerometers'), with each window's covariance as stated and as the residuals say (module notes)."""
    import types

    from car_drive import LEFT_OUT_STD, left_out_covariance
    from car_drive_windows import HORIZONTAL_AT_REST, INSTABILITY_AT_REST, SIX

    from casep.workflows.row_estimators import relative_positive_part
    from casep.workflows.windows import consider_rows, window_consistency

    run = pickle.load(open(run_path, "rb"))
    recs = pickle.load(open(noise_path, "rb"))["windows"]
    ok = [w for w in run["windows"] if w["success"]]
    pairs: list[tuple[dict, dict]] = []
    for w in ok:
        r = min(recs, key=lambda r: abs(r["t0"] - w["t_start"]))
        # the result's covariance is the record's plus what the iteration adds after it (its curvature): a few %
        same = abs(r["t0"] - w["t_start"]) < 1.0 and np.allclose(np.diag(r["cov"]), np.diag(w["covariance"]),
                                                                  rtol=0.1, atol=0)
        if not same:  # the iteration's last pass is not the record's: left out, said
            print(f"window {w['t_start']:.1f}: no noise record with its std within 10 %: left out")
            continue
        pairs.append((w, r))
    names = tuple(ok[0]["names"])
    analyse([r for _, r in pairs])
    print(f"{len(pairs)} windows that succeeded, each matched to its last pass's noise record (its std within 10 %)")
    pooled = {}
    for L in BANDWIDTHS_S:
        o, e = zip(*(hac(r, L) for _, r in pairs))
        pooled[L] = np.sqrt(np.sum([np.diag(x) for x in o], axis=0) / np.sum([np.diag(x) for x in e], axis=0))
        print(f"  pooled HAC std factor, bandwidth {L:4.1f} s: " + ", ".join(
            f"{n} {v:.2f}" for n, v in zip(names, pooled[L]) if n in SIX))
    both = {**INSTABILITY_AT_REST, **HORIZONTAL_AT_REST}

    def windows(cov_of) -> list:
        out = []
        for w, r in pairs:
            res = types.SimpleNamespace(names=names, estimate=w["estimate"], covariance=cov_of(w, r), success=True)
            out.append(types.SimpleNamespace(result=res, sv_end=w["sv_end"], sv_names=tuple(w["sv_names"]), raw=w,
                                             t_start=w["t_start"], consider_gain=w.get("consider_gain"),
                                             consider_names=tuple(w.get("consider_names", ()))))
        return out

    def scaled(f: np.ndarray):
        return lambda w, r: w["covariance"] * np.outer(f, f)

    def own(L: float):
        def cov(w, r):
            o, e = hac(r, L)
            return w["covariance"] + relative_positive_part(o - e, w["covariance"])
        return cov

    cases = [("as stated", lambda w, r: w["covariance"]),
             ("with the tau profile's spread (tau_spread)", lambda w, r: w["covariance"] + r["spread"])]
    cases += [(f"scaled by the pooled HAC factor, {L:g} s", scaled(pooled[L])) for L in BANDWIDTHS_S[1:]]
    cases += [(f"plus each window's own HAC excess, {L:g} s", own(L)) for L in BANDWIDTHS_S[1:]]

    def tracking_times(k: float):
        return lambda w, r: w["covariance"] + (k - 1.0) * r["A"] @ r["Sig_trk"] @ r["A"].T

    cases += [(f"the tracking noise's part times {k:g}", tracking_times(k)) for k in TRACKING_FACTORS]
    k_trk, k_imu = 2.0 ** np.arange(-2.0, 2.01, 0.5), 2.0 ** np.arange(-4.0, 3.01, 1.0 / 3.0)
    scan = restricted_scan([r for _, r in pairs], k_trk, k_imu)
    a, b = np.unravel_index(np.argmin(scan), scan.shape)
    prof = scan.min(axis=0) - scan.min()
    stated = scan[np.argmin(abs(k_trk - 1)), np.argmin(abs(k_imu - 1))]
    inside = k_imu[prof < 3.841]
    print(f"  restricted likelihood of the windows' rows (pooled) over k_t Sigma_track + k_i Sigma_imu: best k_t "
          f"{k_trk[a]:.2f}, k_i {k_imu[b]:.2f} (k_i's profile 95 % interval {inside.min():.2f}-{inside.max():.2f}); "
          f"-2 l_R at the stated noise (1, 1) {stated - scan.min():.1f} above the best")

    def scaled_parts(kt: float, ki: float):
        return lambda w, r: w["covariance"] + r["A"] @ ((kt - 1.0) * r["Sig_trk"] + (ki - 1.0) * r["Sig_imu"]
                                                       ) @ r["A"].T

    cases += [(f"each part scaled by the pooled restricted likelihood's best (k_t {k_trk[a]:.2f}, k_i {k_imu[b]:.2f})",
               scaled_parts(k_trk[a], k_imu[b]))]
    if all("Sig_a" in r for _, r in pairs):
        grid, (kt, qa, qg, idx) = instability_scan([r for _, r in pairs])
        low = grid - grid.min()
        ok_mg = [POOL_MG[i] for i in range(len(POOL_MG)) if low[:, i, :].min() < 3.841]
        ok_dh = [POOL_DEGH[i] for i in range(len(POOL_DEGH)) if low[:, :, i].min() < 3.841]
        none = grid[POOL_KT.index(1.0), 0, 0] - grid.min()
        print(f"  the IMU's bias instability (tau {pairs[0][1]['pool_tau']:g} s) pooled over the windows' rows by "
              f"their restricted likelihood: accelerometers {POOL_MG[idx[1]]:g} mg "
              f"(95 %: {min(ok_mg):g}-{max(ok_mg):g}), "
              f"gyros {POOL_DEGH[idx[2]]:g} deg/h (95 %: {min(ok_dh):g}-{max(ok_dh):g}), tracking part x {kt:g}; "
              f"-2 l_R {none:.1f} better than without it (k_t 1)")

        def with_instability(kt: float, qa: float, qg: float):
            return lambda w, r: w["covariance"] + r["A"] @ ((kt - 1.0) * r["Sig_trk"] + qa * r["Sig_a"]
                                                           + qg * r["Sig_g"]) @ r["A"].T

        cases += [(f"with the pooled bias instability ({POOL_MG[idx[1]]:g} mg, {POOL_DEGH[idx[2]]:g} deg/h, tracking "
                   f"part x {kt:g})", with_instability(kt, qa, qg))]
        hi_a = max(ok_mg) * 1e-3 * 9.80665
        hi_g = np.radians(max(ok_dh) / 3600.0)
        cases += [(f"with the bias instability at its 95 % upper ends ({max(ok_mg):g} mg, {max(ok_dh):g} deg/h)",
                   with_instability(1.0, hi_a**2, hi_g**2))]
    share = np.array([np.diag(r["A"] @ r["Sig_imu"] @ r["A"].T) / np.diag(r["A"] @ (r["Sig_trk"] + r["Sig_imu"])
                                                                          @ r["A"].T) for _, r in pairs])
    six = [names.index(n) for n in SIX]
    print("  the IMU noise's share of each bias's stated variance, median (least) over the windows: " + ", ".join(
        f"{names[i]} {np.median(share[:, i]):.2f} ({share[:, i].min():.2f})" for i in six))
    for label, cov_of in cases:
        ws = windows(cov_of)
        line = [f"  {label}: plain chi2 {window_consistency(ws, SIX)['chi2']:.1f}"]
        if ws[0].consider_gain is not None:
            held = [k for k, n in enumerate(ws[0].consider_names) if n in LEFT_OUT_STD]
            P_c = left_out_covariance([ws[0].consider_names[k] for k in held])
            rows = [g[:, held] for g in consider_rows(ws, SIX)]
            c = window_consistency(ws, SIX, instability=both, consider=(rows, P_c))
            line.append(f"with the left-out terms and the instabilities at rest {c['chi2']:.1f} on {c['dof']} dof, "
                        f"p = {c['p_value']:.2g}, within 1 / 2 std {c['within_1_std']:.2f} / {c['within_2_std']:.2f}")
            if label == "as stated" or "bias instability" in label:
                # the instability in motion stands for the bias movement between windows the one at rest stood for
                c = window_consistency(ws, SIX, consider=(rows, P_c))
                line.append(f"with the left-out terms only {c['chi2']:.1f} on {c['dof']} dof, p = {c['p_value']:.2g}, "
                            f"within 1 / 2 std {c['within_1_std']:.2f} / {c['within_2_std']:.2f}")
        print("; ".join(line))


def main() -> None:
    if len(sys.argv) > 3 and sys.argv[1] == "--compare":
        compare(sys.argv[2], sys.argv[3])
        return
    if len(sys.argv) > 2 and sys.argv[1] == "--read":
        with open(sys.argv[2], "rb") as fh:
            d = pickle.load(fh)
        analyse(d["windows"], d.get("truth"))
        return
    if "--pool-instability" in sys.argv:
        k = sys.argv.index("--pool-instability")
        POOL_TAU.append(float(sys.argv[k + 1]))
        del sys.argv[k:k + 2]
    out = None
    if "--noise-out" in sys.argv:
        k = sys.argv.index("--noise-out")
        out = sys.argv[k + 1]
        del sys.argv[k:k + 2]
    _install()
    import car_drive

    car_drive.main()
    # the last record of each window (its last pass): records are in order, a window's t0 is its start
    last: dict[float, dict] = {}
    for r in RECORDS:
        last[round(r["t0"], 3)] = r
    windows = list(last.values())
    if out:
        with open(out, "wb") as fh:
            pickle.dump({"windows": windows}, fh)
        print("saved", out)
    analyse(windows)


if __name__ == "__main__":
    main()
