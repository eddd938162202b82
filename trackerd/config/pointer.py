"""The pointer and how it is found: its size (``[pointer]``), the detector's colour thresholds
(``[detector]``), the colours learned in the room, and the locator's gates (``[locator]``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from trackerd.config.base import ConfigModel

# --------------------------------------------------------------------------- pointer


class PointerConfig(ConfigModel):
    """The passive pointer: a rod with a coloured ball at each end."""

    front_colour: Literal["red", "blue"] = "red"
    """The end nearer the wall when pointing: the pointing direction runs from the other end to this one."""
    length_m: float = Field(gt=0.0)
    """Distance between the centres of the two coloured ends."""
    length_tolerance_m: float = Field(default=0.05, gt=0.0)
    """A triangulated pointer whose length differs from length_m by more is rejected as impossible."""
    end_diameter_m: float = Field(gt=0.0)
    """Diameter of each coloured ball."""
    rod_diameter_m: float = Field(default=0.012, gt=0.0)
    """Diameter of the (dark) rod joining the balls; used by the simulator and the bias model."""

    @model_validator(mode="after")
    def _geometry(self) -> PointerConfig:
        if self.end_diameter_m >= self.length_m:
            raise ValueError("end_diameter_m must be smaller than length_m")
        if self.rod_diameter_m > self.end_diameter_m:
            raise ValueError("rod_diameter_m must not exceed end_diameter_m")
        return self


# --------------------------------------------------------------------------- detector


class ColourThreshold(ConfigModel):
    """When a pixel counts as one end's colour (report eq. 10-11, made robust to white and grey)."""

    min_excess: int = Field(default=40, ge=1, le=255)
    """The colour's channel must exceed the larger of the other two channels by at least this much."""
    min_value: int = Field(default=60, ge=0, le=255)
    """And the colour's channel itself must be at least this bright."""


class DetectorConfig(ConfigModel):
    """Thresholds of the colour-end detector (trackerd/detect)."""

    red: ColourThreshold = ColourThreshold(min_excess=70)
    """Threshold for the red end. Skin reaches an excess of about 55 and muted reds on a
    projected slide about 50: the default keeps both out (docs/detection.md, tuning)."""
    blue: ColourThreshold = ColourThreshold(min_excess=60, min_value=60)
    """Threshold for the blue end."""
    min_area_px: float = Field(default=12.0, gt=0.0)
    """Smallest blob, in full-resolution pixels, accepted as an end."""
    max_area_px: float = Field(default=20000.0, gt=0.0)
    """Largest blob accepted as an end."""
    max_elongation: float = Field(default=3.0, ge=1.0)
    """A ball images as a near-circle; blobs longer than this times their width are rejected."""
    min_fill: float = Field(default=0.45, gt=0.0, le=1.0)
    """Blob area over its bounding-box area; a disc fills about 0.79, thin streaks much less."""
    search_step_px: int = Field(default=8, ge=2, le=64)
    """Spacing of the subsampled full-frame pass; an end smaller than about 1.5 times this across
    may be missed by a full search (a tracked end is followed smaller)."""
    track_window_px: int = Field(default=96, ge=8)
    """Half-size of the window searched first around the previous frame's position."""
    centroid: Literal["coverage", "weighted", "bbox"] = "coverage"
    """How an end's centre is measured. coverage: the centroid of every pixel's estimated coverage by
    the ball (on Bayer frames each pixel's own channel is used, so the rim is resolved at full
    resolution; the most accurate); weighted: coverage-weighted centroid of the end's own colour
    samples only (cheaper, about twice the error across the pointer on Bayer frames); bbox: the
    report's bounding-box midpoint (eq. 12)."""

    @model_validator(mode="after")
    def _area_range(self) -> DetectorConfig:
        if self.min_area_px >= self.max_area_px:
            raise ValueError("min_area_px must be smaller than max_area_px")
        return self


MIN_LEARNED_EXCESS = 10
"""The lowest threshold `trackerd calibrate pointer` learns (sensor noise reaches it on grey)."""


class LearnedColour(ConfigModel):
    """One end's colour as `trackerd calibrate pointer` measured it in this room (docs/calibration.md).

    Excesses are in grey levels of the detector's test (the colour's channel minus the larger of
    the other two; trackerd/detect/margin.py)."""

    min_excess: int = Field(ge=1, le=255)
    """The threshold learned for this end (replaces ``[detector.<colour>] min_excess`` unless the rig
    file gives that table)."""
    min_value: int = Field(ge=0, le=255)
    """The brightness threshold learned for this end."""
    ball_excess: int = Field(ge=-255, le=255)
    """What the end's paint reached: the 10th percentile of its core samples, over every camera and frame
    (the lowest camera's)."""
    background_excess: int = Field(ge=-255, le=255)
    """The highest excess anything else in view reached over a block of 2 x 2 samples (the highest
    camera's, in any frame). The daemon warns when what it sees comes closer to ``ball_excess``."""

    @model_validator(mode="after")
    def _finds_the_ball(self) -> LearnedColour:
        if self.min_excess > max(self.ball_excess, MIN_LEARNED_EXCESS):
            raise ValueError(
                f"min_excess {self.min_excess} is above the ball's own excess ({self.ball_excess}): this end"
                " would never pass the colour test"
            )
        return self

    @property
    def margin(self) -> int:
        """Ball over background, grey levels: above 0, a threshold between them finds only the ball."""
        return self.ball_excess - self.background_excess


class PointerColours(ConfigModel):
    """The pointer's colours learned in this room by `trackerd calibrate pointer`.

    Written into the calibration file; the detector's red and blue thresholds come from it unless
    the rig file sets ``[detector.red]`` or ``[detector.blue]``, which stay overrides."""

    learned: str
    """When they were learned (ISO 8601 local time)."""
    frames: int = Field(ge=1)
    """Frame pairs the figures come from."""
    red: LearnedColour
    """The red end."""
    blue: LearnedColour
    """The blue end."""

    def of(self, colour: str) -> LearnedColour:
        return self.red if colour == "red" else self.blue


# --------------------------------------------------------------------------- locator


class LocatorConfig(ConfigModel):
    """How detections become a pointer line and a wall hit (trackerd/locator.py)."""

    max_ray_gap_m: float = Field(default=0.03, gt=0.0)
    """Reject a fix when an end's rays miss its estimated centre by more than this
    (a wrong blob in one camera gives rays that do not meet)."""
    min_plane_angle_deg: float = Field(default=4.6, gt=0.0, lt=90.0)
    """Below this angle between the cameras' interpretation planes the pointer's line is
    taken through the two triangulated ends instead (docs/geometry.md)."""
    sphere_correction: bool = True
    """Correct each ball's image centroid for perspective (an imaged sphere's centre is not the
    projection of its centre) before estimating the line."""
    centroid_sigma_px: float = Field(default=0.05, gt=0.0)
    """Assumed standard deviation of a centroid across the pointer, used for the hit's uncertainty."""
    refine: Literal["auto", "always", "never"] = "auto"
    """When each end's outline is fitted and the pointer fitted to every camera at once
    (docs/geometry.md, "The pointer fit"): ``auto`` on every first sighting, whenever the detector's ends
    do not make a pointer or make a loose one (rays that miss by millimetres, a length off by a
    centimetre, ends that disagree beyond their errors), and when an end that has moved or changed its
    visible area is not found again by its outline; between those, tracked pairs take each centroid
    corrected by its ball's outline as last measured (docs/geometry.md, "Tracked ends"); ``always`` on
    every pair; ``never`` only the interpretation planes on the detector's centroids (the code before the
    fit)."""
    search_every_pairs: int = Field(default=6, ge=1, le=600)
    """While the pointer is not found, the search over every camera's candidates (tens of milliseconds,
    where a tracked pair takes one or two) runs on every this many-th pair, and less often the longer
    nothing is found (search_longest_pairs), so a room without the pointer does not keep a core busy; a first
    sighting after a reset is searched at once. So it does, the first
    included, while refined fixes follow each other with an end resting on one outline of a ball's size
    (trackerd/refine.py, RefinedPath.locate)."""
    search_longest_pairs: int = Field(default=192, ge=1, le=6000)
    """While nothing is found for long (eight searches in a row), the wait between searches doubles after each
    (search_every_pairs, twice that, four times...), up to this many pairs (about 3 s at 60 pairs a
    second): before a photo on the display a search takes 0.2-0.9 s for two 1080p cameras, and at a fixed
    cadence a room without the pointer would keep a core searching. The detectors look at every pair in full
    meanwhile, and a pointer they find is found at once. At most search_every_pairs: no doubling."""
    length_sigma_m: float = Field(default=0.003, gt=0.0)
    """How exactly the pointer's length (pointer.length_m) is known: the pointer fit holds the two
    ends this far apart, within this standard deviation."""
