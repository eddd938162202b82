"""The --live modes that watch the pointer: the wall targets (:class:`WallSession`) and the
calibration check (:class:`CheckSession`), fed and driven like the board sessions of
:mod:`trackerd.calibration.live`.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from trackerd.calibration.health import CalibrationHealth
from trackerd.calibration.live import Event, save_frame
from trackerd.calibration.wall import Pointing, Target, Touch

if TYPE_CHECKING:
    from trackerd.locator import Locator

Array = NDArray[np.float64]


@dataclass
class Steadiness:
    """Whether the pointer has been held still: its ends within ``tolerance_m`` over ``frames`` fixes."""

    frames: int = 12
    tolerance_m: float = 0.003
    _fronts: deque = field(default_factory=deque)
    _backs: deque = field(default_factory=deque)

    def add(self, front_m: Array, back_m: Array) -> tuple[Array, Array] | None:
        """Add a fix; when steady, the median ends over the window (and the window restarts)."""
        self._fronts.append(np.asarray(front_m, dtype=np.float64))
        self._backs.append(np.asarray(back_m, dtype=np.float64))
        while len(self._fronts) > self.frames:
            self._fronts.popleft()
            self._backs.popleft()
        if len(self._fronts) < self.frames:
            return None
        fronts, backs = np.array(self._fronts), np.array(self._backs)
        spread = max(
            float(np.max(np.linalg.norm(fronts - np.median(fronts, axis=0), axis=1))),
            float(np.max(np.linalg.norm(backs - np.median(backs, axis=0), axis=1))),
        )
        if spread > self.tolerance_m:
            return None
        self.clear()
        return np.median(fronts, axis=0), np.median(backs, axis=0)

    def clear(self) -> None:
        self._fronts.clear()
        self._backs.clear()


MIN_MOVE_M = 0.02
"""A capture must be this far (either ball) from the previous one: an operator still holding the
pointer where the last target was captured has not yet moved to the next one. Far above the
steadiness tolerance (3 mm); far below the spacing of targets, or of the places they are aimed
at from."""

SKIP_AFTER_FRAMES = 600
"""Frames on one live wall target without a capture after which it is skipped (about 20 s of
cameras at 30 fps: time to walk to a new place and aim): the operator cannot get the pointer
located, or held still, there."""


class WallSession:
    """Walks the operator through the wall targets: touch each (or point at each from several places).

    A target is captured when the pointer has been held still (:class:`Steadiness`)
    somewhere new (:data:`MIN_MOVE_M` from the previous capture); the next one is
    then announced. Frames in which the pointer is not located never advance the
    plan: the same target is asked for again (and the reason said once). After
    ``skip_after`` frames on one target without a capture it is skipped and
    reported as skipped, never filed under another target.
    """

    def __init__(
        self,
        locator: Locator,
        targets: Sequence[Target],
        method: str,
        places: int = 2,
        steadiness: Steadiness | None = None,
        snapshots: Path | None = None,
        camera_ids: Sequence[str] = (),
        skip_after: int | None = SKIP_AFTER_FRAMES,
        min_move_m: float = MIN_MOVE_M,
    ) -> None:
        if method not in ("touch", "point"):
            raise ValueError("method is 'touch' or 'point'")
        self.locator = locator
        self.method = method
        self.places = places if method == "point" else 1
        self.plan = [(t, k) for t in targets for k in range(self.places)]
        self.position = 0
        self.steadiness = steadiness or Steadiness()
        self.touches: list[Touch] = []
        self.pointings: list[Pointing] = []
        self.skipped: list[str] = []
        """Plan entries given up on ('bl', or 'bl from place 2'), in order."""
        self.snapshots = snapshots
        self.camera_ids = list(camera_ids)
        self.skip_after = skip_after if skip_after else None
        self.min_move_m = min_move_m
        self.frames = 0
        self.on_target = 0
        """Frames fed since the current target was asked for."""
        self.unlocated = 0
        """Frames in a row in which the pointer was not located, for the current target."""
        self._last_capture: tuple[Array, Array] | None = None
        self._located = 0
        self._unlocated_reason: str | None = None
        self._said_unlocated = False
        self._said_unmoved = False

    @property
    def done(self) -> bool:
        return self.position >= len(self.plan)

    def current(self) -> tuple[Target, int] | None:
        """The target (and place index) being asked for, or None when done."""
        return None if self.done else self.plan[self.position]

    def prompt(self) -> str:
        if self.done:
            return "all targets done"
        target, place = self.plan[self.position]
        if self.method == "touch":
            return f"touch '{target.label}' with the {self.locator.front_colour} ball and hold still"
        return (
            f"aim at '{target.label}' from place {place + 1} of {self.places}"
            f"{' (move to a new place first)' if place else ''} and hold still"
        )

    def _entry_name(self) -> str:
        target, place = self.plan[self.position]
        return target.label if self.method == "touch" else f"{target.label} from place {place + 1}"

    def _advance(self) -> None:
        self.position += 1
        self.on_target = 0
        self.unlocated = 0
        self._located = 0
        self._unlocated_reason = None
        self._said_unlocated = False
        self._said_unmoved = False
        self.steadiness.clear()

    def feed(self, frames: Sequence[tuple[str, NDArray[np.uint8], str]]) -> Event | None:
        if self.done:
            return None
        self.frames += 1
        self.on_target += 1
        # Each frame is judged on its own: the detector's tracking would otherwise carry
        # a wrong blob from one frame to the next, and speed does not matter here.
        self.locator.reset()
        fix = self.locator.locate([image for _, image, _ in frames])
        target, place = self.plan[self.position]
        located = fix.line is not None and fix.status != "rejected"
        if self.skip_after is not None and self.on_target > self.skip_after:
            skipped = self._entry_name()
            why = f"the pointer was located in {self._located} of them"
            if self._unlocated_reason is not None:
                why += f"; not located: {self._unlocated_reason}"
            self.skipped.append(skipped)
            self._advance()
            return Event(
                f"  skipped '{skipped}': no capture in {self.skip_after} frames ({why}); next: {self.prompt()}",
                finished=self.done,
            )
        if not located or fix.line is None:  # (the second says the same to the type checker)
            self.steadiness.clear()
            self.unlocated += 1
            self._unlocated_reason = fix.reason
            if self.unlocated == self.steadiness.frames and not self._said_unlocated:
                # Said once per target, after a moment: a frame or two lost while moving is normal.
                self._said_unlocated = True
                return Event(
                    f"  '{target.label}': pointer not located ({fix.reason}); hold both balls where both"
                    " cameras see them"
                )
            return None
        self.unlocated = 0
        self._located += 1
        steady = self.steadiness.add(fix.line.front_m, fix.line.back_m)
        if steady is None:
            return None
        front, back = steady
        if self._last_capture is not None:
            moved = max(
                float(np.linalg.norm(front - self._last_capture[0])),
                float(np.linalg.norm(back - self._last_capture[1])),
            )
            if moved < self.min_move_m:
                if self._said_unmoved:
                    return None
                self._said_unmoved = True
                return Event(f"  still where the last capture was: {self.prompt()}")
        self._last_capture = (front, back)
        if self.method == "touch":
            self.touches.append(Touch(target, front, back))
        else:
            self.pointings.append(Pointing(target, front, back))
        if self.snapshots is not None:
            name = target.label if self.method == "touch" else f"{target.label}-{place + 1}"
            for cam_id, (_, image, fmt) in zip(self.camera_ids, frames, strict=False):
                save_frame(self.snapshots, f"{name}-{cam_id}", image, fmt)
        self._advance()
        text = (
            f"[{self.position:>2}/{len(self.plan)}] captured '{target.label}'"
            f" (tip at {', '.join(f'{v:.3f}' for v in front)} m); next: {self.prompt()}"
        )
        return Event(text, accepted=True, finished=self.done)


class CheckSession:
    """Accumulates ray gaps and reprojection errors of the waved pointer."""

    def __init__(self, locator: Locator, health: CalibrationHealth, wanted_fixes: int = 300) -> None:
        self.locator = locator
        self.health = health
        self.wanted = wanted_fixes
        self.frames = 0
        self._last_report = 0

    @property
    def done(self) -> bool:
        return self.health.total >= self.wanted

    def feed(self, frames: Sequence[tuple[str, NDArray[np.uint8], str]]) -> Event | None:
        self.frames += 1
        self.locator.reset()  # judged frame by frame, as in WallSession
        fix = self.locator.locate([image for _, image, _ in frames])
        if not self.health.add_fix(fix):
            return None
        if self.health.total - self._last_report < 25 and not self.done:
            return None
        self._last_report = self.health.total
        f = self.health.figures()
        return Event(
            f"[{self.health.total:>4} fixes] ray gap median {f.gap_p50_mm:.2f} mm (p95 {f.gap_p95_mm:.2f});"
            f" reprojection median {f.reprojection_p50_px:.2f} px (p95 {f.reprojection_p95_px:.2f})",
            finished=self.done,
        )
