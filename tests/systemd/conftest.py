"""Shared paths for the systemd tests."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
UNIT = REPO / "systemd" / "trackerd.service"


@pytest.fixture
def unit_path() -> Path:
    return UNIT
