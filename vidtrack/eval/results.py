"""The files of an evaluation: where a result lives, how it is written and how its record is read.

Running (:mod:`vidtrack.eval.running`) writes them and scoring
(:mod:`vidtrack.eval.scoring`) reads them; nothing else passes between the two
(DESIGN.md: evaluation goes through files)::

    OUT/<filter>/<Sequence>.txt     one x,y,w,h line per ground-truth row, in the
                                    sequence's own convention; rows not tracked
                                    (outside the MIL frames range, before the init
                                    frame, past --max-frames) are 0,0,0,0
    OUT/<filter>/<Sequence>.json    the run record: fps of *that* run and the tracker's
                                    seconds on each tracked row (frame_seconds), tracked
                                    rows, seed, max_frames, the tracker's effective
                                    settings (every option of its configuration), so a
                                    resumed evaluation reports honest fps and reuses only
                                    results made the same way
    OUT/<filter>/<Sequence>.confidence.csv  the tracker's per-frame confidence and
                                    status (:mod:`vidtrack.eval.confidence`)
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from typing import Any

from ..errors import DatasetError
from .confidence import confidence_path

#: Version of the run record's format; a record of another version is never reused.
RECORD_VERSION = 2
#: Ending of a result file's name: ``OUT/<filter>/<Sequence>.txt``
RESULT_SUFFIX = ".txt"
#: A result row the tracker did not track.
NOT_TRACKED = "0,0,0,0"


def result_paths(out: str | Path, filter_name: str, sequence_name: str) -> tuple[Path, Path]:
    """``(OUT/<filter>/<Sequence>.txt, OUT/<filter>/<Sequence>.json)``."""
    folder = Path(out) / filter_name
    return folder / f"{sequence_name}{RESULT_SUFFIX}", folder / f"{sequence_name}.json"


def run_sequences(out: str | Path, suffix: str, what: str, filters: list[str] | None = None) -> dict[str, list[str]]:
    """The trackers of an evaluation folder ``out`` and the sequences each has a ``<Sequence><suffix>`` file for.

    ``filters``: the trackers to take (default: every subfolder with such a
    file); ``what`` names the files in the error messages (``"result files"``).

    Raises
    ------
    DatasetError
        When ``out`` is not a folder, holds no tracker with such files, or a named tracker has none.
    """
    out = Path(out)
    if not out.is_dir():
        raise DatasetError(f"{out}: not a folder")
    if filters is None:
        filters = sorted(f.name for f in out.iterdir() if f.is_dir() and any(f.glob(f"*{suffix}")))
        if not filters:
            raise DatasetError(f"{out}: no tracker with {what}")
    found = {}
    for name in filters:
        names = sorted(path.name[:-len(suffix)] for path in (out / name).glob(f"*{suffix}"))
        if not names:
            raise DatasetError(f"{out / name}: no {what}")
        found[name] = names
    return found


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a ``.part`` file of this writer's own, so a reader never sees half of it.

    The rename is atomic: of two processes writing the same file, the last
    rename wins with a whole file.

    Raises
    ------
    OutputError
        When the file cannot be written; :class:`~vidtrack.sinks.base.WriteFailed`
        for a full disk (the earlier version of the file, if any, is kept).
    """
    from ..sinks.base import failed_write

    # one .part file per writer: two evaluations writing one folder never write into each other's
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.part")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)   # no half-written file left behind (a full disk)
        raise failed_write(path, exc) from None


def check_writable_folder(path: str | Path) -> Path:
    """Create the folder ``path`` (and its missing parents) and check that a file can be written in it.

    An evaluation checks its output folders before the first job runs, so
    an unwritable one is bad input found at the start, not a failure after
    the first sequence.

    Raises
    ------
    OutputError
        When the folder cannot be created or written (read-only, a file of that name, no permission).
    """
    from ..errors import OutputError

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"cannot write {path}: it is not a folder")
    probe = path / f".vidtrack-write-check.{os.getpid()}.{threading.get_ident()}"
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def write_result(out: str | Path, filter_name: str, sequence_name: str, lines: list[str], record: dict[str, Any],
                 confidence: str | None = None) -> None:
    """Write a finished run's result file, its confidence file, then its record (the record marks it complete)."""
    txt, record_path = result_paths(out, filter_name, sequence_name)
    write_atomic(txt, "\n".join(lines) + "\n")
    if confidence is not None:
        write_atomic(confidence_path(txt), confidence)
    write_atomic(record_path, json.dumps(record, indent=1) + "\n")


def read_record(out: str | Path, filter_name: str, sequence_name: str) -> dict[str, Any] | None:
    """The record of a complete result (result, confidence and record files present), else None."""
    txt, record_path = result_paths(out, filter_name, sequence_name)
    if not (txt.is_file() and record_path.is_file() and confidence_path(txt).is_file()):
        return None
    try:
        record = json.loads(record_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None
