"""The cameras one fix is computed from, and the pointer's line and its hit's spread from their views.

The locator's geometry for each pair, on normalised image coordinates (pixels
with the lens removed, eq. 1-2 and 14): the pointer's line from the cameras'
interpretation planes and each end's closest approach (eq. 15-17,
:mod:`trackerd.geometry.pointer_line`), corrected for the balls' size, and the
uncertainty of the line's wall hit (eq. 23-28) when each centroid moves across
the pointer. One path for any number of cameras: the measurement and its moved
copies go through the same batched functions together.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import GeometryError
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.pointer_line import (
    PARALLEL_PLANES_SIN,
    PointerLine,
    interpretation_plane_normals,
    line_on_planes,
    lines_from_planes,
    sphere_centre_scale,
    world_rays,
)
from trackerd.geometry.triangulation import nearest_points_m
from trackerd.geometry.wall import MIN_LINE_PLANE_SIN, WallFrame

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CameraSet:
    """Cameras with their poses stacked for the batched geometry."""

    cameras: list[CameraModel]
    centres_m: Array
    """(C, 3) optical centres in the world."""
    rotations: Array
    """(C, 3, 3) world-to-camera rotations."""
    depth_rows: Array
    """(C, 3) each rotation's last row: with :attr:`depth_offsets_m`, a world point's depth in each camera."""
    depth_offsets_m: Array
    """(C,) each translation's z."""
    focal_px: Array
    """(C,) each camera's focal length in pixels (pixels to normalised coordinates)."""
    translations_m: Array
    """(C, 3) world-to-camera translations (the pointer fit's poses, with :attr:`rotations`)."""

    @staticmethod
    def build(cameras: Sequence[CameraModel]) -> CameraSet:
        rotations = np.stack([cam.rotation for cam in cameras])
        return CameraSet(
            list(cameras),
            np.array([cam.centre_m for cam in cameras]),
            rotations,
            rotations[:, 2, :].copy(),
            np.array([float(cam.translation_m[2]) for cam in cameras]),
            np.array([cam.focal_px for cam in cameras]),
            np.stack([np.asarray(cam.translation_m, dtype=np.float64) for cam in cameras]),
        )

    def subset(self, used: Sequence[int] | None) -> CameraSet:
        """All these cameras (``used`` None or all of them), or those listed."""
        if used is None or len(used) == len(self.cameras):
            return self
        index = np.asarray(used)
        return CameraSet(
            [self.cameras[i] for i in used],
            self.centres_m[index],
            self.rotations[index],
            self.depth_rows[index],
            self.depth_offsets_m[index],
            self.focal_px[index],
            self.translations_m[index],
        )


@dataclass(frozen=True)
class LineEstimate:
    """The pointer's line, and the interpretation planes' lines its uncertainty is read from."""

    line: PointerLine
    plane_points_m: Array
    """(B, 3) a point of each set's planes' line: set 0 as measured, then each end of each camera moved
    across the pointer in turn (none when no move was asked for)."""
    plane_directions: Array
    """(B, 3) those lines' unit directions."""
    plane_conditioning: Array
    """(B,) sine of the angle between each set's planes."""


def moved_across(normalised: Array, focal_px: Array, across_px: float | Array) -> Array:
    """The measurement (C, 2 ends, 2) and 2C copies, each with one end of one camera moved ``across_px``
    (one distance for all, or (C, 2 ends) of them) across that camera's image of the pointer
    -> (1 + 2C, C, 2, 2); set 1 + 2k + e moves camera k's end e.

    Only moves across the pointer's image move the line (along it they only slide the
    ends), so these sets are what the hit's uncertainty needs: :func:`hit_uncertainty_m`.
    """
    sets_moved, camera, end = _moved_index(normalised.shape[0])
    along = normalised[:, 0] - normalised[:, 1]
    # A pixel is 1 / focal in normalised coordinates (distortion's local scale change of a
    # few percent is ignored: this is an estimate).
    scale = 1.0 / (focal_px * np.maximum(np.sqrt((along * along).sum(axis=-1)), 1e-12))
    pixel = along[:, ::-1] * (scale[:, None] * _PERPENDICULAR)  # (-y, x): along turned a quarter, a pixel long
    distances = np.broadcast_to(np.asarray(across_px, dtype=np.float64), normalised.shape[:2])
    sets = np.repeat(normalised[None], len(sets_moved) + 1, axis=0)
    sets[sets_moved, camera, end] += pixel[camera] * distances[camera, end][:, None]
    return sets


_PERPENDICULAR = np.array([-1.0, 1.0])


def across_sigma_px(normalised: Array, covariances: Array, focal_px: Array) -> Array:
    """Each end's standard error across its camera's image of the pointer, in pixels (C, 2 ends), from its
    covariance (C, 2, 2, 2) in normalised units: what :func:`moved_across` moves it by."""
    along = normalised[:, 0] - normalised[:, 1]
    across = along[:, ::-1] * _PERPENDICULAR / np.maximum(np.linalg.norm(along, axis=-1), 1e-300)[:, None]
    variance = np.einsum("ci,ceij,cj->ce", across, covariances, across)
    sigma: Array = np.sqrt(np.maximum(variance, 0.0)) * focal_px[:, None]
    return sigma


@lru_cache(maxsize=8)
def _moved_index(cameras: int) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Which set moves which camera's which end (:func:`moved_across`)."""
    index = (1 + np.arange(2 * cameras), np.repeat(np.arange(cameras), 2), np.tile([0, 1], cameras))
    for array in index:
        array.flags.writeable = False  # the same arrays for every caller
    return index


def estimate_line(
    normalised: Array,
    view: CameraSet,
    min_plane_sin: float,
    ball_radius_m: float | None,
    across_px: float | Array | None = None,
) -> LineEstimate:
    """The pointer's line from normalised coordinates (C, 2 ends (front, back), 2) of the cameras in ``view``.

    The interpretation planes' line with each end placed on it by its rays, or the two
    triangulated ends where the planes are too close to parallel (below ``min_plane_sin``).
    With ``ball_radius_m``, each end's ray is first corrected to its ball's centre
    (:func:`~trackerd.geometry.pointer_line.sphere_centre_scale`) at the depth that end's
    rays triangulate to in each camera. With ``across_px`` (one distance, or one per end), the moved sets of
    :func:`moved_across` go through the same steps beside the measurement. Raises
    GeometryError for a coordinate that is not finite, when an end's two rays coincide in a camera, or
    when the line's ends are not found.
    """
    if not np.isfinite(normalised).all():
        raise GeometryError("an end's ray is undefined (NaN): every camera must see both ends")
    sets = normalised[None] if across_px is None else moved_across(normalised, view.focal_px, across_px)
    if ball_radius_m is not None:
        depths = _end_depths_m(normalised, view)
        # Not where an end is within a ball's radius of a camera's centre (the correction is undefined).
        if depths is not None and (depths > ball_radius_m).all():
            sets = sets * sphere_centre_scale(depths, ball_radius_m)[..., None]
    rays = world_rays(sets, view.rotations)  # (B, C, 2 ends, 3)
    normals = interpretation_plane_normals(rays[..., 0, :], rays[..., 1, :])
    points, directions, conditioning = lines_from_planes(view.centres_m, normals)
    line = line_on_planes(
        view.centres_m, np.swapaxes(rays[0], 0, 1), points[0], directions[0], float(conditioning[0]), min_plane_sin
    )
    return LineEstimate(line, points, directions, conditioning)


def _end_depths_m(normalised: Array, view: CameraSet) -> Array | None:
    """Each end's depth (C, 2 ends) in each camera, where its rays' least-squares point puts it (eq. 15-17);
    None when an end's rays are parallel. Only the correction's scale, 1 - r^2 / Z^2, depends on it, and
    r^2 / Z^2 is a few 1e-5: a depth 5 cm off at 3 m changes it by 3 % of that."""
    rays = np.swapaxes(world_rays(normalised, view.rotations), 0, 1)  # (2 ends, C, 3)
    try:
        ends = nearest_points_m(view.centres_m, rays)
    except np.linalg.LinAlgError:
        return None
    depths: Array = (ends @ view.depth_rows.T + view.depth_offsets_m).T
    return depths


def hit_uncertainty_m(estimate: LineEstimate, wall: WallFrame, end_correlation: float = 0.0) -> float | None:
    """RMS radius of the hit's error when every centroid moves across the pointer by the
    ``across_px`` the estimate was made with: the spread, in the wall's frame, of where the
    moved sets' lines meet the wall (eq. 26-28) around the measured set's.

    ``end_correlation``: the correlation of one camera's two ends' errors across the pointer. Errors that
    move both ends one way shift the line more than they turn it, and it is the turn that the wall's
    distance magnifies: the moves' spreads add as v_f^2 + v_b^2 + 2 rho v_f . v_b per camera.

    None without moved sets, or when a set's planes or line are parallel (to each other, to the wall).
    """
    points, directions = estimate.plane_points_m, estimate.plane_directions
    if len(points) < 2 or np.any(~(estimate.plane_conditioning >= PARALLEL_PLANES_SIN)):
        return None
    plane = wall.plane
    denominator = directions @ plane.normal
    if np.any(~(np.abs(denominator) >= MIN_LINE_PLANE_SIN)):
        return None
    hits = points - ((points @ plane.normal + plane.offset_m) / denominator)[:, None] * directions
    moved = (hits[1:] - hits[0]) @ wall.axes.T  # along the wall's x and y; set 1 + 2k + e moved camera k's end e
    variance = float(np.sum(moved * moved))
    if end_correlation:
        pairs = moved.reshape(-1, 2, 2)
        variance += 2.0 * end_correlation * float(np.sum(pairs[:, 0] * pairs[:, 1]))
    return float(np.sqrt(max(variance, 0.0)))
