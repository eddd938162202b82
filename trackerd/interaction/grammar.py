"""The grammar: events, gestures and hand poses mapped to named commands (the report's Figure 1).

The rig file's ``[interaction.commands]`` table maps a trigger to a command::

    [interaction.commands]
    swipe_left = "previous_slide"
    swipe_right = "next_slide"
    dwell = "select"
    hand_5 = "show_all"

Triggers are gesture names, ``enter``, ``leave``, ``dwell``, and ``hand_0`` to
``hand_5`` (a hand whose debounced finger count becomes that number).
Applications subscribe to ``command`` and react to ``next_slide`` rather than
to a particular gesture, so the operator can change which gesture does what
without touching the application.
"""

from __future__ import annotations

from trackerd.config.interaction import RESERVED_TRIGGERS
from trackerd.errors import ConfigError


class Grammar:
    """Trigger name -> command name, checked against the gestures that can actually happen."""

    def __init__(self, commands: dict[str, str], gesture_names: set[str]) -> None:
        unknown = sorted(t for t in commands if t not in RESERVED_TRIGGERS and t not in gesture_names)
        if unknown:
            raise ConfigError(
                f"interaction.commands: no gesture or event called {', '.join(unknown)}; triggers are"
                f" {', '.join(RESERVED_TRIGGERS)} and the loaded gestures"
                f" ({', '.join(sorted(gesture_names)) or 'none'})"
            )
        clash = sorted(set(RESERVED_TRIGGERS) & gesture_names)
        if clash:
            raise ConfigError(f"gesture templates may not be named {', '.join(clash)} (an event's name)")
        self.commands = dict(commands)

    def command_for(self, trigger: str) -> str | None:
        """The command a trigger sets off, or None."""
        return self.commands.get(trigger)
