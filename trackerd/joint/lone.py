"""A ball only one camera measures: its ray, the pointer's length from the other ball, and the rod
(:mod:`trackerd.joint`).

When one ball triangulates and the other is offered by one camera only (in every other camera it lies on
a surface of its own hue, and the looks there find no outline of it), that camera's ray through it and the
sphere of the pointer's length around the found ball leave two points, one on either side of where the
ray passes the found ball. The rod picks one: in each camera it leaves the found ball towards the other,
and two cameras' rods (:func:`trackerd.geometry.rod_axis.other_ball_along_rod`) put the other ball on the
pointer's axis, with how far along the rod's image line each camera's prediction can be off. The one
camera's candidate must lie on its rod's image line within that spread, and the point taken is the
length's root nearest the axis's prediction. The pointer fit (:mod:`trackerd.geometry.pointer_fit`) then
places that end from its one camera's measurement and the length, and its covariance says how well: where
the ray meets the sphere at a glancing angle, the length fixes the depth poorly and the sigma is large.

Nothing is guessed: no axis (fewer than two cameras show the rod clearly, or their planes are too near
parallel), no candidate on the rod's line, or two candidates there that are not one ball, and there is no
such end.
"""

from __future__ import annotations

import math

import numpy as np

from trackerd.detect.search import Candidate
from trackerd.geometry.camera import CameraModel
from trackerd.joint.looks import ROD_POINTS, RodFrom, length_roots, rod_sightings
from trackerd.joint.points import SIZE_SCALE, Array, Point

LONE_SIZE_RATIO = 1.3
"""The one camera's outline is within this factor of a ball's image radius at the point taken (as the
pointer fit's own test of an outline's size, ``MAX_RADIUS_RATIO`` in :mod:`trackerd.ends`)."""

LONE_MIN_COS = 0.25
"""The one camera's ray must meet the pointer's axis at a cosine of at least this (within about 75 degrees of
it): the depth the length gives is then good to four times the length's error, and the two roots are half a
length apart."""

LONE_PENALTY = 16.0
"""Added to a lone point's score: one camera's ray is weaker evidence than two that meet."""

LONE_APART = 2.0
"""Lone points further apart than this many ball diameters are different balls: the end is ambiguous."""


def lone_points(
    cameras: list[CameraModel],
    candidates: list[dict[str, list[Candidate]]],
    colour: str,
    partners: list[Point],
    ball_radius_m: float,
    length_m: float,
    length_tolerance_m: float,
    room_side: tuple[Array, float] | None,
    rod: RodFrom,
) -> list[Point] | str:
    """Points of ``colour`` that one camera measures (see the module), from the best ROD_POINTS
    ``partners`` (the other colour's points), best first; or why there are none (the reason names what
    was missing, or that the end is ambiguous)."""
    other = "blue" if colour == "red" else "red"
    found: list[Point] = []
    axes = glancing = 0
    for partner in partners[:ROD_POINTS]:
        sightings = rod_sightings(cameras, candidates, colour, partner, ball_radius_m, length_m, rod)
        axes += bool(sightings)
        for sighting in sightings:
            camera = cameras[sighting.camera]
            origin_px = sighting.from_px
            for index, cand in enumerate(candidates[sighting.camera][colour]):
                centre_px = np.asarray(cand.fit.centre_px, dtype=np.float64)
                # On the rod's image line, about where the axis puts the ball (within the spread its
                # directions' error allows, and half a ball either way).
                from_origin = centre_px - origin_px
                across_px = abs(float(from_origin[0] * sighting.along[1] - from_origin[1] * sighting.along[0]))
                along_px = abs(float((centre_px - sighting.expected_px) @ sighting.along))
                if across_px > max(3.0, 0.5 * sighting.radius_px):
                    continue
                if along_px > sighting.spread_px + 0.5 * sighting.radius_px:
                    continue
                _, ray = camera.pixel_to_ray(centre_px[None])
                ray = ray[0] / np.linalg.norm(ray[0])
                roots = length_roots(camera.centre_m, ray, partner.point_m, length_m, length_tolerance_m)
                if not roots:
                    continue
                distance_m = min((s for s, _ in roots), key=lambda s: _off_m(camera, ray, s, sighting.ball_m))
                point = camera.centre_m + distance_m * ray
                if distance_m <= 0.2 or (room_side is not None and float(point @ room_side[0] + room_side[1]) <= 0):
                    continue
                if not length_fixes_depth(camera.centre_m, point, partner.point_m):
                    glancing += 1
                    continue
                size = cand.fit.radius_px / (camera.focal_px * ball_radius_m / distance_m)
                if not 1.0 / LONE_SIZE_RATIO <= size <= LONE_SIZE_RATIO:
                    continue
                score = LONE_PENALTY + (math.log(size) / SIZE_SCALE) ** 2
                found.append(Point(point, {sighting.camera: index}, score))
    if not found:
        if not axes:
            return f"no camera pair shows the rod leaving the {other} ball clearly enough to follow it"
        if glancing:
            return (
                f"one camera's ray meets the {colour} ball's place on the pointer's length at a glancing angle:"
                " the length cannot fix its depth"
            )
        return f"no {colour} candidate lies where the rod leads from the {other} ball"
    found.sort(key=lambda p: p.score)
    best = found[0].point_m
    if any(float(np.linalg.norm(p.point_m - best)) > LONE_APART * 2.0 * ball_radius_m for p in found[1:]):
        return f"{len(found)} {colour} candidates lie where the rod leads, and they are not one ball"
    return found


def length_fixes_depth(camera_m: Array, end_m: Array, other_end_m: Array) -> bool:
    """Whether the pointer's length fixes the depth of ``end_m`` along the ray to it from ``camera_m``: the
    ray meets the pointer's axis at a cosine of at least LONE_MIN_COS. The depth the length gives is good to
    the length's error over that cosine, and the ray's two points at the length from the other end are twice
    the length times it apart: at a glancing angle, neither holds."""
    ray = np.asarray(end_m, dtype=np.float64) - camera_m
    axis = np.asarray(end_m, dtype=np.float64) - other_end_m
    cosine = abs(float(ray @ axis)) / max(float(np.linalg.norm(ray) * np.linalg.norm(axis)), 1e-12)
    return cosine >= LONE_MIN_COS


def _off_m(camera: CameraModel, ray: Array, distance_m: float, predicted_m: Array) -> float:
    """How far the ray's point at ``distance_m`` is from the axis's prediction."""
    return float(np.linalg.norm(camera.centre_m + distance_m * ray - predicted_m))
