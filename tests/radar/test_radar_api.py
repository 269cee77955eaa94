"""Radar measurements through :func:`casep.separate` (``radar=``, ``site=``, ``tracking_model=``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from test_radar import SITE, STATIONS, TRUTH

import casep
from casep.radar.stations import read_station
from casep.simulation.radar import simulate_radar, write_radar_simulation
from casep.units import ARCSEC
from casep.workflows.radar import RadarResult, separate_radar


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A small noisy two-station flight at 5 Hz (as test_radar's), written as the CLI reads it."""
    sim = simulate_radar(STATIONS, SITE, seed=3, telemetry_rate=5, radar_rate=5, tracking_truth=TRUTH)
    folder = tmp_path_factory.mktemp("radar_api")
    write_radar_simulation(sim, folder / "tel.csv")
    pairs = [(folder / f"tel.{s.name}.json", folder / f"tel.{s.name}.csv") for s in STATIONS]
    return folder / "tel.csv", pairs


def _same(a: RadarResult, b: RadarResult) -> None:
    assert isinstance(a, RadarResult) and a.result.names == b.result.names
    np.testing.assert_allclose(a.result.estimate, b.result.estimate, rtol=1e-12, atol=0)
    np.testing.assert_allclose(a.result.std, b.result.std, rtol=1e-12, atol=0)
    assert a.summary["noise"] == b.summary["noise"]


def test_separate_with_radar_is_separate_radar(files):
    tel, pairs = files
    got = casep.separate(str(tel), "platform36", "ols", radar=[(str(s), str(m)) for s, m in pairs], site=SITE)
    ref = separate_radar(tel, pairs, SITE, "platform36", "radar_biases", "ols")
    _same(got, ref)
    assert got.result.success and "S2.elevation_bias" in got.result.names
    # the estimate is not trivially the truth nor zero: the station terms within 5 std of what was injected
    j = got.result.names.index("S1.range_bias")
    assert abs(got.result.estimate[j] - TRUTH["S1"]["range_bias"]) < 5 * got.result.std[j]


def test_separate_with_radar_passes_stations_sigma_and_method_options(files):
    """A Station object in a pair, the noise given per station and type and a method option reach separate_radar."""
    tel, pairs = files
    sigma = {("S1", "range"): 3.0, ("S1", "azimuth"): 8.0 * ARCSEC, ("S1", "elevation"): 8.0 * ARCSEC}
    with warnings.catch_warnings():  # ridge's shrinkage leaves residuals above the given noise: said, not tested here
        warnings.simplefilter("ignore", casep.radar.regression.RadarResidualWarning)
        got = casep.separate(tel, "platform36", "ridge", radar=[(read_station(pairs[0][0]), pairs[0][1])], site=SITE,
                             tracking_model="radar_biases", sigma=sigma, options={"lam": 0.1})
        ref = separate_radar(tel, pairs[:1], SITE, "platform36", "radar_biases", "ridge", sigma=sigma,
                             options={"lam": 0.1})
    _same(got, ref)
    assert got.result.settings["lambda"] == 0.1
    assert [(g["station"], g["type"], g["source"]) for g in got.summary["noise"]] == [
        ("S1", "range", "given"), ("S1", "azimuth", "given"), ("S1", "elevation", "given")]


@pytest.mark.parametrize("kw", [{"denoise": "wavelet"}, {"wavelet_options": {"wavelet": "sym4"}},
                                {"outliers": 0.01}, {"exclude_outliers": 0.01},
                                {"std": "hac"}, {"sigma": 0.05}, {"fit_time_offset": True},
                                {"max_condition_index": 100.0}])
def test_options_that_do_not_apply_with_radar_are_refused_by_name(kw):
    (name, value), = kw.items()
    with pytest.raises(ValueError, match=rf"`{name}={value!r}` is not available with `radar`"):
        casep.separate("no_such_tel.csv", radar=[("S1.json", "S1.csv")], site=SITE, **kw)


def test_radar_needs_site_and_a_telemetry_file_and_site_needs_radar(files):
    tel, pairs = files
    with pytest.raises(ValueError, match=r"`radar` needs `site`, a casep.LaunchSite"):
        casep.separate(tel, radar=pairs)
    t = np.linspace(0.0, 10.0, 11)
    flight = casep.FlightData(t, np.tile([0.0, 9.8, 0.0], (t.size, 1)), np.zeros((t.size, 3)))
    with pytest.raises(ValueError, match=r"`flight` is a FlightData: with `radar` it is the telemetry file"):
        casep.separate(flight, radar=pairs, site=SITE)
    with pytest.raises(ValueError, match=r"`site` is used only with `radar`"):
        casep.separate(flight, site=SITE)
    with pytest.raises(ValueError, match=r"`tracking_model` is used only with `radar`"):
        casep.separate(flight, tracking_model="my_radar.py")
    # tau is the noise model's (per station and type), checked by its one rule before any file is read
    with pytest.raises(ValueError, match=r"option --tau \(`tau`\) must be a number in \(0, 1e4\] s"):
        casep.separate(tel, radar=pairs, site=SITE, tau=-5.0)


@pytest.mark.parametrize(("flags", "named"), [(["--exclude-outliers"], "--exclude-outliers"),
                                              (["--std", "hac"], "--std hac"),
                                              (["--wavelet", "sym4"], "--wavelet, --level"),
                                              (["--mat", "r.mat"], "--mat")])
def test_cli_refuses_through_the_same_list(tmp_path, capsys, flags, named):
    from casep.cli import main

    code = main(["separate", str(tmp_path / "tel.csv"), "--radar", "S1.json", "S1.csv", "--launch-site", "28.5",
                 "-80.6", "3", "90", "--launch-time", "0", *flags])
    assert code == 2
    err = capsys.readouterr().err
    assert f"{named}" in err and "is not available with --radar" in err
