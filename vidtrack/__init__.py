"""vidtrack: video object tracking with robust filters, built on OpenCV."""

__version__ = "0.1.0"
