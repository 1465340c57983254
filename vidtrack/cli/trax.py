"""``vidtrack trax``: any vidtrack tracker as a TraX server, for the VOT toolkit and other TraX clients.

TraX (the protocol the VOT toolkit drives trackers with) runs over the
process's stdin/stdout (the toolkit's default, and what the tests use), or
over a local socket when the client sets ``TRAX_SOCKET``; the reference
implementation, PyPI's ``vot-trax``, handles both.  The server answers

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
"""

from __future__ import annotations

import argparse
from typing import Any, Sequence

import numpy as np

from ..errors import SourceError, UsageError, VidtrackError
from .common import EXIT_OK, OneLineParser, add_filter_argument, add_settings_arguments, default_filter, \
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
        decoded = cv2.imread(image.path(), cv2.IMREAD_COLOR)
        if decoded is None:
            raise SourceError(f"cannot decode image {image.path()}")
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


def serve(server: Any, make_tracker) -> int:
    """Answer ``server``'s requests until the client quits; return the number of frames tracked.

    ``make_tracker()`` builds a fresh :class:`~vidtrack.api.VidtrackTracker`
    for every ``INITIALIZE``.
    """
    from trax import TraxStatus

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
        reply(server, state)


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

    try:
        server = Server([Region.RECTANGLE], [Image.PATH, Image.MEMORY], tracker_name=f"vidtrack-{name}",
                        tracker_description=f"vidtrack {name}", tracker_family="vidtrack",
                        log=args.trax_log or False)
    except TraxException as exc:
        raise UsageError(f"cannot start the TraX server: {exc}") from None
    try:
        serve(server, make_tracker)
    except VidtrackError as exc:   # tell the client why, then the CLI's one line and exit 2
        server.quit(reason=str(exc))
        raise
    except TraxException as exc:   # the client went away or broke the protocol
        raise UsageError(f"TraX connection failed: {exc}") from None
    server.quit()
    return EXIT_OK
