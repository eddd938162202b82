"""`trackerd config check FILE` run as a real process: good rigs, every kind of bad file, --json."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from trackerd.config.loader import load_rig
from trackerd.config.models import PointerConfig
from trackerd.errors import CalibrationPending

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
EXAMPLE_RIGS = [CONFIG_DIR / "datawall.toml", CONFIG_DIR / "simulated.toml"]

CliRun = subprocess.CompletedProcess[str]
Edit = Callable[[str, str, str], str]
Write = Callable[[str, str], Path]
RunCheck = Callable[..., CliRun]


def assert_one_line_error(run: CliRun, prefix: str, *fragments: str) -> str:
    """Exit code 2, nothing on stdout, exactly one line on stderr starting with prefix."""
    assert run.returncode == 2, run
    assert run.stdout == ""
    assert "Traceback" not in run.stderr
    lines = run.stderr.splitlines()
    assert len(lines) == 1, run.stderr
    line = lines[0]
    assert line.startswith(f"trackerd config: {prefix}"), line
    for fragment in fragments:
        assert fragment in line, line
    return line


# ----------------------------------------------------------------- good rigs


@pytest.mark.parametrize("rig", EXAMPLE_RIGS, ids=lambda p: p.name)
def test_example_rigs_pass(run_check: RunCheck, rig: Path) -> None:
    run = run_check(rig)
    assert (run.returncode, run.stderr) == (0, "")
    lines = run.stdout.splitlines()
    assert lines[0] == f"{rig}: OK, rig '{load_rig(rig).config.name}'"
    for camera_id in ("left", "right"):
        assert any(
            line.startswith(f"  camera {camera_id}: 1920x1080 BayerRG8")
            and line.endswith(f"geometry inline in {rig.name}")
            for line in lines
        ), run.stdout
    assert any(line.startswith("  wall: 3.6576 x 0.9144 m (12.00 x 3.00 ft)") for line in lines)


def _trackerd(*args: str, cwd: Path) -> CliRun:
    """The real command, in its own process, from ``cwd``."""
    return subprocess.run(
        [sys.executable, "-m", "trackerd", *args], cwd=cwd, capture_output=True, text=True, timeout=60, check=False
    )


def test_the_documented_check_output_is_what_the_command_prints() -> None:
    """docs/configuration.md shows `config check config/datawall.toml`'s output: it lacked the thresholds
    line for a while after the command gained it."""
    repo = CONFIG_DIR.parent
    doc = (repo / "docs" / "configuration.md").read_text()
    command = "$ trackerd config check config/datawall.toml\n"
    assert doc.count(command) == 1
    shown = doc.split(command, 1)[1].split("```", 1)[0]
    run = _trackerd("config", "check", "config/datawall.toml", cwd=repo)
    assert run.returncode == 0 and run.stdout == shown, run.stdout


@pytest.mark.parametrize("rig", EXAMPLE_RIGS, ids=lambda p: p.name)
def test_json_output_parses_and_matches_the_rig(run_check: RunCheck, rig: Path) -> None:
    run = run_check(rig, "--json")
    assert (run.returncode, run.stderr) == (0, "")
    resolved = json.loads(run.stdout)
    config = load_rig(rig).config
    assert resolved["file"] == str(rig)
    assert resolved["calibration"] is None
    assert resolved["name"] == config.name
    assert [c["id"] for c in resolved["cameras"]] == [c.id for c in config.cameras]
    for out, cam in zip(resolved["cameras"], config.cameras, strict=True):
        assert out["source"] == f"inline in {rig.name}"
        assert out["resolution_px"] == [cam.width_px, cam.height_px]
        assert out["pixel_format"] == cam.pixel_format
        assert out["centre_m"] == pytest.approx(list(cam.extrinsics.position_m), abs=1e-12)
        pose = cam.extrinsics
        assert out["yaw_pitch_roll_deg"] == pytest.approx([pose.yaw_deg, pose.pitch_deg, pose.roll_deg], abs=1e-9)
        fx = out["matrix"][0][0]
        if cam.intrinsics.model == "fov":  # eq. 14
            half_fov = math.radians(cam.intrinsics.horizontal_fov_deg) / 2
            assert fx == pytest.approx(cam.width_px / 2 / math.tan(half_fov))
            assert out["distortion"] == []
        else:
            assert fx == cam.intrinsics.fx_px
            assert out["matrix"][1][2] == cam.intrinsics.cy_px
            assert out["distortion"] == list(cam.intrinsics.distortion)
    wall = resolved["wall"]
    assert wall["source"] == f"inline in {rig.name}"
    assert wall["origin_m"] == pytest.approx(list(config.wall.corners_m[0]))
    assert wall["size_m"] == pytest.approx([3.6576, 0.9144])
    assert wall["normal"] == pytest.approx([0, 0, 1])
    assert wall["display_px"] == [config.wall.display_width_px, config.wall.display_height_px]
    assert wall["max_plane_residual_m"] == pytest.approx(0.0, abs=1e-12)
    assert PointerConfig.model_validate(resolved["pointer"]) == config.pointer
    assert resolved["detector"] == config.detector.model_dump()


# ----------------------------------------------------------------- calibration files


def test_calibration_values_replace_the_rig_and_the_source_is_named(
    run_check: RunCheck, write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    write("cal.toml", left_calibration)
    write(
        "rig.toml",
        edit(minimal_rig, 'name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"'),
    )
    run = run_check("rig.toml")
    assert (run.returncode, run.stderr) == (0, "")
    assert "  calibration: " in run.stdout and run.stdout.count("cal.toml") >= 2
    assert "camera left: 640x480 RGB8, device (first camera found), geometry from cal.toml" in run.stdout
    assert "fx 550.0 fy 551.0 cx 321.0 cy 239.0 px, distortion [-0.05, 0.01, 0, 0]" in run.stdout
    assert "camera right: 640x480 BGR8, device CAM-0002, geometry inline in rig.toml" in run.stdout

    resolved = json.loads(run_check("rig.toml", "--json").stdout)
    assert Path(resolved["calibration"]).name == "cal.toml"
    left, right = resolved["cameras"]
    assert (left["source"], right["source"]) == ("from cal.toml", "inline in rig.toml")
    assert left["matrix"] == [[550.0, 0.0, 321.0], [0.0, 551.0, 239.0], [0.0, 0.0, 1.0]]
    assert right["centre_m"] == pytest.approx([2.5, 1.0, 1.5])


def test_a_calibration_file_may_replace_the_wall(
    check_in_process: RunCheck, write: Write, edit: Edit, minimal_rig: str
) -> None:
    write("cal.toml", "[wall]\ncorners_m = [[0, 0, 0], [3, 0, 0], [3, 1.5, 0], [0, 1.5, 0]]\n")
    write(
        "rig.toml",
        edit(minimal_rig, 'name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"'),
    )
    resolved = json.loads(check_in_process("rig.toml", "--json").stdout)
    assert resolved["wall"]["source"] == "from cal.toml"
    assert resolved["wall"]["size_m"] == pytest.approx([3.0, 1.5])
    assert [c["source"] for c in resolved["cameras"]] == ["inline in rig.toml"] * 2


# ----------------------------------------------------------------- bad files

POSE_RIGHT = 'extrinsics = { kind = "pose", position_m = [2.5, 1.0, 1.5], yaw_deg = -30.0 }'
POINTS_WALL = """\
points_m = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
origin_m = [0.0, 0.0, 0.0]
x_direction = [1.0, 0.0, 0.0]
y_direction = [0.0, 1.0, 0.0]
width_m = 2.0
height_m = 1.0
"""

# (id, old text, new text, what follows "rig.toml: " on the error line, other fragments)
RIG_EDITS = [
    (
        "unknown_key",
        "length_m = 0.45",
        "lenght_m = 0.45",
        "pointer.lenght_m: unknown key 'lenght_m' (did you mean 'length_m'?); allowed keys here:"
        " front_colour, length_m, length_tolerance_m, end_diameter_m, rod_diameter_m",
        [],
    ),
    (
        "unknown_key_in_a_camera",
        'serial = "CAM-0002"',
        'serail = "CAM-0002"',
        "cameras[1].serail: unknown key 'serail' (did you mean 'serial'?)",
        ["allowed keys here: id, serial, address, device_id, width_px, height_px, pixel_format"],
    ),
    (
        "unknown_key_in_a_lens",
        "focal_length_mm = 6.0",
        "focal_length_m = 6.0",
        "cameras[1].intrinsics.focal_length_m: unknown key 'focal_length_m'",
        ["allowed keys here: model, horizontal_fov_deg, vertical_fov_deg, focal_length_mm"],
    ),
    (
        "unknown_key_in_a_pose",
        "yaw_deg = -30.0 }",
        "yaw = -30.0 }",
        "cameras[1].extrinsics.yaw: unknown key 'yaw' (did you mean 'yaw_deg'?)",
        ["allowed keys here: kind, position_m, yaw_deg, pitch_deg, roll_deg"],
    ),
    (
        "unknown_section",
        "[outputs.zmq]",
        "[output.zmq]",
        "output: unknown key 'output' (did you mean 'outputs'?)",
        ["allowed keys here: version, name, calibration, cameras, wall, pointer"],
    ),
    ("missing_key", "length_m = 0.45\n", "", "pointer.length_m: required key is missing", []),
    ("missing_key_in_a_camera", 'id = "right"\n', "", "cameras[1].id: required key is missing", []),
    (
        "wrong_type",
        "horizontal_fov_deg = 60.0 }",
        'horizontal_fov_deg = "wide" }',
        "cameras[0].intrinsics.horizontal_fov_deg: must be a number",
        ['(got "wide")'],
    ),
    (
        "wrong_type_of_table",
        'name = "minimal"\n',
        'name = "minimal"\nsimulation = 7\n',
        "simulation: must be a table (got 7)",
        [],
    ),
    (
        "value_out_of_range",
        "end_diameter_m = 0.04",
        "end_diameter_m = -0.04",
        "pointer.end_diameter_m: Input should be greater than 0 (got -0.04)",
        [],
    ),
    (
        "field_of_view_out_of_range",
        "horizontal_fov_deg = 60.0, focal",
        "horizontal_fov_deg = 190.0, focal",
        "cameras[1].intrinsics.horizontal_fov_deg: Input should be less than 180 (got 190.0)",
        [],
    ),
    (
        "inconsistent_values",
        "end_diameter_m = 0.04",
        "end_diameter_m = 0.5",
        "pointer: end_diameter_m must be smaller than length_m",
        [],
    ),
    (
        "unknown_pixel_format",
        'pixel_format = "RGB8"',
        'pixel_format = "YUV422"',
        "cameras[0].pixel_format: 'YUV422' is not supported; use one of BayerRG8",
        [],
    ),
    (
        "duplicate_camera_ids",
        'id = "right"',
        'id = "left"',
        "cameras: camera ids must be unique; repeated: left",
        [],
    ),
    (
        "bad_camera_id",
        'id = "right"',
        'id = "right camera"',
        "cameras[1].id: String should match pattern",
        [],
    ),
    (
        "unknown_lens_model",
        'model = "fov", horizontal_fov_deg = 60.0 }',
        'model = "fisheye", horizontal_fov_deg = 60.0 }',
        "cameras[0].intrinsics: tag 'fisheye' in key 'model' does not match any of the expected tags: 'fov', 'opencv'",
        [],
    ),
    (
        "two_rotations",
        POSE_RIGHT,
        'extrinsics = { kind = "opencv", rvec = [0.0, 0.0, 0.0],'
        " rotation_matrix = [[1, 0, 0], [0, 1, 0], [0, 0, 1]], tvec_m = [0, 0, 0] }",
        "cameras[1].extrinsics: give exactly one of rvec or rotation_matrix",
        [],
    ),
    (
        "not_a_rotation",
        POSE_RIGHT,
        'extrinsics = { kind = "opencv", rotation_matrix = [[1, 0, 0], [0, 1, 0], [0, 0, -1]], tvec_m = [0, 0, 0] }',
        "cameras[1].extrinsics: rotation_matrix is not a rotation (orthonormal, determinant +1)",
        [],
    ),
    (
        "vector_too_short",
        "position_m = [2.5, 1.0, 1.5]",
        "position_m = [2.5, 1.0]",
        "cameras[1].extrinsics.position_m: ",
        ["3"],
    ),
    (
        "not_a_number",
        "position_m = [2.5, 1.0, 1.5]",
        "position_m = [2.5, nan, 1.5]",
        "cameras[1].extrinsics.position_m[1]: ",
        ["finite"],
    ),
    ("infinite", "length_m = 0.45", "length_m = inf", "pointer.length_m: ", ["finite"]),
    ("rig_version", "version = 1", "version = 2", "version: Input should be 1 (got 2)", []),
    (
        "one_camera",
        '[[cameras]]\nid = "right"',
        '[[spare_cameras]]\nid = "right"',
        "spare_cameras: unknown key 'spare_cameras'",
        [],
    ),
    (
        "wall_given_twice",
        "width_m = 2.0\n",
        "width_m = 2.0\ncorners_m = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]\n",
        "wall: corners_m already fixes the wall; remove origin_m, x_direction, y_direction,"
        " width_m, height_m, points_m",
        [],
    ),
    (
        "wall_frame_incomplete",
        "y_direction = [0.0, 1.0, 0.0]\n",
        "",
        "wall: with points_m also give y_direction",
        [],
    ),
    (
        "non_coplanar_corners",
        POINTS_WALL,
        "corners_m = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0.1]]\n",
        "wall: corners_m are not coplanar",
        ["tolerance 10.0 mm"],
    ),
    (
        "colinear_wall_points",
        "[0.0, 1.0, 0.0]]",
        "[4.0, 0.0, 0.0]]",
        "wall: the three wall points are colinear",
        [],
    ),
    (
        "colinear_wall_corners",
        POINTS_WALL,
        "corners_m = [[0, 0, 0], [2, 0, 0], [3, 0, 0], [1, 0, 0]]\n",
        "wall: ",
        ["colinear"],
    ),
    (
        "folding_lens",
        'intrinsics = { model = "fov", horizontal_fov_deg = 60.0 }',
        'intrinsics = { model = "opencv", fx_px = 333.0, fy_px = 333.0, cx_px = 319.5,'
        " cy_px = 239.5, distortion = [-0.3, 0.12, 0.001, -0.001, -0.02] }",
        "cameras[0].intrinsics.distortion: the lens model folds over near the image edge",
        ["calibration does not hold out to the corners"],
    ),
    (
        # A new user's audit: NumPy's overflow warnings came before the one line (here seven).
        "a_lens_that_overflows",
        'intrinsics = { model = "fov", horizontal_fov_deg = 60.0 }',
        'intrinsics = { model = "opencv", fx_px = 333.0, fy_px = 333.0, cx_px = 319.5,'
        " cy_px = 239.5, distortion = [1e300, 1e300, 0.0, 0.0, 0.0] }",
        "cameras[0].intrinsics.distortion: the lens model folds over near the image edge",
        ["projects back inf px away"],
    ),
    (
        # A new user's audit: a billion pixels wide passed the check; twenty digits were blamed on the lens.
        "an_image_side_beyond_any_sensor",
        'width_px = 640\nheight_px = 480\npixel_format = "RGB8"',
        'width_px = 6400000\nheight_px = 480\npixel_format = "RGB8"',
        "cameras[0].width_px: Input should be less than or equal to 65535 (got 6400000)",
        [],
    ),
]


# The kinds of bad file the CLI must be seen to handle in a real process; the other
# cases run the same entry point in-process, which is ten times faster.
IN_A_SUBPROCESS = {
    "unknown_key",
    "missing_key",
    "wrong_type",
    "value_out_of_range",
    "duplicate_camera_ids",
    "non_coplanar_corners",
    "colinear_wall_points",
    "a_lens_that_overflows",
}


# Valid rigs that cannot track yet: config check passes and says what is left; the tracking commands
# (which load the rig with load_rig) refuse them with that line.
NOT_READY_EDITS = [
    (
        "missing_section",
        "[pointer]\nlength_m = 0.45\nend_diameter_m = 0.04\n",
        "",
        "pointer: required table is missing; tracking needs it",
        [],
    ),
    (
        "mono8",
        'pixel_format = "BGR8"',
        'pixel_format = "Mono8"',
        "cameras[1].pixel_format: Mono8 is monochrome",
        ["use one of BayerRG8, BayerGB8, BayerGR8, BayerBG8, RGB8, BGR8"],
    ),
    (
        "no_intrinsics_and_no_calibration_file",
        'intrinsics = { model = "fov", horizontal_fov_deg = 60.0 }\n',
        "",
        "cameras[0] ('left') has no intrinsics",
        ["calibration"],
    ),
]


@pytest.mark.parametrize(
    ("case", "old", "new", "where", "fragments"),
    [pytest.param(*case, id=case[0]) for case in NOT_READY_EDITS],
)
def test_a_rig_not_ready_to_track_passes_the_check_and_says_what_is_left(
    run_check: RunCheck,
    write: Write,
    edit: Edit,
    minimal_rig: str,
    case: str,
    old: str,
    new: str,
    where: str,
    fragments: list[str],
) -> None:
    rig = write("rig.toml", edit(minimal_rig, old, new))
    run = run_check("rig.toml")
    assert run.returncode == 0 and run.stderr == "", run
    assert run.stdout.startswith(f"rig.toml: OK for calibration; not ready to track yet: {where}"), run.stdout
    for fragment in fragments:
        assert fragment in run.stdout
    with pytest.raises(CalibrationPending, match=re.escape(where)):
        load_rig(rig)


@pytest.mark.parametrize(
    ("case", "added", "says"),
    [
        ("token file missing", '\n[console]\ntoken_file = "missing-token"\n', "cannot read the console token file"),
        ("token file empty", '\n[console]\ntoken_file = "empty-token"\n', "the console token file is empty"),
        ("CURVE key missing", 'curve_secret_key_file = "missing.key_secret"\n', "no such CURVE key file"),
    ],
    ids=["token file missing", "token file empty", "CURVE key missing"],
)
def test_check_refuses_a_rig_whose_files_the_daemon_would_refuse(
    run_check: RunCheck, write: Write, edit: Edit, minimal_rig: str, case: str, added: str, says: str
) -> None:
    """`config check --ready FILE && systemctl reload trackerd` (docs/deployment.md): OK must mean the
    daemon starts. A console token file or a CURVE key file it cannot use passed the check, and `run` then
    refused the rig (exit 2)."""
    write("empty-token", "")
    if added.startswith("curve"):
        text = edit(
            minimal_rig, 'endpoints = ["tcp://127.0.0.1:5560"]\n', 'endpoints = ["tcp://127.0.0.1:5560"]\n' + added
        )
    else:
        text = minimal_rig + added
    write("rig.toml", text)
    assert_one_line_error(run_check("rig.toml", "--ready"), "rig.toml: ", says)
    plain = run_check("rig.toml")  # without --ready: the rig as written, for a machine without those files
    assert plain.returncode == 0 and plain.stdout.startswith("rig.toml: OK"), plain.stderr


def test_the_daemon_refuses_a_rig_not_ready_to_track_in_one_line(
    write: Write, edit: Edit, minimal_rig: str, tmp_path: Path
) -> None:
    write("rig.toml", edit(minimal_rig, 'pixel_format = "BGR8"', 'pixel_format = "Mono8"'))
    run = _trackerd("run", "--config", "rig.toml", cwd=tmp_path)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert run.stderr.strip().splitlines()[-1].endswith("so it needs colour too)")
    assert "cameras[1].pixel_format: Mono8 is monochrome" in run.stderr


@pytest.mark.parametrize(
    ("case", "old", "new", "where", "fragments"),
    [pytest.param(*case, id=case[0]) for case in RIG_EDITS],
)
def test_bad_rig_gives_one_line_naming_file_and_key(
    run_check: RunCheck,
    check_in_process: RunCheck,
    write: Write,
    edit: Edit,
    minimal_rig: str,
    case: str,
    old: str,
    new: str,
    where: str,
    fragments: list[str],
) -> None:
    write("rig.toml", edit(minimal_rig, old, new))
    run = (run_check if case in IN_A_SUBPROCESS else check_in_process)("rig.toml")
    assert_one_line_error(run, f"rig.toml: {where}", *fragments)


def test_bad_toml_syntax(run_check: RunCheck, write: Write, edit: Edit, minimal_rig: str) -> None:
    write("rig.toml", edit(minimal_rig, 'name = "minimal"', 'name = "minimal'))
    assert_one_line_error(run_check("rig.toml"), "rig.toml: not valid TOML: ", "(at line 2, column 16)")


def test_a_byte_order_mark_in_front_is_not_the_files_content(
    run_check: RunCheck, write: Write, minimal_rig: str
) -> None:
    # Windows editors save UTF-8 with one; it was "Invalid statement (at line 1, column 1)".
    path = write("rig.toml", minimal_rig)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    run = run_check("rig.toml")
    assert run.returncode == 0 and run.stderr == "", run


def test_missing_file(run_check: RunCheck) -> None:
    assert_one_line_error(run_check("nowhere.toml"), "nowhere.toml: no such file")


def test_a_directory_instead_of_a_file(check_in_process: RunCheck, tmp_path: Path) -> None:
    (tmp_path / "rigs").mkdir()
    assert_one_line_error(check_in_process("rigs"), "rigs: is a directory")


def test_a_binary_file(check_in_process: RunCheck, tmp_path: Path) -> None:
    (tmp_path / "rig.toml").write_bytes(b'name = "\xff\xfe"\n')
    assert_one_line_error(check_in_process("rig.toml"), "rig.toml: not ")


def test_absolute_path_is_named_as_given(check_in_process: RunCheck, write: Write, minimal_rig: str) -> None:
    path = write("rig.toml", minimal_rig.replace("[pointer]", "[pointers]"))
    assert_one_line_error(check_in_process(path), f"{path}: pointers: unknown key")


def test_calibration_naming_an_unknown_camera(
    run_check: RunCheck, write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    cal = write("cal.toml", edit(left_calibration, "[cameras.left]", "[cameras.middle]"))
    write(
        "rig.toml",
        edit(minimal_rig, 'name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"'),
    )
    assert_one_line_error(
        run_check("rig.toml"),
        f"{cal}: cameras.middle: no camera with this id in the rig",
        "(the rig has left, right)",
    )


def test_bad_key_in_a_calibration_file_names_that_file(
    check_in_process: RunCheck, write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    cal = write("cal.toml", edit(left_calibration, "cx_px", "cxx_px"))
    write(
        "rig.toml",
        edit(minimal_rig, 'name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"'),
    )
    assert_one_line_error(
        check_in_process("rig.toml"),
        f"{cal}: cameras.left.intrinsics.cxx_px: unknown key 'cxx_px'",
        "did you mean 'cx_px'?",
    )


def test_calibration_that_breaks_the_merged_rig(
    check_in_process: RunCheck, write: Write, edit: Edit, minimal_rig: str, left_calibration: str
) -> None:
    # A principal point valid on its own but outside the rig's 640x480 image.
    cal = write("cal.toml", edit(left_calibration, "cx_px = 321.0", "cx_px = 960.0"))
    write(
        "rig.toml",
        edit(minimal_rig, 'name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"'),
    )
    assert_one_line_error(
        check_in_process("rig.toml"),
        f"{cal}: after merging into the rig: cameras[0]",
        "principal point (960.0, 239.0) lies outside the 640x480 image",
    )


def test_missing_calibration_file_names_the_rig_key(
    check_in_process: RunCheck, write: Write, edit: Edit, minimal_rig: str
) -> None:
    write(
        "rig.toml",
        edit(minimal_rig, 'name = "minimal"', 'name = "minimal"\ncalibration = "cal.toml"'),
    )
    run = check_in_process("rig.toml")
    assert run.returncode == 0, run
    assert "rig.toml: OK for calibration; not ready to track yet: calibration: " in run.stdout
    assert "cal.toml: no such file yet" in run.stdout and "`trackerd calibrate intrinsics" in run.stdout
