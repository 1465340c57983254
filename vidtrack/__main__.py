"""``python -m vidtrack``: the ``vidtrack`` command (:func:`vidtrack.cli.main`)."""

import sys

from .cli import main

sys.exit(main())
