"""HOTA, IDF1 and MOTA of a MOT Challenge result file, computed by TrackEval (run in TrackEval's own venv).

    python tests/trackeval_score.py GT.txt RESULT.txt

Both files hold MOT Challenge lines ``frame,id,x,y,w,h,...``.  The IoUs come
from TrackEval's own box IoU and the metrics from its ``HOTA``, ``CLEAR``
and ``Identity`` classes (``eval_sequence`` on per-frame IDs and IoUs), so
vidtrack's code takes no part in the score.  Prints one JSON object: HOTA,
DetA, AssA (means over TrackEval's localisation thresholds), IDF1, IDSW,
MOTA, MOTP.  Imports only NumPy and TrackEval: vidtrack's venv is not needed.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import trackeval
from trackeval.datasets._base_dataset import _BaseDataset


def read_mot(path: str) -> dict[int, list[tuple[int, np.ndarray]]]:
    """Frame -> ``[(id, [x, y, w, h]), ...]`` of a MOT Challenge file."""
    rows: dict[int, list[tuple[int, np.ndarray]]] = {}
    with open(path, encoding="utf-8") as lines:
        for line in lines:
            if line.strip():
                values = [float(v) for v in line.split(",")[:6]]
                rows.setdefault(int(values[0]), []).append((int(values[1]), np.array(values[2:6])))
    return rows


def sequence_data(gt: dict, result: dict) -> dict:
    """TrackEval's per-sequence input: 0-based contiguous IDs and the IoU matrix of every frame."""
    frames = sorted(set(gt) | set(result))
    gt_index = {i: k for k, i in enumerate(sorted({i for rows in gt.values() for i, _ in rows}))}
    tr_index = {i: k for k, i in enumerate(sorted({i for rows in result.values() for i, _ in rows}))}
    data = {"num_timesteps": len(frames), "num_gt_ids": len(gt_index), "num_tracker_ids": len(tr_index),
            "gt_ids": [], "tracker_ids": [], "similarity_scores": [], "num_gt_dets": 0, "num_tracker_dets": 0}
    for frame in frames:
        g, r = gt.get(frame, []), result.get(frame, [])
        data["gt_ids"].append(np.array([gt_index[i] for i, _ in g], dtype=int))
        data["tracker_ids"].append(np.array([tr_index[i] for i, _ in r], dtype=int))
        gb = np.array([b for _, b in g]).reshape(-1, 4)
        rb = np.array([b for _, b in r]).reshape(-1, 4)
        data["similarity_scores"].append(_BaseDataset._calculate_box_ious(gb, rb, box_format="xywh"))
        data["num_gt_dets"] += len(g)
        data["num_tracker_dets"] += len(r)
    return data


def score(gt_path: str, result_path: str) -> dict[str, float]:
    """The metrics of ``result_path`` against ``gt_path``."""
    data = sequence_data(read_mot(gt_path), read_mot(result_path))
    hota = trackeval.metrics.HOTA().eval_sequence(data)
    clear = trackeval.metrics.CLEAR({"PRINT_CONFIG": False}).eval_sequence(data)
    identity = trackeval.metrics.Identity({"PRINT_CONFIG": False}).eval_sequence(data)
    return {"HOTA": float(np.mean(hota["HOTA"])), "DetA": float(np.mean(hota["DetA"])),
            "AssA": float(np.mean(hota["AssA"])), "IDF1": float(identity["IDF1"]), "IDSW": int(clear["IDSW"]),
            "MOTA": float(clear["MOTA"]), "MOTP": float(clear["MOTP"])}


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("\n\n")[1])
    print(json.dumps(score(sys.argv[1], sys.argv[2])))
