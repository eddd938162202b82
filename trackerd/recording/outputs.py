"""Where record, snap, import and export write: checked before any camera opens or any work is done.

A command that would fail to write its output only after taking a pair (snap)
or opening the cameras (record) loses that work; each checks its output here
first and says what is wrong in one line (RecordingError).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from trackerd.errors import RecordingError


def existing_ancestor(path: Path) -> Path:
    """The nearest of ``path`` and its parents that exists (the folder a new path would be made in)."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def output_folder(path: str | Path) -> Path:
    """Create the folder ``path`` (and its parents) if missing and check a file can be written in it;
    RecordingError naming the path otherwise."""
    from trackerd.recording.format import METADATA_FILE

    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise RecordingError(f"{folder}: exists and is not a folder; give a folder to write into")
    if (folder / METADATA_FILE).exists():
        # Images and a CSV among a recording's files would be taken for part of it.
        raise RecordingError(f"{folder}: is a recording; give another folder to write into")
    base = existing_ancestor(folder)
    if not base.is_dir():
        raise RecordingError(f"{folder}: cannot create the folder: {base} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise RecordingError(f"{folder}: cannot create the folder ({err.strerror or err})") from None
    _try_writing(folder, f"{folder}: cannot write into the folder")
    return folder


def check_new_recording(path: str | Path) -> Path:
    """Check that a new recording can be created at ``path`` (it does not exist, or is an empty
    folder, and the folder it goes in can be written), without creating anything."""
    out = Path(path)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RecordingError(f"{out}: already exists; give a new name for the recording")
    base = existing_ancestor(out)
    if not base.is_dir():
        raise RecordingError(f"{out}: cannot create the recording: {base} is a file, not a folder")
    _try_writing(base, f"{out}: cannot create the recording in {base}")
    return out


def _try_writing(folder: Path, failure: str) -> None:
    """Write a file in ``folder`` and remove it; RecordingError ``failure (reason)`` if that fails.

    A real write, not os.access: that says yes to root on a filesystem that refuses all writes.
    """
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise RecordingError(f"{failure} ({err.strerror or err})") from None
