"""The calibrated confidence: the logistic and tree maps, the packaged files, and the filters that use them."""

from __future__ import annotations

import numpy as np
import pytest

from vidtrack.errors import UsageError
from vidtrack.filters import cbt as cbt_filter
from vidtrack.filters import mil as mil_filter
from vidtrack.filters import score_trackers
from vidtrack.filters.calibration import Calibration, LostRule, MonotoneTrees, load_calibration, logistic_probability
from vidtrack.filters.mil import KalmanConfig, MILKalmanFilter
from vidtrack.types import LOST, TRACKING, Box, Detections, Frame, ScoreMap, Superpixels


def _calibration(**changes) -> Calibration:
    fields = dict(cues=("a", "b"), mean=np.array([1.0, 0.0]), scale=np.array([2.0, 1.0]),
                  coef=np.array([1.5, -0.5]), intercept=0.25, fill=np.array([0.0, 3.0]),
                  lower=np.array([-10.0, 0.0]), upper=np.array([10.0, 2.0]), lost_below=0.4)
    fields.update(changes)
    return Calibration(**fields)


def test_probability_is_the_logistic_of_the_standardised_clipped_cues():
    cal = _calibration()
    z = 0.25 + 1.5 * (3.0 - 1.0) / 2.0 - 0.5 * 2.0      # b is clipped to its upper bound 2
    assert cal.probability({"a": 3.0, "b": 5.0}) == pytest.approx(1.0 / (1.0 + np.exp(-z)))
    # a missing or non-finite cue takes its fill value (b: 3, clipped to 2)
    assert cal.probability({"a": 3.0}) == pytest.approx(cal.probability({"a": 3.0, "b": np.nan}))
    assert cal.probability({"a": 3.0}) == pytest.approx(cal.probability({"a": 3.0, "b": 2.0}))
    x = np.array([[3.0, 2.0], [0.0, 0.0]])
    p = logistic_probability(x, cal.mean, cal.scale, cal.coef, cal.intercept)
    assert p.shape == (2,) and p[0] == pytest.approx(cal.probability({"a": 3.0, "b": 2.0}))
    assert Calibration.from_dict(cal.to_dict()).probability({"a": 0.5}) == pytest.approx(cal.probability({"a": 0.5}))


def test_the_presence_model_reads_its_own_cues_and_round_trips():
    presence = Calibration(cues=("c",), mean=np.array([2.0]), scale=np.array([0.5]), coef=np.array([1.0]),
                           intercept=3.0, fill=np.array([0.0]), lower=np.array([0.0]), upper=np.array([5.0]),
                           lost_below=0.4)
    cal = _calibration(presence=presence, lost_after=3)
    z = 3.0 + 1.0 * (4.0 - 2.0) / 0.5
    assert cal.presence_probability({"a": 3.0, "c": 4.0}) == pytest.approx(1.0 / (1.0 + np.exp(-z)))
    assert cal.presence_probability({"a": 3.0, "b": 1.0}) == pytest.approx(1.0 / (1.0 + np.exp(-(3.0 - 4.0))))
    again = Calibration.from_dict(cal.to_dict())
    assert "lost_below" not in cal.to_dict()["presence"] and again.presence.lost_below == cal.lost_below
    assert again.lost_after == 3
    assert again.presence_probability({"c": 1.5}) == pytest.approx(cal.presence_probability({"c": 1.5}))
    plain = _calibration()   # without a presence model the status reads P(IoU > 0.5) itself
    assert plain.presence_probability({"a": 0.5}) == plain.probability({"a": 0.5})
    assert "presence" not in plain.to_dict()


def _two_trees() -> MonotoneTrees:
    """Tree 0 splits on cue a at 1 (-1 left, +1 right); tree 1 on b at 0.5, then its right child on a at 3."""
    return MonotoneTrees(baseline=0.5, feature=np.array([0, -1, -1, 1, -1, 0, -1, -1]),
                         threshold=np.array([1.0, 0, 0, 0.5, 0, 3.0, 0, 0]),
                         left=np.array([1, -1, -1, 4, -1, 6, -1, -1]), right=np.array([2, -1, -1, 5, -1, 7, -1, -1]),
                         value=np.array([0, -1.0, 1.0, 0, 0.25, 0, 2.0, 4.0]), roots=np.array([0, 3]))


def test_tree_probability_is_the_logistic_of_the_baseline_and_the_leaves_the_clipped_cues_reach():
    cal = _calibration(mean=None, scale=None, coef=None, trees=_two_trees())
    def p(z):
        return 1.0 / (1.0 + np.exp(-z))
    assert cal.probability({"a": 0.0, "b": 0.0}) == pytest.approx(p(0.5 - 1.0 + 0.25))
    assert cal.probability({"a": 2.0, "b": 1.0}) == pytest.approx(p(0.5 + 1.0 + 2.0))
    assert cal.probability({"a": 20.0, "b": 1.0}) == pytest.approx(p(0.5 + 1.0 + 4.0))
    assert cal.probability({"a": 2.0}) == pytest.approx(p(0.5 + 1.0 + 2.0))   # b's fill 3, clipped to 2
    # the cues are clipped before the trees see them: a clipped to 2.5 stays below tree 1's split at 3
    capped = _calibration(mean=None, scale=None, coef=None, trees=_two_trees(), upper=np.array([2.5, 2.0]))
    assert capped.probability({"a": 20.0, "b": 1.0}) == pytest.approx(p(0.5 + 1.0 + 2.0))
    again = Calibration.from_dict(cal.to_dict())
    assert "coef" not in cal.to_dict() and again.trees is not None
    for cues in ({"a": 0.5, "b": 0.7}, {"a": 5.0, "b": 0.1}, {"a": -3.0}):
        assert again.probability(cues) == pytest.approx(cal.probability(cues))


def test_bad_trees_are_usage_errors():
    good = _calibration(mean=None, scale=None, coef=None, trees=_two_trees()).to_dict()
    def with_trees(**changes):
        return {**good, "trees": {**good["trees"], **changes}}
    with pytest.raises(UsageError, match="one value per node"):
        Calibration.from_dict(with_trees(value=[0.0]))
    with pytest.raises(UsageError, match="not there"):
        Calibration.from_dict(with_trees(feature=[2, -1, -1, 1, -1, 0, -1, -1]))   # a third cue: there are two
    with pytest.raises(UsageError, match="not there"):   # a child before its parent: the walk might not end
        Calibration.from_dict(with_trees(left=[1, -1, -1, 0, -1, 6, -1, -1]))
    with pytest.raises(UsageError, match="missing"):
        Calibration.from_dict({**good, "trees": {"baseline": 0.0}})
    with pytest.raises(UsageError, match="not there"):   # an index too large for any array
        Calibration.from_dict(with_trees(roots=[0, 2 ** 70]))
    with pytest.raises(UsageError, match="whole numbers"):
        Calibration.from_dict(with_trees(roots=[0, 3.5]))
    with pytest.raises(UsageError, match="not finite"):
        Calibration.from_dict(with_trees(value=[0, -1.0, float("nan"), 0, 0.25, 0, 2.0, 4.0]))


def test_lost_needs_lost_after_low_frames_in_a_row_or_no_measurement():
    # P(IoU > 0.5) = logistic(0.25 + 1.5 (a - 1) / 2 - 0.5 b) with b's fill 3 clipped to 2:
    # a = 1 gives 0.32, below lost_below 0.6; a = 3 gives 0.68
    rule = LostRule(_calibration(lost_below=0.6, lost_after=3))
    low, high = {"a": 1.0}, {"a": 3.0}
    assert [rule.lost(c) for c in (low, low, high, low, low, low, low)] == [False, False, False, False, False,
                                                                           True, True]
    assert rule.lost({**high, "unmeasured": 1.0}) and not rule.lost(high)
    rule.lost(low), rule.lost(low)
    rule.reset()
    assert not rule.lost(low)


def test_bad_calibration_files_are_usage_errors():
    with pytest.raises(UsageError, match="no calibrated confidence"):
        load_calibration("no-such-tracker")
    with pytest.raises(UsageError, match="one value per cue"):
        Calibration.from_dict({**_calibration().to_dict(), "coef": [1.0]})
    with pytest.raises(UsageError, match="missing"):
        Calibration.from_dict({"cues": ["a"]})
    with pytest.raises(UsageError, match="lost_after"):
        Calibration.from_dict({**_calibration().to_dict(), "lost_after": 0})
    with pytest.raises(UsageError, match="missing"):
        Calibration.from_dict({**_calibration().to_dict(), "presence": {"cues": ["a"], "coef": [1.0]}})


MIL_GOOD = {"measured": 1.0, "quality": 0.9, "psr": 20.0, "svm_margin": 1.5, "inlier_coverage": 0.6,
            "motion": 0.5, "scale_change": 0.0, "coast": 0.0, "present": 1.0}
MAP_GOOD = {"measured": 1.0, "quality": 0.9, "psr": 20.0, "concentration": 0.8, "motion": 0.05,
            "mass_quality": 0.72, "coast": 0.0, "verify": 0.6, "verify_mean": 0.6, "colour": 0.7,
            "colour_mean": 0.7, "spread": 0.05}
MAP_DRIFTED = {**MAP_GOOD, "verify": 0.0, "verify_mean": 0.0, "verify_gap": 1.0, "colour": 0.2, "colour_mean": 0.2,
               "spread": 1.0}
COASTING = {"measured": 0.0, "quality": 0.0, "psr": 2.0, "coast": 3.0}
CBT_GOOD = {**MAP_GOOD, "mode_mass": 0.9}
CBT_DRIFTED = {**MAP_DRIFTED, "mode_mass": 0.7}   # and the posterior's mode holds less of its mass


@pytest.mark.parametrize(("name", "cues", "good", "drifted"), [("mil", mil_filter.CUES, MIL_GOOD, None),
                                                               ("nh", score_trackers.CUES, MAP_GOOD, MAP_DRIFTED),
                                                               ("pf", score_trackers.CUES, MAP_GOOD, MAP_DRIFTED),
                                                               ("bayes", score_trackers.CUES, MAP_GOOD, MAP_DRIFTED),
                                                               ("cbt", cbt_filter.CUES, CBT_GOOD, CBT_DRIFTED)])
def test_packaged_calibrations_match_their_filters_cues(name, cues, good, drifted):
    cal = load_calibration(name)
    assert set(cal.cues) <= {c[0] for c in cues}
    assert cal.presence is None or set(cal.presence.cues) <= {c[0] for c in cues}
    assert 0.0 < cal.lost_below < 1.0
    # a typical well-measured frame is likely right and not lost; a long coast without a peak is lost
    assert cal.probability(good) > 0.5 and cal.presence_probability(good) >= cal.lost_below
    rule = LostRule(cal)
    assert not any(rule.lost({**good, "unmeasured": 0.0}) for _ in range(cal.lost_after + 2))
    if name == "mil":   # its presence model reads a coast as lost by itself
        assert cal.presence_probability(COASTING) < cal.lost_below
    else:   # a box off the first frame's appearance, its update made, is lost after the file's run of frames
        rule = LostRule(cal)
        status = [rule.lost({**drifted, "unmeasured": 0.0}) for _ in range(cal.lost_after)]
        assert status == [False] * (cal.lost_after - 1) + [True]


def test_mil_reads_a_box_against_the_frames_edge_as_absent_unless_its_inliers_cover_it():
    """A box that has lost its target comes to rest against the frame's edge: there a weak inlier coverage is
    a loss, a box size or more inside the frame it is not, and inliers over most of the box keep it present."""
    cal = load_calibration("mil")
    inside = {**MIL_GOOD, "inlier_coverage": 0.4, "verify_gap": 0.1, "border_gap": 1.0}
    at_edge = {**inside, "border_gap": 0.0}
    assert cal.presence_probability(inside) >= cal.lost_below > cal.presence_probability(at_edge)
    assert cal.presence_probability({**at_edge, "inlier_coverage": 1.0}) >= cal.lost_below


def _measurement(box: Box, quality: float, psr: float, coverage: float = 0.6, present: bool = False) -> Superpixels:
    scores = np.array([1.0, 0.5, -1.0])
    return Superpixels(labels=np.zeros((2, 2), np.int32), features=np.zeros((3, 1)), scores=scores,
                       inliers=np.array([True, True, False]), box=box, quality=quality, present=present,
                       stages={"psr": psr, "inlier_coverage": coverage})


def test_mil_filter_reports_the_calibrated_probability_and_lost_by_the_presence_rule():
    box = Box(100, 100, 40, 60)
    kf = MILKalmanFilter(KalmanConfig(confidence="mil"))
    kf.initialize(box)
    cal = load_calibration("mil")
    kf.predict()
    good = kf.update(_measurement(box, 0.9, 20.0))
    assert good.status == TRACKING and good.scalars["measured"] == 1.0
    assert good.confidence == pytest.approx(cal.probability(good.scalars))
    assert cal.presence_probability(good.scalars) >= cal.lost_below and good.scalars["svm_margin"] == pytest.approx(0.75)
    for _ in range(5):   # nothing measured: lost at once, the probability low
        kf.predict()
        coast = kf.update(None)
        assert coast.status == LOST
    assert coast.scalars["measured"] == 0.0 and coast.scalars["coast"] == pytest.approx(np.log(6.0))
    assert coast.scalars["unmeasured"] == 1.0 and good.scalars["unmeasured"] == 0.0
    assert coast.confidence < 0.5 < good.confidence and cal.presence_probability(coast.scalars) < cal.lost_below
    # a weak measurement (inliers on 5 % of the box) against the frame's edge: tracking until the presence has
    # stayed low for lost_after frames
    kf = MILKalmanFilter(KalmanConfig(confidence="mil"))
    kf.initialize(box, Frame(0, np.zeros((200, 140, 3), np.uint8)))   # the box's right side on the frame's edge
    kf.predict()
    assert kf.update(_measurement(box, 0.9, 20.0, coverage=0.95, present=True)).status == TRACKING
    weak = []
    for _ in range(cal.lost_after + 1):
        kf.predict()
        weak.append(kf.update(_measurement(box, 0.2, 4.0, coverage=0.05, present=True)))
    assert weak[0].scalars["border_gap"] == pytest.approx(0.0, abs=1e-6)
    assert all(cal.presence_probability(w.scalars) < cal.lost_below for w in weak)
    assert [w.status for w in weak] == [TRACKING] * (cal.lost_after - 1) + [LOST, LOST]
    raw = MILKalmanFilter(KalmanConfig(confidence=None))   # uncalibrated: the quality, lost when not measured
    raw.initialize(box)
    raw.predict()
    assert raw.update(_measurement(box, 0.9, 20.0)).confidence == pytest.approx(0.9)
    raw.predict()
    assert raw.update(None).status == LOST


def _peaked_map(peaks, quality: float, margin: float = 15.0) -> ScoreMap:
    """A map of 20 x 20 boxes on 1 px cells, ``margin`` px beyond the ``(centre, height)`` Gaussian ``peaks``."""
    centres = np.array([centre for centre, _ in peaks], float)
    lo, hi = centres.min(axis=0) - margin, centres.max(axis=0) + margin
    origin = (lo[0] - 10.0, lo[1] - 10.0)
    c = ScoreMap(np.zeros((int(hi[1] - lo[1]) + 1, int(hi[0] - lo[0]) + 1)), origin, 1.0, (20.0, 20.0)).centers()
    scores = np.max([height * np.exp(-((c[..., 0] - centre[0]) ** 2 + (c[..., 1] - centre[1]) ** 2) / 18.0)
                     for centre, height in peaks], axis=0)
    return ScoreMap(scores, origin, 1.0, (20.0, 20.0), quality=quality)


def _map_with_quality(centre, quality: float) -> ScoreMap:
    """A score map peaked at ``centre`` (20 x 20 boxes) whose peak quality is ``quality``."""
    return _peaked_map([(centre, 1.0)], quality)


def _rising_calibration(cue: str) -> Calibration:
    """P(IoU > 0.5) rising with ``cue`` (0.5 at 0.5); lost below 0.3 for 2 frames in a row."""
    return Calibration(cues=(cue,), mean=np.array([0.5]), scale=np.array([0.1]), coef=np.array([4.0]),
                       intercept=0.0, fill=np.array([0.0]), lower=np.array([0.0]), upper=np.array([1.0]),
                       lost_below=0.3, lost_after=2)


@pytest.mark.parametrize("cls", [score_trackers.NormalHedgeBoxFilter, score_trackers.ParticleBoxFilter,
                                 score_trackers.GridBayesBoxFilter])
def test_score_map_filters_report_lost_by_their_calibrated_confidence(cls, monkeypatch):
    cal = _rising_calibration("quality")   # P(IoU > 0.5) rising with the map's quality
    monkeypatch.setattr(score_trackers, "load_calibration", lambda name: cal)
    f = cls(rng=np.random.default_rng(0), confidence="test")
    centre = np.array([100.0, 100.0])
    f.initialize(Box.from_center(*centre, 20.0, 20.0))
    good = f.update(_map_with_quality(f.predict().box.center, 0.9))
    assert good.status == TRACKING and good.confidence == pytest.approx(cal.probability({"quality": 0.9}))
    # quality 0.4: above the filter's own lost_below (0.35), so the update is made, but P(IoU > 0.5) is 0.27
    weak = [f.update(_map_with_quality(f.predict().box.center, 0.4)) for _ in range(3)]
    assert all(w.scalars["measured"] == 1.0 and w.confidence < cal.lost_below for w in weak)
    assert [w.status for w in weak] == [TRACKING, LOST, LOST]
    assert f.update(_map_with_quality(f.predict().box.center, 0.9)).status == TRACKING
    skipped = f.update(_map_with_quality(f.predict().box.center, 0.1))   # the update skipped: lost at once
    assert skipped.status == LOST and skipped.scalars["unmeasured"] == 1.0
    # uncalibrated: lost only when the update was skipped
    raw = cls(rng=np.random.default_rng(0))
    raw.initialize(Box.from_center(*centre, 20.0, 20.0))
    assert all(raw.update(_map_with_quality(raw.predict().box.center, 0.4)).status == TRACKING for _ in range(3))


@pytest.mark.parametrize("cls", [score_trackers.NormalHedgeBoxFilter, score_trackers.ParticleBoxFilter,
                                 score_trackers.GridBayesBoxFilter])
def test_a_lost_score_map_filter_restarts_at_a_confident_re_detection(cls):
    start, found = np.array([100.0, 100.0]), np.array([160.0, 110.0])   # the target reappears 3 boxes away

    def filter_(reseed_above, *, lost: bool = True):
        f = cls(rng=np.random.default_rng(0), reseed_above=reseed_above)
        f.initialize(Box.from_center(*start, 20.0, 20.0))
        quality = 0.1 if lost else 0.9   # a skipped update is lost
        assert f.update(_map_with_quality(f.predict().box.center, quality)).status == (LOST if lost else TRACKING)
        f.predict()
        return f

    def distance(f, smap):
        return np.linalg.norm(f.update(smap).box.center - found)

    # a confident map whose peak the prior's box misses: the lost filter restarts there, and only then
    assert distance(filter_(0.5), _map_with_quality(found, 0.9)) < 2.0
    assert distance(filter_(None), _map_with_quality(found, 0.9)) > 20.0
    # not below reseed_above, not while tracking, not when the prior's own box scores half the peak or more
    assert distance(filter_(0.5), _map_with_quality(found, 0.4)) > 45.0
    assert distance(filter_(0.5, lost=False), _map_with_quality(found, 0.9)) > 45.0
    assert distance(filter_(0.5), _peaked_map([(start, 0.8), (found, 1.0)], 0.9, margin=25.0)) > 45.0
    assert distance(filter_(0.5), _peaked_map([(start, 0.3), (found, 1.0)], 0.9, margin=25.0)) < 2.0
    # a map too weak for the update (quality under lost_below, 0.35) restarts nothing, whatever reseed_above
    f = filter_(0.2)
    f.update(_map_with_quality(found, 0.3))
    assert np.linalg.norm(f.predict().box.center - start) < 15.0


def test_cbt_reports_lost_by_its_calibrated_confidence(monkeypatch):
    cal = _rising_calibration("raw_confidence")   # P(IoU > 0.5) rising with cbt's own confidence
    monkeypatch.setattr(cbt_filter, "load_calibration", lambda name: cal)

    def detection(f, score):   # one detection at the predicted centre
        return Detections(f.predict().box.center[None, :], np.array([score]))

    f = cbt_filter.CBTFilter(confidence="test")
    f.initialize(Box.from_center(100.0, 100.0, 20.0, 20.0))
    good = f.update(detection(f, 0.9))
    assert good.status == TRACKING and good.confidence == pytest.approx(cal.probability(good.scalars))
    # score 0.4: above cbt's own lost_below (0.2), so the frame is measured, but P(IoU > 0.5) is below 0.3
    weak = [f.update(detection(f, 0.4)) for _ in range(3)]
    assert all(w.scalars["measured"] == 1.0 and w.confidence < cal.lost_below for w in weak)
    assert [w.status for w in weak] == [TRACKING, LOST, LOST]
    assert f.update(detection(f, 0.9)).status == TRACKING
    unmeasured = f.update(detection(f, 0.1))   # cbt's own confidence under its lost_below: lost at once
    assert unmeasured.status == LOST and unmeasured.scalars["unmeasured"] == 1.0
    # uncalibrated: lost only below its own lost_below
    raw = cbt_filter.CBTFilter(confidence=None)
    raw.initialize(Box.from_center(100.0, 100.0, 20.0, 20.0))
    assert all(raw.update(detection(raw, 0.4)).status == TRACKING for _ in range(3))
