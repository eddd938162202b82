"""How the scene simulator renders a rig (``[simulation]``)."""

from __future__ import annotations

from pydantic import Field

from trackerd.config.base import ConfigModel


class SimulationConfig(ConfigModel):
    """How the scene simulator renders this rig (trackerd/sim). Ignored by live tracking."""

    seed: int = 7
    """Seed for the room's clutter, so renders are reproducible."""
    room_depth_m: float = Field(default=6.0, gt=0.0)
    """Distance from the wall to the back of the room."""
    room_margin_m: float = Field(default=1.5, ge=0.0)
    """How far the side walls extend beyond the display area on each side."""
    room_height_m: float = Field(default=3.0, gt=0.0)
    """Floor to ceiling."""
    display_height_above_floor_m: float = Field(default=0.9, ge=0.0)
    """Height of the display's bottom edge above the floor."""
    clutter: int = Field(default=12, ge=0)
    """Number of distractor objects (posters, stickers, strips, balls), a third red, a third blue."""
    hand: bool = True
    """Render a skin-coloured hand holding the pointer's handle (skin is a reddish distractor)."""
    presenter_distance_m: tuple[float, float] = (1.2, 2.8)
    """Range of distances of the pointer's tip from the wall for random poses."""
    hand_height_m: tuple[float, float] = (1.0, 1.8)
    """Range of heights of the pointer's tip above the floor for random poses."""
    noise_sigma: float = Field(default=1.0, ge=0.0)
    """Sensor read noise, standard deviation in 8-bit grey levels. The defaults model a 1080p
    CMOS machine-vision sensor (about 32 000 e- full well, 7 e- read noise) at +12 dB gain, as
    a 60 fps camera with a short exposure indoors needs (trackerd/sim/render.py applies it)."""
    shot_noise: float = Field(default=0.2, ge=0.0)
    """Photon (shot) noise scale: the standard deviation in grey levels is this times
    sqrt(grey level) (0.2: 31 electrons per grey level)."""
    supersampling: int = Field(default=4, ge=1, le=8)
    """Anti-aliasing of the pointer: rays per pixel along each axis (4 means 16 rays per pixel)."""
    background_supersampling: int = Field(default=2, ge=1, le=4)
    """Anti-aliasing of the static room, rendered once per camera and cached."""
