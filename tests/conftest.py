"""Shared fixtures: seeded rng, set-up models, the paper's truth and a synthetic flight."""

from __future__ import annotations

import numpy as np
import pytest

import casep
from casep.paper import TABLE1_TRUTH
from casep.synthetic import excitation_force


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture(scope="session")
def platform36() -> casep.ErrorModel:
    return casep.load_model("platform36")


@pytest.fixture(scope="session")
def platform39() -> casep.ErrorModel:
    return casep.load_model("platform39_misalignment")


@pytest.fixture(scope="session")
def truth36(platform36) -> np.ndarray:
    return np.array([TABLE1_TRUTH[n] for n in platform36.names])


@pytest.fixture(scope="session")
def flight_tf() -> tuple[np.ndarray, np.ndarray]:
    """180 s at 20 Hz of the analytic excitation (all three axes)."""
    t = np.arange(0.0, 180.0, 0.05)
    return t, excitation_force(t)
