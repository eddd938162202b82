"""Messages from the locator's fixes, and decoding that tolerates a newer MINOR version."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.publish.conftest import hit_message, status_message
from trackerd.locator import Locator
from trackerd.publish import HitMessage, LatencyPart, PointerMessage, decode, encode, messages_from_fix


def _centroids(locator: Locator, front_m, back_m):
    """Exact image positions of both ends in every camera (no rendering needed for the geometry)."""
    out = []
    for camera in locator.cameras:
        front_px, back_px = camera.project(np.array([front_m, back_m], dtype=float))
        out.append({locator.front_colour: front_px, locator.back_colour: back_px})
    return tuple(out)


@pytest.fixture(scope="module")
def locator(simulated_rig):
    return Locator(simulated_rig)


def test_a_pointer_aimed_at_the_display_gives_a_pointer_and_a_hit(locator):
    front, back = np.array([1.8, 0.45, 1.5]), np.array([1.85, 0.5, 1.95])
    fix = locator.locate_centroids(_centroids(locator, front, back))
    assert fix.status == "hit"
    messages = messages_from_fix(fix, locator, sequence=12, capture_ns=1_700_000_000_000_000_000)
    assert [type(m) for m in messages] == [PointerMessage, HitMessage]
    pointer, hit = messages
    assert pointer.sequence == hit.sequence == 12 and pointer.capture_ns == hit.capture_ns
    assert pointer.status == "hit" and pointer.front_colour == "red"
    np.testing.assert_array_equal(pointer.front_m, fix.line.front_m)
    np.testing.assert_array_equal(pointer.back_m, fix.line.back_m)
    np.testing.assert_allclose(pointer.front_m, front, atol=1e-4)  # the geometry is right, too
    np.testing.assert_allclose(pointer.direction, (front - back) / np.linalg.norm(front - back), atol=1e-4)
    np.testing.assert_allclose((hit.wall_x_m, hit.wall_y_m), fix.hit.wall_xy_m)
    np.testing.assert_allclose((hit.display_x_px, hit.display_y_px), fix.hit.display_px)
    assert hit.on_wall is True
    assert hit.ray_gap_mm == pytest.approx(fix.line.gap_m * 1000)
    assert hit.uncertainty_mm == pytest.approx(fix.uncertainty_m * 1000)
    assert pointer.length_m == pytest.approx(fix.line.length_m)
    assert (pointer.front_gap_mm, pointer.back_gap_mm) == (fix.line.front_gap_m * 1000, fix.line.back_gap_m * 1000)


def test_a_pointer_aimed_away_gives_a_pointer_only(locator):
    fix = locator.locate_centroids(_centroids(locator, [1.85, 0.5, 1.95], [1.8, 0.45, 1.5]))
    assert fix.status == "away"
    messages = messages_from_fix(fix, locator, sequence=1, capture_ns=1)
    assert [m.topic for m in messages] == ["pointer"]
    assert messages[0].status == "away"


def test_no_pointer_no_messages(locator):
    centroids = _centroids(locator, [1.8, 0.45, 1.5], [1.85, 0.5, 1.95])
    missing = (dict(centroids[0], red=None), centroids[1])
    fix = locator.locate_centroids(missing)
    assert fix.status == "not_found"
    assert messages_from_fix(fix, locator, sequence=1, capture_ns=1) == []
    # Ends 10 cm too far apart: an impossible pointer is rejected and not published.
    fix = locator.locate_centroids(_centroids(locator, [1.8, 0.45, 1.5], [1.85, 0.5, 2.05]))
    assert fix.status == "rejected"
    assert messages_from_fix(fix, locator, sequence=1, capture_ns=1) == []


def test_decode_ignores_fields_of_a_newer_minor_and_refuses_another_major():
    topic, payload = encode(hit_message(3))
    data = json.loads(payload)
    newer = {**data, "schema_version": "1.7", "smoothed_x_m": 1.2, "future": {"a": 1}}
    assert decode(topic, json.dumps(newer).encode()).sequence == 3
    with pytest.raises(ValueError, match=r"schema_version '2\.0' is not 1\.x"):
        decode(topic, json.dumps({**data, "schema_version": "2.0"}).encode())
    with pytest.raises(ValueError, match="unknown topic 'nosuchtopic'"):
        decode(b"nosuchtopic", payload)


def test_messages_refuse_non_finite_numbers_and_unknown_fields():
    with pytest.raises(ValueError):
        HitMessage.model_validate({**hit_message().model_dump(), "wall_x_m": float("nan")})
    with pytest.raises(ValueError):
        HitMessage.model_validate({**hit_message().model_dump(), "wal_x_m": 1.0})


def test_decode_keeps_a_status_s_stages():
    """Regression: decode read the values of ``stages`` (a dict of LatencyPart by stage name) as
    one LatencyPart, dropped the stage names as unknown fields and returned ``stages == {}``."""
    status = status_message().model_copy(
        update={"stages": {"detect": LatencyPart(samples=3, p50_ms=2.5), "publish": LatencyPart(samples=3, p50_ms=0.2)}}
    )
    topic, payload = encode(status)
    newer = json.loads(payload)
    newer["stages"]["detect"]["p95_ms"] = 3.0  # a newer MINOR's field inside a part is still ignored
    decoded = decode(topic, json.dumps(newer).encode())
    assert decoded.stages == status.stages
