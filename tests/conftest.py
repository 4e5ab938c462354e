"""Shared fixtures: the reference reference arrays."""

import numpy as np
import pytest

from allocation import WheelArray

DELTA = np.deg2rad(55.0)
GAMMA = np.deg2rad(45.0)


@pytest.fixture
def pyramid() -> WheelArray:
    """Meteor-M No. 2 pyramid, δ = 55°, γ = 45°, unit capacities."""
    return WheelArray.pyramid(DELTA, GAMMA, h_max=1.0, m_max=1.0)
