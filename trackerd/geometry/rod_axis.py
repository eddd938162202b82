"""Where the pointer's other ball should be seen, from one ball's point and the rod leaving it in each image.

When one ball is triangulated and no camera offered the other (it merged with a picture of its colour, or
is too dark for the colour test), the rod still shows: in each image it leaves the found ball towards the
missing one. That image direction and the camera's centre span a plane containing the pointer (the
interpretation plane of :mod:`trackerd.geometry.pointer_line`, from a ball and a direction instead of two
balls), so two or more cameras' planes give the pointer's axis through the found point, and the pointer's
length puts the other ball on it. Projected back, that is where each camera should look for it, together
with how far along the rod's image line the prediction can be off: where the planes are nearly parallel
(cameras looking along the pointer), a degree in one camera's direction moves the point several ball
diameters along the rod in the other's image, but hardly at all across it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.pointer_line import interpretation_plane_normals, lines_from_planes

Array = NDArray[np.float64]

_PLANE_SPAN_PX = 20.0
"""The second pixel of a direction's plane is this far along it (its first is the found ball's centre)."""

MIN_PLANES_DEG = 3.0
"""Planes closer than this give no axis: a direction as far off as the error asked for (3 degrees in the joint
choice) can turn one past the other, and the axis then lies anywhere in them."""


@dataclass(frozen=True)
class RodSighting:
    """Where the other ball should be in one camera's image."""

    camera: int
    expected_px: Array
    """(2,) its predicted centre."""
    along: Array
    """(2,) unit image direction from the found ball towards it (the rod's, as measured)."""
    spread_px: float
    """How far along ``along`` the prediction moves when any one camera's direction is off by the error asked
    for: the look must cover this much either side of ``expected_px``."""
    radius_px: float
    """The other ball's image radius at the predicted point."""
    ball_m: Array
    """(3,) the predicted point itself (the same for every camera's sighting)."""
    from_px: Array
    """(2,) the found ball's centre in this image, where the rod's line starts."""


def other_ball_along_rod(
    cameras: Sequence[CameraModel],
    point_m: Array,
    leaving: dict[int, tuple[Array, Array]],
    length_m: float,
    ball_radius_m: float,
    direction_error_deg: float,
) -> list[RodSighting]:
    """The pointer's other ball as each camera in ``leaving`` should see it (those where it projects), or []
    when fewer than two cameras give a rod direction, their planes are less than MIN_PLANES_DEG apart, or
    their rods do not agree on a side.

    ``point_m`` (3,): the found ball's triangulated centre. ``leaving``: camera index -> (the found ball's
    centre in that image (2,), the unit image direction (2,) in which the rod leaves it). Each direction is
    turned by +/- ``direction_error_deg`` in turn to give each sighting's ``spread_px``.
    """
    indices = sorted(leaving)
    if len(indices) < 2:
        return []
    centres_px = np.stack([leaving[c][0] for c in indices])  # (C, 2)
    along = np.stack([leaving[c][1] for c in indices])  # (C, 2)
    # The nominal directions, then each one turned either way: (1 + 2 C, C, 2).
    turn = math.radians(direction_error_deg)
    sets = np.repeat(along[None], 1 + 2 * len(indices), axis=0)
    for k in range(len(indices)):
        for sign, row in ((1.0, 1 + 2 * k), (-1.0, 2 + 2 * k)):
            c, s = math.cos(sign * turn), math.sin(sign * turn)
            x, y = along[k]
            sets[row, k] = (c * x - s * y, s * x + c * y)
    normals = np.empty((*sets.shape[:2], 3))
    for k, index in enumerate(indices):
        camera = cameras[index]
        pixels = np.concatenate([centres_px[k][None], centres_px[k] + _PLANE_SPAN_PX * sets[:, k]])
        _, rays = camera.pixel_to_ray(pixels)
        normals[:, k] = interpretation_plane_normals(np.broadcast_to(rays[0], rays[1:].shape), rays[1:])
    origins = np.stack([cameras[c].centre_m for c in indices])
    _, axes, conditioning = lines_from_planes(origins, normals)  # (1 + 2 C, 3) unit, either sign
    if float(conditioning[0]) < math.sin(math.radians(MIN_PLANES_DEG)):
        return []
    # The nominal axis's sign: the one whose far end every camera sees along its rod.
    candidates = point_m + length_m * np.stack([axes[0], -axes[0]])
    sides = []
    for other in candidates:
        ahead = [float((cameras[c].project(other[None])[0] - centres_px[k]) @ along[k]) for k, c in enumerate(indices)]
        sides.append(all(np.isfinite(a) and a > 0 for a in ahead))
    if sides[0] == sides[1]:
        return []
    nominal = candidates[0] if sides[0] else candidates[1]
    # Each turned set's axis with the sign nearest the nominal one's.
    axes = axes * np.where(axes @ (nominal - point_m) >= 0, 1.0, -1.0)[:, None]
    others = point_m + length_m * axes  # (1 + 2 C, 3)
    sightings = []
    for k, index in enumerate(indices):
        camera = cameras[index]
        projected = camera.project(others)
        if not np.all(np.isfinite(projected)):
            continue
        distance_along = (projected - centres_px[k]) @ along[k]
        spread = float(np.max(np.abs(distance_along[1:] - distance_along[0])))
        radius = camera.focal_px * ball_radius_m / float(np.linalg.norm(others[0] - camera.centre_m))
        sightings.append(RodSighting(index, projected[0], along[k], spread, radius, others[0], centres_px[k]))
    return sightings
