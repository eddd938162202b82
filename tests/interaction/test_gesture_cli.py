"""`trackerd gesture record` from a file of hit messages, and `trackerd gesture list`, through the real CLI."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from trackerd.interaction.recognizer import score_all
from trackerd.interaction.scripted import circle_path, minimum_jerk, rest, swipe_path
from trackerd.interaction.templates import load_template


def _zigzag(rng) -> np.ndarray:
    """A 'Z': right, down-left, right, in 0.6 s at 60 Hz, between rests."""
    corners = np.array([[1.0, 0.7], [1.4, 0.7], [1.0, 0.3], [1.4, 0.3]])
    legs = [a + np.outer(minimum_jerk(np.linspace(0, 1, 13))[1:], b - a) for a, b in itertools.pairwise(corners)]
    path = np.vstack([corners[:1], *legs])
    return np.vstack([rest(path[0], 0.4, rng), path, rest(path[-1], 0.5, rng)])


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "trackerd", "gesture", *args], capture_output=True, text=True, timeout=60
    )


def test_record_a_gesture_from_hits_and_list_it(tmp_path, rng):
    lines, t = [], 10**18
    for _ in range(3):
        for x, y in _zigzag(rng) + rng.normal(0, 0.001, (1, 2)):
            lines.append(json.dumps({"topic": "hit", "capture_ns": t, "wall_x_m": x, "wall_y_m": y}))
            t += 16_666_667
        t += 500_000_000  # the pointer away for half a second
    hits = tmp_path / "hits.jsonl"
    hits.write_text("\n".join(lines) + "\n")
    done = _cli("record", "zigzag", "--examples", "3", "--dir", str(tmp_path / "g"), "--from", str(hits))
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("example ") == 3 and "wrote" in done.stdout
    template = load_template(tmp_path / "g" / "zigzag.json")
    assert len(template.examples) == 3 and template.max_submovements >= 3
    assert score_all(_zigzag(rng)[20:-25], [template.shape])[0][1] > 0.85
    listed = _cli("list", "--dir", str(tmp_path / "g"))
    assert listed.returncode == 0 and "zigzag" in listed.stdout and "swipe_left" in listed.stdout
    # Recording more appends examples.
    again = _cli("record", "zigzag", "--examples", "1", "--dir", str(tmp_path / "g"), "--from", str(hits))
    assert again.returncode == 0 and len(load_template(tmp_path / "g" / "zigzag.json").examples) == 4


def test_bad_input_is_one_line_and_a_nonzero_exit(tmp_path):
    (tmp_path / "utf16.jsonl").write_bytes('{"topic": "hit"}\n'.encode("utf-16"))  # begins 0xFF 0xFE
    for args, code, text in (
        (("record", "dwell", "--dir", str(tmp_path)), 2, "cannot name a gesture"),
        (("record", "ok", "--dir", str(tmp_path), "--from", str(tmp_path / "missing")), 2, "cannot read"),
        (("record", "ok", "--dir", str(tmp_path), "--from", str(tmp_path / "utf16.jsonl")), 2, "not text"),
    ):
        done = _cli(*args)
        assert done.returncode == code and text in done.stderr and "Traceback" not in done.stderr
    empty = tmp_path / "empty.jsonl"
    empty.write_text("")
    done = _cli("record", "ok", "--dir", str(tmp_path), "--from", str(empty))
    assert done.returncode == 1 and "only 0 of 5 strokes" in done.stderr


def _hits_file(path, paths, rng) -> None:
    """Hit messages at 60 Hz of each path between rests, the pointer away for half a second after each."""
    lines, t = [], 10**18
    for points in paths:
        for x, y in np.vstack([rest(points[0], 0.4, rng), points, rest(points[-1], 0.5, rng)]):
            lines.append(json.dumps({"topic": "hit", "capture_ns": t, "wall_x_m": x, "wall_y_m": y}))
            t += 16_666_667
        t += 500_000_000
    path.write_text("\n".join(lines) + "\n")


def test_an_example_unlike_the_others_is_refused(tmp_path, rng):
    swipe = swipe_path("swipe_right", np.array([1.0, 0.5]), 0.6, 0.3, rng)
    loop = circle_path("circle_cw", np.array([2.0, 0.5]), 0.4, 1.0, rng)
    hits = tmp_path / "hits.jsonl"
    _hits_file(hits, [swipe, loop, swipe + np.array([0.3, 0.05])], rng)
    done = _cli("record", "flick", "--examples", "2", "--dir", str(tmp_path / "g"), "--from", str(hits))
    assert done.returncode == 0, done.stderr
    (refused,) = [line for line in done.stdout.splitlines() if "refused" in line]
    assert refused.startswith("example 2/2:") and "against the other examples of flick" in refused
    template = load_template(tmp_path / "g" / "flick.json")
    assert len(template.examples) == 2
    assert score_all(swipe, [template.shape])[0][1] > 0.9 and score_all(loop, [template.shape])[0][1] < 0.8
    # Added to an existing template, a stroke is compared with the examples already in it.
    again = _cli("record", "flick", "--examples", "1", "--dir", str(tmp_path / "g"), "--from", str(hits))
    assert again.returncode == 0 and "0.9" in again.stdout.splitlines()[0]
    only_loops = tmp_path / "loops.jsonl"
    _hits_file(only_loops, [loop, loop], rng)
    refused = _cli("record", "flick", "--examples", "1", "--dir", str(tmp_path / "g"), "--from", str(only_loops))
    assert refused.returncode == 1 and refused.stdout.count("refused") == 2
    last = refused.stderr.splitlines()[-1]
    assert last.endswith(f"only 0 of 1 strokes, 2 refused as unlike the others in {only_loops}")
    assert len(load_template(tmp_path / "g" / "flick.json").examples) == 3


def test_an_unwritable_directory_is_refused_before_recording(tmp_path, rng):
    hits = tmp_path / "hits.jsonl"
    _hits_file(hits, [swipe_path("swipe_right", np.array([1.0, 0.5]), 0.6, 0.3, rng)], rng)
    afile = tmp_path / "afile"
    afile.write_text("x\n")
    for directory, reason in (
        (afile / "sub", "Not a directory"),
        (afile, "not a directory"),
        (Path("/proc/nope"), "No such file or directory"),
    ):
        done = _cli("record", "flick", "--examples", "1", "--dir", str(directory), "--from", str(hits))
        assert done.returncode == 1 and "Traceback" not in done.stderr
        # One line, and before recording: no stroke was cut.
        assert done.stderr == f"trackerd gesture: --dir {directory}: " + (
            "not a directory\n" if directory == afile else f"cannot write gesture templates there: {reason}\n"
        )
    # A directory made for a recording that gave nothing is removed again.
    empty = tmp_path / "empty.jsonl"
    empty.write_text("")
    done = _cli("record", "flick", "--dir", str(tmp_path / "new" / "g"), "--from", str(empty))
    assert done.returncode == 1 and not (tmp_path / "new").exists()
