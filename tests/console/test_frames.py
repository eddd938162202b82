"""The console's frame thread's pure parts (trackerd/console/frames.py)."""

from __future__ import annotations

from trackerd.console.frames import snapshot_name


def test_snapshot_names_are_numbered_past_the_folder_and_the_snapshots_still_waiting(tmp_path) -> None:
    # A new user's audit: twenty snapshots asked for in one second were named snap-...-b-b-b..., the name
    # growing with each one waiting; they are -2, -3, ... as for names already in the folder.
    (tmp_path / "wall").mkdir()
    assert snapshot_name(tmp_path, "wall") == "wall-2"
    waiting: set[str] = set()
    for _ in range(20):
        waiting.add(snapshot_name(tmp_path, "wall", waiting))
    assert waiting == {f"wall-{n}" for n in range(2, 22)}
    assert snapshot_name(tmp_path, "free") == "free"
    assert snapshot_name(tmp_path).startswith("snap-")
