"""load_rig: reading TOML, merging a calibration file, and the one-line errors it raises."""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest
from pydantic import ValidationError

from trackerd.config.loader import (
    describe_validation_error,
    format_location,
    load_calibration,
    load_rig,
    parse_rig,
    read_toml,
)
from trackerd.config.models import (
    CalibrationFile,
    OpenCVExtrinsics,
    OpenCVIntrinsics,
    PoseExtrinsics,
    RigConfig,
)
from trackerd.errors import CalibrationPending, ConfigError

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
Edit = Callable[[str, str, str], str]
Write = Callable[[str, str], Path]
WITH_CALIBRATION = ('name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"')


def rig_error(data: dict, root: type = RigConfig) -> str:
    with pytest.raises(ValidationError) as err:
        root.model_validate(data)
    return describe_validation_error(err.value, root)


# ----------------------------------------------------------------- example rigs


@pytest.mark.parametrize("name", ["datawall", "simulated"])
def test_example_rigs_load_with_everything_inline(name: str) -> None:
    path = CONFIG_DIR / f"{name}.toml"
    loaded = load_rig(str(path))
    assert loaded.path == path
    assert loaded.calibration_path is None
    assert loaded.config == RigConfig.model_validate(tomllib.loads(path.read_text(encoding="utf-8")))
    assert loaded.sources == {
        **{cam.id: f"inline in {name}.toml" for cam in loaded.config.cameras},
        "wall": f"inline in {name}.toml",
    }


# ----------------------------------------------------------------- calibration files


def test_calibration_replaces_the_rigs_values_and_keeps_the_rest(
    write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    cal_path = write("cal.toml", left_calibration)
    rig_path = write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION))
    loaded = load_rig(rig_path)
    plain = load_rig(write("plain.toml", minimal_rig)).config
    left, right = loaded.config.cameras
    expected = load_calibration(cal_path).cameras["left"]
    assert left.intrinsics == expected.intrinsics
    assert isinstance(left.intrinsics, OpenCVIntrinsics) and left.intrinsics.fx_px == 550.0
    assert left.extrinsics == expected.extrinsics and isinstance(left.extrinsics, OpenCVExtrinsics)
    assert left.model_copy(update={"intrinsics": None, "extrinsics": None}) == plain.cameras[0].model_copy(
        update={"intrinsics": None, "extrinsics": None}
    )
    assert right == plain.cameras[1]
    assert loaded.config.wall == plain.wall
    assert loaded.calibration_path == cal_path.resolve()
    assert loaded.sources == {
        "left": "from cal.toml",
        "right": "inline in rig.toml",
        "wall": "inline in rig.toml",
    }


def test_calibration_path_is_relative_to_the_rig_file_not_the_working_directory(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    edit: Edit,
    minimal_rig: str,
    left_calibration: str,
) -> None:
    rigs = tmp_path / "site" / "rigs"
    rigs.mkdir(parents=True)
    (rigs / "cal.toml").write_text(left_calibration)
    (rigs / "rig.toml").write_text(edit(minimal_rig, *WITH_CALIBRATION))
    monkeypatch.chdir(tmp_path)
    loaded = load_rig("site/rigs/rig.toml")
    assert loaded.calibration_path == (rigs / "cal.toml").resolve()


def test_partial_calibration_names_each_parts_source(write: Write, edit: Edit, minimal_rig: str) -> None:
    # Regression: a calibration entry with only intrinsics was reported as the source of
    # the camera's whole geometry, and an entry with only provenance as the source too.
    write(
        "cal.toml",
        '[cameras.left]\nintrinsics = { model = "fov", horizontal_fov_deg = 55.0 }\n'
        '[cameras.right]\ninfo = { note = "not calibrated yet" }\n',
    )
    loaded = load_rig(write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION)))
    assert loaded.config.cameras[0].intrinsics.horizontal_fov_deg == 55.0
    assert isinstance(loaded.config.cameras[0].extrinsics, PoseExtrinsics)
    assert loaded.sources["left"] == "intrinsics from cal.toml, extrinsics inline in rig.toml"
    assert loaded.sources["right"] == "inline in rig.toml"


def test_calibration_can_supply_what_the_rig_leaves_out(
    write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    text = edit(minimal_rig, *WITH_CALIBRATION)
    text = edit(text, 'intrinsics = { model = "fov", horizontal_fov_deg = 60.0 }\n', "")
    text = edit(text, 'extrinsics = { kind = "pose", position_m = [-0.5, 1.0, 1.5], yaw_deg = 30.0 }\n', "")
    write("cal.toml", left_calibration)
    loaded = load_rig(write("rig.toml", text))
    assert loaded.sources["left"] == "from cal.toml"


def test_camera_missing_geometry_names_the_calibration_file_too(
    write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    text = edit(minimal_rig, *WITH_CALIBRATION)
    text = edit(text, 'extrinsics = { kind = "pose", position_m = [2.5, 1.0, 1.5], yaw_deg = -30.0 }\n', "")
    cal = write("cal.toml", left_calibration)
    rig = write("rig.toml", text)
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    assert str(err.value) == (
        f"{rig}: cameras[1] ('right') has no extrinsics; give them in [cameras.extrinsics]"
        f" or in {cal.resolve()} (a calibration file named by 'calibration'), or run"
        " `trackerd calibrate stereo --config rig.toml`"
    )


def test_cameras_left_in_camera_1s_frame_name_the_wall_step_as_next(
    write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    # What `calibrate stereo` writes for a rig without poses: both cameras in camera 1's frame, no wall.
    stereo = (
        left_calibration.replace("info = { date", 'info = { world_frame = "camera left", date')
        + '\n[cameras.right]\nextrinsics = { kind = "opencv", rvec = [0.0, 0.2, 0.0], tvec_m = [-1.0, 0.0, 0.1] }\n'
        + 'info = { world_frame = "camera left" }\n'
    )
    write("cal.toml", stereo)
    rig = write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION))
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    message = str(err.value)
    assert "the cameras are in camera left's frame" in message
    assert "next: `trackerd calibrate wall --config rig.toml`" in message
    assert "behind the wall" not in message
    # Once the wall is calibrated in that frame, the file loads.
    write("cal.toml", stereo + "\n[wall]\ncorners_m = [[0, 1, 3], [2, 1, 3], [2, 0, 3], [0, 0, 3]]\n")
    assert load_rig(rig).calibration_path is not None


def test_a_rig_without_wall_or_pointer_parses_but_does_not_track(write: Write, minimal_rig: str) -> None:
    # What an operator writes before calibrating: the cameras (intrinsics and stereo need nothing else).
    cameras_only = minimal_rig[: minimal_rig.index("[wall]")]
    rig = write("rig.toml", cameras_only)
    assert parse_rig(read_toml(rig), rig).wall is None
    with pytest.raises(ConfigError, match=r"rig.toml: wall: required table is missing \(here, or in the calibration"):
        load_rig(rig)
    rig = write("rig.toml", minimal_rig[: minimal_rig.index("[pointer]")])
    with pytest.raises(ConfigError, match=r"rig.toml: pointer: required table is missing; tracking needs it"):
        load_rig(rig)


def test_wall_from_the_calibration_file(write: Write, edit: Edit, minimal_rig: str) -> None:
    write("cal.toml", "[wall]\ncorners_m = [[0, 0, 0], [3, 0, 0], [3, 1.5, 0], [0, 1.5, 0]]\n")
    loaded = load_rig(write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION)))
    assert loaded.config.wall.corners_m[2] == (3.0, 1.5, 0.0)
    assert loaded.config.wall.points_m is None
    assert loaded.sources["wall"] == "from cal.toml"


def test_impossible_wall_in_the_calibration_file_names_that_file(write: Write, edit: Edit, minimal_rig: str) -> None:
    cal = write("cal.toml", "[wall]\ncorners_m = [[0, 0, 0], [3, 0, 0], [3, 1.5, 0], [0, 1.5, 0.5]]\n")
    with pytest.raises(ConfigError, match="^" + str(cal.resolve()) + ": wall: corners_m are not coplanar"):
        load_rig(write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION)))


def test_lens_that_folds_before_the_image_corners_is_refused(
    write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    # Regression: a calibration whose distortion polynomial turns back before the image
    # corners (so no ray reaches them) gave rays there that were silently wrong, by 56-116 px
    # for this lens; config check accepted it.
    folding = edit(left_calibration, "fx_px = 550.0\nfy_px = 551.0", "fx_px = 333.3\nfy_px = 333.3")
    folding = edit(folding, "[-0.05, 0.01, 0.0, 0.0]", "[-0.3, 0.12, 0.001, -0.001, -0.02]")
    cal = write("cal.toml", folding)
    rig = write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION))
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    assert str(err.value).startswith(
        f"{cal.resolve()}: cameras.left.intrinsics.distortion: the lens model folds over near the image edge"
    )
    # With a larger k2 the same lens does not fold: accepted, though it moves its corners
    # by about 75 px.
    write("cal.toml", edit(folding, "[-0.3, 0.12,", "[-0.3, 0.15,"))
    assert load_rig(rig).sources["left"] == "from cal.toml"


def test_calibration_with_an_unknown_camera(write: Write, edit: Edit, minimal_rig: str, left_calibration: str) -> None:
    cal = write("cal.toml", edit(left_calibration, "[cameras.left]", "[cameras.centre]"))
    cal = write(
        "cal.toml",
        edit(cal.read_text(), "[cameras.left.intrinsics]", "[cameras.centre.intrinsics]"),
    )
    with pytest.raises(ConfigError) as err:
        load_rig(write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION)))
    assert str(err.value) == (
        f"{cal.resolve()}: cameras.centre: no camera with this id in the rig (the rig has left, right)"
    )


def test_missing_calibration_file(write: Write, edit: Edit, minimal_rig: str) -> None:
    # Regression: the error named only the calibration path, not the rig that asked for it.
    rig = write("rig.toml", edit(minimal_rig, *WITH_CALIBRATION))
    with pytest.raises(CalibrationPending) as err:
        load_rig(rig)
    assert str(err.value) == (
        f"{rig}: calibration: {rig.parent.resolve() / 'cal.toml'}: no such file yet"
        " (the path is relative to the rig file); `trackerd calibrate intrinsics --config rig.toml --camera left`"
        " writes it"
    )


def test_calibration_file_version(write: Write) -> None:
    path = write("cal.toml", "version = 2\n")
    with pytest.raises(ConfigError, match=r"cal.toml: version: Input should be 1 \(got 2\)$"):
        load_calibration(path)
    assert load_calibration(write("empty.toml", "")) == CalibrationFile()


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            'height_px = 480\npixel_format = "RGB8"',
            'height_px = "480"\npixel_format = "RGB8"',
            r'cameras\[0\]\.height_px: must be an integer \(got "480"\)$',
        ),
        ("length_m = 0.45", 'length_m = "0.45"', r'pointer\.length_m: must be a number \(got "0\.45"\)$'),
        ("yaw_deg = 30.0 }", 'yaw_deg = "30" }', r'cameras\[0\]\.extrinsics\.yaw_deg: must be a number \(got "30"\)$'),
        ("min_area_px = 12.0", "min_area_px = true", r"detector\.min_area_px: must be a number \(got true\)$"),
        (
            "min_area_px = 12.0",
            "min_area_px = 12.0\nsearch_step_px = 4.0",
            r"detector\.search_step_px: must be an integer \(got 4\.0\)$",
        ),
    ],
)
def test_values_of_the_wrong_type_are_refused_not_converted(
    write: Write, edit: Edit, minimal_rig: str, old: str, new: str, message: str
) -> None:
    # Regression: "1920" was read as 1920, true as 1, 7.0 as 7, "off" as False.
    with pytest.raises(ConfigError, match=message):
        load_rig(write("rig.toml", edit(minimal_rig, old, new)))


def test_integers_still_stand_for_floats(write: Write, edit: Edit, minimal_rig: str) -> None:
    rig = load_rig(write("rig.toml", edit(minimal_rig, "length_m = 0.45", "length_m = 1"))).config
    assert rig.pointer.length_m == 1.0


# ----------------------------------------------------------------- reading files


def test_read_toml_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nothing\.toml: no such file$"):
        read_toml(tmp_path / "nothing.toml")
    with pytest.raises(ConfigError, match=r"is a directory, expected a TOML file$"):
        read_toml(tmp_path)
    (tmp_path / "bad.toml").write_text("a = 1\nb = = 2\n")
    with pytest.raises(ConfigError, match=r"bad.toml: not valid TOML: .*\(at line 2, column 5\)$"):
        read_toml(tmp_path / "bad.toml")
    (tmp_path / "latin1.toml").write_bytes('name = "café"\n'.encode("latin-1"))
    with pytest.raises(ConfigError, match=r"latin1\.toml: not "):
        read_toml(tmp_path / "latin1.toml")


def test_config_errors_exit_with_code_2() -> None:
    assert ConfigError.exit_code == 2


# ----------------------------------------------------------------- describing errors


@pytest.mark.parametrize(
    ("loc", "text"),
    [
        (("cameras", 1, "intrinsics", "opencv", "fx_px"), "cameras[1].intrinsics.fx_px"),
        (
            ("cameras", 0, "extrinsics", "pose", "position_m", 2),
            "cameras[0].extrinsics.position_m[2]",
        ),
        (("cameras", "left", "intrinsics", "fov", "model"), "cameras.left.intrinsics.model"),
        (("wall", "corners_m", 3, 0), "wall.corners_m[3][0]"),
        (("cameras", "pose"), "cameras.pose"),  # a camera whose id happens to be a tag
        ((), "(top level)"),
    ],
)
def test_format_location(loc: tuple, text: str) -> None:
    assert format_location(loc) == text


def test_unknown_key_lists_the_allowed_keys_and_a_near_miss() -> None:
    message = rig_error({"cameras": [], "wall": {}, "pointer": {}, "detectr": {}})
    assert message.startswith("detectr: unknown key 'detectr' (did you mean 'detector'?); allowed keys here: ")
    assert "version, name, calibration, cameras, wall, pointer" in message


def test_a_misspelt_required_key_is_one_problem(write: Write, edit: Edit, minimal_rig: str) -> None:
    # Regression: the real key's absence was counted as a second problem.
    with pytest.raises(ConfigError) as err:
        load_rig(write("rig.toml", edit(minimal_rig, "length_m = 0.45", "lenght_m = 0.45")))
    assert str(err.value).endswith("end_diameter_m, rod_diameter_m"), err.value


def test_the_same_misspelling_in_two_cameras_is_two_problems() -> None:
    # Regression: the second camera's real key, missing because of its misspelling, was counted
    # as a third problem ("and 2 more problems").
    camera = {"width_px": 640, "height_px": 480, "pixelformat": "Mono8"}
    message = rig_error(
        {
            "cameras": [{"id": "a", **camera}, {"id": "b", **camera}],
            "wall": {"corners_m": [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]},
            "pointer": {"length_m": 0.45, "end_diameter_m": 0.04},
        }
    )
    assert message.startswith("cameras[0].pixelformat: unknown key 'pixelformat' (did you mean 'pixel_format'?)")
    assert message.endswith(" (and 1 more problem)"), message


def test_unknown_key_inside_a_tagged_union_lists_that_forms_keys() -> None:
    data = {"cameras": {"left": {"extrinsics": {"kind": "opencv", "rvec": [0, 0, 0], "tvec": [0, 0, 0]}}}}
    message = rig_error(data, CalibrationFile)
    assert message.startswith(
        "cameras.left.extrinsics.tvec: unknown key 'tvec' (did you mean 'tvec_m'?);"
        " allowed keys here: kind, rvec, rotation_matrix, tvec_m"
    )


def test_failed_items_are_not_counted_twice() -> None:
    # Regression: pydantic adds "cameras: too short after validation, not 0" when every
    # camera fails, which made the line end "(and 2 more problems)" for two.
    minimal = {"width_px": 0, "height_px": 480, "pixel_format": "RGB8"}
    message = rig_error(
        {
            "cameras": [{"id": "a", **minimal}, {"id": "b", **minimal}],
            "wall": {"corners_m": [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]},
            "pointer": {"length_m": 0.45, "end_diameter_m": 0.04},
        }
    )
    assert message == "cameras[0].width_px: Input should be greater than 0 (got 0) (and 1 more problem)"


def test_too_few_cameras_is_still_reported() -> None:
    message = rig_error(
        {
            "cameras": [],
            "wall": {"corners_m": [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]},
            "pointer": {"length_m": 0.45, "end_diameter_m": 0.04},
        }
    )
    assert message.startswith("cameras: Tuple should have at least 2 items")


def test_short_vector_says_how_many_values() -> None:
    # Regression: this read "position_m[2]: required key is missing".
    data = {"cameras": {"left": {"extrinsics": {"kind": "pose", "position_m": [1.0, 2.0]}}}}
    assert rig_error(data, CalibrationFile) == "cameras.left.extrinsics.position_m: needs 3 values, got 2"
    data = {"wall": {"corners_m": [[0, 0, 0], [1, 0, 0]]}}
    assert rig_error(data, CalibrationFile) == "wall.corners_m: needs 4 values, got 2"


def test_missing_form_tag_says_which_forms_exist() -> None:
    # Regression: this read "Unable to extract tag using discriminator 'kind'".
    data = {"cameras": {"left": {"extrinsics": {"position_m": [1.0, 2.0, 3.0]}}}}
    assert rig_error(data, CalibrationFile) == (
        "cameras.left.extrinsics: required key 'kind' is missing; it selects the form (one of 'pose', 'opencv')"
    )
    data = {"cameras": {"left": {"intrinsics": {"model": "pinhole"}}}}
    assert rig_error(data, CalibrationFile) == (
        "cameras.left.intrinsics: tag 'pinhole' in key 'model' does not match any of the expected tags: 'fov', 'opencv'"
    )


# ----------------------------------------------------------------- wall sanity


def _datawall_with(tmp_path: Path, old: str, new: str) -> Path:
    text = (CONFIG_DIR / "datawall.toml").read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "rig.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def test_corners_listed_clockwise_put_the_cameras_behind_the_wall(tmp_path: Path) -> None:
    path = _datawall_with(
        tmp_path,
        "[[0.0, 0.0, 0.0], [3.6576, 0.0, 0.0], [3.6576, 0.9144, 0.0], [0.0, 0.9144, 0.0]]",
        "[[0.0, 0.0, 0.0], [0.0, 0.9144, 0.0], [3.6576, 0.9144, 0.0], [3.6576, 0.0, 0.0]]",
    )
    with pytest.raises(ConfigError, match=r"rig.toml: wall.corners_m: camera\(s\) left, right would be behind"):
        load_rig(path)


@pytest.mark.parametrize(
    ("corner", "message"),
    [
        ("[0.1, 0.9144, 0.0]]", "the bottom edge is 3658 mm long and the top edge 3558 mm"),
        ("[0.0, 0.9144, 0.0]]", None),
    ],
)
def test_corners_must_form_a_rectangle(tmp_path: Path, corner: str, message: str | None) -> None:
    path = _datawall_with(tmp_path, "[0.0, 0.9144, 0.0]]", corner)
    if message is None:
        load_rig(path)
        return
    with pytest.raises(ConfigError, match=message):
        load_rig(path)


def test_curve_key_paths_are_relative_to_the_rig_file(tmp_path: Path) -> None:
    path = _datawall_with(
        tmp_path,
        'endpoints = ["tcp://127.0.0.1:5560"]',
        'endpoints = ["tcp://127.0.0.1:5560"]\ncurve_secret_key_file = "keys/server.key_secret"\n'
        'curve_authorized_keys_dir = "keys/clients"',
    )
    zmq = load_rig(path).config.outputs.zmq
    assert zmq.curve_secret_key_file == tmp_path / "keys" / "server.key_secret"
    assert zmq.curve_authorized_keys_dir == tmp_path / "keys" / "clients"
