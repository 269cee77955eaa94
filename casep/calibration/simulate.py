"""Synthetic ground tests: the readings a model gives for known coefficients, with the errors of a real test.

A session is a sequence of segments, each held for its number of samples at ``rate``:

- static: the true specific force is ``g R_k e_k``, ``e_k`` the nominal direction and ``R_k`` the
  rotation by a random vector ``phi ~ N(0, tilt^2 I)``, ``tilt = position_error_deg`` (a hand or
  fixture position is never exact: the error of the whole segment; the model of casep's
  ``weighting="positions"``);
- rotation: the sensor turns about its axis (along gravity) by the nominal angle times
  ``(1 + angle_error)`` with a smooth rate ``omega(t) = theta / T (1 - cos(2 pi t / T))``, t in [0, T].

Readings ``u = y0(f, omega) + J(f, omega) D + e`` from the model's own functions, ``e`` white
noise of std ``noise`` per axis (reading units; ``noise = 0``: exact).
"""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from casep.calibration.model import CalibrationModel
from casep.calibration.session import Segment, Session, ferraris_segment
from casep.units import G0

__all__ = ["simulate_session", "ferraris_design", "tilted_design"]


def ferraris_design(static_samples: int = 400, rotation_samples: int = 300,
                    angle_deg: float = -360.0) -> list[dict]:
    """The nine segments of the Ferraris procedure (imucal's names) as design entries."""
    out: list[dict[str, Any]] = [{"name": n, "samples": static_samples}
                                 for n in ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")]
    out += [{"name": n, "samples": rotation_samples, "angle_deg": angle_deg} for n in ("x_rot", "y_rot", "z_rot")]
    return out


def tilted_design(static_samples: int = 400) -> list[dict]:
    """Twelve static positions with gravity between two axes (45 deg): they separate the cross terms
    ``Wx Wy`` that the six axis positions leave undetermined."""
    out = []
    for a, b in ((0, 1), (0, 2), (1, 2)):
        for sa in (1, -1):
            for sb in (1, -1):
                g = np.zeros(3)
                g[a], g[b] = sa, sb
                out.append({"name": f"t{'xyz'[a]}{'pa'[sa < 0]}{'xyz'[b]}{'pa'[sb < 0]}", "kind": "static",
                            "gravity": (g / math.sqrt(2)).tolist(), "samples": static_samples})
    return out


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: the rotation matrix by `angle` (rad) about unit `axis`."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


def simulate_session(model: CalibrationModel, truth: Mapping[str, float] | np.ndarray, design: Sequence[dict], *,
                     rate: float = 100.0, noise: Sequence[float] | float | tuple = 0.0,
                     position_error_deg: float = 0.0, angle_error: float = 0.0, gravity: float = G0,
                     seed: int | None = None, acc_unit: str = "a.u.", gyr_unit: str = "a.u.",
                     ) -> tuple[Session, list[Segment]]:
    """A synthetic session and its segments (module notes).

    Parameters
    ----------
    model : CalibrationModel
        Set up.
    truth : mapping or (n,) array
        Coefficients, natural units (a mapping: missing ones are 0).
    design : sequence of dict
        ``{"name", "samples"}`` for imucal's names (``angle_deg`` for a turn), or with ``kind``,
        ``gravity`` (and ``omega_dps`` for a static one, ``axis``, ``angle_deg`` for a turn) for others.
    noise : float or (acc, gyr) pair of float or 3-vectors
        White noise std of the readings, reading units.
    position_error_deg, angle_error : float
        Std of each component of the tilt of a static position (deg) and relative std of each turn's angle.
    seed : int, optional
        Of the random draws (noise, tilts, angle errors).

    Returns
    -------
    (Session, list of Segment)
        Readings in the model's reading units (``readings="si"``: m/s^2 and rad/s, stated as such).
    """
    model.setup()
    rng = np.random.default_rng(seed)
    D = (np.array([float(truth.get(n, 0.0)) for n in model.names]) if isinstance(truth, Mapping)
         else np.asarray(truth, dtype=float))
    if isinstance(noise, (int, float)):
        noise = (noise, noise)
    na, ng = (np.broadcast_to(np.asarray(v, dtype=float), (3,)) for v in noise)
    acc: list[np.ndarray] = []
    gyr: list[np.ndarray] = []
    segs: list[Segment] = []
    k0 = 0
    for d in design:
        k = int(d["samples"])
        rows = np.arange(k0, k0 + k)
        k0 += k
        if "kind" in d:
            g = np.asarray(d["gravity"], dtype=float)
            g = g / np.linalg.norm(g)
            if d["kind"] == "static":
                seg = Segment(d["name"], "static", rows, gravity=g,
                              omega_dps=np.asarray(d.get("omega_dps", np.zeros(3)), dtype=float))
            else:
                ax = np.asarray(d["axis"], dtype=float)
                seg = Segment(d["name"], "rotation", rows, gravity=g, axis=ax / np.linalg.norm(ax),
                              angle_deg=float(d["angle_deg"]))
        else:
            seg = ferraris_segment(d["name"], rows, float(d.get("angle_deg", -360.0)))
        segs.append(seg)
        if seg.kind == "static":
            phi = math.radians(position_error_deg) * rng.normal(size=3)  # rotation vector, rad
            ang = float(np.linalg.norm(phi))
            R = _rotation(phi / ang, ang) if ang > 0 else np.eye(3)
            f = gravity * (R @ seg.gravity)
            w0, a, r = np.deg2rad(seg.omega_dps), np.zeros(3), np.zeros(k)
        else:
            assert seg.angle_deg is not None and seg.axis is not None  # a rotation segment has both
            theta = math.radians(seg.angle_deg) * (1.0 + angle_error * rng.normal())
            T = k / rate
            t = np.arange(k) / rate
            r = theta / T * (1.0 - np.cos(2 * math.pi * t / T))  # rad/s; its rectangle sum / rate = theta
            f, w0, a = gravity * seg.gravity, np.zeros(3), seg.axis  # the turn is about gravity: f stays
        for slot, out, sd in (("accel_reading", acc, na), ("gyro_reading", gyr, ng)):
            if slot not in model.slots:
                out.append(np.zeros((k, 3)))
                continue
            # the reading is affine in omega: y(f, w0 + r a) = y(f, w0) + r [y(f, w0 + a) - y(f, w0)]
            y0 = model.known(slot, f, w0) + model.jacobian(slot, f, w0) @ D
            y1 = model.known(slot, f, w0 + a) + model.jacobian(slot, f, w0 + a) @ D
            out.append(y0[None, :] + r[:, None] * (y1 - y0)[None, :] + rng.normal(size=(k, 3)) * sd)
    n = k0
    ses = Session(t=np.arange(n) / rate, acc=np.vstack(acc), gyr=np.vstack(gyr), rate=rate, source="<simulated>",
                  acc_unit="m/s^2" if model.readings == "si" else acc_unit,
                  gyr_unit="rad/s" if model.readings == "si" else gyr_unit)
    return ses, segs
