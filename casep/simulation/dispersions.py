"""Dispersions of the vehicle and launch parameters for a Monte Carlo (``casep montecarlo --dispersions``).

A dispersions file is a JSON object ``{parameter: distribution}``; each Monte Carlo run draws
every listed parameter once and flies its own trajectory (so S_V differs per run). Distributions:

- ``{"dist": "normal", "mean": m, "std": s}`` (s >= 0)
- ``{"dist": "uniform", "low": a, "high": b}`` (a <= b)

Parameters (:data:`PARAMETERS`; a ``*_scale`` multiplies the scenario's value, nominal 1; a
``*_deg`` or ``*_deg_s`` is added to it, nominal 0):

====================== ===========================================================================
``thrust_scale``       every stage's thrust
``isp_scale``          every stage's specific impulse
``stage<k>_thrust_scale`` stage k's thrust (k = 1, 2, ...), on top of ``thrust_scale``
``stage<k>_isp_scale`` stage k's specific impulse, on top of ``isp_scale``
``liftoff_mass_scale`` lift-off mass (the stages' dry masses unchanged)
``drag_area_scale``    aerodynamic reference area (drag)
``kick_rate_scale``    pitch-over kick rate
``launch_azimuth_deg`` flight azimuth off the platform's x axis (added to the yaw offset)
``yaw_amplitude_scale`` the yaw manoeuvre's amplitude (a scenario without one keeps none)
====================== ===========================================================================

A ``*_scale`` must stay positive: a normal one needs ``mean - 6 std > 0``, a uniform one
``low > 0``. ``launch_azimuth_deg`` must stay within +-180 deg (``|mean| + 6 std``, or ``low`` and
``high``). With the vehicle given, its worst draw (lowest thrust, highest lift-off mass: 6 std, or the
uniform bounds) must still lift off: lift-off thrust / weight above :data:`MIN_LIFTOFF_TW`.
Run k draws from ``default_rng(SeedSequence(seed, spawn_key=(k, 0)))`` in the order of
:data:`PARAMETERS`, so its vehicle depends on the seed and k only.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Mapping

import numpy as np

from casep.simulation.trajectory import Vehicle, YawManoeuvre

__all__ = ["PARAMETERS", "parse_dispersions", "draw_dispersion", "disperse_vehicle"]

PARAMETERS = ("thrust_scale", "isp_scale", "liftoff_mass_scale", "drag_area_scale", "kick_rate_scale",
              "launch_azimuth_deg", "yaw_amplitude_scale")
_STAGE = re.compile(r"^stage([1-9][0-9]*)_(thrust|isp)_scale$")
_DISTS = {"normal": ("mean", "std"), "uniform": ("low", "high")}


def _order(name: str) -> tuple:
    m = _STAGE.match(name)
    return (1, int(m.group(1)), m.group(2)) if m else (0, PARAMETERS.index(name), "")


#: Lift-off thrust-to-weight of the worst dispersed vehicle below this: it does not lift off (refused).
MIN_LIFTOFF_TW = 1.05
#: Largest launch azimuth dispersion, deg (a draw beyond it is another launch direction, not a dispersion).
MAX_AZIMUTH_DEG = 180.0


def parse_dispersions(data: Any, n_stages: int, source: str = "dispersions",
                      vehicle: Vehicle | None = None) -> dict[str, dict]:
    """Check a dispersions mapping; return it in canonical order (errors name `source` and the key).

    `vehicle` (optional): the scenario's vehicle, to refuse dispersions whose worst draw does not lift off."""
    if not isinstance(data, Mapping):
        raise ValueError(f"{source}: must hold a JSON object {{parameter: distribution}}")
    if not data:
        raise ValueError(f"{source}: no parameters (accepted: {', '.join(PARAMETERS)}, stage<k>_thrust_scale, "
                         "stage<k>_isp_scale)")
    out = {}
    for name, spec in data.items():
        m = _STAGE.match(str(name))
        if name not in PARAMETERS and not m:
            raise ValueError(f"{source}: unknown parameter `{name}` (accepted: {', '.join(PARAMETERS)}, "
                             f"stage<k>_thrust_scale, stage<k>_isp_scale)")
        if m and not 1 <= int(m.group(1)) <= n_stages:
            raise ValueError(f"{source}: `{name}`: the vehicle has {n_stages} stage(s)")
        if not isinstance(spec, Mapping) or spec.get("dist") not in _DISTS:
            raise ValueError(f"{source}: `{name}` must be {{\"dist\": \"normal\", \"mean\": m, \"std\": s}} or "
                             f"{{\"dist\": \"uniform\", \"low\": a, \"high\": b}}, got {spec!r}")
        keys = _DISTS[spec["dist"]]
        extra = set(spec) - {"dist", *keys}
        if extra:
            raise ValueError(f"{source}: `{name}`: unexpected key(s) {', '.join(sorted(map(str, extra)))} for a "
                             f"{spec['dist']} distribution (use {', '.join(keys)})")
        vals = []
        for k in keys:
            v = spec.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{source}: `{name}`: `{k}` must be a finite number, got {v!r}")
            vals.append(float(v))
        a, b = vals
        if spec["dist"] == "normal" and b < 0:
            raise ValueError(f"{source}: `{name}`: `std` must be >= 0, got {b:g}")
        if spec["dist"] == "uniform" and a > b:
            raise ValueError(f"{source}: `{name}`: `low` ({a:g}) exceeds `high` ({b:g})")
        if name.endswith("_scale"):
            lowest = a - 6 * b if spec["dist"] == "normal" else a
            if not lowest > 0:
                raise ValueError(f"{source}: `{name}`: a scale factor must stay > 0 "
                                 f"({'mean - 6 std' if spec['dist'] == 'normal' else 'low'} = {lowest:g})")
        if name == "launch_azimuth_deg":
            lo, hi = (a - 6 * b, a + 6 * b) if spec["dist"] == "normal" else (a, b)
            if not (-MAX_AZIMUTH_DEG <= lo and hi <= MAX_AZIMUTH_DEG):
                raise ValueError(f"{source}: `{name}`: draws must stay within +-{MAX_AZIMUTH_DEG:g} deg, got "
                                 f"[{lo:g}, {hi:g}] ({'mean +- 6 std' if spec['dist'] == 'normal' else 'low, high'})")
        out[str(name)] = {"dist": spec["dist"], keys[0]: a, keys[1]: b}
    if vehicle is not None:
        _check_liftoff(out, vehicle, source)
    return {k: out[k] for k in sorted(out, key=_order)}


def _extreme(spec: Mapping | None, high: bool) -> float:
    """The largest (`high`) or smallest draw of a scale factor: mean +- 6 std, or the uniform bound; 1 if absent."""
    if spec is None:
        return 1.0
    if spec["dist"] == "normal":
        return spec["mean"] + (6 if high else -6) * spec["std"]
    return spec["high"] if high else spec["low"]


def _check_liftoff(disp: Mapping[str, dict], vehicle: Vehicle, source: str) -> None:
    """Refuse dispersions whose worst draw does not lift off: T1 min / (m0 max g) < MIN_LIFTOFF_TW."""
    from casep.units import G0

    thrust = vehicle.stages[0].thrust * _extreme(disp.get("thrust_scale"), False) \
        * _extreme(disp.get("stage1_thrust_scale"), False)
    mass = vehicle.liftoff_mass * _extreme(disp.get("liftoff_mass_scale"), True)
    tw = thrust / (mass * G0)
    if tw < MIN_LIFTOFF_TW:
        nominal = vehicle.stages[0].thrust / (vehicle.liftoff_mass * G0)
        raise ValueError(f"{source}: the worst draw (lowest thrust, highest lift-off mass) gives a lift-off "
                         f"thrust-to-weight of {tw:.3g} (nominal {nominal:.3g}), below {MIN_LIFTOFF_TW:g}: that "
                         "vehicle does not lift off; narrow thrust_scale, stage1_thrust_scale or liftoff_mass_scale")


def draw_dispersion(disp: Mapping[str, dict], rng: np.random.Generator) -> dict[str, float]:
    """One draw of every parameter, in the (canonical) order of `disp`."""
    out = {}
    for name, d in disp.items():
        if d["dist"] == "normal":
            out[name] = float(d["mean"] + d["std"] * rng.standard_normal())
        else:
            out[name] = float(rng.uniform(d["low"], d["high"]))
    return out


def disperse_vehicle(vehicle: Vehicle, values: Mapping[str, float]) -> Vehicle:
    """`vehicle` with the drawn parameter values applied (see the module notes)."""
    g = dict(values)
    stages = []
    for k, s in enumerate(vehicle.stages, start=1):
        ft = g.get("thrust_scale", 1.0) * g.get(f"stage{k}_thrust_scale", 1.0)
        fi = g.get("isp_scale", 1.0) * g.get(f"stage{k}_isp_scale", 1.0)
        stages.append(dataclasses.replace(s, thrust=s.thrust * ft, isp=s.isp * fi))
    pitch = dataclasses.replace(vehicle.pitch, kick_rate=vehicle.pitch.kick_rate * g.get("kick_rate_scale", 1.0))
    yaw = vehicle.yaw
    if "launch_azimuth_deg" in g or "yaw_amplitude_scale" in g:
        if yaw is None:
            yaw = YawManoeuvre(amplitude=0.0, offset=g.get("launch_azimuth_deg", 0.0))
        else:
            yaw = dataclasses.replace(yaw, amplitude=yaw.amplitude * g.get("yaw_amplitude_scale", 1.0),
                                      offset=yaw.offset + g.get("launch_azimuth_deg", 0.0))
    return dataclasses.replace(vehicle, stages=tuple(stages), pitch=pitch, yaw=yaw,
                               liftoff_mass=vehicle.liftoff_mass * g.get("liftoff_mass_scale", 1.0),
                               area=vehicle.area * g.get("drag_area_scale", 1.0))
