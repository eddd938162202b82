"""The failure classes found on scenes trackerd did not render for itself (issue 13), each rebuilt on
purpose and located by the daemon's own `Locator`, first sighting (a full search):

* a red ball in front of a magenta picture, one blob at the detector's thresholds;
* cameras behind the presenter: the rod over the front ball, and interpretation planes nearly parallel;
* dark paint in dim light, below the thresholds;
* one end hidden from one camera of three by the presenter's body.

Each failed on the code before the outline fit, the joint choice and the pointer fit (checked by
hand with [locator] refine = "never", which is that code's path: not found, or errors of centimetres).
"""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.config.rig_geometry import wall_frame
from trackerd.locator import Locator
from trackerd.sim.appearance import Look, Occluder
from trackerd.sim.randomized import aimed_camera, build_rig
from trackerd.sim.render import SceneRenderer
from trackerd.sim.scene import PointerPose, pose_aimed_at, true_wall_hit

WALL_W, WALL_H, ABOVE_FLOOR = 3.6, 1.2, 0.9
POINTER = {"length_m": 0.42, "end_diameter_m": 0.036, "rod_diameter_m": 0.012}
PRESENTER = np.array([1.8, 0.5, 1.8])  # the middle of where the presenter stands (floor at y = -0.9)


def _scene(cameras, look: Look | None = None, **simulation):
    rig = build_rig(
        "scene",
        [(cam, "BayerRG8") for cam in cameras],
        WALL_W,
        WALL_H,
        ABOVE_FLOOR,
        POINTER,
        {"seed": 11, "clutter": 6, **simulation},
    )
    renderer = SceneRenderer(rig, list(cameras), look=look or Look(), cache_dir=False)
    return rig, renderer


def _locate(rig, renderer, pose: PointerPose, rng, *, content=None, occluders=()):
    views = [renderer.render(i, pose, rng, content=content, occluders=occluders) for i in range(len(renderer.cameras))]
    locator = Locator(rig, cameras=renderer.cameras)
    fix = locator.locate([v.image for v in views])
    truth = true_wall_hit(pose, wall_frame(rig.wall)).wall_xy_m
    error = None if fix.hit is None else float(np.linalg.norm(fix.hit.wall_xy_m - truth))
    return fix, error, views


def _pose_from_the_middle(
    rng: np.random.Generator, tip_heights_m: tuple[float, float], target_heights_m: tuple[float, float]
) -> PointerPose:
    """The pointer held 1.6 m from the wall before the display's middle, aimed at a random place on it."""
    target_x = float(rng.uniform(1.4, 2.2))
    tip = [target_x + float(rng.uniform(-0.1, 0.1)), float(rng.uniform(*tip_heights_m)), 1.6]
    return pose_aimed_at(tip, [target_x, float(rng.uniform(*target_heights_m)), 0.0], POINTER["length_m"])


def _side_cameras():
    return [
        aimed_camera("left", [-0.8, 1.3, 3.2], PRESENTER, 1920, 1080, 60.0),
        aimed_camera("right", [4.4, 1.3, 3.2], PRESENTER, 1920, 1080, 60.0),
    ]


def _behind_cameras():
    """High at the back of the room, either side of the presenter, looking at the wall past them."""
    target = PRESENTER + np.array([0.0, 0.0, -0.4])
    return [
        aimed_camera("back-left", [0.9, 1.9, 5.6], target, 1920, 1080, 42.0),
        aimed_camera("back-right", [2.7, 1.9, 5.6], target, 1920, 1080, 42.0),
    ]


def test_a_red_ball_in_front_of_a_magenta_picture_is_found() -> None:
    rig, renderer = _scene(_side_cameras())
    magenta = np.zeros((256, 768, 3), dtype=np.float32)
    magenta[:] = (0.85, 0.15, 0.55)
    rng = np.random.default_rng(2)
    located = 0
    for target_x in (1.2, 1.8, 2.4):
        pose = pose_aimed_at([target_x - 0.1, 0.55, 0.9], [target_x, 0.6, 0.0], POINTER["length_m"])
        fix, error, views = _locate(rig, renderer, pose, rng, content=magenta)
        # The red ball is in front of the picture in the images (that is the case being tested).
        assert all(v.truth.visible_fraction("red") > 0.8 for v in views)
        if error is not None:
            located += 1
            assert error < 0.01, (error, fix.reason)
    assert located == 3


def test_cameras_behind_the_presenter_with_the_rod_over_the_front_ball() -> None:
    """(The other half of that rig's trouble, interpretation planes close to parallel, is
    tests/geometry/test_pointer_fit.py's: it needs measurements whose errors are known exactly.)"""
    rig, renderer = _scene(_behind_cameras())
    rng = np.random.default_rng(5)
    errors = []
    for target_x in (1.6, 1.8, 2.0):
        pose = pose_aimed_at([target_x + 0.05, 0.6, 1.6], [target_x, 0.5, 0.0], POINTER["length_m"])
        fix, error, views = _locate(rig, renderer, pose, rng)
        # The front ball is partly behind the rod (and the back ball) from both cameras.
        front = rig.pointer.front_colour
        assert min(v.truth.visible_fraction(front) for v in views) < 0.97
        assert error is not None, fix.reason
        errors.append(error)
    assert np.median(errors) < 0.004 and max(errors) < 0.008, errors


def test_dark_paint_in_dim_light_is_found() -> None:
    look = Look(red_rgb=(0.5, 0.06, 0.05), blue_rgb=(0.06, 0.10, 0.46), gain=0.45)
    rig, renderer = _scene(_side_cameras(), look, noise_sigma=2.0, shot_noise=0.3)
    rng = np.random.default_rng(8)
    errors = []
    for target_x in (1.0, 2.0, 2.8):
        pose = pose_aimed_at([target_x + 0.2, 0.5, 1.7], [target_x, 0.5, 0.0], POINTER["length_m"])
        fix, error, _ = _locate(rig, renderer, pose, rng)
        assert error is not None, fix.reason
        errors.append(error)
    assert max(errors) < 0.008, errors


def test_a_dark_red_ball_before_a_bright_red_picture_is_found() -> None:
    """From behind the presenter, both cameras see the front (red) ball against the display, which shows a
    bright red: ball and picture are one group under every hue test, in both cameras, so no camera offers
    the ball. The darker part of the group is split off and its outline fitted (trackerd/detect/search.py,
    split_candidates). Random poses, those where both balls are at least 60 % visible in both cameras."""
    rig, renderer = _scene(_behind_cameras(), Look(red_rgb=(0.36, 0.04, 0.03)))
    bright_red = np.zeros((256, 768, 3), dtype=np.float32)
    bright_red[:] = (0.95, 0.25, 0.15)
    rng = np.random.default_rng(21)
    errors = []
    while len(errors) < 3:
        pose = _pose_from_the_middle(rng, (0.5, 0.7), (0.4, 0.7))
        fix, error, views = _locate(rig, renderer, pose, rng, content=bright_red)
        if min(v.truth.visible_fraction(c) for v in views for c in ("red", "blue")) < 0.6:
            continue  # the hand hides the back ball from a camera: not this test's case
        assert error is not None, fix.reason
        errors.append(error)
    assert max(errors) < 0.02, errors


def test_a_red_ball_on_the_edge_of_a_red_band_is_found_where_the_rod_leads(monkeypatch: pytest.MonkeyPatch) -> None:
    """From behind the presenter, both cameras see the front (red) ball on the top edge of a red band across
    the display, of the ball's own paint: one region in both cameras, too large for a ball, its split no
    ball either, so no camera offers the ball and the looks from the other ball's candidates have none of
    its rays to start from (`bench robustness`: seed 7 installation 21 frame 29, a blue ball on a blue block;
    seed 11 installation 13 frame 20). The blue ball triangulates, the rod leaves it in both images, and
    the red ball is looked for along the rod where the pointer's axis puts it (trackerd/joint/looks.py,
    look_along_rod). Without that look a pose here is not found; with a darker red, (0.75, 0.08, 0.06)
    for ball and band, 5 of 16 such poses were found without it and 16 of 16 with it."""
    import trackerd.joint.choice as choice

    found_along_rod: list[int] = []  # red outlines each look along the rod added, this pose
    look_along_rod = choice.look_along_rod

    def counted(cameras, candidates, colour, *rest) -> None:
        before = sum(len(per_camera[colour]) for per_camera in candidates)
        look_along_rod(cameras, candidates, colour, *rest)
        found_along_rod.append(sum(len(per_camera[colour]) for per_camera in candidates) - before)

    monkeypatch.setattr(choice, "look_along_rod", counted)
    rig, renderer = _scene(_behind_cameras())
    display_top_m = renderer.room.display[3]
    display_height_m = display_top_m - renderer.room.display[1]
    rng = np.random.default_rng(5)
    errors = []
    while len(errors) < 3:
        pose = _pose_from_the_middle(rng, (0.75, 0.95), (0.6, 0.9))
        # The band's top edge 2 cm under where the cameras see the ball's centre on the display.
        red_m = pose.front_m if rig.pointer.front_colour == "red" else pose.back_m
        seen_y_m = [
            c.centre_m[1] + (red_m[1] - c.centre_m[1]) * c.centre_m[2] / (c.centre_m[2] - red_m[2])
            for c in renderer.cameras
        ]
        edge_row = round((display_top_m - (float(np.mean(seen_y_m)) - 0.02)) / display_height_m * 256)
        content = np.full((256, 768, 3), (0.9, 0.9, 0.85), dtype=np.float32)
        content[edge_row:] = Look().red_rgb
        found_along_rod.clear()
        fix, error, views = _locate(rig, renderer, pose, rng, content=content)
        if min(v.truth.visible_fraction(c) for v in views for c in ("red", "blue")) < 0.6:
            continue  # the hand hides the back ball from a camera: not this test's case
        assert error is not None, fix.reason
        assert sum(found_along_rod) >= 1  # found there, not by another stage
        errors.append(error)
    assert max(errors) < 0.008, errors


def test_an_end_hidden_from_one_camera_of_three_by_the_presenters_arm() -> None:
    """The arm hides the blue ball from the left camera, which sees a blue ball on a shelf instead (the
    only blue thing it sees): taken for the end, it does not agree with the other two cameras, and is left
    out rather than rejecting the pair or pulling the hit."""
    cameras = [*_side_cameras(), aimed_camera("back", [1.8, 1.8, 5.8], PRESENTER, 1920, 1080, 40.0)]
    rig, renderer = _scene(cameras)
    rng = np.random.default_rng(3)
    pose = pose_aimed_at([1.7, 0.55, 1.6], [1.5, 0.6, 0.0], POINTER["length_m"])
    left = cameras[0]
    on_line = pose.back_m + 0.3 * (left.centre_m - pose.back_m)
    arm = Occluder(
        "cylinder",
        (float(on_line[0]), float(on_line[1]), float(on_line[2])),
        0.06,
        (0.15, 0.15, 0.2),
        height_m=0.4,
        label="body",
    )
    decoy = Occluder("sphere", (0.9, 0.9, 2.2), 0.02, (0.10, 0.20, 0.86), label="decoy")
    fix, error, views = _locate(rig, renderer, pose, rng, occluders=(arm, decoy))
    assert views[0].truth.visible_fraction("blue") == 0.0 and views[0].truth.visible_fraction("red") > 0.8
    assert error is not None and error < 0.006, (error, fix.reason)
    assert fix.measurements[0]["red"] is not None


def test_tracked_pairs_take_the_tracked_path_within_their_sigma() -> None:
    """A first sighting is refined (every end's outline fitted); while tracking, pairs take the tracked path
    (each centroid corrected by its ball's outline as last measured: trackerd/tracked_ends.py), their hits
    within 3 of their sigmas. In dim light the detector's window search does not hold the ends (it searches
    whole frames), and every pair is refined."""
    rng = np.random.default_rng(4)
    start = pose_aimed_at([1.7, 0.5, 1.6], [1.6, 0.6, 0.0], POINTER["length_m"])
    step = np.array([0.004, 0.002, 0.0])
    for look, expected in ((Look(), [True, False, False, False]), (Look(gain=0.4), [True, True, True, True])):
        rig, renderer = _scene(_side_cameras(), look)
        wall = wall_frame(rig.wall)
        locator = Locator(rig, cameras=renderer.cameras)
        refined = []
        for k in range(len(expected)):
            pose = PointerPose(start.front_m + k * step, start.back_m + k * step)
            fix = locator.locate([renderer.render(i, pose, rng).image for i in range(2)])
            assert fix.found and fix.hit is not None and fix.uncertainty_m is not None, fix.reason
            refined.append(bool(fix.measurements))
            error = float(np.linalg.norm(fix.hit.wall_xy_m - true_wall_hit(pose, wall).wall_xy_m))
            assert error < 3.0 * fix.uncertainty_m, (look, k, error, fix.uncertainty_m)
        assert refined == expected, (look, refined)


def test_a_blue_ball_before_a_violet_picture_with_as_much_blue_is_found() -> None:
    """`trackerd bench robustness --seed 2026`, installation 26, frame 1: two cameras close to the
    presenter, dim light, orange-red and blue paint, no hand, no blur. Camera 0 sees the blue ball (15, 40,
    104 grey levels) before a violet block (34, 22, 96): blue exceeds the other channels by 64 and 62, so
    the ball has no outline in its colour's excess and the guided look found no rim on any of 32 rays: not
    found. In the direction from the block's colour to the ball's (less red, more green) its outline is
    plain (trackerd/detect/guided.py, ball_tint)."""
    from trackerd.bench.robustness import run_rig

    frame = run_rig((2026, 26, 2, None, 0, 0))[1]
    assert frame["factors"]["occlusion"] == "none" and frame["eligible"]
    assert frame["status"] == "hit", frame["reason"]
    assert frame["error_m"] < 3.0 * frame["sigma_m"] and frame["error_m"] < 0.01, frame


def test_a_ball_touching_a_hand_of_nearly_its_hue_is_a_candidate_and_the_pointer_is_found() -> None:
    """`trackerd bench robustness --seed 7`, installation 10, frame 15: three cameras high behind the
    presenter, warm light, orange-red paint, a slide of red letters, a hand beside the red ball. In
    camera 1 the ball is on the plain wall but touches the hand, whose skin passes the search's hue test:
    ball and hand were one seed, whose outline is not round (rim scatter 1.7 px), so the camera offered
    no red candidate; in the two others the ball lies on the letters, and the split candidates paired two
    letter fragments instead: a hit 338 mm off at 33 sigma. The seed's vivid part alone (excess at least
    half its own channel, which the skin's is not) fits the ball (trackerd/detect/search.py, _vivid_part)."""
    from trackerd.bench.robustness import draw_installation, drawn_frames, renderer_for
    from trackerd.detect.search import search_candidates
    from trackerd.joint.search import JointSearch
    from trackerd.refine import RefinedPath

    drawn, rng = draw_installation(7, 10)
    assert drawn.rig.wall is not None
    wall = wall_frame(drawn.rig.wall)
    (frame,) = drawn_frames(drawn, renderer_for(drawn), wall, rng, 16, lambda number, _: number == 15)
    assert frame.factors["occlusion"] == "hand" and frame.factors["content"] == "red text"
    locator = Locator(drawn.rig, cameras=drawn.cameras)
    view = frame.views[1]
    assert view.truth.visible_fraction("red") > 0.8
    offered = search_candidates(view.image, locator.grids[1], JointSearch(RefinedPath(locator)).radius_range_px(1))[
        "red"
    ]
    truth_px = np.asarray(view.truth.centre_px["red"])
    assert min(float(np.hypot(*(c.fit.centre_px - truth_px))) for c in offered) < 1.0
    fix = locator.locate([v.image for v in frame.views])
    assert fix.status == "hit" and fix.hit is not None and fix.uncertainty_m is not None, fix.reason
    error_m = float(np.linalg.norm(fix.hit.wall_xy_m - frame.truth_xy_m))
    assert error_m < 0.02 and error_m < 3.0 * fix.uncertainty_m, (error_m, fix.uncertainty_m)


def test_a_cyan_ball_in_warm_light_is_found() -> None:
    """`trackerd bench robustness --seed 11`, installation 18 (four cameras close to the presenter, warm
    light, "bright and cyan" paint): 38 of its 39 frames were not found, the blue ball (15, 111, 139 in RGB)
    being only a fifth bluer than it is green, below the search's hue test (RELATIVE_EXCESS) and the
    detector's thresholds; `trackerd calibrate pointer` could not learn it either, since it learns from
    where the locator finds the pointer. The search's last resort takes vivid colours whose strongest
    channel is the end's (trackerd/detect/search.py, vivid_mask)."""
    look = Look(blue_rgb=(0.05, 0.50, 0.93), white_balance=(1.2, 1.0, 0.68))
    rig, renderer = _scene(_side_cameras(), look)
    rng = np.random.default_rng(5)
    for target_x in (0.8, 1.8, 2.8):
        pose = pose_aimed_at([target_x + 0.15, 0.45, 1.75], [target_x, 0.6, 0.0], POINTER["length_m"])
        fix, error, views = _locate(rig, renderer, pose, rng)
        assert all(v.truth.visible_fraction("blue") > 0.8 for v in views)
        assert error is not None, fix.reason
        assert fix.uncertainty_m is not None and error < 0.008 and error < 3.0 * fix.uncertainty_m, (
            error,
            fix.uncertainty_m,
        )


@pytest.mark.parametrize(
    ("seed", "installation", "number", "hidden"),
    [(7, 21, 17, "red"), (7, 9, 1, "blue"), (11, 5, 13, "red")],
)
def test_the_last_resort_does_not_pair_junk_with_a_ball_hidden_from_all_cameras_but_one(
    seed: int, installation: int, number: int, hidden: str
) -> None:
    """`trackerd bench robustness` frames where one end is seen by one camera only, each found as a
    confidently wrong hit by a build of the search's last resort (trackerd/joint/search.py,
    JointSearch._one_paint): seed 7 installation 21 frame 17, a vivid thing of another hue (green 0.82 of
    its red, the ball's 0.11) paired with the red ball, 1.86 m off at 109 mm sigma; installation 9 frame 1,
    a blue thing of 0.64 a ball's size and another shade, 784 mm off at 71 mm sigma; seed 11 installation 5
    frame 13, a red block of the display's, plain red, found through the last resort's looser looks, 1.0 m
    off at 8 mm sigma. Not found (or rejected), with the reason; or, since an end one camera alone measures
    is placed by its ray and the pointer's length where the rod leads (trackerd/joint/lone.py), a hit that
    rests on that camera's ball and nothing else of its colour, within its sigma (7/21/17: 36 mm at 124 mm
    sigma; 11/5/13: 2.3 mm at 8.5 mm)."""
    from trackerd.bench.robustness import draw_installation, drawn_frames, renderer_for

    drawn, rng = draw_installation(seed, installation)
    assert drawn.rig.wall is not None
    wall = wall_frame(drawn.rig.wall)
    (frame,) = drawn_frames(drawn, renderer_for(drawn), wall, rng, number + 1, lambda n, _: n == number)
    seeing = [v.truth.visible_fraction(hidden) for v in frame.views]
    assert sum(1 for f in seeing if f >= 0.6) == 1 and sum(1 for f in seeing if f > 0.0) == 1, seeing
    fix = Locator(drawn.rig, cameras=drawn.cameras).locate([v.image for v in frame.views])
    if fix.hit is None:
        assert fix.status in ("not_found", "rejected") and fix.reason, fix.status
        return
    seen_by = seeing.index(max(seeing))
    for k, (view, used) in enumerate(zip(frame.views, fix.centroids_px, strict=True)):
        if k != seen_by:
            assert used[hidden] is None, (k, used[hidden])
            continue
        assert used[hidden] is not None
        truth_px = np.asarray(view.truth.centre_px[hidden])
        assert float(np.hypot(*(used[hidden] - truth_px))) < 2.0, (used[hidden], truth_px)
    assert frame.truth_xy_m is not None and fix.uncertainty_m is not None
    error = float(np.linalg.norm(fix.hit.wall_xy_m - frame.truth_xy_m))
    assert error < 3.0 * fix.uncertainty_m, (error, fix.uncertainty_m)


def test_an_end_on_one_sound_outline_is_searched_for_in_every_camera() -> None:
    """`trackerd bench robustness --seed 11`, installation 20, frame 1: four cameras, dim light, the blue
    ball hidden from camera 1, too dim for the detector in camera 3, and cut in half by camera 2's frame
    edge, where its outline was not fitted and its centroid (20 px from its centre, its blob's radius a fifth
    of the ball's) was taken: a hit 66 mm off at 13 mm sigma resting on one sound outline of blue. The search
    over every camera's candidates finds the ball in cameras 0, 2 and 3 (trackerd/refine.py,
    RefinedPath.locate)."""
    from trackerd.bench.robustness import draw_installation, drawn_frames, renderer_for

    drawn, rng = draw_installation(11, 20)
    assert drawn.rig.wall is not None
    (frame,) = drawn_frames(
        drawn, renderer_for(drawn), wall_frame(drawn.rig.wall), rng, 2, lambda number, _: number == 1
    )
    assert [round(v.truth.visible_fraction("blue"), 1) for v in frame.views] == [1.0, 0.0, 0.5, 1.0]
    fix = Locator(drawn.rig, cameras=drawn.cameras).locate([v.image for v in frame.views])
    assert fix.status == "hit" and fix.hit is not None and fix.uncertainty_m is not None, fix.reason
    error_m = float(np.linalg.norm(fix.hit.wall_xy_m - frame.truth_xy_m))
    assert error_m < 0.005 and error_m < 3.0 * fix.uncertainty_m, (error_m, fix.uncertainty_m)
    blue_cameras = [i for i, ends in enumerate(fix.measurements) if ends.get("blue") is not None]
    assert blue_cameras == [0, 2, 3]


@pytest.mark.parametrize(
    ("installation", "number", "hidden", "reason"),
    [(12, 14, "blue", "the rod leaves cam0's red ball"), (27, 19, "red", "the rod leaves cam0's blue ball")],
)
def test_a_candidate_the_rod_does_not_lead_to_is_not_taken_for_a_hidden_end(
    installation: int, number: int, hidden: str, reason: str
) -> None:
    """`trackerd bench robustness --seed 11`, two frames where one end is hidden (or mostly) from camera 0 and
    something of its colour there was paired with the ball in camera 1. Installation 12 frame 14: the
    presenter's navy sleeve hides the blue ball, and its edge beside the rod (0.64 of a ball's size) made a
    hit 1.66 m off at 89 mm sigma; the rod leaves the red ball 14 degrees away from that edge. Installation
    27 frame 19: the red ball 41 % visible, and a red thing of a ball's size but another shade (green 0.80
    of its red, the ball's 0.28) made a hit 170 mm off at 22 mm sigma; the rod leaves the blue ball 24
    degrees away from it (trackerd/detect/rod.py, RefinedPath._off_the_rod). No hit, and the reason says
    why."""
    from trackerd.bench.robustness import draw_installation, drawn_frames, renderer_for

    drawn, rng = draw_installation(11, installation)
    assert drawn.rig.wall is not None
    wall = wall_frame(drawn.rig.wall)
    (frame,) = drawn_frames(drawn, renderer_for(drawn), wall, rng, number + 1, lambda n, _: n == number)
    seeing = [v.truth.visible_fraction(hidden) for v in frame.views]
    assert len(seeing) == 2 and seeing[0] < 0.6 <= seeing[1], seeing
    fix = Locator(drawn.rig, cameras=drawn.cameras).locate([v.image for v in frame.views])
    assert fix.hit is None and fix.status in ("not_found", "rejected"), (fix.status, fix.uncertainty_m)
    assert fix.reason is not None and reason in fix.reason, fix.reason


def test_a_red_ball_hidden_from_one_camera_is_placed_by_the_other_and_the_length() -> None:
    """From behind the presenter, a hand hides the front (red) ball from camera 0 altogether; camera 1 sees
    it (all but where the rod crosses it). Its end rests on camera 1 alone (`bench robustness`: seed 7
    installation 23 frame 38, the red ball hidden by the body in one camera of two; and, eligible frames, a
    ball on a surface of its hue where even a look at the truth finds no outline in one camera of two: seed
    2026 installation 15 frame 15, seed 7 installation 18 frame 22, seed 11 installation 0 frame 28). The
    blue ball triangulates, the rod leaves it in both images, and camera 1's ray through the red ball meets
    the sphere of the pointer's length about where the rod's axis puts it (trackerd/joint/lone.py); the fit
    places the red end from that one measurement and the length, and says how well. Before, no pose here
    was found ("no red ball seen consistently by two cameras"). The presenter's hand on the back ball hides
    half of it in some poses: those are left out (4 of these 8 are this test's case)."""
    rig, renderer = _scene(_behind_cameras())
    rng = np.random.default_rng(8)
    results = []
    for _ in range(8):
        pose = _pose_from_the_middle(rng, (0.7, 0.95), (0.5, 0.9))
        red_m = pose.front_m if rig.pointer.front_colour == "red" else pose.back_m
        # A hand 12 cm in front of the ball on camera 0's line of sight to it: 24 degrees off camera 1's,
        # clear of the rod.
        towards = renderer.cameras[0].centre_m - red_m
        hand_m = red_m + 0.12 * towards / np.linalg.norm(towards)
        hand = Occluder("sphere", tuple(float(v) for v in hand_m), 0.03, (0.80, 0.62, 0.52), label="hand")
        fix, error, views = _locate(rig, renderer, pose, rng, occluders=(hand,))
        seen = [[v.truth.visible_fraction(c) for c in ("red", "blue")] for v in views]
        assert seen[0][0] == 0.0
        if seen[1][0] < 0.6 or min(seen[0][1], seen[1][1]) < 0.5:
            continue  # the presenter's hand on the back ball hides half of it: not this test's case
        assert error is not None and fix.uncertainty_m is not None, fix.reason
        assert fix.centroids_px[0]["red"] is None and fix.centroids_px[1]["red"] is not None
        assert error < 3.0 * fix.uncertainty_m, (error, fix.uncertainty_m)
        results.append((error, fix.uncertainty_m))
    assert len(results) >= 3 and max(error for error, _ in results) < 0.01, results


def test_a_tracked_pointer_is_followed_while_a_hand_hides_one_ball_from_one_camera(
    searches: list[int],
) -> None:
    """Tracking from behind the presenter, then a hand hides the red ball from camera 0 for three pairs while
    the pointer moves a few millimetres each: each pair is a hit resting on camera 1's red ball alone,
    fitted from the last pair's ends (RefinedPath._followed_from_one_camera), and the search over every
    camera's candidates runs once for the three (at its cadence for fixes on one sound outline), not once
    per pair (every such pair searched before: each found the end again, which made the next one search)."""
    rig, renderer = _scene(_behind_cameras())
    rng = np.random.default_rng(8)
    rng.random(3)
    wall = wall_frame(rig.wall)
    for _ in range(6):
        tip = np.array([float(rng.uniform(1.5, 2.1)), float(rng.uniform(0.75, 0.9)), 1.6])
        target = np.array([tip[0] + float(rng.uniform(-0.1, 0.1)), float(rng.uniform(0.55, 0.85)), 0.0])
        steps = [np.array([0.004, -0.002, 0.0]) * k for k in range(4)]
        poses = [pose_aimed_at(tip + step, target, POINTER["length_m"]) for step in steps]
        red_m = [p.front_m if rig.pointer.front_colour == "red" else p.back_m for p in poses]
        towards = renderer.cameras[0].centre_m - red_m[1]
        hand_m = red_m[1] + 0.12 * towards / np.linalg.norm(towards)
        hand = Occluder("sphere", tuple(float(v) for v in hand_m), 0.03, (0.80, 0.62, 0.52), label="hand")
        frames = [
            [renderer.render(i, pose, rng, occluders=(hand,) if k else ()) for i in range(2)]
            for k, pose in enumerate(poses)
        ]
        seen = [[[v.truth.visible_fraction(c) for c in ("red", "blue")] for v in views] for views in frames]
        if any(views[0][0] > 0.0 for views in seen[1:]):
            continue  # the hand is not over the red ball in camera 0 in every pair
        if min(seen[0][0][0], *(views[1][0] for views in seen)) < 0.6:
            continue  # the hand is over the red ball in camera 1 too
        if min(f for views in seen for f in (views[0][1], views[1][1])) < 0.5:
            continue  # the presenter's hand on the back ball hides most of it: not this test's case
        locator = Locator(rig, cameras=renderer.cameras)
        first = locator.locate([v.image for v in frames[0]])
        assert first.status == "hit", first.reason
        searches.clear()
        for pose, views in zip(poses[1:], frames[1:], strict=True):
            fix = locator.locate([v.image for v in views])
            assert fix.hit is not None and fix.uncertainty_m is not None, fix.reason
            assert fix.centroids_px[0]["red"] is None and fix.centroids_px[1]["red"] is not None
            error = float(np.linalg.norm(fix.hit.wall_xy_m - true_wall_hit(pose, wall).wall_xy_m))
            assert error < 3.0 * fix.uncertainty_m and error < 0.01, (error, fix.uncertainty_m)
        assert len(searches) <= 1, searches
        return
    pytest.fail("no pose of six had the hand over the red ball in camera 0 only")
