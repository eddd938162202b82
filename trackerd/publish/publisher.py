"""The ZeroMQ publisher: an XPUB socket fed by a C-level proxy, with a last-value cache for ``status``.

Threads and sockets (all in one ZeroMQ context owned by the publisher)::

    caller's thread            proxy thread (libzmq, no GIL)           network
    inlet XPUB --inproc-->  frontend XSUB ==zmq_proxy==> backend XPUB  --> subscribers
    last-value thread:      lvc XPUB --inproc-^      |
                            capture SUB <--inproc-- capture PUB (statuses and subscriptions only)

ZeroMQ sockets are not thread-safe and a late joiner must get the current status
even while the pipeline is idle, so the network socket belongs to a proxy
thread. The proxy runs inside libzmq without holding the GIL, so forwarding
never waits for the pipeline's Python code. The last-value thread sees every
status and every subscription (through the proxy's capture socket, filtered to
those two) and answers a new subscription that covers ``status`` by sending the
last status again through its own socket into the proxy. docs/protocol.md, "Late
joiners", says why this was preferred to a request socket.

Nothing lost at start: a PUB drops what no known subscription covers, and the proxy's own
``status`` subscription reaches the inlet only once the proxy thread has run. The inlet and the
last-value thread's sender are therefore XPUBs, and the constructor waits until each has received
that subscription (``_await_status_subscription``); a status published right after construction
used to vanish whenever the proxy thread started late, and late joiners then got none.

Never blocking: the inlet is an XPUB with XPUB_NODROP, so a full hand-over queue
(HANDOVER_HWM) makes a non-blocking send fail (counted as dropped) instead of blocking; a full
subscriber queue (``send_hwm_messages``) drops that subscriber's messages
inside ZeroMQ and touches nobody else.
"""

from __future__ import annotations

import collections
import itertools
import logging
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from trackerd.config.models import ZmqOutput
from trackerd.errors import ConfigError, TrackerdError
from trackerd.publish.curve_keys import load_curve_key_pair
from trackerd.publish.messages import Message, StatusMessage, encode

log = logging.getLogger(__name__)

STATUS_TOPIC = b"status"
_POLL_MS = 200
_WIRING_TIMEOUT_MS = 5000
"""How long the constructor waits for the proxy thread to pass its subscription on; it takes well
under a millisecond unless the machine is starved."""
ANSWER_INTERVAL_S = 0.25
"""A new status subscriber is answered at most this often: the answer goes to every status subscriber
(a PUB socket cannot address one peer), so a peer sending subscriptions in a loop would otherwise make
every subscriber receive thousands of statuses a second. Subscriptions arriving within the interval
are answered together at its end: a late joiner waits at most this long for the last status."""
READ_BATCH = 100
"""Capture messages the last-value thread reads at a time; a full batch means a flood."""
READ_PAUSE_S = 0.002
"""Its pause after a full batch: under a flood it reads at most READ_BATCH / READ_PAUSE_S messages a
second (a few percent of a core) and libzmq drops the rest, so the pipeline keeps the interpreter."""
MAX_PEER_MESSAGE_BYTES = 4096
"""Largest message a subscriber may send upstream (a subscription is one byte and a topic prefix)."""
HANDOVER_HWM = 10_000
"""Messages the hand-over pipe holds while the proxy thread waits for a CPU (about 4 MB at most);
internal, unlike each subscriber's queue (send_hwm_messages)."""
_pipe_ids = itertools.count()


class PublishError(TrackerdError):
    """The publisher cannot bind its endpoints or is used after it was closed."""


def _authorized_keys_dir(path: Path, allow_empty: bool = False) -> Path:
    """The directory of client keys; an empty one is refused at start (a mistake: nobody could
    subscribe) but taken at a reload, where removing the last key must revoke it."""
    if not path.is_dir():
        raise ConfigError(f"{path}: curve_authorized_keys_dir is not a directory")
    if not any(path.glob("*.key")):
        if not allow_empty:
            raise ConfigError(
                f"{path}: no client public keys (*.key) in curve_authorized_keys_dir; nobody could subscribe"
            )
        log.warning("%s: no client public keys (*.key) left: no subscriber is let in until one is added", path)
    return path


def curve_keys(config: ZmqOutput, allow_no_clients: bool = False) -> tuple[bytes, bytes] | None:
    """The publisher's CURVE key pair (None without CURVE), its client keys' directory checked; ConfigError
    for anything unusable. What the daemon reads at start, and `config check --ready` with it (which allows
    a directory without keys: a reload takes it, to let nobody in)."""
    if config.curve_secret_key_file is None:
        return None
    if not zmq.has("curve"):
        raise ConfigError("outputs.zmq.curve_secret_key_file: this libzmq was built without CURVE")
    keys = load_curve_key_pair(config.curve_secret_key_file)
    if config.curve_authorized_keys_dir is not None:
        _authorized_keys_dir(config.curve_authorized_keys_dir, allow_empty=allow_no_clients)
    return keys


class Publisher:
    """Binds the configured endpoints and publishes messages; use from one thread only.

    ``clock`` gives ``publish_ns`` (nanoseconds since the UNIX epoch by default).
    Raises ConfigError for an insecure or unusable CURVE setup and PublishError
    when an endpoint cannot be bound; either way nothing is left running.
    """

    def __init__(self, config: ZmqOutput, clock: Callable[[], int] = time.time_ns) -> None:
        exposed = config.insecure_endpoints()
        if exposed:
            raise ConfigError(
                f"outputs.zmq.endpoints: {', '.join(exposed)} is reachable from the network; set"
                " curve_secret_key_file or allow_insecure_network = true"
            )
        keys = curve_keys(config)
        self.config = config
        self._clock = clock
        self._counts: dict[str, int] = {}
        self._dropped = 0
        self._closed = False
        self._auth: ThreadAuthenticator | None = None
        self._statuses_sent = 0
        self._context = zmq.Context()
        self._lvc = _LastValue(self._context)
        base = f"inproc://trackerd-publisher-{os.getpid()}-{next(_pipe_ids)}"
        try:
            if keys is not None:
                self._start_authenticator()
            xpub = self._bind(keys)
            sockets = self._wire(base, xpub)
        except BaseException:
            self._context.destroy(linger=0)
            if self._auth is not None:
                self._auth.stop()
            raise
        # Thread start is a full memory barrier, which is what moving a ZeroMQ socket to
        # another thread needs: from here on the proxy's sockets belong to the proxy thread.
        self._proxy = threading.Thread(target=_run_proxy, args=sockets, name="trackerd-zmq-proxy", daemon=True)
        self._proxy.start()
        try:
            deadline = time.monotonic() + _WIRING_TIMEOUT_MS / 1000.0
            _await_status_subscription(self._inlet, "the publisher's inlet", deadline)
            _await_status_subscription(self._lvc.sender, "the last-value thread", deadline)
        except BaseException:
            self._closed = True
            self._shut_down()
            raise
        self._lvc.start()

    def _wire(self, base: str, xpub: zmq.Socket) -> tuple[zmq.Socket, ...]:
        """Create and connect the inproc sockets; returns the proxy thread's sockets."""
        hwm = max(HANDOVER_HWM, self.config.send_hwm_messages)
        frontend = self._context.socket(zmq.XSUB)
        frontend.setsockopt(zmq.RCVHWM, hwm)
        frontend.bind(f"{base}-in")
        # The proxy's own subscription: statuses always reach the capture (the last-value cache),
        # other topics only while someone subscribes. XSUB counts subscriptions per prefix, so a
        # departing status subscriber cannot cancel this one.
        frontend.send(b"\x01" + STATUS_TOPIC)
        capture = self._context.socket(zmq.PUB)
        capture.bind(f"{base}-capture")
        control = self._context.socket(zmq.PAIR)
        control.bind(f"{base}-control")
        self._control = self._context.socket(zmq.PAIR)
        self._control.setsockopt(zmq.LINGER, 0)
        self._control.connect(f"{base}-control")
        # An XPUB, not a PUB, only so that the constructor can see the proxy's subscription arrive.
        self._inlet = self._context.socket(zmq.XPUB)
        self._inlet.setsockopt(zmq.SNDHWM, hwm)
        self._inlet.setsockopt(zmq.XPUB_NODROP, 1)
        self._inlet.setsockopt(zmq.LINGER, 0)
        self._inlet.connect(f"{base}-in")
        self._lvc.connect(f"{base}-capture", f"{base}-in")
        return frontend, xpub, capture, control

    def _start_authenticator(self) -> None:
        self._auth = ThreadAuthenticator(self._context, log=logging.getLogger("trackerd.publish.auth"))
        self._auth.start()
        self.reload_authorized_keys()

    def reload_authorized_keys(self, *, allow_empty: bool = False) -> None:
        """Read curve_authorized_keys_dir again (after SIGHUP, say); no-op without CURVE.
        ``allow_empty``: a directory with no keys left lets nobody in (a reload), rather than being an error."""
        if self._auth is None:
            return
        directory = self.config.curve_authorized_keys_dir
        if directory is None:
            self._auth.configure_curve(domain="*", location=zmq.auth.CURVE_ALLOW_ANY)
        else:
            location = _authorized_keys_dir(directory, allow_empty=allow_empty)
            self._auth.configure_curve(domain="*", location=os.fspath(location))

    def _bind(self, keys: tuple[bytes, bytes] | None) -> zmq.Socket:
        xpub = self._context.socket(zmq.XPUB)
        if any("[" in endpoint for endpoint in self.config.endpoints):
            # Without it libzmq cannot bind tcp://[::1]:...; only then, since it also makes the
            # IPv4 endpoints read back as [::ffff:127.0.0.1].
            xpub.setsockopt(zmq.IPV6, 1)
        xpub.setsockopt(zmq.SNDHWM, self.config.send_hwm_messages)
        xpub.setsockopt(zmq.LINGER, self.config.linger_ms)
        # Pass every subscription and unsubscription upstream, so a second status subscriber is
        # seen (and answered) too, and the frontend's per-prefix counts stay balanced.
        xpub.setsockopt(zmq.XPUB_VERBOSER, 1)
        # Peers send only subscriptions (a byte and a topic prefix): one sending more is cut off at
        # once, rather than having libzmq hold a message of any size for it.
        xpub.setsockopt(zmq.MAXMSGSIZE, MAX_PEER_MESSAGE_BYTES)
        # A dead TCP peer would otherwise keep its queue until the kernel gives up (hours).
        xpub.setsockopt(zmq.HEARTBEAT_IVL, 2000)
        xpub.setsockopt(zmq.HEARTBEAT_TIMEOUT, 6000)
        if keys is not None:
            xpub.setsockopt(zmq.CURVE_SERVER, 1)
            xpub.setsockopt(zmq.CURVE_PUBLICKEY, keys[0])
            xpub.setsockopt(zmq.CURVE_SECRETKEY, keys[1])
        self.endpoints: list[str] = []
        """The bound endpoints, with the port chosen for ``*``."""
        for endpoint in self.config.endpoints:
            try:
                xpub.bind(endpoint)
            except zmq.ZMQError as err:
                raise PublishError(f"outputs.zmq.endpoints: cannot bind {endpoint}: {err.strerror}") from err
            self.endpoints.append(xpub.getsockopt_string(zmq.LAST_ENDPOINT))
        return xpub

    # ------------------------------------------------------------------ publishing

    def publish(self, message: Message) -> bool:
        """Stamp ``publish_ns`` and send; never blocks. False when the message was dropped (queue full)."""
        if self._closed:
            raise PublishError("the publisher is closed")
        return self._send(*encode(message, {"publish_ns": self._clock()}))

    def publish_status(self, message: StatusMessage) -> bool:
        """Publish a status with the publisher's counters filled in; it becomes the last value for late joiners."""
        if self._closed:
            raise PublishError("the publisher is closed")
        counts = dict(self._counts)
        counts["status"] = counts.get("status", 0) + 1
        return self._send(
            *encode(message, {"publish_ns": self._clock(), "messages": counts, "dropped_messages": self._dropped})
        )

    def _send(self, topic: bytes, payload: bytes) -> bool:
        if topic == STATUS_TOPIC:
            # Told to the last-value thread before it can pass the proxy, so that the thread knows it
            # from statuses a peer sends upstream (which the proxy's capture shows it too).
            self._lvc.expect(payload)
        try:
            self._inlet.send_multipart((topic, payload), flags=zmq.NOBLOCK)
        except zmq.Again:
            if topic == STATUS_TOPIC:
                self._lvc.forget(payload)
            self._dropped += 1
            return False
        name = topic.decode("ascii")
        self._counts[name] = self._counts.get(name, 0) + 1
        if topic == STATUS_TOPIC:
            self._lvc.sent(payload)
            self._statuses_sent += 1
            # About once a second: the subscriptions the inlet reports are never needed after
            # start, and would pile up as subscribers come and go.
            _discard_subscriptions(self._inlet)
        return True

    def clock_ns_from_monotonic(self, monotonic_ns: int) -> int:
        """A ``time.monotonic_ns()`` instant (a frame's capture time) on the publisher's clock."""
        return self._clock() - (time.monotonic_ns() - monotonic_ns)

    @property
    def counts(self) -> dict[str, int]:
        """Messages handed to ZeroMQ since start, by topic."""
        return dict(self._counts)

    @property
    def dropped(self) -> int:
        """Messages dropped because the hand-over queue was full."""
        return self._dropped

    # ------------------------------------------------------------------ lifetime

    def close(self) -> None:
        """Flush the last status (for at most ``linger_ms``), unbind and stop every thread; idempotent."""
        if self._closed:
            return
        self._closed = True
        linger_s = self.config.linger_ms / 1000.0
        # The final status (``stopping``) should reach subscribers: wait until the proxy has passed it on.
        self._lvc.wait_for_statuses(self._statuses_sent, timeout_s=linger_s)
        self._shut_down()

    def _shut_down(self) -> None:
        linger_s = self.config.linger_ms / 1000.0
        self._control.send(b"TERMINATE")
        self._proxy.join(timeout=linger_s + 2.0)
        self._lvc.stop()
        self._control.close()
        self._inlet.close()
        if self._auth is not None:
            self._auth.stop()
        if self._proxy.is_alive():
            log.error("the ZeroMQ proxy thread did not stop; leaving its context open")
            return
        self._context.term()

    def __enter__(self) -> Publisher:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def _await_status_subscription(socket: zmq.Socket, name: str, deadline: float) -> None:
    """Block until the XPUB ``socket`` has received the proxy's ``status`` subscription, so that
    what it sends from now on is forwarded; PublishError if the proxy thread has not passed it on
    by ``deadline`` (time.monotonic())."""
    while (left_ms := int((deadline - time.monotonic()) * 1000)) > 0:
        if socket.poll(left_ms) and socket.recv() == b"\x01" + STATUS_TOPIC:
            return
    raise PublishError(f"{name} got no subscription from the ZeroMQ proxy within {_WIRING_TIMEOUT_MS} ms")


def _discard_subscriptions(socket: zmq.Socket) -> None:
    """Read and drop the (un)subscription messages an XPUB holds for its owner."""
    while True:
        try:
            socket.recv(flags=zmq.NOBLOCK)
        except zmq.Again:
            return


def _run_proxy(frontend: zmq.Socket, xpub: zmq.Socket, capture: zmq.Socket, control: zmq.Socket) -> None:
    """The proxy thread: libzmq forwards frontend -> XPUB (and subscriptions back) until TERMINATE."""
    try:
        zmq.proxy_steerable(frontend, xpub, capture, control)
    except zmq.ContextTerminated:
        pass
    finally:
        for sock in (frontend, capture, control):
            sock.close(linger=0)
        xpub.close()  # with the configured linger: queued messages still go out


class _LastValue:
    """The last-value thread: keeps the last status and sends it again to each new status subscriber.

    The proxy's capture shows it what passes in both directions: the pipeline's statuses on their way
    out, and whatever peers send upstream. A peer may send anything, a forged ``status`` included, so
    only a status the publisher itself sent (``expect``) is kept, and only a single-frame subscription
    is answered: nothing that arrives from a subscriber is ever stored or published. A peer may also
    send subscriptions in a loop: answers are at most one per ANSWER_INTERVAL_S, and the thread reads
    the capture in bounded batches (READ_BATCH, READ_PAUSE_S).
    """

    def __init__(self, context: zmq.Context) -> None:
        self._sub: zmq.Socket = context.socket(zmq.SUB)
        # An XPUB so that the constructor can wait for the proxy's subscription (see the module's docstring).
        self._pub: zmq.Socket = context.socket(zmq.XPUB)
        self._stop = threading.Event()
        self._seen = threading.Condition()
        self._statuses = 0
        self._expected: collections.deque[bytes] = collections.deque(maxlen=256)  # a few minutes of statuses
        self._expected_lock = threading.Lock()
        self._newest_sent: bytes | None = None
        self._thread = threading.Thread(target=self._run, name="trackerd-zmq-last-value", daemon=True)

    def connect(self, capture: str, frontend: str) -> None:
        self._sub.setsockopt(zmq.LINGER, 0)
        self._sub.subscribe(b"\x01")  # subscription events (a single frame: 1 + prefix)
        self._sub.subscribe(STATUS_TOPIC)
        self._sub.connect(capture)
        self._pub.setsockopt(zmq.LINGER, 0)
        self._pub.connect(frontend)

    @property
    def sender(self) -> zmq.Socket:
        """The socket the answers go out on; the constructor's until ``start``, then this thread's."""
        return self._pub

    def start(self) -> None:
        self._thread.start()

    def expect(self, payload: bytes) -> None:
        """A status the publisher is about to send (called in the publishing thread)."""
        with self._expected_lock:
            self._expected.append(payload)

    def sent(self, payload: bytes) -> None:
        """A status the publisher has sent: the one new subscribers are answered with from now on
        (called in the publishing thread)."""
        with self._expected_lock:
            self._newest_sent = payload

    def forget(self, payload: bytes) -> None:
        """A status that could not be sent after all."""
        with self._expected_lock:
            if payload in self._expected:
                self._expected.remove(payload)

    def _ours(self, payload: bytes) -> bool:
        """Whether a status seen on the capture is one the publisher sent (each is seen once; its
        publish time makes each payload unique), dropping those sent before it."""
        with self._expected_lock:
            if payload not in self._expected:
                return False
            while self._expected.popleft() != payload:
                pass
            return True

    def wait_for_statuses(self, count: int, timeout_s: float) -> None:
        """Block until ``count`` statuses went through the proxy, or the timeout passes."""
        with self._seen:
            self._seen.wait_for(lambda: self._statuses >= count, timeout=timeout_s)

    def stop(self) -> None:
        if self._thread.ident is None:  # never started: the sockets are still the constructor's
            self._sub.close(linger=0)
            self._pub.close(linger=0)
            return
        self._stop.set()
        self._thread.join(timeout=_POLL_MS / 1000.0 + 2.0)

    def _run(self) -> None:
        last: list[bytes] | None = None
        asked = False
        """A status subscription came in that has not been answered yet."""
        answered = -ANSWER_INTERVAL_S
        try:
            while not self._stop.is_set():
                _discard_subscriptions(self._pub)
                wait_ms = _POLL_MS
                if asked and last is not None:  # (without a status yet there is nothing to answer with)
                    wait_ms = max(0, min(wait_ms, int((answered + ANSWER_INTERVAL_S - time.monotonic()) * 1000)))
                if self._sub.poll(wait_ms):
                    for _ in range(READ_BATCH):
                        try:
                            parts = self._sub.recv_multipart(flags=zmq.NOBLOCK)
                        except zmq.Again:
                            break
                        if len(parts) == 2 and parts[0] == STATUS_TOPIC:
                            # Ours on its way out; not a peer's upload, nor our own answer coming back.
                            if self._ours(parts[1]):
                                last = parts
                                with self._seen:
                                    self._statuses += 1
                                    self._seen.notify_all()
                        elif len(parts) == 1 and parts[0][:1] == b"\x01" and STATUS_TOPIC.startswith(parts[0][1:]):
                            asked = True
                    else:
                        # A whole batch waiting: a flood of subscriptions. Let the pipeline's threads have
                        # the interpreter; what this thread cannot read, the capture drops in libzmq.
                        time.sleep(READ_PAUSE_S)
                now = time.monotonic()
                if asked and last is not None and now >= answered + ANSWER_INTERVAL_S:
                    # The newest status sent, not the last one read off the capture: under a flood the
                    # capture lags (and may drop), and an answer from it went out older than a status
                    # subscribers already had (a status going backwards, seen by a late joiner).
                    with self._expected_lock:
                        newest = self._newest_sent
                    self._pub.send_multipart(last if newest is None else [STATUS_TOPIC, newest], flags=zmq.NOBLOCK)
                    answered, asked = now, False
        except zmq.ContextTerminated:
            pass
        finally:
            self._sub.close(linger=0)
            self._pub.close(linger=0)
