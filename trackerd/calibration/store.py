"""Reading a rig for calibration, and writing its calibration file safely.

Calibrating a new installation starts from a rig file whose cameras have no
intrinsics or extrinsics yet, and whose calibration file may not exist, so the
rig is read leniently here (:func:`open_rig`), unlike ``load_rig`` which insists
on a complete geometry.

Writing (:func:`write_calibration`): the new file is rendered to TOML, read
back and validated (on its own and merged into the rig) before anything
touches the disk; then it is written to a temporary file in the same
directory, flushed to disk, the previous file is copied to
``NAME.bak-YYYYmmdd-HHMMSS``, and the temporary file is renamed over it. A
crash at any point leaves either the old file or the new one, never half of one.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import os
import shutil
import stat
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from trackerd.calibration import CalibrationError
from trackerd.config.loader import describe_validation_error, load_calibration, merge_calibration, parse_rig, read_toml
from trackerd.config.models import CALIBRATION_ONLY_FORMAT, CalibrationFile, RigConfig
from trackerd.config.tomlwrite import dumps
from trackerd.errors import ConfigError

WORLD_FRAME_KEY = "world_frame"
"""Key in a camera's ``info`` table naming the frame its extrinsics are in: ``wall`` or ``camera <id>``."""


@dataclass(frozen=True)
class RigContext:
    """A rig read for calibration: its configuration (possibly incomplete) and its calibration file."""

    rig: RigConfig
    rig_path: Path
    calibration_path: Path | None
    """Where the calibration is written: the rig's ``calibration`` file or an explicit --output."""
    calibration: CalibrationFile
    """The calibration file's current content (empty when it does not exist yet)."""

    def merged(self, calibration: CalibrationFile | None = None) -> RigConfig:
        """The rig with the calibration merged in (the current one, or ``calibration``)."""
        calibration = calibration if calibration is not None else self.calibration
        where = self.calibration_path or self.rig_path
        return merge_calibration(self.rig, calibration, where)

    def complete(self, calibration: CalibrationFile | None = None) -> RigConfig:
        """The merged rig, requiring every camera to have intrinsics and extrinsics."""
        rig = self.merged(calibration)
        for cam in rig.cameras:
            if cam.pixel_format == CALIBRATION_ONLY_FORMAT:
                raise CalibrationError(
                    f"camera '{cam.id}' is {cam.pixel_format}: this step locates the pointer, whose red and"
                    " blue ends only a colour camera tells apart (intrinsics and stereo take Mono8)"
                )
            missing = [part for part in ("intrinsics", "extrinsics") if getattr(cam, part) is None]
            if missing:
                raise CalibrationError(
                    f"camera '{cam.id}' has no {' or '.join(missing)} yet; run"
                    f" `trackerd calibrate {'intrinsics' if 'intrinsics' in missing else 'stereo'}` first"
                )
        if rig.wall is None or rig.pointer is None:
            tables = " and ".join(f"[{t}]" for t, v in (("wall", rig.wall), ("pointer", rig.pointer)) if v is None)
            raise CalibrationError(
                f"{self.rig_path}: no {tables} table: this step locates the pointer on the wall; see"
                " config/datawall.toml for one (the wall's nominal size is enough before `calibrate wall`)"
            )
        return rig


def open_rig(rig_path: str | Path, output: str | Path | None = None) -> RigContext:
    """Read a rig file without requiring its geometry, and its calibration file if it exists.

    ``output`` overrides where the calibration is read from and written to.
    """
    path = Path(rig_path)
    rig = parse_rig(read_toml(path), path)
    if output is not None:
        calibration_path: Path | None = Path(output).resolve()
    elif rig.calibration is not None:
        calibration_path = (path.parent / rig.calibration).resolve()
    else:
        calibration_path = None
    calibration = CalibrationFile()
    if calibration_path is not None and calibration_path.exists():
        calibration = load_calibration(calibration_path)
    return RigContext(rig, path, calibration_path, calibration)


def require_output(context: RigContext) -> Path:
    """The calibration path, or a clear error saying how to name one."""
    if context.calibration_path is None:
        raise CalibrationError(
            f"{context.rig_path}: the rig names no calibration file; add"
            ' calibration = "NAME-calibration.toml" to it, or pass --output FILE'
        )
    return context.calibration_path


def with_camera(calibration: CalibrationFile, camera_id: str, **changes: Any) -> CalibrationFile:
    """A copy of ``calibration`` with one camera's entry updated (``info`` entries are merged)."""
    data = calibration_dict(calibration)
    cameras = data.setdefault("cameras", {})
    entry = cameras.setdefault(camera_id, {})
    info = dict(entry.get("info", {}))
    info.update(changes.pop("info", {}))
    for key, value in changes.items():
        if value is None:
            entry.pop(key, None)
        else:
            entry[key] = value.model_dump(mode="json", exclude_none=True) if hasattr(value, "model_dump") else value
    entry["info"] = info
    return validated(data)


def with_wall(calibration: CalibrationFile, wall: Any) -> CalibrationFile:
    """A copy of ``calibration`` with its [wall] table replaced (None removes it)."""
    data = calibration_dict(calibration)
    if wall is None:
        data.pop("wall", None)
    else:
        data["wall"] = wall.model_dump(mode="json", exclude_none=True) if hasattr(wall, "model_dump") else wall
    return validated(data)


def with_pointer_colours(calibration: CalibrationFile, colours: Any) -> CalibrationFile:
    """A copy of ``calibration`` with its [pointer_colours] table replaced."""
    data = calibration_dict(calibration)
    data["pointer_colours"] = colours.model_dump(mode="json")
    return validated(data)


def validated(data: dict[str, Any]) -> CalibrationFile:
    """Validate calibration data built in code (a bug if it fails: the inputs were validated)."""
    try:
        return CalibrationFile.model_validate(data)
    except ValidationError as err:
        raise CalibrationError(f"invalid calibration: {describe_validation_error(err, CalibrationFile)}") from err


def calibration_dict(calibration: CalibrationFile) -> dict[str, Any]:
    """The calibration as plain data, in the order the file is written, without unset keys."""
    data = calibration.model_dump(mode="json", exclude_none=True, exclude_defaults=False)
    for entry in data.get("cameras", {}).values():
        if not entry.get("info"):
            entry.pop("info", None)
    wall = data.get("wall")
    if wall is not None and wall.get("planarity_tolerance_m") == 0.01:
        wall.pop("planarity_tolerance_m")
    return data


def render_calibration(calibration: CalibrationFile, header: str) -> str:
    """TOML text of a calibration file, checked to read back to the same calibration."""
    data = calibration_dict(calibration)
    text = dumps(data, header)
    try:
        again = CalibrationFile.model_validate(tomllib.loads(text))
    except (tomllib.TOMLDecodeError, ValidationError) as err:  # pragma: no cover - a writer bug
        raise CalibrationError(f"internal error: the calibration file would not read back: {err}") from err
    if again != validated(data):  # pragma: no cover - a writer bug
        raise CalibrationError("internal error: the calibration file would not read back unchanged")
    return text


def write_calibration(
    context: RigContext,
    calibration: CalibrationFile,
    header: str,
    *,
    check_wall: bool = True,
    now: _dt.datetime | None = None,
) -> Path | None:
    """Write ``calibration`` to the rig's calibration file atomically; return the backup's path (if any).

    The result is first merged into the rig and put through the loader's checks
    (every lens must invert out to the image corners; with ``check_wall``, every
    camera must be in front of the wall), so a file that ``trackerd config check``
    would refuse is never written. ``check_wall`` is off only while the cameras
    are in camera 1's frame and the wall is not calibrated yet.
    """
    path = require_output(context)
    try:
        merged = merge_calibration(context.rig, calibration, path)
        check_merged(merged, path, check_wall)
    except ConfigError as err:
        raise CalibrationError(f"not written: {err}") from err
    except ValidationError as err:  # pragma: no cover - merge_calibration wraps these
        raise CalibrationError(f"not written: {describe_validation_error(err, RigConfig)}") from err
    text = render_calibration(calibration, header)
    if not path.parent.is_dir():
        # A typo in --output must not create folders; the rig's own file sits beside the rig.
        raise CalibrationError(f"{path.parent}: no such folder; not written")
    backup = None
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as err:
        # A read-only or full file system, a folder the calibrating user may not write to.
        raise CalibrationError(f"{path}: cannot write the calibration file: {err.strerror or err}") from err
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            _same_access(handle.fileno(), path)
            os.fsync(handle.fileno())
        if path.exists():
            backup = backup_path(path, now)
            shutil.copy2(path, backup)
        os.replace(tmp_name, path)
    except OSError as err:
        raise CalibrationError(f"{path}: cannot write the calibration file: {err.strerror or err}") from err
    finally:
        if os.path.exists(tmp_name):
            os.unlink(tmp_name)
    _fsync_directory(path.parent)
    return backup


def _same_access(fd: int, path: Path) -> None:
    """Give the new file the old one's mode, owner and group (mkstemp makes it 0600, owned by whoever
    calibrates: the daemon's user, reading a root:trackerd 0640 file, would be locked out of it); a new
    file gets the mode the umask gives any file."""
    try:
        old = path.stat()
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        return
    os.fchmod(fd, stat.S_IMODE(old.st_mode))
    # Not root: the file stays the calibrating user's, with the old mode.
    with contextlib.suppress(PermissionError):
        os.fchown(fd, old.st_uid, old.st_gid)


def check_merged(rig: RigConfig, path: Path, check_wall: bool) -> None:
    """The loader's geometric checks on a merged rig (ConfigError naming ``path``), so that what
    is written is exactly what load_rig accepts."""
    from trackerd.config.rig_geometry import check_rig_geometry

    check_rig_geometry(rig, path, check_wall=check_wall)


def backup_path(path: Path, now: _dt.datetime | None = None) -> Path:
    """``NAME.bak-YYYYmmdd-HHMMSS`` next to ``path``, with a counter if that name is taken."""
    stamp = (now or _dt.datetime.now()).strftime("%Y%m%d-%H%M%S")
    candidate = path.with_name(f"{path.name}.bak-{stamp}")
    counter = 2
    while candidate.exists():
        candidate = path.with_name(f"{path.name}.bak-{stamp}-{counter}")
        counter += 1
    return candidate


def _fsync_directory(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def today() -> str:
    """The local date and time as written into ``info``: ``2026-11-22T14:03:05``."""
    return _dt.datetime.now().replace(microsecond=0).isoformat()
