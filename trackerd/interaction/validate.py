"""The checks the interaction stage makes of a rig before it runs, shared with `trackerd config check`.

Everything in ``[interaction]`` that the rig file's schema cannot see on its
own: the gesture templates load (``template_dir`` exists, every file in it is a
template), ``only`` names loaded gestures, every ``[interaction.commands]``
trigger is an event or a loaded gesture, the hand camera is one of the rig's,
and the TUIO host resolves. The extension (trackerd/interaction/extension.py)
builds itself from the result, so `config check` says OK exactly when `run` and
`replay` would start, and otherwise the same one line.
"""

from __future__ import annotations

from dataclasses import dataclass

from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError
from trackerd.interaction.grammar import Grammar
from trackerd.interaction.templates import Template, load_templates
from trackerd.interaction.tuio import resolve


@dataclass(frozen=True)
class CheckedInteraction:
    """What the checks found: the loaded templates, the grammar, and where the hand camera is."""

    templates: dict[str, Template]
    grammar: Grammar
    hand_camera: int | None
    """Index of the hand camera in the rig's cameras, None when hand poses are off."""


def check_interaction(rig: RigConfig) -> CheckedInteraction:
    """Check a rig's ``[interaction]`` as the daemon will use it; ConfigError (one line) when it cannot run."""
    cfg = rig.interaction
    templates: dict[str, Template] = {}
    if cfg.gestures.enabled:
        templates = load_templates(cfg.gestures.template_dir, builtin=cfg.gestures.builtin, only=cfg.gestures.only)
    grammar = Grammar(cfg.commands, set(templates))
    hand_camera = None
    if cfg.hand.enabled:
        ids = [c.id for c in rig.cameras]
        camera = cfg.hand.camera or ids[0]
        if camera not in ids:
            raise ConfigError(f"interaction.hand.camera: no camera '{camera}'; the rig has {', '.join(ids)}")
        hand_camera = ids.index(camera)
    if cfg.tuio.enabled:
        resolve(cfg.tuio)
    return CheckedInteraction(templates, grammar, hand_camera)
