"""Runs a command under the seccomp filters systemd 252 derives from a unit (as sandbox_probe.py
installs them for itself): the filters survive exec, so the command runs as it would in the unit.

Usage: filtered_exec.py UNIT_FILE COMMAND [ARG...] < SYSCALLS_JSON
"""

from __future__ import annotations

import json
import os
import sys

from sandbox_probe import apply_restrictions, unit_settings

if __name__ == "__main__":
    unit, *command = sys.argv[1:]
    syscalls = json.load(sys.stdin)
    apply_restrictions(unit_settings(unit), syscalls)
    os.execv(command[0], command)
