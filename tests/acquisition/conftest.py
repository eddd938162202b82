"""Fixtures of the acquisition tests; helpers and skip markers are in acq_helpers.py."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def out_dir(tmp_path: Path) -> Path:
    """Where a virtual rig writes its ground truth and camera logs."""
    return tmp_path / "simrig"
