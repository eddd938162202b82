"""Loading rig and calibration files from TOML, with errors an operator can act on.

``load_rig(path)`` reads the rig file, reads the calibration file it names (if
any), lets the calibration's values replace the rig's, and checks that every
camera ends up with intrinsics and extrinsics. Any problem raises
:class:`~trackerd.errors.ConfigError` with one line of the form::

    rig.toml: cameras[1].pixel_format: Mono8 is monochrome and cannot ...

Beside it: reading the TOML (``tomlread``), strict validation and the one-line errors
(``validation``), what a valid rig still lacks to track (``readiness``), and a command's options
applied to a loaded rig (``overrides``); their public names are importable from here too.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from trackerd.config.models import (
    CalibrationFile,
    ColourThreshold,
    PointerColours,
    RigConfig,
)
from trackerd.config.overrides import dump_rig, with_console, with_endpoints
from trackerd.config.readiness import check_ready_to_track, pending_steps
from trackerd.config.tomlread import MAX_TOML_BYTES, read_toml
from trackerd.config.validation import describe_validation_error, format_location, key_text, strictly
from trackerd.errors import CalibrationPending, ConfigError

__all__ = [
    "MAX_TOML_BYTES",
    "LoadedRig",
    "check_ready_to_track",
    "describe_validation_error",
    "dump_rig",
    "format_location",
    "load_calibration",
    "load_rig",
    "merge_calibration",
    "parse_calibration",
    "parse_rig",
    "read_toml",
    "with_console",
    "with_endpoints",
    "with_learned_colours",
]


@dataclass(frozen=True)
class LoadedRig:
    """A validated rig, where it came from, and where each camera's calibration came from."""

    config: RigConfig
    path: Path
    calibration_path: Path | None
    sources: dict[str, str]
    """camera id (and 'wall') -> a short phrase naming the file its geometry was taken from."""
    threshold_sources: dict[str, str] | None = None
    """'red' / 'blue' -> where the detector's threshold for that end comes from: 'rig file'
    ([detector.<colour>]), 'learned' (pointer_colours) or 'default'."""


def parse_rig(data: dict[str, Any], path: Path) -> RigConfig:
    """Validate rig data read from ``path``; errors name the file."""
    try:
        rig = strictly(RigConfig, data)
    except ValidationError as err:
        raise ConfigError(f"{path}: {describe_validation_error(err, RigConfig)}") from err
    return rig if rig.pointer_colours is None else with_learned_colours(rig, rig.pointer_colours)


def with_learned_colours(rig: RigConfig, colours: PointerColours) -> RigConfig:
    """The rig with the pointer's learned colours, and the detector's threshold for each end taken from
    them unless the rig file gives ``[detector.red]`` / ``[detector.blue]`` itself (those stay overrides)."""
    given = rig.detector.model_fields_set
    learned = {
        colour: ColourThreshold(min_excess=colours.of(colour).min_excess, min_value=colours.of(colour).min_value)
        for colour in ("red", "blue")
        if colour not in given
    }
    return rig.model_copy(update={"pointer_colours": colours, "detector": rig.detector.model_copy(update=learned)})


def parse_calibration(data: dict[str, Any], path: Path) -> CalibrationFile:
    """Validate calibration data read from ``path``; errors name the file."""
    try:
        return strictly(CalibrationFile, data)
    except ValidationError as err:
        raise ConfigError(f"{path}: {describe_validation_error(err, CalibrationFile)}") from err


def load_calibration(path: Path) -> CalibrationFile:
    """Read and validate a calibration file on its own."""
    return parse_calibration(read_toml(path), path)


def load_rig(path: str | Path, *, for_tracking: bool = True) -> LoadedRig:
    """Read a rig file, merge its calibration file, and check the result can track.

    A rig that is valid but not ready to track (a calibration step still to run, no [wall] or
    [pointer], Mono8 cameras) raises CalibrationPending naming the first thing left, after everything
    that can be checked has been. ``for_tracking=False`` returns such a rig as it is, for commands that
    use only its cameras (``trackerd record``, ``recording import``: a board recorded for calibration).
    """
    rig_path = Path(path)
    data = read_toml(rig_path)
    rig = parse_rig(data, rig_path)
    detector = data.get("detector")
    detector_table: dict[str, Any] = detector if isinstance(detector, dict) else {}
    sources = {cam.id: f"inline in {rig_path.name}" for cam in rig.cameras}
    sources["wall"] = f"inline in {rig_path.name}"
    calibration_path: Path | None = None
    not_ready: list[CalibrationPending] = []
    frame = None
    if rig.calibration is not None:
        calibration_path = (rig_path.parent / rig.calibration).resolve()
        if not calibration_path.exists():
            not_ready.append(
                CalibrationPending(
                    rig_path,
                    f"calibration: {calibration_path}: no such file yet (the path is relative to the rig file);"
                    f" `trackerd calibrate intrinsics --config {rig_path.name} --camera {rig.cameras[0].id}` writes it",
                )
            )
        else:
            calibration = load_calibration(calibration_path)
            rig = merge_calibration(rig, calibration, calibration_path)
            sources.update(_calibration_sources(calibration, calibration_path, rig_path))
            frame = _unfinished_frame(calibration)
    not_ready += pending_steps(rig, rig_path, calibration_path, frame)
    # What can be checked is checked either way: every lens there is, and the wall against the cameras
    # once every camera is posed in the wall's frame.
    posed = all(cam.intrinsics is not None and cam.extrinsics is not None for cam in rig.cameras)
    # Imported here, not at the top: importing any config model runs this module, and NumPy and
    # OpenCV take a quarter of a second to import.
    from trackerd.config.rig_geometry import check_lens, check_wall_in_front

    if posed and rig.wall is not None and frame is None:
        check_wall_in_front(rig, rig_path if "inline" in sources["wall"] else calibration_path)
    rig = _resolve_paths(rig, rig_path)
    for index, cam in enumerate(rig.cameras):
        if cam.intrinsics is None or cam.extrinsics is None:
            continue
        from_calibration = sources[cam.id].startswith(("from ", "intrinsics from "))
        if from_calibration:
            check_lens(cam, f"{calibration_path}: cameras.{cam.id}")
        else:
            check_lens(cam, f"{rig_path}: cameras[{index}]")
    if not_ready and for_tracking:
        raise not_ready[0]
    thresholds = {
        colour: "rig file" if colour in detector_table else "learned" if rig.pointer_colours else "default"
        for colour in ("red", "blue")
    }
    return LoadedRig(rig, rig_path, calibration_path, sources, thresholds)


def _calibration_sources(calibration: CalibrationFile, calibration_path: Path, rig_path: Path) -> dict[str, str]:
    """camera id (and 'wall') -> where its geometry comes from, for what the calibration file gives."""
    sources: dict[str, str] = {}
    for camera_id, entry in calibration.cameras.items():
        given = [part for part in ("intrinsics", "extrinsics") if getattr(entry, part)]
        if len(given) == 2:
            sources[camera_id] = f"from {calibration_path.name}"
        elif given:
            kept = "extrinsics" if given[0] == "intrinsics" else "intrinsics"
            sources[camera_id] = f"{given[0]} from {calibration_path.name}, {kept} inline in {rig_path.name}"
    if calibration.wall is not None:
        sources["wall"] = f"from {calibration_path.name}"
    return sources


def _unfinished_frame(calibration: CalibrationFile) -> str | None:
    """'camera <id>' when a calibration file has cameras in camera 1's frame and no wall in it."""
    if calibration.wall is not None:
        return None
    for entry in calibration.cameras.values():
        frame = str(entry.info.get("world_frame", ""))
        if frame.startswith("camera ") and entry.extrinsics is not None:
            return frame
    return None


def _resolve_paths(rig: RigConfig, rig_path: Path) -> RigConfig:
    """File names inside a rig file are relative to that file, like ``calibration``."""

    def resolved(model: BaseModel, keys: tuple[str, ...]) -> dict[str, Path]:
        return {
            key: (rig_path.parent / value).resolve()
            for key in keys
            if (value := getattr(model, key)) is not None and not Path(value).is_absolute()
        }

    zmq = rig.outputs.zmq
    zmq_update = resolved(zmq, ("curve_secret_key_file", "curve_authorized_keys_dir"))
    gestures = rig.interaction.gestures
    gestures_update = resolved(gestures, ("template_dir",))
    update: dict[str, Any] = {}
    if zmq_update:
        update["outputs"] = rig.outputs.model_copy(update={"zmq": zmq.model_copy(update=zmq_update)})
    if gestures_update:
        update["interaction"] = rig.interaction.model_copy(
            update={"gestures": gestures.model_copy(update=gestures_update)}
        )
    return rig.model_copy(update=update) if update else rig


def merge_calibration(rig: RigConfig, calibration: CalibrationFile, path: Path) -> RigConfig:
    """The rig with each camera's intrinsics/extrinsics (and the wall) replaced by the calibration's."""
    known = {cam.id for cam in rig.cameras}
    unknown = sorted(set(calibration.cameras) - known)
    if unknown:
        raise ConfigError(
            f"{path}: cameras.{key_text(unknown[0])}: no camera with this id in the rig"
            f" (the rig has {', '.join(sorted(known))})"
        )
    cameras = []
    for cam in rig.cameras:
        entry = calibration.cameras.get(cam.id)
        if entry is None:
            cameras.append(cam)
            continue
        calibrated = {k: getattr(entry, k) for k in ("intrinsics", "extrinsics") if getattr(entry, k)}
        cameras.append(cam.model_copy(update=calibrated))
    if calibration.pointer_colours is not None:
        if rig.pointer_colours is not None:
            raise ConfigError(
                f"{path}: pointer_colours: the rig file gives them too; keep one"
                " (`trackerd calibrate pointer` writes them into the calibration file)"
            )
        rig = with_learned_colours(rig, calibration.pointer_colours)
    update: dict[str, Any] = {"cameras": tuple(cameras)}
    if calibration.wall is not None:
        update["wall"] = calibration.wall
    # Re-validate so cross-field checks (principal point inside the image) see the merged values.
    try:
        return RigConfig.model_validate(rig.model_copy(update=update).model_dump())
    except ValidationError as err:
        raise ConfigError(f"{path}: after merging into the rig: {describe_validation_error(err, RigConfig)}") from err
