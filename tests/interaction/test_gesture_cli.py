"""`trackerd gesture record` from a file of hit messages, and `trackerd gesture list`, through the real CLI."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys

import numpy as np

from trackerd.interaction.recognizer import score_all
from trackerd.interaction.scripted import minimum_jerk, rest
from trackerd.interaction.templates import load_template


def _zigzag(rng) -> np.ndarray:
    """A 'Z': right, down-left, right, in 0.6 s at 60 Hz, between rests."""
    corners = np.array([[1.0, 0.7], [1.4, 0.7], [1.0, 0.3], [1.4, 0.3]])
    legs = [a + np.outer(minimum_jerk(np.linspace(0, 1, 13))[1:], b - a) for a, b in itertools.pairwise(corners)]
    path = np.vstack([corners[:1], *legs])
    return np.vstack([rest(path[0], 0.4, rng), path, rest(path[-1], 0.5, rng)])


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "trackerd", "gesture", *args], capture_output=True, text=True,
                          timeout=60)


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
    for args, code, text in (
        (("record", "dwell", "--dir", str(tmp_path)), 2, "cannot name a gesture"),
        (("record", "ok", "--dir", str(tmp_path), "--from", str(tmp_path / "missing")), 2, "cannot read"),
    ):
        done = _cli(*args)
        assert done.returncode == code and text in done.stderr and "Traceback" not in done.stderr
    empty = tmp_path / "empty.jsonl"
    empty.write_text("")
    done = _cli("record", "ok", "--dir", str(tmp_path), "--from", str(empty))
    assert done.returncode == 1 and "only 0 of 5 strokes" in done.stderr
