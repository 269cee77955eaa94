"""Wavelet de-noising (casep.noise.denoise)."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.exceptions import CasepWarning
from casep.noise.denoise import (
    EXTENSIONS,
    MODES,
    denoise,
    denoise_signal,
    extend,
    mad_sigma,
    max_level,
    select_threshold,
)


@pytest.mark.parametrize("n", [10, 33, 1000, 65536])
def test_sqtwolog_and_minimaxi_closed_forms(n):
    x = np.zeros(n)
    assert select_threshold(x, "sqtwolog") == pytest.approx(np.sqrt(2 * np.log(n)), rel=1e-15)
    expect = 0.3936 + 0.1829 * np.log(n) / np.log(2) if n > 32 else 0.0
    assert select_threshold(x, "minimaxi") == pytest.approx(expect, rel=1e-15)


def test_rigrsure_minimises_sure_directly(rng):
    x = np.concatenate([rng.standard_normal(300), rng.normal(0, 4, 30)])
    n = x.size

    def sure(t):  # Stein's unbiased risk of soft thresholding at t, unit variance
        return n - 2 * np.sum(np.abs(x) <= t) + np.sum(np.minimum(np.abs(x), t) ** 2)

    cands = np.sort(np.abs(x))
    best = cands[np.argmin([sure(t) for t in cands])]
    assert select_threshold(x, "rigrsure") == pytest.approx(best, rel=1e-12)


def test_heursure_follows_matlab_switch(rng):
    n = 4096
    crit = np.log2(n) ** 1.5 / np.sqrt(n)
    quiet = rng.standard_normal(n)  # eta ~ 0 < crit: universal
    quiet *= np.sqrt(n / (quiet @ quiet))  # exactly eta = 0
    assert select_threshold(quiet, "heursure") == pytest.approx(np.sqrt(2 * np.log(n)))
    loud = np.concatenate([rng.standard_normal(n - 200), rng.normal(0, 6, 200)])
    assert (loud @ loud - n) / n > crit
    expect = min(select_threshold(loud, "rigrsure"), np.sqrt(2 * np.log(n)))
    assert select_threshold(loud, "heursure") == pytest.approx(expect)


def test_bayes_threshold(rng):
    x = rng.normal(0, 2.0, 100_000)  # signal std sqrt(4 - 1) on unit noise
    assert select_threshold(x, "bayes") == pytest.approx(1 / np.sqrt(3.0), rel=0.02)
    assert select_threshold(np.array([0.1, -0.2, 0.05]), "bayes") == pytest.approx(0.2)  # sigma_x = 0: kill all


@pytest.mark.parametrize("extension", list(EXTENSIONS))
@pytest.mark.parametrize("mode", ["soft", "hard", "garrote"])
def test_zero_threshold_reconstructs_exactly(rng, extension, mode):
    x = np.cumsum(rng.standard_normal(1001))
    y, _ = denoise_signal(x, extension=extension, mode=mode, threshold=0.0)
    np.testing.assert_allclose(y, x, atol=1e-10)


@pytest.mark.parametrize("extension", list(EXTENSIONS))
def test_zero_noise_scale_keeps_signal(rng, extension):
    # A polynomial has (numerically) zero fine details with sym8: sigma_1 ~ 0, threshold 0.
    t = np.linspace(0, 1, 4096)
    x = 3 * t**2 - t + 0.5
    y, s = denoise_signal(x, extension=extension, level=5)
    assert s < 1e-9
    np.testing.assert_allclose(y, x, atol=1e-10)


def test_forced_keeps_only_the_approximation(rng):
    import pywt

    x = rng.standard_normal(2048)
    y, _ = denoise_signal(x, mode="forced", level=4, extension="periodic")
    c = pywt.wavedec(x, "sym8", mode="periodic", level=4)
    ref = pywt.waverec([c[0]] + [np.zeros_like(d) for d in c[1:]], "sym8", mode="periodic")[: x.size]
    np.testing.assert_allclose(y, ref, atol=1e-12)
    d = pywt.wavedec(y, "sym8", mode="periodization", level=4)
    assert np.abs(np.concatenate(d[1:])).max() < 0.6 * np.abs(np.concatenate(c[1:])).max()


def test_extension_modes_match_paper_formulas():
    c = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    N, L = c.size, 3
    zero = np.r_[np.zeros(L), c, np.zeros(L)]  # Eq. (10)
    periodic = np.r_[c[N - L:], c, c[:L]]  # Eq. (11)
    symmetric = np.r_[c[L - 1::-1], c, c[N - 1:N - L - 1:-1]]  # Eq. (12): boundary point repeated
    reflect = np.r_[c[L:0:-1], c, c[N - 2:N - L - 2:-1]]  # Eq. (13): about the boundary point
    for name, ref in (("zero", zero), ("periodic", periodic), ("symmetric", symmetric), ("reflect", reflect)):
        np.testing.assert_array_equal(extend(c, L, name), ref)


def test_mad_sigma_within_5_percent(rng):
    import pywt

    x = 0.37 * rng.standard_normal(200_000)
    d1 = pywt.wavedec(x, "sym8", level=1)[1]
    assert mad_sigma(d1) == pytest.approx(0.37, rel=0.05)


@pytest.mark.parametrize("rule", ["sqtwolog", "rigrsure", "heursure", "minimaxi", "bayes"])
def test_denoised_smooth_signal_is_closer_than_noise(rng, rule):
    t = np.linspace(0, 10, 8192)
    clean = np.sin(t) + 0.3 * np.cos(3.1 * t) + 0.05 * t**2
    noisy = clean + 0.1 * rng.standard_normal(t.size)
    y, s = denoise_signal(noisy, rule=rule)
    assert s == pytest.approx(0.1, rel=0.05)
    assert np.sqrt(np.mean((y - clean) ** 2)) < 0.5 * 0.1


def test_level_warning_and_default():
    x = np.random.default_rng(0).standard_normal(1000)
    top = max_level(1000, "sym8")
    with pytest.warns(CasepWarning, match=f"level {top + 2} exceeds {top}"):
        denoise_signal(x, level=top + 2)
    res = denoise(np.column_stack([x, x, x]))
    assert res.settings["level"] == top


def test_denoise_result_follows_the_result_protocol():
    import json

    from casep.results import Result

    x = np.random.default_rng(1).standard_normal((2048, 3)) * [0.1, 0.2, 0.3]
    res = denoise(x)
    assert isinstance(res, Result)
    data = json.loads(json.dumps(res.to_dict()))
    assert data["method"] == "wavelet" and data["level"] == res.settings["level"]
    assert [data["sigma"][a] for a in "xyz"] == pytest.approx([0.1, 0.2, 0.3], rel=0.1)
    text = res.text()
    assert "sym8" in text and f"z {res.sigma[2]:.4g}" in text and "2048 samples" in text


def test_bad_arguments():
    x = np.zeros((100, 3))
    for kw, msg in (({"wavelet": "nope"}, "`wavelet` must be a discrete"), ({"rule": "aic"}, "`rule` must be one of"),
                    ({"mode": "soft2"}, "`mode` must be one of"),
                    ({"extension": "smooth"}, "`extension` must be one of"),
                    ({"scaling": "x"}, "`scaling` must be one of"), ({"level": 0}, "`level` must be an int >= 1")):
        with pytest.raises(ValueError, match=msg):
            denoise(x, **kw)
    with pytest.raises(ValueError, match=r"`dv` must have shape \(N, 3\)"):
        denoise(np.zeros(10))
    assert set(MODES) == {"soft", "hard", "forced", "garrote"}


def test_separate_records_settings_and_uses_raw_sigma(platform36):
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=3, rate=20.0)
    res = casep.separate(sim.flight, "platform36", "ols", denoise="wavelet",
                         wavelet_options={"rule": "rigrsure", "extension": "reflect"})
    assert res.denoise["threshold_rule"] == "rigrsure" and res.denoise["extension"] == "reflect"
    assert set(res.denoise["sigma"]) == {"x", "y", "z"}
    assert 0.09 < res.sigma < 0.11  # the raw noise, not the ~0.005 m/s left after de-noising
    assert max(res.residual_rms.values()) < 0.05
    assert res.to_dict()["denoise"]["method"] == "wavelet"


@pytest.mark.montecarlo
def test_monte_carlo_denoising_does_not_help_ols(platform36):
    """Reduced form of benchmarks/mc_denoise.py: the claims of docs/results/denoising.md, at 20 Hz and 30 runs."""
    from casep.checks.diagnostics import crlb_covariance
    from casep.simulation.noise import NoiseModel
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper", seed=0, rate=20.0)
    t = sim.flight.t
    S = casep.build_sv(platform36, t, sim.flight.f)
    clean = S @ sim.truth
    k = platform36.index("Ka0y")
    out = {}
    for kind in ("white", "ar1"):
        noise = NoiseModel(kind, 0.1, tau=1.0 if kind == "ar1" else None)
        bound = np.sqrt(np.diag(crlb_covariance(S, 0.1, t=t if kind == "ar1" else None,
                                                tau=1.0 if kind == "ar1" else None)))
        rng = np.random.default_rng(2)
        raw, den, z = [], [], []
        for _ in range(30):
            y = clean + noise.sample(t, rng)
            r = casep.solve_ols(S, y)
            d = denoise(y)
            raw.append(r.estimate - sim.truth)
            den.append(casep.solve_ols(S, d.dv, sigma=float(np.sqrt(np.mean(d.sigma**2)))).estimate - sim.truth)
            z.append((r.estimate - sim.truth) / r.std)
        out[kind] = (np.sqrt(np.mean(np.square(raw), 0)) / bound, np.sqrt(np.mean(np.square(den), 0)) / bound,
                     np.sqrt(np.mean(np.square(z))))
    raw_w, den_w, z_w = out["white"]
    assert 0.8 < np.median(raw_w) < 1.2 and 0.8 < z_w < 1.2  # OLS reaches the CRLB, honest std
    assert np.median(den_w) > 0.95 * np.median(raw_w)  # de-noising does not help
    assert den_w[k] > 2.0 * raw_w[k]  # and hurts Ka0y (shrunk signal)
    raw_a, den_a, z_a = out["ar1"]
    assert 0.8 < np.median(raw_a) < 1.2  # OLS is near the Gauss-Markov (GLS) bound
    assert z_a > 3.0  # but its white-noise std is overconfident
