"""Rerun recording sink: every pipeline stage of every frame, headless by default.

The only module of vidtrack that imports ``rerun`` (rerun-sdk 0.41).  One
recording per :class:`RerunSink`, on its own :class:`rerun.RecordingStream`
(never the global one), so one process can write many recordings (one per
tracker and sequence in ``vidtrack eval --rerun DIR``).

Layout of a recording (one timeline, ``frame``; keep these names so that
recordings of different versions line up).  Every target has its own subtree
``targets/<id>/`` (a one-target run is target 1), its estimate drawn in the
target's colour (:func:`vidtrack.sinks.palette.target_colour_rgb`):

=====================================  ========================================
entity                                 content
=====================================  ========================================
``video/frame``                        the frame, JPEG (never raw)
``video/boxes/ground_truth``           the annotated box (white; eval only)
``targets/<id>/boxes/estimate``        the filter's box (the target's colour,
                                       red while lost; labelled with the ID
                                       when there are several targets)
``targets/<id>/boxes/predicted``       the prior (blue)
``targets/<id>/boxes/measured``        the raw measurement (amber)
``targets/<id>/search_region``         where the measurer looked (grey)
``targets/<id>/stages/superpixels``    SegmentationImage, every ``superpixels_every``-th frame
``targets/<id>/stages/<image stage>``  ``svm_scores``, ``inliers``, ``score_map``,
                                       ``backprojection`` ... as small JPEG/PNG images
``targets/<id>/stages/<point stage>``  ``particles``, ``detections``: Points2D, radius by weight
``targets/<id>/filter/<name>``         ``confidence`` and the filter's scalars (time series)
``targets/<id>/log/status``            TextLog: start, lost, re-acquired
=====================================  ========================================

Image stages cover the search region (``TrackState.search_region``; names
ending in ``_full`` cover the whole frame).  Each is logged with a
``Transform3D`` (translation + per-axis scale) that maps its pixel grid onto
that region, so in frame coordinates it lies exactly where it was computed;
the default blueprint shows each one over the frame.  An entity that had data
on the previous frame but has none now (no measurement, a frame without
ground truth) gets an empty row (or a ``Clear``), so the viewer never shows a
stale box or stage; rate-limited stages (superpixels) keep showing the last one.
Styles (labels, widths, draw order, point colours) are logged once as static
data, so rows carry only geometry, pixels and the box colour (which turns
red while the target is lost).  How a stage is shown and encoded is decided by
the pure functions of :mod:`vidtrack.sinks.stage_images`.
"""

from __future__ import annotations

import re
import uuid
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..errors import OutputError, UsageError
from ..types import Box, Frame, TrackState
from .base import open_text_output
from .palette import target_colour_rgb
from .relayed_file import RelayedFile, relay_supported
from .stage_images import (COLORMAPS, display_image, encode_jpeg, labels_for_segmentation, point_display,
                           region_transform, stage_kind)

# Colours are RGB (rerun's order, not OpenCV's).
ESTIMATE_RGB = (0, 220, 0)
LOST_RGB = (230, 0, 0)
PREDICTED_RGB = (0, 160, 255)
MEASURED_RGB = (255, 200, 0)
GROUND_TRUTH_RGB = (255, 255, 255)
REGION_RGB = (160, 160, 160)
POINT_RGB = {"particles": (255, 120, 0), "detections": (255, 0, 255)}
OTHER_POINT_RGB = (0, 230, 230)


def entity_name(name: str) -> str:
    """A stage or scalar name made safe as one entity-path part."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", str(name)) or "_"


#: Box entities (under a target's subtree, or shared) -> (RGB, label, line radius px, draw order);
#: logged once as static style.  The estimate's colour is the target's own.
BOX_STYLES = {
    "boxes/estimate": (ESTIMATE_RGB, "estimate", 1.5, 12.0),
    "boxes/predicted": (PREDICTED_RGB, "predicted", 1.0, 10.0),
    "boxes/measured": (MEASURED_RGB, "measured", 1.0, 10.0),
    "video/boxes/ground_truth": (GROUND_TRUTH_RGB, "ground truth", 1.0, 11.0),
    "search_region": (REGION_RGB, "search region", 1.0, 5.0),
}


def target_path(target: int, name: str) -> str:
    """The entity ``name`` of target ``target``: ``targets/<id>/<name>``."""
    return f"targets/{int(target)}/{name}"


def rgba32(rgb) -> int:
    """``(r, g, b)`` -> rerun's packed ``0xRRGGBBAA`` colour (opaque)."""
    r, g, b = (int(c) for c in rgb)
    return (r << 24) | (g << 16) | (b << 8) | 0xFF


# ----------------------------------------------------------------- the sink


class RerunSink:
    """Writes every :class:`TrackState` and its stages to a Rerun recording (``.rrd``).

    Frames are JPEG-encoded as they come, but rows (frame, boxes, stage
    images, points, scalars) are buffered per entity and sent as columns every
    ``batch_frames`` frames and on :meth:`close`: one ``send_columns`` per
    entity and batch costs far less than one ``log`` call per entity and frame.
    Superpixel label images and status messages (rare) are logged directly.
    ``close`` also runs after Ctrl-C (``run_tracker`` closes its sinks in a
    ``finally``), so an interrupted run keeps every frame.

    Parameters
    ----------
    path
        The ``.rrd`` file to write (parents are created), or None with ``spawn``.
    filter_name
        The tracker's name (recording name and start message).
    ground_truth
        Frame index -> annotated box, logged as ``video/boxes/ground_truth`` on
        the frames that have one (invalid boxes mean "not annotated").
    spawn
        Also stream to a newly spawned Rerun viewer (needs a screen).
    superpixels_every
        Log ``stages/superpixels`` (a SegmentationImage, the largest stage) on
        every N-th frame only; the viewer keeps showing the last one.
    jpeg_quality
        JPEG quality of the frame.
    stage_every
        Log the other image stages every N-th frame (1: every frame).
    stage_max_side
        Longer side of logged stage images at most this many pixels.
    stage_jpeg_quality
        JPEG quality of real-valued stage images (masks are PNG, lossless).
    colormap
        Colormap of real-valued stage images: viridis, jet, inferno, turbo or gray.
    max_points
        At most this many points per point stage per frame (the heaviest).
    point_radius
        Point radius range in pixels, from zero weight to the largest weight.
    batch_frames
        Buffered rows are sent every this many frames (and on close), and the
        file is flushed: a spawned viewer lags by at most this many frames, and
        after a hard stop (``kill -9``) the file holds every frame up to the
        last complete batch (readable without the footer that ``close``
        writes).
    application_id
        Rerun application id (recordings of one application share blueprints).

    Raises
    ------
    OutputError
        When ``path`` cannot be written or the viewer cannot be spawned.
    """

    def __init__(self, path: str | Path | None, *, filter_name: str,
                 ground_truth: Mapping[int, Box] | None = None, spawn: bool = False,
                 superpixels_every: int = 5, jpeg_quality: int = 75, stage_every: int = 1,
                 stage_max_side: int = 128, stage_jpeg_quality: int = 80, colormap: str | None = "viridis",
                 max_points: int = 300, point_radius: tuple[float, float] = (0.5, 4.0),
                 batch_frames: int = 30, application_id: str = "vidtrack") -> None:
        if path is None and not spawn:
            raise UsageError("a Rerun recording needs a file path or spawn=True")
        if superpixels_every < 1 or stage_every < 1 or batch_frames < 1:
            raise UsageError("superpixels_every, stage_every and batch_frames must be at least 1")
        if not 1 <= jpeg_quality <= 100 or not 1 <= stage_jpeg_quality <= 100:
            raise UsageError("JPEG qualities must lie in 1..100")
        if colormap is not None and colormap not in COLORMAPS:
            raise UsageError(f"unknown colormap {colormap!r}; valid: {', '.join(COLORMAPS)}")
        self.path = Path(path) if path is not None else None
        self.filter_name = filter_name
        self.ground_truth = dict(ground_truth) if ground_truth is not None else {}
        self.spawn = spawn
        self.superpixels_every = int(superpixels_every)
        self.jpeg_quality = int(jpeg_quality)
        self.stage_every = int(stage_every)
        self.stage_max_side = int(stage_max_side)
        self.stage_jpeg_quality = int(stage_jpeg_quality)
        self.colormap = colormap
        self.max_points = int(max_points)
        self.point_radius = (float(point_radius[0]), float(point_radius[1]))
        self.batch_frames = int(batch_frames)
        self.application_id = application_id

        self._shown: set[str] = set()           # image/point entities showing data of the previous frame
        self._image_stages: list[str] = []      # image stage names seen, in order (blueprint)
        self._point_stages: list[str] = []
        self._blueprint_key: tuple | None = None
        self._last_status: dict[int, str] = {}   # target ID -> its status on the previous frame
        self._targets: list[int] = []           # target IDs seen, ascending (blueprint)
        self._styled: set[str] = set()          # entities whose static style is logged
        self._pending: list[tuple[str, str, Any]] = []   # this frame's actions, committed at its end
        # Buffered rows per entity: path -> (kind, rows); a row is (frame, payload),
        # payload None for an empty row that hides the entity from that frame on.
        self._rows: dict[str, tuple[str, list[tuple[int, Any]]]] = {}
        self._buffered = 0
        self._rec: rr.RecordingStream | None = None
        self._relay: RelayedFile | None = None   # the .rrd file, written through a pipe (see _open)
        self._open()

    # -- setup and teardown

    def _open(self) -> None:
        target = self.path
        if self.path is not None:
            open_text_output(self.path).close()   # fail now, with a clear message, if the path is not writable
            if relay_supported():   # rerun writes a pipe, copied here: a full disk is seen, never a hang
                try:
                    self._relay = RelayedFile(self.path)
                except OSError as exc:
                    raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}") from None
                target = self._relay.inlet
        rec = rr.RecordingStream(self.application_id, recording_id=uuid.uuid4())
        rec.set_log_time_enabled(False)  # one timeline: frame
        rec.set_log_tick_enabled(False)
        blueprint = self._blueprint()
        try:
            if self.spawn:
                rec.spawn(connect=False, hide_welcome_screen=True)
                if self.path is not None:
                    rec.set_sinks(rr.GrpcSink(), rr.FileSink(target), default_blueprint=blueprint)
                else:
                    rec.connect_grpc(default_blueprint=blueprint)
            else:
                rec.save(target, default_blueprint=blueprint)
        except Exception as exc:  # rerun raises plain RuntimeError/ValueError
            if self._relay is not None:
                self._relay.close()
                self._relay = None
            target = "a Rerun viewer" if self.path is None else str(self.path)
            raise OutputError(f"cannot write {target}: {str(exc).splitlines()[0] if str(exc) else exc}") from None
        rec.send_recording_name(f"vidtrack {self.filter_name}")
        self._rec = rec
        self._blueprint_key = self._layout_key()

    def close(self) -> None:
        """Finish the recording: send buffered rows, flush, write the footer (the file is then complete).

        Safe to call twice; also called by ``run_tracker`` after Ctrl-C.
        """
        rec = self._rec
        if rec is None:
            return
        try:
            self._send_buffered()
            rec.flush()
        finally:
            self._rec = None
            rec.disconnect()  # drops the file sink, which writes the RRD footer
            if self._relay is not None:   # a failed write cuts the file back to its last complete batch
                relay, self._relay = self._relay, None
                relay.close()

    def __enter__(self) -> "RerunSink":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- blueprint

    def _layout_key(self) -> tuple:
        return tuple(self._image_stages), tuple(self._point_stages), tuple(self._targets)

    def _blueprint(self) -> rrb.Blueprint:
        """Frame with boxes and point stages; one overlay view per image stage; time series; status log."""
        targets = self._targets or [1]
        boxes = [entry for t in targets
                 for entry in (f"+ {target_path(t, 'boxes')}/**", f"+ {target_path(t, 'search_region')}")]
        overlay = ["+ video/frame", "+ video/boxes/**", *boxes]
        points = [f"+ {target_path(t, 'stages/' + p)}" for t in targets for p in self._point_stages]
        frame_view = rrb.Spatial2DView(name="frame", origin="/", contents=["+ video/**", *points, *boxes])
        left = rrb.Vertical(frame_view, rrb.TextLogView(name="status", origin="targets"), row_shares=[4, 1])
        plots = rrb.TimeSeriesView(name="filter", origin="/",
                                   contents=[f"+ {target_path(t, 'filter')}/**" for t in targets])
        if self._image_stages:
            stage_views = [rrb.Spatial2DView(name=s, origin="/",
                                             contents=[*(f"+ {target_path(t, 'stages/' + s)}" for t in targets),
                                                       *overlay])
                           for s in self._image_stages]
            right = rrb.Vertical(rrb.Grid(*stage_views), plots, row_shares=[3, 2])
        else:
            right = plots
        return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), collapse_panels=False)

    def _update_blueprint(self) -> None:
        key = self._layout_key()
        if key != self._blueprint_key:
            self._rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
            self._blueprint_key = key

    # -- writing

    def _style(self, path: str, kind: str, name: str = "", box: tuple | None = None) -> None:
        """Log ``path``'s colours, labels, widths and draw order once, as static data.

        Frames then carry only geometry, pixels and box colours (smaller and faster); entities
        get a style only when first used, so a recording lists only what it shows.
        """
        if path in self._styled or any(item[1] == path for item in self._pending if item[0] == "style"):
            return
        if kind == "box":
            label, show, radius, order = box
            style = rr.Boxes2D.from_fields(labels=[label], show_labels=show, radii=[radius], draw_order=order)
        elif kind == "frame":
            style = rr.EncodedImage.from_fields(media_type="image/jpeg", draw_order=-20.0)
        elif kind == "points":
            style = rr.Points2D.from_fields(colors=[POINT_RGB.get(name, OTHER_POINT_RGB)], draw_order=30.0)
        elif kind == "labels":
            style = rr.SegmentationImage.from_fields(opacity=0.6, draw_order=-10.0)
        else:
            style = rr.EncodedImage.from_fields(draw_order=-10.0)
        self._pending.append(("style", path, (style,)))

    def write(self, frame: Frame, targets: Mapping[int, TrackState]) -> None:
        """Log ``frame`` and every target's state on timeline ``frame`` at the frame's index."""
        if self._rec is None:
            raise OutputError(f"cannot write {self.path or 'to Rerun'}: the recording is closed")
        index = int(frame.index)
        # Everything this frame logs is prepared first and committed at the end, so a
        # Ctrl-C while preparing leaves no half-logged frame in the recording.
        self._pending = []
        shown: set[str] = set()   # entities that show data from this frame on

        self._style("video/frame", "frame")
        self._row("video/frame", "frame", index, encode_jpeg(frame.image, self.jpeg_quality))
        truth = self.ground_truth.get(index)
        if truth is not None and truth.is_valid():
            rgb, label, radius, order = BOX_STYLES["video/boxes/ground_truth"]
            self._style("video/boxes/ground_truth", "box", box=(label, False, radius, order))
            self._row("video/boxes/ground_truth", "box", index, (truth.as_array(), rgba32(rgb)))
            shown.add("video/boxes/ground_truth")
        statuses = {}
        for target, state in targets.items():
            if target not in self._targets:
                self._targets = sorted([*self._targets, int(target)])
            self._write_target(frame, int(target), state, shown, several=len(targets) > 1)
            statuses[int(target)] = self._status_message(int(target), state, several=len(targets) > 1)

        for path in sorted(self._shown - shown):     # showed something last frame, nothing now
            kind = self._rows[path][0] if path in self._rows else None
            if kind is not None and kind != "labels":
                self._row(path, kind, index, None)     # an empty row hides it
            else:
                self._log(path, rr.Clear(recursive=False))

        # commit
        self._rec.set_time("frame", sequence=index)
        for action, path, payload in self._pending:
            if action == "row":
                kind, index_, data = payload
                if path in self._rows and self._rows[path][0] != kind:   # a stage changed shape
                    self._send_buffered()
                    del self._rows[path]
                self._rows.setdefault(path, (kind, []))[1].append((index_, data))
            elif action == "style":
                self._rec.log(path, *payload, static=True)
                self._styled.add(path)
            else:
                self._rec.log(path, *payload)
        self._pending = []
        self._shown = shown
        self._last_status = statuses
        self._update_blueprint()
        self._buffered += 1
        if self._buffered >= self.batch_frames:
            self._send_buffered()
            if self.path is not None:
                self._rec.flush()  # the batch is in the file: a hard stop (kill -9) keeps it
                if self._relay is not None:
                    self._relay.sync()   # a full disk: WriteFailed

    def _write_target(self, frame: Frame, target: int, state: TrackState, shown: set[str], *, several: bool) -> None:
        """Queue one target's boxes, stages and scalars under ``targets/<id>/``."""
        index = int(frame.index)
        for name, box in (("boxes/estimate", state.box), ("boxes/predicted", state.predicted),
                          ("boxes/measured", state.measured), ("search_region", state.search_region)):
            if box is None or not box.is_valid():
                continue
            path = target_path(target, name)
            rgb, label, radius, order = BOX_STYLES[name]
            if name == "boxes/estimate":
                rgb = LOST_RGB if state.status == "lost" else target_colour_rgb(target)
                label = f"{target}" if several else label
            self._style(path, "box", box=(label, several and name == "boxes/estimate", radius, order))
            self._row(path, "box", index, (box.as_array(), rgba32(rgb)))
            shown.add(path)

        for name, value in state.stages.items():
            self._stage(frame, state, target_path(target, f"stages/{entity_name(name)}"), value, shown)

        self._row(target_path(target, "filter/confidence"), "scalar", index, float(state.confidence))
        for name, value in state.scalars.items():
            if name == "confidence":
                continue
            try:
                number = float(value)
            except (TypeError, ValueError):
                continue
            self._row(target_path(target, f"filter/{entity_name(name)}"), "scalar", index, number)

    def _row(self, path: str, kind: str, index: int, payload) -> None:
        """Queue one row of ``path`` (``payload`` None: an empty row), sent with the next batch."""
        self._pending.append(("row", path, (kind, index, payload)))

    def _log(self, path: str, *archetypes) -> None:
        """Log ``archetypes`` at ``path`` directly (at this frame's commit)."""
        self._pending.append(("log", path, archetypes))

    def _send_buffered(self) -> None:
        """Send every entity's buffered rows as columns (one ``send_columns`` per entity)."""
        rec = self._rec
        for path, (kind, rows) in self._rows.items():
            if not rows:
                continue
            frames = [r[0] for r in rows]
            data = [r[1] for r in rows if r[1] is not None]
            lengths = [0 if r[1] is None else 1 for r in rows]
            if kind == "scalar":
                columns = rr.Scalars.columns(scalars=np.array(data, dtype=np.float64)).partition(lengths)
            elif kind == "frame":
                columns = rr.EncodedImage.columns(blob=data).partition(lengths)
            elif kind == "box":
                boxes = np.array([d[0] for d in data], dtype=np.float32).reshape(-1, 4)
                columns = rr.Boxes2D.columns(centers=boxes[:, :2] + boxes[:, 2:] / 2.0,
                                             half_sizes=boxes[:, 2:] / 2.0,
                                             colors=np.array([d[1] for d in data], dtype=np.uint32)
                                             ).partition(lengths)
            elif kind == "points":
                lengths = [0 if r[1] is None else len(r[1][0]) for r in rows]
                positions = np.concatenate([d[0] for d in data]) if data else np.zeros((0, 2), np.float32)
                radii = np.concatenate([d[1] for d in data]) if data else np.zeros(0, np.float32)
                columns = rr.Points2D.columns(positions=positions, radii=radii).partition(lengths)
            elif kind == "image":
                translations = np.array([d[2] for d in data], dtype=np.float32).reshape(-1, 3)
                scales = np.array([d[3] for d in data], dtype=np.float32).reshape(-1, 3)
                columns = [*rr.EncodedImage.columns(blob=[d[0] for d in data],
                                                    media_type=[d[1] for d in data]).partition(lengths),
                           *rr.Transform3D.columns(translation=translations, scale=scales).partition(lengths)]
            else:  # pragma: no cover - labels are logged directly
                raise AssertionError(kind)
            rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)], columns=columns)
            rows.clear()
        self._buffered = 0

    def _stage(self, frame: Frame, state: TrackState, path: str, value, shown: set[str]) -> None:
        """Queue (or log) one stage at ``path``; add it to ``shown`` when it shows something from now on."""
        name = path.rsplit("/", 1)[-1]
        if value is None:
            return
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
        index = int(state.index)
        if arr.ndim == 0:
            if arr.dtype.kind in "biuf":
                self._row(path, "scalar", index, float(arr))
                shown.add(path)
            return
        kind = stage_kind(name, arr)
        if kind is None:
            return
        if kind == "points":
            if name not in self._point_stages:
                self._point_stages.append(name)
            if arr.size == 0:
                return  # nothing to show: hidden as absent
            self._style(path, kind, name)
            self._row(path, "points", index,
                      point_display(arr, max_points=self.max_points, radius_range=self.point_radius))
            shown.add(path)
            return

        every = self.superpixels_every if kind == "labels" else self.stage_every
        if index % every != 0:
            if path in self._shown:
                shown.add(path)   # rate-limited: keep showing the last one
            return
        region = None if name.endswith("_full") else state.search_region
        if region is None or not region.is_valid():
            region = Box(0.0, 0.0, float(frame.width), float(frame.height))
        if name not in self._image_stages:
            self._image_stages.append(name)
        self._style(path, kind, name)
        shown.add(path)
        if kind == "labels":   # every N-th frame only: logged directly
            labels = labels_for_segmentation(arr, self.stage_max_side)
            translation, scale = region_transform(region, labels.shape)
            self._log(path, rr.Transform3D(translation=translation, scale=scale), rr.SegmentationImage(labels))
            return
        contents, media_type, shape = display_image(arr, max_side=self.stage_max_side, colormap=self.colormap,
                                                    jpeg_quality=self.stage_jpeg_quality)
        translation, scale = region_transform(region, shape)
        self._row(path, "image", index, (contents, media_type, translation, scale))

    def _status_message(self, target: int, state: TrackState, *, several: bool) -> str:
        """Queue a TextLog at ``targets/<id>/log/status`` on its first frame and on status changes; return the status."""
        status = state.status
        path = target_path(target, "log/status")
        who = f"target {target} " if several else ""
        last = self._last_status.get(target)
        if last is None:
            self._log(path, rr.TextLog(f"frame {state.index}: {self.filter_name} {who}starts {status} "
                                       f"at {state.box}", level="INFO"))
        elif status != last:
            if status == "lost":
                text = f"frame {state.index}: {who}lost (confidence {state.confidence:.2f}), predicting {state.box}"
                self._log(path, rr.TextLog(text, level="WARN"))
            else:
                text = f"frame {state.index}: {who}re-acquired at {state.box} (confidence {state.confidence:.2f})"
                self._log(path, rr.TextLog(text, level="INFO"))
        return status
