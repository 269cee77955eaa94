"""The time skew of a strapdown telemetry's attitude against its body rate: told where the rate changes from step to
step, not checked (a warning with its std) where it does not, the rate's steps between samples left out
(casep.io.strapdown: _rate_steps, _skew_std, _lag_agreement)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import casep
import casep.io.strapdown as sd
from casep.io.flight import FlightDataError
from casep.io.strapdown import StrapdownWarning

QC = ["q_w", "q_x", "q_y", "q_z"]
UNSEEN = "cannot tell whether they are on one time base"


@pytest.fixture(scope="module")
def boost(tmp_path_factory):
    """``casep simulate --scenario strapdown-boost --rate 10``: its header and table (a pitch kick at 8 s, the rate
    stepping between the samples at 7.9 and 8 s; a roll programme from 10 s)."""
    import pandas as pd

    from casep.cli import main

    path = tmp_path_factory.mktemp("boost") / "sd.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["simulate", "--scenario", "strapdown-boost", "--rate", "10", "-o", str(path)]) == 0
    head = "".join(ln for ln in path.read_text().splitlines(keepends=True) if ln.startswith("#"))
    return head, pd.read_csv(path, comment="#")


def _cut(boost, path, until: float | None = None, late: int = 0):
    """The simulated record up to `until` s (None: whole) with q_* `late` samples late (rolled, the rows it wrapped
    around dropped), written to `path`."""
    head, df = boost
    d = (df if until is None else df[df["t"] <= until + 0.01]).reset_index(drop=True).copy()
    if late:
        d[QC] = np.roll(d[QC].to_numpy(), late, axis=0)
        d = d.iloc[late:] if late > 0 else d.iloc[:late]
    path.write_text(head + d.to_csv(index=False))
    return path


def test_a_10s_cut_whose_only_skew_evidence_is_its_pitch_kick_warns_that_the_skew_is_not_checked(boost, tmp_path):
    """Cut 2 s after the pitch kick: the comparison used to read the cubic's ringing over the rate's step as "q 1
    sample late" and refused a valid record. The step's neighbours are left out; what remains is a constant pitch
    rate, on which no skew shows: read, with a warning giving the skew's std and the step left out."""
    with pytest.warns(StrapdownWarning) as said:
        fl = casep.read_flight(_cut(boost, tmp_path / "cut.csv", 10.0))
    msgs = [str(w.message) for w in said]
    assert len(msgs) == 1 and UNSEEN in msgs[0], msgs
    msg = msgs[0]
    assert "the skew's std is" in msg and "samples" in msg and "beyond the 0.33 sample (33.3 ms)" in msg, msg
    assert "between rows 80 and 81, t = 7.9 .. 8 s" in msg and "the 3 steps across and next to" in msg, msg
    sd_info = fl.meta["strapdown"]
    assert sd_info["skew"]["std"] > 100 * sd.SKEW_STD_MAX  # a constant rate: nothing tells a skew
    assert [s["t_before"] for s in sd_info["rate_steps"]] == pytest.approx([7.9])


def test_the_10s_cut_with_q_late_is_never_a_silent_success(boost, tmp_path):
    """One sample late: the record cannot tell it from none (the step's own interval is left out): the same warning.
    Two samples late: the attitude's turn starts after the rate's step's neighbours, refused as late by at least a
    sample, with the range the record cannot tell apart."""
    with pytest.warns(StrapdownWarning, match=UNSEEN):
        casep.read_flight(_cut(boost, tmp_path / "late1.csv", 10.0, late=1))
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(_cut(boost, tmp_path / "late2.csv", 10.0, late=2))
    msg = str(exc.value)
    assert "columns `q_w`, `q_x`, `q_y`, `q_z`" in msg, msg
    assert "is 1 to 3 or more samples (100 to 300 ms or more) later than the body rate" in msg, msg
    assert "q_* is at least 100 ms late" in msg and "cannot tell the skew closer" in msg, msg


@pytest.mark.parametrize("until", [None, 30.0])
@pytest.mark.parametrize("late", [1, 2, -1])
def test_a_skew_on_a_record_with_a_roll_programme_is_still_refused(boost, tmp_path, until, late):
    """The whole record and a 30 s cut (a roll rate that ramps: the skew shows): q_* late or early is refused
    naming the samples and milliseconds, as before the rate's steps were left out."""
    with pytest.raises(FlightDataError) as exc:
        casep.read_flight(_cut(boost, tmp_path / "late.csv", until, late=late))
    msg = str(exc.value)
    when = "later" if late > 0 else "earlier"
    assert f"is {abs(late)} sample(s) ({100 * abs(late)} ms) {when} than the body rate" in msg, msg
    assert f"move q_* by {-100 * late:+d} ms" in msg, msg


@pytest.mark.parametrize("until", [None, 12.0, 30.0])
def test_a_record_with_a_roll_programme_on_one_time_base_reads_quietly(boost, tmp_path, until):
    with warnings.catch_warnings():
        warnings.simplefilter("error", StrapdownWarning)
        fl = casep.read_flight(_cut(boost, tmp_path / "ok.csv", until))
    assert fl.meta["strapdown"]["skew"]["std"] < 0.01  # samples
    assert abs(fl.meta["strapdown"]["skew"]["tau"]) < 5 * fl.meta["strapdown"]["skew"]["std"] + 0.01


RATE = 50.0


def _rolling(t):
    """A roll rate that changes (1.5 + 2.6 cos 1.3 t rad/s) under a slow pitch: its closed-form attitude and body
    rate (C = Rz(theta) Rx(phi))."""
    phi, phi_dot = 1.5 * t + 2.0 * np.sin(1.3 * t), 1.5 + 2.6 * np.cos(1.3 * t)
    theta, theta_dot = 0.2 * np.sin(0.3 * t), 0.06 * np.cos(0.3 * t)
    q = (Rotation.from_euler("z", theta[:, None]) * Rotation.from_euler("x", phi[:, None])).as_quat(scalar_first=True)
    return q, np.column_stack([phi_dot, np.sin(phi) * theta_dot, np.cos(phi) * theta_dot])


@pytest.mark.parametrize("tau", [0.0, 0.3, -0.5, 1.0])
def test_the_skew_estimate_recovers_a_sub_sample_skew_of_the_closed_form(tau):
    """The attitude of the closed form evaluated tau samples late (not a shifted sample: the motion itself): the
    estimate finds tau."""
    t = np.arange(1000) / RATE
    q, w = _rolling(t)
    q_late, _ = _rolling(t - tau / RATE)
    keep = np.ones(t.size - 1, bool)
    got = sd._skew_std(t, w, sd._step_rotations(q_late), keep, sd.RATE_READINGS["samples of the body rate"])
    assert got["tau"] == pytest.approx(tau, abs=2e-3)
    assert got["std"] < 2e-3


def test_the_skew_std_is_the_scatter_of_its_estimate_under_rate_noise():
    """White noise of 0.02 rad/s on the written rate (the attitude exact), 300 seeds: the estimates' scatter against
    their mean std (the long-run variance carries the cubic's spreading of a reading over neighbouring steps)."""
    t = np.arange(1000) / RATE
    q, w = _rolling(t)
    rv, keep = sd._step_rotations(q), np.ones(t.size - 1, bool)
    rng = np.random.default_rng(7)
    taus, stds = [], []
    for _ in range(300):
        got = sd._skew_std(t, w + 0.02 * rng.standard_normal(w.shape), rv, keep,
                           sd.RATE_READINGS["samples of the body rate"])
        taus.append(got["tau"])
        stds.append(got["std"])
    ratio = float(np.std(taus, ddof=1) / np.mean(stds))
    assert 0.85 < ratio < 1.15, ratio
    assert abs(np.mean(taus)) < 3 * np.std(taus, ddof=1) / np.sqrt(len(taus))


def test_a_constant_body_rate_cannot_tell_a_skew(tmp_path):
    """A spin at a constant body rate: every shift of the attitude agrees alike; read, with the warning."""
    from casep.io.files import write_table

    t = np.arange(600) / RATE
    w = np.tile([0.8, 0.1, -0.2], (t.size, 1))
    q = Rotation.from_rotvec(t[:, None] * w).as_quat(scalar_first=True)
    cols = {"t": t, **{c: q[:, i] for i, c in enumerate(QC)}, **{f"fb_{a}": np.full(t.size, 9.0 + i)
                                                                  for i, a in enumerate("xyz")},
            **{f"w_{a}": w[:, i] for i, a in enumerate("xyz")}, **{f"dv_{a}": np.zeros(t.size) for a in "xyz"}}
    write_table(tmp_path / "spin.csv", cols)
    with pytest.warns(StrapdownWarning, match=UNSEEN):
        fl = casep.read_flight(tmp_path / "spin.csv")
    assert not fl.meta["strapdown"]["skew"]["std"] <= sd.SKEW_STD_MAX
