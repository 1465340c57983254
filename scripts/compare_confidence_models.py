"""Compare the calibrated confidence's models on frames their fit has not seen, copies of *tune* among them.

``scripts/fit_confidence.py`` fits each tracker's ``P(IoU > 0.5)`` as a
logistic function of its cues or as monotone gradient-boosted trees
(:data:`fit_confidence.TRACKERS`), on *tune* alone or on *tune* pooled with
copies of it that hold failures *tune* has few of.  This script prints what
that choice is made by: each tracker is run over *tune* and the copies (the
score-map trackers and ``cbt`` with their calibration switched off, ``mil`` as
packaged, as the fit's first pass runs them), and each of the four models

* the logistic fitted on *tune* alone,
* the logistic fitted on *tune* and the fitted copies,
* the trees fitted on *tune* alone,
* the trees fitted on *tune* and the fitted copies,

gives every frame of a sequence its probability from the fit on the other
sequences (a sequence is held out together with its copies).  The table holds
the ROC AUC of that probability for ``IoU > 0.5``, frames pooled, in each
folder, and over the ``--unseen`` folders: copies that no model is fitted on,
the nearest stand-in here for video the trackers have not seen.  The figure is
that of the probability a tracker would report, each fit's baseline included;
``fit_confidence.py``'s own held-out figure (:func:`fit_confidence.held_out_auc`)
leaves the baseline out to judge cue sets by their ranking alone::

    python scripts/compare_confidence_models.py ../shared/data/sequences OCC1 OCC3 EDGE \\
        --unseen OCC2 FAST2 ZOOM --trackers nh,pf --seeds 0 --cache /tmp/frames

The first folder is *tune*'s (``../shared/data/sequences``, whose *tune*
sequences are taken); the others are copies written by
``scripts/occlude_sequences.py``, ``edge_sequences.py``, ``stride_sequences.py``
and ``zoom_sequences.py`` with ``--sequences`` the *tune* split.  ``--cache DIR``
keeps each tracker's frames per folder
(a name of the folder, the seeds and the sequences) to compare again without
tracking.  A tracker without a calibration, a cue without a monotone direction
(:data:`fit_confidence.CUE_DIRECTION`), a folder without one of the sequences,
a cache that is not a folder or holds frames without the tracker's cues, or
frames that are all on one side of IoU 0.5 for some fit stop the script with
one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import fit_confidence as fit  # noqa: E402

from vidtrack.errors import UsageError, VidtrackError  # noqa: E402
from vidtrack.eval import confidence as conf_metrics  # noqa: E402
from vidtrack.eval.datasets import load_dataset  # noqa: E402

#: The models compared: (label, model kind, fitted on the copies too).
MODELS = (("logistic, tune", "logistic", False), ("logistic, tune + copies", "logistic", True),
          ("trees, tune", "trees", False), ("trees, tune + copies", "trees", True))


def compare(cues, rows: list[dict], ious: np.ndarray, n_folders: int, n_fitted: int,
            C: float = 1.0) -> dict[str, np.ndarray]:
    """The ROC AUC of each model of :data:`MODELS` on the frames of each folder and of the unseen folders.

    Parameters
    ----------
    cues
        The tracker's cues, rows of :data:`fit_confidence.TRACKERS`.
    rows, ious
        The frames' scalars (with ``sequence`` and ``copy``, the index of their folder) and their IoUs.
    n_folders, n_fitted
        How many folders there are, and how many of them are fitted on: ``0 .. n_fitted - 1`` (0 is *tune*).
    C
        Inverse L2 regularisation of the logistic fit.

    Returns
    -------
    dict
        ``{label: (n_folders + 1,) array}``: the ROC AUC in each folder, then over the unseen folders pooled
        (nan without any).

    Raises
    ------
    UsageError
        When a fit would see frames on one side of IoU 0.5 only.
    """
    labels = ious > 0.5
    sequences = np.array([r.get("sequence", "") for r in rows])
    copy = np.array([r.get("copy", 0) for r in rows])
    unseen = copy >= n_fitted
    table = {}
    for label, kind, with_copies in MODELS:
        fitted = (copy < n_fitted) if with_copies else (copy == 0)
        for name in np.unique(sequences):
            if len(np.unique(labels[fitted & (sequences != name)])) < 2:
                raise UsageError(f"the {label} fit without {name} sees frames on one side of IoU 0.5 only")
        p = fit.held_out_confidence(cues, kind, rows, ious, C, fitted=fitted)
        cells = [conf_metrics.roc_auc(p[copy == c], labels[copy == c]) for c in range(n_folders)]
        cells.append(conf_metrics.roc_auc(p[unseen], labels[unseen]) if unseen.any() else float("nan"))
        table[label] = np.array(cells)
    return table


def cache_path(cache: Path, name: str, dataset: str, sequences: list[str], seeds: list[int]) -> Path:
    """Where ``cache`` keeps ``name``'s frames on ``dataset``'s ``sequences`` at ``seeds``."""
    key = hashlib.sha1("\n".join([str(Path(dataset).resolve()), *sequences, *map(str, seeds)]).encode()).hexdigest()
    return cache / f"{name}-{Path(dataset).resolve().name}-{key[:10]}.json"


def folder_frames(name: str, dataset: str, loaded: list, sequences: list[str], seeds: list[int],
                  cache: Path | None) -> tuple[list[dict], np.ndarray]:
    """The tracker's rows and IoUs on one folder's ``sequences`` (from ``cache`` when it holds them).

    ``loaded``: the folder's ``sequences`` as :func:`~vidtrack.eval.datasets.load_dataset` gives them, tracked
    when the cache does not hold them.

    Raises
    ------
    UsageError
        When the cached frames lack one of the tracker's cues (frames of an older tracker).
    """
    path = None if cache is None else cache_path(cache, name, dataset, sequences, seeds)
    frames = None if path is None else fit.read_frames(path, {c[0] for c in fit.TRACKERS[name][0]})
    if frames is not None:
        return frames
    rows, ious = fit.collect(name, [loaded], seeds)
    if path is not None:
        fit.write_frames(path, rows, ious)
    return rows, ious


def markdown(name: str, table: dict[str, np.ndarray], folders: list[str], n_fitted: int) -> str:
    """``table`` as a Markdown table: a row per model, a column per folder and the unseen pooled."""
    heads = [Path(f).resolve().name + ("" if k < n_fitted else " (unseen)") for k, f in enumerate(folders)]
    heads[0] = "tune"
    lines = [f"`{name}`, held-out ROC AUC of P(IoU > 0.5)", "",
             "| model | " + " | ".join(heads + ["unseen, pooled"]) + " |", "|---" * (len(heads) + 2) + "|"]
    lines += [f"| {label} | " + " | ".join(f"{v:.3f}" for v in cells) + " |" for label, cells in table.items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", nargs="+", help="the shared sequences' folder, then the copies fitted on")
    parser.add_argument("--unseen", nargs="*", default=[], help="copies no model is fitted on")
    parser.add_argument("--trackers", default="nh,pf")
    parser.add_argument("--sequences", default=fit.TUNE)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--C", type=float, default=1.0, help="inverse L2 regularisation of the logistic fit")
    parser.add_argument("--cache", type=Path, help="keep (and reuse) each tracker's frames per folder here")
    args = parser.parse_args(argv)

    def stop(message: str) -> int:
        print(f"compare_confidence_models: {message}", file=sys.stderr)
        return 2

    names = [n for n in args.trackers.split(",") if n]
    if not names:
        return stop("--trackers: name at least one tracker")
    unknown = [n for n in names if n not in fit.TRACKERS]
    if unknown:
        return stop(f"no calibration for {unknown[0]!r}; valid: {', '.join(fit.TRACKERS)}")
    for name in names:
        missing = [c[0] for c in fit.TRACKERS[name][0] if c[0] not in fit.CUE_DIRECTION]
        if missing:
            return stop(f"{name}'s cue {missing[0]!r} has no monotone direction (fit_confidence.CUE_DIRECTION)")
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        return stop(f"--seeds: expected integers separated by commas, got {args.seeds!r}")
    if not args.C > 0:
        return stop(f"--C: expected a positive number, got {args.C:g}")
    if args.cache is not None and args.cache.exists() and not args.cache.is_dir():
        return stop(f"--cache: {args.cache} is not a folder")
    folders, sequences = args.dataset + args.unseen, args.sequences.split(",")
    try:
        loaded = [load_dataset(folder, sequences) for folder in folders]   # every folder checked before tracking
        for name in names:
            rows, ious = [], []
            for copy, folder in enumerate(folders):
                folder_rows, folder_ious = folder_frames(name, folder, loaded[copy], sequences, seeds, args.cache)
                rows += [{**r, "copy": copy} for r in folder_rows]
                ious.append(folder_ious)
            table = compare(fit.TRACKERS[name][0], rows, np.concatenate(ious), len(folders), len(args.dataset), args.C)
            print(markdown(name, table, folders, len(args.dataset)) + "\n", flush=True)
    except VidtrackError as exc:
        return stop(str(exc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
