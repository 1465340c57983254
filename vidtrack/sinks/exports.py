"""Exports of the tracks for annotation tools and tracking benchmarks: CVAT for video 1.1, MOT Challenge, JSON lines.

=========  ===========  ======================================================================
format     by name      content
=========  ===========  ======================================================================
``cvat``   ``.xml``     CVAT for video 1.1: ``<meta>`` (task size, ``original_size``, the
                        label ``target``) and one ``<track id=ID label="target">`` per target,
                        a keyframe ``<box frame xtl ytl xbr ybr outside occluded keyframe>``
                        per frame, ``outside="1"`` while the target is lost; frames 0-based
``mot``    ``.txt``     MOT Challenge: ``frame,id,x,y,w,h,confidence,-1,-1,-1`` per target
                        and frame, frames 1-based; lost frames included (their low confidence
                        tells them apart)
``jsonl``  ``.jsonl``   one ``{"frame", "id", "box": [x, y, w, h], "confidence", "status"}``
                        object per target and frame, frames 0-based
=========  ===========  ======================================================================

Boxes are 0-based pixels with 2 decimals (CVAT: corners, the others: ``x, y, w, h``).

After a hard stop (``kill -9``, a power cut) the MOT and JSON lines files
keep every frame written: each frame's lines reach the operating system in
one write.  An XML document is only valid once closed, so the CVAT file is
rewritten whole every ``batch`` frames and at :meth:`CvatExport.close`:
written to a temporary file beside it, then renamed over it, so it is
always a complete document missing only the last frames.  Rewriting costs
time in proportion to the frames so far, so a rewrite waits, beyond
``batch`` frames, until the time since the last one is ten times what that
one took: the document misses at most ``batch`` frames while rewriting is
cheap next to tracking, more on long runs of a fast tracker.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Mapping
from xml.sax.saxutils import escape, quoteattr

from ..errors import OutputError, UsageError
from ..types import Frame, TrackState
from .base import LineFile, failed_write
from .files import format_box
from .palette import target_colour
from .video import as_targets

#: The export formats, by the name ``--export-format`` takes.
EXPORT_FORMATS = ("cvat", "mot", "jsonl")
#: The format a file name's extension stands for.
FORMAT_BY_SUFFIX = {".xml": "cvat", ".txt": "mot", ".jsonl": "jsonl"}
#: The one label of every track in the CVAT export.
CVAT_LABEL = "target"


def export_format(path: str | Path, explicit: str | None = None) -> str:
    """The export format of ``path``: ``explicit`` when given, else by its extension.

    Raises
    ------
    UsageError
        For an unknown ``explicit`` format, or an extension that names none.
    """
    if explicit is not None:
        if explicit not in EXPORT_FORMATS:
            raise UsageError(f"unknown export format '{explicit}': choose one of {', '.join(EXPORT_FORMATS)}")
        return explicit
    suffix = Path(path).suffix.lower()
    if suffix not in FORMAT_BY_SUFFIX:
        named = ", ".join(f"{s} ({f})" for s, f in FORMAT_BY_SUFFIX.items())
        raise UsageError(f"cannot tell the export format of {path}: name it {named} "
                         f"or give --export-format {{{','.join(EXPORT_FORMATS)}}}")
    return FORMAT_BY_SUFFIX[suffix]


def open_export(path: str | Path, format: str, *, size: tuple[int, int] | None = None,
                filter_name: str | None = None, batch: int = 30):
    """A sink writing the tracks to ``path`` in ``format`` (one of :data:`EXPORT_FORMATS`).

    Parameters
    ----------
    size
        ``(width, height)`` of the frames, for the CVAT ``original_size``;
        ``None``: taken from the first frame.
    filter_name
        The tracker, named in the CVAT task's name.
    batch
        Frames between two rewrites of the CVAT file (at least; see the module's notes).

    Raises
    ------
    UsageError
        For an unknown format.
    OutputError
        When ``path`` cannot be written.
    """
    if format == "mot":
        return MotExport(path)
    if format == "jsonl":
        return JsonLinesExport(path)
    if format == "cvat":
        return CvatExport(path, size=size, filter_name=filter_name, batch=batch)
    raise UsageError(f"unknown export format '{format}': choose one of {', '.join(EXPORT_FORMATS)}")


class MotExport:
    """MOT Challenge lines ``frame,id,x,y,w,h,confidence,-1,-1,-1``, frames 1-based, one line per target."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = LineFile(self.path)

    def write(self, frame: Frame, targets: Mapping[int, TrackState] | TrackState) -> None:
        targets = as_targets(targets)
        lines = [f"{frame.index + 1},{target_id},{format_box(state.box)},{state.confidence:.4f},-1,-1,-1"
                 for target_id, state in sorted(targets.items())]
        if lines:
            self._file.write_line("\n".join(lines))

    def close(self) -> None:
        self._file.close()


class JsonLinesExport:
    """One JSON object per target and frame: ``frame`` (0-based), ``id``, ``box``, ``confidence``, ``status``."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file = LineFile(self.path)

    def write(self, frame: Frame, targets: Mapping[int, TrackState] | TrackState) -> None:
        targets = as_targets(targets)
        lines = [json.dumps({"frame": frame.index, "id": target_id,
                             "box": [round(float(v), 2) for v in state.box.as_array()],
                             "confidence": round(float(state.confidence), 4), "status": state.status})
                 for target_id, state in sorted(targets.items())]
        if lines:
            self._file.write_line("\n".join(lines))

    def close(self) -> None:
        self._file.close()


def cvat_box(frame_index: int, state: TrackState, *, outside: bool) -> str:
    """One ``<box>`` element of a CVAT for video track: a keyframe, corners with 2 decimals."""
    x, y, w, h = (float(v) for v in state.box.as_array())
    return (f'    <box frame="{frame_index}" xtl="{x:.2f}" ytl="{y:.2f}" xbr="{x + w:.2f}" ybr="{y + h:.2f}" '
            f'outside="{int(outside)}" occluded="0" keyframe="1" z_order="0"></box>')


def cvat_document(tracks: Mapping[int, list[str]], *, frames: int, size: tuple[int, int] | None,
                  task_name: str) -> str:
    """A CVAT for video 1.1 document: the ``<meta>`` and one ``<track>`` per ID of ``<box>`` rows."""
    r, g, b = target_colour(1)[::-1]
    parts = ['<?xml version="1.0" encoding="utf-8"?>', "<annotations>", "  <version>1.1</version>", "  <meta>",
             "    <task>", f"      <name>{escape(task_name)}</name>", f"      <size>{frames}</size>",
             "      <mode>interpolation</mode>", "      <overlap>0</overlap>", "      <start_frame>0</start_frame>",
             f"      <stop_frame>{max(0, frames - 1)}</stop_frame>", "      <frame_filter></frame_filter>",
             "      <labels>", "        <label>", f"          <name>{CVAT_LABEL}</name>",
             f"          <color>#{r:02x}{g:02x}{b:02x}</color>", "          <type>rectangle</type>",
             "          <attributes></attributes>", "        </label>", "      </labels>"]
    if size is not None:
        parts += ["      <original_size>", f"        <width>{int(size[0])}</width>",
                  f"        <height>{int(size[1])}</height>", "      </original_size>"]
    parts += ["    </task>", "  </meta>"]
    for target_id in sorted(tracks):
        parts.append(f'  <track id="{int(target_id)}" label={quoteattr(CVAT_LABEL)} source="auto">')
        parts.extend(tracks[target_id])
        parts.append("  </track>")
    parts.append("</annotations>")
    return "\n".join(parts) + "\n"


class CvatExport:
    """CVAT for video 1.1 XML: a track per target, a keyframe per frame, ``outside="1"`` while lost.

    A target missing from a frame after it was seen gets an ``outside``
    box on that frame (its last box), which ends the track there in CVAT
    until it comes back.  The file is rewritten atomically after the first
    frame, then every ``batch`` frames or more (see the module's notes),
    and at :meth:`close`.
    """

    #: Largest share of the run's time spent rewriting the file.
    REWRITE_SHARE = 0.1

    def __init__(self, path: str | Path, *, size: tuple[int, int] | None = None, filter_name: str | None = None,
                 batch: int = 30) -> None:
        self.path = Path(path)
        self.size = size
        self.task_name = f"vidtrack {filter_name}" if filter_name else "vidtrack"
        self.batch = max(1, int(batch))
        try:
            if self.path.is_dir():
                raise OutputError(f"cannot write {self.path}: it is a folder")
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with open(self.path, "wb"):
                pass  # fail now, with a clear message, if the path is not writable
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}") from None
        self._tracks: dict[int, list[str]] = {}
        self._last: dict[int, TrackState] = {}
        self._frames = 0
        self._pending = 0
        self._rewrites = 0
        self._last_write = time.monotonic()
        self._write_cost = 0.0

    def write(self, frame: Frame, targets: Mapping[int, TrackState] | TrackState) -> None:
        targets = as_targets(targets)
        if self.size is None:
            self.size = (frame.width, frame.height)
        for target_id in sorted(set(self._last) - set(targets)):   # gone: the track ends here
            self._tracks[target_id].append(cvat_box(frame.index, self._last.pop(target_id), outside=True))
        for target_id, state in sorted(targets.items()):
            self._tracks.setdefault(target_id, []).append(cvat_box(frame.index, state, outside=state.status == "lost"))
            self._last[target_id] = state
        self._frames = max(self._frames, frame.index + 1)
        self._pending += 1
        since = time.monotonic() - self._last_write
        if self._rewrites == 0 or (
                self._pending >= self.batch and self._write_cost <= self.REWRITE_SHARE * since):
            self._rewrite()

    def _rewrite(self) -> None:
        start = time.monotonic()
        text = cvat_document(self._tracks, frames=self._frames, size=self.size, task_name=self.task_name)
        temporary = self.path.with_name(f".{self.path.name}.tmp")
        try:
            with open(temporary, "w", encoding="utf-8") as out:
                out.write(text)
            os.replace(temporary, self.path)
        except OSError as exc:
            temporary.unlink(missing_ok=True)
            raise failed_write(self.path, exc) from None
        self._pending = 0
        self._rewrites += 1
        self._last_write = time.monotonic()
        self._write_cost = self._last_write - start

    def flush(self) -> None:
        """Rewrite the file now with every frame written so far (if any is missing from it)."""
        if self._pending:
            self._rewrite()

    def close(self) -> None:
        self.flush()
