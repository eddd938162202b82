"""backend = "gentl" in the rig file: the producer it needs, and what it cannot take, in one line naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackerd.config.loader import load_rig
from trackerd.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]


def rig_text(camera_lines: str) -> str:
    text = (REPO / "config" / "gentl-viky.toml").read_text()
    start = text.index('id = "right"\n')
    end = text.index("width_px", start)
    return text[:start] + 'id = "right"\n' + camera_lines + "\n" + text[end:]


def test_the_viky_example_reaches_both_cameras_through_a_producer() -> None:
    rig = load_rig(REPO / "config" / "gentl-viky.toml").config
    devices = [(c.backend, c.device_id) for c in rig.cameras]
    assert devices == [("gentl", "VikyTL_DEV_red"), ("gentl", "VikyTL_DEV_green")]
    assert all(c.producer and c.producer.endswith("viky.cti") for c in rig.cameras)


def test_a_rig_may_mix_gentl_and_aravis(tmp_path: Path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(rig_text('serial = "SIM-RIGHT"'))
    rig = load_rig(path).config
    assert [c.backend for c in rig.cameras] == ["gentl", "aravis"]
    assert rig.cameras[1].producer is None


@pytest.mark.parametrize(
    ("camera_lines", "message"),
    [
        ('backend = "gentl"\nserial = "1"', "backend = 'gentl' needs producer"),
        (
            'backend = "gentl"\nproducer = "/opt/x.cti"\naddress = "10.0.0.2"',
            "a camera with backend = 'gentl' is found by serial or device_id",
        ),
        ('backend = "pylon"\nserial = "1"\nproducer = "/opt/x.cti"', "producer is for backend = 'gentl'"),
        ('serial = "1"\nproducer = "/opt/x.cti"', "producer is for backend = 'gentl'"),
        ('backend = "gentl"\nproducer = 3\nserial = "1"', "producer"),
    ],
)
def test_what_the_gentl_backend_cannot_take_is_refused(tmp_path: Path, camera_lines: str, message: str) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(rig_text(camera_lines))
    with pytest.raises(ConfigError, match=message) as info:
        load_rig(path)
    assert "cameras[1]" in str(info.value) and "\n" not in str(info.value)
