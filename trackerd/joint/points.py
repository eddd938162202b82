"""Triangulated points of each colour, and the pair of them that is one pointer: the joint choice's scoring
(:mod:`trackerd.joint`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.detect.search import Candidate
from trackerd.geometry.camera import CameraModel

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
class Point:
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
    one_camera: str | None = None
    """The colour of an end that one camera alone measures (:mod:`trackerd.joint.lone`), or None."""


def pair_points(
    points: dict[str, list[Point]],
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
    best: tuple[float, Point, Point] | None = None
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


def candidate_rays(cam: CameraModel, per_camera: dict[str, list[Candidate]]) -> dict[str, tuple[Array, Array]]:
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


def _same(per_camera: dict[str, list[Candidate]], red_index: int, blue_index: int) -> bool:
    red = per_camera["red"][red_index].fit
    blue = per_camera["blue"][blue_index].fit
    return float(np.hypot(*(red.centre_px - blue.centre_px))) < 0.5 * min(red.radius_px, blue.radius_px)


def triangulated_points(
    cameras: list[CameraModel],
    rays: list[dict],
    colour: str,
    ball_radius_m: float,
    max_gap_m: float,
    room_side: tuple[Array, float] | None,
) -> list[Point]:
    """Triangulated points of one colour from every pair of cameras' candidates, extended to the other
    cameras, best first (at most MAX_HYPOTHESES)."""
    found: list[Point] = []
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
    distinct: list[Point] = []
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
) -> Point:
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
    return Point(point, members, score)
