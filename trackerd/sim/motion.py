"""Scripted pointer motions for the virtual rig: pure functions of time -> pointer pose (or None).

Each motion is periodic (``period_s``), so a rendered loop of one period repeats
seamlessly. Positions are built from the rig: the presenter stands in front of
the middle of the display at the middle of ``simulation.presenter_distance_m``,
the hand at the middle of ``simulation.hand_height_m`` above the floor, and the
pointer (``pointer.length_m`` between ball centres) is aimed at points of the
display. Except where a motion says otherwise, both balls stay inside every
camera's view of config/simulated.toml (tests/sim/test_motion.py checks it).

``sweep``    aims back and forth along the display's horizontal midline;
``figure8``  aims along a figure eight over the display;
``away``     points away from the wall (into the room), swinging side to side;
``leave``    aims at the display, is carried out of view to the right (None while
             gone), and comes back from the left;
``still``    holds one pose aimed at the upper left of the display.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.geometry.wall import WallFrame
from trackerd.sim.scene import PointerPose, pose_aimed_at, scene_pointer, scene_wall

Array = NDArray[np.float64]

MOTIONS = ("sweep", "figure8", "away", "leave", "still")
DEFAULT_PERIOD_S = 4.0


@dataclass(frozen=True)
class Stage:
    """Where the presenter stands and what they aim at: everything a motion needs from the rig."""

    wall: WallFrame
    length_m: float
    hand_m: Array
    """The presenter's hand (the pointer's front ball at rest), world metres."""

    @classmethod
    def from_rig(cls, rig: RigConfig) -> Stage:
        wall = wall_frame(scene_wall(rig))
        sim = rig.simulation
        distance = sum(sim.presenter_distance_m) / 2.0
        height = sum(sim.hand_height_m) / 2.0
        floor_y = float(wall.corners_m[:, 1].min()) - sim.display_height_above_floor_m
        hand = wall.origin_m + 0.5 * wall.width_m * wall.x_axis + distance * wall.normal
        hand = hand + (floor_y + height - hand[1]) * np.array([0.0, 1.0, 0.0])
        return cls(wall, scene_pointer(rig).length_m, hand)

    def on_wall(self, fx: float, fy: float) -> Array:
        """The wall point at fractions (fx, fy) of the display's width and height."""
        return self.wall.from_wall_m(np.array([fx * self.wall.width_m, fy * self.wall.height_m]))


@dataclass(frozen=True)
class Motion:
    """A named, periodic motion: call it with a time in seconds."""

    name: str
    period_s: float
    pose_at: Callable[[float], PointerPose | None]

    def __call__(self, time_s: float) -> PointerPose | None:
        return self.pose_at(time_s)


def _phase(time_s: float, period_s: float) -> float:
    """Position in the cycle, in [0, 1)."""
    return (time_s / period_s) % 1.0


def sweep(time_s: float, stage: Stage, period_s: float) -> PointerPose:
    """Aim moves along the display's midline from 10 % to 90 % of its width and back (cosine)."""
    fx = 0.5 - 0.4 * math.cos(2.0 * math.pi * _phase(time_s, period_s))
    return pose_aimed_at(stage.hand_m, stage.on_wall(fx, 0.5), stage.length_m)


def figure8(time_s: float, stage: Stage, period_s: float) -> PointerPose:
    """Aim traces a figure eight over the display; the hand sways a little with it."""
    angle = 2.0 * math.pi * _phase(time_s, period_s)
    fx = 0.5 + 0.4 * math.sin(angle)
    fy = 0.5 + 0.35 * math.sin(2.0 * angle)
    hand = stage.hand_m + stage.wall.x_axis * 0.15 * math.sin(angle)
    return pose_aimed_at(hand, stage.on_wall(fx, fy), stage.length_m)


def away(time_s: float, stage: Stage, period_s: float) -> PointerPose:
    """Points into the room (front ball farther from the wall than the back ball), swinging sideways."""
    angle = 0.6 * math.sin(2.0 * math.pi * _phase(time_s, period_s))
    normal, x_axis = stage.wall.normal, stage.wall.x_axis
    direction = math.cos(angle) * normal + math.sin(angle) * x_axis + 0.15 * np.array([0.0, 1.0, 0.0])
    direction = direction / np.linalg.norm(direction)
    back = stage.hand_m - 0.5 * stage.length_m * normal
    return PointerPose(back + stage.length_m * direction, back)


def leave(time_s: float, stage: Stage, period_s: float) -> PointerPose | None:
    """In view for 30 % of the cycle, carried out to the right, gone (None), back from the left."""
    phase = _phase(time_s, period_s)
    exit_m = stage.wall.width_m + 3.0  # from the middle of the display: well outside every view
    if phase < 0.3:
        offset = 0.0
    elif phase < 0.45:
        offset = exit_m * (phase - 0.3) / 0.15
    elif phase < 0.7:
        return None
    elif phase < 0.85:
        offset = -exit_m * (0.85 - phase) / 0.15
    else:
        offset = 0.0
    hand = stage.hand_m + offset * stage.wall.x_axis
    return pose_aimed_at(hand, stage.on_wall(0.5, 0.5) + offset * stage.wall.x_axis, stage.length_m)


def still(time_s: float, stage: Stage, period_s: float) -> PointerPose:
    """One pose, aimed at the upper left of the display."""
    return pose_aimed_at(stage.hand_m, stage.on_wall(0.3, 0.7), stage.length_m)


_FUNCTIONS = {"sweep": sweep, "figure8": figure8, "away": away, "leave": leave, "still": still}


def make_motion(name: str, rig: RigConfig, period_s: float = DEFAULT_PERIOD_S) -> Motion:
    """The motion called ``name`` (one of MOTIONS) for this rig; ValueError naming the choices."""
    function = _FUNCTIONS.get(name)
    if function is None:
        raise ValueError(f"unknown motion '{name}'; choose one of {', '.join(MOTIONS)}")
    if not period_s > 0:
        raise ValueError("period_s must be positive")
    stage = Stage.from_rig(rig)
    return Motion(name, period_s, partial(function, stage=stage, period_s=period_s))
