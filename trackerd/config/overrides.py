"""Changing a loaded rig as a command's options ask, checked as the rig file is, and writing it back."""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

from trackerd.config.models import RigConfig, ZmqOutput
from trackerd.config.validation import describe_validation_error
from trackerd.errors import ConfigError


def with_endpoints(rig: RigConfig, endpoints: list[str], option: str = "--endpoint") -> RigConfig:
    """The rig publishing on ``endpoints`` instead of its own, checked as the rig file's are
    (a network address needs CURVE or allow_insecure_network); ConfigError naming ``option``."""
    try:
        zmq_config = ZmqOutput.model_validate({**rig.outputs.zmq.model_dump(), "endpoints": tuple(endpoints)})
    except ValidationError as err:
        problem = describe_validation_error(err, ZmqOutput).removeprefix("(top level): ")
        raise ConfigError(f"{option}: {problem}") from err
    return rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_config})})


def dump_rig(rig: RigConfig, header: str = "") -> str:
    """A rig as TOML text that load_rig reads back to the same rig (defaults left out).

    The ``calibration`` path is written as it is; make it absolute first if the text
    is saved somewhere else than the original rig file's directory.
    """
    from trackerd.config.tomlwrite import dumps

    return dumps(rig.model_dump(mode="json", exclude_none=True, exclude_defaults=True), header=header)


def with_console(rig: RigConfig, listen: str | None, option: str = "--console") -> RigConfig:
    """The rig with its console moved to ``listen`` (HOST:PORT), or switched off ('off'), checked
    as the rig file's ``[console]`` is; None leaves it as it is. ConfigError naming ``option``."""
    from trackerd.config.console import ConsoleConfig

    if listen is None:
        return rig
    if listen.strip().lower() == "off":
        update: dict[str, Any] = {"enabled": False}
    else:
        update = {"enabled": True, "listen": listen}
    try:
        # Only what was set: a listen address not given stays the default (serve() runs on without
        # the console when the default port is taken, and fails when a chosen one is).
        console = ConsoleConfig.model_validate({**rig.console.model_dump(exclude_unset=True), **update})
    except ValidationError as err:
        problem = describe_validation_error(err, ConsoleConfig).removeprefix("(top level): ")
        raise ConfigError(f"{option}: {problem}") from err
    return rig.model_copy(update={"console": console})
