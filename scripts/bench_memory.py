#!/usr/bin/env python3
"""Peak memory of a tracking run against its length: vidtrack streams, so it should stay flat.

Runs ``vidtrack VIDEO --init-box BOX --filter NAME --max-frames N`` in a fresh
process for each N and prints the process's peak resident set size.

Usage::

    python scripts/bench_memory.py ../shared/data/sequences/Sylvester/img --init-box 122,51,51,61 \
        --filter kalman-cv --frames 100,1344
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile

CHILD = """
import resource, sys
from vidtrack.cli import main
code = main(sys.argv[1:])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
sys.exit(code)
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("video")
    parser.add_argument("--init-box", required=True)
    parser.add_argument("--filter", default="kalman-cv")
    parser.add_argument("--frames", default="50,500", help="comma-separated run lengths")
    args = parser.parse_args()
    print(f"{'frames':>8} {'peak RSS (MB)':>14}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(v) for v in args.frames.split(",")):
            result = subprocess.run([sys.executable, "-c", CHILD, args.video, "--init-box", args.init_box,
                                     "--filter", args.filter, "--max-frames", str(n), "--quiet",
                                     "--boxes", f"{tmp}/b.txt"], capture_output=True, text=True)
            if result.returncode != 0:
                print(result.stderr.strip(), file=sys.stderr)
                return result.returncode
            print(f"{n:>8} {int(result.stdout.split()[-1]) / 1024:>14.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
