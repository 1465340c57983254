"""Imported once by the evaluation's fork server, so each job's fresh process starts warm.

Only imports (and the tracker registry): no tracker runs here, so every forked
job still starts with pristine library state.
"""

import tqdm  # noqa: F401  (the command line's progress bar, which jobs may carry)

from ..run import run_tracker  # noqa: F401
from ..sources import open_source  # noqa: F401
from .jobs import run_job  # noqa: F401

try:
    from ..recipes import registry

    registry()
except Exception:  # a broken recipe module must not take the fork server down; the job will report it
    pass
