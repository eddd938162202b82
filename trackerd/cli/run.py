"""`trackerd run`: the real-time service.

Opens the rig's cameras through Aravis, tracks the pointer in every synchronized
pair and publishes hits, pointer poses and status over ZeroMQ until stopped.

Signals (handled here and only here): SIGTERM and SIGINT stop cleanly (cameras
released, sockets closed, exit 0 within about a second); SIGHUP re-reads the
rig file and applies it when it validates, or keeps the running configuration
and logs why not. A crashed pipeline thread exits with status 1.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from trackerd import logs
from trackerd.cli._args import add_console_option, positive_seconds
from trackerd.config.loader import load_rig, with_console
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError, TrackerdError
from trackerd.sdnotify import SdNotify

if TYPE_CHECKING:
    from trackerd.acquisition.live import LivePairSource
    from trackerd.acquisition.source import PairSource
    from trackerd.acquisition.worker import OpenHook
    from trackerd.console.server import ConsoleServer
    from trackerd.pipeline.daemon import Pipeline
    from trackerd.pipeline.extensions import ExtensionContext, ExtensionKind, PipelineExtension
    from trackerd.publish import Publisher
    from trackerd.recording.cameras import CameraInfo

log = logging.getLogger("trackerd.run")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run the tracking daemon on the rig's cameras",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--config", required=True, help="rig TOML file, e.g. /etc/trackerd/rig.toml")
    parser.add_argument(
        "--seconds", type=positive_seconds, help="stop after this many seconds (default: run until stopped)"
    )
    add_console_option(parser)
    parser.set_defaults(handler=run_command)


def aravis_source(rig: RigConfig, on_open: OpenHook | None = None) -> LivePairSource:
    """The daemon's cameras; ``on_open(camera_id, camera)`` runs after each (re)connection."""
    from trackerd.acquisition.live import LivePairSource

    # Cameras switched on after the host: keep waiting for them.
    return LivePairSource(rig, wait_for_cameras=True, on_open=on_open)


def zmq_publisher(rig: RigConfig) -> Publisher:
    from trackerd.publish import Publisher

    return Publisher(rig.outputs.zmq)


def run_command(args: argparse.Namespace) -> int:
    from trackerd.recording.cameras import CameraInfo

    path = Path(args.config)
    rig = with_console(load_rig(path).config, args.console)
    # What each camera says about itself, noted as it opens, for recordings made on demand.
    info = CameraInfo()
    return serve(
        rig,
        path,
        lambda r: aravis_source(r, on_open=info.on_open),
        seconds=args.seconds,
        camera_info=info,
        exit_if_stuck=True,
    )


def extension_kinds() -> tuple[ExtensionKind, ...]:
    """The kinds of extension the daemon runs, in a fixed order: recording sees pairs before interaction.

    Each is imported here, by name: they and their dependencies are part of trackerd (pyproject's
    dependencies), so one that cannot be imported is a broken installation and fails the start
    with its ImportError, never skipped."""
    from trackerd.interaction.extension import create as interaction_extension
    from trackerd.pipeline.extensions import ExtensionKind
    from trackerd.recording.extension import create as recording_extension

    return (ExtensionKind("recording", recording_extension), ExtensionKind("interaction", interaction_extension))


def build_extensions(rig: RigConfig, context: ExtensionContext) -> list[PipelineExtension]:
    """The extensions the rig asks for (:func:`extension_kinds`, in their order). What the rig asks of
    one is checked by its ``create``; a ConfigError then names the rig file, as the loader's own
    errors do."""
    built = []
    for kind in extension_kinds():
        try:
            extension = kind.create(rig, context)
        except ConfigError as err:
            if context.rig_file is None:
                raise
            raise err.in_file(context.rig_file) from None
        if extension is not None:
            built.append(extension)
    return built


def serve(
    rig: RigConfig,
    path: Path | None,
    source_factory: Callable[[RigConfig], PairSource],
    *,
    seconds: float | None = None,
    publisher_factory: Callable[[RigConfig], Publisher] = zmq_publisher,
    banner: str | None = None,
    clock_offset_ns: int | None = None,
    until: Callable[[Pipeline], bool] | None = None,
    camera_info: CameraInfo | None = None,
    exit_if_stuck: bool = False,
    replay: bool = False,
) -> int:
    """Run a pipeline until a signal (or ``seconds``); the CLI's `run` and `replay` share it.

    ``clock_offset_ns`` fixes the pipeline's monotonic-to-epoch offset (a replay publishes the
    recorded capture times with it); ``until(pipeline)``, checked every 0.1 s, ends the run when
    it returns True (a replay that has published its last pair). ``path`` (the rig file) and
    ``camera_info`` go into the metadata of recordings made on demand. ``exit_if_stuck``: when a
    camera thread is still searching for its camera once everything is stopped, end the process
    here (`trackerd run`, which has nothing left to do; not for callers that clean up after).
    ``replay``: the pairs come from a recording, and what is published must follow from them
    alone (trackerd.pipeline.extensions.ExtensionContext.replay).
    """
    from trackerd.pipeline.daemon import Pipeline
    from trackerd.pipeline.extensions import ExtensionContext

    notifier = SdNotify()
    if clock_offset_ns is None:
        clock_offset_ns = time.time_ns() - time.monotonic_ns()
    context = ExtensionContext(
        rig_file=path.resolve() if path is not None else None,
        camera_info=camera_info,
        clock_offset_ns=clock_offset_ns,
        replay=replay,
    )
    tap = None
    if rig.console.enabled:
        from trackerd.pipeline.tap import ConsoleTap

        tap = ConsoleTap()
    pipeline = Pipeline(
        rig,
        source_factory,
        publisher_factory,
        notifier,
        extensions=build_extensions(rig, context),
        extension_kinds=extension_kinds(),
        extension_context=context,
        clock_offset_ns=clock_offset_ns,
        tap=tap,
    )
    console = None
    stop = threading.Event()
    reload_requested = threading.Event()

    def on_stop(signum: int, _frame: object) -> None:
        log.info("%s: stopping", signal.Signals(signum).name)
        stop.set()

    def on_hup(_signum: int, _frame: object) -> None:
        reload_requested.set()

    previous = {
        sig: signal.signal(sig, handler)
        for sig, handler in ((signal.SIGTERM, on_stop), (signal.SIGINT, on_stop), (signal.SIGHUP, on_hup))
    }
    try:
        pipeline.start()
        if tap is not None:
            from trackerd.console.server import ConsoleServer

            console = _start_console(ConsoleServer(pipeline, tap, camera_info=camera_info), rig)
        endpoints = ", ".join(pipeline.publisher.endpoints) if pipeline.publisher else "-"
        print(banner or f"trackerd {rig.name}: publishing on {endpoints} (Ctrl-C to stop)", file=sys.stderr, flush=True)
        if console is not None:
            print(f"trackerd {rig.name}: console at {console.url}", file=sys.stderr, flush=True)
        deadline = None if seconds is None else time.monotonic() + seconds
        while not stop.is_set():
            if pipeline.wait(0.1):
                break
            if reload_requested.is_set():
                reload_requested.clear()
                _reload(pipeline, path)
            if deadline is not None and time.monotonic() >= deadline:
                break
            if until is not None and until(pipeline):
                break
    except TrackerdError:
        raise
    finally:
        if console is not None:
            # Its server and the pipeline stop side by side: a page still open must not hold up the stop.
            console.begin_stop()
        pipeline.stop()
        if console is not None:
            console.stop()
        notifier.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    code = 0
    if pipeline.failure is not None:
        print(f"{logs.error_prefix()}trackerd: a pipeline thread crashed (traceback above); exiting", file=sys.stderr)
        code = 1
    if exit_if_stuck and getattr(pipeline.source, "abandoned_threads", None):
        # A camera thread is inside Aravis's discovery (up to a second, not interruptible) and holds
        # nothing: everything is released and closed, so exit now rather than when it returns
        # (the interpreter's finalisation would wait for it, two seconds and more).
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _start_console(console: ConsoleServer, rig: RigConfig) -> ConsoleServer | None:
    """Start the console; None when the default address is taken (another daemon, a replay beside
    it: the daemon runs on without it), TrackerdError when an address given for it is."""
    try:
        console.start()
    except TrackerdError as err:
        if "listen" in rig.console.model_fields_set:
            raise
        log.warning("%s; running without the console", err)
        return None
    return console


def _reload(pipeline: Pipeline, path: Path | None) -> None:
    if path is None:
        log.warning("SIGHUP: no configuration file to reload")
        return
    try:
        rig = load_rig(path).config
    except TrackerdError as err:
        log.error("SIGHUP: keeping the running configuration: %s", err)
        return
    except Exception as err:  # noqa: BLE001 - whatever the new file does, the daemon runs on
        log.error(
            "SIGHUP: keeping the running configuration: %s: cannot be read (%s: %s)", path, type(err).__name__, err
        )
        return
    pipeline.request_reload(rig)
    log.info("SIGHUP: reloading %s", path)
