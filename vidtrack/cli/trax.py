"""``vidtrack trax``: any vidtrack tracker as a TraX server, for the VOT toolkit and other TraX clients.

TraX (the protocol the VOT toolkit drives trackers with) runs over the
process's stdin/stdout (the toolkit's default), or over a local socket when
the client listens on 127.0.0.1 and names its port in ``TRAX_SOCKET`` (then
nothing is written to stdout); the reference implementation, PyPI's
``vot-trax``, handles both, with the same answers.  The server answers

* ``INITIALIZE`` (image + rectangle): builds a fresh tracker (``--filter``,
  ``--seed``, the tracker options ``--config``, ``--set`` ...) and starts it on
  the box, which must lie mostly inside the image (:func:`vidtrack.api.check_inside`).  A client may initialise
  again at any time over the same connection (the toolkit does after a
  failure): the tracker starts afresh, as ``vidtrack eval`` starts each job.
* ``FRAME`` (image): one tracker step; the reply is the box and the
  properties ``confidence`` (in [0, 1]) and ``status`` (``tracking``/``lost``).

Images arrive as file paths (what the toolkit sends) or as memory images
(RGB, converted to BGR).  Regions arrive and leave as TraX rectangles in
0-based pixels (the toolkit's own convention for its ground truth); a polygon
is reduced to its bounding rectangle by the client library.  Nothing but the
protocol is written to stdout: messages go to stderr.

Faults (over stdin/stdout, where :class:`MessageRelay` hands libtrax only
whole messages): a line that is not a TraX message, a message the client may
not send, or one libtrax cannot parse ends the session with one line
``vidtrack: error: TraX protocol error: ...`` and exit 2; an image that
cannot be read (a path that vanished, a broken file) with one line naming it,
exit 2 (the client is told why in the ``quit`` message); a client that
disconnects without ``quit`` (its end of the pipe closed, also in the middle
of a message or while a reply is being sent) with one line ``vidtrack: error:
TraX client disconnected after N frames ...``, exit 1.  A client that stays
connected and sends nothing is waited for: a server has no time limit.
"""

from __future__ import annotations

import argparse
import os
import select
import sys
import threading
from typing import Any, Sequence

import numpy as np

from ..errors import SourceError, UsageError, VidtrackError
from ..sinks.base import open_text_output
from .common import EXIT_FAILED, EXIT_OK, OneLineParser, error_line, add_filter_argument, add_settings_arguments, default_filter, \
    tracker_settings

DESCRIPTION = ("Serve a vidtrack tracker over the TraX protocol (the VOT toolkit's), on stdin/stdout "
               "or on the socket the client names in TRAX_SOCKET.")


def build_parser() -> OneLineParser:
    parser = OneLineParser(prog="vidtrack trax", description=DESCRIPTION,
                           epilog="In the VOT toolkit's trackers.ini: protocol = trax, "
                                  "command = /absolute/path/to/vidtrack trax --filter NAME")
    add_filter_argument(parser)
    parser.add_argument("--seed", type=int, default=0, help="random seed of every (re-)initialised tracker")
    parser.add_argument("--trax-log", metavar="FILE", help="write libtrax's protocol log here")
    add_settings_arguments(parser)
    return parser


#: The messages a TraX client sends to a server.
CLIENT_MESSAGES = ("initialize", "frame", "quit")
PREFIX = b"@@TRAX:"


def message_end(buffer: bytes) -> int | None:
    """Index of the newline ending the first whole TraX message in ``buffer``, or None.

    Arguments may be quoted strings (``\\"`` and ``\\\\`` escaped inside)
    holding newlines: only a newline outside quotes ends a message.
    """
    quoted = escaped = False
    for i, byte in enumerate(buffer):
        if escaped:
            escaped = False
        elif quoted and byte == 0x5C:   # backslash
            escaped = True
        elif byte == 0x22:              # double quote
            quoted = not quoted
        elif byte == 0x0A and not quoted:
            return i
    return None


def message_problem(message: bytes) -> str | None:
    """Why ``message`` (one whole line) is not a message a TraX client may send, or None when it is."""
    text = message.strip()
    if not text.startswith(PREFIX):
        shown = text[:40].decode("utf-8", "replace")
        return f"not a TraX message: {shown!r}"
    name = text[len(PREFIX):].split(b" ", 1)[0].decode("utf-8", "replace")
    if name not in CLIENT_MESSAGES:
        return f"a client may not send {name!r} (only {', '.join(CLIENT_MESSAGES)})"
    return None


class MessageRelay:
    """Reads the client's stdin and hands libtrax only whole, well-formed messages through a pipe on fd 0.

    libtrax waits forever on a message cut short by the end of its input and
    silently skips lines it does not know; the relay turns both into a
    reason (``problem``: a protocol error; ``disconnected``: the input
    ended, ``partial`` when in the middle of a message).  On a protocol
    error it closes the pipe, so libtrax's wait fails at once; at the end of
    the input it first hands libtrax a ``quit`` of its own (a message
    before it that libtrax cannot parse still fails as malformed, the others
    are answered), so a disconnection is told apart from a broken message.
    """

    def __init__(self) -> None:
        self.problem: str | None = None
        self.disconnected = False
        self.partial = False
        self.last: str | None = None
        self._source = os.dup(0)
        read_end, self._sink = os.pipe()
        os.dup2(read_end, 0)
        os.close(read_end)
        self._thread = threading.Thread(target=self._run, name="trax-relay", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        buffer = b""
        try:
            while self.problem is None:
                chunk = os.read(self._source, 1 << 16)
                if not chunk:
                    self.partial = bool(buffer.strip())
                    self.disconnected = True
                    os.write(self._sink, PREFIX + b"quit \n")
                    return
                buffer += chunk
                while (end := message_end(buffer)) is not None:
                    message, buffer = buffer[:end + 1], buffer[end + 1:]
                    if not message.strip():
                        continue
                    self.problem = message_problem(message)
                    if self.problem is not None:
                        return
                    self.last = message.strip()[len(PREFIX):].split(b" ", 1)[0].decode()
                    os.write(self._sink, message)
        except OSError:   # libtrax already closed its end of the pipe: the server is ending
            pass
        finally:
            try:
                os.close(self._sink)
            except OSError:
                pass

    @staticmethod
    def output_closed() -> bool:
        """True when the client closed its end of our stdout (a pipe then polls as an error)."""
        poller = select.poll()
        poller.register(1, select.POLLOUT)
        return any(event & (select.POLLERR | select.POLLHUP) for _, event in poller.poll(0))

    def settle(self, timeout: float = 2.0) -> None:
        """Give the relay a moment to record why the input stopped (libtrax may notice first)."""
        self._thread.join(timeout)


def read_image(image: Any) -> np.ndarray:
    """A TraX image (path or memory) -> ``(H, W, 3) uint8`` BGR.

    Raises
    ------
    SourceError
        If the file cannot be decoded or the image kind is not supported.
    """
    import cv2
    from trax import Image

    kind = image.type()
    if kind == Image.PATH:
        path = image.path()
        if not os.path.isfile(path):
            raise SourceError(f"cannot decode image {path}: no such file")
        decoded = cv2.imread(path, cv2.IMREAD_COLOR)
        if decoded is None:
            raise SourceError(f"cannot decode image {path}")
        return decoded
    if kind == Image.MEMORY:
        array = np.asarray(image.array())
        if array.dtype != np.uint8:
            array = cv2.convertScaleAbs(array, alpha=255.0 / max(float(array.max()), 1.0))
        if array.ndim == 2:
            return cv2.cvtColor(array, cv2.COLOR_GRAY2BGR)
        return cv2.cvtColor(array, cv2.COLOR_RGB2BGR)
    raise SourceError(f"unsupported TraX image kind {kind!r}")


def region_box(region: Any):
    """A TraX region -> :class:`~vidtrack.types.Box` (its bounding rectangle)."""
    from ..api import as_box

    x, y, w, h = region.bounds()
    return as_box((x, y, w, h))


def reply(server: Any, state) -> None:
    """Send ``state``'s box with its confidence and status as properties."""
    from trax.region import Rectangle

    box = state.box
    properties = {"confidence": f"{state.confidence:.6f}", "status": state.status}
    server.status([(Rectangle.create(box.x, box.y, box.w, box.h), properties)])


class ClientGone(Exception):
    """The client closed its end of the connection while the server was answering."""


class Session:
    """Frames tracked so far in a TraX session (read when the connection fails part-way).

    ``output_closed()`` tells, after each reply, whether the client stopped reading.
    """

    frames = 0

    @staticmethod
    def output_closed() -> bool:
        return False


def serve(server: Any, make_tracker, session: Session | None = None) -> int:
    """Answer ``server``'s requests until the client quits; return the number of frames tracked.

    ``make_tracker()`` builds a fresh :class:`~vidtrack.api.VidtrackTracker`
    for every ``INITIALIZE``; ``session.frames`` counts the frames answered.
    """
    session = session if session is not None else Session()
    from trax import TraxException, TraxStatus

    from ..api import check_inside
    from ..types import Frame

    tracker = None
    frames = 0
    while True:
        request = server.wait()
        if request.type == TraxStatus.QUIT:
            return frames
        if request.type not in (TraxStatus.INITIALIZE, TraxStatus.FRAME):
            continue
        image = read_image(request.image["color"] if "color" in request.image
                           else next(iter(request.image.values())))
        if request.type == TraxStatus.INITIALIZE:
            if not request.objects:
                raise UsageError("TraX INITIALIZE without a region")
            box = region_box(request.objects[0][0])
            check_inside(box, image.shape[1], image.shape[0], what="TraX region")
            tracker = make_tracker()
            state = tracker.init_frame(Frame(0, image), box)
        else:
            if tracker is None:
                raise UsageError("TraX FRAME before INITIALIZE")
            state = tracker.step_frame(Frame(tracker.next_index_, image))
        frames += 1
        try:
            reply(server, state)
        except TraxException as exc:
            raise ClientGone(str(exc)) from None
        session.frames = frames
        if session.output_closed():
            raise ClientGone("the client stopped reading")


def main(argv: Sequence[str]) -> int:
    """``vidtrack trax --filter NAME [options]``: serve until the client quits (exit 0)."""
    from ..api import create

    args: argparse.Namespace = build_parser().parse_args(argv)
    name = args.filter or default_filter()
    settings = tracker_settings(args)
    create(name, seed=args.seed, settings=settings)   # a bad name or option: one line, exit 2, before any protocol

    import cv2
    from trax import Image, Server, TraxException
    from trax.region import Region

    def make_tracker():
        # as eval does per job: OpenCV's global RNG restarts, so a re-initialised tracker equals a fresh one
        cv2.setRNGSeed(args.seed)
        return create(name, seed=args.seed, settings=settings)

    log = False
    if args.trax_log:   # an unwritable log: one line, exit 2, before any protocol
        open_text_output(args.trax_log).close()
        log = os.path.abspath(args.trax_log)   # vot-trax creates the log's folder from its name: never ""
    relay = None if os.environ.get("TRAX_SOCKET") else MessageRelay()
    try:
        server = Server([Region.RECTANGLE], [Image.PATH, Image.MEMORY], tracker_name=f"vidtrack-{name}",
                        tracker_description=f"vidtrack {name}", tracker_family="vidtrack", log=log)
    except TraxException as exc:
        raise UsageError(f"cannot start the TraX server: {exc}") from None
    try:
        return session(server, make_tracker, relay)
    finally:
        release(server)


def session(server: Any, make_tracker, relay: MessageRelay | None) -> int:
    """Serve one client on ``server`` until it quits or fails; the exit code (or the error to report)."""
    from trax import TraxException

    tracked = Session()
    if relay is not None:
        tracked.output_closed = relay.output_closed
    try:
        frames = serve(server, make_tracker, tracked)
    except VidtrackError as exc:   # tell the client why, then the CLI's one line and exit 2
        server.quit(reason=str(exc))
        raise
    except (TraxException, ClientGone) as exc:   # the client went away or broke the protocol
        return connection_failed(exc, relay, tracked.frames)
    server.quit()
    if relay is not None and relay.disconnected:   # the quit was the relay's: the client went away
        return disconnected(relay, frames)
    return EXIT_OK


def release(server: Any) -> None:
    """Free libtrax's handle of ``server`` now, while its log callback still lives; then the callback.

    libtrax logs while it cleans a handle up (it sends the client a last
    ``quit`` when the session did not end with one).  vot-trax's ``Server``
    holds the log callback (``_logger``: with ``--trax-log`` a file logger)
    and the handle (``_handle``) as attributes set in that order, and frees
    the handle only when the server object is collected: after a failed
    session that is at interpreter exit, when the callback (or the module it
    calls into) is gone already, and libtrax's last log message crashes the
    process.  Freeing the handle here, then the callback (which closes the
    log file), makes the order right whatever keeps ``server`` alive.
    """
    attributes = vars(server)
    handle = attributes.pop("_handle", None)
    del handle   # the handle's finalizer (libtrax's trax_cleanup) runs here, logging through the callback
    callback = attributes.pop("_logger", None)
    del callback


def disconnected(relay: MessageRelay | None, frames: int) -> int:
    """One line for a client that went away part-way; exit 1."""
    where = " in the middle of a message" if relay is not None and relay.partial else ""
    print(error_line(f"TraX client disconnected{where} after {frames} frame{'s' if frames != 1 else ''} "
                     f"without quitting"), file=sys.stderr)
    return EXIT_FAILED


def connection_failed(exc: Exception, relay: MessageRelay | None, frames: int) -> int:
    """The one line and exit code of a TraX session that failed part-way (see the module's docstring)."""
    if relay is not None:
        relay.settle()
    if relay is not None and relay.problem is not None:
        raise UsageError(f"TraX protocol error: {relay.problem}")
    if isinstance(exc, ClientGone) or relay is None:
        return disconnected(relay, frames)   # a reply could not be written, or libtrax found its socket closed
    last = f" {relay.last!r}" if relay.last else ""
    raise UsageError(f"TraX protocol error: malformed{last} message")
