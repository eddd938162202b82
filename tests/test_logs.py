"""Log lines on a stream that is journald's (JOURNAL_STREAM names it) and on any other (issue 15).

The streams are real pipes, so ``os.fstat`` sees a real device and inode; what systemd would
put in JOURNAL_STREAM is built from them the way systemd builds it ("%lu:%lu" of st_dev, st_ino).
"""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from trackerd.logs import is_journal_stream, journal_priority, stderr_handler

TIMESTAMP = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} ")


class Pipe:
    """A real pipe: handlers and children write into ``write_fd``; :meth:`text` closes it and reads all."""

    def __init__(self) -> None:
        self.read_fd, self.write_fd = os.pipe()

    def journal_stream(self) -> str:
        """JOURNAL_STREAM as systemd would set it were this pipe the journal's stream."""
        status = os.fstat(self.write_fd)
        return f"{status.st_dev}:{status.st_ino}"

    def text(self) -> str:
        self.close_write_end()
        with os.fdopen(self.read_fd, "r") as reader:
            self.read_fd = -1
            return reader.read()

    def close_write_end(self) -> None:
        if self.write_fd >= 0:
            os.close(self.write_fd)
            self.write_fd = -1

    def close(self) -> None:
        self.close_write_end()
        if self.read_fd >= 0:
            os.close(self.read_fd)


@pytest.fixture
def pipe() -> Iterator[Pipe]:
    pipe = Pipe()
    yield pipe
    pipe.close()


def _other_inode(tmp_path: Path) -> str:
    """JOURNAL_STREAM naming a file that is not the stream written to."""
    other = tmp_path / "other"
    other.write_text("")
    return f"{other.stat().st_dev}:{other.stat().st_ino}"


def _logged(pipe: Pipe, emit) -> str:
    """What a handler built for the pipe writes when ``emit(logger)`` logs."""
    with os.fdopen(os.dup(pipe.write_fd), "w") as stream:
        logger = logging.getLogger("trackerd.test_logs")
        logger.propagate = False
        logger.setLevel(logging.DEBUG)
        handler = stderr_handler(stream)
        logger.addHandler(handler)
        try:
            emit(logger)
        finally:
            logger.removeHandler(handler)
    return pipe.text()


def test_a_warning_on_the_journals_stream_has_priority_4_and_no_timestamp(pipe, monkeypatch):
    monkeypatch.setenv("JOURNAL_STREAM", pipe.journal_stream())
    text = _logged(pipe, lambda log: log.warning("camera %s lost", "left"))
    assert text == "<4>WARNING trackerd.test_logs: camera left lost\n"


def test_every_line_of_a_traceback_carries_the_records_priority(pipe, monkeypatch):
    monkeypatch.setenv("JOURNAL_STREAM", pipe.journal_stream())

    def emit(log: logging.Logger) -> None:
        try:
            raise RuntimeError("stalled")
        except RuntimeError:
            log.exception("pipeline failed")

    lines = _logged(pipe, emit).splitlines()
    assert lines[0] == "<3>ERROR trackerd.test_logs: pipeline failed"
    assert lines[1] == "<3>Traceback (most recent call last):"
    assert lines[-1] == "<3>RuntimeError: stalled"
    assert all(line.startswith("<3>") for line in lines)


def test_another_inode_in_journal_stream_keeps_the_plain_timestamped_format(pipe, tmp_path, monkeypatch):
    # What a child of a unit sees after `2>file`: the variable inherited, the stream not journald's.
    monkeypatch.setenv("JOURNAL_STREAM", _other_inode(tmp_path))
    text = _logged(pipe, lambda log: log.warning("camera left lost"))
    assert TIMESTAMP.match(text), text
    assert text.endswith(" WARNING trackerd.test_logs: camera left lost\n")


@pytest.mark.parametrize("value", ["", "12", "a:b", "12:", ":34", "-1:-2", "1:2:3"])
def test_a_malformed_journal_stream_is_not_the_journal(value, pipe):
    with os.fdopen(os.dup(pipe.write_fd), "w") as stream:
        assert not is_journal_stream(stream, {"JOURNAL_STREAM": value})
        assert is_journal_stream(stream, {"JOURNAL_STREAM": pipe.journal_stream()})


def test_priorities_follow_sd_daemon():
    levels = [logging.CRITICAL, logging.ERROR, logging.WARNING, 25, logging.INFO, logging.DEBUG, 5]
    assert [journal_priority(level) for level in levels] == [2, 3, 4, 5, 6, 7, 7]


def _stderr_of_a_config_error(pipe: Pipe, journal_stream: str) -> str:
    """stderr of `trackerd listen --topic hits` (a configuration error, exit 2) written into the pipe."""
    env = {**os.environ, "JOURNAL_STREAM": journal_stream}
    result = subprocess.run(
        [sys.executable, "-m", "trackerd", "listen", "--topic", "hits"],
        stdout=subprocess.PIPE,
        stderr=pipe.write_fd,
        env=env,
        timeout=60,
    )
    assert result.returncode == 2 and result.stdout == b""
    return pipe.text()


def test_the_clis_one_line_error_has_priority_3_on_the_journals_stream(pipe):
    err = _stderr_of_a_config_error(pipe, pipe.journal_stream())
    assert err.startswith("<3>trackerd listen: --topic hits: trackerd publishes no such topic;"), err


def test_the_clis_one_line_error_is_plain_on_another_stream(pipe, tmp_path):
    err = _stderr_of_a_config_error(pipe, _other_inode(tmp_path))
    assert err.startswith("trackerd listen: --topic hits: trackerd publishes no such topic;"), err
