"""A camera's backend in the rig file: what each backend accepts, in one line naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackerd.config.loader import load_rig
from trackerd.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]


def rig_text(camera_lines: str) -> str:
    text = (REPO / "config" / "gentl-emulated.toml").read_text()
    return text.replace('id = "right"\nbackend = "pylon"\nserial = "0815-0001"', 'id = "right"\n' + camera_lines, 1)


def test_the_gentl_example_reaches_both_cameras_through_pylon() -> None:
    rig = load_rig(REPO / "config" / "gentl-emulated.toml").config
    assert [(c.backend, c.serial) for c in rig.cameras] == [("pylon", "0815-0000"), ("pylon", "0815-0001")]
    assert list(rig.cameras[0].features) == ["TestImageSelector", "ImageFileMode"]


def test_a_rig_may_mix_backends(tmp_path: Path) -> None:
    text = rig_text('serial = "SIM-RIGHT"')
    features = '[cameras.features]\nTestImageSelector = "Testimage1"\nImageFileMode = "Off"\n'
    head, tail = text.rsplit(features, 1)  # the right camera's, which Aravis would not write
    path = tmp_path / "rig.toml"
    path.write_text(head + tail)
    rig = load_rig(path).config
    assert [c.backend for c in rig.cameras] == ["pylon", "aravis"]


@pytest.mark.parametrize(
    ("camera_lines", "message"),
    [
        ('backend = "pylon"\naddress = "10.0.0.2"', "a camera with backend = 'pylon' is found by serial or device_id"),
        ('backend = "harvesters"\nserial = "X"', "backend"),
    ],
)
def test_what_a_backend_cannot_take_is_refused(tmp_path: Path, camera_lines: str, message: str) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(rig_text(camera_lines))
    with pytest.raises(ConfigError, match=message) as info:
        load_rig(path)
    assert "cameras[1]" in str(info.value) and "\n" not in str(info.value)


def test_features_are_for_the_pylon_backend_only(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(rig_text('serial = "SIM-RIGHT"'))  # the right camera keeps its [cameras.features]
    with pytest.raises(ConfigError, match="features are written by the pylon and gentl backends only"):
        load_rig(path)
