"""The console's open pages and what is pushed to them over their WebSockets.

A slow page never holds up the daemon: each page has one slot per camera image and a bounded
list of other messages, and what it has not taken when the next one comes is dropped (and counted).
"""

from __future__ import annotations

import asyncio
import json
import struct
from typing import Any

from aiohttp import WSMsgType, web

from trackerd.console.actions import Actions
from trackerd.console.frames import CameraImage, FrameThread
from trackerd.console.logbook import Logbook
from trackerd.pipeline.tap import ConsoleTap

PUSH_EVERY_S = 0.1
"""How often hits, status and warnings are pushed to the open pages."""
TEXT_QUEUE = 64
"""Text messages waiting for a slow page before the oldest are dropped."""


class Page:
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


class Pages:
    """Every open page (on the server's event loop only): the WebSocket route, the pushing of the
    pipeline's messages, status and warnings, and the camera images the frame thread makes."""

    def __init__(self, tap: ConsoleTap, frames: FrameThread, actions: Actions, logbook: Logbook) -> None:
        self.tap = tap
        self.frames = frames
        self.actions = actions
        self.logbook = logbook
        self.open: set[Page] = set()
        self._dropped_by_gone_pages = 0

    @property
    def dropped(self) -> int:
        """Images and messages pages had not taken when the next came, since start."""
        return self._dropped_by_gone_pages + sum(page.dropped for page in self.open)

    async def websocket(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=4096)
        await ws.prepare(request)
        page = Page(ws)
        self.open.add(page)
        self._viewers_changed()
        page.put_text(json.dumps({"type": "info", **self.actions.info()}))
        page.put_text(self._status_text(self.logbook.since(0)))
        sender = asyncio.ensure_future(self._send_loop(page))
        try:
            async for message in ws:
                if message.type in (WSMsgType.ERROR, WSMsgType.CLOSE):
                    break
        finally:
            sender.cancel()
            self.open.discard(page)
            self._dropped_by_gone_pages += page.dropped
            self._viewers_changed()
        return ws

    def _viewers_changed(self) -> None:
        count = len(self.open)
        self.tap.messages_wanted = count > 0
        if count == 0:
            self.tap.messages.clear()
        self.frames.set_viewers(count)

    async def _send_loop(self, page: Page) -> None:
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

    def deliver_images(self, images: list[CameraImage]) -> None:
        for page in self.open:
            for image in images:
                page.put_image(image)

    async def push_loop(self) -> None:
        """Every PUSH_EVERY_S: the pipeline's new messages, and the status when it or the warnings changed."""
        last_status = None
        warnings_seen = self.logbook.serial
        while True:
            await asyncio.sleep(PUSH_EVERY_S)
            if not self.open:
                last_status, warnings_seen = None, self.logbook.serial
                continue
            messages = []
            while self.tap.messages:
                messages.append(self.tap.messages.popleft())
            if messages:
                text = json.dumps({"type": "fixes", "messages": [m.model_dump(mode="json") for m in messages]})
                for page in self.open:
                    page.put_text(text)
            status = self.tap.status
            new_warnings = self.logbook.since(warnings_seen)
            if status is not last_status or new_warnings:
                last_status = status
                if new_warnings:
                    warnings_seen = new_warnings[-1]["serial"]
                text = self._status_text(new_warnings)
                for page in self.open:
                    page.put_text(text)

    def _status_text(self, warnings: list[dict[str, Any]]) -> str:
        status = self.tap.status
        return json.dumps(
            {
                "type": "status",
                "status": None if status is None else status.model_dump(mode="json"),
                "recording": self.actions.recording_state(),
                "check": self.actions.check_progress(),
                "warnings": warnings,
            }
        )

    def broadcast_status(self) -> None:
        text = self._status_text([])
        for page in self.open:
            page.put_text(text)
