"""Run the got10k toolkit's reports on result files and print its figures as JSON (run in .venv-got10k).

Usage: ``python got10k_reference.py KIND DATASET_ROOT RESULTS_ROOT TRACKER`` with KIND ``otb``,
``got10k`` or ``uav123``.  For ``uav123`` the miniature's sequences are not in the toolkit's table
of frame ranges, so its dataset reader's fields are set here (a split sequence such as car16_1
takes the toolkit's own range, any other its whole frame folder); the experiment's scoring
code runs unchanged.
"""

import json
import os
import sys
import tempfile

import socket

import matplotlib

matplotlib.use("Agg")


def _no_network(*args, **kwargs):
    raise OSError("the got10k reference runs without network")


socket.socket.connect = _no_network  # the toolkit downloads what it misses: never here
socket.create_connection = _no_network


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return float(value) if hasattr(value, "__float__") and not isinstance(value, (str, bool)) else value


def main(kind, root, results, tracker):
    from got10k.experiments import ExperimentGOT10k, ExperimentOTB, ExperimentUAV123

    reports = tempfile.mkdtemp()
    if kind == "otb":  # ExperimentOTB's constructor would download the sequences the tree lacks
        from got10k.datasets import OTB

        experiment = ExperimentOTB.__new__(ExperimentOTB)
        experiment.dataset = OTB(root, "tb100", download=False)
        experiment.result_dir = os.path.join(results, "OTBtb100")
        experiment.report_dir = os.path.join(reports, "OTBtb100")
        experiment.nbins_iou, experiment.nbins_ce = 21, 51
    elif kind == "got10k":
        experiment = ExperimentGOT10k(root, subset="val", result_dir=results, report_dir=reports)
    else:  # the toolkit's reader needs its table of frame ranges: set its fields for the miniature
        import got10k.datasets
        from got10k.datasets import UAV123

        dataset = UAV123.__new__(UAV123)
        dataset.root_dir, dataset.version = root, "UAV123"
        with open(os.path.join(os.path.dirname(got10k.datasets.__file__), "uav123.json")) as f:
            published = json.load(f)["UAV123"]
        anno = os.path.join(root, "anno", "UAV123")
        dataset.seq_names = sorted(f[:-4] for f in os.listdir(anno) if f.endswith(".txt"))
        dataset.anno_files = [os.path.join(anno, n + ".txt") for n in dataset.seq_names]
        metas = {}
        for name in dataset.seq_names:  # split sequences: the toolkit's own ranges; others: the whole folder
            if name in published and published[name]["folder_name"] != name:
                metas[name] = published[name]
            else:
                frames = len(os.listdir(os.path.join(root, "data_seq", "UAV123", name)))
                metas[name] = {"start_frame": 1, "end_frame": frames, "folder_name": name}
        dataset.seq_metas = {"UAV123": metas}
        dataset.seq_dirs = [os.path.join(root, "data_seq", "UAV123", metas[n]["folder_name"]) for n in dataset.seq_names]
        experiment = ExperimentUAV123.__new__(ExperimentUAV123)
        experiment.dataset = dataset
        experiment.result_dir = os.path.join(results, "UAV123")
        experiment.report_dir = os.path.join(reports, "UAV123")
        experiment.nbins_iou, experiment.nbins_ce = 21, 51
    performance = experiment.report([tracker])
    json.dump(_plain(performance[tracker]), sys.stdout)


if __name__ == "__main__":
    main(*sys.argv[1:5])
