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
class Calibration:
    """Logistic map from named cues to ``P(IoU > 0.5)``; see the module docstring.

    ``cues`` names the inputs in order; ``fill`` is the value a missing cue
    takes; ``lower``/``upper`` clip each cue (a single extreme frame must not
    dominate); ``lost_below`` is the probability under which a frame is
    ``lost``: of the ``presence`` model ``P(IoU > 0)`` (a calibration of
    its own, whose ``lost_below`` is this one) for ``lost_after`` frames in
    a row when the file has one, else of ``P(IoU > 0.5)`` itself.
    """

    cues: tuple[str, ...]
    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float
    fill: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    lost_below: float
    presence: Calibration | None = None
    lost_after: int = 1

    def vector(self, cues: Mapping[str, float]) -> np.ndarray:
        """The clipped cue vector ``(K,)`` of ``cues`` (missing or non-finite cues take ``fill``)."""
        x = np.array([float(cues.get(name, np.nan)) for name in self.cues])
        x = np.where(np.isfinite(x), x, self.fill)
        return np.clip(x, self.lower, self.upper)

    def probability(self, cues: Mapping[str, float]) -> float:
        """``P(IoU > 0.5)`` of one frame's ``cues``."""
        return float(logistic_probability(self.vector(cues), self.mean, self.scale, self.coef, self.intercept))

    def presence_probability(self, cues: Mapping[str, float]) -> float:
        """``P(IoU > 0)`` of one frame's ``cues``; ``P(IoU > 0.5)`` when the file has no presence model."""
        return (self.presence or self).probability(cues)

    @classmethod
    def from_dict(cls, data: Mapping) -> Calibration:
        """From the JSON layout ``scripts/fit_confidence.py`` writes."""
        try:
            cues = tuple(data["cues"])
            arrays = {k: np.asarray(data[k], float) for k in ("mean", "scale", "coef", "fill", "lower", "upper")}
            lost_below = float(data["lost_below"])
            presence = data.get("presence")
            if presence is not None:
                presence = cls.from_dict({**presence, "lost_below": lost_below})
            out = cls(cues=cues, intercept=float(data["intercept"]), lost_below=lost_below, presence=presence,
                      lost_after=int(data.get("lost_after", 1)), **arrays)
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
        for key in ("mean", "scale", "coef", "fill", "lower", "upper"):
            out[key] = [round(float(v), 6) for v in getattr(self, key)]
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
