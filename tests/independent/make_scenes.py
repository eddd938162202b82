"""Draw a room, a rig and pointer poses from a seed, render them with tests/independent/room.py and write test files.

    python -m tests.independent.make_scenes --out DIR --poses N --seed S [--format png|bayer] [--scale F]

writes DIR/rig.toml (one room, one pointer, its cameras) and per pose NN-cam0.png (or .npy), NN-cam1..., NN-truth.json
in the format `trackerd locate --truth` reads. The distributions are meant to be wide and honest (what real rooms,
lenses, lamps and presenters do), not shaped by what trackerd finds easy or hard.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tests.independent.room import (
    Array,
    Box,
    Camera,
    Cylinder,
    Decal,
    Ellipsoid,
    Light,
    Material,
    Room,
    Scene,
    Sensor,
    Surface,
    Thing,
    disc_area_outside,
    expose,
    monotonic_radius,
    project,
    ray_grids,
    render,
    undistort,
)

Rng = np.random.Generator
FULL_W, FULL_H = 1920, 1200
# Hue ranges (degrees) of the colours that look most like the pointer's: reds, magentas, oranges, purples, blues.
HARD_HUES = ((345.0, 372.0), (290.0, 335.0), (12.0, 40.0), (258.0, 292.0), (205.0, 250.0))
# Black-body colours (sRGB, 8 bit) by temperature: lamps from warm to cold, and the display's white point.
KELVIN = np.array([2500, 3000, 4000, 5000, 6000, 6500, 7000, 8000], dtype=float)
KELVIN_SRGB = np.array(
    [
        [255, 159, 70],
        [255, 180, 107],
        [255, 209, 163],
        [255, 228, 206],
        [255, 243, 239],
        [255, 249, 253],
        [245, 243, 255],
        [227, 233, 255],
    ],
    dtype=float,
)


def linear(srgb: Array) -> Array:
    """sRGB to linear light: pictures and paints are specified as they look, light adds up linearly."""
    c = np.asarray(srgb, dtype=float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def hsv(h_deg: float, s: float, v: float) -> Array:
    h = (h_deg % 360.0) / 60.0
    c = v * s
    x = c * (1 - abs(h % 2 - 1))
    rgb = [(c, x, 0), (x, c, 0), (0, c, x), (0, x, c), (x, 0, c), (c, 0, x)][int(h) % 6]
    return np.array(rgb) + (v - c)


def blackbody(kelvin: float) -> Array:
    """Linear RGB of a black body, green = 1."""
    rgb = linear(np.array([np.interp(kelvin, KELVIN, KELVIN_SRGB[:, i]) for i in range(3)]) / 255)
    out: Array = rgb / rgb[1]
    return out


def colour(rng: Rng, hard: float = 0.6, hues: tuple[float, float] | None = None) -> Array:
    """An sRGB colour; with probability `hard` a saturated red, magenta, orange, purple or blue."""
    if hues is not None or rng.random() < hard:
        lo, hi = hues or HARD_HUES[rng.integers(len(HARD_HUES))]
        return hsv(rng.uniform(lo, hi), rng.uniform(0.65, 1.0), rng.uniform(0.45, 1.0))
    return hsv(rng.uniform(0, 360), rng.uniform(0, 1) ** 0.5, rng.uniform(0.15, 1.0))


# ------------------------------------------------------------------------------------------------ pictures


def picture(rng: Rng, w: int, h: int, dark: bool = False, hues: tuple[float, float] | None = None) -> Array:
    """A colourful sRGB picture: a smooth gradient under blocks, discs, stripes and soft blobs."""
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    ang = rng.uniform(0, 2 * np.pi)
    ramp = xx * np.cos(ang) + yy * np.sin(ang)
    ramp = (ramp - ramp.min()) / (np.ptp(ramp) + 1e-9)
    c0, c1 = colour(rng, hues=hues), colour(rng, hues=hues)
    if dark:
        c0, c1 = c0 * 0.12, c1 * 0.3
    img = c0 + (c1 - c0) * ramp[..., None]
    for _ in range(rng.integers(2, 15)):
        c = colour(rng, hues=hues)
        x0, y0 = int(rng.integers(0, w)), int(rng.integers(0, h))
        bw, bh = int(rng.integers(h // 8 + 1, max(h // 8 + 2, w // 3))), int(rng.integers(h // 8 + 1, h + 1))
        box = (slice(y0, y0 + bh), slice(x0, x0 + bw))
        kind = rng.integers(4)
        if kind == 0:
            img[box] = c
            continue
        by, bx = yy[box] - y0 - bh / 2, xx[box] - x0 - bw / 2
        if kind == 1:  # disc
            img[box][by**2 + bx**2 < (min(bw, bh) / 2) ** 2] = c
        elif kind == 2:  # stripes
            a = rng.uniform(0, np.pi)
            period = rng.uniform(3, max(4.0, h / 3))
            img[box][((bx * np.cos(a) + by * np.sin(a)) / period) % 1 < rng.uniform(0.3, 0.7)] = c
        else:  # soft blob
            alpha = np.exp(-(bx**2 / (bw / 3) ** 2 + by**2 / (bh / 3) ** 2))[..., None]
            img[box] = img[box] * (1 - alpha) + c * alpha
    out: Array = np.clip(img, 0, 1)
    return out


def slide(rng: Rng, w: int, h: int) -> Array:
    """An sRGB slide: dark or red lines of word-like bars on white, maybe a title bar and a picture."""
    img = np.ones((h, w, 3)) * rng.uniform(0.85, 1.0) * (1 + rng.normal(0, 0.02, 3))
    line = h * rng.uniform(0.04, 0.1)
    top = 0.08 * h
    if rng.random() < 0.5:
        bar = [hsv(rng.uniform(-10, 10), 0.9, 0.8), hsv(rng.uniform(210, 240), 0.9, 0.6), np.full(3, 0.15)]
        img[: int(h * rng.uniform(0.12, 0.22))] = bar[rng.integers(3)]
        top = 0.28 * h
    if rng.random() < 0.4:
        x0, y0 = int(w * rng.uniform(0.55, 0.75)), int(top)
        pw, ph = int(w * rng.uniform(0.15, 0.25)), int(h * rng.uniform(0.3, 0.6))
        img[y0 : y0 + ph, x0 : x0 + pw] = picture(rng, pw, ph)[: h - y0, : w - x0]
        right = x0 - line
    else:
        right = w * rng.uniform(0.6, 0.95)
    y = top
    while y + line < 0.95 * h:
        red = rng.random() < 0.25
        ink = hsv(rng.uniform(-10, 10), rng.uniform(0.8, 1), rng.uniform(0.6, 0.9)) if red else np.full(3, 0.1)
        x = 0.06 * w + (line * 2 if rng.random() < 0.5 else 0)
        end = right * rng.uniform(0.5, 1.0)
        while x < end:
            word = line * rng.uniform(1.2, 6.0)
            img[int(y) : int(y + 0.6 * line), int(x) : int(min(x + word, end))] = ink
            x += word + 0.5 * line
        y += line * rng.uniform(1.4, 2.0)
    return img


def display_content(rng: Rng, w: int, h: int) -> tuple[str, Array]:
    kind = str(rng.choice(["pictures", "slide", "dark"], p=[0.55, 0.3, 0.15]))
    img = slide(rng, w, h) if kind == "slide" else picture(rng, w, h, dark=kind == "dark")
    return kind, linear(img)


# ------------------------------------------------------------------------------------------------ the room


@dataclass(frozen=True)
class Presenter:
    skin: Array
    clothing: Array
    height: float
    body_radius: float
    arm_radius: float
    hand_axes: tuple[float, float, float]  # along the rod, below it, sideways
    handed: int  # +1: the pointer in the right hand (+x, facing the wall)


@dataclass(frozen=True)
class Pointer:
    length: float
    ball_d: float
    rod_d: float
    red: Material
    blue: Material
    rod: Material


@dataclass(frozen=True)
class RoomDraw:
    room: Room
    furniture: tuple[Thing, ...]
    presenter: Presenter
    pointer: Pointer
    cameras: tuple[Camera, ...]
    lens: tuple[tuple[float, float], ...]  # vignetting, lens blur (px), per camera
    gamma: float
    info: dict[str, object]


def surface(rng: Rng, col: Array, amplitude: float, period: tuple[float, float], seams: float = 0.0) -> Surface:
    """A face whose noise has two octaves: blotches eight cells wide (smoothed by wrapped box filters) plus grain."""
    coarse = np.kron(rng.uniform(-1, 1, (8, 8)), np.ones((8, 8)))
    for axis in (0, 1, 0, 1):
        coarse = np.mean([np.roll(coarse, k, axis=axis) for k in range(-4, 4)], axis=0)
    return Surface(linear(col), coarse + 0.5 * rng.uniform(-1, 1, (64, 64)), amplitude, period, seams)


def draw_surfaces(rng: Rng) -> tuple[tuple[Surface, ...], dict[str, object]]:
    wall = hsv(rng.uniform(25, 55), rng.uniform(0, 0.25), rng.uniform(0.45, 0.9))
    dark_front = rng.random() < 0.35
    front = hsv(rng.uniform(0, 360), rng.uniform(0, 0.1), rng.uniform(0.08, 0.3)) if dark_front else wall
    wood = rng.random() < 0.5
    if wood:
        floor = surface(
            rng, hsv(rng.uniform(22, 38), rng.uniform(0.35, 0.6), rng.uniform(0.3, 0.65)), 0.25, (0.75, 0.02)
        )
    else:
        carpet = hsv(rng.uniform(0, 360), rng.uniform(0, 0.3), rng.uniform(0.15, 0.5))
        floor = surface(rng, carpet, 0.2, (0.015, 0.015))
    ceiling = surface(rng, hsv(40, rng.uniform(0, 0.05), rng.uniform(0.75, 0.92)), 0.04, (0.15, 0.15), 0.6)
    walls = [surface(rng, front, rng.uniform(0.02, 0.1), (0.25, 0.25))]
    walls += [surface(rng, wall * rng.uniform(0.92, 1.05), rng.uniform(0.02, 0.1), (0.25, 0.25)) for _ in range(3)]
    return (*walls, floor, ceiling), {"dark_front_wall": dark_front, "floor": "wood" if wood else "carpet"}


def draw_decals(rng: Rng, lo: Array, hi: Array, display: tuple[float, float]) -> tuple[list[Decal], list[str]]:
    """Door, posters (often blue or red), a whiteboard, a rug: static distractors around the room."""
    decals, names = [], []
    floor = lo[1]
    if rng.random() < 0.6:
        x = rng.uniform(lo[0] + 0.3, hi[0] - 1.2)
        tex = linear(hsv(rng.uniform(20, 40), rng.uniform(0, 0.6), rng.uniform(0.2, 0.8)))[None, None]
        decals.append(Decal(1, (x, floor, x + 0.9, floor + 2.05), tex))
        names.append("door")
    for _ in range(rng.integers(0, 4)):
        family = [HARD_HUES[4], HARD_HUES[0], None][rng.choice(3, p=[0.4, 0.2, 0.4])]
        w, h = rng.uniform(0.5, 1.2), rng.uniform(0.6, 1.0)
        face = int(rng.choice([0, 1, 2, 3]))
        v0 = floor + rng.uniform(1.0, 1.5)
        if face == 0:  # beside the display, if there is room
            if display[0] + 0.3 + w < hi[0] - 0.1 and rng.random() < 0.5:
                u0 = rng.uniform(display[0] + 0.3, hi[0] - 0.1 - w)
            elif lo[0] + 0.1 < -0.3 - w:
                u0 = rng.uniform(lo[0] + 0.1, -0.3 - w)
            else:
                continue
        else:
            u0 = rng.uniform(lo[0] + 0.1, hi[0] - 0.1 - w) if face == 1 else rng.uniform(0.3, hi[2] - 0.3 - w)
        decals.append(Decal(face, (u0, v0, u0 + w, v0 + h), linear(picture(rng, 64, 80, hues=family))))
        names.append("poster-" + ("blue" if family == HARD_HUES[4] else "red" if family == HARD_HUES[0] else "any"))
    if rng.random() < 0.3:
        z = rng.uniform(0.5, hi[2] - 2.0)
        decals.append(
            Decal(int(rng.integers(2, 4)), (z, floor + 0.9, z + 1.5, floor + 2.0), linear(slide(rng, 120, 88)))
        )
        names.append("whiteboard")
    if rng.random() < 0.25:
        x, z = rng.uniform(lo[0], hi[0] - 2), rng.uniform(0.3, hi[2] - 2)
        decals.append(Decal(4, (x, z, x + 2.0, z + 1.4), linear(picture(rng, 64, 48) * 0.6)))
        names.append("rug")
    return decals, names


def draw_furniture(rng: Rng, lo: Array, hi: Array, width: float) -> tuple[list[Thing], list[str]]:
    """A chair (often red), a table, a fire extinguisher: away from where the presenter stands."""
    things: list[Thing] = []
    names: list[str] = []
    spots: list[Array] = []

    def spot() -> Array | None:
        for _ in range(50):
            p = np.array([rng.uniform(lo[0] + 0.5, hi[0] - 0.5), rng.uniform(0.5, hi[2] - 0.6)])
            away = p[0] < -0.3 or p[0] > width + 0.3 or p[1] > 3.6
            if away and all(np.linalg.norm(p - q) > 1.2 for q in spots):
                spots.append(p)
                return p
        return None

    f = lo[1]
    if rng.random() < 0.6 and (p := spot()) is not None:
        red = rng.random() < 0.5
        col = hsv(rng.uniform(-10, 10), 0.85, rng.uniform(0.5, 0.85)) if red else colour(rng, hard=0.3) * 0.6
        mat = Material(linear(col), 0.1, 15)
        x, z = p
        side = int(rng.integers(4))
        back_off = [(0, 0.2), (0, -0.2), (0.2, 0), (-0.2, 0)][side]
        boxes = [Box(np.array([x - 0.22, f + 0.42, z - 0.22]), np.array([x + 0.22, f + 0.47, z + 0.22]))]
        bx, bz = x + back_off[0], z + back_off[1]
        half = (0.02, 0.22) if side < 2 else (0.22, 0.02)
        boxes.append(
            Box(np.array([bx - half[1], f + 0.47, bz - half[0]]), np.array([bx + half[1], f + 0.9, bz + half[0]]))
        )
        for sx in (-0.19, 0.19):
            for sz in (-0.19, 0.19):
                boxes.append(
                    Box(
                        np.array([x + sx - 0.015, f, z + sz - 0.015]),
                        np.array([x + sx + 0.015, f + 0.42, z + sz + 0.015]),
                    )
                )
        things += [Thing(f"chair{i}", b, mat, "chair") for i, b in enumerate(boxes)]
        names.append("red chair" if red else "chair")
    if rng.random() < 0.4 and (p := spot()) is not None:
        mat = Material(linear(hsv(rng.uniform(20, 40), rng.uniform(0, 0.5), rng.uniform(0.3, 0.9))), 0.05, 10)
        x, z = p
        hw, hd, top = rng.uniform(0.6, 0.8), rng.uniform(0.3, 0.4), f + rng.uniform(0.72, 0.76)
        boxes = [Box(np.array([x - hw, top - 0.03, z - hd]), np.array([x + hw, top, z + hd]))]
        boxes += [
            Box(np.array([x + s - 0.02, f, z - hd + 0.05]), np.array([x + s + 0.02, top - 0.03, z + hd - 0.05]))
            for s in (-hw + 0.1, hw - 0.14)
        ]
        things += [Thing(f"table{i}", b, mat, "table") for i, b in enumerate(boxes)]
        names.append("table")
    if rng.random() < 0.3:
        x = lo[0] + 0.1 if rng.random() < 0.5 else hi[0] - 0.1
        z, y0 = rng.uniform(0.5, hi[2] - 0.5), f + rng.uniform(0.1, 0.8)
        mat = Material(linear(hsv(rng.uniform(-5, 8), 0.9, rng.uniform(0.55, 0.85))), 0.4, 60, 0.05)
        a, b = np.array([x, y0, z]), np.array([x, y0 + 0.4, z])
        things += [Thing("ext0", Cylinder(a, b, 0.075), mat, "ext")]
        things += [Thing(f"ext{i + 1}", Ellipsoid(e, 0.075 * np.eye(3)), mat, "ext") for i, e in enumerate((a, b))]
        names.append("fire extinguisher")
    return things, names


def look_at(centre: Array, target: Array, roll_deg: float) -> tuple[Array, Array]:
    """OpenCV rotation and translation of a camera at centre looking at target, level apart from the roll."""
    f = (target - centre) / np.linalg.norm(target - centre)
    right = np.cross(f, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(f, right)
    c, s = np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg))
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([right, down, f])
    return rot, -rot @ centre


def draw_lens(rng: Rng, fx: float, cx: float, cy: float) -> tuple[float, float, float, float, float] | None:
    """OpenCV distortion of noticeable size; None if it folds over before the image's corners."""
    k = (
        rng.uniform(-0.25, 0.05),
        rng.uniform(-0.05, 0.15),
        rng.normal(0, 7e-4),
        rng.normal(0, 7e-4),
        rng.uniform(-0.03, 0.03),
    )
    corners = np.array([[-0.5, -0.5], [FULL_W - 0.5, -0.5], [-0.5, FULL_H - 0.5], [FULL_W - 0.5, FULL_H - 0.5]])
    x, y, res = undistort((corners[:, 0] - cx) / fx, (corners[:, 1] - cy) / fx, k, 30)
    if not (res < 1e-12).all() or np.hypot(x, y).max() * 1.15 > monotonic_radius(k):
        return None
    return k


def draw_camera(
    rng: Rng,
    cid: str,
    kind: str,
    lo: Array,
    hi: Array,
    display: tuple[float, float],
    trial: Array,
    others: list[Camera],
) -> Camera:
    """A camera of the given placement that sees the display's centre and most trial pointer ends (rejection)."""
    floor, ceil, depth = lo[1], hi[1], hi[2]
    centre_disp = np.array([display[0] / 2, display[1] / 2, 0.0])
    work = np.array([display[0] / 2, floor + 1.35, 1.6])
    for _ in range(2000):
        if kind == "back_high":
            spot = [
                rng.uniform(lo[0] + 0.2, hi[0] - 0.2),
                ceil - rng.uniform(0.1, 0.6),
                rng.uniform(max(3.6, depth - 2.5), depth - 0.15),
            ]
        elif kind in ("side_left", "side_right"):
            x = lo[0] + rng.uniform(0.1, 0.5) if kind == "side_left" else hi[0] - rng.uniform(0.1, 0.5)
            spot = [x, floor + rng.uniform(1.0, ceil - floor - 0.1), rng.uniform(0.8, min(5.0, depth - 0.2))]
        else:  # low
            spot = [
                rng.uniform(lo[0] + 0.2, hi[0] - 0.2),
                floor + rng.uniform(0.25, 0.9),
                rng.uniform(1.5, depth - 0.2),
            ]
        pos = np.array(spot)
        if any(np.linalg.norm(pos - o.centre) < 0.5 for o in others):
            continue
        target = centre_disp + np.array([rng.normal(0, display[0] / 6), rng.normal(0, display[1] / 4), 0])
        w = rng.uniform(0, 0.6)
        rot, tvec = look_at(pos, (1 - w) * target + w * work, rng.normal(0, 2))
        fx = (FULL_W / 2) / np.tan(np.radians(rng.uniform(45, 90)) / 2)
        cx, cy = (FULL_W - 1) / 2 + rng.normal(0, 12), (FULL_H - 1) / 2 + rng.normal(0, 10)
        lens = draw_lens(rng, fx, cx, cy)
        if lens is None:
            continue
        cam = Camera(cid, FULL_W, FULL_H, fx, fx * (1 + rng.normal(0, 0.003)), cx, cy, lens, rot, tvec)
        px, z = project(cam, np.vstack([centre_disp, trial]))
        inside = (z > 0.3) & (px[:, 0] > 10) & (px[:, 0] < FULL_W - 10) & (px[:, 1] > 10) & (px[:, 1] < FULL_H - 10)
        if inside[0] and inside[1:].mean() >= 0.8:
            return cam
    raise RuntimeError(f"no {kind} placement of {cid} sees the pointer in this room")


def draw_room(rng: Rng) -> RoomDraw:
    if rng.random() < 0.5:
        display = (3.6576, 0.9144)
    else:
        w = rng.uniform(1.8, 4.2)
        display = (w, w / rng.uniform(1.6, 4.0))
    below = rng.uniform(0.6, 1.2)
    tall = max(rng.uniform(2.5, 3.6), below + display[1] + 0.25)
    lo = np.array([-rng.uniform(0.4, 2.5), -below, 0.0])
    hi = np.array([display[0] + rng.uniform(0.4, 2.5), tall - below, rng.uniform(4.5, 9.0)])
    surfaces, surf_info = draw_surfaces(rng)
    decals, decal_names = draw_decals(rng, lo, hi, display)
    room = Room(lo, hi, surfaces, tuple(decals), display, rng.uniform(0.0, 0.04))
    furniture, furniture_names = draw_furniture(rng, lo, hi, display[0])

    t = rng.uniform(0, 1)
    skin = (1 - t) * np.array([0.62, 0.42, 0.33]) + t * np.array([0.11, 0.065, 0.045])
    dark = rng.random() < 0.5
    cloth = (
        hsv(rng.uniform(0, 360), rng.uniform(0, 0.3), rng.uniform(0.05, 0.2)) if dark else colour(rng, hard=0.4) * 0.8
    )
    presenter = Presenter(
        skin,
        linear(cloth),
        rng.uniform(1.55, 1.95),
        rng.uniform(0.16, 0.23),
        rng.uniform(0.035, 0.045),
        (rng.uniform(0.045, 0.055), rng.uniform(0.035, 0.045), rng.uniform(0.04, 0.05)),
        1 if rng.random() < 0.85 else -1,
    )
    red_hsv = (rng.uniform(-12, 18), rng.uniform(0.75, 1.0), rng.uniform(0.45, 1.0))
    blue_hsv = (rng.uniform(215, 245), rng.uniform(0.6, 1.0), rng.uniform(0.2, 0.9))
    glossy = rng.random() < 0.5
    if glossy:
        shine = (rng.uniform(0.15, 0.6), rng.uniform(20, 150), rng.uniform(0.03, 0.12))
    else:
        shine = (rng.uniform(0.0, 0.04), 5.0, 0.0)
    grey = rng.uniform(0.03, 0.15)
    pointer = Pointer(
        rng.uniform(0.35, 0.50),
        rng.uniform(0.025, 0.045),
        rng.uniform(0.008, 0.014),
        Material(linear(hsv(*red_hsv)) * 0.9, *shine),
        Material(linear(hsv(*blue_hsv)) * 0.9, *shine),
        Material(np.full(3, grey), rng.uniform(0, 0.3), 30.0),
    )
    rd = RoomDraw(room, tuple(furniture), presenter, pointer, (), (), 1.0, {})
    trial_rng = np.random.default_rng(rng.integers(1 << 32))
    holds = [draw_geometry(trial_rng, rd, ()) for _ in range(60)]
    trial = np.array([end for h in holds for end in (h.front, h.back)])

    placement = str(rng.choice(["back_high", "sides", "low", "mixed"], p=[0.3, 0.3, 0.15, 0.25]))
    count = 3 if rng.random() < 0.25 else 2
    kinds_any = ["back_high", "side_left", "side_right", "low"]
    kinds = {
        "back_high": ["back_high"] * 3,
        "low": ["low"] * 3,
        "sides": ["side_left", "side_right", str(rng.choice(kinds_any))],
    }
    chosen = kinds.get(placement, [str(rng.choice(kinds_any)) for _ in range(3)])[:count]
    cams: list[Camera] = []
    for i, kind in enumerate(chosen):
        cams.append(draw_camera(rng, f"cam{i}", kind, lo, hi, display, trial, cams))
    lens = tuple((rng.uniform(0, 0.35), rng.uniform(0, 0.8)) for _ in cams)
    gamma = 1.0 if rng.random() < 0.7 else rng.uniform(0.45, 0.8)
    info: dict[str, object] = {
        "placement": placement,
        "camera_kinds": chosen,
        "room_m": [float(v) for v in hi - lo],
        "display_m": list(display),
        "surfaces": surf_info,
        "decals": decal_names,
        "furniture": furniture_names,
        "pointer": {
            "length_m": pointer.length,
            "ball_diameter_m": pointer.ball_d,
            "rod_diameter_m": pointer.rod_d,
            "red_hsv": red_hsv,
            "blue_hsv": blue_hsv,
            "glossy": glossy,
            "rod_grey": grey,
        },
        "presenter": {"skin_dark_share": t, "dark_clothing": dark, "handed": presenter.handed},
        "gamma": gamma,
        "vignetting_blur_px": lens,
    }
    return RoomDraw(room, tuple(furniture), presenter, pointer, tuple(cams), lens, gamma, info)


# ------------------------------------------------------------------------------------------------ poses


@dataclass(frozen=True)
class Holding:
    """Where the presenter stands and how the pointer is held."""

    front: Array
    back: Array
    hand: Ellipsoid
    shoulder: Array
    elbow: Array
    wrist: Array
    body_xz: Array
    info: dict[str, object]


@dataclass(frozen=True)
class Pose:
    hold: Holding
    motion: tuple[Array, Array]  # displacement of the back and the front ball over the exposure
    times: Array  # moment (-0.5 .. 0.5 of the exposure) of each sub-pixel sample
    lights: tuple[Light, ...]
    ambient: Array
    display: Array
    white_balance: Array
    noise: tuple[float, float]  # read noise (grey levels), shot noise (grey levels per sqrt grey level)
    info: dict[str, object]


def _segment_gap(p: Array, a: Array, b: Array) -> float:
    ab = b - a
    s = np.clip((p - a) @ ab / (ab @ ab), 0, 1)
    return float(np.linalg.norm(p - a - s * ab))


def draw_geometry(rng: Rng, rd: RoomDraw, cameras: tuple[Camera, ...]) -> Holding:
    """A presenter 1.2-3 m from the wall holding the pointer by its back end, aiming mostly at the display.

    The arm is two segments: the elbow is placed by the usual two-bone solution, bending down and outwards, so the
    forearm reaches the wrist from below and behind as it does when a stick is held out. Poses in which a ball would
    sit inside the arm or the body, or that the arm cannot reach, are drawn again.
    """
    lo, hi = rd.room.lo, rd.room.hi
    width, height = rd.room.display_m
    pr, pt = rd.presenter, rd.pointer
    r = pt.ball_d / 2
    along, below, side = pr.hand_axes
    upper, fore = 0.30 * pr.height / 1.75, 0.27 * pr.height / 1.75
    for _ in range(10000):
        if rng.random() < 0.85:
            aim = np.array([rng.uniform(0, width), rng.uniform(0, height), 0.0])
        else:
            aim = np.array([rng.uniform(-0.6, width + 0.6), rng.uniform(-0.5, height + 0.5), 0.0])
        body = np.array([np.clip(aim[0] + rng.normal(0, 0.9), lo[0] + 0.4, hi[0] - 0.4), rng.uniform(1.2, 3.0)])
        hand_h = rng.uniform(0.95, min(1.75, 0.82 * pr.height + 0.25))
        grip = np.array(
            [body[0] + pr.handed * rng.uniform(0.12, 0.4), lo[1] + hand_h, body[1] - rng.uniform(0.25, 0.6)]
        )
        d = (aim - grip) / np.linalg.norm(aim - grip)
        down = np.array([0.0, -1.0, 0.0]) + d[1] * d  # straight down, made perpendicular to the rod
        down /= np.linalg.norm(down)
        across = np.cross(d, down)
        hand = Ellipsoid(
            grip + down * rng.uniform(0.005, 0.02), np.column_stack([d * along, down * below, across * side])
        )
        back = grip - d * (r + along + rng.uniform(0.0, 0.03))
        front = back + d * pt.length
        wrist = hand.centre + down * (below + 0.015) - d * along * 0.6
        shoulder = np.array([body[0] + pr.handed * 0.9 * pr.body_radius, lo[1] + 0.82 * pr.height, body[1]])
        reach = float(np.linalg.norm(wrist - shoulder))
        if not abs(upper - fore) + 0.05 < reach < upper + fore:
            continue
        u = (wrist - shoulder) / reach
        a = (upper**2 - fore**2 + reach**2) / (2 * reach)
        pole = np.array([pr.handed * 0.5, -1.0, 0.0])
        pole -= (pole @ u) * u
        elbow = shoulder + a * u + np.sqrt(upper**2 - a**2) * pole / np.linalg.norm(pole)
        ok = (
            min(_segment_gap(back, shoulder, elbow), _segment_gap(back, elbow, wrist)) > r + pr.arm_radius
            and np.hypot(*(back[[0, 2]] - body)) > pr.body_radius + r + 0.02
            and np.hypot(*(hand.centre[[0, 2]] - body)) > pr.body_radius + along
            and np.hypot(*(elbow[[0, 2]] - body)) > pr.body_radius
            and front[2] > r + 0.05
            and all(np.hypot(*(c.centre[[0, 2]] - body)) > pr.body_radius + 0.25 for c in cameras)
            and all(min(np.linalg.norm(c.centre - e) for e in (front, back, grip, elbow)) > 0.3 for c in cameras)
        )
        if ok:
            info = {
                "aim_m": aim[:2].tolist(),
                "presenter_distance_m": float(body[1]),
                "hand_height_m": float(hand_h),
                "pointer_elevation_deg": float(np.degrees(np.arcsin(d[1]))),
            }
            return Holding(front, back, hand, shoulder, elbow, wrist, body, info)
    raise RuntimeError("no presenter pose fits this room")


# The white card's grey level: as drawn (a camera left at any exposure) or as an operator sets it
# (the card near the top of the range, as a camera's auto-exposure or a person at the console would).
CARD_GREY = {"drawn": (35.0, 230.0), "set": (140.0, 230.0)}


def draw_pose(rng: Rng, rd: RoomDraw, samples: int, exposure: str = "drawn") -> Pose:
    hold = draw_geometry(rng, rd, rd.cameras)
    lo, hi = rd.room.lo, rd.room.hi
    width, height = rd.room.display_m
    blur = rng.random() < 0.35
    db = rng.normal(size=3) * rng.uniform(0, 0.006) / np.sqrt(3) if blur else np.zeros(3)
    df = db + (rng.normal(size=3) * rng.uniform(0, 0.012) / np.sqrt(3) if blur else 0)
    times = (rng.permutation(samples**2) + 0.5) / samples**2 - 0.5 if blur else np.zeros(samples**2)

    kelvin = rng.uniform(2700, 7000)
    lamps = []
    for _ in range(1 + int(rng.random() < 0.5)):
        pos = np.array(
            [rng.uniform(lo[0] + 0.3, hi[0] - 0.3), hi[1] - rng.uniform(0.02, 0.4), rng.uniform(0.3, hi[2] - 0.3)]
        )
        lamps.append(
            (pos, np.exp(rng.uniform(np.log(0.3), 0)), rng.uniform(0, 3), blackbody(kelvin + rng.normal(0, 250)))
        )
    ambient_share = rng.uniform(0.05, 0.5)
    drawn = rng.uniform(np.log(35), np.log(230))  # the same draw whatever the exposure: the rest stays the pose's
    if exposure != "drawn":  # the same quantile of the operator's range
        lo_grey, hi_grey = CARD_GREY[exposure]
        drawn = np.log(lo_grey) + (drawn - np.log(35)) * np.log(hi_grey / lo_grey) / np.log(230 / 35)
    white = float(np.exp(drawn))
    card = np.array([width / 2, lo[1] + 1.3, 1.8])  # a white card at the presenter's hand, facing each lamp
    reach = sum(
        w * np.clip((p - card)[1] / np.linalg.norm(p - card), 0, 1) ** m / np.sum((p - card) ** 2)
        for p, w, m, _ in lamps
    )
    scale = white * (1 - ambient_share) / reach
    lights = tuple(Light(p, c * w * scale, m) for p, w, m, c in lamps)
    ambient = blackbody(kelvin) * white * ambient_share
    screen = float(np.exp(rng.uniform(np.log(50), np.log(330))))
    tw = 1536
    kind, content = display_content(rng, tw, max(96, round(tw * height / width)))
    display = content * screen * blackbody(rng.uniform(5500, 7500))
    alpha = rng.uniform(0, 1)
    noise = (rng.uniform(0.5, 3.0), rng.uniform(0.1, 0.35))
    info = hold.info | {
        "motion_blur_mm": [float(np.linalg.norm(db) * 1e3), float(np.linalg.norm(df) * 1e3)],
        "lamps": len(lamps),
        "colour_temperature_k": kelvin,
        "white_card_grey": white,
        "ambient_share": ambient_share,
        "display_white_grey": screen,
        "display_content": kind,
        "white_balance_alpha": alpha,
        "read_noise": noise[0],
        "shot_noise": noise[1],
    }
    wb = blackbody(kelvin) ** -alpha  # the camera's white balance corrects a share alpha of the lamps' cast
    return Pose(hold, (db, df), times, lights, ambient, display, wb, noise, info)


def scene_at(rd: RoomDraw, pose: Pose, s: float) -> Scene:
    """The scene at moment s of the exposure: the pointer, hand and forearm moved by s times their motion."""
    pr, pt = rd.presenter, rd.pointer
    db, df = pose.motion
    hold = pose.hold
    back = hold.back + s * db
    d = hold.front + s * df - back
    front = back + d / np.linalg.norm(d) * pt.length
    hand = Ellipsoid(hold.hand.centre + s * db, hold.hand.axes)
    wrist = hold.wrist + s * db
    bx, bz = hold.body_xz
    f = rd.room.lo[1]
    top = f + 0.82 * pr.height - 0.5 * pr.body_radius
    head_r = 0.105
    skin = Material(pr.skin, 0.05, 10)
    cloth = Material(pr.clothing, 0.02, 5)
    ball = np.eye(3) * pt.ball_d / 2
    things = (
        Thing("red", Ellipsoid(front, ball), pt.red, "pointer"),
        Thing("blue", Ellipsoid(back, ball), pt.blue, "pointer"),
        Thing("rod", Cylinder(back, front, pt.rod_d / 2), pt.rod, "pointer"),
        Thing("hand", hand, skin, "pointer"),
        Thing("upper arm", Cylinder(hold.shoulder, hold.elbow, pr.arm_radius), cloth, "person"),
        Thing("forearm", Cylinder(hold.elbow, wrist, pr.arm_radius), cloth, "person"),
        Thing("shoulder", Ellipsoid(hold.shoulder, np.eye(3) * pr.arm_radius), cloth, "person"),
        Thing("elbow", Ellipsoid(hold.elbow, np.eye(3) * pr.arm_radius), cloth, "person"),
        Thing("wrist", Ellipsoid(wrist, np.eye(3) * pr.arm_radius), skin, "person"),
        Thing("body", Cylinder(np.array([bx, f + 0.25, bz]), np.array([bx, top, bz]), pr.body_radius), cloth, "person"),
        Thing("hips", Ellipsoid(np.array([bx, f + 0.25, bz]), np.eye(3) * pr.body_radius), cloth, "person"),
        Thing("chest", Ellipsoid(np.array([bx, top, bz]), np.eye(3) * pr.body_radius), cloth, "person"),
        Thing("head", Ellipsoid(np.array([bx, f + pr.height - head_r, bz]), np.eye(3) * head_r), skin, "person"),
    )
    return Scene(rd.room, things + rd.furniture, pose.lights, pose.ambient, pose.display)


# ------------------------------------------------------------------------------------------------ files


def num(x: float) -> str:
    return repr(float(x))


def rig_toml(rd: RoomDraw, cams: list[Camera], fmt: str, seed: int) -> str:
    width, height = rd.room.display_m
    pt = rd.pointer
    out = [
        f"# An independent test room (tests/independent/make_scenes.py), seed {seed}.",
        "",
        "version = 1",
        f'name = "independent-{seed}"',
        "",
    ]
    for cam in cams:
        rot = ", ".join("[" + ", ".join(num(v) for v in row) + "]" for row in cam.rotation)
        out += [
            "[[cameras]]",
            f'id = "{cam.id}"',
            f"width_px = {cam.width}",
            f"height_px = {cam.height}",
            f'pixel_format = "{"RGB8" if fmt == "png" else "BayerRG8"}"',
            f'intrinsics = {{ model = "opencv", fx_px = {num(cam.fx)}, fy_px = {num(cam.fy)}, cx_px = {num(cam.cx)}, '
            f"cy_px = {num(cam.cy)}, distortion = [{', '.join(num(k) for k in cam.distortion)}] }}",
            f'extrinsics = {{ kind = "opencv", rotation_matrix = [{rot}], '
            f"tvec_m = [{', '.join(num(v) for v in cam.tvec)}] }}",
            "",
        ]
    corners = [[0.0, 0.0, 0.0], [width, 0.0, 0.0], [width, height, 0.0], [0.0, height, 0.0]]
    out += [
        "[wall]",
        "corners_m = [" + ", ".join("[" + ", ".join(num(v) for v in c) + "]" for c in corners) + "]",
        f"display_width_px = {round(width * 2100)}",
        f"display_height_px = {round(height * 2100)}",
        "",
        "[pointer]",
        'front_colour = "red"',
        f"length_m = {num(pt.length)}",
        "length_tolerance_m = 0.05",
        f"end_diameter_m = {num(pt.ball_d)}",
        f"rod_diameter_m = {num(pt.rod_d)}",
        "",
    ]
    return "\n".join(out)


def plain(x: object) -> object:
    """JSON-ready copies of NumPy values."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--poses", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--format", choices=["png", "bayer"], default="png")
    ap.add_argument("--scale", type=float, default=1.0, help="image size relative to 1920x1200")
    ap.add_argument("--supersample", type=int, default=2, help="sub-pixel samples per axis")
    ap.add_argument(
        "--only", type=lambda text: [int(v) for v in text.split(",")], help="render these poses only (e.g. 2,6)"
    )
    ap.add_argument(
        "--exposure",
        choices=sorted(CARD_GREY),
        default="drawn",
        help="drawn: the white card at the hand reads 35-230 grey levels; set: 140-230, as an operator would set it",
    )
    args = ap.parse_args(argv)
    ss = args.supersample
    rd = draw_room(np.random.default_rng(args.seed))
    cams = [c.scaled(args.scale) for c in rd.cameras]
    # Pose i is drawn from its own generator: pose 6 alone is pose 6 of a run of ten.
    numbers = args.only if args.only is not None else list(range(args.poses))
    poses = [draw_pose(np.random.default_rng([args.seed, i]), rd, ss, args.exposure) for i in numbers]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "rig.toml").write_text(rig_toml(rd, cams, args.format, args.seed))
    ext, pixel_format = (".png", "RGB8") if args.format == "png" else (".npy", "BayerRG8")
    truths: list[dict[str, object]] = []
    for pose in poses:
        front, back = pose.hold.front, pose.hold.back
        hit = back + back[2] / (back[2] - front[2]) * (front - back)
        width, height = rd.room.display_m
        truths.append(
            {
                "note": f"independent room, seed {args.seed}, exposure {args.exposure}",
                "front_m": front.tolist(),
                "back_m": back.tolist(),
                "wall_xy_m": hit[:2].tolist(),
                "on_wall": bool(0 <= hit[0] <= width and 0 <= hit[1] <= height),
                "scene": {"room": rd.info, "pose": pose.info},
            }
        )
    views: list[dict[str, object]] = [{} for _ in poses]
    balls: dict[str, Callable[[Pose], Array]] = {"red": lambda p: p.hold.front, "blue": lambda p: p.hold.back}
    for ci, cam in enumerate(cams):
        start = time.perf_counter()
        grids = ray_grids(cam, ss)
        print(f"{cam.id}: {cam.width}x{cam.height} rays for {ss}x{ss} samples in {time.perf_counter() - start:.2f} s")
        for i, (number, pose) in enumerate(zip(numbers, poses, strict=True)):
            start = time.perf_counter()
            radiance, areas = render(cam, grids, [scene_at(rd, pose, s) for s in pose.times], ("red", "blue"))
            sensor = Sensor(pose.white_balance, *rd.lens[ci], *pose.noise, rd.gamma)
            noise_rng = np.random.default_rng([args.seed, number, ci, 7])
            frame = expose(cam, radiance, sensor, noise_rng, args.format == "bayer")
            name = f"{number:02d}-{cam.id}{ext}"
            if args.format == "png":
                cv2.imwrite(str(args.out / name), np.ascontiguousarray(frame[..., ::-1]))
            else:
                np.save(args.out / name, frame)
            view: dict[str, object] = {"image": name, "pixel_format": pixel_format}
            for colour_name, where in balls.items():
                centre = where(pose)
                px, z = project(cam, centre[None])
                visible, own = areas[colour_name]
                # The share of the whole disc, also the part beyond the image's edge (only needed if any is seen).
                total = own + disc_area_outside(cam, centre, rd.pointer.ball_d / 2, ss) if visible > 0 else 1.0
                view[colour_name] = {
                    "centre_px": px[0].tolist() if z[0] > 0 else None,
                    "visible_fraction": min(1.0, visible / total),
                    "visible_area_px": visible,
                }
            views[i][cam.id] = view
            print(f"  {name}: {time.perf_counter() - start:.2f} s")
    for number, truth, view_of_pose in zip(numbers, truths, views, strict=True):
        truth["views"] = view_of_pose
        (args.out / f"{number:02d}-truth.json").write_text(json.dumps(plain(truth), indent=2) + "\n")


if __name__ == "__main__":
    main()
