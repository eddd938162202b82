"""Rig and calibration paths that are not what they should be: one clear line and exit 2, never a
traceback, never a hang (issue 15). The daemon's SIGHUP with such files is tests/pipeline/test_run_live.py's."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from trackerd.config.loader import MAX_TOML_BYTES
from trackerd.files import MAX_DEPTH, nesting_depth

REPO = Path(__file__).resolve().parents[2]


def _trackerd(*args: str | Path) -> subprocess.CompletedProcess[str]:
    # The timeout is a guard only: every case answers at once.
    return subprocess.run(
        [sys.executable, "-m", "trackerd", *map(str, args)], capture_output=True, text=True, timeout=60
    )


def _one_line(run: subprocess.CompletedProcess[str], command: str, *fragments: str) -> None:
    assert run.returncode == 2, (run.returncode, run.stderr)
    assert "Traceback" not in run.stderr, run.stderr
    lines = [line for line in run.stderr.splitlines() if line.startswith(f"trackerd {command}:")]
    assert len(lines) == 1, run.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def _hostile(tmp_path: Path) -> list[tuple[Path, str]]:
    """(path, what its one line must say) for each kind of hostile rig path."""
    nested = tmp_path / "nested.toml"
    nested.write_text("version = 1\nname = 'x'\nbad = " + "[" * 1200 + "]" * 1200 + "\n")
    deep = tmp_path / "deep.toml"
    deep.write_text("version = 1\nname = 'x'\nbad = " + "[" * 40 + "]" * 40 + "\n")
    fifo = tmp_path / "rig.fifo"
    os.mkfifo(fifo)
    large = tmp_path / "large.toml"
    with large.open("wb") as handle:
        handle.truncate(MAX_TOML_BYTES + 1)
    return [
        (nested, "nested too deeply to be a rig or calibration file"),
        (deep, f"nested more than {MAX_DEPTH} levels deep"),
        (fifo, "not a regular file (a FIFO); expected a TOML file"),
        (Path("/dev/zero"), "not a regular file (a device)"),
        (large, "larger than such a file can be"),
    ]


def test_config_check_and_run_refuse_hostile_rig_files_in_one_line(tmp_path: Path) -> None:
    for path, says in _hostile(tmp_path):
        _one_line(_trackerd("config", "check", path), "config", str(path), says)
        # The daemon at start: exit 2 (systemd's RestartPreventExitStatus=2 stops a restart loop).
        _one_line(_trackerd("run", "--config", path), "run", says)


def test_a_hostile_calibration_file_is_named_as_the_calibration(tmp_path: Path) -> None:
    rig = (REPO / "config" / "simulated.toml").read_text()
    for path, says in _hostile(tmp_path):
        rig_file = tmp_path / f"rig-{path.name}.toml"
        rig_file.write_text(rig.replace('name = "simulated-datawall"', f'name = "x"\ncalibration = "{path}"'))
        _one_line(_trackerd("config", "check", rig_file), "config", str(path), says)


@pytest.mark.parametrize(
    ("value", "depth"),
    [
        (1, 0),
        ({}, 1),
        ([[1], {"a": [2]}], 3),
        ({"a": {"b": {"c": [[[]]]}}}, 6),
    ],
)
def test_nesting_depth_counts_tables_and_arrays(value, depth) -> None:
    assert nesting_depth(value) == depth


def test_nesting_depth_stops_counting_past_its_limit_without_recursion() -> None:
    value: list = []
    for _ in range(100_000):  # far past Python's recursion limit
        value = [value]
    assert MAX_DEPTH < nesting_depth(value) <= MAX_DEPTH + 1


def test_an_integer_too_long_for_python_is_one_line_not_a_traceback(tmp_path: Path) -> None:
    """Found by tests/test_fuzz.py: tomllib reads integers with int(), which refuses more than 4300
    digits with a plain ValueError (not a TOMLDecodeError), and that escaped load_rig."""
    rig = tmp_path / "rig.toml"
    text = (REPO / "config" / "simulated.toml").read_text()
    rig.write_text(text.replace("width_px = 1920", "width_px = " + "9" * 5000, 1))
    _one_line(_trackerd("config", "check", rig), "config", str(rig), "not valid TOML", "4300 digits")


def test_keys_and_tags_with_line_breaks_are_quoted_on_one_line(tmp_path: Path) -> None:
    """Found by tests/test_fuzz.py: a key or a union tag holding a line break, a carriage return or
    another character a log breaks lines at (U+001E, U+2028) was echoed as it is, so the one-line
    error became several. They are quoted with escapes, as TOML would spell them."""
    from trackerd.config.loader import load_calibration, load_rig
    from trackerd.errors import ConfigError

    rig = tmp_path / "rig.toml"
    rig.write_text(
        (REPO / "config" / "simulated.toml")
        .read_text()
        .replace('name = "simulated-datawall"', 'name = "x"\ncalibration = "cal.toml"')
    )
    calibration = tmp_path / "cal.toml"
    cases = [
        ('"bad\\nkey" = 1', 'unknown key "bad\\nkey"'),
        ('"\\u001e" = 0', 'unknown key "\\u001e"'),
        ('[cameras."left\\u2028right"]', 'cameras."left\\u2028right": no camera with this id'),
        (
            '[cameras.right]\nextrinsics = { kind = "\\r", position_m = [1.0, 2.0, 3.0] }',
            "cameras.right.extrinsics: tag \"\\r\" in key 'kind'",
        ),
    ]
    for text, says in cases:
        calibration.write_text(f"version = 1\n{text}\n")
        with pytest.raises(ConfigError) as raised:
            load_rig(rig)
        assert len(str(raised.value).splitlines()) == 1 and says in str(raised.value), str(raised.value)
    calibration.write_text('version = 1\n"it\'s" = 1\n')
    with pytest.raises(ConfigError, match='unknown key "it\'s"'):
        load_calibration(calibration)
