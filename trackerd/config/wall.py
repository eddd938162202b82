"""The display wall (``[wall]``): its plane and its 2D frame."""

from __future__ import annotations

from pydantic import Field, model_validator

from trackerd.config.base import ConfigModel, Vec3


class WallConfig(ConfigModel):
    """The display wall: its plane (eq. 23-25) and its 2D frame (origin, x along, y up).

    Either give the four corners of the display area (then everything follows), or
    give three or more points on the plane together with the frame: ``origin_m``,
    ``x_direction``, ``y_direction``, ``width_m`` and ``height_m``.
    """

    corners_m: tuple[Vec3, Vec3, Vec3, Vec3] | None = None
    """Display corners in world coordinates: bottom-left, bottom-right, top-right, top-left."""
    points_m: tuple[Vec3, ...] | None = None
    """Three or more measured points on the wall plane (a least-squares plane when more than three)."""
    origin_m: Vec3 | None = None
    """With points_m: the display's bottom-left corner (projected onto the plane)."""
    x_direction: Vec3 | None = None
    """With points_m: a direction along the bottom edge, to the right (projected onto the plane)."""
    y_direction: Vec3 | None = None
    """With points_m: a direction roughly up the wall (made perpendicular to x in the plane)."""
    width_m: float | None = Field(default=None, gt=0.0)
    """With points_m: width of the display area along x."""
    height_m: float | None = Field(default=None, gt=0.0)
    """With points_m: height of the display area along y."""
    display_width_px: int | None = Field(default=None, gt=0)
    """Width of the displayed image in pixels, to report hits in display pixels."""
    display_height_px: int | None = Field(default=None, gt=0)
    """Height of the displayed image in pixels."""
    planarity_tolerance_m: float = Field(default=0.01, gt=0.0)
    """Corners or points further than this from their best-fit plane are rejected as a mistake."""

    @model_validator(mode="after")
    def _one_description(self) -> WallConfig:
        frame_keys = ("origin_m", "x_direction", "y_direction", "width_m", "height_m")
        if self.corners_m is not None:
            given = [k for k in (*frame_keys, "points_m") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"corners_m already fixes the wall; remove {', '.join(given)}")
        elif self.points_m is not None:
            if len(self.points_m) < 3:
                raise ValueError("points_m needs three or more points (eq. 24)")
            missing = [k for k in frame_keys if getattr(self, k) is None]
            if missing:
                raise ValueError(f"with points_m also give {', '.join(missing)}")
        else:
            raise ValueError("give either corners_m or points_m (with origin_m, x_direction, ...)")
        if (self.display_width_px is None) != (self.display_height_px is None):
            raise ValueError("give both display_width_px and display_height_px, or neither")
        return self
