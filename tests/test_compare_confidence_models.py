"""scripts/compare_confidence_models.py: the confidence's models judged on frames their fit has not seen."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import SEQUENCES, load_script

CUES = (("colour_mean", 0.5, 0.0, 1.0), ("border_gap", 1.0, 0.0, 1.0))


@pytest.fixture(scope="module")
def compare():
    return load_script("compare_confidence_models")


def edge_frames(seed: int = 0):
    """Five sequences in *tune* (copy 0), a copy fitted on (1) and an unseen copy (2).

    In *tune* every box is far from the frame's edge; in the copies a box near the edge (``border_gap`` under
    0.3) has lost its target whatever its colour, a failure only the copies show.
    """
    rng = np.random.default_rng(seed)
    rows, ious = [], []
    for copy in (0, 1, 2):
        for name in "ABCDE":
            colour = rng.uniform(size=120)
            gap = np.ones(120) if copy == 0 else rng.uniform(size=120)
            good = (colour + rng.normal(0.0, 0.15, 120) > 0.5) & (gap > 0.3)
            rows += [{"sequence": name, "seed": 0, "copy": copy, "colour_mean": c, "border_gap": g}
                     for c, g in zip(colour, gap)]
            ious.append(np.where(good, 0.7, 0.2))
    return rows, np.concatenate(ious)


def test_models_fitted_with_the_copies_rank_the_unseen_copy_better(compare):
    rows, ious = edge_frames()
    table = compare.compare(CUES, rows, ious, n_folders=3, n_fitted=2)
    assert set(table) == {label for label, _, _ in compare.MODELS}
    for kind in ("logistic", "trees"):
        alone, pooled = table[f"{kind}, tune"], table[f"{kind}, tune + copies"]
        assert pooled.shape == (4,)   # tune, the fitted copy, the unseen copy, the unseen pooled
        assert pooled[2] > alone[2] + 0.05   # only the copies teach the edge
        assert pooled[3] == pytest.approx(pooled[2])   # one unseen folder: the pooled figure is its own
        assert min(alone[0], pooled[0]) > 0.8   # on tune, colour alone ranks the frames
    copy = np.array([r["copy"] for r in rows])
    flipped = compare.compare(CUES, rows, np.where(copy == 2, 0.9 - ious, ious), n_folders=3, n_fitted=2)
    for label, cells in table.items():   # no fit learns from the unseen copy
        assert np.array_equal(cells[:2], flipped[label][:2])


def test_without_unseen_folders_the_pooled_figure_is_nan(compare):
    rows, ious = edge_frames(1)
    rows, ious = rows[:1200], ious[:1200]   # tune and the fitted copy
    table = compare.compare(CUES, rows, ious, n_folders=2, n_fitted=2)
    assert all(np.isnan(cells[-1]) and np.isfinite(cells[:-1]).all() for cells in table.values())


@pytest.mark.parametrize("kind", ["logistic", "trees"])
def test_a_held_out_sequence_and_the_unseen_copy_never_reach_a_fit(compare, kind):
    """Each sequence's probability comes from fits that saw neither its frames (in any folder) nor the unseen copy's."""
    fit = compare.fit
    rows, ious = edge_frames(2)
    copy = np.array([r["copy"] for r in rows])
    sequence = np.array([r["sequence"] for r in rows])
    fitted = copy < 2
    p = fit.held_out_confidence(CUES, kind, rows, ious, 1.0, fitted=fitted)
    flipped_a = np.where(sequence == "A", 0.9 - ious, ious)   # A's labels reversed in every folder
    p_a = fit.held_out_confidence(CUES, kind, rows, flipped_a, 1.0, fitted=fitted)
    assert np.array_equal(p[sequence == "A"], p_a[sequence == "A"])
    assert not np.allclose(p[sequence != "A"], p_a[sequence != "A"])   # the other sequences' fits did see A
    flipped_unseen = np.where(copy == 2, 0.9 - ious, ious)
    assert np.array_equal(p, fit.held_out_confidence(CUES, kind, rows, flipped_unseen, 1.0, fitted=fitted))


def test_frames_all_on_one_side_of_the_threshold_are_a_usage_error(compare):
    rows, _ = edge_frames(3)
    with pytest.raises(compare.UsageError, match="one side"):
        compare.compare(CUES, rows, np.full(len(rows), 0.7), n_folders=3, n_fitted=2)


def test_a_run_from_cached_frames_prints_a_table_per_tracker(compare, capsys, tmp_path):
    """main over three folders whose frames are in the cache: no tracking, one table with every folder."""
    from vidtrack.eval.synthetic import write_sequence

    rows, ious = edge_frames(4)
    folders = [tmp_path / name for name in ("tune", "occ1", "occ2")]
    for copy, folder in enumerate(folders):
        for name in "ABCDE":
            write_sequence(folder / name, frames=4)
        mine = [k for k, r in enumerate(rows) if r["copy"] == copy]
        frames = [{**rows[k], "quality": rows[k]["colour_mean"], "verify_gap": 0.0} for k in mine]
        compare.fit.write_frames(compare.cache_path(tmp_path / "cache", "nh", str(folder), list("ABCDE"), [0]),
                                 frames, ious[mine])
    args = [str(folders[0]), str(folders[1]), "--unseen", str(folders[2]), "--trackers", "nh",
            "--sequences", "A,B,C,D,E", "--cache", str(tmp_path / "cache")]
    assert compare.main(args) == 0
    out = capsys.readouterr().out
    assert "| model | tune | occ1 | occ2 (unseen) | unseen, pooled |" in out
    assert out.count("| logistic, tune") == 2 and out.count("| trees, tune") == 2


def test_markdown_names_the_folders_and_marks_the_unseen(compare):
    table = {"logistic, tune": np.array([0.9, 0.8, 0.7, 0.7])}
    text = compare.markdown("nh", table, ["/data/sequences", "/x/occ1", "/x/occ2"], n_fitted=2)
    assert "| model | tune | occ1 | occ2 (unseen) | unseen, pooled |" in text
    assert "| logistic, tune | 0.900 | 0.800 | 0.700 | 0.700 |" in text


@pytest.mark.parametrize("args, message", [
    (["--trackers", "nope"], "no calibration for 'nope'"),
    (["--seeds", "0,x"], "--seeds"),
    (["--trackers", ","], "at least one tracker"),
    (["--C", "0"], "--C"),
])
def test_bad_arguments_stop_with_one_line(compare, capsys, args, message):
    assert compare.main([str(SEQUENCES), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("compare_confidence_models: ") and message in err[0]


def test_a_folder_without_the_sequences_stops_before_tracking(compare, capsys, tmp_path):
    from vidtrack.eval.synthetic import write_sequence

    write_sequence(tmp_path / "tune" / "A", frames=4)
    write_sequence(tmp_path / "copy" / "B", frames=4)
    args = [str(tmp_path / "tune"), "--unseen", str(tmp_path / "copy"), "--sequences", "A"]
    assert compare.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("compare_confidence_models: ") and "'A'" in err[0]


def test_a_cache_that_is_a_file_stops_before_tracking(compare, capsys, tmp_path):
    (tmp_path / "frames").write_text("")
    assert compare.main([str(SEQUENCES), "--cache", str(tmp_path / "frames")]) == 2
    assert "not a folder" in capsys.readouterr().err


def test_a_cache_of_frames_without_the_trackers_cues_stops_with_one_line(compare, capsys, tmp_path):
    """Frames of an older tracker (a cue missing from every frame) are refused, not fitted on fill values."""
    from vidtrack.eval.synthetic import write_sequence

    write_sequence(tmp_path / "tune" / "A", frames=4)
    path = compare.cache_path(tmp_path / "cache", "nh", str(tmp_path / "tune"), ["A"], [0])
    compare.fit.write_frames(path, [{"sequence": "A", "quality": 0.9}], np.array([0.8]))
    args = [str(tmp_path / "tune"), "--trackers", "nh", "--sequences", "A", "--cache", str(tmp_path / "cache")]
    assert compare.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "colour_mean" in err[0] and "delete it to collect again" in err[0]
