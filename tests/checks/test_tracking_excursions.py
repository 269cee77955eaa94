"""The physics check at the tracking's own noise: a block of wrong epochs a few m/s off, while the vehicle does tens
or hundreds of m/s, is below the gross jump rule (10 m/s) but far beyond the tracking's epoch-to-epoch scatter.

Built independently of the screen: the block is added to the tracking file (or to dv) by hand, and the truth of
the flight is the simulator's. Without the rule, a 1 s block of 20 Hz epochs 2 m/s off was taken for "a smooth
misfit of the model" (two runs of rejections of the robust filter), no times said, and the result a plain success.
"""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pandas as pd
import pytest

from casep.checks.tracking_quality import EXCURSION_SIGMAS, screen_tracking
from casep.cli import main
from casep.exceptions import TrackingQualityWarning
from casep.frames import LaunchSite
from casep.io.pair import pair_flight
from casep.simulation.earth_fixed import write_earth_fixed_flight

SITE = LaunchSite(28.5, -80.6, 3.0, 90.0, 0.0)


def _pair(rng, block=None, step=None, noise=0.05):
    """A 20 Hz tracking of a smooth climb (tens to hundreds of m/s) with white noise; `block` ``(t1, t2, dv)``: the
    tracking off by ``dv`` m/s on x over ``t1 <= t < t2``; `step` ``(t1, dv)``: off from ``t1`` on (it stays)."""
    t_tel = np.arange(0.0, 60.0, 0.01)
    acc = np.column_stack([5 * np.sin(0.3 * t_tel), 20 + 0 * t_tel, 3 * np.cos(0.2 * t_tel)])
    v_tel = np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (acc[1:] + acc[:-1]) * 0.01, axis=0)])
    t_trk = np.arange(0.0, 60.0, 0.05)
    v_trk = np.column_stack([np.interp(t_trk, t_tel, v_tel[:, i]) for i in range(3)])
    v_trk += rng.normal(0, noise, v_trk.shape)
    if block is not None:
        v_trk[(t_trk >= block[0] - 1e-9) & (t_trk < block[1] - 1e-9), 0] += block[2]
    if step is not None:
        v_trk[t_trk >= step[0] - 1e-9, 0] += step[1]
    signals = {f"a_{c}": acc[:, i] for i, c in enumerate("xyz")}
    return pair_flight(t_tel, acc, v_tel, t_trk, v_trk, signals=signals, source="pair",
                       meta={"tracking_repeats": np.array([], dtype=int)})


def test_a_block_of_wrong_epochs_is_left_out_and_named(rng):
    flight = _pair(rng, block=(30.0, 31.0, 2.0))
    said = r"20 tracking epochs in 1 span\(s\) are off the telemetry's course.* up to 2\.\d+ m/s.* t = 30\.\.30\.95 s"
    with pytest.warns(TrackingQualityWarning, match=said):
        screened = screen_tracking(flight)
    t = flight.t
    wrong = flight.observed & (t >= 30.0 - 1e-9) & (t < 31.0 - 1e-9)
    assert wrong.sum() == 20 and not screened.observed[wrong].any()
    assert np.array_equal(screened.observed, flight.observed & ~wrong)  # nothing else
    scr = screened.meta["tracking_screen"]
    assert scr["excursions"] == [(30.0, 30.95, 20)] and scr["rejected"] == [] and len(scr["left_out_rows"]) == 20


@pytest.mark.parametrize("size", [0.3, 0.0])
def test_a_clean_pair_and_a_block_within_the_noise_are_kept(rng, size):
    """0.3 m/s in 0.05 m/s noise: the change's robust sigma is 0.07 m/s, the rule's 10 sigma 0.7 m/s: kept, unsaid
    (the fit's robust filter judges what is below the rule)."""
    flight = _pair(rng, block=(30.0, 31.0, size))
    screened = screen_tracking(flight)  # no warning: the suite makes one an error
    assert np.array_equal(screened.observed, flight.observed) and screened.meta["tracking_screen"]["excursions"] == []


def test_a_step_that_stays_leaves_nothing_out(rng):
    """A lone jump of 2 m/s that stays (a change of the receiver's solution, a time tag at lift-off): no jump back,
    nothing left out by the screen (the fit judges it)."""
    flight = _pair(rng, step=(30.0, 2.0))
    screened = screen_tracking(flight)
    assert np.array_equal(screened.observed, flight.observed)


def test_two_steps_that_do_not_cancel_are_no_excursion(rng):
    """Away by 2 m/s and on by another 2 m/s within a second: not back where the course would be, nothing left out."""
    flight = _pair(rng, step=(30.0, 2.0))
    dv = flight.dv.copy()
    dv[flight.t >= 30.5 - 1e-9, 0] -= 2.0  # dv = v_tel - v_trk: the tracking a further 2 m/s off from 30.5 s
    screened = screen_tracking(dataclasses.replace(flight, dv=dv))
    assert np.array_equal(screened.observed, flight.observed)


def test_the_rule_is_the_noise_not_a_fixed_size(rng):
    """The same 2 m/s block in 0.3 m/s noise (the change's sigma 0.42 m/s, the rule 4.2 m/s) is kept: the rule
    scales with the stretch's scatter."""
    assert EXCURSION_SIGMAS == 10.0
    flight = _pair(rng, block=(30.0, 31.0, 2.0), noise=0.3)
    assert np.array_equal(screen_tracking(flight).observed, flight.observed)


def _run(tmp_path, capsys, block: bool):
    fl = write_earth_fixed_flight(tmp_path / "tel.csv", SITE, frame="ecef", seed=1)
    trk = fl.tracking
    if block:  # the tracking file's v_ecef_x 2 m/s off over 1 s (20 epochs), its positions untouched
        head = [line for line in trk.read_text().splitlines(keepends=True) if line.startswith("#")]
        k = pd.read_csv(trk, comment="#")
        k.loc[(k.t >= 30.0 - 1e-9) & (k.t < 31.0 - 1e-9), "v_ecef_x"] += 2.0
        trk = tmp_path / "glitch.csv"
        with open(trk, "w") as f:
            f.writelines(head)
            k.to_csv(f, index=False)
    out = tmp_path / "res.json"
    status = main(["separate", str(fl.telemetry), "--tracking", str(trk), "--tracking-frame", "ecef",
                   "--launch-site", "28.5", "-80.6", "3", "90", "--launch-time", "0", "--json", str(out)])
    printed = "".join(capsys.readouterr())
    res = json.loads(out.read_text())
    truth = fl.truth_record["coefficients"]
    z = np.array([(e - truth[n]) / s for n, e, s in zip(res["names"], res["estimates"], res["std"]) if n in truth])
    return status, printed, res, z


def test_a_flight_with_a_block_of_wrong_epochs_is_separated_without_them(tmp_path, capsys):
    """ECEF tracking 2 m/s off over 1 s (its positions unchanged): the epochs named by line and time and left out,
    the result a success within its std of the truth, as the clean flight's."""
    status, printed, res, z = _run(tmp_path, capsys, block=True)
    assert status == 0 and res["success"], printed
    named = r"20 tracking epochs .* lines \d+\.\.\d+ of glitch\.csv, t = 30\.\.30\.95 s \(20\)"
    assert re.search(named, printed), printed
    assert "misfit" not in printed and "misfit_runs" not in res["diagnostics"]
    assert np.abs(z).max() < 3.5 and 0.5 < np.sqrt(np.mean(z**2)) < 1.5, z
    status, printed, clean, z_clean = _run(tmp_path, capsys, block=False)  # no warning: the suite makes one an error
    assert status == 0 and clean["success"] and "off the telemetry's course" not in printed
    assert res["n_samples"] == clean["n_samples"] - 20
    assert np.abs(z - z_clean).max() < 0.5, (z, z_clean)  # 20 of ~3000 epochs fewer: the same result



def test_one_epoch_left_out_is_named_by_its_time_not_as_a_span_to_itself(rng):
    flight = _pair(rng)
    k = int(np.flatnonzero(flight.observed & (np.abs(flight.t - 30.0) < 1e-9))[0])
    dv = flight.dv.copy()
    dv[k, 2] += 50.0  # one epoch 50 m/s off: beyond the gross jump rule (10 m/s), alone
    with pytest.warns(TrackingQualityWarning) as caught:
        screened = screen_tracking(dataclasses.replace(flight, dv=dv))
    said = " ".join(str(w.message) for w in caught)
    assert "1 tracking epochs fail the physics check" in said and "t = 30 s (1)" in said, said
    assert "30..30" not in said
    assert np.array_equal(screened.observed, flight.observed & (np.arange(flight.t.size) != k))
