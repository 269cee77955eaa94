"""The time-offset warning's advice on a one-file flight (t, f_*, v_tel_*, v_trk_*): the command it names runs
(the kinematic acceleration a = f + g of casep.io.flight.FlightData.model_signals), and its dt_trk, fitted with the
samples whose tracking straddles the burnout left out, finds the offset within its std (seed 1, --noise gmw: 33.6 +- 3.0
ms; without leaving them out 21.7 +- 2.3; before, the advised run failed: missing column a_x)."""

from __future__ import annotations

import json
import re

import numpy as np

from casep.cli import main
from casep.units import G0

OFFSET = 0.030  # s, tracking time tags late


def _flight(path, seed: int = 1) -> None:
    """40 s at 50 Hz (fine grid 2 kHz): 15 -> 21 m/s^2 of thrust pitching over, cut within one sample at 20 s,
    no instrument error; tracking = the true velocity OFFSET late (interpolated on the fine grid) + Gauss-Markov
    (tau 1 s, 0.1 m/s) + white 0.05 m/s noise, from 1 s."""
    rng = np.random.default_rng(seed)
    tf = np.arange(0.0, 40.0 + 1e-9, 1.0 / 2000.0)
    amp = np.where(tf < 20.0, 15.0 + 0.3 * tf, 0.0)
    th = np.radians(90.0 - 40.0 * (1.0 - np.exp(-tf / 30.0)))
    F = np.stack([amp * np.cos(th), amp * np.sin(th), 0.5 * amp * np.sin(2 * np.pi * tf / 20.0) / 15.0], 1)
    a = F + np.array([0.0, -G0, 0.0])
    V = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (a[1:] + a[:-1]) / 2000.0, axis=0)])
    idx = np.arange(0, tf.size, 40)
    t = tf[idx]
    late = np.stack([np.interp(t - OFFSET, tf, V[:, k]) for k in range(3)], 1)
    phi = np.exp(-0.02)
    gm = np.empty((t.size, 3))
    gm[0] = rng.normal(0.0, 0.1, 3)
    for k in range(1, t.size):
        gm[k] = phi * gm[k - 1] + rng.normal(0.0, 0.1 * np.sqrt(1 - phi**2), 3)
    trk = late + gm + rng.normal(0.0, 0.05, (t.size, 3))
    with open(path, "w") as fh:
        fh.write("t,f_x,f_y,f_z,v_tel_x,v_tel_y,v_tel_z,v_trk_x,v_trk_y,v_trk_z\n")
        for k in range(t.size):
            cells = [f"{t[k]:.4f}"] + [f"{x:.10g}" for x in (*F[idx[k]], *V[idx[k]])]
            cells += [f"{x:.10g}" for x in trk[k]] if t[k] >= 1.0 else ["", "", ""]
            fh.write(",".join(cells) + "\n")


def test_offset_advice_runs_on_a_one_file_flight(tmp_path, capsys):
    path = tmp_path / "boost.csv"
    _flight(path)
    main(["separate", str(path), "--model", "platform36", "--noise", "gmw"])
    err = "".join(capsys.readouterr())
    said = [line for line in err.splitlines() if "would explain them" in line]
    assert said, err
    advice = re.search(r"--model (\S+),", said[0])
    assert advice and advice.group(1) == "platform36+dt_trk", said[0]
    out = tmp_path / "res.json"
    main(["separate", str(path), "--model", advice.group(1), "--noise", "gmw", "--json", str(out)])
    res = json.loads(out.read_text())
    dt = next(c for c in res["coefficients"] if c["name"] == "dt_trk")
    assert abs(dt["estimate"] - 1e3 * OFFSET) < 3.0 * dt["std"], dt
    assert "at a step of the acceleration left out" in res["message"], res["message"]



def test_several_flights_fitted_jointly_leave_out_each_flights_step_samples(tmp_path):
    """The rule of one flight for several fitted jointly (casep.workflows.flights.separate_flights): each one-file
    flight's samples whose tracking straddles its burnout are left out of the joint fit with dt_trk, and each flight's
    own dt_trk finds the offset within its std (seeds 1, 2: 29.3 +- 2.5 and 30.5 +- 2.5 ms; with every sample kept
    20.2 +- 2.0 and 17.1 +- 2.1, 5 and 6 std short)."""
    import warnings

    from casep.workflows.flights import separate_flights

    paths = [tmp_path / f"boost{k}.csv" for k in (1, 2)]
    for k, p in enumerate(paths, 1):
        _flight(p, seed=k)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one boost of a model without errors to find: ill-conditioned, said elsewhere
        res, _ = separate_flights([str(p) for p in paths], "platform36+dt_trk", noise="gmw")
    idx = [j for j, n in enumerate(res.names) if n.startswith("dt_trk[")]
    assert len(idx) == 2, res.names
    for j in idx:
        assert abs(res.estimate[j] - 1e3 * OFFSET) < 3.0 * res.std[j], (res.names[j], res.estimate[j], res.std[j])
    left = res.settings["step_samples_left_out"]
    assert all(left) and all(999 <= k <= 1004 for rows in left for k in rows), left  # the cut at 20 s, 50 Hz
    assert res.message.count("at a step of the acceleration left out of") == 2, res.message
