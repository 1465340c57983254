"""Reading a Rerun recording back: which entities show data on which frames (for the tests).

An independent check of :class:`vidtrack.sinks.rerun.RerunSink`'s output
beside the ``rerun`` CLI (``rerun rrd verify`` / ``rerun rrd stats``): the
``.rrd`` file is streamed chunk by chunk with rerun-sdk's ``RrdReader`` and
its Arrow columns are inspected, without a viewer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from rerun.chunk import RrdReader

from vidtrack.errors import OutputError


def read_recording(path: str | Path) -> dict[str, list[int]]:
    """Entity path -> sorted ``frame`` indices that show data, read from an ``.rrd`` file.

    Rows that only clear or hide an entity (``Clear``, an empty box list) do
    not count.  Static-only entities map to an empty list.

    Raises
    ------
    OutputError
        When the file cannot be read as a Rerun recording.
    """
    frames: dict[str, set[int]] = {}
    try:
        for chunk in RrdReader(str(path)).stream():
            entity = chunk.entity_path.lstrip("/")
            if entity.startswith("__"):
                continue
            batch = chunk.to_record_batch()
            seen = frames.setdefault(entity, set())
            if "frame" not in batch.schema.names:
                continue
            present = np.zeros(batch.num_rows, dtype=bool)
            for name in batch.schema.names:
                if ":" not in name or name.startswith(("Clear:", "rerun.")):
                    continue
                column = batch.column(name)
                if pa.types.is_list(column.type) or pa.types.is_large_list(column.type):
                    filled = pc.fill_null(pc.greater(pc.list_value_length(column), 0), False)
                else:
                    filled = pc.is_valid(column)
                present |= np.asarray(filled.to_pylist(), dtype=bool)
            index = batch.column("frame").to_pylist()
            seen.update(int(i) for i, p in zip(index, present) if p and i is not None)
    except Exception as exc:
        raise OutputError(f"cannot read Rerun recording {path}: {str(exc).splitlines()[0] if str(exc) else exc}") from None
    return {entity: sorted(idx) for entity, idx in sorted(frames.items())}
