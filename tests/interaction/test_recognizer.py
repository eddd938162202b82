"""The $1-family recogniser and gesture templates as data."""

from __future__ import annotations

import json

import numpy as np
import pytest

from trackerd.errors import ConfigError
from trackerd.interaction.recognizer import POINTS, normalise, path_length, resample, rotate, score_all
from trackerd.interaction.scripted import builtin_templates, circle_path, swipe_path
from trackerd.interaction.templates import (
    BUILTIN_DIR,
    format_template,
    load_directory,
    load_template,
    load_templates,
    save_template,
    stroke_features,
    template_from_strokes,
)


def test_resample_spaces_points_evenly_along_the_path():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0]])
    out = resample(points, 5)
    steps = np.hypot(*np.diff(out, axis=0).T)
    assert np.allclose(steps, 1.0) and np.allclose(out[[0, -1]], points[[0, -1]])
    assert path_length(out) == pytest.approx(4.0)
    with pytest.raises(ValueError, match="no length"):
        resample(np.zeros((3, 2)))


def test_normalise_is_centred_with_unit_rms_radius(rng):
    shape = normalise(rng.normal(5.0, 2.0, (POINTS, 2)))
    assert np.allclose(shape.mean(axis=0), 0.0)
    assert np.mean(np.sum(shape**2, axis=1)) == pytest.approx(1.0)


def test_shipped_templates_are_the_ones_the_code_makes():
    shipped = load_directory(BUILTIN_DIR)
    for template in builtin_templates():
        assert format_template(template) == (BUILTIN_DIR / f"{template.name}.json").read_text()
        assert shipped[template.name].name == template.name


def test_directions_and_senses_are_told_apart(templates, rng):
    shapes = [t.shape for t in templates.values()]
    for name in ("swipe_left", "swipe_right", "swipe_up", "swipe_down"):
        path = swipe_path(name, np.array([1.0, 0.4]), 0.5, 0.25, rng)
        best, score = score_all(path, shapes)[0]
        assert best == name and score > 0.9
    for name in ("circle_cw", "circle_ccw"):
        for start in (0.0, 2.0, 4.0):  # a circle may start anywhere
            path = circle_path(name, np.array([1.0, 0.4]), 0.4, 1.0, rng, start_rad=start, aspect=0.85)
            (best, score), (_, second) = score_all(path, shapes)[:2]
            assert best == name and score > 0.85 and score - second > 0.3


def test_a_swipe_turned_beyond_the_limit_does_not_match(templates, rng):
    path = swipe_path("swipe_right", np.zeros(2), 0.5, 0.25, rng, ideal=True)
    shape = templates["swipe_right"].shape
    assert score_all(rotate(path, np.radians(20.0)), [shape])[0][1] > 0.95
    assert score_all(rotate(path, np.radians(60.0)), [shape])[0][1] < 0.7


def test_recorded_template_round_trips_with_gates_from_its_examples(tmp_path, rng):
    strokes = []
    for duration in (0.3, 0.5):
        path = circle_path("circle_cw", np.zeros(2), 0.3, duration, rng)
        times = (np.arange(len(path)) * 1e9 / 60).astype(np.int64)
        strokes.append((times, path))
    template = template_from_strokes("loop", strokes, rotation_invariant=True)
    slowest = min(stroke_features(t, p).mean_speed_m_s for t, p in strokes)
    assert template.min_mean_speed_m_s == pytest.approx(0.6 * slowest)
    path = save_template(template, tmp_path)
    loaded = load_template(path)
    assert loaded.name == "loop" and len(loaded.examples) == 2 and loaded.rotation_invariant
    assert load_templates(tmp_path, builtin=False, only=("loop",)).keys() == {"loop"}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("not json", "not JSON"),
        ('{"format": "x"}', "not a trackerd gesture template"),
        ('{"format": "trackerd-gesture-template", "version": 9}', "version 9"),
        ('{"format": "trackerd-gesture-template", "version": 1, "name": "bad", "examples": [[[0, 0]]]}', "64 finite"),
    ],
)
def test_bad_template_files_get_one_clear_line(tmp_path, text, message):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_template(path)


def test_a_template_must_be_named_after_its_file(tmp_path):
    data = json.loads((BUILTIN_DIR / "swipe_up.json").read_text())
    (tmp_path / "other.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"must be named swipe_up\.json"):
        load_template(tmp_path / "other.json")
    with pytest.raises(ConfigError, match="no template for nope"):
        load_templates(only=("nope",))
