"""Tracker options from the command line: ``--config FILE.toml``, ``--set KEY=VALUE``, ``vidtrack filters NAME``.

The settings reach the tracker (its parts hold the values, its boxes change),
apply in the documented order (the TOML file, the shortcuts, each ``--set``),
are the same through the Python API, and apply to every tracker of
``vidtrack eval``, whose run records keep them so that a result made with
other settings is not reused.
"""

from __future__ import annotations

import json

import pytest

import vidtrack
import vidtrack.recipes
from vidtrack.cli import main
from vidtrack.config import describe
from vidtrack.eval.synthetic import write_sequence
from vidtrack.recipes import recipe_config, registry

from conftest import SAMPLE_VIDEO

FRAMES = 12


@pytest.fixture
def built(monkeypatch):
    """Every tracker the command line builds, in order (the recipes' build_tracker, spied on)."""
    trackers = []
    original = vidtrack.recipes.build_tracker

    def spy(*args, **kwargs):
        trackers.append(original(*args, **kwargs))
        return trackers[-1]

    monkeypatch.setattr(vidtrack.recipes, "build_tracker", spy)
    return trackers


def track(tmp_path, sample_init_box, *options, name="b.txt"):
    boxes = tmp_path / name
    code = main([str(SAMPLE_VIDEO), "--init-box", sample_init_box, "--boxes", str(boxes), "--max-frames", str(FRAMES),
                 "-q", *options])
    assert code == 0
    return boxes.read_text().splitlines()


def test_set_reaches_the_measurer_and_the_filter(tmp_path, sample_init_box, built):
    track(tmp_path, sample_init_box, "--filter", "svk", "--set", "meanshift.bins=8", "--set", "svr.C=2",
          "--set", "svr.window=7")
    tracker = built[-1]
    assert tracker.measurer.bins == 8
    assert tracker.filter.core_.C == 2.0 and tracker.filter.core_.window == 7
    track(tmp_path, sample_init_box, "--filter", "svk")
    default = recipe_config("svk")
    assert built[-1].measurer.bins == default.meanshift.bins != 8
    assert built[-1].filter.core_.C == default.svr.C != 2.0


def test_config_file_then_set_in_order(tmp_path, sample_init_box, built):
    toml = tmp_path / "svk.toml"
    toml.write_text("[meanshift]\nbins = 8\nscale_step = 0.05\n\n[svr]\nC = 2.0\n")
    track(tmp_path, sample_init_box, "--filter", "svk", "--config", str(toml), "--set", "meanshift.bins=4")
    tracker = built[-1]
    assert tracker.measurer.bins == 4                 # --set after the file wins
    assert tracker.measurer.scale_step == 0.05 and tracker.filter.core_.C == 2.0   # the file's other values


def test_an_option_changes_the_boxes_and_the_file_equals_the_flags(tmp_path, sample_init_box):
    default = track(tmp_path, sample_init_box, "--filter", "kalman-cv", name="default.txt")
    flags = track(tmp_path, sample_init_box, "--filter", "kalman-cv", "--set", "bins=6", "--set",
                  "background_weighting=false", name="flags.txt")
    toml = tmp_path / "kcv.toml"
    toml.write_text("bins = 6\nbackground_weighting = false\n")
    from_file = track(tmp_path, sample_init_box, "--filter", "kalman-cv", "--config", str(toml), name="file.txt")
    assert flags != default
    assert from_file == flags
    assert flags[0] == default[0] == sample_init_box   # the init box is given


def test_the_api_takes_the_same_settings(sample_init_box, tmp_path):
    cli = track(tmp_path, sample_init_box, "--filter", "svk", "--set", "svr.C=2", "--set", "meanshift.bins=8")
    box = tuple(float(v) for v in sample_init_box.split(","))
    states = list(vidtrack.track(SAMPLE_VIDEO, box, filter="svk", settings={"svr.C": "2", "meanshift.bins": 8},
                                 max_frames=FRAMES))
    from vidtrack.sinks.files import format_box

    assert [format_box(s.box) for s in states] == cli
    tracker = vidtrack.create("svk", settings={"svr.C": 2.0}, meanshift={"bins": 8})
    assert tracker.tracker.measurer.bins == 8


def test_filters_lists_every_tracker_one_line_each(capsys):
    assert main(["filters"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == sorted(registry())
    assert all(line.split(None, 1)[1].strip() == registry()[line.split()[0]].description for line in lines)


def test_filters_name_lists_every_option_with_default_type_and_doc(capsys):
    assert main(["filters", "svk"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"svk: {registry()['svk'].description}"
    rows = {line.split()[0]: line for line in out[2:]}
    c = rows["svr.C"].split(None, 3)
    assert c[:3] == ["svr.C", "0.0009765625", "float"]
    assert c[3] == "SVR regularisation weight (the paper: 2^-10 on linear motion, 2 on non-linear)"
    assert set(rows) - {"option"} == {key for key, *_ in describe(recipe_config("svk"))}


def test_filters_of_an_unknown_name_is_one_line(capsys):
    assert main(["filters", "no-such"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vidtrack: error: unknown filter 'no-such'; valid filters: ")


def test_bench_takes_the_settings(capsys, sample_init_box, built):
    assert main(["bench", str(SAMPLE_VIDEO), "--init-box", sample_init_box, "--filter", "svk", "--max-frames", "4",
                 "--set", "svr.C=2"]) == 0
    assert built[-1].filter.core_.C == 2.0
    assert "vidtrack bench: svk on" in capsys.readouterr().out


@pytest.fixture
def dataset(tmp_path):
    write_sequence(tmp_path / "data" / "Otb", layout="otb", frames=12, size=(96, 72))
    return tmp_path / "data"


def test_eval_settings_apply_to_every_filter_and_decide_reuse(dataset, tmp_path, capsys):
    out = tmp_path / "out"
    base = ["eval", str(dataset), "--filter", "kalman-cv,ms", "--out", str(out), "--no-plots", "--in-process"]
    assert main(base) == 0
    first = {name: json.loads((out / name / "Otb.json").read_text()) for name in ("kalman-cv", "ms")}
    assert first["ms"]["settings"] == dict((key, value) for key, value, *_ in describe(recipe_config("ms")))
    assert "2 run, 0 reused" in capsys.readouterr().err

    assert main([*base, "--set", "bins=16"]) == 0         # the default given explicitly: the same run
    assert "0 run, 2 reused" in capsys.readouterr().err

    assert main([*base, "--set", "bins=6"]) == 0          # other settings: run again, for every filter
    assert "2 run, 0 reused" in capsys.readouterr().err
    for name in ("kalman-cv", "ms"):
        record = json.loads((out / name / "Otb.json").read_text())
        assert record["settings"] == {**first[name]["settings"], "bins": "6"}

    assert main([*base, "--set", "bins=6"]) == 0          # the same settings again: reused
    assert "0 run, 2 reused" in capsys.readouterr().err


def test_eval_an_option_one_filter_lacks_names_that_filter(dataset, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["eval", str(dataset), "--filter", "kalman-cv,opencv-kcf", "--out", str(out), "--set",
                 "scale_step=0.05"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("vidtrack: error: filter opencv-kcf: unknown option 'scale_step'; valid options: ")
    assert not out.exists()   # nothing ran
