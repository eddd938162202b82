"""Talking to a running daemon's console from the command line (`trackerd ctl`, `trackerd snap`).

Plain HTTP with the standard library: the same requests the page's buttons make. The daemon is
found where the rig's ``[console] listen`` says (or ``--console ADDR``), with the rig's token.
"""

from __future__ import annotations

import contextlib
import http.client
import json
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any

from trackerd.config.console import split_listen
from trackerd.errors import TrackerdError

FIND_TIMEOUT_S = 1.0


class ConsoleError(TrackerdError):
    """The daemon's console refused a request or did not answer as expected."""

    def __init__(self, message: str, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status
        """The HTTP status it answered with, when it answered."""


class NotAConsole(ConsoleError):
    """Something answers at the console's address, but not as a trackerd console."""


class ConsoleClient:
    """Requests to one daemon's console."""

    def __init__(self, listen: str, token: str | None = None, timeout_s: float = 15.0) -> None:
        host, port = split_listen(listen)
        if host in ("0.0.0.0", "::"):
            host = "127.0.0.1"  # listening everywhere: this machine reaches it on the loopback address
        self.base = f"http://{f'[{host}]' if ':' in host else host}:{port}"
        self.token = token
        self.timeout_s = timeout_s

    @classmethod
    def for_rig(cls, rig: Any, listen: str | None = None) -> ConsoleClient:
        from trackerd.console.access import read_token

        token = read_token(rig.console.token_file) if rig.console.token_file is not None else None
        return cls(listen or rig.console.listen, token)

    def find(self) -> dict[str, Any] | None:
        """The daemon's rig info if a trackerd console answers there, else None (nothing listening).
        ConsoleError when one answers but wants a token this client does not have (or not that one)."""
        try:
            info = self._request("GET", "/api/info", timeout_s=FIND_TIMEOUT_S)
        except NotAConsole:
            raise  # said as it is: "no daemon answers" would send the user looking for a stopped daemon
        except ConsoleError as err:
            if err.status == 401:
                given = "a different token" if self.token is not None else "none"
                raise ConsoleError(
                    f"the console at {self.base} wants its token, and this rig gives {given}: name the daemon's"
                    " token file in [console] token_file (docs/console.md)",
                    401,
                ) from None
            return None
        return info if isinstance(info, dict) and "rig" in info and "cameras" in info else None

    def runs_cameras_of(self, info: dict[str, Any], rig: Any) -> bool:
        """Whether the daemon that answered with ``info`` runs ``rig``'s cameras (same ids and addresses),
        not another rig's daemon that happens to listen there."""
        mine = [(c.id, c.address, c.device_id, c.serial) for c in rig.cameras]
        theirs = [(c.get("id"), c.get("address"), c.get("device_id"), c.get("serial")) for c in info["cameras"]]
        return mine == theirs

    def _request(self, method: str, path: str, timeout_s: float | None = None) -> Any:
        request = urllib.request.Request(self.base + path, method=method, data=b"" if method == "POST" else None)
        request.add_header("X-Trackerd-Console", "1")
        if self.token is not None:
            request.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(request, timeout=timeout_s or self.timeout_s) as response:
                return json.loads(response.read())
        except urllib.error.HTTPError as err:
            try:
                body = json.loads(err.read())
                problem = body.get("error") or body.get("message") or err.reason
            except ValueError:
                problem = err.reason
            raise ConsoleError(f"the daemon at {self.base} answered {err.code}: {problem}", err.code) from None
        except (http.client.RemoteDisconnected, ConnectionError) as err:
            # A daemon stopping or restarting mid-request: no answer, not a wrong one.
            raise ConsoleError(f"the daemon's console at {self.base} did not answer ({err})") from None
        except (http.client.HTTPException, ValueError) as err:
            # Something answers there, but not a console: the rig's ZeroMQ port given as --console (its
            # publisher streams messages at an HTTP request), another web server.
            raise NotAConsole(
                f"{self.base} answers, but not as a trackerd console ({type(err).__name__}); is it the console's"
                " address ([console] listen)?"
            ) from None
        except (urllib.error.URLError, OSError) as err:
            reason = getattr(err, "reason", None) or getattr(err, "strerror", None) or err
            raise ConsoleError(f"the daemon's console at {self.base} did not answer ({reason})") from None

    def get(self, path: str) -> Any:
        return self._request("GET", path)

    def post(self, path: str) -> Any:
        return self._request("POST", path)

    def download(self, url: str, path: Path) -> None:
        """One of the daemon's files into ``path``; ConsoleError saying what failed (a file cut short by a
        full disk is removed)."""
        request = urllib.request.Request(f"{self.base}/{url.lstrip('/')}")
        if self.token is not None:
            request.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(request, timeout=self.timeout_s) as response:
                data = response.read()
        except urllib.error.HTTPError as err:
            raise ConsoleError(f"the daemon at {self.base} answered {err.code} for {url}", err.code) from None
        except (urllib.error.URLError, http.client.HTTPException, OSError) as err:
            raise ConsoleError(f"the daemon at {self.base} did not send {url} ({err})") from None
        try:
            path.write_bytes(data)
        except OSError as err:
            with contextlib.suppress(OSError):  # a read-only file system refuses that too
                path.unlink()
            raise ConsoleError(f"{path}: cannot write ({err.strerror or err})") from None

    def snapshot_into(self, folder: Path, name: str | None = None) -> dict[str, Any]:
        """Take a snapshot from the running pipeline and download its files into ``folder``, which is
        checked first (a snapshot the daemon took and this side cannot save would be left on its host)."""
        from trackerd.recording.outputs import output_folder

        output_folder(folder)
        answer: dict[str, Any] = self.post("/api/snapshot" + (f"?name={urllib.parse.quote(name)}" if name else ""))
        for entry in answer["files"]:
            self.download(entry["url"], folder / entry["name"])
        return answer
