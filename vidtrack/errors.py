"""Errors the CLI turns into a one-line message and exit code 2."""


class VidtrackError(Exception):
    """Base class of the errors a user can cause and fix (bad input, bad output path)."""


class UsageError(VidtrackError):
    """A bad argument: malformed box, unknown filter, bad option value."""


class SourceError(VidtrackError):
    """A video or frame folder that cannot be opened or decoded."""


class OutputError(VidtrackError):
    """An output path that cannot be written."""


class DatasetError(VidtrackError):
    """A dataset folder or sequence that does not have the expected layout."""
