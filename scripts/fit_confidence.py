"""Fit the calibrated confidence of ``mil``, ``nh``, ``pf``, ``bayes`` and ``cbt`` on the *tune* split (and copies of it).

Runs each tracker (the score-map trackers and ``cbt`` with their calibration
switched off, so the cues are those of the uncalibrated tracker, and their
second pass with the first pass's file; ``mil`` as
packaged, with its packaged calibration, which decides whether it measures the
appearance verification and, through ``lost``, where it searches) over the *tune* sequences of
``../shared/data/sequences`` at the given seeds, records every frame's cues
(the filter's ``scalars``, see :mod:`vidtrack.filters.calibration`) and
whether its box overlaps the ground truth by more than 0.5 (annotated frames,
the init frame left out), fits scikit-learn's ``LogisticRegression`` on the
standardised cues (``mil``, ``bayes``, ``cbt``) or its monotone
``HistGradientBoostingClassifier`` on the clipped cues (``nh``, ``pf``:
:data:`TRACKERS`, :data:`CUE_DIRECTION`, :data:`TREES`), and writes
``vidtrack/filters/calibration/<tracker>.json``.  ``nh`` and ``pf`` are fitted
on *tune* and three copies of it, in which bars of a random colour or of the
target's cross the target, and in which the target keeps to the frame's side::

    python scripts/fit_confidence.py ../shared/data/sequences --trackers mil --seeds 0,1 --passes 2
    python scripts/fit_confidence.py ../shared/data/sequences --trackers bayes,cbt --seeds 0 --passes 2
    python scripts/occlude_sequences.py ../shared/data/sequences OCC1 --sequences <tune>
    python scripts/occlude_sequences.py ../shared/data/sequences OCC3 --sequences <tune> --bar-colour target
    python scripts/edge_sequences.py ../shared/data/sequences EDGE --sequences <tune>
    python scripts/fit_confidence.py ../shared/data/sequences OCC1 OCC3 EDGE --trackers nh,pf --seeds 0 --passes 2

The packaged ``pf.json`` was fitted so on ``pf`` with the detector's own
defaults (learning from the average sample, ``cf.second_moment=false``,
``cf.support=1``, ``cf.solve_interval=1``, ``cf.admm_iterations=2``); refitted on its
every-sample preset, the trees read a vanished target as present (about 0.5)
and ``tests/test_confidence_cues.py`` fails, so check that test after a refit.

``--passes 2`` refits on the frames of the tracker run with the first fit
(written to the package, where the tracker reads it, so not with another ``--out``),
for a tracker whose status feeds back into its search: ``mil``, which searches
a frame it reports lost as an unmeasured one (``fusion.search_when_lost``), and
the score-map trackers and ``cbt``, whose detector re-detects while they report
lost and learns only while they report tracking, so their boxes follow their
lost rule.
``--select`` prints the cue selection described below, and ``--compare
a,b,...`` (repeatable) the same held-out figures for a set of cues of one's
own on the same frames, to weigh a set against the packaged one.  ``--cache DIR``
keeps the frames to refit without tracking again; ``--table`` prints false
lost and missed loss at every threshold (``mil``: of its lost rule, on the
held-out frames).  Several dataset folders pool their frames: *tune* and the
copies of it that ``scripts/occlude_sequences.py``, ``edge_sequences.py`` and
the like write, each sequence held out of a fold together with its copies::

    python scripts/fit_confidence.py ../shared/data/sequences EDGE --trackers mil --seeds 0,1 --select \
        --cache /tmp/frames --out /tmp/fit

``mil``'s ``lost`` status has a model of its own: a second logistic
regression, on cues of its own (:data:`PRESENCE_CUES`), of ``IoU > 0`` (the
box still overlaps the target), the question ``lost`` answers.  ``lost`` is that
presence probability below ``t`` for ``k`` scored frames in a row, and ``t``
(0.01 .. 0.99) and ``k`` (1 .. 5) are chosen on the *tune* frames held out
sequence by sequence (each sequence's presence from the fit on the others):
the pair minimising ``max(false_lost / 0.15, missed_loss / 0.02)``, i.e.
balancing the two failure rates of :mod:`vidtrack.eval.confidence` against
the targets they are held to, on frames the fit has not seen.  The
score-map trackers' ``lost`` is read from the confidence itself: ``P(IoU >
0.5)`` below ``t`` for ``k`` frames in a row, or a frame whose update was
skipped (its ``unmeasured`` scalar), with ``(t, k)`` chosen in the same way
on the held-out confidence (trees fitted on the other sequences, for a tree
model); ``cbt``'s likewise, a frame it does not measure (its uncalibrated
confidence below its ``lost_below``) being its skipped update.  With copies
pooled, the rule is chosen on the frames of the sequences themselves
(:func:`own_rows`): the copies teach the confidence what their failures look
like, but fail far more often than real video.  The script prints, per
tracker, the frames used, the coefficients (or the trees' count and
directions), the tune ROC AUC, expected calibration error, false lost and
missed loss of the fitted confidence (with the status as the filter reports
it), and the ROC AUC with each sequence held out (:func:`held_out_auc`, or
:func:`held_out_trees_auc`); ``--select`` also prints the forward selection of
cues on the logistic's held-out figure (:func:`select_cues`), the figure the packaged
cue sets were chosen by (the trees read the sets chosen so), and for ``mil``'s presence model the forward selection on the
held-out lost rule's cost (:func:`select_presence_cues`).  A frame in which
``mil`` measured nothing at all (its ``unmeasured`` scalar) is lost whatever
its presence, in the fit as in the filter.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vidtrack.errors import UsageError  # noqa: E402
from vidtrack.eval import confidence as conf_metrics  # noqa: E402
from vidtrack.eval import metrics  # noqa: E402
from vidtrack.eval.datasets import annotated_rows, load_dataset  # noqa: E402
from vidtrack.filters import cbt as cbt_filter  # noqa: E402
from vidtrack.filters import mil as mil_filter  # noqa: E402
from vidtrack.filters import score_trackers  # noqa: E402
from vidtrack.filters.calibration import Calibration, LostRule, MonotoneTrees, load_calibration  # noqa: E402
from vidtrack.recipes import build_tracker  # noqa: E402
from vidtrack.sources import ImageFolderSource  # noqa: E402

TUNE = "David,Sylvester,FaceOcc1,FaceOcc2,Girl,Tiger1,Tiger2,Man,Dancer2,Football1,Human9,Subway,MotorRolling"
OUT = Path(__file__).resolve().parents[1] / "vidtrack" / "filters" / "calibration"

#: The cues the packaged files use, chosen on tune by forward selection on :func:`held_out_auc` (fit on 12
#: sequences, score the 13th, pooled).  mil: the running verification, the inlier coverage, the presence
#: flag, the colour likelihood and the verification gap (0.937 on the packaged tracker's frames, where the
#: selection takes the inlier coverage, the verification gap and the running colour likelihood, 0.940;
#: ``--compare`` gives, on the same frames, the quality, PSR and inlier coverage 0.890, all of
#: :data:`~vidtrack.filters.mil.CUES` 0.915, the five with the border gap 0.930).  The
#: score-map trackers and cbt, likewise, on the uncalibrated tracker's frames (the score-map trackers' figures
#: with their verification map two box sizes wide).  nh: the running colour likelihood, the verification gap,
#: the map's quality and the box's gap to the frame's border (0.938; without the border gap 0.931; forward
#: selection takes the actions' spread instead of the quality and stops there, 0.936; the uncalibrated
#: confidence 0.811, all of :data:`~vidtrack.filters.score_trackers.CUES` 0.879); pf: the running colour
#: likelihood, the verification gap, the particles' spread and the border gap (0.967, the set forward
#: selection takes; without the border gap 0.951; the uncalibrated confidence 0.720, all 0.930); bayes: the
#: running verification and colour likelihood, the spread and the border gap (0.906; forward selection takes
#: this frame's verification, the border gap and the running colour likelihood, 0.920, whose file gives lower
#: boxes on tune and six copies of it, seed 0, and reads a box whose template no longer matches as present;
#: the uncalibrated confidence 0.747, all 0.831); cbt: the running colour likelihood, the running
#: verification and the mode mass (0.923; with the border gap 0.925, under the selection's step; the
#: uncalibrated confidence 0.654, all of :data:`~vidtrack.filters.cbt.CUES` 0.898).
MIL_CUES = tuple(c for c in mil_filter.CUES
                 if c[0] in ("verify_mean", "inlier_coverage", "present", "colour", "verify_gap"))
NH_CUES = tuple(c for c in score_trackers.CUES if c[0] in ("colour_mean", "verify_gap", "quality", "border_gap"))
PF_CUES = tuple(c for c in score_trackers.CUES if c[0] in ("colour_mean", "verify_gap", "spread", "border_gap"))
BAYES_CUES = tuple(c for c in score_trackers.CUES if c[0] in ("verify_mean", "colour_mean", "spread", "border_gap"))
CBT_CUES = tuple(c for c in cbt_filter.CUES if c[0] in ("colour_mean", "verify_mean", "mode_mass"))

#: tracker -> (its cues, the setting that switches its calibration off, the rule of its lost threshold, its model:
#: ``"logistic"`` or monotone ``"trees"``; docs/trackers.md gives the held-out figures each model was chosen by).
TRACKERS = {
    "mil": (MIL_CUES, {}, "balance", "logistic"),   # run as packaged: its lost rule steers its search (--passes 2)
    "nh": (NH_CUES, {"confidence": None}, "confidence", "trees"),   # its lost rule steers its detector (--passes 2)
    "pf": (PF_CUES, {"confidence": None}, "confidence", "trees"),
    "bayes": (BAYES_CUES, {"confidence": None}, "confidence", "logistic"),
    "cbt": (CBT_CUES, {"confidence": None}, "confidence", "logistic"),
}
#: The direction in which ``P(IoU > 0.5)`` moves with each cue a tree model reads (its monotone constraints);
#: every tracker's cues have one, as ``scripts/compare_confidence_models.py`` fits trees for each.
CUE_DIRECTION = {
    "quality": 1,       # the detector's peak stands out of its map: it sees a target
    "verify_gap": -1,   # the first frame's target matches better elsewhere in the region: the box is beside it
    "verify_mean": 1,   # the box looks like the first frame's target
    "colour_mean": 1,   # the box holds the first frame's target colours
    "border_gap": 1,    # a box that has lost its target comes to rest against the frame's edge
    "spread": -1,       # the posterior is spread over several places
    "inlier_coverage": 1,   # mil: the superpixels its classifier calls target cover the box
    "present": 1,       # mil: its fusion found the target in this frame
    "colour": 1,        # the box holds the first frame's target colours, in this frame alone
    "mode_mass": 1,     # cbt: the channel representation's mode holds most of the mass
}
#: The gradient boosting of the tree models: 100 trees of depth 3, each leaf at least 100 frames
TREES = {"max_iter": 100, "learning_rate": 0.05, "max_depth": 3, "min_samples_leaf": 100}
#: The cues of the presence model ``P(IoU > 0)`` that decides ``lost`` (rule ``"balance"``), judged on tune by
#: the cost of the lost rule on held-out frames, which :func:`select_presence_cues` (``--select``) lowers by
#: forward selection.  mil: the presence flag, the box's gap to the frame's border, the inlier coverage and the
#: verification gap, the set the selection takes: held-out cost 0.57 on the packaged tracker's frames (seeds 0
#: and 1; false lost 0.085, missed loss 0.011 below 0.87 for 5 frames).  Without ``border_gap`` 2.07; the colour
#: likelihood, the correlation filter's PSR, the inlier coverage and the presence flag 1.99.  A box that has lost
#: its target comes to rest against the frame's edge, and one whose inliers also cover little of it is lost
#: there.  The presence cues steer the search of a frame reported lost, so they change the frames this cost is
#: measured on: another set is judged by the tracking it steers (docs/trackers.md).
PRESENCE_CUES = {"mil": tuple(c for c in mil_filter.CUES
                              if c[0] in ("present", "border_gap", "inlier_coverage", "verify_gap"))}
#: The runs of low presence ``mil``'s lost rule may require (``lost_after``).
LOST_AFTER = (1, 2, 3, 4, 5)
#: The cues ``--select`` chooses from.
SELECT_FROM = {"mil": mil_filter.CUES, "nh": score_trackers.CUES, "pf": score_trackers.CUES,
               "bayes": score_trackers.CUES, "cbt": cbt_filter.CUES}
THRESHOLD_RULES = {
    "balance": "presence P(IoU > 0) below lost_below for lost_after frames in a row; the pair is the argmin of "
               "max(false_lost / 0.15, missed_loss / 0.02) on the tune frames, each sequence held out of the fit",
    "confidence": "P(IoU > 0.5) below lost_below for lost_after frames in a row, or the update skipped; the pair is "
                  "the argmin of max(false_lost / 0.15, missed_loss / 0.02) on the tune frames, each sequence held out "
                  "of the fit",
}


def collect(name: str, folders, seeds, calibrated: bool = False) -> tuple[list[dict], np.ndarray]:
    """Per scored frame: the filter's scalars, and its IoU with the ground truth.

    ``folders``: one list of sequences per dataset folder; each row records its folder's index as
    ``copy`` (a sequence and its copies keep one ``sequence`` name, so a fold holds them out together).
    ``calibrated``: run the tracker with its packaged calibration (else switched off).
    """
    off = TRACKERS[name][1]
    off = {} if calibrated else off
    rows, ious = [], []
    for seed in seeds:
        for copy, seq in ((copy, seq) for copy, sequences in enumerate(folders) for seq in sequences):
            start, stop = seq.eval_range
            source = ImageFolderSource(seq.path, files=list(seq.files[start:stop]))
            tracker = build_tracker(name, seed=seed, settings=off)
            init = seq.to_pixels(seq.ground_truth_box(start))
            scalars, boxes = [], []
            for count, frame in enumerate(source):
                state = tracker.initialize(frame, init) if count == 0 else tracker.step(frame)
                boxes.append(seq.from_pixels(state.box).as_array())
                scalars.append(dict(state.scalars))
            iou = metrics.iou(np.array(boxes), seq.ground_truth[start:stop])
            valid = annotated_rows(seq.ground_truth[start:stop])
            for k in range(1, len(boxes)):
                if valid[k]:
                    rows.append({**scalars[k], "sequence": seq.name, "seed": seed, "copy": copy})
                    ious.append(iou[k])
            print(f"  {name} seed {seed} {seq.path}: {len(boxes)} frames", file=sys.stderr, flush=True)
    return rows, np.array(ious)


def run_starts(rows: list[dict]) -> np.ndarray:
    """``(N,)`` bool: the row opens a tracking run (its sequence, seed or folder differs from the previous row's)."""
    keys = [(r.get("sequence", ""), r.get("seed", 0), r.get("copy", 0)) for r in rows]
    return np.array([k == 0 or keys[k] != keys[k - 1] for k in range(len(keys))], bool)


def own_rows(rows: list[dict]) -> np.ndarray:
    """``(N,)`` bool: the row is a frame of the sequences themselves (the first dataset folder), not of a copy.

    The copies' frames teach the confidence what their failures look like; the lost rule is chosen on these
    alone, so that it trades false lost against missed loss at the rate the sequences themselves fail.
    """
    return np.array([r.get("copy", 0) == 0 for r in rows], bool)


def chosen_lost_rule(held: np.ndarray, rows: list[dict], ious: np.ndarray) -> tuple[float, int, float, float]:
    """:func:`choose_lost_rule` on the held-out ``held`` of the sequences' own rows (:func:`own_rows`)."""
    own = own_rows(rows)
    mine = [r for r, keep in zip(rows, own) if keep]
    return choose_lost_rule(held[own], ious[own], run_starts(mine), unmeasured_rows(mine))


def unmeasured_rows(rows: list[dict]) -> np.ndarray:
    """``(N,)`` bool: the row's ``unmeasured`` scalar is set, so it is lost at once whatever its probability.

    ``mil``: nothing at all was measured (the search left the frame); the score-map trackers: the update was skipped.
    """
    return np.array([r.get("unmeasured", 0.0) > 0 for r in rows], bool)


def low_runs(p: np.ndarray, starts: np.ndarray, t: float) -> np.ndarray:
    """``(N,)`` int: how many rows in a row, up to this one and within its run, have ``p < t``."""
    out = np.zeros(len(p), int)
    count = 0
    for k, (value, start) in enumerate(zip(p, starts)):
        count = (0 if start else count) + 1 if value < t else 0
        out[k] = count
    return out


def held_out_presence(X: np.ndarray, rows: list[dict], ious: np.ndarray, C: float,
                      above: float = 0.0, directions=None, fitted: np.ndarray | None = None) -> np.ndarray:
    """``P(IoU > above)`` of each row from the fit on the other sequences' rows.

    The logistic fit (on their own standardisation), or with ``directions`` (one +1 or -1 per column of
    ``X``) the monotone trees (:func:`trees_model`).  ``fitted``: ``(N,)`` bool, the rows a fit may learn from
    (default all); every row is scored.
    """
    from sklearn.linear_model import LogisticRegression

    y = ious > above
    sequences = np.array([r.get("sequence", "") for r in rows])
    fitted = np.ones(len(rows), bool) if fitted is None else fitted
    p = np.zeros(len(rows))
    for name in np.unique(sequences):
        test = sequences == name
        train = fitted & ~test
        if directions is not None:
            model = trees_model(directions, X[train], y[train])
            p[test] = model.predict_proba(X[test])[:, list(model.classes_).index(True)]
            continue
        mean, scale = X[train].mean(axis=0), X[train].std(axis=0)
        scale = np.where(scale > 1e-9, scale, 1.0)
        model = LogisticRegression(C=C, max_iter=1000).fit((X[train] - mean) / scale, y[train])
        p[test] = model.predict_proba((X[test] - mean) / scale)[:, 1]
    return p


def lost_rule_cost(false_lost: float, missed_loss: float) -> float:
    """``max(false_lost / 0.15, missed_loss / 0.02)``: the two failure rates against their targets (at most 1: both met)."""
    return max(0.0 if np.isnan(false_lost) else false_lost / 0.15, 0.0 if np.isnan(missed_loss) else missed_loss / 0.02)


def choose_lost_rule(p: np.ndarray, ious: np.ndarray, starts: np.ndarray,
                     forced: np.ndarray | None = None) -> tuple[float, int, float, float]:
    """``(t, k, false lost, missed loss)``: lost = ``p < t`` for ``k`` rows in a row, balancing the two rates.

    ``forced``: rows that are lost whatever their ``p`` (:func:`unmeasured_rows`).
    """
    forced = np.zeros(len(p), bool) if forced is None else forced
    best = (np.inf, 0.5, 1, np.nan, np.nan)
    for t in np.round(np.arange(0.01, 1.0, 0.01), 2):
        runs = low_runs(p, starts, t)
        for k in LOST_AFTER:
            status = np.where((runs >= k) | forced, conf_metrics.LOST, conf_metrics.TRACKING)
            fl, ml = conf_metrics.false_lost(ious, status), conf_metrics.missed_loss(ious, status)
            cost = lost_rule_cost(fl, ml)
            if cost < best[0]:
                best = (cost, float(t), k, fl, ml)
    return best[1:]


def threshold_table(p: np.ndarray, ious: np.ndarray, starts: np.ndarray, k: int,
                    forced: np.ndarray | None = None) -> list[tuple[float, float, float, float]]:
    """``(t, false lost, missed loss, lost rate)`` of each threshold ``t = 0.05 .. 0.95``.

    Lost = ``p < t`` for ``k`` rows in a row, or ``forced`` (:func:`unmeasured_rows`).
    """
    forced = np.zeros(len(p), bool) if forced is None else forced
    table = []
    for t in np.round(np.arange(0.05, 0.96, 0.05), 2):
        lost = (low_runs(p, starts, t) >= k) | forced
        status = np.where(lost, conf_metrics.LOST, conf_metrics.TRACKING)
        table.append((float(t), conf_metrics.false_lost(ious, status), conf_metrics.missed_loss(ious, status),
                      float(np.mean(lost))))
    return table


def lost_status(cal: Calibration, rows: list[dict]) -> np.ndarray:
    """The status :class:`~vidtrack.filters.calibration.LostRule` gives ``rows``, run by run."""
    rule, status = LostRule(cal), []
    for row, start in zip(rows, run_starts(rows)):
        if start:
            rule.reset()
        status.append(conf_metrics.LOST if rule.lost(row) else conf_metrics.TRACKING)
    return np.array(status)


def fit(name: str, rows: list[dict], ious: np.ndarray, C: float,
        held_presence: np.ndarray | None = None) -> Calibration:
    """``name``'s model (:data:`TRACKERS`: logistic or monotone trees) of ``IoU > 0.5`` on its clipped cues.

    ``held_presence``: as in :func:`fit_cues`.
    """
    cues, _, rule, model = TRACKERS[name]
    return fit_cues(cues, rule, rows, ious, C, PRESENCE_CUES.get(name), held_presence, model)


def cue_matrix(cues, rows: list[dict]) -> np.ndarray:
    """``(N, K)`` clipped cue values of ``rows`` (missing or non-finite cues take their fill value)."""
    fill, lower, upper = (np.array([c[i] for c in cues], float) for i in (1, 2, 3))
    X = np.array([[float(r.get(c[0], np.nan)) for c in cues] for r in rows], float).reshape(len(rows), len(cues))
    return np.clip(np.where(np.isfinite(X), X, fill), lower, upper)


def held_out_auc(cues, rows: list[dict], ious: np.ndarray, C: float = 1.0, X: np.ndarray | None = None) -> float:
    """Leave-one-sequence-out ROC AUC of the logistic fit on ``cues`` (rows carry their ``sequence``).

    Each sequence's frames are scored by the fit on the other sequences: the held-out score is the
    cues, standardised over all rows, projected on the fit's direction (its weights in those units,
    scaled to length 1); these scores are pooled over the sequences and their ROC AUC for ``IoU > 0.5``
    returned.  The fit's constant and length are left out because with one sequence held out they
    mostly encode the other sequences' rate of good frames (lower when the held-out sequence is a good
    one): pooled, they would rank each sequence's frames by its own label rate, against them.  With one
    cue the score is the cue itself (signed), so a single cue's figure is its own ROC AUC when the folds
    agree on its sign.  ``X``: the rows' :func:`cue_matrix`, if already built.
    """
    from sklearn.linear_model import LogisticRegression

    X = cue_matrix(cues, rows) if X is None else X
    y = ious > 0.5
    sequences = np.array([r.get("sequence", "") for r in rows])
    z = np.zeros(len(rows))
    g_mean, g_scale = X.mean(axis=0), X.std(axis=0)
    g_scale = np.where(g_scale > 1e-9, g_scale, 1.0)
    for name in np.unique(sequences):
        test = sequences == name
        if len(np.unique(y[~test])) < 2:
            return float("nan")
        mean, scale = X[~test].mean(axis=0), X[~test].std(axis=0)
        scale = np.where(scale > 1e-9, scale, 1.0)
        model = LogisticRegression(C=C, max_iter=1000).fit((X[~test] - mean) / scale, y[~test])
        direction = model.coef_[0] / scale * g_scale
        z[test] = ((X[test] - g_mean) / g_scale) @ (direction / max(float(np.linalg.norm(direction)), 1e-12))
    return conf_metrics.roc_auc(z, y)


def held_out_confidence(cues, model: str, rows: list[dict], ious: np.ndarray, C: float,
                        fitted: np.ndarray | None = None) -> np.ndarray:
    """``P(IoU > 0.5)`` of each row from ``model`` (``"logistic"`` or ``"trees"``) fitted on the other sequences.

    ``fitted``: as in :func:`held_out_presence`.
    """
    directions = cue_directions(cues) if model == "trees" else None
    return held_out_presence(cue_matrix(cues, rows), rows, ious, C, above=0.5, directions=directions, fitted=fitted)


def held_out_trees_auc(cues, rows: list[dict], ious: np.ndarray) -> float:
    """Leave-one-sequence-out ROC AUC of the monotone trees on ``cues``, like :func:`held_out_auc`.

    Each sequence's frames are scored by the trees fitted on the other sequences, without the fit's
    baseline (the other sequences' rate of good frames, as the logistic's constant in :func:`held_out_auc`).
    """
    X, y = cue_matrix(cues, rows), ious > 0.5
    directions = cue_directions(cues)
    sequences = np.array([r.get("sequence", "") for r in rows])
    z = np.zeros(len(rows))
    for name in np.unique(sequences):
        test = sequences == name
        if len(np.unique(y[~test])) < 2:
            return float("nan")
        model = trees_model(directions, X[~test], y[~test])
        z[test] = model.decision_function(X[test]) - float(np.ravel(model._baseline_prediction)[0])
    return conf_metrics.roc_auc(z, y)


def select_cues(table, rows: list[dict], ious: np.ndarray, C: float = 1.0, min_gain: float = 0.003):
    """Forward selection on :func:`held_out_auc`: from no cue, add the cue of ``table`` that raises it most.

    Stops when no cue raises it by ``min_gain``; returns the chosen cues (rows of ``table``) and a line
    per step.
    """
    table = tuple(table)
    X = cue_matrix(table, rows)
    chosen, best, lines = [], 0.5, []
    while len(chosen) < len(table):
        scored = [(held_out_auc(tuple(chosen) + (c,), rows, ious, C,
                                X[:, [table.index(k) for k in (*chosen, c)]]), c)
                  for c in table if c not in chosen]
        auc, cue = max(scored, key=lambda t: t[0])
        if not auc >= best + min_gain:
            break
        chosen.append(cue)
        best = auc
        lines.append(f"  + {cue[0]}: held-out ROC AUC {auc:.3f}")
    return tuple(chosen), lines


def select_presence_cues(table, rows: list[dict], ious: np.ndarray, C: float = 1.0, min_gain: float = 0.02):
    """Forward selection of the presence model's cues on the held-out lost rule's :func:`lost_rule_cost`.

    From no cue, add the cue of ``table`` whose held-out presence (:func:`held_out_presence`), under its
    best rule (:func:`chosen_lost_rule`), lowers the cost most; stop when no cue lowers it by
    ``min_gain``.  Returns the chosen cues (rows of ``table``) and a line per step.
    """
    table = tuple(table)
    X = cue_matrix(table, rows)
    chosen, best, lines = [], np.inf, []
    while len(chosen) < len(table):
        scored = []
        for cue in table:
            if cue in chosen:
                continue
            held = held_out_presence(X[:, [table.index(c) for c in (*chosen, cue)]], rows, ious, C)
            t, k, fl, ml = chosen_lost_rule(held, rows, ious)
            scored.append((lost_rule_cost(fl, ml), cue, t, k, fl, ml))
        cost, cue, t, k, fl, ml = min(scored, key=lambda s: s[0])
        if not cost <= best - min_gain:
            break
        chosen.append(cue)
        best = cost
        lines.append(f"  + {cue[0]}: held-out cost {cost:.2f} (below {t:.2f} for {k} frame(s): false lost {fl:.3f}, "
                     f"missed loss {ml:.3f})")
    return tuple(chosen), lines


def compare_cue_sets(table, sets, rows: list[dict], ious: np.ndarray, C: float = 1.0,
                     presence: bool = False) -> list[str]:
    """The held-out figures of each set of cue names in ``sets`` on the same frames, a line per set.

    Each line holds the leave-one-sequence-out ROC AUC of a confidence on those cues (:func:`held_out_auc`)
    and, with ``presence``, the cost of the lost rule with them as the presence cues (the rule chosen on
    the held-out presence as the fit chooses it: :func:`held_out_presence`, :func:`chosen_lost_rule`).
    A cue that no frame carries (one the tracker does not compute, or frames cached by an older tracker)
    is said so at the end of its line: its fill value stands in for it.
    """
    table = tuple(table)
    X = cue_matrix(table, rows)
    lines = []
    for names in sets:
        cues = tuple(next(c for c in table if c[0] == n) for n in names)
        columns = [table.index(c) for c in cues]
        line = f"  {', '.join(names)}: held-out ROC AUC {held_out_auc(cues, rows, ious, C, X[:, columns]):.3f}"
        if presence:
            held = held_out_presence(X[:, columns], rows, ious, C)
            t, k, fl, ml = chosen_lost_rule(held, rows, ious)
            line += (f"; as the presence cues, held-out cost {lost_rule_cost(fl, ml):.2f} (below {t:.2f} for {k} "
                     f"frame(s): false lost {fl:.3f}, missed loss {ml:.3f})")
        absent = [n for n in names if not any(n in r for r in rows)]
        if absent:
            line += f" [no frame carries {', '.join(absent)}: its fill value stands in]"
        lines.append(line)
    return lines


def logistic_fit(cues, rows: list[dict], labels: np.ndarray, C: float, lost_below: float = 0.5) -> Calibration:
    """Logistic regression of the bool ``labels`` on the standardised, clipped ``cues`` of ``rows``."""
    from sklearn.linear_model import LogisticRegression

    names = tuple(c[0] for c in cues)
    fill, lower, upper = (np.array([c[i] for c in cues], float) for i in (1, 2, 3))
    X = cue_matrix(cues, rows)
    mean, scale = X.mean(axis=0), X.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)
    model = LogisticRegression(C=C, max_iter=1000).fit((X - mean) / scale, labels)
    return Calibration(cues=names, mean=mean, scale=scale, coef=model.coef_[0], intercept=float(model.intercept_[0]),
                       fill=fill, lower=lower, upper=upper, lost_below=lost_below)


def cue_directions(cues) -> list[int]:
    """The monotone direction of each of ``cues`` (:data:`CUE_DIRECTION`)."""
    unknown = [c[0] for c in cues if c[0] not in CUE_DIRECTION]
    if unknown:
        raise SystemExit(f"fit_confidence: no monotone direction for the cue {unknown[0]!r} (CUE_DIRECTION)")
    return [CUE_DIRECTION[c[0]] for c in cues]


def trees_model(directions, X: np.ndarray, labels: np.ndarray):
    """scikit-learn's gradient-boosted trees (:data:`TREES`) of ``labels`` on ``X``, monotone in ``directions``."""
    from sklearn.ensemble import HistGradientBoostingClassifier

    model = HistGradientBoostingClassifier(**TREES, monotonic_cst=list(directions), early_stopping=False,
                                           random_state=0)
    return model.fit(X, labels)


def exported_trees(model) -> MonotoneTrees:
    """The trees of a fitted ``HistGradientBoostingClassifier`` as a :class:`MonotoneTrees` (same log-odds)."""
    feature, threshold, left, right, value, roots = [], [], [], [], [], []
    for (predictor,) in model._predictors:
        base = len(feature)
        roots.append(base)
        for node in predictor.nodes:
            leaf = bool(node["is_leaf"])
            feature.append(-1 if leaf else int(node["feature_idx"]))
            threshold.append(0.0 if leaf else float(node["num_threshold"]))
            left.append(-1 if leaf else base + int(node["left"]))
            right.append(-1 if leaf else base + int(node["right"]))
            value.append(float(node["value"]) if leaf else 0.0)
    return MonotoneTrees(baseline=float(np.ravel(model._baseline_prediction)[0]), feature=np.array(feature),
                         threshold=np.array(threshold), left=np.array(left), right=np.array(right),
                         value=np.array(value), roots=np.array(roots))


def trees_fit(cues, rows: list[dict], labels: np.ndarray, lost_below: float = 0.5) -> Calibration:
    """Monotone gradient-boosted trees of the bool ``labels`` on the clipped ``cues`` of ``rows``."""
    fill, lower, upper = (np.array([c[i] for c in cues], float) for i in (1, 2, 3))
    model = trees_model(cue_directions(cues), cue_matrix(cues, rows), labels)
    return Calibration(cues=tuple(c[0] for c in cues), fill=fill, lower=lower, upper=upper, lost_below=lost_below,
                       trees=exported_trees(model))


def fit_cues(cues, rule: str, rows: list[dict], ious: np.ndarray, C: float, presence_cues=None,
             held_presence: np.ndarray | None = None, model: str = "logistic") -> Calibration:
    """The ``model`` of ``IoU > 0.5`` on the clipped ``cues`` (logistic: standardised); ``rule`` sets the threshold.

    ``"balance"``: the status from a presence model, ``IoU > 0`` on ``presence_cues``, lost below a
    threshold for some frames in a row (:func:`choose_lost_rule` on held-out frames: ``held_presence``,
    the rows' :func:`held_out_presence` on those cues, when already computed).  ``"confidence"``: no
    presence model; lost when ``P(IoU > 0.5)`` itself is below a threshold for some frames in a row, chosen
    likewise on its held-out values (``held_presence``: the rows' ``P(IoU > 0.5)`` from the fits on the
    other sequences).  ``model``: ``"logistic"``, or ``"trees"`` (:func:`trees_fit`; rule ``"confidence"`` only).
    """
    trees = model == "trees"
    cal = trees_fit(cues, rows, ious > 0.5) if trees else logistic_fit(cues, rows, ious > 0.5, C)
    if rule == "confidence":
        held = held_presence if held_presence is not None else held_out_confidence(cues, model, rows, ious, C)
        threshold, lost_after, _, _ = chosen_lost_rule(held, rows, ious)
        return replace(cal, lost_below=threshold, lost_after=lost_after)
    if rule != "balance" or trees:
        raise ValueError(f"no threshold rule {rule!r} for a {model} model")
    if held_presence is None:
        held_presence = held_out_presence(cue_matrix(presence_cues, rows), rows, ious, C)
    threshold, lost_after, _, _ = chosen_lost_rule(held_presence, rows, ious)
    return replace(cal, lost_below=threshold, lost_after=lost_after,
                   presence=logistic_fit(presence_cues, rows, ious > 0, C, threshold))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", nargs="+",
                        help="dataset folder(s): the sequences are read from each, their frames pooled, and each "
                             "sequence is held out with its copies")
    parser.add_argument("--trackers", default="mil,nh,pf,bayes")
    parser.add_argument("--sequences", default=TUNE)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--C", type=float, default=1.0, help="inverse L2 regularisation of the logistic fit")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--cache", type=Path, help="keep (and reuse) each tracker's frames in this folder")
    parser.add_argument("--table", action="store_true", help="print false lost and missed loss per threshold")
    parser.add_argument("--select", action="store_true",
                        help="also print the forward selection of the confidence's cues by held-out ROC AUC, and "
                             "of mil's presence cues by the held-out lost rule's cost")
    parser.add_argument("--compare", action="append", default=[], metavar="CUE,CUE,...",
                        help="also print the held-out figures of this set of cues on the same frames (repeatable; "
                             "each set must be cues of every tracker named)")
    parser.add_argument("--passes", type=int, default=1,
                        help="2: refit on the frames of the tracker run with the first pass's calibration "
                             "(its status feeds back into its search); writes the packaged files")
    args = parser.parse_args(argv)
    if args.passes > 1 and args.out.resolve() != OUT.resolve():
        parser.error("--passes 2 runs the tracker with the first pass's file, which it reads from the package: "
                     "leave --out at the package's folder")
    names = args.trackers.split(",")
    unknown = [n for n in names if n not in TRACKERS]
    if unknown:
        parser.error(f"no calibration for {unknown[0]!r}; valid: {', '.join(TRACKERS)}")
    args.compare = [tuple(c.strip() for c in spec.split(",")) for spec in args.compare]
    for spec in args.compare:
        twice = sorted({c for c in spec if spec.count(c) > 1})
        if twice:
            print(f"fit_confidence: --compare {','.join(spec)}: {twice[0]!r} is named twice", file=sys.stderr)
            return 2
        for name in names:
            known = {c[0] for c in SELECT_FROM[name]}
            bad = [c for c in spec if c not in known]
            if bad:
                print(f"fit_confidence: --compare {','.join(spec)}: {bad[0]!r} is not a cue of {name} "
                      f"({', '.join(sorted(known))})", file=sys.stderr)
                return 2
    folders = [load_dataset(dataset, args.sequences.split(",")) for dataset in args.dataset]
    seeds = [int(s) for s in args.seeds.split(",")]
    for name in names:
        for run in range(args.passes):
            cal, rows, ious = fit_pass(name, folders, seeds, args, calibrated=run > 0)
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / f"{name}.json").write_text(calibration_json(document(name, cal, rows, ious, args, seeds, run + 1)),
                                                   encoding="utf-8")
            load_calibration.cache_clear()
    return 0


def copy_names(args) -> list[str]:
    """The names of the dataset folders after the first: the copies whose frames are pooled with it."""
    return [Path(d).resolve().name for d in args.dataset[1:]]


def read_frames(path: Path, wanted) -> tuple[list[dict], np.ndarray] | None:
    """The rows and IoUs a frame cache keeps at ``path`` (:func:`write_frames`), None when there is none.

    Raises
    ------
    UsageError
        When no frame holds one of the ``wanted`` cues: frames of an older tracker, which a fit would read
        as the cue's fill value.
    """
    if not path.is_file():
        return None
    saved = json.loads(path.read_text(encoding="utf-8"))
    rows, ious = saved["rows"], np.array(saved["ious"])
    missing = sorted(c for c in wanted if not any(c in r for r in rows))
    if missing:
        raise UsageError(f"{path} has no frame with {', '.join(missing)}; delete it to collect again")
    return rows, ious


def write_frames(path: Path, rows: list[dict], ious: np.ndarray) -> None:
    """Keep a tracker's rows and IoUs at ``path`` for :func:`read_frames`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"rows": rows, "ious": ious.tolist()}), encoding="utf-8")


def fit_pass(name, folders, seeds, args, *, calibrated: bool):
    """One pass: collect the frames (or read them from the cache), fit, print the tune figures."""
    cache = None
    if args.cache is not None:
        copies = "".join(f"-{copy}" for copy in copy_names(args))
        cache = args.cache / f"{name}-{'-'.join(map(str, seeds))}{copies}{'-calibrated' if calibrated else ''}.json"
    wanted = {c[0] for c in TRACKERS[name][0] + PRESENCE_CUES.get(name, ())}
    wanted.add("unmeasured")   # the lost rule also reads whether anything was measured
    try:
        frames = None if cache is None else read_frames(cache, wanted)
    except UsageError as exc:
        raise SystemExit(f"fit_confidence: {exc}") from None
    if frames is not None:
        rows, ious = frames
    else:
        rows, ious = collect(name, folders, seeds, calibrated)
        if cache is not None:
            write_frames(cache, rows, ious)
    held = None   # each sequence's presence (or confidence) from the fit on the others: chooses the lost rule
    if TRACKERS[name][2] == "balance":
        held = held_out_presence(cue_matrix(PRESENCE_CUES[name], rows), rows, ious, args.C)
    elif TRACKERS[name][2] == "confidence":
        held = held_out_confidence(TRACKERS[name][0], TRACKERS[name][3], rows, ious, args.C)
    cal = fit(name, rows, ious, args.C, held)
    own = own_rows(rows)   # the figures below are the sequences' own (the copies only join the fit)
    p = np.array([cal.probability(r) for r in rows])
    status = lost_status(cal, rows)
    m = conf_metrics.confidence_metrics(ious[own], p[own], status[own])
    if cal.trees is not None:
        weights = (f"{len(cal.trees.roots)} trees monotone in "
                   + ", ".join(f"{c} {'+' if CUE_DIRECTION[c] > 0 else '-'}" for c in cal.cues))
    else:
        weights = ", ".join(f"{c} {w:+.2f}" for c, w in zip(cal.cues, cal.coef))
    lost = f"lost below {cal.lost_below:.3f}" + (f" for {cal.lost_after} frame(s)" if cal.lost_after > 1 else "")
    if cal.presence is not None:
        presence = ", ".join(f"{c} {w:+.2f}" for c, w in zip(cal.presence.cues, cal.presence.coef))
        lost = (f"presence: {presence}; intercept {cal.presence.intercept:+.2f}; lost below {cal.lost_below:.3f} "
                f"for {cal.lost_after} frame(s)")
    print(f"{name}{' (pass on the calibrated tracker)' if calibrated else ''}: {len(rows)} frames; {weights}; "
          + ("" if cal.trees is not None else f"intercept {cal.intercept:+.2f}; ") + lost)
    print(f"  tune: ROC AUC {m['confidence_auc']:.3f}, ECE {m['ece']:.3f}, false lost {m['false_lost']:.3f}, "
          f"missed loss {m['missed_loss']:.3f}, lost rate {m['lost_rate']:.3f}", flush=True)
    if all("sequence" in r for r in rows):
        auc = (held_out_trees_auc(TRACKERS[name][0], rows, ious) if cal.trees is not None
               else held_out_auc(TRACKERS[name][0], rows, ious, args.C))
        print(f"  tune{'' if own.all() else ' and its copies'}, each sequence held out: ROC AUC {auc:.3f}")
    if args.select and name in SELECT_FROM:
        chosen, lines = select_cues(SELECT_FROM[name], rows, ious, args.C)
        print("\n".join(lines) + f"\n  selected: {', '.join(c[0] for c in chosen)}", flush=True)
        if name in PRESENCE_CUES:
            chosen, lines = select_presence_cues(SELECT_FROM[name], rows, ious, args.C)
            print("  presence, IoU > 0, on the held-out lost rule:\n" + "\n".join(lines)
                  + f"\n  selected: {', '.join(c[0] for c in chosen)}", flush=True)
    if args.compare:
        print("  cue sets compared on these frames:\n"
              + "\n".join(compare_cue_sets(SELECT_FROM[name], args.compare, rows, ious, args.C,
                                           presence=name in PRESENCE_CUES)), flush=True)
    if held is not None:   # the lost rule on frames the fit has not seen
        mine = [r for r, keep in zip(rows, own) if keep]
        held, ious_own = held[own], ious[own]
        starts, forced = run_starts(mine), unmeasured_rows(mine)
        status = np.where((low_runs(held, starts, cal.lost_below) >= cal.lost_after) | forced, conf_metrics.LOST,
                          conf_metrics.TRACKING)
        print(f"  tune, each sequence held out: false lost {conf_metrics.false_lost(ious_own, status):.3f}, "
              f"missed loss {conf_metrics.missed_loss(ious_own, status):.3f}", flush=True)
        if TRACKERS[name][2] == "balance":
            confidence = held_out_presence(cue_matrix(TRACKERS[name][0], rows), rows, ious, args.C, above=0.5)
            t, k, fl, ml = choose_lost_rule(confidence[own], ious_own, starts, forced)
            print(f"  (the same rule on the confidence P(IoU > 0.5) instead, best below {t:.2f} for {k} frame(s): "
                  f"false lost {fl:.3f}, missed loss {ml:.3f})", flush=True)
        if args.table:
            for t, fl, ml, rate in threshold_table(held, ious_own, starts, cal.lost_after, forced):
                print(f"    held out, lost below {t:.2f}: false lost {fl:.3f}, missed loss {ml:.3f}, "
                      f"lost rate {rate:.3f}")
    elif args.table:
        for t, fl, ml, rate in threshold_table(p, ious, np.ones(len(p), bool), 1):
            print(f"    lost below {t:.2f}: false lost {fl:.3f}, missed loss {ml:.3f}, lost rate {rate:.3f}")
    return cal, rows, ious


def calibration_json(data: dict) -> str:
    """``data`` as indented JSON with each list of numbers on one line (a tree model has about a thousand nodes)."""
    text = json.dumps(data, indent=1)
    numbers = re.compile(r"\[\s*(-?[0-9][0-9.eE+-]*(?:,\s*-?[0-9][0-9.eE+-]*)*)\s*\]")
    return numbers.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text) + "\n"


def document(name: str, cal: Calibration, rows, ious, args, seeds, passes: int) -> dict:
    """The JSON file's content: the calibration and what it was fitted on."""
    data = cal.to_dict()
    data["fitted_on"] = {"sequences": args.sequences, "seeds": seeds, "frames": len(rows), "passes": passes,
                         **({"copies": copy_names(args)} if len(args.dataset) > 1 else {}),
                         "positive_rate": round(float(np.mean(ious > 0.5)), 4),
                         "threshold_rule": THRESHOLD_RULES[TRACKERS[name][2]]}
    return data


if __name__ == "__main__":
    raise SystemExit(main())
