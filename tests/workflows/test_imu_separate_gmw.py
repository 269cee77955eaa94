"""Raw-IMU separation under Gauss-Markov plus white tracking noise: the combinations stated hold their std.

A 20 s rail launch at 10 Hz (6 s on the pad, 6 g for 10 s, a roll programme) with ``strapdown15_axial`` errors drawn
at their declared magnitudes, tracked at 5 Hz with Gauss-Markov (0.05 m/s, tau 1 s) plus white (0.03 m/s) noise:
the usual radar or GNSS mixture, on a flight short enough that the noise model is hard to tell from the data. The
full-size Monte Carlo is ``benchmarks/mc_imu_gmw_combinations.py``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.frames import LaunchSite
from casep.io.files import write_table
from casep.navigation import ImuData, check_imu, navigate
from casep.simulation.noise import ar1_noise, white_noise
from casep.simulation.strapdown import rail_launch, with_drawn_errors
from casep.workflows.imu_separate import separate_imu

SITE = LaunchSite(28.46, -80.53, 3.0, 95.0, 6.0)  # lift-off at t = 6 s
ALIGN, HEADING, MODEL = (0.0, 5.5), 95.0, "strapdown15_axial"
#: Tracking noise per axis: Gauss-Markov std (m/s) and correlation time (s), white std (m/s).
GM_STD, GM_TAU, WHITE_STD = 0.05, 1.0, 0.03


@pytest.fixture(scope="module")
def launch():
    """The clean record ``t, w, f`` and its navigation (the truth)."""
    t = np.round(np.arange(0.0, 20.0, 0.1), 10)
    w, f = rail_launch(SITE, t, elevation_deg=84.0, boost_g=6.0, burn_s=10.0, coast_g=-0.3, roll=(1.5, 3.0))
    return t, w, f, navigate(check_imu(ImuData(t, w, f)), SITE, ALIGN, heading_deg=HEADING)


def flight(directory, launch, seed: int):
    """IMU and tracking files of the launch with errors drawn at the declared magnitudes (`seed`) and the tracking
    noise drawn after them; returns (imu, tracking, truth in declared magnitudes)."""
    t, w, f, nav = launch
    rng = np.random.default_rng(seed)
    w_m, f_m, z = with_drawn_errors(casep.load_model(MODEL), nav.q, w, f, t, rng)
    imu, trk = directory / f"imu{seed}.csv", directory / f"trk{seed}.csv"
    write_table(imu, {"t": t, **{f"w_{a}": w_m[:, i] for i, a in enumerate("xyz")},
                      **{f"fb_{a}": f_m[:, i] for i, a in enumerate("xyz")}})
    k = slice(None, None, 2)
    v = nav.v[k] + ar1_noise(t[k], GM_STD, GM_TAU, rng) + white_noise(t[k].size, WHITE_STD, rng)
    write_table(trk, {"t": t[k], **{f"v_trk_{a}": v[:, i] for i, a in enumerate("xyz")}})
    return imu, trk, z


def test_the_combinations_stated_hold_their_std_under_gauss_markov_plus_white_tracking(launch, tmp_path):
    """Seeds 1 and 3 (seeds 0-11: ``benchmarks/mc_imu_gmw_combinations.py``), the default fit: every result a
    success stating combinations, each within 4 of its std of the truth, and their z pooled (6 each) with an RMS of
    at most 1.75: 12 independent unit normals exceed it with probability 2.5e-4 (the z of one seed are correlated,
    which widens the RMS's spread; measured 0.80 and 0.60).

    Before the passes far from convergence judged the instrument's plausible size by std that carry the tracking
    noise's correlation (:func:`casep.workflows.imu_separate.determined_step`), their white std (2.2 to 2.6 times
    too small here) made noise look like evidence of errors of ~90 declared magnitudes, the passes linearised that far
    from the truth, and seed 1 stated combinations 13.6 and 27.4 std off (seed 5: 5.8; pooled RMS z of seeds 0-5:
    5.5). With the plug-in noise model seeds 0-11 (the benchmark) gave a pooled RMS of 1.45, 87 % within 1.96 std;
    with the correlation times' uncertainty in the std (next test) 0.88, 94 %. The bounds fail the defect by an
    order of magnitude (|z| < 4 fails its seed 1 alone; seeds 0-3 here gave 21 z, RMS 0.56)."""
    z = []
    for seed in (1, 3):
        zs = _stated_z(tmp_path, launch, seed)
        assert np.all(np.abs(zs) < 4.0), (seed, zs)
        z.append(zs)
    rms = float(np.sqrt(np.mean(np.concatenate(z) ** 2)))
    assert rms <= 1.75, rms


def test_the_correlation_times_uncertainty_is_in_the_std_of_the_combinations_stated(launch, tmp_path):
    """Seeds 8 and 10 of the benchmark, where REML's noise model is far from the truth on 100 epochs per axis: seed 8
    took white noise on an axis (likelihood ratio 1.6), seed 10 white on one (5.4) and tau 5.7 s on another (truth 1
    s everywhere). Under the plug-in model their best-determined combination was 4.1 and 5.6 std off the truth
    (under the true noise model the same estimator's std are 2.5 times wider: 2.6 and 2.2 std). With the
    correlation times' profile likelihood in the std (:func:`casep.workflows.imu_separate.tau_spread`) every
    combination stated is within 3 std, and the z is no longer the plug-in one."""
    for seed in (8, 10):
        zs = _stated_z(tmp_path, launch, seed)
        assert np.all(np.abs(zs) < 3.0), (seed, zs)


def _stated_z(tmp_path, launch, seed: int) -> np.ndarray:
    """The seed's flight separated with the defaults (a success, some combination stated), and each stated
    combination's (estimate - truth) / std."""
    imu, trk, truth = flight(tmp_path, launch, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning, what the record leaves undetermined: said by the result
        out = separate_imu(imu, trk, SITE, ALIGN, MODEL, heading_deg=HEADING)
    assert out.success, (seed, out.message)
    combos = out.result.diagnostics["determined"]["combinations"]
    assert combos, seed
    return np.array([(c["estimate"] - np.dot(c["weights"], truth)) / c["std"] for c in combos])
