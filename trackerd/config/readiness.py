"""Whether a valid rig can track yet, and what is left to do when it cannot.

A rig file can be valid long before it can track: a calibration step still to run, no ``[wall]``
or ``[pointer]`` yet, cameras in Mono8 for calibrating. Each missing piece is a
:class:`~trackerd.errors.CalibrationPending` naming the step that supplies it, in the order the
steps run.
"""

from __future__ import annotations

from pathlib import Path

from trackerd.config.camera import CALIBRATION_ONLY_FORMAT, COLOUR_PIXEL_FORMATS
from trackerd.config.models import RigConfig
from trackerd.errors import CalibrationPending


def pending_steps(
    rig: RigConfig, rig_path: Path, calibration_path: Path | None, frame: str | None
) -> list[CalibrationPending]:
    """What ``rig`` (read from ``rig_path``, merged with ``calibration_path``) still lacks to track.

    ``frame`` is ``'camera <id>'`` when the calibration file holds the cameras in that camera's frame
    and no wall yet (after `trackerd calibrate stereo`), else None.
    """
    not_ready: list[CalibrationPending] = []
    # In the order the steps run: every lens, then the poses, then what only colour cameras can do.
    for part in ("intrinsics", "extrinsics"):
        for index, cam in enumerate(rig.cameras):
            if getattr(cam, part) is None:
                where = f" or in {calibration_path}" if calibration_path else ""
                step = f"intrinsics --camera {cam.id}" if part == "intrinsics" else "stereo"
                not_ready.append(
                    CalibrationPending(
                        rig_path,
                        f"cameras[{index}] ('{cam.id}') has no {part}; give them in"
                        f" [cameras.{part}]{where} (a calibration file named by 'calibration'), or run"
                        f" `trackerd calibrate {step} --config {rig_path.name}`",
                    )
                )
    for index, cam in enumerate(rig.cameras):
        if cam.pixel_format == CALIBRATION_ONLY_FORMAT:
            not_ready.append(
                CalibrationPending(
                    rig_path,
                    f"cameras[{index}].pixel_format: {cam.pixel_format} is monochrome and cannot tell"
                    f" the pointer's red end from its blue end; use one of {', '.join(COLOUR_PIXEL_FORMATS)}"
                    f" to track ({cam.pixel_format} is fine for `trackerd calibrate intrinsics` and `stereo`;"
                    " `calibrate wall` locates the pointer, so it needs colour too)",
                )
            )
    missing_tables = [table for table, given in (("wall", rig.wall), ("pointer", rig.pointer)) if given is None]
    if frame is not None:
        # After `calibrate stereo` on a rig without poses the cameras are in camera 1's frame and the
        # rig's wall, in its own frame, does not match them: not a wrong wall, a step still to come.
        tables = [f"[{table}]" for table in missing_tables]
        first = f" (it needs {' and '.join(tables)} in {rig_path.name} first: the wall's nominal size, the pointer)"
        not_ready.append(
            CalibrationPending(
                calibration_path,
                f"the cameras are in {frame}'s frame (as `trackerd calibrate stereo` left them)"
                f" and the wall is not calibrated in it yet; next: `trackerd calibrate wall --config {rig_path.name}`"
                + (first if tables else ""),
            )
        )
    for table in missing_tables:
        where = " (here, or in the calibration file from `trackerd calibrate wall`)" if table == "wall" else ""
        not_ready.append(
            CalibrationPending(
                rig_path,
                f"{table}: required table is missing{where}; tracking needs it (config/datawall.toml has one to copy)",
            )
        )
    return not_ready


def check_ready_to_track(rig: RigConfig, where: object) -> None:
    """For a rig assembled elsewhere (a recording's): CalibrationPending unless it can track as load_rig
    would have it (wall, pointer, every camera's lens and pose, colour), then the geometric checks."""
    for table in ("wall", "pointer"):
        if getattr(rig, table) is None:
            raise CalibrationPending(where, f"{table}: required table is missing; tracking needs it")
    for index, cam in enumerate(rig.cameras):
        missing = [part for part in ("intrinsics", "extrinsics") if getattr(cam, part) is None]
        if missing:
            raise CalibrationPending(where, f"cameras[{index}] ('{cam.id}') has no {' or '.join(missing)}")
        if cam.pixel_format == CALIBRATION_ONLY_FORMAT:
            raise CalibrationPending(
                where, f"cameras[{index}].pixel_format: Mono8 cannot tell the pointer's red end from its blue end"
            )
    # Here, not at the top: NumPy and OpenCV take a quarter of a second to import (as in load_rig).
    from trackerd.config.rig_geometry import check_rig_geometry

    check_rig_geometry(rig, Path(str(where)))
