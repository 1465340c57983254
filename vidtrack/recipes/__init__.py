"""The registry of trackers: a name users type (``--filter mil``) -> a :class:`~vidtrack.tracker.Recipe`.

One module per family, each exposing a plain dict ``RECIPES``; :func:`registry`
merges them.  A recipe's ``config`` is its family's frozen configuration
(:mod:`vidtrack.config`); :func:`build_tracker` applies the caller's settings
to it and builds the tracker.
"""

from __future__ import annotations

from typing import Any, Mapping

from ..config import with_settings
from ..errors import UsageError
from ..tracker import Recipe, Tracker

__all__ = ["Recipe", "registry", "build_tracker", "recipe_config"]

_REGISTRY: dict[str, Recipe] | None = None


def registry() -> dict[str, Recipe]:
    """All registered recipes by name (the family modules are imported on first use)."""
    global _REGISTRY
    if _REGISTRY is None:
        from . import channels, classic, mil, normalhedge, opencv, svk

        merged: dict[str, Recipe] = {}
        for module in (classic, opencv, svk, normalhedge, channels, mil):
            merged.update(module.RECIPES)
        _REGISTRY = merged
    return _REGISTRY


def _recipe(name: str) -> Recipe:
    recipes = registry()
    if name not in recipes:
        raise UsageError(f"unknown filter {name!r}; valid filters: {', '.join(sorted(recipes))}")
    return recipes[name]


def recipe_config(name: str, settings: Mapping[str, Any] | None = None) -> Any:
    """The configuration of the tracker registered as ``name`` with ``settings`` (dotted key -> value) applied.

    Raises
    ------
    UsageError
        For an unknown name (the message lists the valid ones), an unknown
        option (listing the valid ones) or a value of the wrong type.
    """
    recipe = _recipe(name)
    settings = dict(settings or {})
    if recipe.config is None:
        if settings:
            raise UsageError(f"filter {name} takes no options, got {', '.join(sorted(settings))}")
        return None
    return with_settings(recipe.config, settings)


def build_tracker(name: str, *, seed: int | None = None, settings: Mapping[str, Any] | None = None,
                  **options: Any) -> Tracker:
    """Build the tracker registered as ``name``, its configuration changed by ``settings`` and ``options``.

    ``settings`` maps dotted keys (``fusion.redetect``) to values or strings;
    ``options`` are top-level fields given as keywords (a group as a mapping).

    Raises
    ------
    UsageError
        For an unknown name, an unknown option or a bad value (one line naming the valid ones).
    """
    config = recipe_config(name, {**(settings or {}), **options})
    tracker = _recipe(name).build(config, seed=seed)
    tracker.name = name
    return tracker
