"""Fixtures of the detector tests (the synthetic scenes live in detect_synthetic.py)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def detect_rng() -> np.random.Generator:
    return np.random.default_rng(7)
