"""vidtrack: video object tracking with robust filters, built on OpenCV."""

__version__ = "0.1.0"

import os as _os

# Keep FFmpeg's own log lines ("moov atom not found" ...) off stderr: vidtrack
# reports decoding problems itself, in one line.  Must be set before cv2 loads.
_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
_os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

#: The Python API (:mod:`vidtrack.api`), imported on first use so that ``import vidtrack`` stays light.
#: ``vidtrack.filters`` is the package of estimators, made callable: ``vidtrack.filters()`` lists the trackers.
_API = {"create", "track", "VidtrackTracker"}
_TYPES = {"Box", "Frame", "TrackState"}
__all__ = ["__version__", "filters", *sorted(_API), *sorted(_TYPES)]


def __getattr__(name: str):
    if name in _API:
        from . import api

        return getattr(api, name)
    if name == "filters":
        import importlib

        return importlib.import_module(f"{__name__}.filters")
    if name in _TYPES:
        from . import types

        return getattr(types, name)
    raise AttributeError(f"module 'vidtrack' has no attribute {name!r}")
