"""Sequences across sources, and a source replaced by a reload (sources of our own: no cameras)."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.acquisition.frame import Frame, FramePair
from trackerd.acquisition.status import CameraStatus, SourceStatus
from trackerd.pipeline.sourceslot import Renumbering, SourceSlot
from trackerd.sdnotify import SdNotify


def test_numbers_go_on_from_the_last_one_whatever_the_next_source_counts_from():
    numbering = Renumbering()
    assert [numbering.number(s) for s in (0, 1, 2, 5, 6)] == [0, 1, 2, 5, 6]  # a gap is kept: pairs dropped
    numbering.swapped()
    assert [numbering.number(s) for s in (1, 2, 4)] == [7, 8, 10]  # a source counting from 1
    numbering.swapped()
    assert [numbering.number(s) for s in (0, 1)] == [11, 12]  # and one from 0
    numbering.swapped()
    assert numbering.number(1000) == 13  # a source counting from anywhere


class _Source:
    """A pair source that delivers the given sequences once, then nothing; counts what it delivered."""

    def __init__(self, sequences, *, refuse: bool = False, camera_state: str = "streaming") -> None:
        self.sequences = list(sequences)
        self.refuse = refuse
        self.camera_state = camera_state
        self.started = self.stopped = 0

    def start(self) -> None:
        if self.refuse:
            raise RuntimeError("the camera refuses the setting")
        self.started += 1

    def stop(self) -> None:
        self.stopped += 1

    def next_pair(self, timeout_s: float) -> FramePair | None:
        if not self.sequences:
            return None
        sequence = self.sequences.pop(0)
        image = np.zeros((2, 2), dtype=np.uint8)
        frame = Frame("left", sequence, 0, 1000 + sequence, "Mono8", image)
        return FramePair((frame,), timestamp_ns=1000 + sequence, skew_ns=0, sequence=sequence)

    def status(self) -> SourceStatus:
        camera = CameraStatus(camera_id="left", state=self.camera_state, device="fake")
        return SourceStatus(
            running=True,
            trigger="free",
            pairing="timestamp",
            pairs=10 * self.started,
            dropped_pairs=self.started,
            cameras=(camera,),
        )


def _drain(slot: SourceSlot) -> list[int]:
    out = []
    while (pair := slot.next_pair(0.0)) is not None:
        out.append(pair.sequence)
    return out


def test_a_reopened_source_goes_on_numbering_and_the_old_ones_counts_are_kept(simulated_rig):
    sources = [_Source([0, 1, 2]), _Source([0, 1])]
    slot = SourceSlot(lambda rig: sources.pop(0), SdNotify({}))
    slot.start(simulated_rig)
    first = slot.source
    assert _drain(slot) == [0, 1, 2]
    slot.reopen(simulated_rig, simulated_rig)
    assert first.stopped == 1 and slot.source is not first
    assert _drain(slot) == [3, 4]
    # The first source's last status: 10 pairs, 1 dropped.
    assert (slot.retired_pairs, slot.retired_dropped_pairs) == (10, 1)


def test_a_refused_setting_reopens_the_old_settings_and_raises(simulated_rig):
    new_rig = simulated_rig.model_copy(update={"name": "new"})
    made = []

    def factory(rig):
        made.append(rig.name)
        return _Source([0, 1], refuse=rig.name == "new")

    slot = SourceSlot(factory, SdNotify({}))
    slot.start(simulated_rig)
    assert _drain(slot) == [0, 1]
    with pytest.raises(RuntimeError, match="refuses"):
        slot.reopen(new_rig, simulated_rig)
    assert made == [simulated_rig.name, "new", simulated_rig.name]
    assert slot.source.started == 1  # the old settings, opened again
    assert _drain(slot) == [2, 3]
    assert slot.retired_pairs == 10


def test_a_lost_camera_is_recovering_and_the_first_sources_pairs_pass_as_they_are(simulated_rig):
    source = _Source([4], camera_state="lost")
    slot = SourceSlot(lambda rig: source, SdNotify({}))
    assert slot.status() is None
    slot.start(simulated_rig)
    assert slot.some_camera_recovering()
    pair = slot.next_pair(0.0)
    assert pair is not None and pair.sequence == 4
    source.camera_state = "streaming"
    assert not slot.some_camera_recovering()
