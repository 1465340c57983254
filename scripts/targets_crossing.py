"""Score several targets on the generated crossing clips, aware of each other and independent, with TrackEval.

For each seed, writes the clip (``tests/crossing_clip.py``), tracks its
targets from ``boxes.txt`` (the input of ``vidtrack --init-boxes``) with every
filter twice, as ``vidtrack`` does (:class:`vidtrack.targets.MultiTargetTracker`)
and with independent trackers (``InteractionConfig(aware=False)``), writes the
MOT Challenge files and scores them with TrackEval in its own venv
(``tests/trackeval_score.py``).  Prints a Markdown table (IDF1, HOTA, MOTA, ID
switches per filter, mode and seed, and the means)::

    python scripts/targets_crossing.py --trackeval .venv-trackeval/bin/python --out /tmp/crossing
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from crossing_clip import write_clip  # noqa: E402

from vidtrack.api import track_targets  # noqa: E402
from vidtrack.cli.init_boxes import read_init_boxes  # noqa: E402
from vidtrack.recipes import build_tracker  # noqa: E402
from vidtrack.sinks.files import mot_line  # noqa: E402
from vidtrack.sources import open_source  # noqa: E402
from vidtrack.targets import InteractionConfig, MultiTargetTracker  # noqa: E402

MODES = {"aware": InteractionConfig(), "independent": InteractionConfig(aware=False)}


def run(clip: Path, boxes_file: Path, filter_name: str, config: InteractionConfig, out: Path) -> Path:
    """Track every target of ``boxes_file`` through ``clip``; the MOT Challenge file written."""
    boxes = read_init_boxes(boxes_file)
    multi = MultiTargetTracker({i: build_tracker(filter_name, seed=0) for i in boxes}, config=config)
    try:
        lines = [mot_line(frame.index + 1, target, state)
                 for frame, states in track_targets(multi, open_source(clip), boxes)
                 for target, state in states.items()]
    finally:
        multi.close()
    out.write_text("\n".join(lines) + "\n")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trackeval", required=True, help="the python of TrackEval's venv (make trackeval-env)")
    parser.add_argument("--out", required=True, help="folder for the clips and the result files")
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--filters", default="mil,kalman-cv")
    args = parser.parse_args()
    rows = []
    for seed in (int(s) for s in args.seeds.split(",")):
        paths = write_clip(Path(args.out) / f"seed{seed}", seed)
        for name in args.filters.split(","):
            for mode, config in MODES.items():
                result = run(paths["clip"], paths["boxes"], name, config, paths["clip"].parent / f"{name}-{mode}.txt")
                scores = json.loads(subprocess.run(
                    [args.trackeval, str(ROOT / "tests" / "trackeval_score.py"), str(paths["gt"]), str(result)],
                    check=True, capture_output=True, text=True).stdout)
                rows.append((name, mode, seed, scores))
    print("| filter | targets | seed | IDF1 | HOTA | MOTA | ID switches |\n|---|---|---|---|---|---|---|")
    for name in args.filters.split(","):
        for mode in MODES:
            mine = [r[3] for r in rows if r[0] == name and r[1] == mode]
            for (_, _, seed, s) in (r for r in rows if r[0] == name and r[1] == mode):
                print(f"| `{name}` | {mode} | {seed} | {s['IDF1']:.3f} | {s['HOTA']:.3f} | {s['MOTA']:.3f} | {s['IDSW']} |")
            print(f"| `{name}` | {mode} | mean | {np.mean([s['IDF1'] for s in mine]):.3f} | "
                  f"{np.mean([s['HOTA'] for s in mine]):.3f} | {np.mean([s['MOTA'] for s in mine]):.3f} | |")


if __name__ == "__main__":
    main()
