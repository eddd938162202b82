"""The rig and calibration models: closed, documented, unit-named, and their cross-field rules."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, get_args, get_origin

import pytest
from pydantic import BaseModel, ValidationError

from trackerd.config import models
from trackerd.config.models import (
    COLOUR_PIXEL_FORMATS,
    MONO_PIXEL_FORMATS,
    CalibrationFile,
    CameraConfig,
    DetectorConfig,
    FovIntrinsics,
    OpenCVExtrinsics,
    OpenCVIntrinsics,
    PointerConfig,
    PoseExtrinsics,
    RigConfig,
    WallConfig,
    horizontal_focal_px,
)

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
EXAMPLE_RIGS = [CONFIG_DIR / "datawall.toml", CONFIG_DIR / "simulated.toml"]
# Units, plus "_ratio" for a quantity whose name already says it has none.
UNIT_SUFFIXES = (
    "_m",
    "_mm",
    "_px",
    "_deg",
    "_rad",
    "_us",
    "_ms",
    "_ns",
    "_s",
    "_hz",
    "_db",
    "_ratio",
)
# Float fields that are ratios, counts, directions or grey levels and so carry no unit suffix.
DIMENSIONLESS = {
    "distortion",  # OpenCV's coefficients, applied to normalised coordinates
    "x_direction",
    "y_direction",  # directions: only their sense matters
    "rotation_matrix",
    "rvec",  # radians, as OpenCV names it
    "max_elongation",
    "min_fill",  # ratios of lengths and areas
    "noise_sigma",
    "shot_noise",  # grey levels
}


def reachable_models(root: type[BaseModel]) -> set[type[BaseModel]]:
    """Every model class that can appear somewhere inside ``root``."""
    found: set[type[BaseModel]] = set()

    def visit(annotation: Any) -> None:
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            if annotation not in found:
                found.add(annotation)
                for field in annotation.model_fields.values():
                    visit(field.annotation)
            return
        for arg in get_args(annotation):
            visit(arg)

    visit(root)
    return found


ALL_MODELS = sorted(reachable_models(RigConfig) | reachable_models(CalibrationFile), key=lambda m: m.__name__)


def float_like(annotation: Any) -> bool:
    """A float, or a vector or optional of floats; not a free-form table such as ``info``."""
    if get_origin(annotation) is dict:
        return False
    return annotation is float or any(float_like(arg) for arg in get_args(annotation))


def error_types(err: pytest.ExceptionInfo[ValidationError]) -> list[str]:
    return [e["type"] for e in err.value.errors()]


def camera(**overrides: Any) -> dict[str, Any]:
    data = {
        "id": "left",
        "width_px": 640,
        "height_px": 480,
        "pixel_format": "BayerRG8",
        "intrinsics": {"model": "fov", "horizontal_fov_deg": 60.0},
        "extrinsics": {"kind": "pose", "position_m": [0, 1, 2]},
    }
    data.update(overrides)
    return data


# ----------------------------------------------------------------- the whole tree


@pytest.mark.parametrize("rig", EXAMPLE_RIGS, ids=lambda p: p.name)
def test_example_rigs_validate(rig: Path) -> None:
    config = RigConfig.model_validate(tomllib.loads(rig.read_text(encoding="utf-8")))
    assert len(config.cameras) >= 2
    assert all(c.intrinsics is not None and c.extrinsics is not None for c in config.cameras)


def test_the_walk_reaches_every_section() -> None:
    names = {m.__name__ for m in ALL_MODELS}
    assert {
        "RigConfig",
        "CameraConfig",
        "FovIntrinsics",
        "OpenCVIntrinsics",
        "PoseExtrinsics",
        "OpenCVExtrinsics",
        "WallConfig",
        "PointerConfig",
        "DetectorConfig",
        "ColourThreshold",
        "OutputsConfig",
        "ZmqOutput",
        "SimulationConfig",
        "CalibrationFile",
        "CameraCalibration",
    } <= names


@pytest.mark.parametrize("model", ALL_MODELS, ids=lambda m: m.__name__)
def test_every_model_is_closed_frozen_and_documented(model: type[BaseModel]) -> None:
    assert model.model_config.get("extra") == "forbid"
    assert model.model_config.get("frozen") is True
    assert model.__doc__ and model.__doc__.strip()
    undocumented = [name for name, f in model.model_fields.items() if not (f.description or "").strip()]
    assert not undocumented, f"{model.__name__}: fields without a docstring: {undocumented}"


@pytest.mark.parametrize("model", ALL_MODELS, ids=lambda m: m.__name__)
def test_every_quantity_has_its_unit_in_its_name(model: type[BaseModel]) -> None:
    unnamed = [
        name
        for name, f in model.model_fields.items()
        if float_like(f.annotation) and not name.endswith(UNIT_SUFFIXES) and name not in DIMENSIONLESS
    ]
    assert not unnamed, f"{model.__name__}: float fields without a unit suffix: {unnamed}"


@pytest.mark.parametrize("model", [m for m in ALL_MODELS if m.__module__ == models.__name__], ids=lambda m: m.__name__)
def test_every_rig_model_refuses_nan_and_infinity(model: type[BaseModel]) -> None:
    # Regression: TOML spells nan and inf, and position_m = [nan, 1, 2] used to pass.
    # (The acquisition models live in their own module and base class.)
    assert model.model_config.get("allow_inf_nan") is False
    for name, field in model.model_fields.items():
        if field.annotation is float:
            with pytest.raises(ValidationError) as err:
                model.model_validate({name: math.nan})
            assert "finite_number" in error_types(err), name


def test_models_are_frozen() -> None:
    pointer = PointerConfig(length_m=0.45, end_diameter_m=0.04)
    with pytest.raises(ValidationError):
        pointer.length_m = 1.0  # type: ignore[misc]


# ----------------------------------------------------------------- lenses


def test_fov_bounds() -> None:
    FovIntrinsics(model="fov", horizontal_fov_deg=179.9, vertical_fov_deg=0.1)
    for bad in (0.0, 180.0, -10.0, math.nan, math.inf):
        with pytest.raises(ValidationError):
            FovIntrinsics(model="fov", horizontal_fov_deg=bad)


def test_horizontal_focal_px_inverts_eq_14() -> None:
    fov = FovIntrinsics(model="fov", horizontal_fov_deg=90.0)
    assert horizontal_focal_px(fov, 1920) == pytest.approx(960.0)


@pytest.mark.parametrize("length", [0, 4, 5, 8, 12, 14])
def test_opencv_distortion_lengths_accepted(length: int) -> None:
    lens = OpenCVIntrinsics(model="opencv", fx_px=1, fy_px=1, cx_px=0, cy_px=0, distortion=(0.01,) * length)
    assert len(lens.distortion) == length


@pytest.mark.parametrize("length", [1, 3, 6, 7, 9, 13, 15])
def test_opencv_distortion_lengths_rejected(length: int) -> None:
    with pytest.raises(ValidationError, match=f"has {length} coefficients; OpenCV takes 0, 4, 5, 8, 12, 14"):
        OpenCVIntrinsics(model="opencv", fx_px=1, fy_px=1, cx_px=0, cy_px=0, distortion=(0.01,) * length)


def test_principal_point_must_lie_in_the_image() -> None:
    lens = {"model": "opencv", "fx_px": 500.0, "fy_px": 500.0, "cx_px": 639.9, "cy_px": 0.0}
    CameraConfig.model_validate(camera(intrinsics=lens))
    for cx, cy in ((640.0, 240.0), (-0.1, 240.0), (320.0, 480.0)):
        with pytest.raises(ValidationError, match=r"principal point .* lies outside the 640x480 image"):
            CameraConfig.model_validate(camera(intrinsics={**lens, "cx_px": cx, "cy_px": cy}))


# ----------------------------------------------------------------- poses


def test_pose_angles_default_to_zero() -> None:
    pose = PoseExtrinsics(kind="pose", position_m=(1.0, 2.0, 3.0))
    assert (pose.yaw_deg, pose.pitch_deg, pose.roll_deg) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "rotation",
    [
        {},  # neither
        {"rvec": (0.0, 0.0, 0.1), "rotation_matrix": ((1, 0, 0), (0, 1, 0), (0, 0, 1))},  # both
    ],
)
def test_opencv_extrinsics_need_exactly_one_rotation(rotation: dict[str, Any]) -> None:
    with pytest.raises(ValidationError, match="give exactly one of rvec or rotation_matrix"):
        OpenCVExtrinsics(kind="opencv", tvec_m=(0, 0, 0), **rotation)


@pytest.mark.parametrize(
    "matrix",
    [
        ((1, 0, 0), (0, 1, 0), (0, 0, -1)),  # a reflection
        ((2, 0, 0), (0, 1, 0), (0, 0, 1)),  # a scale
        ((1, 0.01, 0), (0, 1, 0), (0, 0, 1)),  # a shear
    ],
)
def test_rotation_matrix_must_be_a_rotation(matrix: tuple[tuple[float, ...], ...]) -> None:
    with pytest.raises(ValidationError, match="not a rotation"):
        OpenCVExtrinsics(kind="opencv", tvec_m=(0, 0, 0), rotation_matrix=matrix)


def test_forms_are_chosen_by_their_tag() -> None:
    cam = CameraConfig.model_validate(
        camera(
            intrinsics={
                "model": "opencv",
                "fx_px": 5.0,
                "fy_px": 5.0,
                "cx_px": 32.0,
                "cy_px": 24.0,
            },
            extrinsics={"kind": "opencv", "rvec": [0, 0, 0], "tvec_m": [0, 0, 0]},
        )
    )
    assert isinstance(cam.intrinsics, OpenCVIntrinsics)
    assert isinstance(cam.extrinsics, OpenCVExtrinsics)


# ----------------------------------------------------------------- cameras


@pytest.mark.parametrize("pixel_format", COLOUR_PIXEL_FORMATS)
def test_colour_pixel_formats_accepted(pixel_format: str) -> None:
    assert CameraConfig.model_validate(camera(pixel_format=pixel_format)).pixel_format == pixel_format


@pytest.mark.parametrize("pixel_format", [f for f in MONO_PIXEL_FORMATS if f != "Mono8"])
def test_monochrome_pixel_formats_rejected_with_the_reason(pixel_format: str) -> None:
    with pytest.raises(ValidationError, match=f"{pixel_format} is monochrome and cannot tell"):
        CameraConfig.model_validate(camera(pixel_format=pixel_format))


def test_mono8_is_a_camera_for_calibration_only() -> None:
    # The model takes it (a rig used to calibrate); load_rig, which tracking uses, refuses it
    # (tests/config/test_cli_config.py and tests/calibration/test_cli.py).
    assert CameraConfig.model_validate(camera(pixel_format="Mono8")).pixel_format == "Mono8"


def test_camera_ids_are_short_names() -> None:
    for good in ("left", "cam_10", "A-1"):
        CameraConfig.model_validate(camera(id=good))
    for bad in ("", "left camera", "x" * 33, "café"):
        with pytest.raises(ValidationError):
            CameraConfig.model_validate(camera(id=bad))


def test_camera_geometry_may_be_left_to_a_calibration_file() -> None:
    cam = CameraConfig.model_validate(camera(intrinsics=None, extrinsics=None))
    assert cam.intrinsics is None and cam.extrinsics is None


def rig(**overrides: Any) -> dict[str, Any]:
    data: dict[str, Any] = {
        "cameras": [camera(id="left"), camera(id="right")],
        "wall": {"corners_m": [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]},
        "pointer": {"length_m": 0.45, "end_diameter_m": 0.04},
    }
    data.update(overrides)
    return data


def test_rig_needs_two_cameras_with_distinct_ids() -> None:
    RigConfig.model_validate(rig())
    with pytest.raises(ValidationError) as err:
        RigConfig.model_validate(rig(cameras=[camera(id="left")]))
    assert error_types(err) == ["too_short"]
    with pytest.raises(ValidationError, match="camera ids must be unique; repeated: left"):
        RigConfig.model_validate(rig(cameras=[camera(id="left"), camera(id="left")]))


def test_camera_lookup_by_id() -> None:
    config = RigConfig.model_validate(rig())
    assert config.camera("right").id == "right"
    with pytest.raises(KeyError, match="no camera 'middle'; the rig has left, right"):
        config.camera("middle")


# ----------------------------------------------------------------- wall


POINTS_FRAME = {
    "points_m": [[0, 0, 0], [2, 0, 0], [0, 1, 0]],
    "origin_m": [0, 0, 0],
    "x_direction": [1, 0, 0],
    "y_direction": [0, 1, 0],
    "width_m": 2.0,
    "height_m": 1.0,
}


@pytest.mark.parametrize(
    ("wall", "message"),
    [
        ({}, "give either corners_m or points_m"),
        ({"corners_m": [[0, 0, 0]] * 4, "width_m": 2.0}, "corners_m already fixes the wall"),
        ({**POINTS_FRAME, "points_m": [[0, 0, 0], [1, 0, 0]]}, "points_m needs three or more"),
        (
            {"points_m": POINTS_FRAME["points_m"], "width_m": 2.0},
            "with points_m also give origin_m, x_direction, y_direction, height_m",
        ),
        ({**POINTS_FRAME, "display_width_px": 1920}, "give both display_width_px and display_h"),
    ],
)
def test_wall_descriptions(wall: dict[str, Any], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        WallConfig.model_validate(wall)


def test_wall_by_points_and_display() -> None:
    wall = WallConfig.model_validate({**POINTS_FRAME, "display_width_px": 1920, "display_height_px": 960})
    assert wall.planarity_tolerance_m == 0.01
    assert len(wall.points_m) == 3


def test_corners_need_exactly_four_points() -> None:
    with pytest.raises(ValidationError):
        WallConfig.model_validate({"corners_m": [[0, 0, 0], [2, 0, 0], [2, 1, 0]]})


# ----------------------------------------------------------------- pointer and detector


@pytest.mark.parametrize(
    ("pointer", "message"),
    [
        ({"length_m": 0.04, "end_diameter_m": 0.04}, "end_diameter_m must be smaller than"),
        (
            {"length_m": 0.45, "end_diameter_m": 0.04, "rod_diameter_m": 0.05},
            "rod_diameter_m must not exceed end_diameter_m",
        ),
        ({"length_m": 0.0, "end_diameter_m": 0.04}, "greater than 0"),
        ({"length_m": 0.45, "end_diameter_m": 0.04, "front_colour": "green"}, "'red' or 'blue'"),
    ],
)
def test_pointer_rules(pointer: dict[str, Any], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        PointerConfig.model_validate(pointer)


def test_pointer_defaults() -> None:
    pointer = PointerConfig(length_m=0.45, end_diameter_m=0.04)
    assert (pointer.front_colour, pointer.length_tolerance_m, pointer.rod_diameter_m) == (
        "red",
        0.05,
        0.012,
    )


def test_detector_area_range() -> None:
    with pytest.raises(ValidationError, match="min_area_px must be smaller than max_area_px"):
        DetectorConfig(min_area_px=100.0, max_area_px=100.0)
    with pytest.raises(ValidationError):
        DetectorConfig.model_validate({"red": {"min_excess": 0}})


# ----------------------------------------------------------------- calibration file


def test_calibration_file_tables_per_camera() -> None:
    cal = CalibrationFile.model_validate(
        {
            "cameras": {
                "left": {
                    "intrinsics": {"model": "fov", "horizontal_fov_deg": 50.0},
                    "info": {"date": "2026-01-01", "views": 20, "rms_px": 0.3},
                }
            },
        }
    )
    assert cal.version == 1 and cal.wall is None
    assert cal.cameras["left"].extrinsics is None
    assert cal.cameras["left"].info["views"] == 20
    with pytest.raises(ValidationError):
        CalibrationFile.model_validate({"cameras": {"left": {"lens": {}}}})
