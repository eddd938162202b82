"""Which candidate is each ball in each camera: chosen jointly, by what the geometry allows.

Per image, a red blob on a slide and the red ball can look alike; across
cameras they cannot. Among every camera's candidates of both colours
(:mod:`trackerd.detect.search`), the choice is the combination that

* triangulates: each ball's rays from two or more cameras meet (their gap),
* has the ball's size at that distance in every camera that sees it (a ball of
  radius R at distance d images with a radius of about f R / d),
* is one pointer: the red and the blue point are the pointer's length apart,
* lies in the room, in front of the wall, and in front of every camera,

scored by how far each of those is from exact, in units of what measurement
noise allows. Cameras beyond the first two join a choice when one of their
candidates lies where the choice projects. The answer says, per camera and
colour, which candidate (or none), so the pointer fit
(:mod:`trackerd.geometry.pointer_fit`) can use cameras that see only one end.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.search import Candidate
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rod_axis import other_ball_along_rod

Array = NDArray[np.float64]

GAP_SCALE_M = 0.006
"""Ray gaps are scored in units of this."""
SIZE_SCALE = 0.15
"""Image radius over the expected one is scored as its logarithm in units of this."""
LENGTH_SCALE_M = 0.01
"""The pointer's length error is scored in units of this."""
MAX_SIZE_RATIO = 1.6
"""A candidate more than this much larger or smaller than a ball at its distance is not that ball."""
MAX_HYPOTHESES = 24
"""Best points of each colour kept for pairing."""
EXTRA_CAMERA_BONUS = 4.0
"""Score taken off for every further camera that sees a ball where the choice puts it."""


@dataclass(frozen=True)
class _Point:
    """One colour's ball at a triangulated point, seen by some cameras."""

    point_m: Array
    members: dict[int, int]
    """camera index -> candidate index."""
    score: float


@dataclass(frozen=True)
class JointChoice:
    """The chosen candidate per camera and colour (None: that camera does not see that ball)."""

    chosen: list[dict[str, Candidate | None]]
    red_m: Array
    blue_m: Array
    score: float
    alternatives: int = 0
    """How many other consistent combinations there were."""


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
    """The most consistent choice (see the module), or the reason there is none.

    ``room_side``: (normal, offset) of the wall's plane, oriented so that the room (where the cameras
    are) has positive signed distance; points behind the wall are ruled out. ``look``: when nothing
    pairs, each colour's ball is looked for with it where the pointer's length puts it from the other
    colour's best points, in the cameras whose search did not offer it; what it finds joins the
    candidates (a copy: the caller's lists are not changed). ``rod``: when still no camera has a ball of
    one colour where the geometry allows it, that ball is looked for where the rod leads from the other
    colour's best points (:func:`_along_rod`).
    """
    candidates = [{c: list(per_camera.get(c, [])) for c in ("red", "blue")} for per_camera in candidates]
    rays = [_rays(cam, per_camera) for cam, per_camera in zip(cameras, candidates, strict=True)]
    points = {colour: _points(cameras, rays, colour, ball_radius_m, max_gap_m, room_side) for colour in ("red", "blue")}
    choice = _pair(points, candidates, length_m, length_tolerance_m)
    if not isinstance(choice, str) or look is None:
        return choice
    # Nothing pairs: one ball may have merged, in some camera, with something of its colour. Look for each
    # colour where the pointer's length puts it from the other colour's best points.
    for colour, other in (("red", "blue"), ("blue", "red")):
        if points[other]:
            points[colour] = points[colour] + _guided(
                cameras,
                candidates,
                colour,
                points[other][:GUIDED_POINTS],
                ball_radius_m,
                length_m,
                length_tolerance_m,
                room_side,
                look,
            )
    choice = _pair(points, candidates, length_m, length_tolerance_m)
    if not isinstance(choice, str) or rod is None:
        return choice
    # A ball no camera offered (or whose every offer the looks refused): the rod still leads to it.
    for colour, other in (("red", "blue"), ("blue", "red")):
        if points[colour] or not points[other]:
            continue
        before = [len(per_camera[colour]) for per_camera in candidates]
        for partner in points[other][:ROD_POINTS]:
            _along_rod(cameras, candidates, colour, partner, ball_radius_m, length_m, look, rod)
        if all(len(per_camera[colour]) == n for per_camera, n in zip(candidates, before, strict=True)):
            continue
        rays = [_rays(cam, per_camera) for cam, per_camera in zip(cameras, candidates, strict=True)]
        points[colour] = _points(cameras, rays, colour, ball_radius_m, max_gap_m, room_side) + _guided(
            cameras,
            candidates,
            colour,
            points[other][:GUIDED_POINTS],
            ball_radius_m,
            length_m,
            length_tolerance_m,
            room_side,
            look,
            first=before,
        )
        points[colour].sort(key=lambda p: p.score)
    choice = _pair(points, candidates, length_m, length_tolerance_m)
    if not isinstance(choice, str) or points["red"] or points["blue"]:
        return choice
    # No ball triangulates: each may be offered by one camera only, and not the same one. Look along the
    # epipolar lines of the candidates the rod leaves, then pair what triangulates.
    counts = [len(per_camera["red"]) + len(per_camera["blue"]) for per_camera in candidates]
    for colour in ("red", "blue"):
        _along_epipolar(cameras, candidates, colour, ball_radius_m, room_side, look, rod)
    if [len(per_camera["red"]) + len(per_camera["blue"]) for per_camera in candidates] == counts:
        return choice
    rays = [_rays(cam, per_camera) for cam, per_camera in zip(cameras, candidates, strict=True)]
    points = {c: _points(cameras, rays, c, ball_radius_m, max_gap_m, room_side) for c in ("red", "blue")}
    for colour, other in (("red", "blue"), ("blue", "red")):
        if points[other] and not points[colour]:
            points[colour] = _guided(
                cameras,
                candidates,
                colour,
                points[other][:GUIDED_POINTS],
                ball_radius_m,
                length_m,
                length_tolerance_m,
                room_side,
                look,
            )
    return _pair(points, candidates, length_m, length_tolerance_m)


def _along_epipolar(
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
                        size = seen.fit.radius_px / radii[i]
                        if miss < max(3.0, 0.5 * radii[i]) and 1.0 / MAX_SIZE_RATIO < size < MAX_SIZE_RATIO:
                            taken = seen
                            break
                    if taken is not None:
                        break
                if taken is not None:
                    candidates[b][colour].append(taken)


def _along_rod(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    partner: _Point,
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
    other = "blue" if colour == "red" else "red"
    leaving: dict[int, tuple[Array, Array]] = {}
    for c, k in partner.members.items():
        fit = candidates[c][other][k].fit
        direction = rod(c, float(fit.centre_px[0]), float(fit.centre_px[1]), float(fit.radius_px))
        if direction is not None:
            leaving[c] = (np.asarray(fit.centre_px, dtype=np.float64), np.asarray(direction, dtype=np.float64))
    sightings = other_ball_along_rod(
        cameras, partner.point_m, leaving, length_m, ball_radius_m, ROD_DIRECTION_ERROR_DEG
    )
    for sighting in sightings:
        camera = cameras[sighting.camera]
        step = ROD_LOOK_STEP * sighting.radius_px
        steps = int((sighting.spread_px + 0.5 * sighting.radius_px) // step)
        offsets = sorted((k * step for k in range(-steps, steps + 1)), key=abs)[:ROD_LOOKS]
        origin = leaving[sighting.camera][0]
        towards = (-float(sighting.along[0]), -float(sighting.along[1]))
        for offset in offsets:
            start = sighting.expected_px + offset * sighting.along
            if not bool(camera.contains(start[None])[0]):
                continue
            taken = None
            for seen in look(sighting.camera, colour, float(start[0]), float(start[1]), sighting.radius_px, towards):
                # On the rod's image line (its own direction puts the ball there to a few pixels), and of the
                # ball's size at about that distance.
                offset_px = seen.fit.centre_px - origin
                across = abs(float(offset_px[0] * sighting.along[1] - offset_px[1] * sighting.along[0]))
                size = seen.fit.radius_px / sighting.radius_px
                if across < max(3.0, 0.5 * sighting.radius_px) and 1.0 / MAX_SIZE_RATIO < size < MAX_SIZE_RATIO:
                    taken = seen
                    break
            if taken is not None:
                candidates[sighting.camera][colour].append(taken)
                break


def _pair(
    points: dict[str, list[_Point]],
    candidates: list[dict[str, list[Candidate]]],
    length_m: float,
    length_tolerance_m: float,
) -> JointChoice | str:
    """The best red and blue points the pointer's length apart, or why there are none."""
    if not points["red"] or not points["blue"]:
        missing = [c for c in ("red", "blue") if not points[c]]
        return (
            f"no {' or '.join(missing)} ball seen consistently by two cameras"
            " (rays that meet, of a ball's size at that distance)"
        )
    best: tuple[float, _Point, _Point] | None = None
    consistent = 0
    for red in points["red"]:
        for blue in points["blue"]:
            distance = float(np.linalg.norm(red.point_m - blue.point_m))
            error = abs(distance - length_m)
            if error > length_tolerance_m:
                continue
            # One candidate cannot be both balls.
            if any(
                blue.members.get(c) is not None
                and red.members[c] is not None
                and _same(candidates[c], red.members[c], blue.members[c])
                for c in red.members
            ):
                continue
            consistent += 1
            score = red.score + blue.score + (error / LENGTH_SCALE_M) ** 2
            if best is None or score < best[0]:
                best = (score, red, blue)
    if best is None:
        return (
            f"no red and blue balls the pointer's length apart ({len(points['red'])} red and"
            f" {len(points['blue'])} blue points triangulated)"
        )
    score, red, blue = best
    chosen: list[dict[str, Candidate | None]] = []
    for index, per_camera in enumerate(candidates):
        pick: dict[str, Candidate | None] = {}
        for colour, point in (("red", red), ("blue", blue)):
            k = point.members.get(index)
            pick[colour] = per_camera[colour][k] if k is not None else None
        chosen.append(pick)
    return JointChoice(chosen, red.point_m, blue.point_m, score, consistent - 1)


def _rays(cam: CameraModel, per_camera: dict[str, list[Candidate]]) -> dict[str, tuple[Array, Array]]:
    """Unit world rays through each candidate's centre, and its radius, per colour."""
    entry = {}
    for colour in ("red", "blue"):
        cands = per_camera.get(colour, [])
        if cands:
            centres = np.array([c.fit.centre_px for c in cands])
            _, dirs = cam.pixel_to_ray(centres)
            dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
            radii = np.array([c.fit.radius_px for c in cands])
        else:
            dirs, radii = np.zeros((0, 3)), np.zeros(0)
        entry[colour] = (dirs, radii)
    return entry


def _guided(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    partners: list[_Point],
    ball_radius_m: float,
    length_m: float,
    length_tolerance_m: float,
    room_side: tuple[Array, float] | None,
    look: Look,
    first: list[int] | None = None,
) -> list[_Point]:
    """Points of ``colour`` found by looking where the pointer's length puts them: for each candidate ray
    of ``colour`` in one camera (from index ``first[camera]`` on, when given), where it meets the sphere of
    the pointer's length around a partner point, the other cameras are looked into (``look``).

    A camera that sees the pointer side-on has its ray through one ball nearly tangent to that sphere,
    and the partner's small error can make it miss the sphere altogether: a ray passing outside it by
    no more than the length's tolerance is taken at its closest point to the partner."""
    found: list[_Point] = []
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
                # |c + s d - P| = L: s^2 + 2 s d.(c - P) + |c - P|^2 - L^2 = 0.
                offset = cam.centre_m - partner.point_m
                b = float(d @ offset)
                disc = b * b - (float(offset @ offset) - length_m**2)
                # Each root with how far along the ray the length's tolerance lets the ball be either way
                # (none for a clean crossing of the sphere: the cameras' agreement is checked below).
                if disc < 0:
                    closest = math.sqrt(max(float(offset @ offset) - b * b, 0.0))
                    if closest > length_m + length_tolerance_m:
                        continue
                    reach = math.sqrt(max(b * b - (float(offset @ offset) - (length_m + length_tolerance_m) ** 2), 0.0))
                    roots: tuple[tuple[float, float], ...] = ((-b, reach),)
                else:
                    roots = ((-b - math.sqrt(disc), 0.0), (-b + math.sqrt(disc), 0.0))
                for s, reach in roots:
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
                            size = seen.fit.radius_px / expected
                            if miss < max(3.0, 0.5 * expected) and 1.0 / MAX_SIZE_RATIO < size < MAX_SIZE_RATIO:
                                candidates[c][colour].append(seen)
                                members[c] = len(candidates[c][colour]) - 1
                                # Where it was found against where the geometry put it (a ray gap, in effect).
                                score += (miss / max(1.0, 0.1 * expected)) ** 2 + (math.log(size) / SIZE_SCALE) ** 2
                                break
                    if len(members) >= 2:
                        found.append(_Point(point, members, score - EXTRA_CAMERA_BONUS * (len(members) - 2)))
    found.sort(key=lambda p: p.score)
    return found[:MAX_HYPOTHESES]


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


def _same(per_camera: dict[str, list[Candidate]], red_index: int, blue_index: int) -> bool:
    red = per_camera["red"][red_index].fit
    blue = per_camera["blue"][blue_index].fit
    return float(np.hypot(*(red.centre_px - blue.centre_px))) < 0.5 * min(red.radius_px, blue.radius_px)


def _points(
    cameras: list[CameraModel],
    rays: list[dict],
    colour: str,
    ball_radius_m: float,
    max_gap_m: float,
    room_side: tuple[Array, float] | None,
) -> list[_Point]:
    """Triangulated points of one colour from every pair of cameras' candidates, extended to the other
    cameras, best first (at most MAX_HYPOTHESES)."""
    found: list[_Point] = []
    n = len(cameras)
    for a in range(n):
        for b in range(a + 1, n):
            da, ra = rays[a][colour]
            db, rb = rays[b][colour]
            if len(da) == 0 or len(db) == 0:
                continue
            ca, cb = cameras[a].centre_m, cameras[b].centre_m
            # Closest approach of every ray of a with every ray of b: (Na, Nb).
            w = ca - cb
            dot = da @ db.T
            wa = da @ w
            wb = db @ w
            denom = 1.0 - dot * dot
            ok = denom > 1e-6
            denom = np.where(ok, denom, 1.0)
            s = (dot * wb[None, :] - wa[:, None]) / denom
            t = (wb[None, :] - dot * wa[:, None]) / denom
            pa = ca + s[..., None] * da[:, None, :]
            pb = cb + t[..., None] * db[None, :, :]
            gap = np.linalg.norm(pa - pb, axis=-1)
            point = 0.5 * (pa + pb)
            size_a = ra[:, None] / (cameras[a].focal_px * ball_radius_m / np.maximum(s, 1e-3))
            size_b = rb[None, :] / (cameras[b].focal_px * ball_radius_m / np.maximum(t, 1e-3))
            good = ok & (s > 0.2) & (t > 0.2) & (gap <= max_gap_m)
            good &= (size_a < MAX_SIZE_RATIO) & (size_a > 1.0 / MAX_SIZE_RATIO)
            good &= (size_b < MAX_SIZE_RATIO) & (size_b > 1.0 / MAX_SIZE_RATIO)
            if room_side is not None:
                normal, offset = room_side
                good &= (point @ normal + offset) > 0.0
            for i, j in zip(*np.nonzero(good), strict=True):
                score = (
                    (gap[i, j] / GAP_SCALE_M) ** 2
                    + (math.log(size_a[i, j]) / SIZE_SCALE) ** 2
                    + (math.log(size_b[i, j]) / SIZE_SCALE) ** 2
                )
                members = {a: int(i), b: int(j)}
                found.append(_extend(cameras, rays, colour, point[i, j], members, score, ball_radius_m))
    found.sort(key=lambda p: p.score)
    distinct: list[_Point] = []
    for p in found:
        if all(p.members != q.members for q in distinct):
            distinct.append(p)
        if len(distinct) >= MAX_HYPOTHESES:
            break
    return distinct


def _extend(
    cameras: list[CameraModel],
    rays: list[dict],
    colour: str,
    point: Array,
    members: dict[int, int],
    score: float,
    ball_radius_m: float,
) -> _Point:
    """Add the other cameras whose candidate of this colour lies where ``point`` projects."""
    members = dict(members)
    for c, cam in enumerate(cameras):
        if c in members:
            continue
        dirs, radii = rays[c][colour]
        if len(dirs) == 0:
            continue
        to_point = point - cam.centre_m
        distance = float(np.linalg.norm(to_point))
        if distance < 0.2:
            continue
        unit = to_point / distance
        angle = np.arccos(np.clip(dirs @ unit, -1.0, 1.0))
        expected = cam.focal_px * ball_radius_m / distance
        # Within a third of the ball's image radius, and of its size.
        near = angle * cam.focal_px < max(2.0, 0.35 * expected)
        sized = (radii / expected < MAX_SIZE_RATIO) & (radii / expected > 1.0 / MAX_SIZE_RATIO)
        hits = np.nonzero(near & sized)[0]
        if hits.size:
            k = int(hits[np.argmin(angle[hits])])
            members[c] = k
            score -= EXTRA_CAMERA_BONUS
    return _Point(point, members, score)
