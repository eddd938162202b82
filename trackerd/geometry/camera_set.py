"""The cameras one fix is computed from, and the pointer's line and its hit's spread from their views.

The locator's geometry for each pair, on normalised image coordinates (pixels
with the lens removed, eq. 1-2 and 14): the pointer's line from the cameras'
interpretation planes and each end's closest approach (eq. 15-17,
:mod:`trackerd.geometry.pointer_line`; two cameras by the closed forms of
:mod:`trackerd.geometry.two_cameras`), and the uncertainty of the line's wall
hit (eq. 23-28) when each centroid moves across the pointer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError
from trackerd.geometry import two_cameras
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.pointer_line import (
    PointerLine,
    cross3,
    estimate_pointer_line,
    line_from_planes,
    sphere_centre_direction,
)
from trackerd.geometry.wall import WallFloats, WallFrame

Array = NDArray[np.float64]

ScalarPose = tuple[two_cameras.Vec, two_cameras.Rows, two_cameras.Vec]
"""A camera's centre, world-to-camera rotation rows and translation as tuples of floats."""


@dataclass(frozen=True)
class CameraSet:
    """Cameras with their stacked centres (C, 3) and world-to-camera rotations (C, 3, 3)."""

    cameras: list[CameraModel]
    centres_m: Array
    rotations: Array
    scalar_poses: tuple[ScalarPose, ...]
    """Per camera, its pose as floats (trackerd.geometry.two_cameras)."""

    @staticmethod
    def build(cameras: Sequence[CameraModel]) -> CameraSet:
        centres = np.array([cam.centre_m for cam in cameras])
        # d_world = d_cam @ R (R is world-to-camera), stacked for all cameras.
        rotations = np.stack([cam.rotation for cam in cameras])
        poses = tuple(_scalar_pose(cam) for cam in cameras)
        return CameraSet(list(cameras), centres, rotations, poses)

    def subset(self, used: Sequence[int] | None) -> CameraSet:
        """All these cameras (``used`` None or all of them), or those listed."""
        if used is None or len(used) == len(self.cameras):
            return self
        index = np.asarray(used)
        return CameraSet(
            [self.cameras[i] for i in used],
            self.centres_m[index],
            self.rotations[index],
            tuple(self.scalar_poses[i] for i in used),
        )


def _scalar_pose(cam: CameraModel) -> ScalarPose:
    cx, cy, cz = (float(v) for v in cam.centre_m)
    tx, ty, tz = (float(v) for v in cam.translation_m)
    r = cam.rotation
    rows = (
        (float(r[0, 0]), float(r[0, 1]), float(r[0, 2])),
        (float(r[1, 0]), float(r[1, 1]), float(r[1, 2])),
        (float(r[2, 0]), float(r[2, 1]), float(r[2, 2])),
    )
    return (cx, cy, cz), rows, (tx, ty, tz)


def estimate_line(normalised: Array, view: CameraSet, min_plane_sin: float, ball_radius_m: float | None) -> PointerLine:
    """Pointer line from normalised coordinates (C, 2 ends (front, back), 2) of the cameras in ``view``.

    With ``ball_radius_m``, each end's ray is corrected to its ball's centre
    (:func:`~trackerd.geometry.pointer_line.sphere_centre_direction`) at the
    depth a first line puts it. Raises GeometryError as estimate_pointer_line does.
    """
    if len(view.cameras) == 2:
        fast = _estimate_two(normalised, view, min_plane_sin, ball_radius_m)
        if fast is not None:
            return fast
    rays = np.concatenate([normalised, np.ones((*normalised.shape[:2], 1))], axis=2)
    rays /= np.sqrt(np.sum(rays * rays, axis=2, keepdims=True))
    line = _line_from_camera_rays(rays[:, 0], rays[:, 1], view, min_plane_sin)
    if ball_radius_m is not None:
        front_depth = np.array([cam.to_camera_frame(line.front_m[None])[0, 2] for cam in view.cameras])
        back_depth = np.array([cam.to_camera_frame(line.back_m[None])[0, 2] for cam in view.cameras])
        if np.all(front_depth > ball_radius_m) and np.all(back_depth > ball_radius_m):
            line = _line_from_camera_rays(
                sphere_centre_direction(rays[:, 0], front_depth, ball_radius_m),
                sphere_centre_direction(rays[:, 1], back_depth, ball_radius_m),
                view,
                min_plane_sin,
            )
    return line


def _estimate_two(
    normalised: Array, view: CameraSet, min_plane_sin: float, ball_radius_m: float | None
) -> PointerLine | None:
    """:func:`estimate_line` for two cameras in plain floats (trackerd.geometry.two_cameras); None where
    the planes are too close to parallel, for the general path's two-point line."""
    (centre0, rows0, t0), (centre1, rows1, t1) = view.scalar_poses
    (x0f, y0f), (x0b, y0b) = normalised[0].tolist()
    (x1f, y1f), (x1b, y1b) = normalised[1].tolist()
    world_ray = two_cameras.world_ray
    rays = (
        world_ray(rows0, x0f, y0f),
        world_ray(rows0, x0b, y0b),
        world_ray(rows1, x1f, y1f),
        world_ray(rows1, x1b, y1b),
    )
    ends = two_cameras.pointer_ends(centre0, centre1, *rays, min_plane_sin)
    if ends is None:
        return None
    if ball_radius_m is not None:
        front, back, _ = ends
        depths = [
            rows[2][0] * p[0] + rows[2][1] * p[1] + rows[2][2] * p[2] + t[2]
            for rows, t in ((rows0, t0), (rows1, t1))
            for p in (front, back)
        ]
        if not min(depths) <= ball_radius_m:  # (as the test always was, should a depth be NaN)
            # As sphere_centre_direction: the ellipse's centre lies (1 - r^2 / Z^2) further out.
            k0f, k0b, k1f, k1b = (1.0 - (ball_radius_m / z) ** 2 for z in depths)
            return two_cameras.pointer_line(
                centre0,
                centre1,
                world_ray(rows0, x0f * k0f, y0f * k0f),
                world_ray(rows0, x0b * k0b, y0b * k0b),
                world_ray(rows1, x1f * k1f, y1f * k1f),
                world_ray(rows1, x1b * k1b, y1b * k1b),
                min_plane_sin,
            )
    # The first line is the answer (no correction, or an end too close to a camera for one).
    return two_cameras.line_through(centre0, centre1, *rays, ends)


def _line_from_camera_rays(front_cam: Array, back_cam: Array, view: CameraSet, min_plane_sin: float) -> PointerLine:
    """Line from camera-frame unit rays (C, 3) through the front and back ends."""
    front_world = np.einsum("cj,cjk->ck", front_cam, view.rotations)
    back_world = np.einsum("cj,cjk->ck", back_cam, view.rotations)
    return estimate_pointer_line(view.centres_m, front_world, back_world, min_plane_sin)


def hit_uncertainty_m(
    normalised: Array, view: CameraSet, sigma_px: float, wall: WallFrame, wall_scalars: WallFloats
) -> float | None:
    """RMS radius of the hit's error when every centroid moves by ``sigma_px`` across the pointer.

    Only displacements across each camera's image of the pointer move the
    line (along it they only slide the ends), so one perturbation per end per
    camera gives the Jacobian of the hit. Pixels are converted to normalised
    coordinates with each camera's focal length (distortion's local scale
    change of a few percent is ignored: this is an estimate). None when a
    moved line is parallel to the wall.
    """
    if len(view.cameras) == 2:
        return hit_uncertainty_two_m(normalised, view, sigma_px, wall_scalars)
    return hit_uncertainty_reference_m(normalised, view, sigma_px, wall)


def hit_uncertainty_reference_m(normalised: Array, view: CameraSet, sigma_px: float, wall: WallFrame) -> float | None:
    """:func:`hit_uncertainty_m` for any number of cameras: the reference of :func:`hit_uncertainty_two_m`."""
    n_cameras = len(view.cameras)
    # Variant 0 is the measurement; then each end of each camera moved across the pointer.
    variants = np.repeat(normalised[None], 1 + 2 * n_cameras, axis=0)
    for index, cam in enumerate(view.cameras):
        along = normalised[index, 0] - normalised[index, 1]
        across = np.array([-along[1], along[0]]) / max(float(np.hypot(*along)), 1e-12)
        for end in (0, 1):
            variants[1 + 2 * index + end, index, end] += across * sigma_px / cam.focal_px
    try:
        hits = _plane_hits_xy(variants, view, wall)
    except GeometryError:
        return None
    return float(np.sqrt(np.sum((hits[1:] - hits[0]) ** 2)))


def hit_uncertainty_two_m(
    normalised: Array, view: CameraSet, sigma_px: float, wall_scalars: WallFloats
) -> float | None:
    """:func:`hit_uncertainty_m` for two cameras, in plain floats (trackerd.geometry.two_cameras)."""
    (centre0, rows0, _), (centre1, rows1, _) = view.scalar_poses
    measured = normalised.reshape(8).tolist()  # x0f, y0f, x0b, y0b, x1f, y1f, x1b, y1b
    variants = [tuple(measured)]
    for index, cam in enumerate(view.cameras):
        xf, yf, xb, yb = measured[4 * index : 4 * index + 4]
        along_x, along_y = xf - xb, yf - yb
        scale = sigma_px / cam.focal_px / max(math.hypot(along_x, along_y), 1e-12)
        shift = (-along_y * scale, along_x * scale)
        for end in (0, 1):
            moved = list(measured)
            moved[4 * index + 2 * end] += shift[0]
            moved[4 * index + 2 * end + 1] += shift[1]
            variants.append(tuple(moved))
    try:
        hits = two_cameras.plane_line_hits(
            centre0, centre1, (rows0, rows1), variants, wall_scalars.normal, wall_scalars.offset_m
        )
    except GeometryError:
        return None
    # The hits lie in the wall's plane: their spread in the wall's frame, along its two axes.
    (hx, hy, hz), x_axis, y_axis = hits[0], wall_scalars.x_axis, wall_scalars.y_axis
    total = 0.0
    for px, py, pz in hits[1:]:
        dx, dy, dz = px - hx, py - hy, pz - hz
        along_x = dx * x_axis[0] + dy * x_axis[1] + dz * x_axis[2]
        along_y = dx * y_axis[0] + dy * y_axis[1] + dz * y_axis[2]
        total += along_x * along_x + along_y * along_y
    return math.sqrt(total)


def _plane_hits_xy(variants: Array, view: CameraSet, wall: WallFrame) -> Array:
    """Wall hits (B, 2) of the interpretation planes' lines for B sets of normalised
    coordinates (B, C, 2 ends, 2), in NumPy (two cameras take :func:`hit_uncertainty_two_m`)."""
    rays = np.concatenate([variants, np.ones((*variants.shape[:3], 1))], axis=3)
    world = np.einsum("bcej,cjk->bcek", rays, view.rotations)
    normals = cross3(world[:, :, 0], world[:, :, 1])
    normals /= np.sqrt(np.sum(normals * normals, axis=-1, keepdims=True))
    lines = [line_from_planes(view.centres_m, n) for n in normals]
    points = np.array([line[0] for line in lines])
    directions = np.array([line[1] for line in lines])
    plane = wall.plane
    denominator = directions @ plane.normal
    if np.any(np.abs(denominator) < 1e-9):
        raise GeometryError("the pointer is parallel to the wall")
    hits = points - (plane.signed_distance_m(points) / denominator)[:, None] * directions
    result: Array = wall.to_wall_m(hits)
    return result
