"""What every script that writes a copy of benchmark sequences does alike: rows and the copy's place."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import REPO, load_script, read_rows
from vidtrack.eval.synthetic import write_sequence

#: script -> its arguments beyond the dataset and the output folder
COPIES = {"zoom_sequences": ["--depth", "0.3", "--period", "20"], "edge_sequences": []}


@pytest.mark.parametrize("script", sorted(COPIES))
def test_rows_not_annotated_stay_zero(script, tmp_path):
    source = tmp_path / "src"
    write_sequence(source / "Sparse", frames=11, annotate_every=5)
    assert load_script(script).main([str(source), str(tmp_path / "out"), *COPIES[script]]) == 0
    truth = read_rows(tmp_path / "out" / "Sparse" / "groundtruth_rect.txt")
    assert np.all(truth[[1, 2, 3, 4, 6, 7, 8, 9]] == 0)
    assert np.all(truth[[0, 5, 10], 2] > 0)


@pytest.mark.parametrize("script", sorted(COPIES))
def test_the_copy_is_refused_inside_the_repository(script, tmp_path):
    write_sequence(tmp_path / "src" / "Still", frames=3)
    with pytest.raises(SystemExit, match="outside the repository"):
        load_script(script).main([str(tmp_path / "src"), str(REPO / "sequence-copy")])
    assert not (REPO / "sequence-copy").exists()
