"""The paper's scenario constants (Table 1 truth, noise, RELS prior), from docs/reference/model.md."""

from __future__ import annotations

__all__ = ["TABLE1_TRUTH", "TABLE1_NOISE_SIGMA", "TABLE1_P0", "spec_magnitude", "demo_bounds", "demo_prior"]

#: True coefficients of Table 1 in platform36 order and natural units.
TABLE1_TRUTH: dict[str, float] = {
    "Kg0x": 0.5, "Kg1x": -0.1, "Kg1xy": -0.01, "Kg1xz": 0.02, "Kg2x": 1e-4,
    "Kg0y": 0.3, "Kg1y": 0.01, "Kg1yz": 0.02, "Kg1yx": -0.01, "Kg2y": 1e-4,
    "Kg0z": -0.5, "Kg1z": 0.01, "Kg1zx": -0.02, "Kg1zy": 0.02, "Kg2z": 1e-4,
    "Ka0x": -2.0, "Ka1x": 0.5, "Ka1xy": 50.0, "Ka1xz": 50.0, "Ka2x": 3e-3, "Ka2xy": 3e-3, "Ka2xz": 3e-3,
    "Ka0y": -2.0, "Ka1y": 0.5, "Ka1yz": 50.0, "Ka1yx": 50.0, "Ka2y": 3e-3, "Ka2yz": 3e-3, "Ka2yx": 3e-3,
    "Ka0z": 1.0, "Ka1z": 0.5, "Ka1zx": 50.0, "Ka1zy": 50.0, "Ka2z": 3e-3, "Ka2zx": 3e-3, "Ka2zy": 3e-3,
}
#: White tracking noise of the paper, m/s per axis.
TABLE1_NOISE_SIGMA = 0.1
#: The paper's RELS initial covariance scale (P0 = 1e6 I, natural units).
TABLE1_P0 = 1e6


def spec_magnitude(name: str) -> float | None:
    """Typical specification magnitude of a platform36 coefficient (natural units).

    A platform IMU of the paper's class, independent of the Table 1 values: gyro bias
    1 deg/h, first-order g-sensitivity 0.2 deg/h/g, second order 0.01 deg/h/g^2;
    accelerometer bias 5 mg, scale factor 1 mg/g, cross-axis 100 ug/g, second order
    10 ug/g^2. None for other names.
    """
    if len(name) < 4 or name[:2] not in ("Kg", "Ka"):
        return None
    kind, order, rest = name[1], name[2], name[3:]
    if kind == "g":
        return {"0": 1.0, "1": 0.2, "2": 0.01}.get(order)
    if order == "0":
        return 5.0
    if order == "1":
        return 1.0 if len(rest) == 1 else 100.0
    return 10.0 if order == "2" else None


def demo_bounds(names) -> dict[str, list[float]]:
    """The demo's plausible box: each coefficient within +- its spec magnitude."""
    return {n: [-m, m] for n in names if (m := spec_magnitude(n)) is not None}


def demo_prior(names) -> dict[str, dict[str, float]]:
    """The demo's ground-calibration-like prior.

    std = half the spec magnitude; mean = the Table 1 value offset by half a prior std with
    alternating sign (a ground calibration that is close, but not exact, and that the flight
    may have shifted).
    """
    out = {}
    for j, n in enumerate(names):
        m = spec_magnitude(n)
        if m is None or n not in TABLE1_TRUTH:
            continue
        std = 0.5 * m
        out[n] = {"mean": TABLE1_TRUTH[n] + (0.5 if j % 2 == 0 else -0.5) * std, "std": std}
    return out
