"""``ftrac-design serve`` and ``push``: poses live over OpenIGTLink (pyigtl, the ``live`` extra).

**Server.** A client (PLUS, a frame grabber's software, a script) connects and sends IMAGE
messages; each frame is tracked and answered by a TRANSFORM, in the header version the client
speaks (:mod:`ftrac_design.igt.link` says what each version carries and how a version-1 client
learns a frame was refused). One client at a time; when it leaves, the server waits for the next.

- **Threads.** The server's thread (a ``socketserver.TCPServer``, one connection at a time)
  reads the socket (:func:`ftrac_design.igt.link.read_message`: the wire framing) and puts each
  IMAGE in the inbox; the calling (main) thread tracks frames from the inbox and queues the
  answers, which the server thread sends between reads: it waits on the socket and on a
  socket pair that the tracking thread writes a byte to with each answer, so an answer leaves
  the moment it is queued. pyigtl packs and unpacks the messages.
  Both threads count into the :class:`ServeSummary`, which holds its own lock. The server is
  created in the calling thread because it installs SIGINT/SIGTERM handlers there: Ctrl-C (or
  SIGTERM) raises KeyboardInterrupt in that thread, :func:`serve` leaves its loop, closes the
  socket and returns its summary (pyigtl's own server shuts down inside its signal handler,
  where the interrupted thread may hold a lock the socket thread needs).
- **A bounded inbox.** The socket thread only reads: a frame is checked and decoded (CRC,
  pixels, camera) when the tracker takes it, so a frame that is dropped costs its bytes only.
  At most ``queue`` frames wait; a frame arriving at a full inbox pushes out the OLDEST, which
  is never answered and is counted (metadata ``dropped``, per connection). The sender is never
  blocked by the tracker and nothing grows: the newest frame is always tracked, so the last
  answer of a run carries its final drop count. A frame of a connection that has closed is
  dropped unanswered (counted as undelivered).
- **Bad messages never stop the server.** An IMAGE whose body is malformed, fails its CRC or
  gives no camera is answered (when its turn comes) by a STATUS error (code, text), a message
  of another type than IMAGE or STATUS at once, and the connection goes on; a header that
  cannot be trusted (unknown version, absurd body size) is answered by a STATUS error and that
  connection is closed, the server listens on. A frame whose tracking raises is answered by an
  INVALID TRANSFORM saying why.

**The tracker is pluggable**: :data:`TrackerFactory` makes, from the command's
:class:`~ftrac_design.workflows.track_run.TrackSetup`, a ``track(image, camera, time_s) -> pose``
callable (SPEC §4 object) called once per frame, in order, from one thread.
:func:`run_tracker`, the default, tracks each frame from the previous frame's pose as ``track``
tracks a run (:class:`~ftrac_design.tracking.RunTracker`: the full identification
when the fiducial is lost, jumps or fails the tests); :func:`frame_by_frame_tracker`
(``serve --independent``) tracks each frame alone exactly as ``track`` tracks an image.

**Client** (:func:`push_poses`): the poses of a ``track`` run sent as TRANSFORMs to a listening
OpenIGTLink server (3D Slicer's OpenIGTLinkIF, port 18944), paced by their ``time_s`` or a rate,
in the header version the server speaks once it has sent a message (``header_version`` before).
"""

from __future__ import annotations

import collections
import math
import select
import signal
import socket
import socketserver
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, TextIO

import numpy as np

from ..errors import InputError
from ..igt import link
from ..igt.frames import POSE_TRANSFORM, Space, check_transform_name
from ..images import Frame
from ..pose import Camera, TrackedPose
from ..pose.record import with_provenance
from ..tracking import RunTracker
from .track_run import TrackSetup, one_line, track_pixels

#: OpenIGTLink's default port (3D Slicer's OpenIGTLinkIF and PLUS use it)
DEFAULT_PORT = 18944
#: Python's thread switch interval while serving (s): the socket thread waits at most this for
#: the GIL when the tracker holds it, so reading keeps up with the sender (default 5 ms)
SWITCH_INTERVAL_S = 0.0005


class Tracker(Protocol):
    """Tracks one frame: ``(H, W)`` pixels as received, the frame's camera and its time (s)
    → the SPEC §4 pose object (``converged`` false with ``error`` when none). Called once per
    frame, in order, from one thread; it may keep state between frames."""

    def __call__(self, image: np.ndarray, camera: Camera, time_s: float) -> dict[str, Any]: ...


#: makes the server's tracker from the command's setup (features, body, options, --camera)
TrackerFactory = Callable[[TrackSetup], Tracker]


def _stream_frame(image: np.ndarray, camera: Camera, index: int, time_s: float) -> Frame:
    """A frame that came over OpenIGTLink: its pixels and camera as sent, nothing known of how
    it was formed."""
    return Frame(
        pixels=image,
        camera=camera,
        camera_source={},
        formation=None,
        polarity=None,
        source="OpenIGTLink",
        index=index,
        time_s=time_s,
    )


def frame_by_frame_tracker(setup: TrackSetup) -> Tracker:
    """The default tracker: every frame alone, no prior, exactly as ``ftrac-design track`` tracks
    an image (:func:`~ftrac_design.workflows.track_run.track_pixels`: undistortion, the image
    path, ``--refine``).

    Parameters
    ----------
    setup : features, body, tracking options, distortion model, refinement.

    Returns
    -------
    Tracker : returns the frame's SPEC §4 object with ``time_s`` and ``camera``.
    """

    def track(image: np.ndarray, camera: Camera, time_s: float) -> dict[str, Any]:
        _, res, _ = track_pixels(_stream_frame(image, camera, 0, time_s), setup)
        record = res.record("tracked" if res.pose.converged else "lost")
        return with_provenance(record, time_s=time_s, camera=camera).to_dict()

    return track


def run_tracker(setup: TrackSetup) -> Tracker:
    """The tracker of a live stream: frames in order through one
    :class:`~ftrac_design.tracking.RunTracker` (each from the previous frame's pose,
    the full identification when that fails), undistorted and refined as ``track`` does
    (:func:`~ftrac_design.workflows.track_run.track_pixels`). A dropped frame is simply not seen:
    the next one is predicted from the poses before it, scaled by the frames' times.

    Parameters
    ----------
    setup : features, body, tracking options, distortion model, refinement.

    Returns
    -------
    Tracker : returns the frame's SPEC §4 object with ``status``, ``timing``, ``time_s`` and
        ``camera``.
    """
    tracker = RunTracker(setup.features, setup.camera, setup.options)
    count = iter(range(1 << 62))  # frames in the order they reach the tracker: the run's own count

    def track(image: np.ndarray, camera: Camera, time_s: float) -> dict[str, Any]:
        frame = _stream_frame(image, camera, next(count), time_s)
        try:
            _, res, answer = track_pixels(frame, setup, tracker)
        except Exception:
            tracker.forget()  # nothing half-known is carried to the next frame
            raise
        return with_provenance(answer.record(), time_s=time_s, camera=camera).to_dict()

    return track


@dataclass(frozen=True)
class ServeOptions:
    """Settings of :func:`serve`, checked as they are made: the transform name is a PLUS name
    and the ``live`` extra (pyigtl) is installed (InputError otherwise).

    Attributes
    ----------
    host : the address to listen on (``127.0.0.1``: this machine only; ``0.0.0.0``: every
        interface).
    port : TCP port (0: any free one, printed).
    name : the TRANSFORM's device name (PLUS ``<From>To<To>``, ≤ 20 characters).
    space : the TRANSFORM matrix's coordinates: ``"ras"`` (3D Slicer) or ``"lps"`` (SPEC §4's
        numbers).
    queue : how many frames may wait for the tracker (the oldest is dropped beyond).
    camera : ``--camera``, overriding every frame's own, or None.
    valid_only : send no TRANSFORM for a frame without a pose (PLUS's SendValidTransformsOnly).
    report_s : seconds between progress lines while frames flow (0: none).
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    name: str = POSE_TRANSFORM
    space: Space = "ras"
    queue: int = 1
    camera: Camera | None = None
    valid_only: bool = False
    report_s: float = 10.0

    def __post_init__(self) -> None:
        _live_link(self.name)


@dataclass
class InboxItem:
    """An IMAGE message waiting for the tracker, as received: decoded (CRC, pixels, camera) only
    when its turn comes, so the socket thread does no more than read and frames that are dropped
    cost nothing but their bytes.

    Attributes
    ----------
    message : the message as read (header fields, body, stated CRC).
    connection, index : the connection it came on and its 0-based index among the IMAGE
        messages of that connection.
    received : when it was fully read (``time.perf_counter``).
    """

    message: link.RawMessage
    connection: int
    index: int
    received: float

    @property
    def timestamp(self) -> float:
        """The IMAGE's timestamp (s since 1970)."""
        return self.message.timestamp

    @property
    def device(self) -> str:
        """The IMAGE's device name."""
        return self.message.device


@dataclass
class ServeSummary:
    """What a :func:`serve` session did (totals over all connections). The socket thread and the
    tracking thread both count: :meth:`count` and :meth:`latency` hold the summary's own lock.
    """

    connections: int = 0
    received: int = 0
    answered: int = 0
    tracked: int = 0
    dropped: int = 0
    undelivered: int = 0
    bad_messages: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def count(self, **added: int) -> None:
        """Add to counters by name, atomically (e.g. ``count(answered=1, tracked=1)``)."""
        with self._lock:
            for name, n in added.items():
                setattr(self, name, getattr(self, name) + n)

    def latency(self, ms: float) -> None:
        """Record one delivered answer's latency (ms)."""
        with self._lock:
            self.latencies_ms.append(ms)

    def line(self) -> str:
        """One line: the counts and the latency's median and maximum."""
        lat = (
            f"; latency median {np.median(self.latencies_ms):.0f} ms, max {max(self.latencies_ms):.0f} ms"
            if self.latencies_ms
            else ""
        )
        return (
            f"{self.connections} connections, {self.received} frames received, {self.answered} answered "
            f"({self.tracked} with a pose), {self.dropped} dropped (queue full), {self.undelivered} undelivered "
            f"(client gone), {self.bad_messages} bad messages{lat}"
        )


class FrameInbox:
    """Bounded, drop-oldest queue of frames between the socket thread and the tracker.

    Parameters
    ----------
    size : the most frames held (≥ 1).
    """

    def __init__(self, size: int):
        if size < 1:
            raise InputError(None, None, f"at least 1, got {size}", parameter="queue")
        self._items: collections.deque[InboxItem] = collections.deque()
        self._size = size
        self._cond = threading.Condition()
        self.dropped: dict[int, int] = collections.defaultdict(int)

    def put(self, item: InboxItem) -> None:
        """Add ``item``; when full, the oldest frame is removed and counted against its connection."""
        with self._cond:
            if len(self._items) >= self._size:
                old = self._items.popleft()
                self.dropped[old.connection] += 1
            self._items.append(item)
            self._cond.notify()

    def get(self, timeout: float) -> InboxItem | None:
        """The oldest frame waiting, or None after ``timeout`` seconds."""
        with self._cond:
            if not self._items:
                self._cond.wait(timeout)
            return self._items.popleft() if self._items else None

    def discard_connection(self, connection: int) -> int:
        """Remove the waiting frames of ``connection``; returns how many."""
        with self._cond:
            keep = [it for it in self._items if it.connection != connection]
            n = len(self._items) - len(keep)
            self._items = collections.deque(keep)
            return n


class _Handler(socketserver.BaseRequestHandler):
    """One client connection: read one message, send what is queued, repeat."""

    server: IgtlServer

    def handle(self) -> None:
        srv = self.server
        conn = srv.connection_opened(self.client_address)
        sock = self.request
        # the thread waits for a message or an answer to send, whichever comes first; a started
        # message is read with short waits. The receive buffer is left to the kernel's
        # autotuning (setting it would cap it at rmem_max)
        sock.settimeout(0.01)
        try:
            while not srv.stop_requested:
                try:
                    if srv.wait(sock):
                        srv.receive_one(sock, conn)
                except link.FramingError as exc:
                    srv.reply_error(link.STATUS_INVALID_PACKET, f"{exc}; closing this connection", "", conn)
                    srv.flush(sock)
                    break
                srv.flush(sock)
        except (link.ConnectionClosed, OSError):
            pass
        finally:
            srv.connection_closed(conn)


class IgtlServer(socketserver.TCPServer):
    """The OpenIGTLink server: one client at a time, a bounded inbox, counted drops,
    per-connection state (its header version, :class:`~ftrac_design.igt.link.PeerVersion`) and
    STATUS answers to bad messages (see the module).

    Create it in the main thread: it installs its SIGINT/SIGTERM handlers there (they raise
    KeyboardInterrupt); :meth:`close` stops it and puts the previous handlers back.

    Parameters
    ----------
    options : host, port, queue size, camera override.
    log : where connection lines go (or None).
    """

    allow_reuse_address = True
    #: answers waiting to be sent; beyond this the oldest is dropped (a client that does not read)
    MAX_OUTGOING = 100

    def __init__(self, options: ServeOptions, log: TextIO | None = None):
        self.options, self.log = options, log
        self.inbox = FrameInbox(options.queue)
        self.summary = ServeSummary()
        self.connection = 0
        self.connected = False
        self.stop_requested = False
        #: (message, header version) waiting to be sent to the current connection
        self.outgoing: collections.deque[tuple[Any, link.HeaderVersion]] = collections.deque(maxlen=self.MAX_OUTGOING)
        self._frames: dict[int, int] = collections.defaultdict(int)
        self._versions: dict[int, link.PeerVersion] = collections.defaultdict(link.PeerVersion)
        self._lock = threading.Lock()
        try:
            super().__init__((options.host, options.port), _Handler)
        except OSError as exc:
            raise InputError(
                None,
                None,
                f"an address and port this machine can listen on: {options.host}:{options.port}: {exc.strerror or exc}",
                parameter="port",
            ) from None
        self.port = self.server_address[1]
        # a byte on this pair wakes the socket thread to send an answer the moment it is queued
        # (a poll of the socket every 10 ms made each answer wait 5 ms on average); made once the
        # port is bound, so that a port already in use leaves nothing open
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._previous_signal_handlers = {
            s: signal.signal(s, self._signal_handler) for s in (signal.SIGTERM, signal.SIGINT)
        }
        self._thread = threading.Thread(target=self.serve_forever, daemon=True)
        self._thread.start()

    def _signal_handler(self, signum: int, frame: Any) -> None:
        """SIGINT / SIGTERM: leave :func:`serve`'s loop, which then closes the server."""
        raise KeyboardInterrupt

    def _say(self, text: str) -> None:
        if self.log is not None:
            print(text, file=self.log, flush=True)

    def close(self) -> None:
        """Stop serving, close the socket, restore the signal handlers (idempotent)."""
        if not self.stop_requested:
            self.stop_requested = True
            self.shutdown()
            self.server_close()
            self._wake_r.close()
            self._wake_w.close()
        for s, h in self._previous_signal_handlers.items():
            if signal.getsignal(s) == self._signal_handler:
                signal.signal(s, h)

    def version_of(self, conn: int) -> link.HeaderVersion:
        """The header version connection ``conn`` is answered in now."""
        return self._versions[conn].version

    def connection_opened(self, address: Any) -> int:
        """A client connected: a new connection number; stale answers are forgotten."""
        with self._lock:
            self.connection += 1
            self.outgoing.clear()
            self.connected = True
            conn = self.connection
        self.summary.count(connections=1)
        self._say(f"client {address[0]}:{address[1]} connected (connection {conn})")
        return conn

    def connection_closed(self, conn: int) -> None:
        """The client left: its waiting frames are dropped unanswered (undelivered)."""
        n = self.inbox.discard_connection(conn)
        with self._lock:
            self.connected = False
        self.summary.count(undelivered=n)
        self._say(
            f"connection {conn} closed: {self._frames[conn]} frames received, {self.inbox.dropped[conn]} dropped; "
            f"answered in header version {self.version_of(conn)}"
        )

    def wait(self, sock: socket.socket, timeout_s: float = 0.2) -> bool:
        """Wait until ``sock`` has bytes to read (True) or an answer was queued or
        ``timeout_s`` passed (False)."""
        ready, _, _ = select.select([sock, self._wake_r], [], [], timeout_s)
        if self._wake_r in ready:
            try:
                while self._wake_r.recv(4096):
                    pass
            except BlockingIOError:
                pass
        return sock in ready

    def flush(self, sock: socket.socket) -> None:
        """Send every queued answer, each in its header version (OSError when the client is gone)."""
        while True:
            with self._lock:
                if not self.outgoing:
                    return
                msg, version = self.outgoing.popleft()
            sock.sendall(link.packed(msg, version))

    def reply(self, msg: Any, conn: int) -> bool:
        """Queue ``msg`` for connection ``conn`` in its header version now; False (and counted
        undelivered) when it has closed."""
        version = self.version_of(conn)
        with self._lock:
            live = conn == self.connection and self.connected
            if live:
                self.outgoing.append((msg, version))
        if not live:
            self.summary.count(undelivered=1)
            return False
        try:
            self._wake_w.send(b"\0")
        except (BlockingIOError, OSError):
            pass  # a wake-up is pending already, or the server has closed
        return True

    def discard_stale(self, item: InboxItem) -> None:
        """Drop a frame whose connection has closed (counted undelivered)."""
        self.summary.count(undelivered=1)

    def reply_error(self, code: int, text: str, device: str, conn: int, timestamp: float | None = None) -> None:
        """Answer a bad message with a STATUS in the connection's header version (and count it)."""
        self.summary.count(bad_messages=1)
        msg = link.status_message(code, text, device or "ftrac-design", timestamp, version=self.version_of(conn))
        self.reply(msg, conn)
        self._say(f"connection {conn}: bad message: {one_line(text)}")

    def receive_one(self, sock: socket.socket, conn: int) -> None:
        """Read one message (or return after the socket's timeout) and deal with it: the
        connection's header version follows the client's; an IMAGE goes to the inbox."""
        raw = link.read_message(sock)
        if raw is None:
            return
        self._versions[conn].heard(raw.version)
        if raw.type == "STATUS":
            # a peer's status is information, not a request: answering it could ping-pong
            return
        if raw.type != "IMAGE":
            self.reply_error(
                link.STATUS_UNKNOWN_INSTRUCTION,
                f"{raw.type} {raw.device!r}: only IMAGE messages are tracked; message ignored",
                raw.device,
                conn,
                raw.timestamp,
            )
            return
        with self._lock:
            index = self._frames[conn]
            self._frames[conn] += 1
        self.summary.count(received=1)
        self.inbox.put(InboxItem(raw, conn, index, time.perf_counter()))

    def decode(self, item: InboxItem) -> tuple[np.ndarray, Camera] | None:
        """The pixels and camera of a queued IMAGE, or None after answering a bad one with a STATUS
        (CRC mismatch 9, malformed 0, no camera 10)."""
        name, conn, ts = item.device, item.connection, item.timestamp
        if not item.message.crc_ok():
            self.reply_error(link.STATUS_CHECKSUM_ERROR, f"IMAGE {name!r}: CRC mismatch; frame ignored", name, conn, ts)
            return None
        try:
            msg = link.image_message(item.message.fields, item.message.body)
            pixels = link.image_pixels(msg)
        except InputError as exc:
            self.reply_error(link.STATUS_INVALID_PACKET, f"IMAGE {name!r}: {exc}", name, conn, ts)
            return None
        except Exception as exc:  # noqa: BLE001 — any decoding failure of a sender's bytes is its error
            self.reply_error(
                link.STATUS_INVALID_PACKET,
                f"IMAGE {name!r}: malformed ({type(exc).__name__}: {one_line(exc)})",
                name,
                conn,
                ts,
            )
            return None
        try:
            camera, _ = link.image_camera(msg, pixels.shape, self.options.camera)
        except InputError as exc:
            self.reply_error(link.STATUS_CONFIGURATION_ERROR, f"IMAGE {name!r}: no camera: {exc}", name, conn, ts)
            return None
        return pixels, camera


def _guarded(tracker: Tracker, pixels: np.ndarray, camera: Camera, time_s: float) -> dict[str, Any]:
    """The tracker's answer, or a failed pose saying why it raised (the server goes on)."""
    try:
        pose = tracker(pixels, camera, time_s)
        if not isinstance(pose, dict):
            raise TypeError(f"the tracker returned {type(pose).__name__}, not a pose object")
        return pose
    except Exception as exc:  # noqa: BLE001 — one frame's failure must not stop the live session
        return TrackedPose.failed(f"internal error: {type(exc).__name__}: {one_line(exc)}", "error").to_dict()


def _compose(
    options: ServeOptions, pose: dict[str, Any], item: InboxItem, extra: dict[str, str], version: link.HeaderVersion
) -> tuple[list[Any], bool]:
    """The messages answering one frame in the client's header ``version`` and whether it has a
    pose; a tracker's pose that cannot be sent becomes that frame's error."""
    try:
        msgs = link.answer_messages(
            pose, options.name, options.space, item.timestamp, extra, version, options.valid_only
        )
        return msgs, link.has_pose(pose)
    except Exception as exc:  # noqa: BLE001 — a tracker's malformed answer is that frame's error
        why = f"internal error: the tracker's pose: {type(exc).__name__}: {one_line(exc)}"
        pose = TrackedPose.failed(why, "error").to_dict()
        msgs = link.answer_messages(
            pose, options.name, options.space, item.timestamp, extra, version, options.valid_only
        )
        return msgs, False


def answer_frame(server: IgtlServer, tracker: Tracker, item: InboxItem) -> None:
    """Track one frame from the inbox and queue its answer for its connection, in the header
    version the client speaks (:func:`ftrac_design.igt.link.answer_messages`)."""
    start = time.perf_counter()
    decoded = server.decode(item)
    if decoded is None:
        return
    begin = time.perf_counter()
    pose = _guarded(tracker, *decoded, item.timestamp)
    done = time.perf_counter()
    extra = {
        "frame": str(item.index),
        "image_device": item.device,
        "dropped": str(server.inbox.dropped[item.connection]),
        "queue_ms": f"{1e3 * (start - item.received):.3f}",
        "track_ms": f"{1e3 * (done - begin):.3f}",
    }
    msgs, ok = _compose(server.options, pose, item, extra, server.version_of(item.connection))
    server.summary.count(answered=1, tracked=int(ok))
    for msg in msgs:
        latency_ms = 1e3 * (time.perf_counter() - item.received)
        if msg.header_version > 1:
            msg.metadata["latency_ms"] = f"{latency_ms:.3f}"
        if server.reply(msg, item.connection):
            server.summary.latency(latency_ms)


def _progress_line(server: IgtlServer, reported: int) -> str:
    s = server.summary
    lat = s.latencies_ms[reported:]
    return f"{s.received} frames received, {s.answered} answered, {sum(server.inbox.dropped.values())} dropped" + (
        f"; latency median {np.median(lat):.0f} ms" if lat else ""
    )


def _answer_until_stopped(
    server: IgtlServer, tracker: Tracker, log: TextIO | None, stop: threading.Event | None
) -> None:
    """The tracking loop: answer frames from the inbox until ``stop`` is set (or Ctrl-C), with a
    progress line every ``report_s`` seconds while frames flow."""
    report_s = server.options.report_s
    last_report, reported = time.monotonic(), 0
    while stop is None or not stop.is_set():
        item = server.inbox.get(0.2)
        if item is None:
            continue
        if item.connection != server.connection:
            server.discard_stale(item)
            continue
        answer_frame(server, tracker, item)
        if report_s and log is not None and time.monotonic() - last_report > report_s:
            print(_progress_line(server, reported), file=log, flush=True)
            last_report, reported = time.monotonic(), len(server.summary.latencies_ms)


def serve(
    setup: TrackSetup,
    options: ServeOptions,
    factory: TrackerFactory = run_tracker,
    log: TextIO | None = None,
    stop: threading.Event | None = None,
    on_listen: Callable[[IgtlServer], None] | None = None,
) -> ServeSummary:
    """Run the OpenIGTLink server until Ctrl-C (or ``stop``): IMAGE in, TRANSFORM out.

    Parameters
    ----------
    setup : what frames are tracked with (features, body, options, distortion, refine).
    options : address, port, names, queue (see :class:`ServeOptions`).
    factory : makes the tracker from ``setup`` (default :func:`run_tracker`).
    log : where the listening line, connection lines and progress go (None: nowhere).
    stop : an event that ends the session when set (Ctrl-C does too).
    on_listen : called with the server once it listens (e.g. to read its port).

    Returns
    -------
    ServeSummary : totals. Must run in the main thread (the server's signal handlers).
    """
    tracker = factory(setup)
    server = IgtlServer(options, log)
    switch = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    try:
        if log is not None:
            where = "every interface" if options.host in ("0.0.0.0", "::", "") else options.host
            print(
                f"listening on {options.host}:{server.port} ({where}); IMAGE in, TRANSFORM {options.name} out "
                f"({options.space.upper()}); Ctrl-C stops",
                file=log,
                flush=True,
            )
        if on_listen is not None:
            on_listen(server)
        _answer_until_stopped(server, tracker, log, stop)
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
        sys.setswitchinterval(switch)
    server.summary.dropped = sum(server.inbox.dropped.values())
    return server.summary


@dataclass(frozen=True)
class PushOptions:
    """Settings of :func:`push_poses`, checked as they are made (as :class:`ServeOptions`).

    Attributes
    ----------
    host, port : the OpenIGTLink server (3D Slicer's OpenIGTLinkIF listens on 18944).
    name : the TRANSFORM's device name.
    space : ``"ras"`` (3D Slicer) or ``"lps"``.
    rate_hz : frames per second; None: paced by the poses' ``time_s`` (else 30 per second).
    connect_timeout_s : how long to wait for the server.
    header_version : the OpenIGTLink header version to send in until the server has sent a
        message (then the highest version it has sent, at most 2): 2 (OpenIGTLink 3, 3D Slicer
        4.8 and later; metadata) or 1 (the reference library 1.x, older PLUS builds).
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    name: str = POSE_TRANSFORM
    space: Space = "ras"
    rate_hz: float | None = None
    connect_timeout_s: float = 10.0
    header_version: link.HeaderVersion = link.MAX_HEADER_VERSION

    def __post_init__(self) -> None:
        _live_link(self.name)


def _live_link(name: str) -> None:
    """What a live link needs, checked once as its settings are made: the ``live`` extra
    (pyigtl; MissingDependencyError) and a transform ``name`` PLUS takes (InputError)."""
    link.pyigtl()
    check_transform_name(name, "name")


def _connect(options: PushOptions) -> Any:
    """A pyigtl client connected to the server, or InputError after ``connect_timeout_s``."""
    client = link.pyigtl().OpenIGTLinkClient(options.host, options.port)
    deadline = time.monotonic() + options.connect_timeout_s
    while not client.is_connected():
        if time.monotonic() > deadline:
            client.stop()
            raise InputError(
                None,
                None,
                f"an OpenIGTLink server listening at {options.host}:{options.port} "
                f"(none answered within {options.connect_timeout_s:g} s)",
                parameter="port",
            )
        time.sleep(0.01)
    return client


def server_version(client: Any, default: link.HeaderVersion) -> link.HeaderVersion:
    """The header version to send to the server ``client`` is connected to: the highest version
    of the messages it has sent (at most 2), else ``default`` while it has sent none."""
    try:
        heard = [int(m.header_version) for m in list(client.incoming_messages.values())]
    except RuntimeError:  # the receiving thread changed the store meanwhile: ask again next time
        heard = []
    return min(max(heard), link.MAX_HEADER_VERSION) if heard else default  # type: ignore[return-value]


def push_poses(poses: list[TrackedPose], options: PushOptions, progress: Callable[[int], None] | None = None) -> int:
    """Send each pose as a TRANSFORM to a listening OpenIGTLink server, in order, paced, in the
    header version the server speaks (:func:`server_version`).

    Parameters
    ----------
    poses : the run (:func:`ftrac_design.pose.read_tracked_poses`); one without a pose is sent
        INVALID (identity) in header version 2, as a STATUS ``NoPose`` in version 1 (see
        :mod:`ftrac_design.igt.link`).
    options : server, names, pace, header version.
    progress : called with the number sent after each (e.g. a progress bar's update).

    Returns
    -------
    int : how many were sent. Raises InputError when no server answers at host:port within
    ``connect_timeout_s``.
    """
    client = _connect(options)
    try:
        times = send_times(poses, options.rate_hz)
        start, wall0 = times[0], time.monotonic()
        for k, (p, t) in enumerate(zip(poses, times)):
            wait = wall0 + (t - start) - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            frame, time_s = p.provenance.frame, p.provenance.time_s
            extra = {"frame": str(frame if frame is not None else k)}
            if time_s is not None:
                extra["time_s"] = repr(time_s)
            version = server_version(client, options.header_version)
            for msg in link.answer_messages(p.to_dict(), options.name, options.space, time.time(), extra, version):
                client.send_message(msg, wait=True)
            if progress is not None:
                progress(k + 1)
        return len(poses)
    finally:
        client.stop()


def send_times(poses: list[TrackedPose], rate_hz: float | None) -> list[float]:
    """When each pose is sent (s from the first): ``k / rate_hz``, else the poses' ``time_s``
    when every pose has one and they do not go back, else 30 per second."""
    n = len(poses)
    ts = [p.provenance.time_s for p in poses]
    if rate_hz is None and all(t is not None for t in ts) and all(b >= a for a, b in zip(ts, ts[1:])):
        return [float(t) for t in ts]
    rate = rate_hz if rate_hz is not None and math.isfinite(rate_hz) and rate_hz > 0 else 30.0
    return [k / rate for k in range(n)]
