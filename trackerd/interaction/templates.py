"""Gesture templates as data: one JSON file per gesture, shipped ones and an operator's own.

A template file (``NAME.json``, format version 1)::

    {
      "format": "trackerd-gesture-template",
      "version": 1,
      "name": "swipe_left",
      "rotation_invariant": false,       # true for shapes that may start anywhere (circles)
      "max_rotation_deg": 30.0,          # directional templates: how far a stroke may be turned
      "min_mean_speed_m_s": 0.9,         # kinematic gates (null: no gate), from the examples
      "max_duration_ms": 500.0,
      "min_size_m": 0.2,                 # the stroke's bounding-box diagonal on the wall
      "max_submovements": 1,             # speed peaks (a flick has one; aimed moves often two)
      "examples": [[[x, y], ...], ...]   # each example: 64 points, resampled and normalised
    }

Examples are stored prepared (trackerd/interaction/recognizer.py: resampled to
64 points, centroid at the origin, unit RMS radius, and turned to indicative
angle 0 when rotation-invariant), so a reader in another language needs no
more than this page and that module's docstring. ``trackerd gesture record
NAME`` writes these files; the built-in ones live in
``trackerd/interaction/templates/`` and were made from ideal strokes by
:func:`trackerd.interaction.scripted.builtin_templates` (a test checks they
still match).

Kinematic gates make a shape into a gesture: a swipe is a *fast* straight
stroke; moving the pointer from one thing to another is straight too, but
slower for its length (Fitts' law), so it is not a swipe.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.errors import ConfigError
from trackerd.interaction.recognizer import POINTS, Shape, path_length, prepare

Array = NDArray[np.float64]

FORMAT = "trackerd-gesture-template"
VERSION = 1
BUILTIN_DIR = Path(__file__).resolve().parent / "templates"
NAME_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,63}$")

SPEED_GATE_FRACTION = 0.6
"""A recorded template accepts strokes down to this fraction of its slowest example's mean speed."""
DURATION_GATE_FACTOR = 1.6
"""... and up to this many times its longest example's duration."""
SIZE_GATE_FRACTION = 0.5
"""... and down to this fraction of its smallest example's size."""
DIP_FRACTION = 0.4
"""A submovement ends when the speed falls below this fraction of its peak ..."""
RISE_FRACTION = 0.2
"""... and the next begins when it rises again above this fraction of the previous peak (and above
RISE_MIN_M_S): an aimed movement's correction at its end (Meyer et al., 1988) counts, noise does not."""
RISE_MIN_M_S = 0.3


@dataclass(frozen=True)
class StrokeFeatures:
    """What the kinematic gates look at in a stroke."""

    duration_ms: float
    path_m: float
    size_m: float
    """Diagonal of the stroke's bounding box on the wall."""
    submovements: int = 1
    """Speed peaks separated by a clear dip: 1 for a flick, 2 or more for a movement with a correction."""

    @property
    def mean_speed_m_s(self) -> float:
        return self.path_m / max(self.duration_ms / 1000.0, 1e-9)


def stroke_features(times_ns: NDArray[np.int64], points_m: Array) -> StrokeFeatures:
    """Duration, path length and size of a stroke: times (N,) and wall positions (N, 2)."""
    extent = points_m.max(axis=0) - points_m.min(axis=0)
    return StrokeFeatures(
        duration_ms=float(times_ns[-1] - times_ns[0]) / 1e6,
        path_m=path_length(points_m),
        size_m=float(math.hypot(*extent)),
        submovements=count_submovements(times_ns, points_m),
    )


def count_submovements(times_ns: NDArray[np.int64], points_m: Array) -> int:
    """Speed peaks of a stroke separated by dips (DIP_FRACTION, RISE_FRACTION): times (N,), positions (N, 2)."""
    if len(points_m) < 3:
        return 1
    # Central differences over two sample intervals: steady at 60 Hz without a filter's delay.
    dt_s = (times_ns[2:] - times_ns[:-2]) / 1e9
    speeds = np.hypot(*(points_m[2:] - points_m[:-2]).T) / np.maximum(dt_s, 1e-9)
    count, peak, low = 1, 0.0, None
    for speed in speeds:
        if low is None:
            if speed > peak:
                peak = speed
            elif speed < DIP_FRACTION * peak:
                low = speed
        elif speed > max(RISE_FRACTION * peak, RISE_MIN_M_S, 2.0 * low):
            count, peak, low = count + 1, speed, None
        else:
            low = min(low, speed)
    return count


@dataclass(frozen=True)
class Template:
    """One gesture: its shape and its kinematic gates."""

    name: str
    examples: tuple[Array, ...]
    rotation_invariant: bool = False
    max_rotation_deg: float = 30.0
    min_mean_speed_m_s: float | None = None
    max_duration_ms: float | None = None
    min_size_m: float | None = None
    max_submovements: int | None = None
    source: str = field(default="", compare=False)
    """Where it was loaded from, for messages."""

    @property
    def shape(self) -> Shape:
        return Shape(self.name, self.examples, self.rotation_invariant, self.max_rotation_deg)

    def admits(self, features: StrokeFeatures) -> str | None:
        """None when the stroke's kinematics fit this gesture, else why not (one phrase)."""
        if self.min_mean_speed_m_s is not None and features.mean_speed_m_s < self.min_mean_speed_m_s:
            return f"too slow for {self.name} ({features.mean_speed_m_s:.2f} < {self.min_mean_speed_m_s:.2f} m/s)"
        if self.max_duration_ms is not None and features.duration_ms > self.max_duration_ms:
            return f"too long for {self.name} ({features.duration_ms:.0f} > {self.max_duration_ms:.0f} ms)"
        if self.min_size_m is not None and features.size_m < self.min_size_m:
            return f"too small for {self.name} ({features.size_m:.2f} < {self.min_size_m:.2f} m)"
        if self.max_submovements is not None and features.submovements > self.max_submovements:
            return f"{features.submovements} submovements, {self.name} has {self.max_submovements}: an aimed movement"
        return None

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "version": VERSION,
            "name": self.name,
            "rotation_invariant": self.rotation_invariant,
            "max_rotation_deg": self.max_rotation_deg,
            "min_mean_speed_m_s": _rounded(self.min_mean_speed_m_s),
            "max_duration_ms": _rounded(self.max_duration_ms),
            "min_size_m": _rounded(self.min_size_m),
            "max_submovements": self.max_submovements,
            "examples": [(np.round(example, 4) + 0.0).tolist() for example in self.examples],
        }


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(float(value), 3)


def template_from_strokes(
    name: str,
    strokes: list[tuple[NDArray[np.int64], Array]],
    *,
    rotation_invariant: bool = False,
    max_rotation_deg: float = 30.0,
) -> Template:
    """A template from recorded strokes (times (N,) in ns, wall positions (N, 2) in metres each),
    with gates from their kinematics (SPEED_GATE_FRACTION, DURATION_GATE_FACTOR, SIZE_GATE_FRACTION)."""
    if not NAME_PATTERN.match(name):
        raise ValueError(f"'{name}' is not a gesture name (letters, digits, _ and -, starting with a letter)")
    if not strokes:
        raise ValueError("no strokes to make a template from")
    features = [stroke_features(t, p) for t, p in strokes]
    return Template(
        name=name,
        examples=tuple(prepare(p, rotation_invariant) for _, p in strokes),
        rotation_invariant=rotation_invariant,
        max_rotation_deg=max_rotation_deg,
        min_mean_speed_m_s=SPEED_GATE_FRACTION * min(f.mean_speed_m_s for f in features),
        max_duration_ms=DURATION_GATE_FACTOR * max(f.duration_ms for f in features),
        min_size_m=SIZE_GATE_FRACTION * min(f.size_m for f in features),
        max_submovements=max(f.submovements for f in features),
    )


def parse_template(data: Any, source: str) -> Template:
    """A template from a file's parsed JSON; ConfigError naming ``source`` when it is not one."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ConfigError(f'{source}: not a trackerd gesture template (no "format": "{FORMAT}")')
    if data.get("version") != VERSION:
        raise ConfigError(f"{source}: template format version {data.get('version')!r}; this trackerd reads {VERSION}")
    name = data.get("name")
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise ConfigError(f"{source}: name {name!r} is not a gesture name (letters, digits, _ and -)")
    try:
        examples = tuple(np.asarray(e, dtype=np.float64) for e in data["examples"])
        rotation_invariant = bool(data.get("rotation_invariant", False))
        max_rotation = float(data.get("max_rotation_deg", 30.0))
        gates = {
            key: None if data.get(key) is None else float(data[key])
            for key in ("min_mean_speed_m_s", "max_duration_ms", "min_size_m")
        }
        submovements = data.get("max_submovements")
        max_submovements = None if submovements is None else int(submovements)
    except (KeyError, TypeError, ValueError) as err:
        raise ConfigError(f"{source}: malformed template ({err})") from err
    if not examples or any(e.shape != (POINTS, 2) or not np.all(np.isfinite(e)) for e in examples):
        raise ConfigError(f"{source}: every example must be {POINTS} finite [x, y] points")
    if not 0.0 <= max_rotation <= 180.0:
        raise ConfigError(f"{source}: max_rotation_deg must be from 0 to 180")
    return Template(
        name, examples, rotation_invariant, max_rotation, source=source, max_submovements=max_submovements, **gates
    )


def load_template(path: Path) -> Template:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise ConfigError(f"{path}: cannot read gesture template: {err.strerror}") from err
    except ValueError as err:
        raise ConfigError(f"{path}: not JSON ({err})") from err
    template = parse_template(data, str(path))
    if template.name != path.stem:
        raise ConfigError(f"{path}: holds gesture '{template.name}'; the file must be named {template.name}.json")
    return template


def load_directory(directory: Path) -> dict[str, Template]:
    """Every ``*.json`` template in a directory, by name; ConfigError when it is not a directory."""
    if not directory.is_dir():
        raise ConfigError(f"{directory}: gesture template directory does not exist")
    return {t.name: t for t in (load_template(p) for p in sorted(directory.glob("*.json")))}


def load_templates(
    template_dir: Path | None = None, *, builtin: bool = True, only: tuple[str, ...] = ()
) -> dict[str, Template]:
    """Built-in templates, overridden by those in ``template_dir``, restricted to ``only`` when given."""
    templates = load_directory(BUILTIN_DIR) if builtin else {}
    if template_dir is not None:
        templates.update(load_directory(template_dir))
    if only:
        missing = [name for name in only if name not in templates]
        if missing:
            raise ConfigError(
                f"interaction.gestures.only: no template for {', '.join(missing)};"
                f" loaded: {', '.join(sorted(templates)) or 'none'}"
            )
        templates = {name: templates[name] for name in only}
    return templates


def format_template(template: Template) -> str:
    """The file's text: one header field per line (easy to edit by hand), one example per line."""
    data = template.to_json()
    examples = data.pop("examples")
    lines = [f"  {json.dumps(key)}: {json.dumps(value)}," for key, value in data.items()]
    rows = ",\n".join(f"    {json.dumps(example, separators=(',', ':'))}" for example in examples)
    return "{\n" + "\n".join(lines) + '\n  "examples": [\n' + rows + "\n  ]\n}\n"


def save_template(template: Template, directory: Path) -> Path:
    """Write ``directory/NAME.json`` atomically; returns the path."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{template.name}.json"
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    try:
        tmp.write_text(format_template(template), encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        # A full disk: the old file stays as it was, and no half-written one is left beside it.
        tmp.unlink(missing_ok=True)
        raise
    return path
