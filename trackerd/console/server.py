"""The console's web server: aiohttp on a thread of its own, with its own event loop.

Why aiohttp: one maintained library gives the HTTP server, WebSockets and static files on an
asyncio loop that runs in one thread at the edge of the daemon, started and stopped with it
(``AppRunner`` / ``TCPSite``); an ASGI stack (Starlette with uvicorn) wants to own the process's
main loop and its signals, which belong to trackerd's CLI here.

Routes (docs/console.md):

* ``GET /``, ``/static/...``: the page;
* ``GET /ws``: a WebSocket pushing the camera images (binary: a 4-byte big-endian header length,
  the header as JSON, the JPEG), the hits and pointer poses, the status and new warnings (JSON);
* ``GET /api/info``, ``/api/status``: the rig and the last status message;
* ``POST /api/snapshot``: save the next pair (raw, annotated, JSON) on the host; the answer lists
  the files, downloadable under ``/snapshots/NAME/FILE``;
* ``POST /api/recording/start``, ``/api/recording/stop``: recording on demand;
* ``POST /api/check``, ``GET /api/check``: a calibration check on the live pointer;
* ``GET /metrics`` (Prometheus) and ``GET /healthz``.

A slow page never holds up the daemon: each page has one slot per camera image and a bounded
list of other messages, and what it has not taken when the next one comes is dropped.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import secrets
import struct
import tempfile
import threading
import time
from importlib import resources
from pathlib import Path
from typing import Any

from aiohttp import WSMsgType, web

from trackerd.config.console import split_listen
from trackerd.console.actions import Actions
from trackerd.console.frames import CameraImage, FrameThread
from trackerd.console.logbook import Logbook
from trackerd.console.metrics import exposition, registry_for
from trackerd.errors import ConfigError, TrackerdError
from trackerd.files import read_bounded
from trackerd.pipeline.tap import ConsoleTap

log = logging.getLogger(__name__)

PUSH_EVERY_S = 0.1
"""How often hits, status and warnings are pushed to the open pages."""
TEXT_QUEUE = 64
"""Text messages waiting for a slow page before the oldest are dropped."""
SNAPSHOT_TIMEOUT_S = 10.0
STOP_TIMEOUT_S = 0.6
COOKIE = "trackerd_console_token"
ACTION_HEADER = "X-Trackerd-Console"
"""Every POST must carry it: a page of another site cannot add it without the console's consent."""
LOCAL_NAMES = ("127.0.0.1", "localhost", "::1")


class _Page:
    """One open page: the newest image per camera and a bounded list of text messages."""

    def __init__(self, ws: web.WebSocketResponse) -> None:
        self.ws = ws
        self.images: dict[str, CameraImage] = {}
        self.texts: list[str] = []
        self.dropped = 0
        self.ready = asyncio.Event()

    def put_text(self, text: str) -> None:
        self.texts.append(text)
        if len(self.texts) > TEXT_QUEUE:
            del self.texts[0]
            self.dropped += 1
        self.ready.set()

    def put_image(self, image: CameraImage) -> None:
        if image.camera_id in self.images:
            self.dropped += 1
        self.images[image.camera_id] = image
        self.ready.set()


def default_snapshot_directory() -> Path:
    """Under systemd, the unit's state directory (``StateDirectory=trackerd``: /var/lib/trackerd);
    otherwise ``trackerd-snapshots`` in the system's temporary directory."""
    state = os.environ.get("STATE_DIRECTORY")
    if state:
        return Path(state.split(":")[0]) / "snapshots"
    return Path(tempfile.gettempdir()) / "trackerd-snapshots"


def read_token(path: Path) -> str:
    """The token in ``path`` (ConfigError naming the file when it is missing or empty)."""
    try:
        text = read_bounded(path, 4096).decode("utf-8", "replace").strip()
    except OSError as err:
        raise ConfigError(f"{path}: cannot read the console token file ({err.strerror or err})") from None
    if not text:
        raise ConfigError(f"{path}: the console token file is empty")
    return text.splitlines()[0].strip()


class ConsoleServer:
    """The console for one pipeline: start() binds (errors raise there), stop() within a second."""

    def __init__(self, pipeline: Any, tap: ConsoleTap, *, listen: str | None = None, camera_info: Any = None) -> None:
        self.pipeline = pipeline
        self.tap = tap
        rig = pipeline.rig
        self.config = rig.console
        self.listen = listen or self.config.listen
        self.host, self.port = split_listen(self.listen)
        self.token = read_token(self.config.token_file) if self.config.token_file is not None else None
        self.snapshot_directory = self.config.snapshot_directory or default_snapshot_directory()
        self.logbook = Logbook()
        self._pages: set[_Page] = set()
        self._dropped_by_gone_pages = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._runner: web.AppRunner | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._start_error: BaseException | None = None
        self._stop_event: asyncio.Event | None = None
        self.frames = FrameThread(tap, rig, self._images_from_thread, self.snapshot_directory, camera_info)
        self.actions = Actions(pipeline, tap, self.frames)
        self.registry = registry_for(tap, self._extra_metrics)
        self._static = resources.files("trackerd.console") / "static"

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    # ------------------------------------------------------------------ lifecycle (caller's thread)

    def start(self) -> None:
        self._thread = threading.Thread(target=self._serve, name="trackerd-console", daemon=True)
        self._thread.start()
        self._started.wait(10.0)
        if self._start_error is not None:
            raise self._start_error
        logging.getLogger("trackerd").addHandler(self.logbook)
        self.frames.start()

    def begin_stop(self) -> None:
        """Ask the server and the frame thread to stop, without waiting (the daemon stops its
        pipeline meanwhile; :meth:`stop` then waits)."""
        logging.getLogger("trackerd").removeHandler(self.logbook)
        self.frames.begin_stop()
        loop, event = self._loop, self._stop_event
        if loop is not None and event is not None and not loop.is_closed():
            loop.call_soon_threadsafe(event.set)

    def stop(self) -> None:
        """Stop and wait (at most about :data:`STOP_TIMEOUT_S`); idempotent."""
        start = time.monotonic()
        self.begin_stop()
        self.frames.stop()
        if self._thread is not None:
            self._thread.join(max(0.0, STOP_TIMEOUT_S + 0.3 - (time.monotonic() - start)))
            if self._thread.is_alive():
                log.warning("console: the web server did not stop in time; leaving it")
        log.debug("console: stopped in %.0f ms", (time.monotonic() - start) * 1e3)

    # ------------------------------------------------------------------ the server's thread

    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        except BaseException as err:
            if not self._started.is_set():
                self._start_error = err
            else:
                log.exception("console: the web server failed")
        finally:
            self._started.set()
            loop.close()

    async def _main(self) -> None:
        self._stop_event = asyncio.Event()
        app = web.Application(middlewares=[self._auth], client_max_size=64 * 1024)
        app.add_routes([
            web.get("/", self._index),
            web.get("/static/{name}", self._static_file),
            web.get("/ws", self._websocket),
            web.get("/api/info", self._info),
            web.get("/api/status", self._status),
            web.post("/api/snapshot", self._snapshot),
            web.get("/snapshots/{name}/{file}", self._snapshot_file),
            web.post("/api/recording/{action}", self._recording),
            web.post("/api/check", self._check_start),
            web.get("/api/check", self._check_progress),
            web.get("/metrics", self._metrics),
            web.get("/healthz", self._healthz),
        ])
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=STOP_TIMEOUT_S / 2)
        await runner.setup()
        self._runner = runner
        try:
            await web.TCPSite(runner, self.host, self.port, reuse_address=True).start()
        except OSError as err:
            await runner.cleanup()
            raise TrackerdError(
                f"console: cannot listen on {self.listen}: {err.strerror or err}; give --console ADDR,"
                " or [console] enabled = false in the rig"
            ) from None
        self._started.set()
        pusher = asyncio.ensure_future(self._push_loop())
        await self._stop_event.wait()
        pusher.cancel()
        began = time.monotonic()
        # All pages at once, each given a moment to answer the close (a stuck one is not waited for).
        closing = [asyncio.wait_for(page.ws.close(code=1001, message=b"daemon stopping"), 0.1)
                   for page in list(self._pages)]
        await asyncio.gather(*closing, return_exceptions=True)
        log.debug("console: pages closed in %.0f ms", (time.monotonic() - began) * 1e3)
        try:
            await asyncio.wait_for(runner.cleanup(), STOP_TIMEOUT_S)
        except TimeoutError:
            log.warning("console: connections still open at stop were abandoned")

    # ------------------------------------------------------------------ access

    @web.middleware
    async def _auth(self, request: web.Request, handler: Any) -> web.StreamResponse:
        refused = self._cross_site(request)
        if refused is not None:
            return web.json_response({"error": refused}, status=403)
        if self.token is None:
            return await handler(request)
        given = request.query.get("token") or request.cookies.get(COOKIE)
        header = request.headers.get("Authorization", "")
        if header.startswith("Bearer "):
            given = header.removeprefix("Bearer ").strip()
        if given is None or not secrets.compare_digest(given.encode(), self.token.encode()):
            return web.json_response({"error": "the console needs its token (?token=... or Authorization: Bearer)"},
                                     status=401)
        response = await handler(request)
        if "token" in request.query and not response.prepared:
            response.set_cookie(COOKIE, self.token, httponly=True, samesite="Strict")
        return response

    def _cross_site(self, request: web.Request) -> str | None:
        """Why a request that another web site could have made the operator's browser send is
        refused, else None.

        Without a token, being on the loopback address is the console's only protection, and any
        page open in a browser on this machine can make requests to it: actions must carry a header
        such a page cannot add without the console's consent (it answers no CORS preflight), the
        WebSocket must come from the console's own page (Origin), and the Host must be this
        machine's name for it (a DNS name pointed at 127.0.0.1 by another site does not pass).
        """
        if request.method == "POST" and ACTION_HEADER not in request.headers:
            return f"actions need the header {ACTION_HEADER} (the console's page and `trackerd ctl` send it)"
        origin = request.headers.get("Origin")
        # Behind a reverse proxy the page's origin is the proxy's, which it names in X-Forwarded-Host.
        hosts = {request.host, request.headers.get("X-Forwarded-Host")}
        if request.path == "/ws" and origin is not None and origin.split("://", 1)[-1] not in hosts:
            return f"a WebSocket from {origin} is not the console's page"
        if self.token is None and request.host.rsplit(":", 1)[0].strip("[]") not in LOCAL_NAMES:
            return f"Host {request.host} is not this machine's (use 127.0.0.1, or give the console a token)"
        return None

    # ------------------------------------------------------------------ the page

    async def _index(self, _request: web.Request) -> web.Response:
        text = (self._static / "index.html").read_text(encoding="utf-8")
        return web.Response(text=text, content_type="text/html", headers={"Cache-Control": "no-store"})

    async def _static_file(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        types = {".js": "text/javascript", ".css": "text/css", ".svg": "image/svg+xml"}
        suffix = Path(name).suffix
        if "/" in name or suffix not in types:
            raise web.HTTPNotFound()
        path = self._static / name
        if not path.is_file():
            raise web.HTTPNotFound()
        return web.Response(body=path.read_bytes(), content_type=types[suffix], headers={"Cache-Control": "no-store"})

    async def _info(self, _request: web.Request) -> web.Response:
        return web.json_response(self.actions.info())

    async def _status(self, _request: web.Request) -> web.Response:
        status = self.tap.status
        return web.json_response({"status": None if status is None else status.model_dump(mode="json"),
                                  "recording": self.actions.recording_state(),
                                  "check": self.actions.check_progress()})

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=4096)
        await ws.prepare(request)
        page = _Page(ws)
        self._pages.add(page)
        self._viewers_changed()
        page.put_text(json.dumps({"type": "info", **self.actions.info()}))
        self._queue_status(page, since=0)
        sender = asyncio.ensure_future(self._send_loop(page))
        try:
            async for message in ws:
                if message.type in (WSMsgType.ERROR, WSMsgType.CLOSE):
                    break
        finally:
            sender.cancel()
            self._pages.discard(page)
            self._dropped_by_gone_pages += page.dropped
            self._viewers_changed()
        return ws

    def _viewers_changed(self) -> None:
        count = len(self._pages)
        self.tap.messages_wanted = count > 0
        if count == 0:
            self.tap.messages.clear()
        self.frames.set_viewers(count)

    async def _send_loop(self, page: _Page) -> None:
        while not page.ws.closed:
            await page.ready.wait()
            page.ready.clear()
            texts, page.texts = page.texts, []
            images, page.images = list(page.images.values()), {}
            try:
                for text in texts:
                    await page.ws.send_str(text)
                for image in images:
                    header = json.dumps(image.header).encode()
                    await page.ws.send_bytes(struct.pack(">I", len(header)) + header + image.jpeg)
            except (ConnectionError, RuntimeError):
                return

    def _images_from_thread(self, images: list[CameraImage]) -> None:
        """Called on the frame thread: hand the images to the loop (never waits)."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._deliver_images, images)

    def _deliver_images(self, images: list[CameraImage]) -> None:
        for page in self._pages:
            for image in images:
                page.put_image(image)

    async def _push_loop(self) -> None:
        last_status = None
        warnings_seen = self.logbook.serial
        while True:
            await asyncio.sleep(PUSH_EVERY_S)
            if not self._pages:
                last_status, warnings_seen = None, self.logbook.serial
                continue
            messages = []
            while self.tap.messages:
                messages.append(self.tap.messages.popleft())
            if messages:
                text = json.dumps({"type": "fixes", "messages": [m.model_dump(mode="json") for m in messages]})
                for page in self._pages:
                    page.put_text(text)
            status = self.tap.status
            new_warnings = self.logbook.since(warnings_seen)
            if status is not last_status or new_warnings:
                last_status = status
                if new_warnings:
                    warnings_seen = new_warnings[-1]["serial"]
                text = self._status_text(new_warnings)
                for page in self._pages:
                    page.put_text(text)

    def _status_text(self, warnings: list[dict[str, Any]]) -> str:
        status = self.tap.status
        return json.dumps({
            "type": "status",
            "status": None if status is None else status.model_dump(mode="json"),
            "recording": self.actions.recording_state(),
            "check": self.actions.check_progress(),
            "warnings": warnings,
        })

    def _queue_status(self, page: _Page, since: int) -> None:
        page.put_text(self._status_text(self.logbook.since(since)))

    def _broadcast_status(self) -> None:
        text = self._status_text([])
        for page in self._pages:
            page.put_text(text)

    # ------------------------------------------------------------------ actions

    async def _snapshot(self, request: web.Request) -> web.Response:
        wanted = request.query.get("name")
        if wanted is not None and not (0 < len(wanted) <= 64 and all(c.isalnum() or c in "-_." for c in wanted)
                                       and not wanted.startswith(".")):
            return web.json_response({"error": "name: letters, digits, '-', '_' and '.' only (at most 64)"},
                                     status=400)
        loop = asyncio.get_running_loop()
        future: asyncio.Future = loop.create_future()

        def done(result: Any) -> None:
            loop.call_soon_threadsafe(lambda: future.done() or future.set_result(result))

        name = self.frames.request_snapshot(done, wanted)
        try:
            result = await asyncio.wait_for(future, SNAPSHOT_TIMEOUT_S)
        except TimeoutError:
            self.frames.cancel_snapshot(name)
            return web.json_response(
                {"error": f"no pair was processed within {SNAPSHOT_TIMEOUT_S:g} s (are the cameras streaming?)"},
                status=503)
        if isinstance(result, BaseException):
            return web.json_response({"error": f"the snapshot could not be saved: {result}"}, status=500)
        folder = self.snapshot_directory / name
        return web.json_response({
            "name": name, "folder": str(folder),
            "files": [{"name": p.name, "url": f"snapshots/{name}/{p.name}", "bytes": p.stat().st_size}
                      for p in result],
        })

    async def _snapshot_file(self, request: web.Request) -> web.StreamResponse:
        name, file = request.match_info["name"], request.match_info["file"]
        if name.startswith(".") or any(c in name + file for c in "/\\") or file.startswith("."):
            raise web.HTTPNotFound()
        path = self.snapshot_directory / name / file
        if not path.is_file():
            raise web.HTTPNotFound()
        return web.FileResponse(path, headers={"Content-Disposition": f'attachment; filename="{file}"'})

    async def _recording(self, request: web.Request) -> web.Response:
        action = request.match_info["action"]
        if action not in ("start", "stop"):
            raise web.HTTPNotFound()
        ok, text = self.actions.recording(action)
        self._broadcast_status()
        return web.json_response({"ok": ok, "message": text, "recording": self.actions.recording_state()},
                                 status=200 if ok else 409)

    async def _check_start(self, request: web.Request) -> web.Response:
        try:
            fixes = int(request.query.get("fixes", "200"))
        except ValueError:
            return web.json_response({"error": "fixes must be a whole number"}, status=400)
        ok, text = self.actions.start_check(fixes)
        return web.json_response({"ok": ok, "message": text, "check": self.actions.check_progress()},
                                 status=200 if ok else 409)

    async def _check_progress(self, _request: web.Request) -> web.Response:
        return web.json_response(self.actions.check_progress())

    # ------------------------------------------------------------------ monitoring

    async def _metrics(self, _request: web.Request) -> web.Response:
        body = exposition(self.registry)
        return web.Response(body=body, headers={"Content-Type": "text/plain; version=0.0.4; charset=utf-8"})

    async def _healthz(self, _request: web.Request) -> web.Response:
        healthy, detail = self.actions.health()
        return web.json_response(detail, status=200 if healthy else 503)

    def _extra_metrics(self) -> dict[str, Any]:
        dropped = self._dropped_by_gone_pages + sum(page.dropped for page in self._pages)
        return {"console_viewers": len(self._pages), "console_dropped_for_slow_pages": dropped}
