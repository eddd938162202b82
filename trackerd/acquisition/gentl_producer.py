"""GenTL producers through harvesters: loading one (once per process), what it offers, a camera's producer.

One producer is loaded once per process (:class:`Producer`) and shared by every camera that names
it: GenTL libraries are process-wide, and a second harvesters ``Harvester`` on the same ``.cti`` sees
no devices. Sessions on its cameras are :mod:`trackerd.acquisition.gentl`'s.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from trackerd.acquisition.arv import CameraConfigError
from trackerd.config.models import CameraConfig
from trackerd.errors import CameraError

GENTL_EXTRA = "trackerd[gentl]"
"""The optional extra that installs harvesters (and pypylon)."""


def load_harvesters() -> Any:
    """harvesters' ``Harvester`` class; CameraError naming the extra to install if it is missing."""
    try:
        from harvesters.core import Harvester
    except ImportError as err:
        raise CameraError(
            f"backend = 'gentl' needs harvesters, which is not installed ({err}); install the optional extra:"
            f" pip install '{GENTL_EXTRA}'"
        ) from err
    return Harvester


def harvesters_missing_reason() -> str | None:
    """Why the gentl backend cannot be used here, or None if it can (for skipping tests and commands)."""
    try:
        load_harvesters()
    except CameraError as err:
        return str(err)
    return None


def genicam_errors() -> tuple[type[Exception], ...]:
    """The exceptions a GenICam node or a GenTL call raises (genicam's, and harvesters' ValueError)."""
    from genicam import genapi, gentl

    return (genapi.GenericException, gentl.GenericException, ValueError)


def producer_path(cam: CameraConfig) -> Path:
    """The camera's producer file; CameraConfigError naming it if it is not there."""
    where = f"camera '{cam.id}' (backend gentl)"
    if not cam.producer:
        raise CameraConfigError(f"{where} has no producer (the GenTL producer's .cti file) in the rig file")
    path = Path(cam.producer).expanduser()
    if not path.is_file():
        raise CameraConfigError(
            f"{where}: producer = {cam.producer!r}: no such file (the grabber vendor's GenTL producer,"
            " a .cti file; its SDK installs it and usually lists its directory in GENICAM_GENTL64_PATH)"
        )
    return path.resolve()


@dataclass(frozen=True)
class GentlDevice:
    """One device a producer offers."""

    device_id: str
    """The producer's device id (GenTL ``DEVICE_INFO_ID``): ``device_id`` in the rig file."""
    serial: str
    vendor: str
    model: str
    tl_type: str
    """The producer's transport layer type: ``CoaXPress``, ``CameraLink``, ``GEV``, ``Custom``, ..."""


class Producer:
    """One loaded producer, shared by the cameras that name it."""

    def __init__(self, path: Path) -> None:
        harvester_class = load_harvesters()
        self.path = path
        self.lock = threading.Lock()
        self.open_count = 0
        self.harvester = harvester_class()
        cannot_load: tuple[type[Exception], ...] = (OSError, *genicam_errors())
        try:
            self.harvester.add_file(str(path), check_existence=True, check_validity=True)
            self.harvester.update()
        except cannot_load as err:
            raise CameraError(f"GenTL producer {path} cannot be loaded: {err}") from err

    def devices(self) -> list[GentlDevice]:
        """What the producer offers; refreshed only while none of its cameras is open."""
        with self.lock:
            if self.open_count == 0:
                self.harvester.update()
            return [
                GentlDevice(
                    device_id=str(info.id_),
                    serial=str(info.serial_number or ""),
                    vendor=str(info.vendor or ""),
                    model=str(info.model or ""),
                    tl_type=str(info.tl_type or ""),
                )
                for info in self.harvester.device_info_list
            ]

    def create(self, device_id: str) -> Any:
        """An ``ImageAcquirer`` on ``device_id`` (ValueError if the producer does not list it)."""
        with self.lock:
            acquirer = self.harvester.create({"id_": device_id})
            self.open_count += 1
            return acquirer

    def release(self, acquirer: Any) -> None:
        with self.lock:
            try:
                acquirer.destroy()
            finally:
                self.open_count -= 1


_producers: dict[Path, Producer] = {}
_producers_lock = threading.Lock()


def producer(path: Path) -> Producer:
    """The loaded producer at ``path`` (loaded on first use; CameraError if it cannot be)."""
    path = path.resolve()  # one producer per file, however the rig spells its path
    with _producers_lock:
        if path not in _producers:
            _producers[path] = Producer(path)
        return _producers[path]


def list_gentl_devices(path: str | Path) -> list[GentlDevice]:
    """Every device the producer at ``path`` offers (CameraError if harvesters or the file is missing)."""
    resolved = Path(path).expanduser()
    if not resolved.is_file():
        raise CameraError(f"GenTL producer {path}: no such file")
    return producer(resolved.resolve()).devices()
