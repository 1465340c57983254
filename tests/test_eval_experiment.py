"""The evaluation runner and ``vidtrack eval``: result files, conventions, resume, failures,
parallel processes and a Dask LocalCluster giving identical files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vidtrack.cli import main as vidtrack_main
from vidtrack.eval.datasets import load_dataset, read_boxes
from vidtrack.eval.evaluation import make_jobs, run_evaluation
from vidtrack.eval.synthetic import write_sequence
from vidtrack.recipes import Recipe, registry
from vidtrack.types import TrackState

METRICS = {"auc", "precision20", "pascal", "center_error", "norm_precision", "fps", "false_lost", "missed_loss",
           "confidence_auc", "ece", "lost_rate"}


class StaticTracker:
    """Reports the init box on every frame; remembers the init boxes it was given."""

    received: list = []

    def __init__(self, crash_wider_than: int | None = None) -> None:
        self.crash_wider_than = crash_wider_than

    def initialize(self, frame, box):
        StaticTracker.received.append(box)
        self.box = box
        return TrackState(frame.index, box, 1.0, "tracking")

    def step(self, frame):
        if self.crash_wider_than is not None and frame.width > self.crash_wider_than and frame.index == 3:
            raise RuntimeError("synthetic crash on a wide frame")
        return TrackState(frame.index, self.box, 1.0, "tracking")


@pytest.fixture
def fake_trackers(monkeypatch):
    StaticTracker.received = []
    monkeypatch.setitem(registry(), "test-static", Recipe("test", lambda config, seed=None: StaticTracker()))
    monkeypatch.setitem(registry(), "test-crash",
                        Recipe("test", lambda config, seed=None: StaticTracker(crash_wider_than=100)))


@pytest.fixture
def dataset(tmp_path):
    data = tmp_path / "data"
    truth = {
        "Otb": write_sequence(data / "Otb", layout="otb", frames=20, size=(96, 72)),
        "Mil": write_sequence(data / "Mil", layout="mil", frames=22, size=(128, 72), first_number=0,
                              annotate_every=5, frames_range=(3, 21), box=(20, 30, 18, 16), velocity=(1.0, -0.5)),
    }
    return data, truth


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def test_each_sequences_trackers_run_back_to_back(dataset):
    """Jobs go sequence by sequence, every filter on one sequence before the next, so the trackers compared in
    one run meet the same machine load."""
    sequences = load_dataset(dataset[0])
    jobs = make_jobs(sequences, ["a", "b", "c"])
    assert [(job.sequence.name, job.filter_name) for job in jobs] == [
        (sequence.name, name) for sequence in sequences for name in ("a", "b", "c")]


def test_result_files_use_each_sequence_convention(dataset, tmp_path, fake_trackers):
    data, truth = dataset
    sequences = load_dataset(data)
    out = tmp_path / "out"
    evaluation = run_evaluation(sequences, ["test-static"], out, isolate=False)
    # the tracker got 0-based pixel boxes: OTB rows shifted by -1, MIL rows unchanged
    by_name = {s.name: s for s in sequences}
    got = {name: (box.x, box.y) for name, box in zip([s.name for s in sequences], StaticTracker.received)}
    assert got["Otb"] == tuple(truth["Otb"][0, :2])
    assert got["Mil"] == tuple(truth["Mil"][5, :2])  # MIL range 3..21: first annotated row is 5
    otb = _lines(out / "test-static" / "Otb.txt")
    assert len(otb) == 20 and all(line == "17,21,16,18" for line in otb)  # 1-based GT row 1
    mil = _lines(out / "test-static" / "Mil.txt")
    assert len(mil) == 22 and mil[:5] == ["0,0,0,0"] * 5  # rows before the init frame: not tracked
    assert mil[5] == _lines(data / "Mil" / "Mil_gt.txt")[5] and set(mil[5:]) == {mil[5]}
    assert np.allclose(read_boxes(out / "test-static" / "Mil.txt")[5], by_name["Mil"].ground_truth[5])
    summary = evaluation.summary["test-static"]
    assert set(summary) == {"Otb", "Mil", "mean"} and set(summary["Otb"]) == METRICS
    # a static box on a moving target: IoU 1 on the first frame only among the scored ones
    assert summary["Mil"]["auc"] < 1.0 and summary["Otb"]["center_error"] > 5


def test_cli_end_to_end_resume_force_and_honest_fps(dataset, tmp_path, capsys):
    data, _ = dataset
    out = tmp_path / "r"
    args = ["eval", str(data), "--filter", "kalman-cv,ms", "--out", str(out), "-q", "--in-process"]
    assert vidtrack_main(args) == 0
    first = capsys.readouterr().out
    assert "| kalman-cv | Mil" in first and "**mean**" in first
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) == {"kalman-cv", "ms"}
    for name in summary:
        assert set(summary[name]) == {"Otb", "Mil", "mean"}
        for sequence, row in summary[name].items():
            extra = {"reliability"} if sequence == "mean" else set()   # the pooled reliability diagram's bins
            assert set(row) == METRICS | extra and 0 <= row["auc"] <= 1 and row["fps"] > 0
    assert summary["kalman-cv"]["Otb"]["auc"] > 0.5  # it really tracks the synthetic target
    assert (out / "summary.md").read_text().count("| ms ") == 3 + 1  # scores: 2 sequences + mean; confidence: 1
    for png in ("success.png", "precision.png", "plots/Mil_success.png"):
        assert (out / png).read_bytes()[:4] == b"\x89PNG"
    record = json.loads((out / "kalman-cv" / "Otb.json").read_text())
    assert record["fps"] == summary["kalman-cv"]["Otb"]["fps"] and record["tracked"] == [0, 20]

    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*/*.txt")}
    assert vidtrack_main(args) == 0  # resumed: every result reused, the same table and fps
    assert capsys.readouterr().out == first
    assert {p: p.stat().st_mtime_ns for p in out.glob("*/*.txt")} == stamps

    # another run (a fresh process per job, the default): not reused
    assert vidtrack_main(args[:-1] + ["--max-frames", "6", "--sequences", "Otb"]) == 0
    assert len(_lines(out / "ms" / "Otb.txt")) == 20 and _lines(out / "ms" / "Otb.txt")[6] == "0,0,0,0"
    assert json.loads((out / "ms" / "Otb.json").read_text())["tracked"] == [0, 6]
    assert set(json.loads((out / "summary.json").read_text())["ms"]) == {"Otb", "mean"}


def test_crashing_tracker_is_reported_and_others_go_on(dataset, tmp_path, capsys, fake_trackers):
    data, _ = dataset
    out = tmp_path / "r"
    base = ["eval", str(data), "--out", str(out), "--no-plots", "--in-process"]
    assert vidtrack_main(base + ["--filter", "kalman-cv", "-q"]) == 0
    kept = {p: p.read_bytes() for p in out.glob("kalman-cv/*")}
    capsys.readouterr()
    assert vidtrack_main(base + ["--filter", "test-crash,kalman-cv", "--force"]) == 1
    captured = capsys.readouterr()
    assert "test-crash FAILED on Mil: RuntimeError: synthetic crash on a wide frame" in captured.err
    assert "FAILED: RuntimeError" in captured.out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["test-crash"]["Mil"]["auc"] is None and "synthetic crash" in summary["test-crash"]["Mil"]["error"]
    assert summary["test-crash"]["Otb"]["auc"] > 0  # the 96-px-wide sequence ran
    assert summary["test-crash"]["mean"]["failed"] == ["Mil"]
    assert summary["test-crash"]["mean"]["auc"] == summary["test-crash"]["Otb"]["auc"]
    assert not (out / "test-crash" / "Mil.txt").exists()
    assert {p: p.read_bytes() for p in out.glob("kalman-cv/*.txt")} == {p: b for p, b in kept.items() if p.suffix == ".txt"}


def test_processes_and_dask_give_identical_files(dataset, tmp_path):
    # opencv-mil keeps hidden RNG state inside OpenCV: only a fresh process per job makes its
    # result independent of the job order, which differs between these three runs
    data, _ = dataset
    sequences = load_dataset(data)
    filters = ["opencv-mil", "kalman-cv"] if "opencv-mil" in registry() else ["kalman-cv"]
    serial = tmp_path / "serial"
    run_evaluation(sequences, filters, serial, max_frames=8)
    parallel = tmp_path / "parallel"
    run_evaluation(sequences[::-1], filters[::-1], parallel, max_frames=8, workers=2)
    distributed = pytest.importorskip("dask.distributed")
    import dask

    # non-daemonic workers fork each job from a warm fork server (test_isolated_job covers the
    # subprocess path that daemonic workers, Dask's default, take)
    with dask.config.set({"distributed.worker.daemon": False}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                                     dashboard_address=None) as cluster:
        dask_out = tmp_path / "dask"
        evaluation = run_evaluation(sequences, filters, dask_out, max_frames=8,
                                    scheduler=cluster.scheduler_address)
    assert set(evaluation.status.values()) == {"done"}
    files = sorted(p.relative_to(serial) for p in serial.glob("*/*.txt"))
    assert len(files) == 2 * len(filters)
    for rel in files:
        reference = (serial / rel).read_bytes()
        assert (parallel / rel).read_bytes() == reference
        assert (dask_out / rel).read_bytes() == reference


def test_isolated_job_matches_forked_and_in_process(dataset):
    from vidtrack.eval.jobs import Job, run_job
    from vidtrack.eval.worker import run_forked, run_isolated

    data, _ = dataset
    job = Job("kalman-cv", load_dataset(data, ["Mil"])[0], max_frames=8)
    isolated, forked, here = run_isolated(job), run_forked(job), run_job(job)
    assert isolated.status == "done" and isolated.lines == forked.lines == here.lines
    assert isolated.record["tracked"] == [5, 13]


def test_in_process_only_one_at_a_time(dataset, tmp_path, capsys):
    data, _ = dataset
    assert vidtrack_main(["eval", str(data), "--filter", "ms", "--in-process", "--jobs", "2"]) == 2
    assert "--in-process runs one job at a time" in capsys.readouterr().err


def test_rerun_recordings(dataset, tmp_path):
    pytest.importorskip("vidtrack.sinks.rerun")
    data, _ = dataset
    out, rrd = tmp_path / "r", tmp_path / "rrd"
    args = ["eval", str(data), "--filter", "kalman-cv", "--sequences", "Mil", "--max-frames", "11",
            "--out", str(out), "--rerun", str(rrd), "-q", "--no-plots"]
    assert vidtrack_main(args + ["--in-process"]) == 0
    recording = rrd / "kalman-cv" / "Mil.rrd"
    assert recording.stat().st_size > 1000
    recording.unlink()
    stamp = (out / "kalman-cv" / "Mil.txt").stat().st_mtime_ns
    assert vidtrack_main(args) == 0  # a result without its recording is run again
    assert recording.is_file() and (out / "kalman-cv" / "Mil.txt").stat().st_mtime_ns != stamp
