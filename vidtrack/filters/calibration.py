"""A calibrated confidence: per-frame cues mapped to the probability that the box is right.

A tracker's raw scores (a correlation peak's PSR, an SVM margin, the weight
mass near the estimate) rank frames but are not probabilities, and no single
one of them sees every failure.  :class:`Calibration` combines several cues
``x`` (named numbers a filter computes every frame) by logistic regression
(Platt, "Probabilistic outputs for support vector machines", 1999; the
multi-cue form of Niculescu-Mizil & Caruana, "Predicting good probabilities
with supervised learning", ICML 2005)::

    P(IoU > 0.5 | x) = 1 / (1 + exp(-(b + sum_k w_k (x_k - m_k) / s_k)))

with ``m``, ``s`` the cues' mean and spread and ``w``, ``b`` fitted on the
*tune* split by ``scripts/fit_confidence.py`` (scikit-learn's
``LogisticRegression``).  The fitted numbers are small JSON files in
``vidtrack/filters/calibration/`` (``<tracker>.json``), loaded by name.  A frame
whose probability is below the file's ``lost_below`` is reported ``lost``;
the script chooses that threshold on *tune* too (the file says how).

A file may also hold a ``presence`` model: the same logistic form on cues of
its own, fitted to ``IoU > 0`` instead, the probability that the box still
overlaps the target at all.  That is the question ``lost`` answers (a box
half off a turning target is poor, not lost), so with it the status is read
from the presence: ``lost`` once it has stayed below ``lost_below`` for
``lost_after`` frames in a row (:class:`LostRule`), while the reported
confidence stays ``P(IoU > 0.5)``.

A file may instead map the cues through a sum of small regression trees
(:class:`MonotoneTrees`, gradient boosting with the log-loss: Friedman,
"Greedy function approximation: a gradient boosting machine", 2001; fitted
by scikit-learn's ``HistGradientBoostingClassifier``), each tree constrained
to be monotone in every cue in the direction the cue's meaning gives::

    P(IoU > 0.5 | x) = 1 / (1 + exp(-(b + sum_t f_t(x))))

A cue's effect may then level off or set in at a value, which the logistic's
straight log-odds cannot, and the constraints keep the probability from
falling as a cue improves, wherever the fit's frames are few.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Mapping

import numpy as np

from ..errors import UsageError


def logistic_probability(x: np.ndarray, mean: np.ndarray, scale: np.ndarray, coef: np.ndarray,
                         intercept: float) -> np.ndarray:
    """``1 / (1 + exp(-(b + w . (x - m) / s)))`` for cues ``x`` ``(..., K)``; the result has shape ``(...)``."""
    z = intercept + ((np.asarray(x, float) - mean) / scale) @ coef
    return 1.0 / (1.0 + np.exp(-np.clip(z, -50.0, 50.0)))


@dataclass(frozen=True)
class MonotoneTrees:
    """A sum of binary regression trees over the cue vector: the log-odds ``b + sum_t f_t(x)``.

    The trees' nodes are stored flat: node ``i`` splits on cue
    ``feature[i]`` (``-1`` at a leaf), sending ``x`` to ``left[i]`` when
    ``x[feature[i]] <= threshold[i]`` and to ``right[i]`` otherwise; a leaf
    adds ``value[i]``.  ``roots`` holds each tree's first node; a node's
    children come after it, so every walk ends.
    """

    baseline: float
    feature: np.ndarray
    threshold: np.ndarray
    left: np.ndarray
    right: np.ndarray
    value: np.ndarray
    roots: np.ndarray

    def log_odds(self, x: np.ndarray) -> float:
        """``b + sum_t f_t(x)`` for one clipped cue vector ``x`` ``(K,)``, all trees walked together."""
        x = np.asarray(x, float)
        node = self.roots.copy()
        inner = self.feature[node] >= 0
        while inner.any():
            at = node[inner]
            node[inner] = np.where(x[self.feature[at]] <= self.threshold[at], self.left[at], self.right[at])
            inner = self.feature[node] >= 0
        return float(self.baseline + self.value[node].sum())

    @classmethod
    def from_dict(cls, data: Mapping, n_cues: int) -> MonotoneTrees:
        """From the ``trees`` entry of a calibration file; ``n_cues`` is the length of its cue vector."""
        numbers = {k: np.asarray(data[k], dtype=float) for k in ("feature", "left", "right", "roots", "threshold",
                                                                   "value")}
        if not all(np.all(np.isfinite(v)) for v in numbers.values()) or not np.isfinite(float(data["baseline"])):
            raise UsageError("calibration file: the trees hold a number that is not finite")
        if any(np.any(numbers[k] != np.round(numbers[k])) for k in ("feature", "left", "right", "roots")):
            raise UsageError("calibration file: the trees' cue and node indices must be whole numbers")
        n = len(numbers["feature"])
        if any(np.any(np.abs(numbers[k]) > max(n, n_cues)) for k in ("feature", "left", "right", "roots")):
            raise UsageError("calibration file: the trees name a cue or a node that is not there")
        ints = {k: numbers[k].astype(np.int64) for k in ("feature", "left", "right", "roots")}
        floats = {k: numbers[k] for k in ("threshold", "value")}
        if any(a.shape != (n,) for a in (ints["feature"], ints["left"], ints["right"], *floats.values())) \
                or ints["roots"].ndim != 1:
            raise UsageError("calibration file: every node array of the trees needs one value per node")
        inner = ints["feature"] >= 0
        index = np.arange(n)
        if (np.any(ints["feature"] >= n_cues) or np.any((ints["roots"] < 0) | (ints["roots"] >= n))
                or np.any(inner & ((ints["left"] <= index) | (ints["right"] <= index)
                                   | (ints["left"] >= n) | (ints["right"] >= n)))):
            raise UsageError("calibration file: the trees name a cue or a node that is not there")
        return cls(baseline=float(data["baseline"]), **ints, **floats)

    def to_dict(self) -> dict:
        """The ``trees`` entry of :meth:`from_dict`."""
        return {"baseline": round(float(self.baseline), 6),
                **{k: [int(v) for v in getattr(self, k)] for k in ("feature", "left", "right", "roots")},
                **{k: [round(float(v), 6) for v in getattr(self, k)] for k in ("threshold", "value")}}


@dataclass(frozen=True)
class Calibration:
    """Map from named cues to ``P(IoU > 0.5)``: logistic, or monotone trees; see the module docstring.

    ``cues`` names the inputs in order; ``fill`` is the value a missing cue
    takes; ``lower``/``upper`` clip each cue (a single extreme frame must not
    dominate); ``lost_below`` is the probability under which a frame is
    ``lost``: of the ``presence`` model ``P(IoU > 0)`` (a calibration of
    its own, whose ``lost_below`` is this one) for ``lost_after`` frames in
    a row when the file has one, else of ``P(IoU > 0.5)`` itself.  The map
    is the logistic of ``mean``, ``scale``, ``coef`` and ``intercept``, or,
    when ``trees`` is given, that :class:`MonotoneTrees`' log-odds.
    """

    cues: tuple[str, ...]
    fill: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    lost_below: float
    mean: np.ndarray | None = None
    scale: np.ndarray | None = None
    coef: np.ndarray | None = None
    intercept: float = 0.0
    trees: MonotoneTrees | None = None
    presence: Calibration | None = None
    lost_after: int = 1

    def vector(self, cues: Mapping[str, float]) -> np.ndarray:
        """The clipped cue vector ``(K,)`` of ``cues`` (missing or non-finite cues take ``fill``)."""
        x = np.array([float(cues.get(name, np.nan)) for name in self.cues])
        x = np.where(np.isfinite(x), x, self.fill)
        return np.clip(x, self.lower, self.upper)

    def probability(self, cues: Mapping[str, float]) -> float:
        """``P(IoU > 0.5)`` of one frame's ``cues``."""
        if self.trees is not None:
            return float(1.0 / (1.0 + np.exp(-np.clip(self.trees.log_odds(self.vector(cues)), -50.0, 50.0))))
        return float(logistic_probability(self.vector(cues), self.mean, self.scale, self.coef, self.intercept))

    def presence_probability(self, cues: Mapping[str, float]) -> float:
        """``P(IoU > 0)`` of one frame's ``cues``; ``P(IoU > 0.5)`` when the file has no presence model."""
        return (self.presence or self).probability(cues)

    @classmethod
    def from_dict(cls, data: Mapping) -> Calibration:
        """From the JSON layout ``scripts/fit_confidence.py`` writes."""
        try:
            cues = tuple(data["cues"])
            keys = ("fill", "lower", "upper") if "trees" in data else ("mean", "scale", "coef", "fill", "lower", "upper")
            arrays = {k: np.asarray(data[k], float) for k in keys}
            model = ({"trees": MonotoneTrees.from_dict(data["trees"], len(cues))} if "trees" in data
                     else {"intercept": float(data["intercept"])})
            lost_below = float(data["lost_below"])
            presence = data.get("presence")
            if presence is not None:
                presence = cls.from_dict({**presence, "lost_below": lost_below})
            out = cls(cues=cues, lost_below=lost_below, presence=presence, lost_after=int(data.get("lost_after", 1)),
                      **model, **arrays)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise UsageError(f"calibration file: missing or bad field ({exc})") from None
        if any(a.shape != (len(cues),) for a in arrays.values()):
            raise UsageError("calibration file: every array needs one value per cue")
        if out.lost_after < 1:
            raise UsageError("calibration file: lost_after must be at least 1")
        return out

    def to_dict(self) -> dict:
        """The JSON layout of :meth:`from_dict`."""
        out: dict = {"cues": list(self.cues)}
        keys = ("fill", "lower", "upper") if self.trees is not None else ("mean", "scale", "coef", "fill", "lower", "upper")
        for key in keys:
            out[key] = [round(float(v), 6) for v in getattr(self, key)]
        if self.trees is not None:
            out["trees"] = self.trees.to_dict()
        else:
            out["intercept"] = round(float(self.intercept), 6)
        out["lost_below"] = float(self.lost_below)
        if self.presence is not None:   # its threshold is this one's
            out["presence"] = {k: v for k, v in self.presence.to_dict().items() if k != "lost_below"}
        if self.lost_after != 1:
            out["lost_after"] = int(self.lost_after)
        return out


class LostRule:
    """The ``lost`` status of a calibrated tracker, frame by frame.

    ``lost`` when the presence (:meth:`Calibration.presence_probability`) has been below
    ``lost_below`` for ``lost_after`` frames in a row, or when nothing was
    measured at all (the frame's ``unmeasured`` scalar is 1); a single
    doubtful frame between good ones is not a loss.
    """

    def __init__(self, calibration: Calibration) -> None:
        self.calibration = calibration
        self.low_run = 0

    def reset(self) -> None:
        """Forget the run of low frames (a new target)."""
        self.low_run = 0

    def lost(self, cues: Mapping[str, float]) -> bool:
        """Whether this frame (its ``cues``, with ``unmeasured``) is ``lost``; call once per frame, in order."""
        low = self.calibration.presence_probability(cues) < self.calibration.lost_below
        self.low_run = self.low_run + 1 if low else 0
        return cues.get("unmeasured", 0.0) > 0 or self.low_run >= self.calibration.lost_after


@lru_cache(maxsize=None)
def load_calibration(name: str) -> Calibration:
    """The packaged calibration ``vidtrack/filters/calibration/<name>.json``.

    Raises
    ------
    UsageError
        When there is no such file or it is malformed.
    """
    try:
        text = resources.files(__package__).joinpath("calibration", f"{name}.json").read_text(encoding="utf-8")
    except (FileNotFoundError, OSError):
        raise UsageError(f"no calibrated confidence named {name!r}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UsageError(f"calibration {name!r}: not JSON ({exc})") from None
    return Calibration.from_dict(data)
