"""vidtrack: video object tracking with robust filters, built on OpenCV."""

__version__ = "0.1.0"

import os as _os

# Keep FFmpeg's own log lines ("moov atom not found" ...) off stderr: vidtrack
# reports decoding problems itself, in one line.  Must be set before cv2 loads.
_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
_os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
