"""Reproductions of the papers' tables: ``vidtrack reproduce NAME``.

Each experiment module exposes

* ``DESCRIPTION: str`` -- one line for ``vidtrack reproduce --list``;
* ``add_arguments(parser)`` -- its own options (``--runs``, ``--seed`` and
  ``--json`` are added by the CLI for every experiment);
* ``run(args, progress) -> dict`` -- runs it and returns the JSON-able result
  (``progress(iterable, total=..., desc=...)`` wraps loops in a progress bar);
* ``format_table(result) -> str`` -- the table printed like the paper's.

Experiments share the filters' code in :mod:`vidtrack.filters`; they never
keep a private copy of it.
"""

#: name -> module (imported on use, so a missing optional family never breaks the CLI).
EXPERIMENTS = {
    "svk-linear": "vidtrack.experiments.svk_tables",
    "svk-nonlinear": "vidtrack.experiments.svk_tables",
    "nh-1d": "vidtrack.experiments.nh_1d",
    "cbt-carlin": "vidtrack.experiments.cbt_carlin",
    "cbt-detections": "vidtrack.experiments.cbt_detections",
}
