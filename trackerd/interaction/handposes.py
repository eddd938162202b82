"""Hand poses for the interaction stage: looks for a hand, the count debounced, ``hand`` events out.

A look (trackerd/interaction/hand.py) costs 4-5 ms at half resolution on the
development machine: on the processing thread it would hold up every pair
looked at by that much, beyond the daemon's 4 ms latency target. So live, looks
run on a thread of their own: the processing thread hands the frame over
through a one-slot mailbox that drops the older look when a newer one comes
(newest wins; the drops are counted in :attr:`HandPoses.dropped`), and takes
the events of finished looks with the next pair, each with the sequence and
capture time of the pair it was looked for in. A pair's hand event then
follows that pair's hit on the wire by a pair or two.

Replayed (``threaded=False``: a replay, an export), a look is made in the
processing thread as the pair comes, so what is published follows from the
pairs alone and repeats bit for bit; a replay pays the look's time per pair.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from trackerd.acquisition.frame import FramePair
from trackerd.config.interaction import HandConfig
from trackerd.interaction.hand import FingerDebouncer, HandDetector, HandObservation
from trackerd.interaction.outcomes import EventMaker
from trackerd.pipeline.events import Event, HandSeen
from trackerd.pipeline.queues import DropOldestQueue

log = logging.getLogger(__name__)

LOOK_WAIT_S = 0.1
"""How long the look thread waits for a frame before checking for stop."""
STOP_TIMEOUT_S = 1.0


@dataclass(frozen=True)
class _Look:
    """A frame to look for a hand in, with the pair it came with."""

    image: NDArray[np.uint8]
    pixel_format: str
    camera_id: str
    sequence: int
    capture_ns: int
    generation: int


class HandPoses:
    """The hand camera's looks and their debounced finger count (see the module's docstring).

    ``offer`` and ``take`` run in the processing thread; with ``threaded`` the looks run on a
    thread of their own, started with the first offer and stopped by :meth:`stop`."""

    def __init__(
        self,
        config: HandConfig,
        camera_index: int,
        camera_id: str,
        maker: EventMaker,
        *,
        threaded: bool,
        detector: HandDetector | None = None,
    ) -> None:
        self.camera_index = camera_index
        self.camera_id = camera_id
        self.threaded = threaded
        self._maker = maker
        self._detector = detector or HandDetector(config)
        self._debouncer = FingerDebouncer(config.debounce_pairs)
        self._last: HandObservation | None = None
        self._lock = threading.Lock()
        """Held by a look and by whatever touches the look's state (the detector, the debouncer)."""
        self._outbox: list[Event] = []
        self._outbox_lock = threading.Lock()
        """Held only to hand finished looks' events over: the processing thread never waits for a look."""
        self._generation = 0
        """Counts session ends: a look handed over before one is not made after it."""
        self._mailbox: DropOldestQueue[_Look] = DropOldestQueue(1)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._failure: BaseException | None = None
        self.looked = 0
        """Looks made so far."""

    @property
    def dropped(self) -> int:
        """Looks replaced in the mailbox by a newer one before the look thread took them."""
        return self._mailbox.dropped

    def offer(self, pair: FramePair, capture_ns: int) -> list[Event]:
        """Look for a hand in this pair's frame of the hand camera; the events ready now (threaded:
        those of looks finished since the last call, see :meth:`take`)."""
        frame = pair.frames[self.camera_index]
        look = _Look(frame.image, frame.pixel_format, frame.camera_id, pair.sequence, capture_ns, self._generation)
        if not self.threaded:
            return self._look(look)
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="trackerd-hand", daemon=True)
            self._thread.start()
        self._mailbox.put(look)
        return self.take()

    def take(self) -> list[Event]:
        """The events of the looks finished since the last call (a look that crashed raises here)."""
        if self._failure is not None:
            raise RuntimeError("the hand-pose thread failed") from self._failure
        if not self._outbox:
            return []
        with self._outbox_lock:
            out, self._outbox = self._outbox, []
        return out

    def end_session(self, sequence: int, capture_ns: int, *, forget_scene: bool = False) -> list[Event]:
        """Forget the hand (a reset, a reload, the stop): the events of finished looks, then a ``hand``
        with ``present`` false when a counted hand was in view (stamped with pair ``sequence``).
        ``forget_scene`` also forgets the learnt empty scene."""
        while self._mailbox.get(0.0) is not None:
            pass  # a look handed over before the end is no longer wanted
        with self._lock:  # waits for a look in progress
            self._generation += 1
            out = self.take() + self._forget_hand(sequence, capture_ns, self.camera_id)
            if forget_scene:
                self._detector.reset()
        return out

    def stop(self) -> None:
        """Stop the look thread (a look in progress is finished; its events stay to be taken)."""
        thread, self._thread = self._thread, None
        if thread is None:
            return
        self._stop.set()
        thread.join(STOP_TIMEOUT_S)
        if thread.is_alive():
            log.warning("the hand-pose thread is still looking after %.0f s", STOP_TIMEOUT_S)

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                look = self._mailbox.get(LOOK_WAIT_S)
                if look is None:
                    continue
                with self._lock:
                    if look.generation != self._generation:
                        continue  # handed over before a session ended
                    events = self._look(look)
                    with self._outbox_lock:  # before a session can end: its events go out ahead of the end
                        self._outbox += events
        except BaseException as err:
            log.exception("the hand-pose thread failed")
            self._failure = err

    def _forget_hand(self, sequence: int, capture_ns: int, camera_id: str) -> list[Event]:
        """The hand is gone (not seen, or the session ended): a ``hand`` with ``present`` false when a
        counted hand was in view, and the count starts again."""
        out: list[Event] = []
        last = self._last
        if last is not None and self._debouncer.stable is not None:
            out.append(
                HandSeen(
                    sequence=sequence,
                    capture_ns=capture_ns,
                    camera=camera_id,
                    present=False,
                    fingers=self._debouncer.stable,
                    fingers_now=last.fingers,
                    centre_px=last.centre_px,
                    area_px=last.area_px,
                )
            )
        self._last = None
        self._debouncer.reset()
        return out

    def _look(self, look: _Look) -> list[Event]:
        """One look and what it changes: a hand seen steadily (and its command when the count
        changes), or one seen before gone again."""
        seen = self._detector.look(look.image, look.pixel_format)
        self.looked += 1
        out: list[Event] = []
        if seen is None:
            return self._forget_hand(look.sequence, look.capture_ns, look.camera_id)
        self._last = seen
        changed = self._debouncer.add(seen.fingers)
        if self._debouncer.stable is None:
            return out  # not seen steadily enough yet
        event = HandSeen(
            sequence=look.sequence,
            capture_ns=look.capture_ns,
            camera=look.camera_id,
            present=True,
            fingers=self._debouncer.stable,
            fingers_now=seen.fingers,
            centre_px=seen.centre_px,
            area_px=seen.area_px,
        )
        out.append(event)
        if changed:
            self._maker.add_command(out, f"hand_{self._debouncer.stable}", event)
        return out
