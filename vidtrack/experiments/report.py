"""``vidtrack reproduce all --out DIR``: every experiment, one report.

Runs each experiment of :data:`vidtrack.experiments.EXPERIMENTS` with its
defaults (``--runs`` as in :data:`RUNS`), each with its own progress bar, and
writes into ``DIR``:

* ``report.md`` -- opens with a table of every claim of the papers and
  whether vidtrack's run shows it, then each experiment's table (vidtrack's
  value, the paper's and the relative difference in every cell) and its
  figures;
* ``<experiment>.json`` -- each experiment's full result (the same JSON as
  ``vidtrack reproduce NAME --json``, with ``vs_paper`` and ``claims``);
* the figures as PNG: NormalHedge Figs. 2-3, SVK's trajectories (Fig. 4 and
  the non-linear motion), Carlin's truth vs estimates.
"""

from __future__ import annotations

import argparse
import importlib
import json
import time
from pathlib import Path

from ..errors import UsageError
from . import EXPERIMENTS

DESCRIPTION = "Run every experiment; write DIR/report.md (claims table first), the JSONs and the PNG figures"

#: Runs per experiment in the report (None: the experiment's own default).
RUNS = {"svk-linear": None, "svk-nonlinear": None, "nh-1d": None, "cbt-carlin": None, "cbt-detections": 5}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="DIR", required=True, help="directory for report.md, the JSONs and the PNGs")
    parser.add_argument("--seed", type=int, default=0, help="random seed of every experiment (default 0)")
    parser.add_argument("--only", metavar="NAMES", default=None,
                        help=f"comma-separated subset of the experiments (default all: {', '.join(EXPERIMENTS)})")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars")


def experiment_args(name: str, module, *, seed: int, out_dir: Path) -> argparse.Namespace:
    """The experiment's default options (as ``vidtrack reproduce NAME`` would parse them), set for the report."""
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--runs", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None)
    parser.add_argument("-q", "--quiet", action="store_true")
    module.add_arguments(parser)
    args = parser.parse_args([])
    args.experiment, args.seed, args.runs = name, seed, RUNS.get(name)
    args.figure_dir = str(out_dir)
    if name == "nh-1d":
        args.plot = str(out_dir / "nh-1d-figs2-3.png")
    if name.startswith("svk-"):
        args.imm_variants = True
    return args


def run_all(args: argparse.Namespace, progress) -> Path:
    """Run the experiments, write the JSONs and ``report.md``; returns the report's path."""
    names = list(EXPERIMENTS) if not args.only else [n.strip() for n in args.only.split(",") if n.strip()]
    unknown = [n for n in names if n not in EXPERIMENTS]
    if unknown or not names:
        raise UsageError(f"unknown experiment(s) {', '.join(unknown) or '(none)'}; valid: {', '.join(EXPERIMENTS)}")
    out_dir = Path(args.out)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create {out_dir}: {exc.strerror or exc}") from None
    sections = []
    for name in names:
        module = importlib.import_module(EXPERIMENTS[name])
        exp_args = experiment_args(name, module, seed=args.seed, out_dir=out_dir)
        start = time.perf_counter()
        result = module.run(exp_args, progress)
        seconds = time.perf_counter() - start
        (out_dir / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
        figures = list(result.get("figures", [])) + ([result["plot"]] if result.get("plot") else [])
        sections.append({"name": name, "description": module.DESCRIPTION, "table": module.format_table(result),
                         "claims": result.get("claims", []), "figures": figures, "seconds": seconds,
                         "runs": result.get("runs")})
    path = out_dir / "report.md"
    path.write_text(render(sections, seed=args.seed))
    return path


def render(sections: list[dict], *, seed: int) -> str:
    """The Markdown report: the claims table first, then each experiment's table and figures."""
    claims = [(s["name"], c) for s in sections for c in s["claims"]]
    held = sum(c["holds"] for _, c in claims)
    lines = ["# vidtrack reproduce all", "",
             f"Every experiment at its defaults (cbt-detections with 5 runs, the SVK tables with --imm-variants), "
             f"seed {seed}; vidtrack's figures come from this run, the papers' values are typed from their tables "
             "(the targets).", "",
             f"## Claims: {held} of {len(claims)} hold", "",
             "| experiment | claim | holds | vidtrack |", "|---|---|---|---|"]
    for name, c in claims:
        lines.append(f"| {name} | {_md(c['claim'])} | {'yes' if c['holds'] else '**no**'} | {_md(c['detail'])} |")
    lines.append("")
    total = sum(s["seconds"] for s in sections)
    lines.append(f"Run time: {total:.0f} s (" + ", ".join(f"{s['name']} {s['seconds']:.0f} s" for s in sections) + ").")
    for s in sections:
        lines += ["", f"## {s['name']}", "", s["description"], "", "```", s["table"], "```"]
        for fig in s["figures"]:
            rel = Path(fig).name
            lines += ["", f"![{s['name']}: {rel}]({rel})"]
    return "\n".join(lines) + "\n"


def _md(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")
