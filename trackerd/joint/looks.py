"""Looking for a ball where no camera's search offered it: where the pointer's length puts it from the other
ball (each candidate ray of its colour against the length's sphere), where the rod leads from the other ball,
or along a candidate's epipolar line (:mod:`trackerd.joint`). What a look finds joins the candidates; the
choice (:mod:`trackerd.joint.points`) judges it with the rest."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import numpy as np

from trackerd.detect.search import Candidate
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rod_axis import RodSighting, other_ball_along_rod
from trackerd.joint.points import EXTRA_CAMERA_BONUS, MAX_HYPOTHESES, MAX_SIZE_RATIO, SIZE_SCALE, Array, Point

Look = Callable[[int, str, float, float, float, "tuple[float, float] | None"], "Iterable[Candidate]"]
"""``look(camera, colour, x_px, y_px, radius_px, axis)``: balls of that colour fitted where the geometry says
one should be, in a camera whose search did not offer it (it merged with something of its colour), in order
of preference, each made only when the one before was not taken (not where the geometry allows the ball, or
not of its size); ``axis`` is the image direction towards the pointer's other ball (where the rod meets this
one), when known."""

GUIDED_POINTS = 4
"""Best points of one colour from which the other colour's ball is looked for, when nothing pairs."""

RodFrom = Callable[[int, float, float, float], "tuple[float, float] | None"]
"""``rod(camera, x_px, y_px, radius_px)``: the unit image direction in which the rod clearly leaves the ball
measured there (and no other dark line as clearly), or None."""

ROD_POINTS = 2
"""Best points of one colour from which the rod is followed to the other colour's ball, when no camera offered
that ball at all."""
ROD_DIRECTION_ERROR_DEG = 3.0
"""How far a rod's measured image direction may be off: its fan's step, and the rod's bend in a lens."""
ROD_LOOK_STEP = 0.6
"""Looks along the rod's image line are this many of the ball's image radii apart: a look finds a ball when it
starts within about half a radius of its centre."""
ROD_LOOKS = 5
"""Looks along the rod's image line in one camera, nearest the prediction first."""

EPIPOLAR_CANDIDATES = 3
"""Candidates of each colour in each camera whose epipolar lines are looked along, when no ball triangulates."""
EPIPOLAR_SIZE = 1.3
"""A candidate's ball lies between the distances at which a ball would image this much larger and smaller."""
EPIPOLAR_LOOKS = 12
"""Looks along one candidate's epipolar line in one camera, nearest the distance its size gives first."""
EPIPOLAR_SAMPLES = 400
"""Points along a candidate's ray between those distances, projected into the other camera."""

LOOK_SLACK_SHARE = 0.5
LOOK_SLACK_MIN_PX = 3.0
"""A look's outline is the ball only within this share of the ball's expected image radius of where the geometry
puts it, or LOOK_SLACK_MIN_PX where that is more (:func:`look_slack_px`): a ball of its colour farther off is
something else."""


def look_slack_px(expected_px: float) -> float:
    """How far from where the geometry puts a ball (of image radius ``expected_px``) a look may find it."""
    return max(LOOK_SLACK_MIN_PX, LOOK_SLACK_SHARE * expected_px)


def guided_points(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    partners: list[Point],
    ball_radius_m: float,
    length_m: float,
    length_tolerance_m: float,
    room_side: tuple[Array, float] | None,
    look: Look,
    first: list[int] | None = None,
) -> list[Point]:
    """Points of ``colour`` found by looking where the pointer's length puts them: for each candidate ray
    of ``colour`` in one camera (from index ``first[camera]`` on, when given), where it meets the sphere of
    the pointer's length around a partner point, the other cameras are looked into (``look``).

    A camera that sees the pointer side-on has its ray through one ball nearly tangent to that sphere,
    and the partner's small error can make it miss the sphere altogether: a ray passing outside it by
    no more than the length's tolerance is taken at its closest point to the partner."""
    found: list[Point] = []
    # The rays looked along are the searches' own candidates: what a look finds joins ``candidates`` (for
    # the pairing) but is not looked from again, or each find would seed more looks in every other camera
    # and their number would grow with every partner (a 4-camera installation made 240,000 looks).
    offered = [len(per_camera[colour]) for per_camera in candidates]
    starts = first or [0] * len(cameras)
    for partner in partners:
        for a, cam in enumerate(cameras):
            for i, cand in enumerate(candidates[a][colour][: offered[a]]):
                if i < starts[a]:
                    continue
                _, d = cam.pixel_to_ray(cand.fit.centre_px[None])
                d = d[0] / np.linalg.norm(d[0])
                for s, reach in length_roots(cam.centre_m, d, partner.point_m, length_m, length_tolerance_m):
                    point = cam.centre_m + s * d
                    if s <= 0.2 or (room_side is not None and float(point @ room_side[0] + room_side[1]) <= 0):
                        continue
                    expected_a = cam.focal_px * ball_radius_m / s
                    ratio = cand.fit.radius_px / expected_a
                    if not 1.0 / MAX_SIZE_RATIO < ratio < MAX_SIZE_RATIO:
                        continue
                    members = {a: i}
                    score = (math.log(ratio) / SIZE_SCALE) ** 2
                    for c, other in enumerate(cameras):
                        if c == a:
                            continue
                        depth = float(other.to_camera_frame(point[None])[0, 2])
                        if depth <= 0.2:
                            continue
                        px = other.project(point[None])[0]
                        if not (np.all(np.isfinite(px)) and bool(other.contains(px[None], 2.0)[0])):
                            continue
                        expected = other.focal_px * ball_radius_m / float(np.linalg.norm(point - other.centre_m))
                        partner_px = other.project(partner.point_m[None])[0]
                        axis = (float(partner_px[0] - px[0]), float(partner_px[1] - px[1]))
                        for seen in look(
                            c,
                            colour,
                            float(px[0]),
                            float(px[1]),
                            expected,
                            axis if np.all(np.isfinite(partner_px)) else None,
                        ):
                            miss = (
                                _miss_px(
                                    seen.fit.centre_px,
                                    px,
                                    other,
                                    cam.centre_m + (s - reach) * d,
                                    cam.centre_m + (s + reach) * d,
                                )
                                if reach > 0
                                else float(np.hypot(*(seen.fit.centre_px - px)))
                            )
                            if _is_the_ball(miss, seen.fit.radius_px, expected):
                                size = seen.fit.radius_px / expected
                                candidates[c][colour].append(seen)
                                members[c] = len(candidates[c][colour]) - 1
                                # Where it was found against where the geometry put it (a ray gap, in effect).
                                score += (miss / max(1.0, 0.1 * expected)) ** 2 + (math.log(size) / SIZE_SCALE) ** 2
                                break
                    if len(members) >= 2:
                        found.append(Point(point, members, score - EXTRA_CAMERA_BONUS * (len(members) - 2)))
    found.sort(key=lambda p: p.score)
    return found[:MAX_HYPOTHESES]


def length_roots(
    origin_m: Array, direction: Array, partner_m: Array, length_m: float, length_tolerance_m: float
) -> tuple[tuple[float, float], ...]:
    """Where the ray ``origin_m + s direction`` (a unit direction) meets the sphere of radius ``length_m``
    around ``partner_m``: each distance s with how far along the ray the length's tolerance lets the ball
    be either way (0 for a clean crossing: the cameras' agreement judges it). A ray passing outside the
    sphere by no more than the tolerance gives its closest point to the partner, with the reach the
    tolerance's larger sphere allows; a ray farther out gives none."""
    # |o + s d - P| = L: s^2 + 2 s d.(o - P) + |o - P|^2 - L^2 = 0.
    offset = origin_m - partner_m
    b = float(direction @ offset)
    square = float(offset @ offset)
    disc = b * b - (square - length_m**2)
    if disc >= 0:
        return ((-b - math.sqrt(disc), 0.0), (-b + math.sqrt(disc), 0.0))
    if math.sqrt(max(square - b * b, 0.0)) > length_m + length_tolerance_m:
        return ()
    return ((-b, math.sqrt(max(b * b - (square - (length_m + length_tolerance_m) ** 2), 0.0))),)


def rod_sightings(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    partner: Point,
    ball_radius_m: float,
    length_m: float,
    rod: RodFrom,
) -> list[RodSighting]:
    """Where each camera should see the ``colour`` ball, from ``partner`` (the other ball's point) and the rod
    leaving its candidate in every camera that measured it and shows the rod clearly
    (:func:`trackerd.geometry.rod_axis.other_ball_along_rod`, directions ROD_DIRECTION_ERROR_DEG off at most)."""
    other = "blue" if colour == "red" else "red"
    leaving: dict[int, tuple[Array, Array]] = {}
    for c, k in partner.members.items():
        fit = candidates[c][other][k].fit
        direction = rod(c, float(fit.centre_px[0]), float(fit.centre_px[1]), float(fit.radius_px))
        if direction is not None:
            leaving[c] = (np.asarray(fit.centre_px, dtype=np.float64), np.asarray(direction, dtype=np.float64))
    return other_ball_along_rod(cameras, partner.point_m, leaving, length_m, ball_radius_m, ROD_DIRECTION_ERROR_DEG)


def look_along_rod(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    partner: Point,
    ball_radius_m: float,
    length_m: float,
    look: Look,
    rod: RodFrom,
) -> None:
    """Look for the ``colour`` ball where the rod leads from ``partner`` (the other ball's point): in each
    camera that measured the partner and shows the rod leaving it, along the rod's image line about where
    the pointer's axis (:func:`trackerd.geometry.rod_axis.other_ball_along_rod`) puts the ball. The first
    outline of the ball's size on that line in each camera joins ``candidates``; the caller triangulates
    them, or looks from them into the other cameras."""
    for sighting in rod_sightings(cameras, candidates, colour, partner, ball_radius_m, length_m, rod):
        camera = cameras[sighting.camera]
        step_px = ROD_LOOK_STEP * sighting.radius_px
        # Within the spread, at most ROD_LOOKS: where the planes are a few degrees apart the spread is several
        # balls long, and the looks then cover its middle (the camera whose prediction is good finds the ball,
        # and the length's sphere from there the others).
        most = min(int((sighting.spread_px + 0.5 * sighting.radius_px) // step_px), ROD_LOOKS // 2)
        offsets_px = [k * step_px for k in sorted(range(-most, most + 1), key=abs)]
        origin = sighting.from_px
        towards = (-float(sighting.along[0]), -float(sighting.along[1]))
        for offset_px in offsets_px:
            start = sighting.expected_px + offset_px * sighting.along
            if not bool(camera.contains(start[None], 2.0)[0]):
                continue
            taken = None
            for seen in look(sighting.camera, colour, float(start[0]), float(start[1]), sighting.radius_px, towards):
                # On the rod's image line (its own direction puts the ball there to a few pixels), and of the
                # ball's size at about that distance.
                from_origin = seen.fit.centre_px - origin
                across_px = abs(float(from_origin[0] * sighting.along[1] - from_origin[1] * sighting.along[0]))
                if _is_the_ball(across_px, seen.fit.radius_px, sighting.radius_px):
                    taken = seen
                    break
            if taken is not None:
                candidates[sighting.camera][colour].append(taken)
                break


def look_along_epipolar(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    ball_radius_m: float,
    room_side: tuple[Array, float] | None,
    look: Look,
    rod: RodFrom,
) -> None:
    """Look for the ``colour`` ball along the epipolar line of each of the first EPIPOLAR_CANDIDATES
    candidates of that colour in each camera that the rod leaves (a ball of the pointer's, not a blob of a
    picture), in every other camera: between the distances its image size allows (EPIPOLAR_SIZE either way),
    in front of the wall, nearest the distance its size gives first. The first outline on the line and of
    the ball's size there joins ``candidates`` of that camera; the caller triangulates."""
    offered = [len(per_camera[colour]) for per_camera in candidates]
    for a, cam in enumerate(cameras):
        for cand in candidates[a][colour][: min(offered[a], EPIPOLAR_CANDIDATES)]:
            centre = cand.fit.centre_px
            if rod(a, float(centre[0]), float(centre[1]), float(cand.fit.radius_px)) is None:
                continue
            _, d = cam.pixel_to_ray(centre[None])
            d = d[0] / np.linalg.norm(d[0])
            sized_m = cam.focal_px * ball_radius_m / cand.fit.radius_px
            near_m, far_m = sized_m / EPIPOLAR_SIZE, sized_m * EPIPOLAR_SIZE
            if room_side is not None:
                # The wall's plane along this ray: the ball is in front of it.
                rate = float(d @ room_side[0])
                if rate < 0:
                    far_m = min(far_m, -float(cam.centre_m @ room_side[0] + room_side[1]) / rate)
            if far_m <= max(near_m, 0.2):
                continue
            # Finely enough that the starts below, picked from these, are ROD_LOOK_STEP of a ball apart.
            distances_m = np.geomspace(max(near_m, 0.2), far_m, EPIPOLAR_SAMPLES)
            along_m = cam.centre_m + distances_m[:, None] * d
            for b, other in enumerate(cameras):
                if b == a:
                    continue
                depth = other.to_camera_frame(along_m)[:, 2]
                projected = other.project(along_m)
                inside = (depth > 0.2) & np.all(np.isfinite(projected), axis=1)
                inside &= other.contains(np.where(np.isfinite(projected), projected, -1e9), 2.0)
                if not np.any(inside):
                    continue
                radii = other.focal_px * ball_radius_m / np.linalg.norm(along_m - other.centre_m, axis=1)
                # Starts ROD_LOOK_STEP of a ball's image apart along the line (by its length in the image),
                # nearest the size's distance first.
                steps_px = np.hypot(*np.diff(np.where(np.isfinite(projected), projected, 0.0), axis=0).T)
                arc_px = np.concatenate([[0.0], np.cumsum(np.where(inside[1:] & inside[:-1], steps_px, 0.0))])
                middle = int(np.argmin(np.abs(np.log(distances_m / sized_m))))
                step_px = ROD_LOOK_STEP * float(radii[middle])
                offsets = sorted(range(-EPIPOLAR_LOOKS, EPIPOLAR_LOOKS + 1), key=abs)
                indices = np.searchsorted(arc_px, arc_px[middle] + step_px * np.array(offsets, dtype=float))
                starts = [int(i) for i in dict.fromkeys(np.clip(indices, 0, EPIPOLAR_SAMPLES - 1)) if inside[i]]
                starts = starts[:EPIPOLAR_LOOKS]
                taken = None
                for i in starts:
                    for seen in look(b, colour, float(projected[i][0]), float(projected[i][1]), float(radii[i]), None):
                        miss = _miss_px(seen.fit.centre_px, projected[i], other, along_m[0], along_m[-1])
                        if _is_the_ball(miss, seen.fit.radius_px, float(radii[i])):
                            taken = seen
                            break
                    if taken is not None:
                        break
                if taken is not None:
                    candidates[b][colour].append(taken)


def _is_the_ball(miss_px: float, radius_px: float, expected_px: float) -> bool:
    """Whether a look's outline is the ball: less than :func:`look_slack_px` from where the geometry allows it,
    and of its size there (within MAX_SIZE_RATIO)."""
    size = radius_px / expected_px
    return miss_px < look_slack_px(expected_px) and 1.0 / MAX_SIZE_RATIO < size < MAX_SIZE_RATIO


def _miss_px(found_px: Array, looked_px: Array, camera: CameraModel, first_m: Array, last_m: Array) -> float:
    """How far ``found_px`` is from the image of the segment first_m-last_m in ``camera`` (where the
    geometry allows the ball), measured from ``looked_px`` where an end of it does not project."""
    ends = camera.project(np.stack([first_m, last_m]))
    if not np.all(np.isfinite(ends)):
        return float(np.hypot(*(found_px - looked_px)))
    along = ends[1] - ends[0]
    span = float(along @ along)
    t = 0.0 if span <= 1e-12 else min(max(float((found_px - ends[0]) @ along) / span, 0.0), 1.0)
    return float(np.hypot(*(found_px - (ends[0] + t * along))))
