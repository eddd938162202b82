"""The operator's console: the ``[console]`` table of a rig file (trackerd/console, docs/console.md).

The daemon serves a web page showing what the cameras see, the wall hit and the
status, with buttons for a snapshot, recording and a calibration check, plus
``/metrics`` (Prometheus) and ``/healthz``. It is on by default, on the loopback
address only; listening on any other address needs a token, so that nobody on
the network can take snapshots or start recordings.
"""

from __future__ import annotations

import ipaddress
from pathlib import Path

from pydantic import Field, field_validator, model_validator

from trackerd.config.base import ConfigModel

DEFAULT_LISTEN = "127.0.0.1:8560"


def split_listen(text: str) -> tuple[str, int]:
    """'HOST:PORT' (IPv6 as '[::1]:PORT') -> (host, port); ValueError saying what is wrong."""
    host, sep, port = text.strip().rpartition(":")
    if not sep or not host:
        raise ValueError(f"'{text}' is not HOST:PORT (for example 127.0.0.1:8560)")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"'{text}': the port must be a number from 1 to 65535")
    return host, int(port)


def is_loopback(host: str) -> bool:
    """Whether ``host`` is reachable from this machine only ('localhost' counts)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class ConsoleConfig(ConfigModel):
    """The operator's console served by the daemon (docs/console.md)."""

    enabled: bool = True
    """Serve the console (web page, ``/metrics``, ``/healthz``) while the daemon runs."""
    listen: str = DEFAULT_LISTEN
    """HOST:PORT to listen on. Beyond the loopback address a ``token_file`` is required (or keep
    the loopback address and put a reverse proxy with its own authentication in front)."""
    token_file: Path | None = None
    """A file holding the access token (one line). With it, every request must carry it: a
    browser opens ``http://HOST:PORT/?token=...`` once (a cookie keeps it), a scraper or script
    sends ``Authorization: Bearer ...``. A relative path is relative to the daemon's working
    directory."""
    frame_rate_hz: float = Field(default=4.0, gt=0.0, le=15.0)
    """Camera images sent to the page per second and camera, while someone watches."""
    image_width_px: int = Field(default=640, ge=160, le=1920)
    """Width the camera images are scaled down to for the page."""
    jpeg_quality: int = Field(default=75, ge=20, le=95)
    """JPEG quality of those images."""
    snapshot_directory: Path | None = None
    """Where the console's snapshots are saved (one folder per snapshot). Omit for ``snapshots`` in
    the service's state directory under systemd (/var/lib/trackerd/snapshots), else
    ``trackerd-snapshots-UID`` under the system's temporary directory (the user's own, 0700)."""

    @field_validator("listen")
    @classmethod
    def _listen_syntax(cls, listen: str) -> str:
        split_listen(listen)
        return listen.strip()

    @model_validator(mode="after")
    def _token_beyond_loopback(self) -> ConsoleConfig:
        host, _ = split_listen(self.listen)
        if self.enabled and not is_loopback(host) and self.token_file is None:
            raise ValueError(
                f"listen = '{self.listen}' is reachable from the network: give a token_file, or keep"
                " 127.0.0.1 and put a reverse proxy with authentication in front (docs/console.md)"
            )
        return self
