"""`trackerd config check FILE`: validate a rig file and print the rig as trackerd resolves it."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from trackerd.config.loader import LoadedRig, load_rig
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.errors import CalibrationPending, ConfigError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import ypr_from_world_from_camera
from trackerd.geometry.wall import WallFrame
from trackerd.interaction.validate import check_interaction


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "config",
        help="check rig configuration files",
        description="check FILE: validate a rig file (every key, type and range; the calibration file it"
        " names) and print the rig as trackerd resolves it; --ready also asks whether it can track"
        " (docs/configuration.md)",
    )
    config_sub = parser.add_subparsers(dest="config_command", metavar="ACTION", required=True)
    check = config_sub.add_parser("check", help="validate a rig file and print the resolved rig")
    check.add_argument("file", help="rig TOML file, for example config/datawall.toml")
    check.add_argument("--json", action="store_true", help="print the resolved rig as JSON")
    check.add_argument(
        "--ready",
        action="store_true",
        help="fail (exit 2) unless the rig is ready to track, as `run` needs it; without it a rig still being"
        " calibrated passes, saying what is left",
    )
    check.set_defaults(handler=check_command)


def check_command(args: argparse.Namespace) -> int:
    try:
        loaded = load_rig(args.file)
    except CalibrationPending as pending:
        # Valid as far as it goes, mid-calibration or for calibration only: say what is left, and pass
        # (the tracking commands refuse such a rig with the same line, as --ready does).
        if args.ready:
            raise
        if args.json:
            print(json.dumps({"file": str(args.file), "ready_to_track": False, "not_ready": pending.detail}))
        else:
            print(f"{args.file}: OK for calibration; not ready to track yet: {pending.detail}")
        return 0
    cameras = [camera_model(cam) for cam in loaded.config.cameras]
    assert loaded.config.wall is not None  # load_rig raised CalibrationPending without one
    wall = wall_frame(loaded.config.wall)
    try:
        if loaded.config.interaction.any_enabled:
            # What the daemon's interaction stage checks at start (templates, commands, hand camera,
            # TUIO host): OK here means `run` and `replay` start.
            check_interaction(loaded.config)
        if args.ready:
            check_files_read_at_start(loaded.config)
    except ConfigError as err:
        raise err.in_file(loaded.path) from None
    if args.json:
        print(json.dumps(resolved_summary(loaded, cameras, wall), indent=2))
    else:
        print(describe(loaded, cameras, wall))
    return 0


def check_files_read_at_start(rig: RigConfig) -> None:
    """ConfigError for a file the daemon reads at start and would refuse: the publisher's CURVE keys and
    its client keys' directory (one without keys passes: a reload takes it), the console's token file."""
    from trackerd.console.access import read_token
    from trackerd.publish.publisher import curve_keys

    curve_keys(rig.outputs.zmq, allow_no_clients=True)
    if rig.console.enabled and rig.console.token_file is not None:
        read_token(rig.console.token_file)


def resolved_summary(loaded: LoadedRig, cameras: list[CameraModel], wall: WallFrame) -> dict[str, Any]:
    rig = loaded.config
    assert rig.pointer is not None  # load_rig raised CalibrationPending without one
    return {
        "file": str(loaded.path),
        "ready_to_track": True,
        "calibration": str(loaded.calibration_path) if loaded.calibration_path else None,
        "name": rig.name,
        "cameras": [
            {
                "id": cam.camera_id,
                "source": loaded.sources[cam.camera_id],
                "resolution_px": [cam.width_px, cam.height_px],
                "pixel_format": cfg.pixel_format,
                "matrix": cam.matrix.tolist(),
                "distortion": cam.distortion.tolist(),
                "centre_m": cam.centre_m.tolist(),
                "yaw_pitch_roll_deg": list(ypr_from_world_from_camera(cam.world_from_camera)),
                "optical_axis": cam.world_from_camera[:, 2].tolist(),
            }
            for cam, cfg in zip(cameras, rig.cameras, strict=True)
        ],
        "wall": {
            "source": loaded.sources["wall"],
            "origin_m": wall.origin_m.tolist(),
            "x_axis": wall.x_axis.tolist(),
            "y_axis": wall.y_axis.tolist(),
            "normal": wall.normal.tolist(),
            "size_m": [wall.width_m, wall.height_m],
            "display_px": [wall.display_width_px, wall.display_height_px] if wall.has_display else None,
            "max_plane_residual_m": float(np.max(np.abs(wall.fit_residuals_m)))
            if wall.fit_residuals_m is not None
            else 0.0,
        },
        "pointer": rig.pointer.model_dump(),
        "detector": rig.detector.model_dump(),
        "pointer_colours": rig.pointer_colours.model_dump() if rig.pointer_colours else None,
        "threshold_sources": dict(loaded.threshold_sources or {}),
    }


def describe(loaded: LoadedRig, cameras: list[CameraModel], wall: WallFrame) -> str:
    rig = loaded.config
    lines = [f"{loaded.path}: OK, rig '{rig.name}'"]
    if loaded.calibration_path:
        lines.append(f"  calibration: {loaded.calibration_path}")
    for cam, cfg in zip(cameras, rig.cameras, strict=True):
        yaw, pitch, roll = ypr_from_world_from_camera(cam.world_from_camera)
        k = cam.matrix
        where = cfg.serial or cfg.address or cfg.device_id or "(first camera found)"
        if cfg.backend != "aravis":
            where = f"{where} through {cfg.backend}"
        lines.append(
            f"  camera {cam.camera_id}: {cam.width_px}x{cam.height_px} {cfg.pixel_format}, device {where},"
            f" geometry {loaded.sources[cam.camera_id]}"
        )
        lines.append(
            f"    fx {k[0, 0]:.1f} fy {k[1, 1]:.1f} cx {k[0, 2]:.1f} cy {k[1, 2]:.1f} px,"
            f" distortion [{', '.join(f'{d:g}' for d in cam.distortion) or 'none'}]"
        )
        centre = ", ".join(f"{v:.3f}" for v in cam.centre_m)
        lines.append(f"    at ({centre}) m, yaw {yaw:.2f} pitch {pitch:.2f} roll {roll:.2f} deg")
    base = np.linalg.norm(cameras[0].centre_m - cameras[1].centre_m)
    lines.append(f"  baseline {cameras[0].camera_id}-{cameras[1].camera_id}: {base:.3f} m")
    lines.append(
        f"  wall: {wall.width_m:.4f} x {wall.height_m:.4f} m ({wall.width_m / 0.3048:.2f} x"
        f" {wall.height_m / 0.3048:.2f} ft), origin ({', '.join(f'{v:.3f}' for v in wall.origin_m)}),"
        f" normal ({', '.join(f'{v:.3f}' for v in wall.normal)}), {loaded.sources['wall']}"
    )
    if wall.has_display:
        lines.append(f"    display {wall.display_width_px}x{wall.display_height_px} px")
    p = rig.pointer
    assert p is not None  # load_rig raised CalibrationPending without one
    lines.append(
        f"  pointer: {p.front_colour} end in front, {p.length_m * 1000:.0f} mm between end centres"
        f" (+-{p.length_tolerance_m * 1000:.0f} mm), ends {p.end_diameter_m * 1000:.0f} mm"
    )
    lines.append("  " + _thresholds_line(rig, loaded.threshold_sources or {}))
    return "\n".join(lines)


def _thresholds_line(rig: RigConfig, sources: dict[str, str]) -> str:
    """The detector's thresholds and where they come from (learned colours, the rig file, defaults)."""
    learned = rig.pointer_colours
    parts = []
    for colour in ("red", "blue"):
        threshold = getattr(rig.detector, colour)
        if sources.get(colour) == "rig file":
            parts.append(f"{colour} {threshold.min_excess} (rig file's [detector.{colour}])")
        elif learned is not None:
            seen = learned.of(colour)
            parts.append(
                f"{colour} {threshold.min_excess} (learned: ball {seen.ball_excess}, room {seen.background_excess})"
            )
        else:
            parts.append(f"{colour} {threshold.min_excess} (default)")
    when = (
        f"; colours learned {learned.learned}"
        if learned is not None
        else ("; colours not learned (`trackerd calibrate pointer` learns them in this room)")
    )
    return f"thresholds (colour excess, grey levels): {', '.join(parts)}{when}"
