"""Tracker recipes by family; each module exposes a plain dict ``RECIPES``.

See :data:`vidtrack.tracker.RECIPE_MODULES` for the modules merged into the
registry.
"""
