"""The joint choice's stages: the searches' candidates first, then looks where they leave a ball out
(:mod:`trackerd.joint`)."""

from __future__ import annotations

from dataclasses import replace

from trackerd.detect.search import Candidate
from trackerd.geometry.camera import CameraModel
from trackerd.joint.lone import lone_points
from trackerd.joint.looks import (
    GUIDED_POINTS,
    ROD_POINTS,
    Look,
    RodFrom,
    guided_points,
    look_along_epipolar,
    look_along_rod,
)
from trackerd.joint.points import Array, JointChoice, Point, candidate_rays, pair_points, triangulated_points


def choose_jointly(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    ball_radius_m: float,
    length_m: float,
    length_tolerance_m: float,
    max_gap_m: float,
    room_side: tuple[Array, float] | None = None,
    look: Look | None = None,
    rod: RodFrom | None = None,
) -> JointChoice | str:
    """The most consistent choice (see :mod:`trackerd.joint`), or the reason there is none.

    ``room_side``: (normal, offset) of the wall's plane, oriented so that the room (where the cameras
    are) has positive signed distance; points behind the wall are ruled out. ``look``: when nothing
    pairs, each colour's ball is looked for with it where the pointer's length puts it from the other
    colour's best points, in the cameras whose search did not offer it; what it finds joins the
    candidates (a copy: the caller's lists are not changed). ``rod``: when still no camera has a ball of
    one colour where the geometry allows it, that ball is looked for where the rod leads from the other
    colour's best points (:func:`~trackerd.joint.looks.look_along_rod`); and when no ball of either colour
    triangulates, the candidates the rod leaves are looked for along their epipolar lines
    (:func:`~trackerd.joint.looks.look_along_epipolar`).
    """
    candidates = [{c: list(per_camera.get(c, [])) for c in ("red", "blue")} for per_camera in candidates]

    def triangulated(*colours: str) -> dict[str, list[Point]]:
        # The rays of the candidates as they are now (looks append to them), once for the colours asked.
        rays = [candidate_rays(cam, per_camera) for cam, per_camera in zip(cameras, candidates, strict=True)]
        return {c: triangulated_points(cameras, rays, c, ball_radius_m, max_gap_m, room_side) for c in colours}

    points = triangulated("red", "blue")
    choice = pair_points(points, candidates, length_m, length_tolerance_m)
    if not isinstance(choice, str) or look is None:
        return choice
    looking: Look = look

    def guided(colour: str, other: str, first: list[int] | None = None) -> list[Point]:
        """Looks from ``colour``'s candidate rays (from index ``first`` in each camera) where the pointer's
        length puts its ball from ``other``'s best points."""
        return guided_points(
            cameras,
            candidates,
            colour,
            points[other][:GUIDED_POINTS],
            ball_radius_m,
            length_m,
            length_tolerance_m,
            room_side,
            looking,
            first=first,
        )

    def one_camera(reason: str) -> JointChoice | str:
        """The pointer with one end that one camera alone offers (:mod:`trackerd.joint.lone`), paired with
        the other colour's points; ``reason`` (with why not) when there is none, or when both colours give
        one (they contradict each other)."""
        assert rod is not None
        paired: list[JointChoice] = []
        why: list[str] = []
        for colour, other in (("red", "blue"), ("blue", "red")):
            if not points[other]:
                continue
            lone = lone_points(
                cameras, candidates, colour, points[other], ball_radius_m, length_m, length_tolerance_m, room_side, rod
            )
            if isinstance(lone, str):
                why.append(lone)
                continue
            found = pair_points({colour: lone, other: points[other]}, candidates, length_m, length_tolerance_m)
            if isinstance(found, str):
                why.append(f"one camera's {colour} ball: {found}")
            else:
                paired.append(replace(found, one_camera=colour))
        if len(paired) == 1:
            return paired[0]
        if paired:
            why.append("each colour's ball is offered by one camera only where the rod leads, and they disagree")
        return "; ".join([reason, *why])

    # Nothing pairs: one ball may have merged, in some camera, with something of its colour. Look for each
    # colour where the pointer's length puts it from the other colour's best points.
    for colour, other in (("red", "blue"), ("blue", "red")):
        if points[other]:
            points[colour] = points[colour] + guided(colour, other)
    choice = pair_points(points, candidates, length_m, length_tolerance_m)
    if not isinstance(choice, str) or rod is None:
        return choice
    # A ball no camera offered (or whose every offer the looks refused): the rod still leads to it.
    for colour, other in (("red", "blue"), ("blue", "red")):
        if points[colour] or not points[other]:
            continue
        before = [len(per_camera[colour]) for per_camera in candidates]
        for partner in points[other][:ROD_POINTS]:
            look_along_rod(cameras, candidates, colour, partner, ball_radius_m, length_m, looking, rod)
        if all(len(per_camera[colour]) == n for per_camera, n in zip(candidates, before, strict=True)):
            continue
        points[colour] = triangulated(colour)[colour] + guided(colour, other, first=before)
        points[colour].sort(key=lambda p: p.score)
    choice = pair_points(points, candidates, length_m, length_tolerance_m)
    if not isinstance(choice, str):
        return choice
    if points["red"] or points["blue"]:
        return one_camera(choice)
    # No ball triangulates: each may be offered by one camera only, and not the same one. Look along the
    # epipolar lines of the candidates the rod leaves, then pair what triangulates.
    counts = [len(per_camera["red"]) + len(per_camera["blue"]) for per_camera in candidates]
    for colour in ("red", "blue"):
        look_along_epipolar(cameras, candidates, colour, ball_radius_m, room_side, looking, rod)
    if [len(per_camera["red"]) + len(per_camera["blue"]) for per_camera in candidates] == counts:
        return choice
    points = triangulated("red", "blue")
    for colour, other in (("red", "blue"), ("blue", "red")):
        if points[other] and not points[colour]:
            points[colour] = guided(colour, other)
    choice = pair_points(points, candidates, length_m, length_tolerance_m)
    return choice if not isinstance(choice, str) else one_camera(choice)
