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
    table = compare.compare(CUES, rows, ious, n_fitted=2)
    assert set(table) == {label for label, _, _ in compare.MODELS}
    for kind in ("logistic", "trees"):
        alone, pooled = table[f"{kind}, tune"], table[f"{kind}, tune + copies"]
        assert pooled.shape == (4,)   # tune, the fitted copy, the unseen copy, the unseen pooled
        assert pooled[2] > alone[2] + 0.05   # only the copies teach the edge
        assert pooled[3] == pytest.approx(pooled[2])   # one unseen folder: the pooled figure is its own
        assert min(alone[0], pooled[0]) > 0.8   # on tune, colour alone ranks the frames


def test_without_unseen_folders_the_pooled_figure_is_nan(compare):
    rows, ious = edge_frames(1)
    rows, ious = rows[:1200], ious[:1200]   # tune and the fitted copy
    table = compare.compare(CUES, rows, ious, n_fitted=2)
    assert all(np.isnan(cells[-1]) and np.isfinite(cells[:-1]).all() for cells in table.values())


def test_markdown_names_the_folders_and_marks_the_unseen(compare):
    table = {"logistic, tune": np.array([0.9, 0.8, 0.7, 0.7])}
    text = compare.markdown("nh", table, ["/data/sequences", "/x/occ1", "/x/occ2"], n_fitted=2)
    assert "| model | tune | occ1 | occ2 (unseen) | unseen, pooled |" in text
    assert "| logistic, tune | 0.900 | 0.800 | 0.700 | 0.700 |" in text


@pytest.mark.parametrize("args, message", [
    (["--trackers", "nope"], "no calibration for 'nope'"),
    (["--seeds", "0,x"], "--seeds"),
])
def test_bad_arguments_stop_with_one_line(compare, capsys, args, message):
    assert compare.main([str(SEQUENCES), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("compare_confidence_models: ") and message in err[0]


def test_a_folder_without_the_sequences_stops_before_tracking(compare, capsys, tmp_path):
    assert compare.main([str(SEQUENCES), "--unseen", str(tmp_path), "--sequences", "David"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("compare_confidence_models: ")
