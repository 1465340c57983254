"""Fingerprint what vidtrack computes: SHA-256 of result files, to show that a change moves no box.

Runs every registered tracker (``vidtrack filters``) with ``vidtrack eval`` on a few shared
sequences at one random seed, and ``vidtrack reproduce all``, then prints and writes the SHA-256
of every result file (``<filter>/<Sequence>.txt``) and of every experiment's JSON table (with its
timing fields removed, the only part of it that varies from run to run)::

    python scripts/behaviour_hashes.py ../shared/data/sequences --write before.json
    ...  # change the code
    python scripts/behaviour_hashes.py ../shared/data/sequences --check before.json

``--keep DIR`` keeps the outputs; ``--rehash DIR`` hashes kept outputs again without running anything.
``--check`` exits 1 and names every result whose hash differs; trackers or experiments present on
one side only are listed, not counted as differences.  The default sequences are two of the *tune*
split and two of *validate*, short ones so a full run takes a few minutes.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

DEFAULT_SEQUENCES = "Football1,Man,Crossing,Human8"

#: Keys of an experiment's JSON that hold wall-clock times (dropped before hashing).
TIMING_KEY = re.compile(r"seconds|elapsed|runtime|fps|(^|_)time(_|$)|(^|_)ms(_|$)")


def vidtrack(*args: str) -> subprocess.CompletedProcess:
    """Run ``python -m vidtrack ARGS`` with this interpreter; stop on failure."""
    result = subprocess.run([sys.executable, "-m", "vidtrack", *args], capture_output=True, text=True)
    if result.returncode not in (0,):
        sys.exit(f"behaviour_hashes: vidtrack {' '.join(args)} exited {result.returncode}: "
                 f"{result.stderr.strip().splitlines()[-1:] or ''}")
    return result


def registered_filters() -> list[str]:
    """Every tracker name ``vidtrack filters`` lists (the first word of each line)."""
    lines = vidtrack("filters").stdout.splitlines()
    return [line.split()[0] for line in lines if line.strip() and not line.startswith(" ")]


def without_timing(value, folder: str = ""):
    """``value`` (parsed JSON) without its timing fields and with paths into ``folder`` made relative, recursively."""
    if isinstance(value, dict):
        return {k: without_timing(v, folder) for k, v in value.items() if not TIMING_KEY.search(k)}
    if isinstance(value, list):
        return [without_timing(v, folder) for v in value]
    if folder and isinstance(value, str) and value.startswith(folder):
        return value[len(folder):].lstrip("/")
    return value


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def hash_outputs(folder: Path) -> dict[str, str]:
    """The hashes of the result files under ``folder/eval`` and the JSON tables under ``folder/reproduce``."""
    hashes: dict[str, str] = {}
    for path in sorted((folder / "eval").glob("*/*.txt")):
        hashes[f"eval/{path.parent.name}/{path.name}"] = sha256(path.read_bytes())
    tables = folder / "reproduce"
    for path in sorted(tables.glob("*.json")):
        content = without_timing(json.loads(path.read_text()), str(tables))
        hashes[f"reproduce/{path.name}"] = sha256(json.dumps(content, sort_keys=True).encode())
    return hashes


def fingerprint(dataset: str, sequences: str, seed: int, jobs: int, keep: str | None = None) -> dict[str, str]:
    """``{"eval/<filter>/<Sequence>.txt": sha, "reproduce/<name>.json": sha}`` from fresh runs (kept in ``keep``)."""
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(keep or scratch)
        vidtrack("eval", dataset, "--sequences", sequences, "--filter", ",".join(registered_filters()),
                 "--seed", str(seed), "--out", str(folder / "eval"), "--jobs", str(jobs), "--no-plots", "-q")
        vidtrack("reproduce", "all", "--out", str(folder / "reproduce"), "--seed", str(seed), "-q")
        return hash_outputs(folder)


def compare(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """Lines naming every result that changed, appeared or disappeared."""
    lines = [f"changed: {key}" for key in sorted(before.keys() & after.keys()) if before[key] != after[key]]
    lines += [f"only before: {key}" for key in sorted(before.keys() - after.keys())]
    lines += [f"only after: {key}" for key in sorted(after.keys() - before.keys())]
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", nargs="?", help="folder of sequence folders (e.g. ../shared/data/sequences)")
    parser.add_argument("--sequences", default=DEFAULT_SEQUENCES, help=f"default {DEFAULT_SEQUENCES}")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--keep", metavar="DIR", help="keep the eval results and the JSON tables in DIR")
    parser.add_argument("--rehash", metavar="DIR", help="run nothing: hash the outputs an earlier --keep DIR holds")
    target = parser.add_mutually_exclusive_group(required=True)
    target.add_argument("--write", metavar="FILE.json", help="write the hashes to FILE")
    target.add_argument("--check", metavar="FILE.json", help="compare with the hashes in FILE; exit 1 on a change")
    args = parser.parse_args()
    if args.rehash:
        hashes = hash_outputs(Path(args.rehash))
    elif args.dataset:
        hashes = fingerprint(args.dataset, args.sequences, args.seed, args.jobs, args.keep)
    else:
        parser.error("give DATASET (or --rehash DIR)")
    for key, value in hashes.items():
        print(f"{value}  {key}")
    if args.write:
        Path(args.write).write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")
        return 0
    report = compare(json.loads(Path(args.check).read_text()), hashes)
    changed = [line for line in report if line.startswith("changed")]
    print("\n".join(report) or "every result identical")
    print(f"{len(hashes)} results, {len(changed)} changed", file=sys.stderr)
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
