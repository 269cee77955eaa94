"""A clock drift stated by the user (``clock_drift``, ppm; CLI ``--clock-drift``, manifest ``clock_drift_ppm``):
the tracking time tags taken to the telemetry's scale by ``t = (T - time_shift) / (1 + eps)``
(casep.io.pair.telemetry_time), in the sign the clock-drift checks report (a late tag ``eps t``: ``dv = a eps t``)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import casep
from casep.cli import main
from casep.io.pair import telemetry_time, tracking_time
from casep.io.provenance import flight_provenance

EPS_PPM = 1000.0  # 80 ms over the 80 s flight: far beyond the interpolation's rounding


def _v(t):
    """A smooth velocity, m/s (a cubic, a line and a slow sine: cubic splines at 100 Hz hold it to ~1e-9)."""
    return np.column_stack([0.02 * t**3, 40.0 * t, 3.0 * np.sin(0.2 * t)])


def _a(t):
    return np.column_stack([0.06 * t**2, np.full_like(t, 40.0), 0.6 * np.cos(0.2 * t)])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Telemetry at 100 Hz on its own clock; tracking at 10 Hz whose tags run ``EPS_PPM`` fast from a 43200 s
    shift: the fix of the instant at telemetry time ``t`` is tagged ``T = 43200 + t (1 + eps)``."""
    d = tmp_path_factory.mktemp("drift")
    t = np.arange(0.0, 80.0 + 1e-9, 0.01)
    f = _a(t)
    tel = pd.DataFrame({"t": t, **{f"f_{a}": f[:, i] for i, a in enumerate("xyz")},
                        **{f"v_tel_{a}": _v(t)[:, i] for i, a in enumerate("xyz")}})
    tt = np.arange(0.5, 79.5, 0.1)  # the fixes' instants, telemetry scale
    T = tracking_time(tt, 43200.0, EPS_PPM)
    trk = pd.DataFrame({"t": T, **{f"v_trk_{a}": _v(tt)[:, i] for i, a in enumerate("xyz")}})
    tel.to_csv(d / "tel.csv", index=False)
    trk.to_csv(d / "trk.csv", index=False)
    return d / "tel.csv", d / "trk.csv"


def test_the_time_maps_are_inverse_and_closed_form():
    T = np.array([43200.0, 43250.0, 43290.5])
    t = telemetry_time(T, 43200.0, 104.0)
    assert t == pytest.approx((T - 43200.0) / (1.0 + 104e-6), rel=0, abs=1e-12)
    assert tracking_time(t, 43200.0, 104.0) == pytest.approx(T, rel=0, abs=1e-9)
    assert telemetry_time(T, 43200.0) == pytest.approx(T - 43200.0, rel=0, abs=0)  # no drift: the shift alone


def test_a_stated_drift_takes_the_late_tags_out(files):
    """Read as one rate, the pair's dv is the late tag's ``a eps t`` (the checks' sign: 80 ms late at 80 s, up
    to 30 m/s here); with the drift stated, the exact pair's dv is the interpolation's rounding."""
    tel, trk = files
    raw = casep.read_flight_pair(tel, trk, time_shift=43200.0)
    obs = np.asarray(raw.observed)
    t = raw.t[obs]
    expected = _a(t) * (EPS_PPM * 1e-6 * t)[:, None]  # dv = v(t) - v(t - eps t) ~ a eps t
    assert np.max(np.abs(raw.dv[obs] - expected)) < 2e-3 * np.max(np.abs(expected)), "not the late tag's a eps t"
    fixed = casep.read_flight_pair(tel, trk, time_shift=43200.0, clock_drift=EPS_PPM)
    ok = np.asarray(fixed.observed)
    assert ok.sum() == obs.sum()
    assert np.max(np.abs(fixed.dv[ok])) < 1e-6, np.max(np.abs(fixed.dv[ok]))
    assert fixed.meta["clock_drift_ppm"] == EPS_PPM
    assert flight_provenance(fixed)["clock_drift_ppm"] == EPS_PPM


def test_a_drift_that_is_no_clock_is_refused(files, tmp_path, capsys):
    """2e4 ppm (2 %): a fraction or milliseconds given as ppm: exit 2 naming the option's parameter and the rule;
    nothing written."""
    tel, trk = files
    out = tmp_path / "r.json"
    assert main(["separate", str(tel), "--tracking", str(trk), "--time-shift", "43200", "--clock-drift", "2e4",
                 "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "`clock_drift` 20000 ppm" in err and "at most 10000 ppm" in err, err
    assert not out.exists()
    with pytest.raises(ValueError, match="`clock_drift` .* must be finite"):
        casep.read_flight_pair(tel, trk, time_shift=43200.0, clock_drift=float("nan"))


def test_the_manifest_states_it_and_names_the_field(files, tmp_path):
    from casep.workflows.manifest import read_manifest

    tel, trk = files
    good = tmp_path / "good.toml"
    good.write_text(f'[[flight]]\ntelemetry = "{tel}"\ntracking = "{trk}"\ntime_shift_s = 43200.0\n'
                    f"clock_drift_ppm = {EPS_PPM}\n")
    (flight,) = read_manifest(good).read()
    assert flight.meta["clock_drift_ppm"] == EPS_PPM and np.nanmax(np.abs(flight.dv)) < 1e-6
    bad = tmp_path / "bad.toml"
    bad.write_text(f'[[flight]]\ntelemetry = "{tel}"\ntracking = "{trk}"\nclock_drift_ppm = 2e4\n')
    with pytest.raises(ValueError, match="clock_drift_ppm"):
        read_manifest(bad)


def test_a_telemetry_separated_with_a_drift_says_the_ins_integration_is_not_corrected(files, tmp_path):
    """The drift given is taken out of the tracking tags only: the result says that the telemetry's INS, where its
    own clock drifts, integrated over steps that much too long (a common scale factor of minus the drift on every
    sensor, not corrected), and records it in ``diagnostics["clock_drift_given"]``."""
    import json

    tel, trk = files
    out = tmp_path / "r.json"
    main(["separate", str(tel), "--tracking", str(trk), "--time-shift", "43200", "--clock-drift", str(EPS_PPM),
          "--json", str(out)])
    res = json.loads(out.read_text())
    said = res["diagnostics"]["clock_drift_given"]
    assert said["ppm"] == EPS_PPM and said["ins_integration_corrected"] is False
    assert said["scale_factor_if_ins_clock_ppm"] == -EPS_PPM
    assert "that integration is not corrected" in res["message"] and "-1e+03 ppm" in res["message"], res["message"]
