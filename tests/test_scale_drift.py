"""scripts/scale_drift.py: a tracker's scale filter alone, fed the true centres, against the true size."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_script
from vidtrack.eval.synthetic import write_sequence


@pytest.fixture(scope="module")
def drift():
    return load_script("scale_drift")


@pytest.fixture(scope="module")
def zooming(tmp_path_factory):
    """A still target zoomed out to 0.75 of its size over 40 frames, annotated every 5th frame (OTB layout)."""
    root = tmp_path_factory.mktemp("scale-drift")
    write_sequence(root / "src" / "Shrink", frames=41, size=(240, 180), box=(96, 70, 48, 40), velocity=(0.0, 0.0),
                   annotate_every=5)
    assert load_script("zoom_sequences").main([str(root / "src"), str(root / "zoomed"), "--depth", "0.25",
                                               "--period", "80"]) == 0
    return root / "zoomed"


def table_rows(text: str) -> dict[str, list[str]]:
    rows = [line.strip("|").split("|") for line in text.splitlines() if line.startswith("| ")]
    return {cells[0].strip(): [c.strip() for c in cells[1:]] for cells in rows}


def test_true_centres_interpolate_between_annotated_rows(drift):
    truth = np.array([[0, 0, 10, 10], [0, 0, 0, 0], [0, 0, 0, 0], [30, 60, 10, 10]], float)
    np.testing.assert_allclose(drift.true_centres(truth), [[5, 5], [15, 25], [25, 45], [35, 65]])


@pytest.mark.parametrize("name", ["mil", "nh", "cbt"])
def test_the_scale_filter_follows_a_known_shrink_given_the_true_centres(drift, zooming, capsys, name):
    assert drift.main([str(zooming), "--sequences", "Shrink", "--filter", name]) == 0
    rows = table_rows(capsys.readouterr().out)
    frames, annotated, last, mean_drift, largest = rows["Shrink"]
    assert (int(frames), int(annotated)) == (41, 9)
    # the size falls to 0.75 of the first; the estimate stays within 5 % of the truth on every annotated frame
    assert abs(float(last) - 1.0) < 0.05
    assert float(largest) < 0.05 and float(mean_drift) <= float(largest)


def test_a_moving_target_in_the_mil_layout_keeps_its_size(drift, tmp_path, capsys):
    """0-based MIL ground truth every 5th frame, a run range starting between annotations, a moving centre."""
    write_sequence(tmp_path / "Walker", layout="mil", frames=48, size=(200, 150), box=(30, 40, 36, 44),
                   velocity=(2.0, 1.0), annotate_every=5, frames_range=(3, 45))
    assert drift.main([str(tmp_path), "--sequences", "Walker", "--filter", "mil"]) == 0
    frames, annotated, last, mean_drift, largest = table_rows(capsys.readouterr().out)["Walker"]
    assert int(annotated) < int(frames)
    assert abs(float(last) - 1.0) < 0.03 and float(largest) < 0.03


def test_a_wrong_size_shows_as_drift(drift, zooming):
    """Fed a fixed size (no scale estimate), the same sequence ends at 1 / 0.75 of the truth."""
    from vidtrack.eval.datasets import load_dataset

    sequence = load_dataset(zooming, ["Shrink"])[0]
    truth = np.asarray(sequence.ground_truth, float)
    fixed = np.repeat(truth[:1, 2:], len(truth), axis=0)
    ratios = drift.size_ratios(fixed, truth)
    assert ratios[0] == pytest.approx(1.0)
    assert ratios[-1] == pytest.approx(1 / 0.75, rel=0.03)


@pytest.mark.parametrize("args, message", [
    (["--filter", "mil-paper"], "does not come from a correlation filter's scale filter"),
    (["--filter", "nh-face"], "does not come from a correlation filter's scale filter"),
    (["--set", "correlation.scale_filter=false"], "does not come from a correlation filter's scale filter"),
    (["--set", "fusion.size_from=inliers"], "does not come from a correlation filter's scale filter"),
    (["--set", "correlation.scale_factors=0.95,1,1.05"], "does not come from a correlation filter's scale filter"),
    (["--set", "correlation.no_such_option=1"], "unknown option"),
    (["--set", "no_equals_sign"], "--set takes KEY=VALUE"),
])
def test_bad_input_stops_with_one_line(drift, zooming, args, message):
    with pytest.raises(SystemExit) as stop:
        drift.main([str(zooming), "--sequences", "Shrink", *args])
    assert message in str(stop.value) and "\n" not in str(stop.value)


def test_a_missing_dataset_stops_with_one_line(drift, tmp_path):
    with pytest.raises(SystemExit) as stop:
        drift.main([str(tmp_path / "nowhere")])
    assert str(stop.value).startswith("scale_drift: ") and "\n" not in str(stop.value)


def test_the_trace_holds_every_frame_and_the_tables_ratios(drift, zooming, tmp_path, capsys):
    import csv

    assert drift.main([str(zooming), "--sequences", "Shrink", "--filter", "nh", "--trace", str(tmp_path / "t")]) == 0
    frames, annotated, last, mean_drift, largest = table_rows(capsys.readouterr().out)["Shrink"]
    with (tmp_path / "t" / "Shrink.csv").open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["frame"]) for r in rows] == list(range(int(frames)))
    scored = [r for r in rows if r["ratio"]]
    assert len(scored) == int(annotated) and all(not r["true_width"] for r in rows if not r["ratio"])
    ratios = np.array([float(r["ratio"]) for r in scored])
    assert ratios[-1] == pytest.approx(float(last), abs=0.005)
    assert np.abs(np.log(ratios)).mean() == pytest.approx(float(mean_drift), abs=0.001)
    # the estimate shrinks with the target: the last frame's width is about 0.75 of the first's
    assert float(rows[-1]["width"]) / float(rows[0]["width"]) == pytest.approx(0.75, abs=0.05)


def test_a_trace_folder_that_cannot_be_made_stops_with_one_line(drift, zooming, tmp_path):
    (tmp_path / "file").write_text("not a folder", encoding="utf-8")
    with pytest.raises(SystemExit) as stop:
        drift.main([str(zooming), "--sequences", "Shrink", "--trace", str(tmp_path / "file" / "t")])
    assert str(stop.value).startswith("scale_drift: --trace ") and "\n" not in str(stop.value)
