"""``OUT/report.html``: the evaluation in one self-contained page a person reads at a glance.

The page holds the mean and per-sequence score tables (sortable: click a
column header), the confidence table, the attribute table, the success,
precision and attribute plots, and per sequence a strip of thumbnails with
the ground truth and every tracker's box drawn, taken where the best tracker
(highest mean AUC) first fails, so failures are seen rather than read.
Images are inlined as base64 data URIs and the sorting script is inline:
the file opens from disk with no network and no other file.

Like the rest of the report it reads only result files (and the sequences'
frames for the thumbnails).
"""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import OutputError
from .plots import palette, reliability_plot

REPORT_FILE = "report.html"
#: Ground-truth box colour in the thumbnails (BGR) and in the legend.
GT_BGR, GT_HEX = (255, 255, 255), "#ffffff"
THUMB_WIDTH = 184
#: IoU below which a frame counts as a failure in the thumbnail strips: lower than PASCAL's 0.5, so
#: that a box wobbling around 0.5 is not shown as a failure but one visibly off the target is.
FAIL_BELOW = 0.3

SCORE_COLUMNS = (("auc", "AUC", 3), ("precision20", "Prec@20", 3), ("norm_precision", "NormPrec", 3),
                 ("pascal", "PASCAL", 3), ("center_error", "CLE px", 1), ("fps", "fps", 1), ("lost_rate", "lost", 3),
                 ("false_lost", "false lost", 3), ("missed_loss", "missed loss", 3),
                 ("confidence_auc", "conf. ROC AUC", 3), ("ece", "ECE", 3))
#: GOT-10k's average overlap and success rates, shown when a sequence has them.
GOT10K_COLUMNS = (("ao", "AO", 3), ("sr50", "SR0.5", 3), ("sr75", "SR0.75", 3))

_STYLE = """
body{font-family:system-ui,sans-serif;margin:1.2em 2em;color:#222;background:#fafafa}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;font-size:0.85em;margin:0.5em 0}
th,td{border:1px solid #ccc;padding:2px 7px;text-align:right}th{background:#eee}
td:first-child,td.t,th.t{text-align:left}
table.sortable th{cursor:pointer;user-select:none}table.sortable th:hover{background:#ddd}
th.asc::after{content:" \\25B2"}th.desc::after{content:" \\25BC"}
.plots{display:flex;flex-wrap:wrap;gap:0.5em;align-items:flex-start}
.plots img{border:1px solid #ddd;background:#fff;max-width:calc(50% - 0.5em)}.plots img.wide{max-width:100%}.fail{color:#c00;font-weight:bold}
.strip{display:flex;flex-wrap:wrap;gap:6px}
figure{margin:0;font-size:0.75em;text-align:center}figure img{display:block;border:1px solid #999}
.legend span{display:inline-block;margin-right:1em;font-size:0.85em}
.legend i{display:inline-block;width:1.6em;height:0.7em;margin-right:0.3em;border:1px solid #555}
.note{font-size:0.85em;color:#555;max-width:60em}
#broken{display:none;background:#fdd;border:1px solid #c00;padding:0.5em}
"""

# a click on a header sorts its table's body by that column (numbers by data-v, else text); again reverses
_SCRIPT = """
document.querySelectorAll('table.sortable').forEach(function (table) {
  table.querySelectorAll('th').forEach(function (th, col) {
    th.addEventListener('click', function () {
      var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
      var desc = !th.classList.contains('desc');
      table.querySelectorAll('th').forEach(function (h) { h.classList.remove('asc', 'desc'); });
      th.classList.add(desc ? 'desc' : 'asc');
      function key(row) {
        var cell = row.cells[col], v = cell.getAttribute('data-v');
        return v === null ? cell.textContent : (v === '' ? NaN : parseFloat(v));
      }
      rows.sort(function (a, b) {
        var x = key(a), y = key(b), c;
        if (typeof x === 'number' || typeof y === 'number') {
          if (isNaN(x)) { return isNaN(y) ? 0 : 1; }
          if (isNaN(y)) { return -1; }
          c = x - y;
        } else { c = x < y ? -1 : (x > y ? 1 : 0); }
        return desc ? -c : c;
      });
      rows.forEach(function (row) { body.appendChild(row); });
    });
  });
});
window.addEventListener('load', function () {
  var images = document.images, loaded = 0;
  for (var i = 0; i < images.length; i++) {
    if (images[i].complete && images[i].naturalWidth > 0) { loaded++; }
  }
  document.body.setAttribute('data-images', loaded + '/' + images.length);
  if (loaded < images.length) {
    var banner = document.getElementById('broken');
    banner.textContent = (images.length - loaded) + ' of ' + images.length + ' images failed to load';
    banner.style.display = 'block';
  }
});
"""


def _number(value: Any) -> float | None:
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def _td(value: Any, digits: int) -> str:
    number = _number(value)
    if number is None:
        return '<td data-v="">-</td>'
    return f'<td data-v="{number:.6g}">{number:.{digits}f}</td>'


def _table(header: Sequence[str], rows: Sequence[str], *, sortable: bool = True, left: int = 1) -> str:
    cells = "".join(f'<th class="t">{html.escape(h)}</th>' if i < left else f"<th>{html.escape(h)}</th>"
                    for i, h in enumerate(header))
    kind = ' class="sortable"' if sortable else ""
    return f"<table{kind}><thead><tr>{cells}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def _text_cell(text: str, colour: str | None = None) -> str:
    swatch = f'<i style="background:{colour}"></i>' if colour else ""
    return f'<td class="t"><span class="legend">{swatch}</span>{html.escape(text)}</td>'


def data_uri(data: bytes, mime: str) -> str:
    """``data:MIME;base64,...`` for ``data``."""
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _hex(rgb: tuple[int, int, int]) -> str:
    return "#%02x%02x%02x" % rgb


def strip_rows(ious: np.ndarray, *, count: int = 6, threshold: float = FAIL_BELOW) -> list[int]:
    """The rows to show for one sequence: where the tracker fails first.

    Parameters
    ----------
    ious
        ``(N,)`` IoU per ground-truth row, NaN on rows not scored.
    count
        How many rows at most.
    threshold
        A scored row with ``IoU < threshold`` is a failure.

    Returns
    -------
    list of int
        Sorted rows: the first scored row, then the starts of failures (a
        failing row whose previous scored row did not fail) in order, then the
        last scored row; when there are fewer failures than room, evenly
        spaced scored rows fill up.
    """
    ious = np.asarray(ious, dtype=float)
    scored = np.flatnonzero(np.isfinite(ious))
    if scored.size == 0 or count < 1:
        return []
    failing = ious[scored] < threshold
    onsets = [int(scored[i]) for i in range(scored.size) if failing[i] and (i == 0 or not failing[i - 1])]
    chosen = [int(scored[0])]
    for row in onsets:
        if len(chosen) >= count - 1:
            break
        if row not in chosen:
            chosen.append(row)
    if int(scored[-1]) not in chosen and len(chosen) < count:
        chosen.append(int(scored[-1]))
    for row in np.linspace(0, scored.size - 1, count + 2).round().astype(int)[1:-1]:
        if len(chosen) >= count:
            break
        if int(scored[row]) not in chosen:
            chosen.append(int(scored[row]))
    return sorted(chosen)


def thumbnail(image: np.ndarray, boxes: Mapping[str, Any], colours: Mapping[str, tuple[int, int, int]], *,
              ground_truth=None, width: int = THUMB_WIDTH) -> np.ndarray:
    """``image`` (``(H, W, 3)`` uint8 BGR) scaled to ``width`` px with the boxes drawn.

    ``boxes`` maps a tracker to its ``x, y, w, h`` box in 0-based pixels of
    ``image`` (None: not drawn); ``colours`` gives its ``(r, g, b)``;
    ``ground_truth`` is drawn white over a black outline.
    """
    import cv2

    scale = width / image.shape[1]
    small = cv2.resize(image, (width, max(1, int(round(image.shape[0] * scale)))), interpolation=cv2.INTER_AREA)
    if small.ndim == 2:
        small = cv2.cvtColor(small, cv2.COLOR_GRAY2BGR)

    def draw(box, bgr, thickness):
        x, y, w, h = (float(v) * scale for v in box)
        if not all(math.isfinite(v) for v in (x, y, w, h)) or w <= 0 or h <= 0:
            return
        cv2.rectangle(small, (int(round(x)), int(round(y))), (int(round(x + w)), int(round(y + h))), bgr,
                      thickness, cv2.LINE_AA)

    if ground_truth is not None:
        draw(ground_truth, (0, 0, 0), 3)
        draw(ground_truth, GT_BGR, 1)
    for name, box in boxes.items():
        if box is not None:
            r, g, b = colours[name]
            draw(box, (b, g, r), 2)
    return small


def _jpeg_uri(image: np.ndarray) -> str:
    import cv2

    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 82])
    if not ok:
        raise OutputError("cannot encode a report thumbnail")
    return data_uri(data.tobytes(), "image/jpeg")


def _sequence_strip(sequence, boxes: Mapping[str, np.ndarray], best: str | None,
                    colours: Mapping[str, tuple[int, int, int]], ious: np.ndarray | None) -> str:
    import cv2

    rows = strip_rows(ious) if ious is not None else []
    figures = []
    for row in rows:
        image = cv2.imread(str(sequence.files[row]), cv2.IMREAD_COLOR)
        if image is None:
            continue
        pixel_boxes = {}
        for name, array in boxes.items():
            b = array[row]
            pixel_boxes[name] = None if not np.any(b) else (b[0] - sequence.origin, b[1] - sequence.origin, b[2], b[3])
        gt = sequence.ground_truth[row]
        gt_box = (gt[0] - sequence.origin, gt[1] - sequence.origin, gt[2], gt[3])
        label = html.escape(sequence.files[row].name)
        if best is not None and ious is not None and np.isfinite(ious[row]):
            fails = ' class="fail"' if ious[row] < FAIL_BELOW else ""
            label += f"<br><span{fails}>{html.escape(best)} IoU {ious[row]:.2f}</span>"
        figures.append(f'<figure><img alt="{html.escape(sequence.name)} {html.escape(sequence.files[row].name)}" '
                       f'src="{_jpeg_uri(thumbnail(image, pixel_boxes, colours, ground_truth=gt_box))}">'
                       f"<figcaption>{label}</figcaption></figure>")
    if not figures:
        return "<p class=note>no scored frame to show</p>"
    return '<div class="strip">' + "".join(figures) + "</div>"


def _score_tables(summary: Mapping[str, Mapping[str, Mapping[str, Any]]],
                  colours: Mapping[str, tuple[int, int, int]]) -> tuple[str, str]:
    has_got = any("ao" in row for rows in summary.values() for row in rows.values())
    columns = SCORE_COLUMNS[:5] + GOT10K_COLUMNS + SCORE_COLUMNS[5:] if has_got else SCORE_COLUMNS
    header = ["filter", *(title for _, title, _ in columns)]
    means, per_sequence = [], []
    for name, rows in summary.items():
        mean = rows.get("mean", {})
        failed = f" ({len(mean['failed'])} failed)" if mean.get("failed") else ""
        means.append("<tr>" + _text_cell(name + failed, _hex(colours[name]))
                     + "".join(_td(mean.get(k), d) for k, _, d in columns) + "</tr>")
        for sequence, row in rows.items():
            if sequence == "mean":
                continue
            cells = (f'<td class="t" colspan="{len(columns)}">FAILED: {html.escape(str(row["error"]))}</td>'
                     if "error" in row else "".join(_td(row.get(k), d) for k, _, d in columns))
            per_sequence.append("<tr>" + _text_cell(name, _hex(colours[name])) + _text_cell(sequence) + cells
                                + "</tr>")
    return (_table(header, means),
            _table(["filter", "sequence", *header[1:]], per_sequence, left=2))


def _confidence_table(summary: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> str:
    keys = (("lost_rate", "lost"), ("false_lost", "false lost"), ("missed_loss", "missed loss"),
            ("confidence_auc", "conf. ROC AUC"), ("ece", "ECE"))
    rows = []
    for name, per in summary.items():
        mean = per.get("mean", {})
        rows.append("<tr>" + _text_cell(name) + "".join(_td(mean.get(k), 3) for k, _ in keys) + "</tr>")
        if isinstance(mean.get("ok_flag"), dict):
            rows.append("<tr>" + _text_cell(f"{name} (OpenCV ok flag)")
                        + "".join(_td(mean["ok_flag"].get(k), 3) for k, _ in keys) + "</tr>")
    return _table(["filter", *(title for _, title in keys)], rows)


def _attribute_table(by_attribute: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> str:
    from .attributes import OTB_ATTRIBUTES, tag_order

    tags = tag_order({t for per in by_attribute.values() for t in per})
    counts = {t: max(per[t]["sequences"] for per in by_attribute.values() if t in per) for t in tags}
    header = ["filter", *(f"{t} ({counts[t]})" for t in tags)]
    rows = ["<tr>" + _text_cell(name) + "".join(_td(per.get(t, {}).get("auc"), 3) for t in tags) + "</tr>"
            for name, per in by_attribute.items()]
    names = ", ".join(f"{t} {OTB_ATTRIBUTES[t]}" for t in tags if t in OTB_ATTRIBUTES)
    return _table(header, rows) + f'<p class="note">Mean success AUC over the sequences carrying each tag ' \
                                  f'(their number in brackets). {html.escape(names)}.</p>'


def best_filter(summary: Mapping[str, Mapping[str, Mapping[str, Any]]]) -> str | None:
    """The filter with the highest mean AUC (None when none has one)."""
    scored = [(_number(rows.get("mean", {}).get("auc")), name) for name, rows in summary.items()]
    scored = [(auc, name) for auc, name in scored if auc is not None]
    return max(scored, key=lambda item: item[0])[1] if scored else None


def render_report(summary: Mapping[str, Mapping[str, Mapping[str, Any]]], sequences: Sequence, out: str | Path, *,
                  by_attribute: Mapping[str, Mapping[str, Mapping[str, Any]]] | None = None,
                  plots: Sequence[str | Path] = (), title: str = "vidtrack evaluation") -> str:
    """The report page's HTML text.

    Parameters
    ----------
    summary
        :attr:`vidtrack.eval.evaluation.Evaluation.summary`.
    sequences
        The evaluated :class:`~vidtrack.eval.datasets.BenchmarkSequence` s (frames for the thumbnails).
    out
        The evaluation folder (``OUT/<filter>/<Sequence>.txt`` result files are read from it).
    by_attribute
        :func:`vidtrack.eval.attributes.by_attribute`'s output, if any.
    plots
        PNG files to inline (missing ones are left out).
    """
    from .datasets import read_boxes
    from .results import result_paths
    from .metrics import iou

    out = Path(out)
    filters = list(summary)
    colours = palette(filters)
    best = best_filter(summary)
    means, per_sequence = _score_tables(summary, colours)
    parts = [f"<h1>{html.escape(title)}</h1>",
             '<div id="broken"></div>',
             f'<p class="note">{len(filters)} tracker{"s" * (len(filters) != 1)} on {len(sequences)} '
             f'sequence{"s" * (len(sequences) != 1)}. Click a column header to sort. AUC: OTB success AUC; '
             "Prec@20: fraction of frames with centre error &le; 20 px; PASCAL: fraction with IoU &gt; 0.5; "
             "CLE: mean centre error; lost: fraction of frames marked lost; false lost: of those, the fraction "
             "still overlapping the target; missed loss: of the frames marked tracking, the fraction with "
             "IoU = 0; conf. ROC AUC: the confidence as a predictor of IoU &gt; 0.5 (0.5 = chance). Means "
             "are over sequences; the confidence columns pool the frames of all sequences.</p>",
             "<h2>Mean over sequences</h2>", means]
    images = [Path(p) for p in plots if Path(p).is_file()]
    if images:
        parts.append('<h2>Plots</h2><div class="plots">' + "".join(
            f'<img alt="{html.escape(p.stem)}" class="{"wide" if p.stem == "attributes" else "half"}" '
            f'src="{data_uri(p.read_bytes(), "image/png")}">' for p in images)
            + "</div>")
    parts += ["<h2>Can the confidence be trusted?</h2>", _confidence_table(summary),
              '<p class="note">Frames of all sequences pooled, init frame excluded. ECE: expected calibration '
              "error of the confidence read as the probability of IoU &gt; 0.5 (ten equal-width bins). The OpenCV "
              "ok flag rows score OpenCV's own update() flag as the status (it stays True after the target has "
              "gone).</p>"]
    if any(isinstance(per.get("mean", {}).get("reliability"), Mapping) for per in summary.values()):
        png = reliability_plot(None, summary, colours=colours)
        parts.append(f'<div class="plots"><img alt="reliability" class="half" src="{data_uri(png, "image/png")}">'
                     "</div>")
    if by_attribute and any(by_attribute.values()):
        parts += ["<h2>Success AUC by attribute</h2>", _attribute_table(by_attribute)]
    parts += ["<h2>Per sequence</h2>", per_sequence]

    legend = "".join(f'<span><i style="background:{_hex(colours[n])}"></i>{html.escape(n)}</span>' for n in filters)
    parts.append(f'<h2>Frames</h2><p class="legend"><span><i style="background:{GT_HEX}"></i>ground truth</span>'
                 f"{legend}</p><p class=note>Per sequence: the first frame, the frames where {html.escape(str(best))} "
                 f"(the best mean AUC) starts to fail (IoU &lt; {FAIL_BELOW:g}, in red), then evenly spaced frames "
                 "and the last one.</p>")
    for sequence in sequences:
        boxes = {}
        for name in filters:
            path = result_paths(out, name, sequence.name)[0]
            if "error" not in summary[name].get(sequence.name, {}) and path.is_file():
                array = read_boxes(path)
                if len(array) == len(sequence):
                    boxes[name] = array
        ious = None
        if best in boxes:
            scored = sequence.annotated & np.any(boxes[best] != 0, axis=1)  # 0,0,0,0: not tracked
            ious = np.full(len(sequence), np.nan)
            ious[scored] = iou(boxes[best][scored], sequence.ground_truth[scored])
        parts.append(f"<h3>{html.escape(sequence.name)}</h3>" + _sequence_strip(sequence, boxes, best, colours, ious))
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>"
            + "\n".join(parts) + f"<script>{_SCRIPT}</script></body></html>\n")


def write_report(out: str | Path, summary, sequences, **options) -> Path:
    """Write :func:`render_report`'s page to ``OUT/report.html``; options as there."""
    path = Path(out) / REPORT_FILE
    text = render_report(summary, sequences, out, **options)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path
