"""Under a real journald, trackerd's lines keep their priority (issue 15).

Runs trackerd in transient units (systemd-run), whose standard error systemd connects to
journald and names in JOURNAL_STREAM, and asks `journalctl -p` for the lines. It needs systemd
as PID 1 and root; elsewhere it is skipped (tests/test_logs.py covers the same on pipes).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.root


def _no_journal() -> str | None:
    if not Path("/run/systemd/system").is_dir():  # sd_booted(3)'s test
        return "systemd is not PID 1 here (no /run/systemd/system): no journald to log into"
    if os.geteuid() != 0:
        return "needs root to start transient system units"
    for tool in ("systemd-run", "journalctl"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed"
    return None


def _run_in_unit(unit: str, *command: str) -> None:
    """Run ``command`` in the transient service ``unit`` and wait for it to finish."""
    subprocess.run(
        [
            "systemd-run",
            "--quiet",
            "--wait",
            "--collect",
            f"--unit={unit}",
            f"--setenv=PYTHONPATH={REPO}",
            "--property=SyslogIdentifier=trackerd-journal-test",
            *command,
        ],
        check=False,
        timeout=120,
    )


def _journal_lines(unit: str, priority: str, wanted: str, timeout_s: float = 30.0) -> list[str]:
    """The unit's messages at ``priority`` or worse, once one containing ``wanted`` is there
    (journald may store a stream's lines after the unit has exited)."""
    deadline = time.monotonic() + timeout_s
    while True:
        out = subprocess.run(
            ["journalctl", "--no-pager", "-o", "cat", "-u", unit, "-p", priority],
            capture_output=True,
            text=True,
            timeout=30,
        ).stdout
        lines = out.splitlines()
        if any(wanted in line for line in lines) or time.monotonic() > deadline:
            return lines
        time.sleep(0.2)


def test_journalctl_sees_trackerds_warnings_and_errors_at_their_priority():
    reason = _no_journal()
    if reason:
        pytest.skip(reason)
    token = uuid.uuid4().hex[:12]
    unit = f"trackerd-journal-test-{token}"
    probe = (
        "import logging; from trackerd import logs; logs.configure(logging.INFO);"
        f"log = logging.getLogger('trackerd.journal_test'); log.info('info {token}'); log.warning('warning {token}')"
    )
    _run_in_unit(unit, sys.executable, "-c", probe)
    warnings = _journal_lines(unit, "warning", f"warning {token}")
    assert f"WARNING trackerd.journal_test: warning {token}" in warnings, warnings
    assert not any(f"info {token}" in line for line in warnings)
    everything = _journal_lines(unit, "debug", f"info {token}")
    assert f"INFO trackerd.journal_test: info {token}" in everything, everything  # no "<6>", no timestamp

    # The CLI's own one-line error (a configuration error, exit 2) is an error in the journal.
    _run_in_unit(f"{unit}-cli", sys.executable, "-m", "trackerd", "listen", "--topic", f"hits{token}")
    errors = _journal_lines(f"{unit}-cli", "err", f"--topic hits{token}")
    assert any(
        line.startswith(f"trackerd listen: --topic hits{token}: trackerd publishes no such topic") for line in errors
    ), errors
