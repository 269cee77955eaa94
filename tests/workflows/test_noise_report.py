"""casep.workflows.noise_report.flight_noise: the Allan deviation of a flight's least-squares residuals."""

import dataclasses
import warnings

import numpy as np
import pytest

from casep.model.loader import load_model
from casep.model.sv import build_sv
from casep.noise.identification import identify_noise
from casep.simulation.simulate import simulate_flight
from casep.workflows.noise_report import flight_noise


@pytest.fixture(scope="module")
def paper20():
    return simulate_flight("paper", seed=4, rate=20.0).flight


def test_residuals_are_those_of_an_independent_least_squares_fit(paper20):
    """The identification equals identify_noise on the residuals of numpy's lstsq on S_V (same Allan deviation,
    same fits), and the paper's 0.1 m/s white noise is found white with s within 10 %."""
    model = load_model("platform36")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioned boost flight
        noise, problem = flight_noise(paper20, model)
    S = build_sv(model, paper20.t, paper20.f).reshape(-1, model.n_coefficients)  # (3N, n), rows x, y, z per sample
    y = paper20.dv.reshape(-1)
    scale = np.linalg.norm(S, axis=0)
    scale[scale == 0] = 1.0
    d, *_ = np.linalg.lstsq(S / scale, y, rcond=None)  # column-equilibrated: well posed in double precision
    r = (y - S @ (d / scale)).reshape(-1, 3)
    ref = identify_noise(r, float(np.median(np.diff(paper20.t))))
    np.testing.assert_allclose(noise.adev, ref.adev, rtol=1e-6)
    assert noise.choice == ref.choice == "white"
    assert abs(noise.fits["white"]["s"] / 0.1 - 1) < 0.1
    assert problem.source == paper20.source


def test_gaps_leave_the_longest_evenly_sampled_stretch(paper20):
    """A tracking dropout: the Allan deviation runs on the longest evenly sampled stretch (a GapWarning names
    it), equal to identify_noise on the least-squares residuals of that stretch; white noise stays white."""
    from casep.estimators.ols import solve_ols
    from casep.exceptions import GapWarning

    keep = np.ones(paper20.t.size, bool)
    keep[100:140] = False  # 2 s of samples missing: the stretch after it is the longest
    gappy = dataclasses.replace(paper20, t=paper20.t[keep], f=paper20.f[keep], dv=paper20.dv[keep], observed=None,
                                signals={})
    model = load_model("platform36")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioned boost flight
        warnings.simplefilter("always", GapWarning)
        # two GapWarnings: S_V's (integrated across the gap by the trapezoid rule) and the noise report's stretch
        with pytest.warns(GapWarning, match=r"`t` has 1 gap\(s\) longer than 10x the median step 0\.05 s \(largest "
                                            r"2\.05 s before sample 101, t = 7 s\)"), \
                pytest.warns(GapWarning, match=r"longest evenly sampled stretch, t = 7 \.\. .* \(\d+ of \d+ samples\)"):
            noise, problem = flight_noise(gappy, model)
        r = problem.residuals(solve_ols(problem).estimate).reshape(-1, 3)[100:]
    ref = identify_noise(r, float(np.median(np.diff(gappy.t))))
    np.testing.assert_allclose(noise.adev, ref.adev, rtol=1e-12)
    assert noise.choice == "white"


def test_uneven_steps_other_than_gaps_are_refused(paper20):
    t = paper20.t.copy()
    t[200:] -= 0.5 * (t[1] - t[0])  # one step of half the sample interval: not a dropout
    uneven = dataclasses.replace(paper20, t=t, signals={})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError, match="uniform step"):
            flight_noise(uneven, load_model("platform36"))
