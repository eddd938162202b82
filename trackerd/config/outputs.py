"""Where results go (``[outputs]``): the ZeroMQ publisher and its network safety."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, field_validator, model_validator

from trackerd.config.base import ConfigModel


class ZmqOutput(ConfigModel):
    """ZeroMQ publishing of hits, pointer poses and status (docs/protocol.md).

    Binding anything but a loopback address (127.0.0.0/8, ::1, ``localhost``) or an
    ``ipc://`` path needs CURVE (``curve_secret_key_file``) or an explicit
    ``allow_insecure_network = true``: the messages say where a presenter points,
    and without CURVE anyone on the network could read them.
    """

    endpoints: tuple[str, ...] = Field(default=("tcp://127.0.0.1:5560",), min_length=1)
    """Endpoints the PUB socket binds: ``tcp://HOST:PORT`` (HOST an address, ``localhost``,
    an interface name or ``*``; PORT may be ``*`` for any free port) or ``ipc:///path``."""
    send_hwm_messages: int = Field(default=1000, ge=1, le=1_000_000)
    """Messages queued per subscriber before further messages to that subscriber are dropped
    (ZeroMQ SNDHWM): a slow or stalled subscriber never blocks or slows the pipeline."""
    linger_ms: int = Field(default=200, ge=0, le=10_000)
    """On shutdown, how long queued messages may still be sent before the socket is dropped."""
    status_interval_ms: float = Field(default=1000.0, gt=0.0, le=60_000.0)
    """Period of the ``status`` message; it is also sent on every change of state."""
    curve_secret_key_file: Path | None = None
    """The daemon's CURVE key pair (a ``.key_secret`` file from ``trackerd keys server``).
    Setting it turns on CURVE encryption and authentication for every endpoint. A relative
    path is relative to the rig file."""
    curve_authorized_keys_dir: Path | None = None
    """A directory of client public keys (``*.key`` files from ``trackerd keys client``);
    only those clients may subscribe. Omit to accept any client that knows the server's
    public key. Needs curve_secret_key_file. A relative path is relative to the rig file."""
    allow_insecure_network: bool = False
    """Bind non-loopback addresses without CURVE: anyone who can reach the port reads every
    message. For isolated networks only."""

    @field_validator("endpoints")
    @classmethod
    def _endpoint_syntax(cls, endpoints: tuple[str, ...]) -> tuple[str, ...]:
        for endpoint in endpoints:
            cls.endpoint_host(endpoint)
        if len(set(endpoints)) != len(endpoints):
            raise ValueError("lists the same endpoint twice")
        return endpoints

    @model_validator(mode="after")
    def _secure_network(self) -> ZmqOutput:
        if self.curve_authorized_keys_dir is not None and self.curve_secret_key_file is None:
            raise ValueError("curve_authorized_keys_dir needs curve_secret_key_file (CURVE is off without it)")
        exposed = self.insecure_endpoints()
        if exposed:
            raise ValueError(
                f"{', '.join(exposed)} is reachable from the network; set curve_secret_key_file"
                " (make one with `trackerd keys server`) or allow_insecure_network = true"
            )
        return self

    @staticmethod
    def endpoint_host(endpoint: str) -> str | None:
        """The host part of a ``tcp://`` endpoint (None for ``ipc://``); ValueError when malformed."""
        scheme, sep, rest = endpoint.partition("://")
        if not sep or scheme not in ("tcp", "ipc"):
            raise ValueError(f"'{endpoint}' is not a tcp://HOST:PORT or ipc:///path endpoint")
        if scheme == "ipc":
            if not rest:
                raise ValueError(f"'{endpoint}' names no path")
            return None
        host, colon, port = rest.rpartition(":")
        if not colon or not host:
            raise ValueError(f"'{endpoint}' needs HOST:PORT, for example tcp://127.0.0.1:5560")
        if port != "*" and not (port.isdigit() and 1 <= int(port) <= 65535):
            raise ValueError(f"'{endpoint}': port '{port}' is not a number from 1 to 65535 or '*'")
        if host.startswith("[") and host.endswith("]"):
            host = host[1:-1]
        return host

    @staticmethod
    def is_loopback_host(host: str) -> bool:
        """Whether a tcp endpoint's host is reachable from this machine only."""
        import ipaddress

        if host in ("localhost", "lo"):
            return True
        try:
            return ipaddress.ip_address(host).is_loopback
        except ValueError:
            return False  # '*', an interface name or a host name: assume the network

    def insecure_endpoints(self) -> list[str]:
        """Endpoints reachable from the network that would carry plain text (empty when allowed)."""
        if self.curve_secret_key_file is not None or self.allow_insecure_network:
            return []
        return [
            e for e in self.endpoints if (host := self.endpoint_host(e)) is not None and not self.is_loopback_host(host)
        ]


class OutputsConfig(ConfigModel):
    """Where results go."""

    zmq: ZmqOutput = ZmqOutput()
    """ZeroMQ publisher (docs/protocol.md)."""
