"""A sounding rocket on the rotating Earth, run end to end as a user would: ``casep separate --imu ... --tracking ...``.

The truth comes from the independent strapdown generator of ``benchmarks/aircraft_flight.py`` (WGS84, J2, the
Earth's rotation; not casep's navigation): 20 s at rest on the pad at the rocket range of
:data:`casep.simulation.rocket.ROCKET_SITE` (67.89 N), a rail at 85 deg elevation, 4 s of boost at 9 g with a roll
ramp to 180 deg/s, a coast through apogee (about 36 s) and a tumble about the body y axis from 45 s that takes the
gyro past its 2000 deg/s full scale, 55 s of flight. The faults of the flight the strapdown issue describes, made by
:class:`casep.simulation.rocket.RocketSpec`'s rules (its defaults): an 800 Hz IMU with ``strapdown12``'s biases and
scale factors (3 mg, 1000 ppm, 30 deg/h, 1000 ppm) and white noise, packets lost (75 ms at burnout, six others of
10-50 ms), its clock 104 ppm fast against GPS time; a 10 Hz GNSS file (geodetic, or ECEF with ``--frame ecef``) that
repeats its last fix from 0.5 s after lift-off for 26 s, then reports 1 s of fresh-looking wrong epochs (2 m/s while
the rocket does 80-90 m/s), then a solution 0.4 s late, updated once a second, with Gauss-Markov errors of 3 m/s
(tau 5 s). The heading is not observable on the pad (the horizontal Earth rate is 5.6 deg/h, the gyro biases
30 deg/h): the rail's azimuth is given, ``--heading-error`` deg off (default 0.2).

Each seed writes the two files and runs ``casep separate --imu IMU --tracking GNSS --tracking-frame geodetic
--launch-site ... --launch-time ... --align ... --heading ... --heading-axis y --gyr-range 2000 --model
strapdown15_phi0 --json OUT`` in a subprocess (its command, stdout and stderr kept in ``outN.log``); printed: the
exit code and status, the first line of the message, what casep listed (IMU gaps, clipped samples, stale and wrong
tracking epochs, a failed set-up check, the tracking lines its robust step rejected), and z = (estimate - truth) /
std of every combination the result states (``diagnostics.determined``), the truth being the injected coefficients
and, as the free ``phi0``, the attitude error of the levelling of the truly corrected IMU
(``benchmarks/rocket_rawlog.py``'s rule, which is what the given heading's error leaves once the model carries the
levelling's own ``A D``). Then the RMS z, the coverage and the largest z over the seeds.

Run:  OPENBLAS_NUM_THREADS=1 python benchmarks/rocket_flight.py [--seeds 1 2 3] [--frame geodetic|ecef]
                                                               [--heading-error 0.2] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from aircraft_flight import G0, c_bn, c_ne, earth_truth, geod2ecef, ramp, with_errors  # noqa: E402
from zfigures import z_figures  # noqa: E402

FINE_HZ = 3200  # the generator's grid: the body rate's central difference is 2e-6 of it at the 3 rad/s roll
ELEVATION, THRUST_G, BURN, TAIL, ROLL_DPS, TUMBLE_START, TUMBLE_DPS = 85.0, 9.0, 4.0, 0.3, 180.0, 45.0, 2600.0


def motion(tau: np.ndarray, az_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """The Earth-relative NED velocity and the body-to-NED attitude at times `tau` from lift-off (body x along the
    rail, body y horizontal on the pad)."""
    el, az = math.radians(ELEVATION), math.radians(az_deg)
    u = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])  # the rail, NED
    dt = tau[1] - tau[0]
    on = ramp(tau, 0.0, 0.1)  # the rocket leaves the rail's rest smoothly
    thrust = THRUST_G * G0 * on * (1 - ramp(tau, BURN - TAIL, TAIL))
    acc = thrust[:, None] * u + on[:, None] * np.array([0.0, 0.0, G0])  # straight along the rail, then ballistic
    acc[:, :] -= (0.3 * np.exp(-np.clip(tau, 0, None) / 15.0) * on)[:, None] * u  # a little drag
    vn = np.concatenate([np.zeros((1, 3)), np.cumsum((acc[1:] + acc[:-1]) / 2, axis=0) * dt])
    rate = np.radians(ROLL_DPS) * ramp(tau, 0.0, BURN)
    roll = np.concatenate([[0], np.cumsum((rate[1:] + rate[:-1]) / 2) * dt])
    pitch = el - np.radians(0.4) * np.clip(tau - BURN, 0, None)
    trate = np.radians(TUMBLE_DPS) * ramp(tau, TUMBLE_START, 3.0)
    tumble = np.concatenate([[0], np.cumsum((trate[1:] + trate[:-1]) / 2) * dt])
    c, s = np.cos(tumble), np.sin(tumble)
    Ry = np.zeros((tau.size, 3, 3))
    Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = c, s, 1.0, -s, c
    Cbn = np.einsum("kij,kjl->kil", c_bn(np.full(tau.size, az), pitch, roll), Ry)
    return vn, Cbn


def flight(seed: int, directory: Path, frame: str, heading_error: float) -> dict:
    """Write the IMU and GNSS files of one seed; return the paths, the site, the settings and the truth."""
    from casep.frames import OMEGA_EARTH, _rz, ecef_to_geodetic
    from casep.io.files import write_table
    from casep.rotations import dcm_to_quat
    from casep.simulation.rocket import ROCKET_SITE, RocketSpec, _gps, _lost

    sp, site = RocketSpec(), ROCKET_SITE
    rng = np.random.default_rng(seed)
    tau = np.arange(-round(sp.pad_s * FINE_HZ), round(sp.flight_s * FINE_HZ) + 1) / FINE_HZ
    vn, Cbn = motion(tau, site.azimuth_deg)
    p, fb, wb = earth_truth(tau, (math.radians(site.lat_deg), math.radians(site.lon_deg), site.h_m), vn, Cbn)
    coef = {**{f"ba_{a}": rng.normal(0, sp.acc_bias_mg) for a in "xyz"},
            **{f"sa_{a}": rng.normal(0, sp.acc_scale_ppm) for a in "xyz"},
            **{f"bg_{a}": rng.normal(0, sp.gyr_bias_dph) for a in "xyz"},
            **{f"sg_{a}": rng.normal(0, sp.gyr_scale_ppm) for a in "xyz"}}
    zeros = {f"{k}_{a}{b}": 0.0 for k in ("ma", "mg", "gg") for a in "xyz" for b in "xyz"}
    fm, wm = with_errors(fb, wb, {**zeros, **coef})
    k = slice(None, None, FINE_HZ // int(sp.rate))
    t = tau[k]
    fm = fm[k] + rng.normal(0, sp.acc_noise, (t.size, 3))
    wm = wm[k] + rng.normal(0, sp.gyr_noise, (t.size, 3))
    fs = math.radians(sp.gyr_range_dps)
    clipped = np.flatnonzero(np.any(np.abs(wm) >= fs, axis=1))
    wm = np.clip(wm, -fs, fs)
    keep, gaps = _lost(sp, rng, t)
    t_imu = site.t0 + t * (1 + sp.clock_ppm * 1e-6)
    imu = {"t": t_imu[keep], **{f"w_{a}": wm[keep, i] for i, a in enumerate("xyz")},
           **{f"fb_{a}": fm[keep, i] for i, a in enumerate("xyz")}}
    r_e = geod2ecef(p[k, 0], p[k, 1], p[k, 2])
    v_e = np.einsum("kij,kj->ki", c_ne(p[k, 0], p[k, 1]), vn[k])
    gps, spans = _gps(sp, rng, t, r_e, v_e, site.t0)
    if frame == "geodetic":
        r = np.column_stack([gps[f"r_ecef_{a}"] for a in "xyz"])
        v = np.column_stack([gps[f"v_ecef_{a}"] for a in "xyz"])
        lat, lon, h, ve, vnn, vu = ecef_to_geodetic(r, v)
        gps = {"t": gps["t"], "lat": lat, "lon": lon, "h": h, "v_east": ve, "v_north": vnn, "v_up": vu}
    imu_path, gps_path = directory / f"imu{seed}.csv", directory / f"gps{seed}.csv"
    write_table(imu_path, imu)
    write_table(gps_path, gps)
    # the true attitude at the first IMU sample, body to launch-inertial: C^T Rz(w (t - t0)) C_b^e
    Cbe0 = c_ne(p[0:1, 0], p[0:1, 1])[0] @ Cbn[0]
    C_lb = site.C.T @ _rz(np.array([OMEGA_EARTH * t[0]]))[0] @ Cbe0
    heading = (site.azimuth_deg + 90.0) % 360.0  # body y on the pad: horizontal, the rail's azimuth + 90 deg
    return {"imu": imu_path, "gps": gps_path, "site": site, "spec": sp, "coef": coef, "q0": dcm_to_quat(C_lb),
            "heading": heading + heading_error, "align": (float(imu["t"][0]), site.t0 - 1.0),
            "events": {"gaps": gaps, "first_clipped": float(t[clipped[0]]) if clipped.size else None, **spans},
            "imu_table": imu}


def phi0_truth(fl: dict) -> dict[str, float]:
    """The injected coefficients and the ``phi0`` the levelling of the truly corrected IMU leaves (module notes)."""
    from casep.navigation import ImuData
    from casep.navigation.navigator import pad_state
    from casep.rotations import quat_to_dcm

    c, imu = fl["coef"], fl["imu_table"]
    ba = np.array([c[f"ba_{a}"] for a in "xyz"]) * 1e-3 * G0
    sa = np.array([c[f"sa_{a}"] for a in "xyz"]) * 1e-6
    bg = np.radians(np.array([c[f"bg_{a}"] for a in "xyz"]) / 3600.0)
    sg = np.array([c[f"sg_{a}"] for a in "xyz"]) * 1e-6
    w = np.column_stack([imu[f"w_{a}"] for a in "xyz"])
    f = np.column_stack([imu[f"fb_{a}"] for a in "xyz"])
    pad = imu["t"] <= fl["align"][1] + 0.5
    q0 = pad_state(ImuData(imu["t"][pad], (w[pad] - bg) / (1 + sg), (f[pad] - ba) / (1 + sa)), fl["site"],
                   fl["align"], heading_deg=fl["heading"], heading_axis="y")[0]
    E = np.eye(3) - quat_to_dcm(q0) @ quat_to_dcm(fl["q0"]).T
    phi = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 2
    return {**c, **{f"phi0_{a}": math.degrees(phi[i]) * 3600 for i, a in enumerate("xyz")}, "dt_trk": 0.0}


def run(fl: dict, frame: str, out: Path, extra: list[str] | None = None) -> tuple[subprocess.CompletedProcess, dict]:
    """``casep separate --imu`` on the seed's files, as a user types it; the completed process and the JSON."""
    s = fl["site"]
    cmd = [sys.executable, "-m", "casep", "separate", "--imu", str(fl["imu"]), "--tracking", str(fl["gps"]),
           "--tracking-frame", frame, "--launch-site", str(s.lat_deg), str(s.lon_deg), str(s.h_m), str(s.azimuth_deg),
           "--launch-time", repr(s.t0), "--align", repr(fl["align"][0]), repr(fl["align"][1]),
           "--heading", repr(fl["heading"]), "--heading-axis", "y", "--gyr-range", str(fl["spec"].gyr_range_dps),
           "--model", "strapdown15_phi0", "--json", str(out), *(extra or [])]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    out.with_suffix(".log").write_text(" ".join(cmd) + "\n--- stdout\n" + proc.stdout + "--- stderr\n" + proc.stderr)
    return proc, (json.loads(out.read_text()) if out.exists() else {})


def zs(result: dict, truth: dict[str, float]) -> list[float]:
    """z of every combination the result states, against the truth."""
    det = (result.get("diagnostics") or {}).get("determined") or {}
    if not det:
        return []
    x = np.array([truth[n] / s for n, s in det["scales"].items()])
    return [(c["estimate"] - float(np.dot(c["weights"], x))) / c["std"] for c in det["combinations"]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--frame", choices=["geodetic", "ecef"], default="geodetic")
    ap.add_argument("--heading-error", type=float, default=0.2, help="deg added to the true heading given")
    ap.add_argument("--keep", type=Path, default=None, help="write the files here (kept) instead of a temporary folder")
    args = ap.parse_args()
    pooled: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        d = args.keep or Path(tmp)
        d.mkdir(parents=True, exist_ok=True)
        for seed in args.seeds:
            c0 = time.process_time()
            fl = flight(seed, d, args.frame, args.heading_error)
            c1 = time.process_time()
            proc, res = run(fl, args.frame, d / f"out{seed}.json")
            ch = resource_children()
            z = zs(res, phi0_truth(fl)) if res else []
            pooled += z
            print(f"seed {seed}: exit {proc.returncode}, status {res.get('status')}; simulated in {c1 - c0:.1f} CPU s, "
                  f"casep {ch:.1f} CPU s")
            print("  " + (res.get("message") or proc.stderr.strip()[-400:]).splitlines()[0][:300])
            print("  said: " + ", ".join(f"{k} {v}" for k, v in listed(proc.stdout + proc.stderr).items()))
            print(f"  events: gaps {[(round(a, 3), round(n, 3)) for a, n in fl['events']['gaps']]}, first clipped "
                  f"{fl['events']['first_clipped']}, stale {fl['events']['stale']}, wrong {fl['events']['wrong']}")
            print(f"  {len(z)} combinations stated, z " + " ".join(f"{v:+.2f}" for v in z), flush=True)
    a = np.asarray(pooled)
    if a.size:
        print(f"pooled: {a.size} z from {len(args.seeds)} seeds, " + z_figures(a))


def listed(said: str) -> dict[str, Any]:
    """What casep's output lists of the faults (the numbers it prints), and the tracking file's lines its robust step
    rejected as glitches (line 202 is lift-off, one line per 0.1 s)."""
    import re

    def num(pattern: str) -> Any:
        m = re.search(pattern, said)
        return m.group(1) if m else None

    robust = re.search(r"sample\(s\) rejected as glitches: (.*?), \d+ row", said)
    rejected = [int(x) for x in re.findall(r"line (\d+) of", robust.group(1))] if robust else []
    return {"IMU gaps": num(r"(\d+) gaps? in t"), "longest gap s": num(r"the longest ([0-9.]+) s"),
            "clipped": num(r"the IMU clipped: (w_\w: \d+) samples"),
            "stale epochs": num(r"(\d+) stale tracking epochs"),
            "physics-check epochs": num(r"(\d+) tracking epochs fail the physics check"),
            "set-up failed": "set-up check" in said, "robust-rejected tracking lines": rejected}


def resource_children() -> float:
    """CPU s of the finished child processes so far (the casep runs), user + system, since the last call."""
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = r.ru_utime + r.ru_stime
    last = getattr(resource_children, "last", 0.0)
    resource_children.last = total  # type: ignore[attr-defined]
    return total - last


if __name__ == "__main__":
    main()
