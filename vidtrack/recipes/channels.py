"""Channel-Based Tracking on video: ``--filter cbt``.

Detections per frame are the local maxima of the correlation-filter
detector's score map (``detector="ncc"``: the NCC template's) (clutter included, no association; :mod:`vidtrack.measure.detections`);
:class:`~vidtrack.filters.channels.CBTFilter` tracks the box centre from them
on a cos² channel grid over the frame ("Learning Object Tracking in Image
Sequences", Felsberg & Larsson).  Its motion model is learned online from its
own estimates, or loaded from ``--model FILE`` (a ``.npz`` written by
``vidtrack learn cbt``).
"""

from __future__ import annotations

from ..filters.box import MeasuredSizeFilter
from ..filters.channels import CBTFilter, CBTModel
from ..measure.detections import DetectionMeasurer
from ..tracker import Recipe, Tracker

_MEASURER_OPTIONS = frozenset(("detector", "margin", "lost_margin", "nms_fraction", "min_score", "max_detections",
                               "scale_filter", "cf_options"))


def build_cbt(config=None, seed=None, model=None, **options) -> Tracker:
    """CBT tracker; ``model`` is the path of a learned model file (or a :class:`CBTModel`)."""
    measurer_options = {k: options.pop(k) for k in list(options) if k in _MEASURER_OPTIONS}
    if model is not None and not isinstance(model, CBTModel):
        model = CBTModel.load(model)
    if model is not None:
        options.setdefault("order", model.order)
    return Tracker(DetectionMeasurer(**measurer_options), MeasuredSizeFilter(CBTFilter(model=model, **options)))


RECIPES = {
    "cbt": Recipe("Channel-Based Tracking (cos² channels, learned motion) on correlation-filter detections", build_cbt),
}
