#!/usr/bin/env python3
"""Write ``docs/results.md``: the measured tables, from ``vidtrack eval`` output folders.

Each table is made from the ``summary.json`` of one ``vidtrack eval`` run per
split and random seed (the *tune* and *validate* splits of the shared
sequences' ``INDEX.md``): the mean success AUC, PASCAL score, precision@20
and fps per tracker, the success AUC per sequence, and whether the confidence
can be trusted (lost / false lost / missed loss / ROC AUC / ECE).  Under each table
stand the exact commands, the vidtrack version, the git commit and the date.

Run the evaluations and write the tables (one ``vidtrack eval`` process at a
time, each writing ``ROOT/<split>/seed<S>/``)::

    python scripts/results_tables.py --run /tmp/results-runs \\
        --filter mil,opencv-csrt,opencv-mil,nh,pf,bayes,cbt --splits validate,tune --seeds 0,1,2

or table folders that already exist (a ``--run`` root, or any ``vidtrack eval
--out`` folders; a folder's split is recognised from its sequences)::

    python scripts/results_tables.py /tmp/results-runs

A run folder written by ``--run`` holds ``results_run.json`` (the command,
version, commit, dates and load average).  For other folders the command is
rebuilt from the run records beside the result files and the version is
marked as not recorded.  ``--run`` re-uses a folder's results only when they
were made by the same committed code (the git trees of ``vidtrack/`` and
``pyproject.toml``), so an interrupted run resumes; otherwise it passes ``--force``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATASET = "../shared/data/sequences"
DEFAULT_FILTERS = "mil,opencv-csrt,opencv-mil,nh,pf,bayes,cbt"
META = "results_run.json"

#: The splits of the shared sequences (INDEX.md), used when the dataset's INDEX.md cannot be read.
SPLITS = {
    "validate": ("Couple", "Crossing", "Dog", "Freeman1", "Human8", "Jogging", "Suv"),
    "tune": ("David", "Sylvester", "FaceOcc1", "FaceOcc2", "Girl", "Tiger1", "Tiger2", "Man", "Dancer2",
             "Football1", "Human9", "Subway", "MotorRolling"),
}

METRIC_DOC = (
    "AUC: OTB success AUC (mean over IoU thresholds 0, 0.05, ..., 1 of the fraction of frames with IoU above "
    "it); PASCAL: fraction of frames with IoU > 0.5; Prec@20: fraction of frames with centre error <= 20 px; "
    "fps: frames tracked per second by the wall clock, decoding excluded. Means are over the split's "
    "sequences; only annotated ground-truth frames are scored. A cell `a / b / c` holds the values at the "
    "random seeds named in the table's heading, in that order; a single value means every seed gave it.")
CONFIDENCE_DOC = (
    "Frames of all the split's sequences pooled, init frame excluded. lost: fraction of frames marked lost; "
    "false lost: of those, the fraction whose box still overlaps the target (IoU > 0); missed loss: of the "
    "frames marked tracking, the fraction with IoU = 0; ROC AUC: the confidence as a predictor of IoU > 0.5 "
    "(0.5 = chance); ECE: expected calibration error of the confidence read as P(IoU > 0.5) (ten equal-width "
    "bins; `report.html` of each run draws its reliability diagram). The `(OpenCV ok flag)` rows score OpenCV's own update() flag instead of vidtrack's "
    "confidence.")


# ------------------------------------------------------------------ reading runs


def read_splits(dataset: str | Path) -> dict[str, tuple[str, ...]]:
    """The splits named in ``DATASET/INDEX.md`` (``tune = `A,B```), or :data:`SPLITS` without one."""
    index = Path(dataset) / "INDEX.md"
    if not index.is_file():
        return dict(SPLITS)
    found = dict(re.findall(r"(\w+) = `([A-Za-z0-9_,]+)`", index.read_text(encoding="utf-8")))
    splits = {name: tuple(found[name].split(",")) for name in ("validate", "tune") if name in found}
    return splits or dict(SPLITS)


def _records(folder: Path) -> list[dict]:
    out = []
    for path in sorted(folder.glob("*/*.json")):
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(record, dict) and "filter" in record and "sequence" in record:
            out.append(record | {"_mtime": path.stat().st_mtime})
    return out


def load_run(folder: Path, splits: dict[str, tuple[str, ...]]) -> dict:
    """One ``vidtrack eval`` output folder: its summary, split, seed and provenance."""
    summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    summary.pop("by_attribute", None)
    sequences = list(dict.fromkeys(s for per in summary.values() for s in per if s != "mean"))
    records = _records(folder)
    seeds = {r.get("seed") for r in records}
    meta_path = folder / META
    if meta_path.is_file():
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    else:
        stamp = max((r["_mtime"] for r in records), default=(folder / "summary.json").stat().st_mtime)
        settings = {k: v for r in records for k, v in (r.get("settings") or {}).items()}
        command = ["vidtrack", "eval", "DATASET", "--sequences", ",".join(sequences),
                   "--filter", ",".join(summary), "--seed", str(next(iter(seeds), "?"))]
        command += [a for k, v in settings.items() for a in ("--set", f"{k}={v}")]
        meta = {"command": command, "version": None, "commit": None,
                "finished": datetime.datetime.fromtimestamp(stamp, datetime.timezone.utc).isoformat(),
                "note": "command rebuilt from the run records; version and commit not recorded"}
    split = next((name for name, members in splits.items() if set(members) == set(sequences)),
                 "sequences " + ", ".join(sequences))
    return {"folder": folder, "summary": summary, "sequences": sequences, "split": split,
            "seed": meta.get("seed", next(iter(seeds)) if len(seeds) == 1 else None), "meta": meta}


def find_runs(paths: list[str], splits: dict[str, tuple[str, ...]]) -> list[dict]:
    """Every eval output folder (a folder holding ``summary.json``) under ``paths``."""
    folders: list[Path] = []
    for p in map(Path, paths):
        if not p.is_dir():
            raise SystemExit(f"results_tables: no such folder: {p}")
        found = [p] if (p / "summary.json").is_file() else sorted(s.parent for s in p.rglob("summary.json"))
        if not found:
            raise SystemExit(f"results_tables: no summary.json under {p} (is it a vidtrack eval --out folder?)")
        folders += [f for f in found if f not in folders]
    return [load_run(f, splits) for f in folders]


# ------------------------------------------------------------------ running


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def provenance() -> dict:
    """The vidtrack version and git commit that ``python -m vidtrack`` from this checkout runs."""
    env = os.environ | {"PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    probe = subprocess.run([sys.executable, "-c", "import vidtrack; print(vidtrack.__version__); "
                            "print(vidtrack.__file__)"], capture_output=True, text=True, env=env)
    if probe.returncode != 0:
        raise SystemExit(f"results_tables: cannot import vidtrack: {probe.stderr.strip().splitlines()[-1:]}")
    version, location = probe.stdout.split("\n")[:2]
    if not Path(location).resolve().is_relative_to(REPO):
        raise SystemExit(f"results_tables: python -m vidtrack runs {location}, not this checkout ({REPO})")
    commit = _git("rev-parse", "--short=12", "HEAD")
    dirty = bool(_git("status", "--porcelain", "--", "vidtrack", "pyproject.toml"))  # the code, not docs/
    code = " ".join(_git("rev-parse", f"HEAD:{p}") for p in ("vidtrack", "pyproject.toml")).strip()
    return {"version": version, "commit": commit or None, "dirty": dirty, "code": code or None, "env": env}


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def run_evaluations(args, splits: dict[str, tuple[str, ...]]) -> list[Path]:
    """One ``vidtrack eval`` per split and seed into ``ROOT/<split>/seed<S>``; returns the folders."""
    prov = provenance()
    folders = []
    for split in args.splits:
        if split not in splits:
            raise SystemExit(f"results_tables: unknown split {split!r}; valid splits: {', '.join(splits)}")
        for seed in args.seeds:
            out = Path(args.run) / split / f"seed{seed}"
            command = ["vidtrack", "eval", args.dataset, "--sequences", ",".join(splits[split]),
                       "--filter", args.filter, "--seed", str(seed), "--out", str(out), "--no-plots", "-q"]
            command += [a for s in args.set for a in ("--set", s)] + (["--config", args.config] if args.config else [])
            previous = json.loads((out / META).read_text()) if (out / META).is_file() else {}
            # resume only on the same code (git trees of vidtrack/ and pyproject.toml), committed and unchanged
            same = (prov["code"] is not None and previous.get("code") == prov["code"]
                    and not prov["dirty"] and not previous.get("dirty"))
            argv = command[1:] + ([] if same else ["--force"])
            meta = {"command": command, "seed": seed, "version": prov["version"], "commit": prov["commit"],
                    "dirty": prov["dirty"], "code": prov["code"], "cpus": os.cpu_count(), "load_start": round(os.getloadavg()[0], 2),
                    "started": _now()}
            out.mkdir(parents=True, exist_ok=True)
            (out / META).write_text(json.dumps(meta | {"status": "running"}, indent=2) + "\n")
            print(f"results_tables: {shlex.join(command)}", flush=True)
            code = subprocess.run([sys.executable, "-m", "vidtrack", *argv], env=prov["env"],
                                  stdout=subprocess.DEVNULL).returncode   # the tables are in OUT/summary.*
            if code == 2:
                raise SystemExit(f"results_tables: vidtrack eval rejected its input (exit 2): {shlex.join(command)}")
            meta |= {"finished": _now(), "load_end": round(os.getloadavg()[0], 2), "exit_code": code}
            (out / META).write_text(json.dumps(meta, indent=2) + "\n")
            folders.append(out)
    return folders


# ------------------------------------------------------------------ tables


def _fmt(value, digits: int) -> str:
    if value is None:
        return "–"
    if digits == 0:
        return f"{value:.0f}" if value >= 10 else f"{value:.1f}"
    return f"{value:.{digits}f}"


def _per_seed(values: list, digits: int, collapse: bool = True) -> str:
    cells = [_fmt(v, digits) for v in values]
    if collapse and len(set(cells)) == 1:
        return cells[0]
    return " / ".join(cells)


def _markdown(header: list[str], rows: list[list[str]], left: int = 1) -> str:
    rule = ["---"] * left + ["---:"] * (len(header) - left)
    return "\n".join("| " + " | ".join(r) + " |" for r in [header, rule, *rows])


def _date(meta: dict) -> str:
    return str(meta.get("finished") or meta.get("started") or "?")[:10]


def _caption(runs: list[dict], seeds: list) -> str:
    """The commands (seed and output folder written as S when only they differ), version, commit, date."""
    def general(run):
        cmd = list(run["meta"]["command"])
        for i, a in enumerate(cmd[:-1]):
            if a == "--seed":
                cmd[i + 1] = "S"
            if a == "--out":
                cmd[i + 1] = re.sub(r"seed\d+$", "seedS", cmd[i + 1])
        return shlex.join(cmd)

    if len(runs) == 1:
        commands, for_seeds = [shlex.join(runs[0]["meta"]["command"])], ""
    else:
        commands, for_seeds = list(dict.fromkeys(general(r) for r in runs)), f" for S = {', '.join(map(str, seeds))}"
    lines = [f"`{c}`" for c in commands]
    versions = sorted({f"vidtrack {r['meta'].get('version') or '(version not recorded)'}"
                       + (f", commit {r['meta']['commit']}" if r["meta"].get("commit") else "")
                       + (" with local changes" if r["meta"].get("dirty") else "") for r in runs})
    dates = sorted({_date(r["meta"]) for r in runs})
    text = ("Made by " + " and ".join(lines) + for_seeds + "; "
            + "; ".join(versions) + "; " + (dates[0] if len(dates) == 1 else f"{dates[0]} to {dates[-1]}") + ".")
    notes = sorted({r["meta"]["note"] for r in runs if r["meta"].get("note")})
    return text + ("".join(f" ({n}.)" for n in notes))


def split_section(split: str, runs: list[dict]) -> str:
    """The tables of one split: means, AUC per sequence, confidence."""
    seeds = sorted({r["seed"] for r in runs}, key=lambda s: (s is None, s))
    trackers = list(dict.fromkeys(t for r in runs for t in r["summary"]))
    sequences = list(dict.fromkeys(s for r in runs for s in r["sequences"]))

    def row(tracker, seed, sequence="mean"):
        for r in runs:
            if r["seed"] == seed and tracker in r["summary"]:
                return r["summary"][tracker].get(sequence, {})
        return {}

    def values(tracker, key, sequence="mean"):
        return [row(tracker, s, sequence).get(key) for s in seeds]

    caption = _caption(runs, seeds)
    means = []
    for t in trackers:
        auc = [v for v in values(t, "auc") if v is not None]
        failed = sum(len(row(t, s).get("failed") or []) for s in seeds)
        name = f"`{t}`" + (f" ({failed} failed job{'s' if failed > 1 else ''}: mean of the others)" if failed else "")
        means.append([name, _per_seed(values(t, "auc"), 3), _fmt(sum(auc) / len(auc), 3) if auc else "–",
                      _per_seed(values(t, "pascal"), 3), _per_seed(values(t, "precision20"), 3),
                      _per_seed(values(t, "fps"), 0, collapse=False)])
    per_sequence = []
    for q in sequences:
        cells = []
        for t in trackers:
            rows = [row(t, s, q) for s in seeds]
            cells.append("failed" if any("error" in r for r in rows) else _per_seed([r.get("auc") for r in rows], 3))
        per_sequence.append([q, *cells])
    per_sequence.append(["**mean**", *(_per_seed(values(t, "auc"), 3) for t in trackers)])
    confidence = []
    keys = ("lost_rate", "false_lost", "missed_loss", "confidence_auc", "ece")
    for t in trackers:
        confidence.append([f"`{t}`", *(_per_seed(values(t, k), 3) for k in keys)])
        flags = [row(t, s).get("ok_flag") for s in seeds]
        if any(isinstance(f, dict) for f in flags):
            confidence.append([f"`{t}` (OpenCV ok flag)",
                               *(_per_seed([(f or {}).get(k) for f in flags], 3) for k in keys)])
    seed_label = ("seed " if len(seeds) == 1 else "seeds ") + " / ".join(map(str, seeds))
    return "\n\n".join([
        f"## {split} ({len(sequences)} sequences)",
        f"### Mean over the sequences ({seed_label})",
        _markdown(["tracker", "AUC", "mean AUC", "PASCAL", "Prec@20", "fps"], means), caption,
        f"### Success AUC per sequence ({seed_label})",
        _markdown(["sequence", *(f"`{t}`" for t in trackers)], per_sequence), caption,
        f"### Confidence ({seed_label})",
        _markdown(["tracker", "lost", "false lost", "missed loss", "ROC AUC", "ECE"], confidence), caption,
    ])


def write_results(runs: list[dict], output: Path, splits: dict[str, tuple[str, ...]]) -> str:
    """Group ``runs`` by split (validate, then tune, then others) and write the Markdown to ``output``."""
    by_split: dict[str, list[dict]] = {}
    for r in runs:
        by_split.setdefault(r["split"], []).append(r)
    for split, members in by_split.items():
        seen = {}
        for r in members:
            for t in r["summary"]:
                key = (r["seed"], t)
                if key in seen:
                    raise SystemExit(f"results_tables: {t} at seed {r['seed']} on {split} is in both "
                                     f"{seen[key]} and {r['folder']}; give one of them")
                seen[key] = r["folder"]
    order = [s for s in ("validate", "tune") if s in by_split] + [s for s in by_split if s not in splits]
    cpus = sorted({r["meta"].get("cpus") for r in runs if r["meta"].get("cpus")})
    loads = [r["meta"][k] for r in runs for k in ("load_start", "load_end") if r["meta"].get(k) is not None]
    machine = (f" The runs were made one `vidtrack eval` process at a time on a machine with {cpus[0]} CPUs "
               f"(load average {min(loads):.1f} to {max(loads):.1f} at their starts and ends); fps is of that "
               "machine and load: compare it within a run." if len(cpus) == 1 and loads else
               " fps depends on the machine and its load: compare it within a run.")
    split_lines = [f"*{name}* ({len(members)}): {', '.join(members)}" for name, members in splits.items()]
    text = "\n\n".join([
        "# Measured results",
        "Written by `python scripts/results_tables.py` from `vidtrack eval` output folders (their "
        "`summary.json`); re-run the script rather than editing this file. Defaults are chosen on the *tune* "
        "split of the shared sequences and *validate* is reported, never tuned on "
        "(`../shared/data/sequences/INDEX.md`; what each tracker does: [trackers.md](trackers.md)).",
        "Splits: " + "; ".join(split_lines) + ".",
        METRIC_DOC + machine,
        "Confidence tables: " + CONFIDENCE_DOC,
        *(split_section(s, by_split[s]) for s in order),
    ]) + "\n"
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(text, encoding="utf-8")
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", help="vidtrack eval --out folders, or folders holding them")
    parser.add_argument("--run", metavar="ROOT", help="first run the evaluations into ROOT/<split>/seed<S>")
    parser.add_argument("--dataset", default=DEFAULT_DATASET, help=f"sequences folder (default {DEFAULT_DATASET})")
    parser.add_argument("--filter", default=DEFAULT_FILTERS, help=f"trackers to run (default {DEFAULT_FILTERS})")
    parser.add_argument("--splits", default="validate,tune", help="splits to run (default validate,tune)")
    parser.add_argument("--seeds", default="0,1,2", help="random seeds to run (default 0,1,2)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="passed to vidtrack eval (every listed tracker)")
    parser.add_argument("--config", metavar="FILE.toml", help="passed to vidtrack eval")
    parser.add_argument("--output", default=str(REPO / "docs" / "results.md"),
                        help="the Markdown file to write (default docs/results.md)")
    args = parser.parse_args(argv)
    args.splits = [s for s in args.splits.split(",") if s]
    args.seeds = [int(s) for s in args.seeds.split(",") if s]
    splits = read_splits(args.dataset)
    folders = list(args.folders)
    if args.run:
        folders += [str(f) for f in run_evaluations(args, splits)]
    if not folders:
        parser.error("give result folders, or --run ROOT")
    runs = find_runs(folders, splits)
    write_results(runs, Path(args.output), splits)
    print(f"results_tables: wrote {args.output} from {len(runs)} run folders")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
