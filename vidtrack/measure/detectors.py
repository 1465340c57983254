"""The score-map detectors by name (``--detector NAME``): a plain-dict registry.

``cf`` (default) is the correlation-filter detector on HOG and colour
(:mod:`vidtrack.measure.correlation_score_map`), ``ncc`` the grey NCC template
(:mod:`vidtrack.measure.score_map`), ``face`` OpenCV's Haar face cascade
(:mod:`vidtrack.measure.face`, the NormalHedge paper's motivating example).
"""

from __future__ import annotations

from ..config import with_settings
from ..errors import UsageError

DETECTORS = ("cf", "ncc", "face")


def make_detector(name: str = "cf", cf=None, **options):
    """The score-map measurer called ``name``, built with ``options``.

    For ``cf`` the options are fields of
    :class:`~vidtrack.measure.correlation_score_map.CorrelationDetectorConfig`
    (values or strings, converted to the field's type; an unknown one raises
    :class:`~vidtrack.errors.UsageError` naming the valid ones), set on top
    of ``cf`` (that configuration; its defaults when ``None``); for the
    others, keyword arguments of the measurer, and ``cf`` is not used.
    """
    if name == "cf":
        from .correlation_score_map import CorrelationDetectorConfig, CorrelationScoreMapMeasurer

        return CorrelationScoreMapMeasurer(with_settings(cf or CorrelationDetectorConfig(), options))
    if name == "ncc":
        from .score_map import NCCScoreMapMeasurer

        return NCCScoreMapMeasurer(**options)
    if name == "face":
        from .face import FaceScoreMapMeasurer, find_face_cascade

        find_face_cascade()  # fail now, with a one-line message, if there is no cascade
        return FaceScoreMapMeasurer(**options)
    raise UsageError(f"unknown detector {name!r}; valid detectors: {', '.join(DETECTORS)}")
