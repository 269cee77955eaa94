"""The paper's scenario constants (Table 1 truth, noise, RELS prior), from spec/model.md."""

from __future__ import annotations

__all__ = ["TABLE1_TRUTH", "TABLE1_NOISE_SIGMA", "TABLE1_P0"]

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
