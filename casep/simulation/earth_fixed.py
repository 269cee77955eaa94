"""A simulated flight tracked in an Earth-fixed frame: telemetry, ECEF or geodetic tracking, and the truth.

``casep simulate --rotating-earth --launch-site ... --tracking-frame ecef|geodetic`` writes three files
through :func:`write_earth_fixed_flight`: the telemetry (``t, f_*, v_tel_*, a_*``, launch-inertial),
the tracking in the Earth-fixed frame (:meth:`casep.simulation.simulate.TwoRateData.write`, converted
by :mod:`casep.frames` with the launch site; lift-off is t = 0) and the truth sidecar
(``<stem>.truth.json``, docs/reference/file-formats.md) that records the model, the true
coefficients, the noise, the trajectory, the seed and the tracking set-up. A strapdown scenario's
(:func:`write_strapdown_earth_fixed`): its flight file, truth sidecar and raw IMU, and its own tracking
(the flight's ``r_*, v_*``) in the Earth-fixed frame.

:func:`read_truth` reads a ``--truth`` file (``{"Kg0x": value, ...}`` or a truth sidecar) and
checks it against the model, for any simulation.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["EarthFixedFlight", "write_earth_fixed_flight", "write_strapdown_earth_fixed", "earth_fixed_truth",
           "read_truth", "tracking_path"]


def tracking_path(telemetry: str | os.PathLike) -> Path:
    """Default tracking file beside the telemetry: ``flight.csv`` -> ``flight.tracking.csv``."""
    p = Path(telemetry)
    return p.with_name(f"{p.stem}.tracking{p.suffix}")


def read_truth(path: str | os.PathLike, model: Any, option: str = "--truth") -> dict[str, float]:
    """True coefficients from a JSON file, checked against the model.

    Parameters
    ----------
    path : str or path-like
        ``{"Kg0x": value, ...}`` in natural units, or a truth sidecar (its ``coefficients``).
    model : ErrorModel
        The model whose coefficients they are (names not given are 0).
    option : str, optional
        The option named in messages.

    Returns
    -------
    dict
        ``{name: value}`` as given.

    Raises
    ------
    ValueError
        A name the model does not have, or a value that is not a finite number.
    """
    from casep.io.files import read_json_table
    from casep.simulation.simulate import truth_vector

    truth = read_json_table(path, option)
    truth = truth["coefficients"] if isinstance(truth.get("coefficients"), dict) else truth
    truth_vector(model, truth, f"{option} {path}")
    return truth


@dataclass(frozen=True)
class EarthFixedFlight:
    """What :func:`write_earth_fixed_flight` simulated and wrote."""

    data: Any  # casep.simulation.simulate.TwoRateData
    scenario: Any  # casep.simulation.scenarios.Scenario (with the model and truth used)
    telemetry: Path
    tracking: Path
    truth: Path
    truth_record: dict


def earth_fixed_truth(data: Any, scenario: Any, *, seed: int, telemetry_rate: float, tracking_rate: float,
                      time_offset_ms: float, frame: str, tracking: str | os.PathLike) -> dict:
    """The truth sidecar of an Earth-fixed two-file flight (docs/reference/file-formats.md, "Truth sidecar")."""
    return {"model": data.model.name,
            "coefficients": {n: float(v) for n, v in zip(data.model.names, data.truth)},
            "units": dict(zip(data.model.names, data.model.units)), "noise": scenario.noise.to_dict(),
            "trajectory": {"scenario": scenario.name, "description": scenario.description,
                           "rate_hz": telemetry_rate, "vehicle": scenario.vehicle.to_dict()},
            "seed": seed,
            "tracking": {"time_offset_ms": time_offset_ms, "lever_arm_m": [0.0, 0.0, 0.0], "rotating_earth": True,
                         "frame": frame, "file": str(tracking), "rate_hz": tracking_rate,
                         "launch_site": data.site.to_dict()}}


def write_earth_fixed_flight(telemetry: str | os.PathLike, site: Any, *, frame: str = "ecef",
                             tracking: str | os.PathLike | None = None, scenario: str = "paper", seed: int = 0,
                             telemetry_rate: float | None = None, tracking_rate: float = 20.0,
                             time_offset_ms: float = 0.0, model: str | os.PathLike | None = None,
                             truth: dict | None = None) -> EarthFixedFlight:
    """Simulate a rotating-Earth flight and write its telemetry, Earth-fixed tracking and truth files.

    Parameters
    ----------
    telemetry : str or path-like
        Telemetry file (``.csv`` or ``.parquet``); the truth goes to ``<stem>.truth.json`` beside it.
    site : LaunchSite
        Launch point and azimuth (:class:`casep.frames.LaunchSite`; its ``t0`` is lift-off, 0).
    frame : {"ecef", "geodetic"}, optional
        Frame of the tracking file.
    tracking : str or path-like, optional
        Tracking file (default :func:`tracking_path`).
    scenario : str, optional
        Scenario name (:data:`casep.simulation.scenarios.SCENARIOS`).
    seed : int, optional
        Noise seed.
    telemetry_rate : float, optional
        Hz (default: the scenario's).
    tracking_rate : float, optional
        Hz.
    time_offset_ms : float, optional
        Tracking time tags late by this much, ms (recorded as given).
    model : str or path, optional
        Error model to inject (default: the scenario's).
    truth : dict, optional
        True coefficients, natural units (default: the scenario's; checked by :func:`read_truth`'s rule).

    Returns
    -------
    EarthFixedFlight
        The data and the three paths. The files are written atomically (inside a
        :func:`casep.io._atomic.output_group`, all three or none).
    """
    from casep.io._atomic import atomic_open, output_group
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_two_rate, truth_path

    if frame not in ("ecef", "geodetic"):
        raise ValueError(f"`frame` must be 'ecef' or 'geodetic', got {frame!r}")
    out = Path(telemetry)
    trk = Path(tracking) if tracking else tracking_path(out)
    sc = get_scenario(scenario)
    if sc.strapdown:
        raise ValueError(f"--tracking-frame {frame}: scenario `{sc.name}` is a strapdown flight (its telemetry is "
                         "q_*, fb_*, w_*): write it with write_strapdown_earth_fixed (what casep simulate does)")
    if model is not None or truth is not None:
        sc = dataclasses.replace(sc, model=os.fspath(model) if model else sc.model,
                                 truth=sc.truth if truth is None else dict(truth))
    rate = telemetry_rate or sc.rate
    d = simulate_two_rate(sc, seed=seed, telemetry_rate=rate, tracking_rate=tracking_rate,
                          time_offset=time_offset_ms * 1e-3, rotating_earth=True, site=site)  # ms -> s
    record = earth_fixed_truth(d, sc, seed=seed, telemetry_rate=rate, tracking_rate=tracking_rate,
                               time_offset_ms=time_offset_ms, frame=frame, tracking=trk)
    with output_group():
        d.write(out, trk, tracking_frame=frame)
        with atomic_open(truth_path(out)) as fh:  # as write_simulation writes its sidecar
            fh.write(json.dumps(record, indent=2) + "\n")
    return EarthFixedFlight(d, sc, out, trk, truth_path(out), record)


def write_strapdown_earth_fixed(sim: Any, telemetry: str | os.PathLike, tracking: str | os.PathLike, *,
                                frame: str, imu: str | os.PathLike | None = None, imu_pad: float = 0.0,
                                imu_sensor: Any = None) -> tuple[Path, Path]:
    """A rotating-Earth strapdown flight's files with its tracking in an Earth-fixed frame, all or none.

    The flight file, truth sidecar and raw IMU (`imu_pad`, `imu_sensor` as there) of
    :func:`casep.simulation.simulate.write_simulation`, and the
    tracking file: the flight's tracked position and velocity (``r_*``, ``v_*``, launch-inertial, the velocity with
    its noise) at its observed samples, turned into ECEF (``t, r_ecef_*, v_ecef_*``) by
    :func:`casep.frames.launch_to_ecef` or into geodetic (``t, lat, lon, h, v_east, v_north, v_up``) by
    :func:`casep.frames.ecef_to_geodetic`, with the flight's launch site (lift-off t = 0).

    Returns
    -------
    (Path, Path)
        The flight file and the truth sidecar (`tracking` as given).
    """
    import numpy as np

    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS, ecef_to_geodetic, launch_to_ecef
    from casep.io._atomic import output_group
    from casep.io.files import write_table
    from casep.simulation.simulate import write_simulation

    site = sim.trajectory.site
    if frame not in ("ecef", "geodetic") or site is None:
        raise ValueError(f"--tracking-frame {frame}: needs 'ecef' or 'geodetic' and a rotating-Earth flight "
                         "(--rotating-earth --launch-site)")
    fl = sim.flight
    keep = np.asarray(fl.observed, bool)
    r, v = (np.column_stack([fl.signals[f"{p}_{a}"][keep] for a in "xyz"]) for p in ("r", "v"))
    r_e, v_e = launch_to_ecef(site, fl.t[keep], r, v)
    values = (*r_e.T, *v_e.T) if frame == "ecef" else ecef_to_geodetic(r_e, v_e)
    names = ECEF_COLUMNS if frame == "ecef" else GEODETIC_COLUMNS
    with output_group():
        paths = write_simulation(sim, telemetry, imu=imu, imu_pad=imu_pad, imu_sensor=imu_sensor)
        write_table(tracking, {"t": fl.t[keep], **dict(zip(names[1:], values))}, comments=[
            f"casep simulated tracking, {frame} (WGS84), launch site {site.to_dict()} (t0: lift-off, t = 0); the "
            f"flight's tracked r_*, v_* at its observed samples"])
    return paths
