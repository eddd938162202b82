"""`trackerd config check` refuses what the interaction stage would refuse at start, with the same line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from trackerd.cli.run import build_extensions
from trackerd.config.loader import load_rig
from trackerd.errors import ConfigError
from trackerd.interaction.extension import create
from trackerd.pipeline.extensions import ExtensionContext

SIMULATED = Path(__file__).resolve().parents[2] / "config" / "simulated.toml"


def _rig_file(tmp_path: Path, extra: str) -> Path:
    # The simulated rig's file (it names no other file) with an [interaction] part of the test's own,
    # whose relative paths are relative to the copy.
    path = tmp_path / "rig.toml"
    path.write_text(SIMULATED.read_text(encoding="utf-8") + "\n" + extra, encoding="utf-8")
    return path


def _check(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "trackerd", "config", "check", str(path)], capture_output=True, text=True, timeout=60
    )


def _malformed(tmp_path: Path) -> str:
    (tmp_path / "gestures").mkdir()
    (tmp_path / "gestures" / "zigzag.json").write_text('{"format": "trackerd-gesture-template", "version": 1,')
    return '[interaction.gestures]\ntemplate_dir = "gestures"\n'


@pytest.mark.parametrize(
    ("make", "text"),
    [
        (lambda tmp: '[interaction.commands]\nbogus_trigger = "x"\n', "no gesture or event called bogus_trigger"),
        (lambda tmp: '[interaction.gestures]\ntemplate_dir = "nowhere"\n', "gesture template directory does not exist"),
        (_malformed, "zigzag.json: not JSON"),
        (lambda tmp: '[interaction.hand]\nenabled = true\ncamera = "middle"\n', "no camera 'middle'"),
    ],
    ids=["unknown trigger", "missing template_dir", "malformed template", "unknown hand camera"],
)
def test_config_check_refuses_what_the_daemon_refuses(tmp_path, make, text):
    path = _rig_file(tmp_path, make(tmp_path))
    loaded = load_rig(path)
    with pytest.raises(ConfigError) as refused:
        build_extensions(loaded.config, ExtensionContext(rig_file=loaded.path))  # what run and replay build at start
    done = _check(path)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    # The same line, naming the rig file first as every configuration error does.
    assert done.stderr == f"trackerd config: {refused.value}\n" and text in done.stderr
    assert str(refused.value).startswith(f"{loaded.path}: ")


def test_config_check_accepts_what_the_daemon_accepts(tmp_path):
    (tmp_path / "gestures").mkdir()
    path = _rig_file(
        tmp_path,
        '[interaction.gestures]\ntemplate_dir = "gestures"\n[interaction.commands]\nswipe_left = "previous_slide"\n',
    )
    assert create(load_rig(path).config) is not None
    done = _check(path)
    assert done.returncode == 0 and ": OK, rig" in done.stdout, done.stderr
