"""From the locator's answer for one camera pair to the messages that describe it."""

from __future__ import annotations

from trackerd.geometry.wall import as_vec3
from trackerd.locator import Locator, PointerFix
from trackerd.publish.messages import HitMessage, Message, PointerMessage


def messages_from_fix(fix: PointerFix, locator: Locator, *, sequence: int, capture_ns: int) -> list[Message]:
    """The messages for one pair: none, a pointer, or a pointer and a hit (in that order).

    A pointer is sent whenever both ends were seen and the geometry is plausible
    (``fix.found``: not ``not_found`` nor ``rejected``); a hit whenever the line
    meets the wall's plane in front of the pointer (status ``hit`` or ``off_wall``).
    ``sequence`` is the pair's sequence number and ``capture_ns`` its capture
    time on the publisher's clock (see ``Publisher.clock_ns_from_monotonic``).
    """
    line = fix.line
    if not fix.found or line is None:
        return []
    front, back = as_vec3(line.front_m), as_vec3(line.back_m)
    out: list[Message] = [
        PointerMessage(
            sequence=sequence,
            capture_ns=capture_ns,
            status=fix.status,
            front_colour=locator.front_colour,
            front_m=front,
            back_m=back,
            direction=as_vec3(line.direction),
            length_m=line.length_m,
            front_gap_mm=line.front_gap_m * 1000.0,
            back_gap_mm=line.back_gap_m * 1000.0,
            method=line.method,
        )
    ]
    hit = fix.hit
    if hit is not None:
        x_m, y_m = (float(v) for v in hit.wall_xy_m[:2])
        display = None if hit.display_px is None else [float(v) for v in hit.display_px[:2]]
        out.append(
            HitMessage(
                sequence=sequence,
                capture_ns=capture_ns,
                wall_x_m=x_m,
                wall_y_m=y_m,
                display_x_px=None if display is None else display[0],
                display_y_px=None if display is None else display[1],
                on_wall=hit.on_wall,
                distance_m=hit.distance_m,
                front_m=front,
                back_m=back,
                ray_gap_mm=line.gap_m * 1000.0,
                uncertainty_mm=None if fix.uncertainty_m is None else fix.uncertainty_m * 1000.0,
            )
        )
    return out
