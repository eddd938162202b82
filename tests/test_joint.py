"""Choosing each ball's candidate in every camera at once (trackerd/joint/)."""

from __future__ import annotations

import numpy as np

from trackerd.detect.ballfit import BallFit
from trackerd.detect.search import Candidate
from trackerd.geometry.camera import CameraModel
from trackerd.joint import JointChoice, choose_jointly
from trackerd.joint.looks import ROD_LOOK_STEP

K = np.array([[1600.0, 0.0, 960.0], [0.0, 1600.0, 540.0], [0.0, 0.0, 1.0]])
BALL_R = 0.02
LENGTH = 0.45
RED = np.array([1.4, 0.8, 1.6])
BLUE = RED + np.array([0.1, 0.08, 0.43]) / np.linalg.norm([0.1, 0.08, 0.43]) * LENGTH


def _camera(name: str, position) -> CameraModel:
    position = np.asarray(position, float)
    forward = np.array([1.8, 0.6, 1.8]) - position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    return CameraModel.from_pose(
        name, 1920, 1080, K, np.zeros(0), position, np.column_stack([right, np.cross(forward, right), forward])
    )


CAMERAS = [_camera("left", [-1.2, 1.6, 3.2]), _camera("right", [4.8, 1.6, 3.2]), _camera("back", [1.9, 2.2, 5.8])]


def _ball(cam: CameraModel, point, colour: str, radius_m: float = BALL_R) -> Candidate:
    centre = cam.project(np.asarray(point, float)[None])[0]
    radius = cam.focal_px * radius_m / float(np.linalg.norm(np.asarray(point) - cam.centre_m))
    fit = BallFit(True, centre, radius, np.zeros((0, 2)), 1.0, 0.25, 0.05, 100.0)
    return Candidate(colour, fit, (float(centre[0]), float(centre[1])), radius)


def _choose(candidates, cameras=CAMERAS, look=None, rod=None):
    room = (np.array([0.0, 0.0, 1.0]), 0.0)  # the wall is z = 0, the room at z > 0
    return choose_jointly(cameras, candidates, BALL_R, LENGTH, 0.05, 0.03, room, look, rod)


def test_decoys_on_the_wall_and_in_one_camera_do_not_win() -> None:
    """Each camera sees the two balls and red decoys: a red sticker on the wall (it triangulates, but is
    not the pointer's length from the blue ball), a large red disc near the ball in one image, and
    a red blob only one camera sees."""
    sticker = np.array([2.2, 0.5, 0.0])
    candidates = []
    for k, cam in enumerate(CAMERAS):
        decoys = [_ball(cam, sticker, "red", 0.025)]
        if k == 0:
            near = _ball(cam, RED, "red", 0.05)  # the size of a ball twice as close
            near.fit.centre_px[:] += [30.0, 10.0]
            decoys += [near, _ball(cam, RED + np.array([0.3, -0.5, 0.4]), "red")]
        candidates.append({"red": [*decoys, _ball(cam, RED, "red")], "blue": [_ball(cam, BLUE, "blue")]})
    choice = _choose(candidates)
    assert isinstance(choice, JointChoice)
    assert np.linalg.norm(choice.red_m - RED) < 1e-6 and np.linalg.norm(choice.blue_m - BLUE) < 1e-6
    for k, picks in enumerate(choice.chosen):
        assert picks["red"] is candidates[k]["red"][-1] and picks["blue"] is candidates[k]["blue"][0]


def test_a_ball_one_camera_misses_is_chosen_from_the_others() -> None:
    candidates = [{"red": [_ball(cam, RED, "red")], "blue": [_ball(cam, BLUE, "blue")]} for cam in CAMERAS]
    candidates[2]["red"] = []  # the presenter's body hides it from the back camera
    choice = _choose(candidates)
    assert isinstance(choice, JointChoice)
    assert choice.chosen[2]["red"] is None and choice.chosen[2]["blue"] is not None
    assert np.linalg.norm(choice.red_m - RED) < 1e-6


def test_a_ball_merged_in_one_of_two_cameras_is_looked_for_where_the_length_puts_it() -> None:
    """Two cameras; the red ball is no candidate in the right camera (it merged with a picture): it is
    looked for on the sphere of the pointer's length around the blue point, where the left camera's ray
    meets it."""
    cameras = CAMERAS[:2]
    candidates = [{"red": [_ball(cam, RED, "red")], "blue": [_ball(cam, BLUE, "blue")]} for cam in cameras]
    candidates[1]["red"] = []
    asked = []

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        asked.append((camera, colour))
        truth = _ball(cameras[camera], RED, "red")
        near = np.hypot(*(truth.fit.centre_px - [x, y])) < 3.0
        return [truth] if colour == "red" and near else []

    assert isinstance(_choose(candidates, cameras), str)  # without looking: no red point
    choice = _choose(candidates, cameras, look)
    assert isinstance(choice, JointChoice), choice
    assert (1, "red") in asked
    assert np.linalg.norm(choice.red_m - RED) < 1e-6


def test_a_ball_is_looked_for_even_where_a_side_on_cameras_ray_misses_the_length_sphere() -> None:
    """The left camera sees the pointer side-on: its ray through the red ball is at right angles to the
    pointer, so it only grazes the sphere of the pointer's length around the blue point, and a blue point
    a few millimetres off (as noise puts it) leaves it outside. The ball is looked for where the ray comes
    closest, allowed along the ray as far as the length's tolerance reaches."""
    cameras = CAMERAS[:2]
    sight = RED - cameras[0].centre_m
    across = np.cross(sight, [0.0, 1.0, 0.0]) + np.cross(sight, [1.0, 0.0, 0.0]) * 0.3
    across /= np.linalg.norm(across)
    blue = RED + across * LENGTH
    blue_seen = blue + across * 0.004  # the triangulated blue point, 4 mm further out
    candidates = [{"red": [_ball(cam, RED, "red")], "blue": [_ball(cam, blue_seen, "blue")]} for cam in cameras]
    candidates[1]["red"] = []

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        truth = _ball(cameras[camera], RED, "red")
        return [truth] if colour == "red" and np.hypot(*(truth.fit.centre_px - [x, y])) < 20.0 else []

    choice = _choose(candidates, cameras, look)
    assert isinstance(choice, JointChoice), choice
    assert choice.chosen[1]["red"] is not None
    assert np.linalg.norm(choice.red_m - RED) < 0.01


def test_a_look_s_next_outline_is_asked_for_when_the_first_is_not_where_the_ball_must_be() -> None:
    """A look may first fit a round outline a radius away from the ball (a dark ball before a brighter
    picture of its hue, in its colour's excess) and the ball itself only in a later pass (in its tint):
    the first is not where the pointer's length puts the ball, so the next is asked for, and taken; none
    after it is made."""
    cameras = CAMERAS[:2]
    candidates = [{"red": [_ball(cam, RED, "red")], "blue": [_ball(cam, BLUE, "blue")]} for cam in cameras]
    candidates[1]["red"] = []
    made: list[list] = []  # per look, the outlines it made

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        if colour != "red":
            return
        made.append([])
        truth = _ball(cameras[camera], RED, "red")
        beside = _ball(cameras[camera], RED, "red")
        beside.fit.centre_px[:] += [0.0, -truth.fit.radius_px]  # a radius above the ball
        for outline in (beside, truth, truth):
            made[-1].append(outline)
            yield outline

    choice = _choose(candidates, cameras, look)
    assert isinstance(choice, JointChoice), choice
    assert np.linalg.norm(choice.red_m - RED) < 1e-6
    assert choice.chosen[1]["red"] is not None
    assert np.allclose(choice.chosen[1]["red"].fit.centre_px, _ball(cameras[1], RED, "red").fit.centre_px)
    # Where the ball was taken, its outline was the second made and no third was; elsewhere (the length's
    # sphere crossed twice) nothing was where the ball must be, and all three were made.
    assert sorted(len(outlines) for outlines in made)[0] == 2


def test_a_ball_no_camera_offered_is_looked_for_where_the_rod_leads() -> None:
    """The blue ball merged with a picture of its colour in both cameras: no blue candidate anywhere, so no
    ray to look along. The rod leaves the red ball towards it in both images; the looks along the rod's
    image line find it (here only within 3 px of its centre, as a real look needs to start inside the
    ball), and they triangulate. Where the rod shows in one camera only, or leads elsewhere, nothing is."""
    cameras = CAMERAS[:2]
    candidates = [{"red": [_ball(cam, RED, "red")], "blue": []} for cam in cameras]
    looks: list[tuple[int, str]] = []
    looked_at: list[tuple[int, float, float, float]] = []

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        looks.append((camera, colour))
        looked_at.append((camera, x, y, radius))
        truth = _ball(cameras[camera], BLUE, "blue")
        return [truth] if colour == "blue" and np.hypot(*(truth.fit.centre_px - [x, y])) < 3.0 else []

    def rod_towards(towards_m, cameras_showing=(0, 1)):
        def rod(camera: int, x: float, y: float, radius: float):
            if camera not in cameras_showing:
                return None
            far = cameras[camera].project(towards_m[None])[0] - [x, y]
            return tuple(far / np.linalg.norm(far))

        return rod

    assert isinstance(_choose(candidates, cameras, look), str)  # without the rod
    choice = _choose(candidates, cameras, look, rod_towards(BLUE))
    assert isinstance(choice, JointChoice), choice
    assert np.linalg.norm(choice.blue_m - BLUE) < 1e-6
    assert all(picks["blue"] is not None for picks in choice.chosen)
    looks.clear()
    assert isinstance(_choose(candidates, cameras, look, rod_towards(BLUE, cameras_showing=(0,))), str)
    assert looks == []  # one camera's rod is no axis
    # The rod as if it left the red ball the other way: looked for there (and only there), nothing found.
    elsewhere = RED + (RED - BLUE)
    assert isinstance(_choose(candidates, cameras, look, rod_towards(elsewhere)), str)
    assert looks and all(colour == "blue" for _, colour in looks)
    looked_at.clear()
    _choose(candidates, cameras, look, rod_towards(elsewhere))
    for camera, x, y, radius in looked_at:  # along the rod's line, at most two steps from the prediction
        assert np.hypot(*(cameras[camera].project(elsewhere[None])[0] - [x, y])) < 2 * ROD_LOOK_STEP * radius + 0.5


def test_balls_each_offered_by_a_different_camera_are_looked_for_along_their_epipolar_lines() -> None:
    """The red ball offered by the left camera only, the blue by the right only: nothing triangulates, so
    there is no point to look from. Each candidate the rod leaves is looked for along its epipolar line in
    the other camera, between the distances its image size allows; both finds triangulate and pair. Where
    no rod leaves them (blobs of a picture), they are not looked from."""
    cameras = CAMERAS[:2]
    candidates = [
        {"red": [_ball(cameras[0], RED, "red")], "blue": []},
        {"red": [], "blue": [_ball(cameras[1], BLUE, "blue")]},
    ]
    looks: list[tuple[int, str]] = []

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        looks.append((camera, colour))
        truth = _ball(cameras[camera], RED if colour == "red" else BLUE, colour)
        return [truth] if np.hypot(*(truth.fit.centre_px - [x, y])) < 0.5 * truth.fit.radius_px else []

    def rod(camera: int, x: float, y: float, radius: float):
        return (1.0, 0.0)

    assert isinstance(_choose(candidates, cameras, look), str)  # without the rod, no look along the line
    choice = _choose(candidates, cameras, look, rod)
    assert isinstance(choice, JointChoice), choice
    assert np.linalg.norm(choice.red_m - RED) < 1e-6 and np.linalg.norm(choice.blue_m - BLUE) < 1e-6
    assert (1, "red") in looks and (0, "blue") in looks
    looks.clear()
    assert isinstance(_choose(candidates, cameras, look, lambda camera, x, y, radius: None), str)
    assert looks == []


def _rod_towards(cameras, towards_m):
    """Each camera's rod leaving the ball it is asked about towards ``towards_m`` (the image direction)."""

    def rod(camera: int, x: float, y: float, radius: float):
        far = cameras[camera].project(np.asarray(towards_m, float)[None])[0] - [x, y]
        return tuple(far / np.linalg.norm(far))

    return rod


def test_a_ball_one_camera_alone_offers_is_placed_by_its_ray_and_the_length_where_the_rod_leads() -> None:
    """The blue ball is offered by the right camera only; no look finds it in the left one (it lies on a
    surface of its hue there). The red ball triangulates and the rod leaves it towards the blue one in both
    images: the right camera's ray through the blue candidate meets the sphere of the pointer's length around
    the red point twice, and the root the rod's axis points at is the ball. A blue blob off the rod's line
    in the same camera is not taken; without the rod, or with the rod leading elsewhere, nothing is."""
    cameras = CAMERAS[:2]
    junk = _ball(cameras[1], RED + np.array([0.2, -0.3, 0.1]), "blue")
    candidates = [
        {"red": [_ball(cameras[0], RED, "red")], "blue": []},
        {"red": [_ball(cameras[1], RED, "red")], "blue": [junk, _ball(cameras[1], BLUE, "blue")]},
    ]

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        return []

    assert isinstance(_choose(candidates, cameras, look), str)  # without the rod
    choice = _choose(candidates, cameras, look, _rod_towards(cameras, BLUE))
    assert isinstance(choice, JointChoice), choice
    assert choice.one_camera == "blue"
    assert np.linalg.norm(choice.blue_m - BLUE) < 1e-6 and np.linalg.norm(choice.red_m - RED) < 1e-6
    assert choice.chosen[1]["blue"] is candidates[1]["blue"][1] and choice.chosen[0]["blue"] is None
    # The other root lies on the same ray, the pointer's length from the red ball, on the far side of
    # where the ray passes it: the left camera's rod tells them apart, and where it leads there, that is the
    # ball (the right camera sees both roots at the blue candidate's pixel).
    ray = BLUE - cameras[1].centre_m
    ray /= np.linalg.norm(ray)
    closest = cameras[1].centre_m + float((RED - cameras[1].centre_m) @ ray) * ray
    mirror = 2.0 * closest - BLUE
    assert abs(np.linalg.norm(mirror - RED) - LENGTH) < 1e-9
    other_root = _choose(candidates, cameras, look, _rod_towards(cameras, mirror))
    assert isinstance(other_root, JointChoice) and np.linalg.norm(other_root.blue_m - mirror) < 1e-6
    reason = _choose(candidates, cameras, look, _rod_towards(cameras, RED + (RED - BLUE)))
    assert isinstance(reason, str) and "where the rod leads" in reason, reason


def test_a_ball_one_camera_sees_at_a_glancing_angle_to_the_pointer_is_not_placed() -> None:
    """The pointer held across the left camera's line of sight: its ray through the blue ball meets the
    length's sphere around the red one at a glancing angle, where an error of the length's size moves the
    ball along the ray several times as far, and the two roots nearly meet. Not found, with the reason."""
    cameras = CAMERAS[:2]
    across = np.cross(RED - cameras[0].centre_m, [0.0, 1.0, 0.0])
    blue = RED + LENGTH * across / np.linalg.norm(across)
    sight = (blue - cameras[0].centre_m) / np.linalg.norm(blue - cameras[0].centre_m)
    assert abs(float(sight @ (blue - RED))) / LENGTH < 0.25
    candidates = [
        {"red": [_ball(cameras[0], RED, "red")], "blue": [_ball(cameras[0], blue, "blue")]},
        {"red": [_ball(cameras[1], RED, "red")], "blue": []},
    ]
    reason = _choose(candidates, cameras, lambda *args: [], _rod_towards(cameras, blue))
    assert isinstance(reason, str) and "glancing" in reason, reason


def test_no_pointer_is_a_reason() -> None:
    candidates = [
        {"red": [_ball(cam, RED, "red")], "blue": [_ball(cam, RED + np.array([1.0, 0.0, 0.0]), "blue")]}
        for cam in CAMERAS
    ]
    reason = _choose(candidates)
    assert isinstance(reason, str) and "length apart" in reason
    assert "no red" in _choose([{"red": [], "blue": []} for _ in CAMERAS])


def test_what_a_look_finds_is_not_looked_from_again() -> None:
    """The red ball merged in two of three cameras: looking from the one camera's red candidate finds it
    in the other two. Those finds join the candidates for the pairing, but the rays looked along stay the
    searches' own: were each find looked from again, every find would seed looks in every other camera,
    and a 4-camera installation made 240,000 looks for one frame."""
    candidates = [{"red": [_ball(cam, RED, "red")], "blue": [_ball(cam, BLUE, "blue")]} for cam in CAMERAS]
    candidates[1]["red"] = []
    candidates[2]["red"] = []
    asked = []

    def look(camera: int, colour: str, x: float, y: float, radius: float, axis):
        asked.append((camera, colour))
        truth = _ball(CAMERAS[camera], RED if colour == "red" else BLUE, colour)
        return [truth] if np.hypot(*(truth.fit.centre_px - [x, y])) < 3.0 else []

    choice = _choose(candidates, look=look)
    assert isinstance(choice, JointChoice), choice
    assert choice.chosen[1]["red"] is not None and choice.chosen[2]["red"] is not None
    assert np.linalg.norm(choice.red_m - RED) < 1e-6
    # Red is looked for from camera 0's one candidate only (into the two other cameras, at most two
    # crossings of the length's sphere, around each of at most GUIDED_POINTS blue points); blue from the
    # three offered blue candidates around the one red point.
    from trackerd.joint import GUIDED_POINTS

    assert sum(1 for _, colour in asked if colour == "red") <= GUIDED_POINTS * 2 * 2
    assert sum(1 for _, colour in asked if colour == "blue") <= 3 * 2 * 2
