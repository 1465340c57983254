"""scripts/fit_confidence.py: mil's lost rule, chosen on frames each fit has not seen."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import load_script


@pytest.fixture(scope="module")
def fit():
    return load_script("fit_confidence")


def test_runs_restart_with_each_sequence_and_seed(fit):
    rows = [{"sequence": "A", "seed": 0}] * 3 + [{"sequence": "B", "seed": 0}] * 2 + [{"sequence": "B", "seed": 1}]
    assert fit.run_starts(rows).tolist() == [True, False, False, True, False, True]
    p = np.array([0.1, 0.1, 0.1, 0.1, 0.9, 0.1])
    assert fit.low_runs(p, fit.run_starts(rows), 0.5).tolist() == [1, 2, 3, 1, 0, 1]


def test_a_copy_of_a_sequence_opens_its_own_run_and_is_held_out_with_its_original(fit):
    """Frames pooled from several folders: a copy's frames start a run of their own (the lost rule's counts do
    not carry over from the original), and a fold holds a sequence out together with its copies."""
    rows = [{"sequence": "A", "seed": 0, "copy": 0}] * 2 + [{"sequence": "A", "seed": 0, "copy": 1}] * 2
    assert fit.run_starts(rows).tolist() == [True, False, True, False]
    rng = np.random.default_rng(3)
    rows, X, ious = [], [], []
    for copy in (0, 1):
        for name in "ABC":
            x = rng.normal(size=(40, 1))
            rows += [{"sequence": name, "seed": 0, "copy": copy}] * 40
            X.append(x)
            ious.append(np.where(x[:, 0] > 0, 0.7, 0.0))
    X, ious = np.vstack(X), np.concatenate(ious)
    p = fit.held_out_presence(X, rows, ious, 1.0)
    changed = ious.copy()
    in_a = np.array([r["sequence"] == "A" for r in rows])
    changed[in_a] = 0.7 - ious[in_a]      # relabel A and its copy: neither's own presence moves
    q = fit.held_out_presence(X, rows, changed, 1.0)
    assert np.allclose(q[in_a], p[in_a]) and not np.allclose(q[~in_a], p[~in_a])


def test_the_lost_rule_balances_false_lost_and_missed_loss(fit):
    """A run of low presence where the box has left the target is lost; single dips on the target are not."""
    # the dips go lower than the loss, so no threshold alone tells them apart
    p = np.array([0.9] * 40 + [0.1] + [0.9] * 20 + [0.1] + [0.9] * 20 + [0.2] * 10 + [0.9] * 9)
    ious = np.array([0.7] * 40 + [0.6] + [0.7] * 20 + [0.5] + [0.7] * 20 + [0.0] * 10 + [0.7] * 9)
    starts = np.zeros(len(p), bool)
    starts[0] = True
    t, k, false_lost, missed_loss = fit.choose_lost_rule(p, ious, starts)
    assert 0.2 < t <= 0.9 and k == 2        # two low frames in a row: the dips are not lost, the loss is
    assert false_lost == 0.0 and missed_loss == pytest.approx(1 / 92)   # its first frame is missed


def test_the_held_out_presence_of_a_sequence_comes_from_the_others(fit):
    rng = np.random.default_rng(0)
    rows, X, ious = [], [], []
    for name in "ABC":
        x = rng.normal(size=(60, 1))
        rows += [{"sequence": name}] * 60
        X.append(x)
        ious.append(np.where(x[:, 0] > -0.5, 0.7, 0.0))
    X, ious = np.vstack(X), np.concatenate(ious)
    p = fit.held_out_presence(X, rows, ious, 1.0)
    assert p.shape == (180,) and np.all((p > 0) & (p < 1))
    assert np.mean((p > 0.5) == (ious > 0)) > 0.9
    changed = ious.copy()
    changed[:60] = 0.7 - ious[:60]        # relabel A: A's own presence does not move, B's and C's do
    q = fit.held_out_presence(X, rows, changed, 1.0)
    assert np.allclose(q[:60], p[:60]) and not np.allclose(q[60:], p[60:])


def test_a_balanced_fit_holds_a_presence_model_on_its_own_cues(fit):
    """The confidence is fitted to IoU > 0.5 on its cues, the presence to IoU > 0 on others, each standardised."""
    rng = np.random.default_rng(1)
    rows, ious = [], []
    for name in "ABCD":
        for _ in range(80):
            seen, good = rng.uniform(0, 30), rng.uniform(0, 1)
            rows.append({"sequence": name, "psr": seen, "quality": good})
            ious.append(0.0 if seen < 8 else (0.7 if good > 0.5 else 0.3))
    ious = np.array(ious)
    cues = (("quality", 0.0, 0.0, 1.0),)
    presence_cues = (("psr", 0.0, 0.0, 30.0),)
    cal = fit.fit_cues(cues, "balance", rows, ious, 1.0, presence_cues)
    assert cal.cues == ("quality",) and cal.presence.cues == ("psr",)
    assert cal.presence.lost_below == cal.lost_below and cal.lost_after in fit.LOST_AFTER
    assert cal.presence_probability({"psr": 2.0}) < cal.lost_below < cal.presence_probability({"psr": 20.0})
    assert cal.probability({"quality": 0.9}) > 0.5 > cal.probability({"quality": 0.1})


def test_a_frame_without_any_measurement_is_lost_in_the_fit_as_in_the_filter(fit):
    """Rows marked ``unmeasured`` are lost whatever their presence, in the rule's choice and in the status."""
    p = np.array([0.9] * 60)
    ious = np.array([0.7] * 30 + [0.0] * 3 + [0.7] * 27)
    rows = [{"sequence": "A", "unmeasured": 1.0 if 30 <= k < 33 else 0.0} for k in range(60)]
    forced = fit.unmeasured_rows(rows)
    assert forced.tolist() == [False] * 30 + [True] * 3 + [False] * 27
    starts = fit.run_starts(rows)
    _, _, false_lost, missed_loss = fit.choose_lost_rule(p, ious, starts, forced)
    assert false_lost == 0.0 and missed_loss == 0.0
    _, _, _, missed_without = fit.choose_lost_rule(p, ious, starts)
    assert missed_without > 0.0   # the presence alone never sees these frames
    cal = replace(fit.logistic_fit((("psr", 0.0, 0.0, 30.0),), [{"psr": 2.0}, {"psr": 20.0}] * 5,
                                   np.array([False, True] * 5), 1.0), lost_below=0.5, lost_after=2)
    status = fit.lost_status(cal, [{**r, "psr": 20.0} for r in rows])
    assert (status == "lost").tolist() == forced.tolist()   # high presence: lost exactly where nothing was measured
    table = fit.threshold_table(p, ious, starts, 1, forced)
    assert all(missed == 0.0 and rate == pytest.approx(3 / 60) for t, _, missed, rate in table if t <= 0.9)


def _two_losses(cues: dict, lost_cues: dict, low: float):
    """Two sequences of 40 rows of ``cues``, each with a 3-frame loss (IoU 0, ``lost_cues``); a held-out
    probability ``low`` on the losses and on one single doubtful frame on the target in each, 0.9 elsewhere."""
    rows = [{"sequence": name, **cues} for name in "AB" for _ in range(40)]
    ious = np.full(80, 0.7)
    ious[[10, 11, 12, 50, 51, 52]] = 0.0
    for k in (10, 11, 12, 50, 51, 52):
        rows[k] = {**rows[k], **lost_cues}
    held = np.where(ious > 0, 0.9, low)
    held[[20, 60]] = low
    return rows, ious, held


def test_the_lost_rule_is_chosen_on_the_given_held_out_presence(fit):
    """``fit_cues`` chooses the rule on the held-out presence it is given (the script computes it once)."""
    rows, ious, held = _two_losses({"psr": 20.0, "quality": 0.8}, {"psr": 2.0}, low=0.3)
    cues, presence_cues = (("quality", 0.0, 0.0, 1.0),), (("psr", 0.0, 0.0, 30.0),)
    cal = fit.fit_cues(cues, "balance", rows, ious, 1.0, presence_cues, held)
    # the dips make a single low frame a false loss: two in a row (the cues alone would separate at one)
    assert 0.3 < cal.lost_below <= 0.9 and cal.lost_after == 2


def test_a_score_map_tracker_reads_its_lost_rule_from_its_own_held_out_confidence(fit):
    """Rule ``"confidence"``: no presence model; the pair is chosen on the held-out P(IoU > 0.5), skipped updates lost."""
    rows, ious, held = _two_losses({"quality": 0.8, "unmeasured": 0.0}, {"quality": 0.1}, low=0.2)
    rows[30] = {**rows[30], "unmeasured": 1.0}   # a skipped update on the target: lost whatever the rule
    cues = (("quality", 0.0, 0.0, 1.0),)
    cal = fit.fit_cues(cues, "confidence", rows, ious, 1.0, held_presence=held)
    assert cal.presence is None and cal.cues == ("quality",)
    assert 0.2 < cal.lost_below <= 0.9 and cal.lost_after == 2   # two low frames in a row, as chosen on ``held``
    assert fit.TRACKERS["nh"][2] == fit.TRACKERS["pf"][2] == fit.TRACKERS["bayes"][2] == "confidence"
    status = fit.lost_status(replace(cal, lost_below=0.5), [{**r, "quality": 0.8} for r in rows])
    assert (status == "lost").tolist() == [k == 30 for k in range(80)]


def _a_and_b_frames():
    """Four sequences whose target is away in frames 60-79: ``a`` dips for single frames on the target,
    ``b`` overlaps the away frames over whole runs, ``noise`` says nothing; the table holds ``b`` and ``a``."""
    rng = np.random.default_rng(2)
    rows, ious = [], []
    for name in "ABCD":
        for k in range(150):
            away = 60 <= k < 80
            a = 5.0 if away else (1.0 if k % 10 == 3 else 20.0)
            b = rng.uniform(0.0, 0.45) if away else rng.uniform(0.35, 1.0)
            rows.append({"sequence": name, "seed": 0, "a": a, "b": b, "noise": rng.uniform(0, 1)})
            ious.append(0.0 if away else 0.6)
    return rows, np.array(ious), (("b", 0.0, 0.0, 1.0), ("a", 0.0, 0.0, 30.0))


def test_the_presence_cues_are_chosen_on_the_held_out_lost_rule(fit):
    """The selection follows the lost rule's cost, not the ranking: the cue whose dips are single frames goes first.

    ``a`` is high on the target but drops below every lost frame for single frames, which costs it ranking
    but not the rule (two low frames in a row); ``b`` ranks better but overlaps over whole runs; ``noise``
    says nothing.
    """
    rows, ious, table = _a_and_b_frames()
    table = (("noise", 0.0, 0.0, 1.0),) + table
    by_ranking, _ = fit.select_cues(table, rows, ious, 1.0)   # the confidence's selection, by held-out ROC AUC
    assert by_ranking[0][0] == "b"
    chosen, lines = fit.select_presence_cues(table, rows, ious, 1.0)
    assert chosen[0][0] == "a" and "noise" not in [c[0] for c in chosen]
    assert len(lines) == len(chosen) and all("held-out cost" in line for line in lines)


def test_a_second_pass_refuses_a_file_the_tracker_would_not_read(fit, tmp_path, capsys):
    """The second pass runs the tracker with the first pass's file, which the tracker reads from the package:
    with ``--out`` elsewhere it would run with the old file, so the script stops before tracking anything."""
    with pytest.raises(SystemExit) as stop:
        fit.main([str(tmp_path / "no-dataset"), "--trackers", "mil", "--passes", "2", "--out", str(tmp_path)])
    assert stop.value.code == 2
    assert "--passes 2" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_compared_cue_sets_get_the_held_out_figures_the_selection_uses(fit):
    """Each set's line holds its held-out ROC AUC and, as presence cues, its lost rule's held-out cost."""
    rows, ious, table = _a_and_b_frames()
    lines = fit.compare_cue_sets(table, [("a",), ("b",), ("a", "b")], rows, ious, 1.0, presence=True)
    assert [line.split(":")[0].strip() for line in lines] == ["a", "b", "a, b"]
    auc = [float(line.split("ROC AUC ")[1].split(";")[0]) for line in lines]
    cost = [float(line.split("held-out cost ")[1].split(" ")[0]) for line in lines]
    assert auc[1] > auc[0] and cost[0] < cost[1]   # b ranks better, a gives the better lost rule
    assert auc[2] == pytest.approx(fit.held_out_auc(table, rows, ious, 1.0), abs=5e-4)
    held = fit.held_out_presence(fit.cue_matrix(table[1:], rows), rows, ious, 1.0)
    starts, forced = fit.run_starts(rows), fit.unmeasured_rows(rows)
    assert cost[0] == pytest.approx(fit.lost_rule_cost(*fit.choose_lost_rule(held, ious, starts, forced)[2:]),
                                    abs=5e-3)
    plain = fit.compare_cue_sets(table, [("b",)], rows, ious, 1.0)
    assert "cost" not in plain[0] and plain[0].startswith(lines[1].split(";")[0])
    assert not any("no frame carries" in line for line in lines + plain)
    unseen = fit.compare_cue_sets(table + (("never", 0.0, 0.0, 1.0),), [("b", "never")], rows, ious, 1.0)
    assert unseen[0].endswith("[no frame carries never: its fill value stands in]")


@pytest.mark.parametrize("trackers, spec, says", [
    ("mil", "psr,no_such_cue", "'no_such_cue' is not a cue of mil"),
    ("mil", "psr,psr", "'psr' is named twice"),
    ("mil", "", "'' is not a cue of mil"),
    ("mil,nh", "present,psr", "'present' is not a cue of nh"),   # a set must suit every tracker named
])
def test_a_bad_compared_set_stops_before_tracking(fit, tmp_path, capsys, trackers, spec, says):
    code = fit.main([str(tmp_path / "no-dataset"), "--trackers", trackers, "--compare", spec, "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_exported_trees_give_the_fitted_model_s_probability_and_respect_the_cues_directions(fit):
    """The trees written to the file reproduce scikit-learn's model, and never fall as a rising cue rises."""
    rng = np.random.default_rng(0)
    rows = [{"sequence": "AB"[k % 2], "quality": q, "verify_gap": g}
            for k, (q, g) in enumerate(rng.uniform(0.0, 1.0, (2000, 2)))]
    x = np.array([[r["quality"], r["verify_gap"]] for r in rows])
    ious = np.where(x[:, 0] - x[:, 1] + 0.3 * rng.normal(size=2000) > 0.0, 0.8, 0.2)
    cues = (("quality", 0.0, 0.0, 1.0), ("verify_gap", 0.0, 0.0, 2.0))
    cal = fit.trees_fit(cues, rows, ious > 0.5)
    model = fit.trees_model(fit.cue_directions(cues), x, ious > 0.5)
    assert cal.trees is not None and len(cal.trees.roots) == fit.TREES["max_iter"]
    ours = [cal.probability(r) for r in rows[:100]]
    assert np.allclose(ours, model.predict_proba(x[:100])[:, 1], atol=1e-5)
    grid = np.linspace(0.0, 1.0, 21)
    rising = [cal.probability({"quality": q, "verify_gap": 0.4}) for q in grid]
    falling = [cal.probability({"quality": 0.6, "verify_gap": g}) for g in grid]
    assert np.all(np.diff(rising) >= 0) and np.all(np.diff(falling) <= 0) and rising[-1] - rising[0] > 0.5
    assert fit.held_out_trees_auc(cues, rows, ious) > 0.8


def test_the_score_map_trackers_fit_trees_and_their_lost_rule_on_the_trees_held_out_confidence(fit):
    """Three sequences whose target is away for 30 frames (low quality) and dips for single frames on it."""
    rng = np.random.default_rng(1)
    rows, ious = [], []
    for name in "ABC":
        for k in range(300):
            away = 100 <= k < 130
            quality = rng.uniform(0.0, 0.3) if away or k % 25 == 7 else rng.uniform(0.5, 1.0)
            rows.append({"sequence": name, "seed": 0, "quality": quality, "unmeasured": 0.0})
            ious.append(0.0 if away else 0.7)
    ious = np.array(ious)
    cues = (("quality", 0.0, 0.0, 1.0),)
    cal = fit.fit_cues(cues, "confidence", rows, ious, 1.0, model="trees")
    assert cal.trees is not None and cal.presence is None
    assert cal.lost_after >= 2   # a single low frame on the target is not a loss
    status = fit.lost_status(cal, rows) == "lost"
    away = ious == 0.0
    assert status[away].mean() > 0.8 and status[~away].mean() < 0.01
    assert [fit.TRACKERS[n][3] for n in ("mil", "nh", "pf", "bayes", "cbt")] == ["logistic", "trees", "trees",
                                                                                  "logistic", "logistic"]
    with pytest.raises(ValueError, match="trees"):   # mil's presence rule is a logistic model's
        fit.fit_cues(cues, "balance", rows, ious, 1.0, cues, model="trees")


def test_with_copies_pooled_the_lost_rule_is_chosen_on_the_sequences_own_frames(fit):
    """A copy whose losses look like the sequences' single dips must not make the rule catch those dips."""
    rows, ious, held = _two_losses({"quality": 0.8, "unmeasured": 0.0}, {"quality": 0.1}, low=0.2)
    own = fit.chosen_lost_rule(held, rows, ious)
    # the same sequences in a copy (copy 1) where the target is away in runs of one frame, at the dips' level
    copy_rows = [{**r, "copy": 1} for r in rows]
    copy_ious = np.where(np.arange(80) % 4 == 1, 0.0, 0.7)
    copy_held = np.where(copy_ious > 0, 0.9, 0.2)
    pooled_rows, pooled_ious = rows + copy_rows, np.concatenate([ious, copy_ious])
    pooled_held = np.concatenate([held, copy_held])
    assert fit.own_rows(pooled_rows).tolist() == [True] * 80 + [False] * 80
    assert fit.chosen_lost_rule(pooled_held, pooled_rows, pooled_ious) == own
    assert own[1] == 2   # two low frames in a row on the sequences' own frames
    everything = fit.choose_lost_rule(pooled_held, pooled_ious, fit.run_starts(pooled_rows),
                                      fit.unmeasured_rows(pooled_rows))
    assert everything[1] == 1   # on all frames the copy's one-frame losses would make one low frame a loss


def test_the_frame_cache_keeps_rows_and_ious_and_refuses_frames_without_a_wanted_cue(fit, tmp_path):
    from vidtrack.errors import UsageError

    path = tmp_path / "frames" / "nh-0.json"
    assert fit.read_frames(path, {"quality"}) is None
    rows = [{"sequence": "A", "quality": 0.9}, {"sequence": "A", "quality": 0.2, "unmeasured": 1.0}]
    fit.write_frames(path, rows, np.array([0.8, 0.0]))
    read_rows, read_ious = fit.read_frames(path, {"quality", "unmeasured"})
    assert read_rows == rows and np.array_equal(read_ious, [0.8, 0.0])
    with pytest.raises(UsageError, match="no frame with border_gap, colour_mean; delete it"):
        fit.read_frames(path, {"quality", "colour_mean", "border_gap"})
