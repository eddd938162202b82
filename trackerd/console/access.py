"""Who may use the console: its token, and the checks that keep other web sites' pages out.

Without a token, being on the loopback address is the console's only protection, and any page open
in a browser on this machine can make requests to it; with one, every request must carry it (a
query parameter once, then a cookie, or an ``Authorization: Bearer`` header).
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path

from aiohttp import web
from aiohttp.typedefs import Handler, Middleware

from trackerd.errors import ConfigError
from trackerd.files import read_bounded

COOKIE = "trackerd_console_token"
ACTION_HEADER = "X-Trackerd-Console"
"""Every POST must carry it: a page of another site cannot add it without the console's consent."""
LOCAL_NAMES = ("127.0.0.1", "localhost", "::1")


def token_exposed(path: Path) -> str | None:
    """Why the token file at ``path`` lets every user of the host in (other users may read it), else None:
    the daemon's CURVE secret key is refused for that; a token file that many deployments made 0644 is
    warned about instead."""
    try:
        mode = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return None
    if mode & stat.S_IROTH:
        return f"{path}: the console token is readable by every user of this host (mode {mode:04o}); chmod o-r it"
    return None


def read_token(path: Path) -> str:
    """The token in ``path``: its first line, printable ASCII (ConfigError naming the file when it is missing,
    empty or holds anything else: an HTTP header carries ASCII, so a token of other characters could not be
    sent as the same bytes by every client)."""
    try:
        data = read_bounded(path, 4096)
    except OSError as err:
        raise ConfigError(f"{path}: cannot read the console token file ({err.strerror or err})") from None
    lines = data.strip().splitlines()
    if not lines:
        raise ConfigError(f"{path}: the console token file is empty")
    token = lines[0].strip()
    if not all(0x21 <= byte <= 0x7E for byte in token):
        raise ConfigError(
            f"{path}: the console token must be printable ASCII without spaces"
            " (`head -c 24 /dev/urandom | base64` makes one)"
        )
    return token.decode("ascii")


@web.middleware
async def json_errors(request: web.Request, handler: Handler) -> web.StreamResponse:
    """An error aiohttp answers itself (no such path: 404; a method the path does not take: 405) as the
    console's own errors are: a JSON object ``{"error": ...}`` (docs/console.md), not a text page."""
    try:
        return await handler(request)
    except web.HTTPException as err:
        if err.status < 400:
            raise
        allow = {"Allow": err.headers["Allow"]} if "Allow" in err.headers else None
        # Its text says why where aiohttp says more than the reason ("No WebSocket UPGRADE hdr").
        text = (err.text or "").removeprefix(f"{err.status}: ").strip()
        return web.json_response({"error": text or err.reason}, status=err.status, headers=allow)


def access_middleware(token: str | None) -> Middleware:
    """The middleware that refuses cross-site requests (403) and, with a ``token``, requests without
    it (401); a request that gave the token as ``?token=`` gets it back as a cookie."""

    @web.middleware
    async def check(request: web.Request, handler: Handler) -> web.StreamResponse:
        refused = cross_site(request, token)
        if refused is not None:
            return web.json_response({"error": refused}, status=403)
        if token is None:
            return await handler(request)
        given = request.query.get("token") or request.cookies.get(COOKIE)
        header = request.headers.get("Authorization", "")
        if header.startswith("Bearer "):
            given = header.removeprefix("Bearer ").strip()
        if given is None or not same_token(given, token):
            return web.json_response(
                {"error": "the console needs its token (?token=... or Authorization: Bearer)"}, status=401
            )
        response = await handler(request)
        if "token" in request.query and not response.prepared:
            response.set_cookie(COOKIE, token, httponly=True, samesite="Strict")
        return response

    return check


def same_token(given: str, token: str) -> bool:
    """Whether a request's ``given`` token is the console's, in constant time. A header's bytes that are not
    UTF-8 come as surrogates, which do not encode: such a token is not the console's (it was an error, a
    500 and a traceback logged for anyone who sent one)."""
    try:
        given_bytes = given.encode()
    except UnicodeError:
        return False
    return secrets.compare_digest(given_bytes, token.encode())


def cross_site(request: web.Request, token: str | None) -> str | None:
    """Why a request that another web site could have made the operator's browser send is
    refused, else None.

    Actions must carry a header such a page cannot add without the console's consent (it answers
    no CORS preflight), the WebSocket must come from the console's own page (Origin), and without
    a token the Host must be this machine's name for it (a DNS name pointed at 127.0.0.1 by
    another site does not pass).
    """
    if request.method == "POST" and ACTION_HEADER not in request.headers:
        return f"actions need the header {ACTION_HEADER} (the console's page and `trackerd ctl` send it)"
    origin = request.headers.get("Origin")
    # Behind a reverse proxy the page's origin is the proxy's, which it names in X-Forwarded-Host.
    hosts = {request.host, request.headers.get("X-Forwarded-Host")}
    if request.path == "/ws" and origin is not None and origin.split("://", 1)[-1] not in hosts:
        return f"a WebSocket from {origin} is not the console's page"
    if token is None and request.host.rsplit(":", 1)[0].strip("[]") not in LOCAL_NAMES:
        return f"Host {request.host} is not this machine's (use 127.0.0.1, or give the console a token)"
    return None
