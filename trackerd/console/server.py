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

The open pages and what is pushed to them are :mod:`trackerd.console.pages`'s; who may connect,
:mod:`trackerd.console.access`'s.
"""

from __future__ import annotations

import asyncio
import logging
import os
import tempfile
import threading
import time
from importlib import resources
from pathlib import Path
from typing import Any

from aiohttp import web

from trackerd.config.console import split_listen
from trackerd.console.access import access_middleware, json_errors, read_token, token_exposed
from trackerd.console.actions import Actions
from trackerd.console.frames import CameraImage, FrameThread
from trackerd.console.logbook import Logbook
from trackerd.console.metrics import exposition, registry_for
from trackerd.console.pages import Pages
from trackerd.errors import TrackerdError
from trackerd.pipeline.tap import ConsoleTap

log = logging.getLogger(__name__)


class _MalformedRequests(logging.Filter):
    """aiohttp logs a request it cannot parse (a URL or header line over 8190 bytes, a bad request line)
    as an ERROR with its traceback, although it answered 400 and nothing is wrong with the daemon: anyone
    who reaches the port could fill the journal with error-priority tracebacks. Such a record becomes one
    debug line of the console's own."""

    def filter(self, record: logging.LogRecord) -> bool:
        from aiohttp.http_exceptions import HttpProcessingError

        error = record.exc_info[1] if record.exc_info else None
        if isinstance(error, HttpProcessingError):
            log.debug("refused a malformed request (%s: %s)", type(error).__name__, error.message)
            return False
        return True


MALFORMED_REQUESTS = _MalformedRequests()

SNAPSHOT_TIMEOUT_S = 10.0
STOP_TIMEOUT_S = 0.6


def default_snapshot_directory() -> Path:
    """Under systemd, the unit's state directory (``StateDirectory=trackerd``: /var/lib/trackerd);
    otherwise ``trackerd-snapshots-UID`` in the system's temporary directory, the user's own (one name
    for every user there, 0755, let each see the others' snapshots, and let anyone who made it first,
    or a link by that name, decide where root's went: :func:`trackerd.console.frames.own_directory`)."""
    state = os.environ.get("STATE_DIRECTORY")
    if state:
        return Path(state.split(":")[0]) / "snapshots"
    return Path(tempfile.gettempdir()) / f"trackerd-snapshots-{os.getuid()}"


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
        exposed = token_exposed(self.config.token_file) if self.config.token_file is not None else None
        if exposed is not None:
            log.warning("%s", exposed)
        self.snapshot_directory = self.config.snapshot_directory or default_snapshot_directory()
        self.logbook = Logbook()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._runner: web.AppRunner | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._start_error: BaseException | None = None
        self._stop_event: asyncio.Event | None = None
        private = self.config.snapshot_directory is None and "STATE_DIRECTORY" not in os.environ
        self.frames = FrameThread(
            tap, rig, self._images_from_thread, self.snapshot_directory, camera_info, private_snapshots=private
        )
        self.actions = Actions(pipeline, tap, self.frames)
        self.pages = Pages(tap, self.frames, self.actions, self.logbook)
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
        logging.getLogger("aiohttp.server").addFilter(MALFORMED_REQUESTS)  # once: a set of filters
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
        app = web.Application(middlewares=[json_errors, access_middleware(self.token)], client_max_size=64 * 1024)
        app.add_routes(
            [
                web.get("/", self._index),
                web.get("/static/{name}", self._static_file),
                web.get("/ws", self.pages.websocket),
                web.get("/api/info", self._info),
                web.get("/api/status", self._status),
                web.post("/api/snapshot", self._snapshot),
                web.get("/snapshots/{name}/{file}", self._snapshot_file),
                web.post("/api/recording/{action}", self._recording),
                web.post("/api/check", self._check_start),
                web.get("/api/check", self._check_progress),
                web.get("/metrics", self._metrics),
                web.get("/healthz", self._healthz),
            ]
        )
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
        pusher = asyncio.ensure_future(self.pages.push_loop())
        await self._stop_event.wait()
        pusher.cancel()
        began = time.monotonic()
        # All pages at once, each given a moment to answer the close (a stuck one is not waited for).
        closing = [
            asyncio.wait_for(page.ws.close(code=1001, message=b"daemon stopping"), 0.1)
            for page in list(self.pages.open)
        ]
        await asyncio.gather(*closing, return_exceptions=True)
        log.debug("console: pages closed in %.0f ms", (time.monotonic() - began) * 1e3)
        try:
            await asyncio.wait_for(runner.cleanup(), STOP_TIMEOUT_S)
        except TimeoutError:
            log.warning("console: connections still open at stop were abandoned")

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
        return web.json_response(
            {
                "status": None if status is None else status.model_dump(mode="json"),
                "recording": self.actions.recording_state(),
                "check": self.actions.check_progress(),
            }
        )

    def _images_from_thread(self, images: list[CameraImage]) -> None:
        """Called on the frame thread: hand the images to the loop (never waits)."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self.pages.deliver_images, images)

    # ------------------------------------------------------------------ actions

    async def _snapshot(self, request: web.Request) -> web.Response:
        wanted = request.query.get("name")
        if wanted is not None and not (
            0 < len(wanted) <= 64 and all(c.isalnum() or c in "-_." for c in wanted) and not wanted.startswith(".")
        ):
            return web.json_response({"error": "name: letters, digits, '-', '_' and '.' only (at most 64)"}, status=400)
        loop = asyncio.get_running_loop()
        future: asyncio.Future[Any] = loop.create_future()

        def done(result: Any) -> None:
            def settle() -> None:
                if not future.done():
                    future.set_result(result)

            loop.call_soon_threadsafe(settle)

        try:
            name = self.frames.request_snapshot(done, wanted)
        except OSError as err:
            where = err.filename or self.snapshot_directory
            return web.json_response({"error": f"{where}: cannot save snapshots there: {err.strerror}"}, status=500)
        try:
            result = await asyncio.wait_for(future, SNAPSHOT_TIMEOUT_S)
        except TimeoutError:
            self.frames.cancel_snapshot(name)
            return web.json_response(
                {"error": f"no pair was processed within {SNAPSHOT_TIMEOUT_S:g} s (are the cameras streaming?)"},
                status=503,
            )
        if isinstance(result, BaseException):
            return web.json_response({"error": f"the snapshot could not be saved: {result}"}, status=500)
        folder = self.snapshot_directory / name
        return web.json_response(
            {
                "name": name,
                "folder": str(folder),
                "files": [
                    {"name": p.name, "url": f"snapshots/{name}/{p.name}", "bytes": p.stat().st_size} for p in result
                ],
            }
        )

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
        self.pages.broadcast_status()
        return web.json_response(
            {"ok": ok, "message": text, "recording": self.actions.recording_state()}, status=200 if ok else 409
        )

    async def _check_start(self, request: web.Request) -> web.Response:
        try:
            fixes = int(request.query.get("fixes", "200"))
        except ValueError:
            return web.json_response({"error": "fixes must be a whole number"}, status=400)
        try:
            ok, text = self.actions.start_check(fixes)
        except ValueError as err:
            return web.json_response({"error": str(err)}, status=400)
        return web.json_response(
            {"ok": ok, "message": text, "check": self.actions.check_progress()}, status=200 if ok else 409
        )

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
        return {"console_viewers": len(self.pages.open), "console_dropped_for_slow_pages": self.pages.dropped}
