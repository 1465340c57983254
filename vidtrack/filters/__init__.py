"""Filters: recursive (robust) estimators of the target box.

The package is also callable: ``vidtrack.filters()`` is :func:`vidtrack.api.filters`
(every registered tracker name with its description), so the Python API keeps
that name although this package holds it.
"""

import sys as _sys
import types as _types


class _CallablePackage(_types.ModuleType):
    def __call__(self) -> dict[str, str]:
        """Every registered filter name with its one-line description (:func:`vidtrack.api.filters`)."""
        from ..api import filters

        return filters()


_sys.modules[__name__].__class__ = _CallablePackage
