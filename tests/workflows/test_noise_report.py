"""casep.workflows.noise_report.flight_noise: the Allan deviation of a flight's least-squares residuals."""

import dataclasses
import warnings

import numpy as np
import pytest

from casep.analysis.noise_id import identify_noise
from casep.model.loader import load_model
from casep.model.sv import build_sv
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


def test_a_gap_is_refused(paper20):
    keep = np.ones(paper20.t.size, bool)
    keep[100:140] = False  # 2 s of samples missing
    gappy = dataclasses.replace(paper20, t=paper20.t[keep], f=paper20.f[keep], dv=paper20.dv[keep], observed=None,
                                signals={})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError, match="uniform step"):
            flight_noise(gappy, load_model("platform36"))
