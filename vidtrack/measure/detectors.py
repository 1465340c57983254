"""The score-map detectors by name (``--detector NAME``): a plain-dict registry.

``cf`` (default) is the correlation-filter detector on HOG and colour
(:mod:`vidtrack.measure.correlation`), ``ncc`` the grey NCC template
(:mod:`vidtrack.measure.score_map`), ``face`` OpenCV's Haar face cascade
(:mod:`vidtrack.measure.face`, the NormalHedge paper's motivating example).
"""

from __future__ import annotations

from ..errors import UsageError

DETECTORS = ("cf", "ncc", "face")


def make_detector(name: str = "cf", **options):
    """The score-map measurer called ``name``, built with ``options``."""
    if name == "cf":
        from .correlation import CorrelationScoreMapMeasurer

        return CorrelationScoreMapMeasurer(**options)
    if name == "ncc":
        from .score_map import NCCScoreMapMeasurer

        return NCCScoreMapMeasurer(**options)
    if name == "face":
        from .face import FaceScoreMapMeasurer, find_face_cascade

        find_face_cascade()  # fail now, with a one-line message, if there is no cascade
        return FaceScoreMapMeasurer(**options)
    raise UsageError(f"unknown detector {name!r}; valid detectors: {', '.join(DETECTORS)}")
