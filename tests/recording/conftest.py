"""Fixtures of the recording tests: the bundled recording and its ground truth."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest
from rec_helpers import BUNDLE, DATA


@pytest.fixture(scope="session")
def bundle() -> Path:
    return BUNDLE


@pytest.fixture(scope="session")
def bundle_truth() -> list[dict[str, Any]]:
    return json.loads((DATA / "truth.json").read_text())["pairs"]


@pytest.fixture
def small_disk(tmp_path):
    """A real 12 MB filesystem (tmpfs) to fill: three raw pairs of two 1080p Bayer frames."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small filesystem needs root")
    mount = tmp_path / "small"
    mount.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=12m", "tmpfs", str(mount)], check=True)
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)
