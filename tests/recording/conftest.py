"""Fixtures of the recording tests: the bundled recording and its ground truth."""

from __future__ import annotations

import json
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
