"""Tracker configuration: frozen dataclasses with a one-line doc per field, set by dotted keys.

Every tracker family declares its options as a frozen dataclass whose fields
are made with :func:`option` (a default and a one-line doc).  A tracker with
parts groups them: a field whose default is itself such a dataclass is a
*group*, addressed with a dotted key (``fusion.redetect``).  A named variant
of a tracker is a preset: the same dataclass with other values, registered
under its own name (:mod:`vidtrack.recipes`).

Settings arrive as Python values (``vidtrack.create("mil", lam=2.5)``), as
strings from the command line (``--set fusion.redetect=false``) or as TOML
values (``--config FILE.toml``); :func:`with_settings` checks the key, converts
the value to the field's type and returns a new config.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Iterator, Mapping

from .errors import UsageError

__all__ = ["option", "with_settings", "describe", "flat_items", "read_toml", "parse_setting"]

_NONE_WORDS = {"none", "null"}
_TRUE_WORDS = {"true", "yes", "on", "1"}
_FALSE_WORDS = {"false", "no", "off", "0"}


def option(default: Any, doc: str, *, minimum: float | None = None, above: float | None = None) -> Any:
    """A dataclass field with ``default`` and its one-line ``doc`` (shown by ``vidtrack filters NAME``).

    A group (a nested config dataclass) is given as its default instance.
    ``minimum`` (the value may equal it) and ``above`` (it must exceed it)
    bound a number: a setting outside is a one-line :class:`UsageError`.
    """
    if dataclasses.is_dataclass(default) and not isinstance(default, type):
        return dataclasses.field(default_factory=lambda: default, metadata={"doc": doc})
    return dataclasses.field(default=default, metadata={"doc": doc, "minimum": minimum, "above": above})


def redefault(config_class: type, name: str, default: Any) -> Any:
    """The field ``name`` of the config dataclass ``config_class`` with a new ``default``, its doc and bounds kept.

    For a subclass that differs from its parent in a few defaults.
    """
    metadata = config_class.__dataclass_fields__[name].metadata
    return option(default, metadata["doc"], minimum=metadata.get("minimum"), above=metadata.get("above"))


def _check_bounds(value: Any, metadata: Mapping) -> None:
    """Raise ValueError when the number ``value`` is under the field's ``minimum`` or not above its ``above``."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return
    if metadata.get("minimum") is not None and value < metadata["minimum"]:
        raise ValueError(f"expected at least {metadata['minimum']:g}")
    if metadata.get("above") is not None and value <= metadata["above"]:
        raise ValueError(f"expected more than {metadata['above']:g}")


def _is_group(value: Any) -> bool:
    return dataclasses.is_dataclass(value) and not isinstance(value, type)


def _hints(config: Any) -> dict[str, Any]:
    return typing.get_type_hints(type(config))


def flat_items(config: Any, prefix: str = "") -> Iterator[tuple[str, Any, Any, str]]:
    """``(dotted key, value, type, doc)`` for every leaf field of ``config``, groups expanded in order."""
    hints = _hints(config)
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        key = prefix + f.name
        if _is_group(value):
            yield from flat_items(value, key + ".")
        else:
            yield key, value, hints[f.name], f.metadata.get("doc", "")


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return "|".join(str(a) for a in typing.get_args(tp))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if origin is tuple:
        return "(" + ", ".join("..." if a is Ellipsis else _type_name(a) for a in typing.get_args(tp)) + ")"
    if tp is type(None):
        return "none"
    return getattr(tp, "__name__", str(tp))


def _format_value(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        return ",".join(_format_value(v) for v in value)
    return str(value)


def describe(config: Any) -> list[tuple[str, str, str, str]]:
    """``(key, default as text, type as text, doc)`` of every field, for ``vidtrack filters NAME``."""
    return [(key, _format_value(value), _type_name(tp), doc) for key, value, tp, doc in flat_items(config)]


def _convert(value: Any, tp: Any, key: str) -> Any:
    """``value`` (a Python value or a string) as type ``tp``; raises ValueError with the reason."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(tp)
        if type(None) in options and (value is None or (isinstance(value, str) and value.lower() in _NONE_WORDS)):
            return None
        errors = []
        for choice in (a for a in options if a is not type(None)):
            try:
                return _convert(value, choice, key)
            except ValueError as exc:
                errors.append(str(exc))
        raise ValueError("; ".join(errors))
    if origin is typing.Literal:
        choices = typing.get_args(tp)
        for choice in choices:
            if value == choice or (isinstance(value, str) and value == str(choice)):
                return choice
        raise ValueError(f"expected one of {', '.join(str(c) for c in choices)}")
    if origin is tuple:
        parts = value.split(",") if isinstance(value, str) else list(value)
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:   # tuple[X, ...]: any number of X
            args = (args[0],) * len(parts)
            if not parts:
                raise ValueError("expected at least one value")
        if len(parts) != len(args):
            raise ValueError(f"expected {len(args)} comma-separated values")
        return tuple(_convert(p.strip() if isinstance(p, str) else p, a, key) for p, a in zip(parts, args, strict=True))
    if tp is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in _TRUE_WORDS | _FALSE_WORDS:
            return value.lower() in _TRUE_WORDS
        raise ValueError("expected true or false")
    if tp is int:
        if isinstance(value, bool):
            raise ValueError("expected an integer")
        if isinstance(value, int):
            return value
        if isinstance(value, float) and value.is_integer():
            return int(value)
        if isinstance(value, str):
            try:
                return int(value)
            except ValueError:
                pass
        raise ValueError("expected an integer")
    if tp is float:
        if isinstance(value, bool):
            raise ValueError("expected a number")
        try:
            result = float(value)
        except (TypeError, ValueError):
            raise ValueError("expected a number") from None
        if not math.isfinite(result):
            raise ValueError("expected a finite number")
        return result
    if tp is str:
        if isinstance(value, str):
            return value
        raise ValueError("expected a string")
    if isinstance(value, tp):
        return value
    raise ValueError(f"expected {_type_name(tp)}")


def _set(config: Any, path: list[str], value: Any, full_key: str, valid: list[str]) -> Any:
    names = {f.name for f in dataclasses.fields(config)}
    head = path[0]
    if head not in names:
        raise UsageError(f"unknown option {full_key!r}; valid options: {', '.join(valid)}")
    current = getattr(config, head)
    if _is_group(current):
        if len(path) == 1:
            if isinstance(value, Mapping):
                for sub_key, sub_value in value.items():
                    current = _set(current, [*str(sub_key).split(".")], sub_value, f"{full_key}.{sub_key}", valid)
                return dataclasses.replace(config, **{head: current})
            if isinstance(value, type(current)):
                return dataclasses.replace(config, **{head: value})
            raise UsageError(f"option {full_key!r} is a group: set its fields ({full_key}.NAME=VALUE)")
        return dataclasses.replace(config, **{head: _set(current, path[1:], value, full_key, valid)})
    if len(path) > 1:
        raise UsageError(f"unknown option {full_key!r}; valid options: {', '.join(valid)}")
    tp = _hints(config)[head]
    try:
        converted = _convert(value, tp, full_key)
        _check_bounds(converted, next(f for f in dataclasses.fields(config) if f.name == head).metadata)
    except ValueError as exc:
        raise UsageError(f"bad value {value!r} for option {full_key} ({_type_name(tp)}): {exc}") from None
    return dataclasses.replace(config, **{head: converted})


def with_settings(config: Any, settings: Mapping[str, Any]) -> Any:
    """A copy of ``config`` with ``settings`` (dotted key -> value) applied in order.

    Values may be Python values or strings (``"false"``, ``"0.5"``, ``"none"``,
    ``"1,2"`` for a pair); a group may be set as a whole from a mapping or an
    instance of its dataclass.

    Raises
    ------
    UsageError
        For an unknown key (the message lists the valid ones) or a value that
        does not convert to the field's type.
    """
    valid = [key for key, *_ in flat_items(config)]
    for key, value in settings.items():
        config = _set(config, str(key).split("."), value, str(key), valid)
    return config


def parse_setting(text: str) -> tuple[str, str]:
    """``"KEY=VALUE"`` -> ``(KEY, VALUE)``, both stripped (``--set``).

    Raises
    ------
    UsageError
        When there is no ``=`` or no key.
    """
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise UsageError(f"--set takes KEY=VALUE (e.g. fusion.redetect=false), got {text!r}")
    return key.strip(), value.strip()


def _flatten(table: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in table.items():
        if isinstance(value, Mapping):
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = tuple(value) if isinstance(value, list) else value
    return flat


def read_toml(path: str | Path) -> dict[str, Any]:
    """The settings of a TOML file as dotted keys (tables are groups: ``[fusion]`` then ``redetect = false``).

    Raises
    ------
    UsageError
        For a missing or unreadable file or invalid TOML (the message names the file and the line).
    """
    try:
        with open(path, "rb") as handle:
            table = tomllib.load(handle)
    except FileNotFoundError:
        raise UsageError(f"--config: no such file: {path}") from None
    except IsADirectoryError:
        raise UsageError(f"--config: {path} is a folder, not a TOML file") from None
    except OSError as exc:
        raise UsageError(f"--config: cannot read {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UsageError(f"--config: {path} is not valid TOML: {exc}") from None
    return _flatten(table)
