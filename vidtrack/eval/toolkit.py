"""Result files in the layout each benchmark's own toolkit reads, beside vidtrack's own.

::

    OUT/toolkit/otb/<filter>/<Sequence>.txt        OTB, LaSOT and UAV123 (folder lasot/, uav123/):
    OUT/toolkit/lasot/<filter>/<sequence>.txt      one x,y,w,h row per frame, commas, in the
    OUT/toolkit/uav123/<filter>/<sequence>.txt     benchmark's own pixel convention
    OUT/toolkit/got10k/<filter>/<seq>/<seq>_001.txt  GOT-10k: one x,y,w,h row per frame (0-based), run 1
    OUT/toolkit/got10k/<filter>/<seq>/<seq>_time.txt seconds per frame

``OUT/toolkit/got10k/<filter>/`` zipped as it is is a GOT-10k test-split
submission.  Each tracked frame's time is the tracker's seconds on that frame
(the run record's ``frame_seconds``, :mod:`vidtrack.eval.frame_times`; the
first line is the initialisation); a record without them (written by an
earlier vidtrack) gives every tracked frame the run's mean time per frame.
Rows not tracked (``--max-frames``) have time 0 and the box ``0,0,0,0``,
which the toolkits skip or score as failures.  MIL and VOT sequences have no
such folder (VOT's toolkit runs the tracker itself, over TraX).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from .results import result_paths, write_atomic
from .sequence import BenchmarkSequence

TOOLKIT_FOLDER = "toolkit"
#: Layouts whose toolkit reads one ``<sequence>.txt`` per tracker folder.
FLAT_LAYOUTS = ("otb", "lasot", "uav123")


def toolkit_paths(out: str | Path, layout: str, filter_name: str, sequence_name: str) -> tuple[Path, Path | None]:
    """``(result file, time file or None)`` of one run in its toolkit's layout.

    Raises
    ------
    ValueError
        For a layout without a toolkit layout (``mil``, ``vot``).
    """
    base = Path(out) / TOOLKIT_FOLDER / layout / filter_name
    if layout in FLAT_LAYOUTS:
        return base / f"{sequence_name}.txt", None
    if layout == "got10k":
        folder = base / sequence_name
        return folder / f"{sequence_name}_001.txt", folder / f"{sequence_name}_time.txt"
    raise ValueError(f"no toolkit layout for {layout!r} sequences")


def frame_times(record: Mapping[str, Any], rows: int) -> list[float]:
    """Seconds per ground-truth row: each tracked row's time, 0 on the rows not tracked.

    The times are the record's ``frame_seconds`` (one per tracked row, in
    order); a record without them, or with another count, gives every
    tracked row the run's mean time per frame.
    """
    start, stop = record["tracked"]
    times = [0.0] * rows
    recorded = record.get("frame_seconds")
    if isinstance(recorded, list) and len(recorded) == stop - start:
        times[start:stop] = (float(t) for t in recorded)
        return times
    frames = max(int(record.get("frames") or 0), 1)
    each = float(record.get("track_seconds") or 0.0) / frames
    times[start:stop] = [each] * (stop - start)
    return times


def write_toolkit_results(out: str | Path, sequences: Sequence[BenchmarkSequence], filters: Sequence[str],
                          records: Mapping[tuple[str, str], Mapping[str, Any] | None]) -> list[Path]:
    """Copy every finished result (those with a record) into its toolkit's layout; the tracker folders written.

    Raises
    ------
    OutputError
        When a file cannot be written.
    """
    written: list[Path] = []
    for name in filters:
        for sequence in sequences:
            record = records.get((name, sequence.name))
            if record is None or sequence.layout not in (*FLAT_LAYOUTS, "got10k"):
                continue
            source = result_paths(out, name, sequence.name)[0]
            result, times = toolkit_paths(out, sequence.layout, name, sequence.name)
            write_atomic(result, source.read_text(encoding="utf-8"))
            if times is not None:
                write_atomic(times, "".join(f"{t:.8f}\n" for t in frame_times(record, len(sequence))))
            folder = Path(out) / TOOLKIT_FOLDER / sequence.layout / name
            if folder not in written:
                written.append(folder)
    return written
