"""The bundled example rigs (trackerd/config/examples.py) are the top-level config/ files, and load."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackerd.config.examples import EXAMPLE_RIGS, example_rig
from trackerd.config.loader import load_rig

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", EXAMPLE_RIGS)
def test_each_bundled_example_is_the_config_folder_file_and_loads(name: str) -> None:
    path = example_rig(name)
    assert path.read_bytes() == (REPO / "config" / f"{name}.toml").read_bytes()
    assert load_rig(path).config.cameras


def test_every_example_in_config_is_listed() -> None:
    assert sorted(p.stem for p in (REPO / "config").glob("*.toml")) == sorted(EXAMPLE_RIGS)


def test_an_unknown_example_names_the_ones_there_are() -> None:
    with pytest.raises(ValueError, match="there are datawall, simulated"):
        example_rig("nope")
