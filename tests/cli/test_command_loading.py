"""`trackerd COMMAND` imports only that command's module; the parser it builds is the full one's."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from trackerd.cli.main import _command_modules, build_parser


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


COMMANDS = sorted(_commands(build_parser()))


def test_every_command_module_defines_its_command():
    assert sorted(name.replace("_", "-") for name in _command_modules()) == COMMANDS
    assert {"run", "listen", "calibrate", "cpu-latency", "replay"} <= set(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_a_command_built_alone_has_the_same_arguments_and_help(command):
    alone = _commands(build_parser(["--log-level", "info", command]))
    assert sorted(alone) == COMMANDS  # the others are still known by name, for argparse's messages
    assert alone[command].format_help() == _commands(build_parser())[command].format_help()


def test_a_light_command_starts_without_opencv_or_the_config_models():
    probe = (
        "import sys; from trackerd.cli.main import build_parser;"
        "build_parser(['keys', 'server']).parse_args(['keys', 'server']);"
        "print(sorted(m for m in ('cv2', 'trackerd.config.models', 'gi') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize(
    "argv", [["--help"], ["-h", "run"], ["--version", "keys"], ["nosuch"], ["--log-level", "debug"]]
)
def test_without_a_known_command_every_command_is_loaded(argv):
    loaded, full = _commands(build_parser(argv)), _commands(build_parser())
    assert [c for c in COMMANDS if loaded[c].format_help() != full[c].format_help()] == []


@pytest.mark.parametrize("command", ["run", "replay", "record", "demo", "simrig"])
@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "soon"])
def test_seconds_must_be_a_positive_number(command, value, capsys):
    # Regression: `trackerd run --seconds 0` (or -1) ran for a moment and exited 0.
    rig = ["--config", "rig.toml"]
    needed = {"run": rig, "replay": ["session.trec"], "record": [*rig, "out.trec"], "simrig": rig, "demo": []}
    required = needed[command]
    with pytest.raises(SystemExit) as exit_:
        build_parser([command]).parse_args([command, *required, "--seconds", value])
    assert exit_.value.code == 2
    assert f"argument --seconds: must be a positive number of seconds, not '{value}'" in capsys.readouterr().err
    assert build_parser([command]).parse_args([command, *required, "--seconds", "2.5"]).seconds == 2.5


def test_the_global_options_are_not_abbreviated(capsys):
    with pytest.raises(SystemExit) as exit_:
        build_parser(["--he", "keys", "server"]).parse_args(["--he", "keys", "server"])
    assert exit_.value.code == 2 and "unrecognized arguments: --he" in capsys.readouterr().err


def _every_parser(parser: argparse.ArgumentParser, path: str = "trackerd"):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _every_parser(sub, f"{path} {name}")


def test_every_commands_help_formats():
    """`--help` of every command and subcommand, `calibrate intrinsics` included (a bare '%' in a help
    text made it a traceback)."""
    broken = []
    for path, parser in _every_parser(build_parser()):
        try:
            parser.format_help()
        except (ValueError, TypeError, KeyError) as err:
            broken.append(f"{path}: {err}")
    assert broken == []
    assert sum(1 for _ in _every_parser(build_parser())) > len(COMMANDS)
