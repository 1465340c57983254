"""vidtrack: video object tracking with robust filters, built on OpenCV.

The Python API is :mod:`vidtrack.api` (``vidtrack.create``, ``vidtrack.track``,
``vidtrack.filters()``), imported on first use so that ``import vidtrack``
stays light; the command line is :mod:`vidtrack.cli`.
"""

import os as _os
import types as _types

from .version import __version__

# Keep FFmpeg's own log lines ("moov atom not found" ...) off stderr: vidtrack
# reports decoding problems itself, in one line.  Must be set before cv2 loads.
_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
_os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

from . import filters  # noqa: E402  (the estimators' package; its __init__ imports nothing)

_API = {"create", "track", "VidtrackTracker"}
_TYPES = {"Box", "Frame", "TrackState"}
__all__ = ["__version__", "filters", *sorted(_API), *sorted(_TYPES)]


class _CallableFilters(_types.ModuleType):
    """The :mod:`vidtrack.filters` package, also callable as :func:`vidtrack.api.filters`.

    ``vidtrack.filters`` names both the package of estimators and the API's
    listing of the registered trackers; the package itself must not import
    the API (a layer above it), so the call is made here, importing the API
    only when called.
    """

    def __call__(self) -> dict[str, str]:
        """Every registered tracker name with its one-line description (:func:`vidtrack.api.filters`)."""
        from .api import filters as list_filters

        return list_filters()


filters.__class__ = _CallableFilters


def __getattr__(name: str):
    if name in _API:
        from . import api

        return getattr(api, name)
    if name in _TYPES:
        from . import types

        return getattr(types, name)
    raise AttributeError(f"module 'vidtrack' has no attribute {name!r}")
