"""The pointer rendered alone into the tiles of a view its image touches, with the truth of each ball.

Only tiles near the pointer's projected outline are ray-cast, with adaptive
supersampling (one ray per interior pixel, ``supersampling``^2 rays per pixel
where what a pixel sees changes); the same sub-pixel samples give each ball's
visible area and the centroid of that area. A pointer moving during the
exposure is rendered at several instants and averaged (motion blur).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.geometry.camera import CameraModel
from trackerd.sim.appearance import Occluder
from trackerd.sim.lens_rays import LensRays
from trackerd.sim.pointer_shading import BLUE_BALL, NOTHING, RED_BALL, PointerLook, shade_pointer
from trackerd.sim.scene import HAND_RADIUS_M, HANDLE_LENGTH_FACTOR, PointerPose

Array = NDArray[np.float64]

TILE_PX = 16


@dataclass(frozen=True)
class PointerPatch:
    """The pointer alone in the box of tiles its image touches, at (x0, y0) in the view."""

    x0: int
    y0: int
    rgb: Array
    """(h, w, 3) colour premultiplied by coverage."""
    coverage: Array
    """(h, w) share of each pixel the pointer (or an occluder) covers."""
    sums: dict[str, tuple[float, float, float]]
    """Per ball colour: (visible area, sum of x, sum of y) over its visible samples, in pixels."""


PatchKey = tuple[tuple[bytes, ...], tuple[Occluder, ...]]


class PointerRenderer:
    """Renders the pointer (and what stands in front of it) into each camera's view."""

    def __init__(self, cameras: list[CameraModel], lens: LensRays, scene: PointerLook, supersampling: int) -> None:
        self.cameras = cameras
        self.lens = lens
        self.scene = scene
        self.supersampling = supersampling
        self._last: dict[int, tuple[PatchKey, PointerPatch | None]] = {}

    def patch(self, index: int, poses: list[PointerPose], occluders: tuple[Occluder, ...] = ()) -> PointerPatch | None:
        """:meth:`render`, remembered for the last poses of each camera: a pointer held still
        (a presenter asked to hold it there) is ray-cast once; each frame still gets its own noise."""
        key = (tuple(p.front_m.tobytes() + p.back_m.tobytes() for p in poses), occluders)
        last = self._last.get(index)
        if last is not None and last[0] == key:
            return last[1]
        patch = self.render(index, poses, occluders)
        self._last[index] = (key, patch)
        return patch

    def forget(self) -> None:
        """Cast the next frame of every camera afresh, whatever the last poses were."""
        self._last.clear()

    def render(self, index: int, poses: list[PointerPose], occluders: tuple[Occluder, ...] = ()) -> PointerPatch | None:
        """Render the pointer alone in the tiles its image touches, averaged over ``poses``; None when
        nothing is in view."""
        cam = self.cameras[index]
        tiles: set[tuple[int, int]] = set()
        for pose in poses:
            tiles |= self.tiles_near_pointer(cam, pose, occluders)
        if not tiles:
            return None
        tx = np.array([t[0] for t in tiles])
        ty = np.array([t[1] for t in tiles])
        x0, y0 = int(tx.min() * TILE_PX), int(ty.min() * TILE_PX)
        x1 = min(cam.width_px, int((tx.max() + 1) * TILE_PX))
        y1 = min(cam.height_px, int((ty.max() + 1) * TILE_PX))
        in_tiles = np.zeros((y1 - y0, x1 - x0), dtype=bool)
        for tile_x, tile_y in tiles:
            in_tiles[
                tile_y * TILE_PX - y0 : (tile_y + 1) * TILE_PX - y0, tile_x * TILE_PX - x0 : (tile_x + 1) * TILE_PX - x0
            ] = True
        local_y, local_x = np.nonzero(in_tiles)
        centre_dirs = self.lens.pixel_rays(index, local_x + x0, local_y + y0)
        rgb = np.zeros((y1 - y0, x1 - x0, 3))
        coverage = np.zeros((y1 - y0, x1 - x0))
        sums = {"red": np.zeros(3), "blue": np.zeros(3)}
        weight = 1.0 / len(poses)
        for pose in poses:
            self._accumulate_pose(
                index,
                pose,
                x0,
                y0,
                local_x,
                local_y,
                centre_dirs,
                (y1 - y0, x1 - x0),
                weight,
                rgb,
                coverage,
                sums,
                occluders,
            )
        result = {c: (float(v[0]), float(v[1]), float(v[2])) for c, v in sums.items()}
        return PointerPatch(x0, y0, rgb, coverage, result)

    def _accumulate_pose(
        self,
        index: int,
        pose: PointerPose,
        x0: int,
        y0: int,
        local_x: NDArray[np.intp],
        local_y: NDArray[np.intp],
        centre_dirs: Array,
        shape: tuple[int, int],
        weight: float,
        rgb: Array,
        coverage: Array,
        sums: dict[str, Array],
        occluders: tuple[Occluder, ...] = (),
    ) -> None:
        """Adaptive supersampling: one ray per pixel, then ss x ss rays where ids change.

        A pixel whose centre and 8 neighbours all hit the same primitive is taken
        as fully covered by it; every other pixel (edges, junctions) gets the full
        grid of sub-pixel rays, so areas and centroids stay exact at the edges
        while most interior pixels cost one ray.
        """
        cam = self.cameras[index]
        ss = self.supersampling
        ids_c, colours_c = shade_pointer(self.scene, cam.centre_m, centre_dirs, pose, occluders)
        id_grid = np.zeros(shape, dtype=np.int8)
        id_grid[local_y, local_x] = ids_c
        # A pixel is on an edge where its 3 x 3 neighbourhood (the frame's border repeated) holds more than
        # one id: where the neighbourhood's largest id is not its smallest.
        ids_u8 = id_grid.view(np.uint8)
        square = np.ones((3, 3), dtype=np.uint8)
        largest = cv2.dilate(ids_u8, square, borderType=cv2.BORDER_REPLICATE)
        smallest = cv2.erode(ids_u8, square, borderType=cv2.BORDER_REPLICATE)
        is_edge = (largest != smallest)[local_y, local_x]
        # Interior pixels: one sample stands for the whole pixel.
        interior = ~is_edge & (ids_c != NOTHING)
        iy, ix = local_y[interior], local_x[interior]
        coverage[iy, ix] += weight
        rgb[iy, ix] += weight * colours_c[interior]
        for colour, prim in (("red", RED_BALL), ("blue", BLUE_BALL)):
            mask = ids_c[interior] == prim
            if np.any(mask):
                sums[colour] += weight * np.array([mask.sum(), (ix[mask] + x0).sum(), (iy[mask] + y0).sum()])
        if not np.any(is_edge):
            return
        # Edge pixels: the full sub-pixel grid.
        ey, ex = local_y[is_edge], local_x[is_edge]
        offsets = (np.arange(ss) + 0.5) / ss - 0.5
        ox, oy = np.meshgrid(offsets, offsets)
        sample_x = ((ex + x0)[:, None] + ox.ravel()[None, :]).ravel()
        sample_y = ((ey + y0)[:, None] + oy.ravel()[None, :]).ravel()
        ids, colours = shade_pointer(
            self.scene, cam.centre_m, self.lens.rays(index, sample_x, sample_y), pose, occluders
        )
        n = ss * ss
        coverage[ey, ex] += weight * (ids != NOTHING).reshape(-1, n).sum(axis=1) / n
        rgb[ey, ex] += weight * colours.reshape(-1, n, 3).sum(axis=1) / n
        for colour, prim in (("red", RED_BALL), ("blue", BLUE_BALL)):
            mask = ids == prim
            if np.any(mask):
                sums[colour] += (weight / n) * np.array([mask.sum(), sample_x[mask].sum(), sample_y[mask].sum()])

    def tiles_near_pointer(
        self, cam: CameraModel, pose: PointerPose, occluders: tuple[Occluder, ...] = ()
    ) -> set[tuple[int, int]]:
        """Tiles (x, y) whose centre lies within reach of the pointer's (and the occluders') projected outline."""
        length = pose.length_m
        handle_end = pose.back_m - HANDLE_LENGTH_FACTOR * length * pose.direction
        hand_centre = handle_end - HAND_RADIUS_M * 0.5 * pose.direction
        axis_points = np.linspace(0.0, 1.0, 24)[:, None]
        points = np.vstack(
            [
                pose.front_m + axis_points * (handle_end - pose.front_m),
                hand_centre[None, :],
            ]
        )
        radius = np.full(len(points), max(self.scene.end_diameter_m / 2.0, self.scene.rod_diameter_m / 2.0))
        radius[-1] = HAND_RADIUS_M if self.scene.hand else 0.0
        in_cam = cam.to_camera_frame(points)
        ahead = in_cam[:, 2] > 0.05
        if not np.any(ahead):
            return set()
        projected = cam.project(points[ahead])
        reach = cam.focal_px * radius[ahead] / in_cam[ahead, 2] * 1.3 + 3.0 + TILE_PX * 0.75
        n_tx = (cam.width_px + TILE_PX - 1) // TILE_PX
        n_ty = (cam.height_px + TILE_PX - 1) // TILE_PX
        # Candidate tiles around each projected point and along segments between them.
        dense = []
        for k in range(len(projected) - 1):
            a, b = projected[k], projected[k + 1]
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
                continue
            steps = max(2, int(np.linalg.norm(b - a) / (TILE_PX / 2)) + 1)
            for f in np.linspace(0, 1, steps):
                dense.append((a + f * (b - a), reach[k] + f * (reach[k + 1] - reach[k])))
        dense.append((projected[-1], reach[-1]))
        dense += occluder_reach(cam, occluders)
        marked = np.zeros((n_ty, n_tx), dtype=bool)
        for centre, r in dense:
            if not np.all(np.isfinite(centre)):
                continue
            lo = np.floor((centre - r) / TILE_PX).astype(int)
            hi = np.floor((centre + r) / TILE_PX).astype(int)
            marked[max(lo[1], 0) : min(hi[1], n_ty - 1) + 1, max(lo[0], 0) : min(hi[0], n_tx - 1) + 1] = True
        rows, cols = np.nonzero(marked)
        return set(zip(cols.tolist(), rows.tolist(), strict=True))


def occluder_reach(cam: CameraModel, occluders: tuple[Occluder, ...]) -> list[tuple[Array, float]]:
    """(image point, reach in pixels) along each occluder, for the tiles to render."""
    out: list[tuple[Array, float]] = []
    for occ in occluders:
        centre = np.asarray(occ.centre_m, dtype=np.float64)
        if occ.kind == "sphere":
            points = centre[None]
        else:
            steps = max(2, int(occ.height_m / max(occ.radius_m, 0.01)) * 2 + 1)
            points = centre + np.linspace(-0.5, 0.5, steps)[:, None] * np.array([0.0, occ.height_m, 0.0])
        depth = cam.to_camera_frame(points)[:, 2]
        ahead = depth > 0.05
        if not np.any(ahead):
            continue
        projected = cam.project(points[ahead])
        reach = cam.focal_px * occ.radius_m / depth[ahead] * 1.3 + 3.0 + TILE_PX * 0.75
        step_px = TILE_PX / 2
        for k in range(len(projected)):
            out.append((projected[k], float(reach[k])))
            if k + 1 < len(projected):
                a, b = projected[k], projected[k + 1]
                if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
                    n = max(2, int(np.linalg.norm(b - a) / step_px) + 1)
                    for f in np.linspace(0, 1, n)[1:-1]:
                        out.append((a + f * (b - a), float(reach[k] + f * (reach[k + 1] - reach[k]))))
    return out
