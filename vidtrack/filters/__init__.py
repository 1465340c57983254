"""Filters: recursive (robust) estimators of the target box.

They never look at pixels (measurers do) and never import the layers above
them.  ``vidtrack.filters()``, the Python API's list of registered trackers,
is this package made callable by the root package (:mod:`vidtrack`).
"""
