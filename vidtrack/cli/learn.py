"""``vidtrack learn cbt VIDEO_OR_DATASET --out model.npz``: learn a Channel-Based Tracking motion model.

The model (:class:`~vidtrack.filters.cbt_model.CBTModel`) holds per-axis
displacement conditionals ``D[d_k, d_{k-1}, ...]`` on a cos² channel basis,
displacements measured in box sizes, estimated by the normalised covariance
of consecutive channel vectors (eq. 11 of "Learning Object Tracking in Image
Sequences", Felsberg & Larsson) with a random-walk prior for histories never
seen.  ``vidtrack VIDEO --filter cbt --model model.npz`` uses it instead of
learning online.

Sources:

* a dataset folder (OTB or MIL layout, or one sequence folder): the ground
  truth centres; MIL ground truth annotates every 5th frame, so centres are
  interpolated linearly between annotated rows at most ``--max-gap`` frames
  apart (longer gaps break the track);
* a video file or frame folder with ``--init-box``: the CBT tracker runs on it
  learning online from its own estimates, and its learned model is saved.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DatasetError, OutputError, UsageError
from .common import EXIT_OK, OneLineParser, check_box_in_frame, parse_init_box


def _interpolated_tracks(centres: np.ndarray, annotated: np.ndarray, max_gap: int) -> list[np.ndarray]:
    """Pieces of a per-frame centre track, linearly interpolated across gaps of at most ``max_gap`` frames."""
    rows = np.flatnonzero(annotated)
    pieces: list[np.ndarray] = []
    current: list[np.ndarray] = []
    for a, b in zip(rows[:-1], rows[1:]):
        if b - a > max_gap:
            if len(current) > 1:
                pieces.append(np.array(current))
            current = []
            continue
        if not current:
            current.append(centres[a])
        for t in range(1, b - a + 1):
            current.append(centres[a] + (centres[b] - centres[a]) * t / (b - a))
    if len(current) > 1:
        pieces.append(np.array(current))
    return pieces


def learn_from_dataset(path: str, *, order: int, names: list[str] | None, max_gap: int, prior_weight: float):
    from ..eval.datasets import load_dataset
    from ..channels import ChannelBasis, conditional_from_counts, displacement_counts, random_walk_displacement
    from ..filters.cbt_model import CBTModel
    from ..recipes.channels import CBTConfig

    defaults = CBTConfig()
    basis = ChannelBasis(-defaults.d_range, defaults.d_range, defaults.d_channels)
    counts = [np.zeros((basis.n,) * order) for _ in range(2)]
    used = frames = 0
    for seq in load_dataset(path, names):
        start, stop = seq.eval_range
        gt = np.asarray(seq.ground_truth[start:stop], float)
        annotated = seq.annotated[start:stop]
        centres = gt[:, :2] + gt[:, 2:] / 2.0
        scale = seq.ground_truth_box(start).scale
        for piece in _interpolated_tracks(centres, annotated, max_gap):
            for axis in range(2):
                counts[axis] += displacement_counts(piece[:, axis], basis, scale, order)
            frames += len(piece)
        used += 1
    if frames == 0:
        raise DatasetError(f"{path}: no run of annotated frames to learn from (try a larger --max-gap)")
    prior = random_walk_displacement(basis, defaults.prior_sigma, order)
    D = [conditional_from_counts(c, prior, prior_weight) for c in counts]
    return CBTModel(basis, D[0], D[1]), f"{used} sequence(s), {frames} frames of ground truth"


def learn_from_video(path: str, init_box: str, *, order: int, max_frames: int | None, prior_weight: float):
    from ..filters.cbt_model import CBTModel
    from ..recipes import build_tracker
    from ..run import run_tracker
    from ..sources import open_source

    box = parse_init_box(init_box)
    tracker = build_tracker("cbt", seed=0, order=order, relearn_every=1, prior_weight=prior_weight)
    result = run_tracker(tracker, open_source(path), box, max_frames=max_frames, validate_box=check_box_in_frame)
    filt = tracker.filter.inner  # CBTFilter inside its MeasuredSizeFilter
    if not np.any([c.sum() > 0 for c in filt.counts_]):
        raise UsageError(f"{path}: the tracker never tracked {order + 1} frames in a row; nothing learned")
    return (CBTModel(filt.d_basis_, filt.D_[0], filt.D_[1]),
            f"{result.frames} frames tracked online ({result.lost_frames} lost)")


def main(argv: Sequence[str]) -> int:
    """``vidtrack learn cbt SOURCE --out FILE.npz``: exit 0, or 2 on bad input."""
    parser = OneLineParser(prog="vidtrack learn", description="Learn a model for a filter that takes one.")
    parser.add_argument("kind", choices=["cbt"], help="what to learn (cbt: Channel-Based Tracking motion model)")
    parser.add_argument("source", metavar="VIDEO_OR_DATASET",
                        help="a dataset / sequence folder with ground truth, or a video (needs --init-box)")
    parser.add_argument("--out", required=True, metavar="FILE.npz", help="write the model here")
    parser.add_argument("--init-box", metavar="x,y,w,h", help="for a video: the object's box in the first frame")
    parser.add_argument("--order", type=int, default=2, help="Markov order of the model (1-3, default 2)")
    parser.add_argument("--sequences", metavar="S1,S2", help="dataset: only these sequences")
    parser.add_argument("--max-gap", type=int, default=10,
                        help="dataset: interpolate across at most this many frames between annotations (default 10)")
    parser.add_argument("--prior-weight", type=float, default=20.0,
                        help="pseudo-counts of the random-walk prior (default 20)")
    parser.add_argument("--max-frames", type=int, metavar="N", help="video: learn from at most N frames")
    args = parser.parse_args(list(argv))
    if not 1 <= args.order <= 3:
        raise UsageError("--order must be 1, 2 or 3")
    if args.max_gap < 1 or args.prior_weight < 0:
        raise UsageError("--max-gap must be at least 1 and --prior-weight non-negative")
    source = Path(args.source)
    if not source.exists():
        raise UsageError(f"no such video or dataset: {args.source}")
    from ..eval.datasets import find_sequences

    is_dataset = False
    if source.is_dir() and args.init_box is None:
        try:
            find_sequences(source)
            is_dataset = True
        except DatasetError:
            is_dataset = False
    if is_dataset:
        names = [n for n in args.sequences.split(",") if n] if args.sequences else None
        model, what = learn_from_dataset(str(source), order=args.order, names=names, max_gap=args.max_gap,
                                         prior_weight=args.prior_weight)
    else:
        if args.init_box is None:
            raise UsageError(f"{args.source} is not a dataset with ground truth; give --init-box to learn from a video")
        model, what = learn_from_video(str(source), args.init_box, order=args.order, max_frames=args.max_frames,
                                       prior_weight=args.prior_weight)
    try:
        with open(args.out, "wb") as handle:
            model.save(handle)
    except OSError as exc:
        raise OutputError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(f"vidtrack learn: cbt model of order {model.order} from {what}; wrote {args.out}", file=sys.stderr)
    return EXIT_OK
