"""The base class shared by every configuration model."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

Vec3 = tuple[float, float, float]
"""A point or direction in the world frame (metres for a point)."""


class ConfigModel(BaseModel):
    """Base for every configuration model: closed (unknown keys are errors) and immutable.

    Field docstrings become the field descriptions (``use_attribute_docstrings``),
    which docs/configuration.md and error messages draw on. NaN and infinity are
    refused: TOML can spell them (nan, inf), but no setting of a rig can take them.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True, allow_inf_nan=False)
