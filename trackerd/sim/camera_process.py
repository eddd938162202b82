"""One simulated GigE Vision camera (:mod:`trackerd.sim.gvcamera`) as a child process of the virtual rig.

The process is started in its own process group, answers "ready" on stdout once
it serves, logs to a file, and can be stopped (politely, then by force), killed
at once (a crash or a pulled cable) and started again at the same address.
"""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
from pathlib import Path
from typing import IO

from trackerd.errors import CameraError

READY_TIMEOUT_S = 15.0


def read_line(process: subprocess.Popen[str], timeout_s: float) -> str:
    """One line of the process's stdout, or '' if it exits or says nothing within ``timeout_s``."""
    if process.stdout is None:
        raise ValueError("the process was started without a pipe for its stdout")
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        if not selector.select(timeout_s):
            return ""
    return process.stdout.readline()


def gvcamera_command(
    *,
    exec_prefix: list[str],
    interface: str,
    serial: str,
    label: str,
    start_ns: int,
    clock: tuple[int, float],
    phase_us: float,
    truth_out: Path,
    loop: tuple[Path, Path, float] | None,
    size_px: tuple[int, int],
) -> list[str]:
    """The command line of a simulated camera: its identity, clock and capture phase, where its truth
    goes, and what it serves: ``loop`` (frames file, truth file, loop frames per second) or, when None,
    a synthetic moving square of ``size_px`` (width, height). ``exec_prefix`` runs it elsewhere (in a
    network namespace)."""
    offset_ns, drift_ppm = clock
    command = [
        *exec_prefix,
        sys.executable,
        "-m",
        "trackerd.sim.gvcamera",
        "--interface",
        interface,
        "--serial",
        serial,
        "--label",
        label,
        "--start-ns",
        str(start_ns),
        "--clock-offset-ns",
        str(offset_ns),
        "--clock-drift-ppm",
        str(drift_ppm),
        "--phase-us",
        f"{phase_us:.1f}",
        "--parent-pid",
        str(os.getpid()),
    ]
    command += ["--truth-out", str(truth_out)]
    if loop is None:
        command += ["--synthetic", f"{size_px[0]}x{size_px[1]}"]
    else:
        frames, truth, content_fps = loop
        command += ["--loop", str(frames), "--loop-truth", str(truth)]
        command += ["--content-fps", str(content_fps)]
    return command


class CameraProcess:
    """A simulated camera's process: started by :meth:`spawn`, ended by :meth:`terminate` or :meth:`kill`."""

    def __init__(self, index: int, label: str, command: list[str]) -> None:
        self.index = index
        self.label = label
        self.command = command
        self.process: subprocess.Popen[str] | None = None
        self.log: IO[str] | None = None

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def spawn(self, env: dict[str, str], log_path: Path) -> None:
        """Start the camera and wait until it says it is ready (CameraError if it does not)."""
        self.log = log_path.open("a")
        # Its own process group: a Ctrl-C in the terminal then reaches the daemon and not the cameras,
        # which are stopped after it. Sharing the group, they vanished under a daemon still streaming
        # from them, and its acquisition threads were reported as not stopping in time.
        self.process = subprocess.Popen(
            self.command, stdout=subprocess.PIPE, stderr=self.log, text=True, env=env, process_group=0
        )
        line = read_line(self.process, READY_TIMEOUT_S)
        if not line.startswith("ready"):
            self.terminate()
            detail = line.strip() or f"no answer in {READY_TIMEOUT_S:g} s; see {log_path}"
            raise CameraError(f"simulated camera '{self.label}' did not start: {detail}")

    def kill(self) -> None:
        """Kill the process at once (SIGKILL), as a crash or a pulled cable would."""
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait(5)

    def terminate(self) -> None:
        """Stop the process (SIGTERM, then SIGKILL after 3 s) and close its pipe and log."""
        process = self.process
        if process is not None:
            if process.poll() is None:
                process.terminate()
                try:
                    process.wait(3)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait(3)
            if process.stdout is not None:
                process.stdout.close()
            self.process = None
        if self.log is not None:
            self.log.close()
            self.log = None
