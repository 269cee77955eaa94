"""Coarse time alignment of tracking and telemetry (casep.io.align)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import casep
from casep.exceptions import TimeOffsetWarning
from casep.io.align import coarse_time_offset
from casep.io.files import write_table
from casep.simulation.simulate import simulate_two_rate


def _v(t):  # boost-like velocity, m/s: x-acceleration 1.5 t, plus 1.5 (t - 40) after 40 s
    return np.column_stack([0.75 * t**2 + np.where(t > 40.0, 0.75 * (t - 40.0) ** 2, 0.0),
                            40.0 * t, 3.0 * np.sin(0.2 * t)])


def test_offset_of_an_exact_pair_is_found_to_a_microsecond():
    """No instrument error: the velocities of two rates line up exactly at the injected offset."""
    t_tel = np.arange(0.0, 80.0, 0.01)
    t_trk = np.arange(0.0, 80.0, 0.1)
    for tau in (-0.42, 0.0, 0.35, 1.3):
        a = coarse_time_offset(t_tel, _v(t_tel), t_trk, _v(t_trk - tau))  # v_trk(t) = v_true(t - tau)
        assert abs(a.tau - tau) < 1e-6, (tau, a.tau)
        assert a.exceeds_period == (abs(tau) > 0.1)
        assert a.cost <= a.cost_at_zero


@pytest.mark.parametrize("scenario", ["paper", "paper-azimuth"])
def test_instrument_errors_do_not_pull_the_coarse_offset(scenario):
    """The paper truth's dv (metres per second) would pull a fit of the velocities by ~60 ms; the
    increments over 1 s are not: 0, 20 and 300 ms found to within 2 ms (0.1 m/s noise, 20 Hz)."""
    for off in (0.0, 0.02, 0.3):
        d = simulate_two_rate(scenario, seed=3, telemetry_rate=20.0, tracking_rate=20.0, time_offset=off)
        a = coarse_time_offset(d.t_tel, d.v_tel, d.t_trk, d.v_trk)
        assert abs(a.tau - off) < 2e-3, (off, a.tau)


def test_a_large_offset_warns_and_auto_plus_dt_trk_recovers_it(tmp_path):
    """300 ms late tracking at 5 Hz: reading the pair warns with the numbers; --time-offset auto
    shifts it back and dt_trk estimates the rest: their sum within 3 std of 300 ms."""
    from casep.cli import main

    d = simulate_two_rate("paper", seed=3, telemetry_rate=20.0, tracking_rate=5.0, time_offset=0.3)
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    d.write(tel, trk)
    with pytest.warns(TimeOffsetWarning,
                      match=r"look 30\d\.\d ms late .* more than a tracking sample period \(200 ms\)"):
        casep.read_flight_pair(tel, trk)
    fl = casep.read_flight_pair(tel, trk, time_offset="auto")
    shift = fl.meta["time_alignment"]["applied_s"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioned
        res = casep.separate(fl, "platform36_timeoffset")
    j = list(res.names).index("dt_trk")
    total = shift * 1e3 + res.estimate[j]
    assert abs(total - 300.0) < 3 * res.std[j], (total, res.std[j])
    out = tmp_path / "r.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["separate", str(tel), "--tracking", str(trk), "--model", "platform36_timeoffset",
                     "--time-offset", "auto", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["time_alignment"]["applied_s"] == pytest.approx(shift)
    # a given offset (ms on the command line) is applied as given
    g = casep.read_flight_pair(tel, trk, time_offset=0.25)
    assert g.meta["time_alignment"]["applied_s"] == 0.25
    with pytest.raises(SystemExit) as exc:
        main(["separate", str(tel), "--tracking", str(trk), "--time-offset", "soon"])
    assert exc.value.code == 2


def test_no_warning_for_offsets_within_a_sample(tmp_path):
    """Pairs without offset, or 20 ms late at 20 Hz tracking (a 50 ms period), read quietly."""
    for off in (0.0, 0.02):
        d = simulate_two_rate("paper", seed=4, telemetry_rate=20.0, tracking_rate=20.0, time_offset=off)
        d.write(tmp_path / "tel.csv", tmp_path / "trk.csv")
        with warnings.catch_warnings():
            warnings.simplefilter("error", TimeOffsetWarning)
            fl = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv")
        assert abs(fl.meta["time_alignment"]["tau_s"] - off) < 2e-3 and fl.meta["time_alignment"]["applied_s"] == 0.0


def test_bad_input():
    t = np.arange(0.0, 5.0, 0.1)
    with pytest.raises(ValueError, match="`max_offset` must be finite and > 0"):
        coarse_time_offset(t, _v(t), t, _v(t), max_offset=0.0)
    with pytest.raises(ValueError, match="fewer than 4 tracking samples"):
        coarse_time_offset(t, _v(t), t, _v(t), max_offset=2.4)


def test_the_offset_std_is_its_scatter_and_infinite_at_rest():
    """0.5 m/s tracking noise, 40 ms late, 20 seeds: RMS (tau - 40 ms) / std near 1 (measured 0.94 on 40 seeds).
    At rest the velocity increments do not change with the offset: the std is seconds, beyond AUTO_MAX_STD of the
    period."""
    from casep.io.align import AUTO_MAX_STD

    t_tel, t_trk = np.arange(0.0, 80.0, 0.01), np.arange(0.0, 80.0, 0.1)
    z = []
    for seed in range(20):
        noise = np.random.default_rng(seed).normal(0.0, 0.5, (t_trk.size, 3))
        a = coarse_time_offset(t_tel, _v(t_tel), t_trk, _v(t_trk - 0.04) + noise)
        z.append((a.tau - 0.04) / a.std)
    assert 0.7 < float(np.sqrt(np.mean(np.square(z)))) < 1.3, z  # RMS of 20 z: sampling std ~0.16
    rest = np.random.default_rng(1).normal(0.0, 0.05, (t_trk.size, 3))
    a = coarse_time_offset(t_tel, 0.01 * np.sin(t_tel / 7)[:, None] * np.ones(3), t_trk, rest)
    assert a.std > AUTO_MAX_STD * a.tracking_period * 10


def test_auto_leaves_an_offset_the_record_does_not_determine_unapplied(tmp_path):
    """A vehicle at rest: the offset that lines up the velocities is noise; --time-offset auto does not apply it
    and says so with its std."""
    rng = np.random.default_rng(2)
    t_tel, t_trk = np.arange(0.0, 40.0, 0.01), np.arange(0.0, 40.0, 0.1)
    f = np.tile([0.0, 0.0, 9.805], (t_tel.size, 1))
    write_table(tmp_path / "tel.csv", {"t": t_tel, **{f"f_{c}": f[:, i] for i, c in enumerate("xyz")},
                                                **{f"v_tel_{c}": 0.01 * np.sin(t_tel / 7 + i) for i, c in
                                                   enumerate("xyz")}})
    v = rng.normal(0.0, 0.05, (t_trk.size, 3))
    write_table(tmp_path / "trk.csv", {"t": t_trk, **{f"v_trk_{c}": v[:, i] for i, c in enumerate("xyz")}})
    with pytest.warns(TimeOffsetWarning, match=r"auto: .* ms late, but that offset's std is .* Not applied"):
        fl = casep.read_flight_pair(tmp_path / "tel.csv", tmp_path / "trk.csv", time_offset="auto")
    assert fl.meta["time_alignment"]["applied_s"] == 0.0 and fl.meta["time_alignment"]["std_s"] > 0.025


def test_the_lateness_left_in_place_is_the_readers_warning_rule():
    """unaligned_lateness: the coarse offset when no time_offset was given, it exceeds a sample period and explains
    the data; None when it was applied (auto or given), is within a period, or explains nothing."""
    from casep.io.align import TimeAlignment, unaligned_lateness

    def record(tau: float, cost: float = 1.0, mode: str = "none") -> dict:
        # 1000 samples at 5 Hz, the misfit at zero 10x the shifted one: the shift explains the data
        return {**TimeAlignment(tau, cost, 10.0, 0.2, 1000).to_dict(), "mode": mode}

    assert record(0.297)["explains"] and record(0.297)["exceeds_period"]
    assert unaligned_lateness(record(0.297)) == 0.297
    assert unaligned_lateness(record(-0.25)) == -0.25
    for rec in (record(0.297, mode="auto"), record(0.297, mode="given"), record(0.297, cost=9.99), record(0.15),
                record(-0.2)):
        assert unaligned_lateness(rec) is None, rec
    assert unaligned_lateness(None) is None and unaligned_lateness({}) is None


def _stepped(d, jitter: float, seed: int = 0):
    """`d` with its 20 Hz tracking velocity held at each whole second's fix (a receiver's 1 Hz solution after
    reacquisition), `jitter` m/s of white noise on the held epochs (0: exact repeats)."""
    import dataclasses

    k = np.floor(d.t_trk + 1e-9).astype(int)
    first = np.flatnonzero(np.concatenate([[True], np.diff(k) > 0]))
    held = d.v_trk[first[np.searchsorted(first, np.arange(k.size), side="right") - 1]].copy()
    held[np.setdiff1d(np.arange(k.size), first)] += np.random.default_rng(seed).normal(
        0.0, jitter, (k.size - first.size, 3)) if jitter else 0.0
    return dataclasses.replace(d, v_trk=held)


@pytest.mark.parametrize("jitter", [0.0, 0.005])
def test_a_held_tracking_velocity_is_not_called_late(tmp_path, jitter):
    """A 20 Hz tracking velocity held at 1 Hz steps lags the vehicle by up to a second between fixes (unscreened:
    "400 ms late"); the alignment judges the epochs the stale screen keeps: no warning, the offset within 3 std of
    0 and dt_trk's total (auto shift + fit) within 3 std of 0. The same stepped tracking 400 ms late is still found
    (at the 1 s period of its fresh epochs, within a period: not warned), and 20 Hz tracking 400 ms late is warned."""
    d = simulate_two_rate("paper", seed=5, telemetry_rate=20.0, tracking_rate=20.0, time_offset=0.0)
    tel, trk = tmp_path / "tel.csv", tmp_path / "trk.csv"
    _stepped(d, jitter).write(tel, trk)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimeOffsetWarning)
        fl = casep.read_flight_pair(tel, trk)
        auto = casep.read_flight_pair(tel, trk, time_offset="auto")
    rec = fl.meta["time_alignment"]
    assert rec["stale_left_out"] > 0.9 * d.t_trk.size and rec["tracking_period_s"] == pytest.approx(1.0)
    assert abs(rec["tau_s"]) < 3 * rec["std_s"] and rec["std_s"] < 0.01, rec
    shift = auto.meta["time_alignment"]["applied_s"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioned; the stale epochs left out
        res = casep.separate(auto, "platform36_timeoffset")
    j = list(res.names).index("dt_trk")
    assert res.status >= 0, res.message
    assert abs(shift * 1e3 + res.estimate[j]) < 3 * res.std[j], (shift, res.estimate[j], res.std[j])
    for late, data, warned in ((0.4, _stepped(simulate_two_rate("paper", seed=5, telemetry_rate=20.0,
                                                                tracking_rate=20.0, time_offset=0.4), jitter), False),
                               (0.4, simulate_two_rate("paper", seed=5, telemetry_rate=20.0, tracking_rate=20.0,
                                                       time_offset=0.4), True)):
        data.write(tel, trk)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            rec = casep.read_flight_pair(tel, trk).meta["time_alignment"]
        assert abs(rec["tau_s"] - late) < max(3 * rec["std_s"], 2e-3), rec
        assert any(issubclass(w.category, TimeOffsetWarning) and "ms late" in str(w.message)
                   for w in seen) == warned, [str(w.message) for w in seen]
