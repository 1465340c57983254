"""Tracker configuration: typed fields with docs, dotted keys, string and TOML values, one-line errors."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Literal

import pytest

from vidtrack.config import describe, option, parse_setting, read_toml, with_settings
from vidtrack.errors import UsageError
from vidtrack.recipes import build_tracker, recipe_config, registry
from vidtrack.types import Box


@dataclass(frozen=True)
class Inner:
    rate: float = option(0.5, "a rate")
    on: bool = option(True, "a switch")


@dataclass(frozen=True)
class Outer:
    size: int = option(3, "a count")
    mode: Literal["a", "b"] = option("a", "a choice")
    limit: float | None = option(None, "an optional number")
    pair: tuple[float, float] = option((1.0, 2.0), "two numbers")
    name: str = option("x", "a text")
    factors: tuple[float, ...] = option((1.0,), "any number of numbers")
    inner: Inner = option(Inner(), "a group")


def test_strings_convert_to_the_field_types():
    config = with_settings(Outer(), {"size": "7", "mode": "b", "limit": "0.25", "pair": "3,4", "name": "y",
                                     "inner.rate": "1e-3", "inner.on": "false"})
    assert config == Outer(size=7, mode="b", limit=0.25, pair=(3.0, 4.0), name="y", inner=Inner(rate=1e-3, on=False))
    assert with_settings(config, {"limit": "none"}).limit is None
    assert with_settings(config, {"factors": "0.9,1,1.1"}).factors == (0.9, 1.0, 1.1)
    assert with_settings(config, {"factors": [2]}).factors == (2.0,)


def test_python_values_and_whole_groups():
    config = with_settings(Outer(), {"size": 5, "inner": {"on": False}})
    assert config.size == 5 and config.inner == Inner(on=False)
    assert with_settings(Outer(), {"inner": Inner(rate=2.0)}).inner.rate == 2.0


@dataclass(frozen=True)
class Bounded:
    count: int = option(3, "at least 1", minimum=1)
    step: float = option(1.5, "more than 1", above=1.0)


def test_bounded_numbers_take_values_inside_and_reject_the_rest_in_one_line():
    config = with_settings(Bounded(), {"count": 1, "step": "1.0001"})
    assert (config.count, config.step) == (1, 1.0001)
    for settings, words in (({"count": 0}, ("count", "at least 1")), ({"step": "1"}, ("step", "more than 1"))):
        with pytest.raises(UsageError) as info:
            with_settings(Bounded(), settings)
        assert "\n" not in str(info.value) and all(word in str(info.value) for word in words)


def test_the_default_is_never_modified():
    default = Outer()
    with_settings(default, {"inner.rate": 9.0})
    assert default == Outer() and default.inner.rate == 0.5


@pytest.mark.parametrize("settings, words", [
    ({"nope": 1}, ["unknown option 'nope'", "inner.rate", "size"]),
    ({"inner.nope": 1}, ["unknown option 'inner.nope'"]),
    ({"size.x": 1}, ["unknown option 'size.x'"]),
    ({"size": "three"}, ["bad value", "size", "integer"]),
    ({"size": 2.5}, ["integer"]),
    ({"mode": "c"}, ["one of a, b"]),
    ({"inner.on": "maybe"}, ["true or false"]),
    ({"inner.rate": "nan"}, ["finite"]),
    ({"pair": "1"}, ["2 comma-separated"]),
    ({"inner": 3}, ["group"]),
])
def test_bad_settings_are_one_line_usage_errors(settings, words):
    with pytest.raises(UsageError) as info:
        with_settings(Outer(), settings)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message


def test_describe_lists_every_leaf_with_default_type_and_doc():
    rows = {key: (default, kind, doc) for key, default, kind, doc in describe(Outer())}
    assert list(rows) == ["size", "mode", "limit", "pair", "name", "factors", "inner.rate", "inner.on"]
    assert rows["factors"][:2] == ("1.0", "(float, ...)")
    assert rows["inner.on"] == ("true", "bool", "a switch")
    assert rows["limit"] == ("none", "float or none", "an optional number")
    assert rows["mode"][1] == "a|b"


def test_parse_setting():
    assert parse_setting(" fusion.redetect = false ") == ("fusion.redetect", "false")
    assert parse_setting("name=a=b") == ("name", "a=b")
    for bad in ("novalue", "=3"):
        with pytest.raises(UsageError):
            parse_setting(bad)


def test_toml_tables_are_groups(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text('size = 4\npair = [5, 6]\n[inner]\non = false\n')
    settings = read_toml(path)
    assert settings == {"size": 4, "pair": (5, 6), "inner.on": False}
    assert with_settings(Outer(), settings) == Outer(size=4, pair=(5.0, 6.0), inner=Inner(on=False))


@pytest.mark.parametrize("content", ["size = ", "[inner\n", None])
def test_bad_toml_files_are_usage_errors(tmp_path, content):
    path = tmp_path / "bad.toml"
    if content is not None:
        path.write_text(content)
    with pytest.raises(UsageError) as info:
        read_toml(path)
    assert str(path) in str(info.value)


def test_every_registered_config_is_frozen_and_documented():
    for name, recipe in registry().items():
        if recipe.config is None:
            continue
        rows = describe(recipe.config)
        assert rows, name
        for key, _default, _kind, doc in rows:
            assert doc.strip(), f"{name}: option {key} has no doc"
        top_level = fields(recipe.config)
        assert len(top_level) <= 20, f"{name} takes {len(top_level)} top-level options"
        with pytest.raises(AttributeError):
            setattr(recipe.config, top_level[0].name, None)


def test_settings_reach_the_built_tracker():
    tracker = build_tracker("svk", seed=0, settings={"svr.C": "0.5", "meanshift.bins": "8"})
    assert tracker.measurer.bins == 8
    assert tracker.filter.make_core(Box(10, 10, 20, 20)).C == 0.5   # the SVK core is built per box
    assert recipe_config("svk", {"svr.C": "0.5"}).svr.C == 0.5
    assert build_tracker("kalman-cv", seed=0, bins=4).measurer.bins == 4


def test_unknown_filter_and_option_name_the_valid_ones():
    with pytest.raises(UsageError, match="valid filters: .*kalman-cv"):
        build_tracker("nope")
    with pytest.raises(UsageError, match="valid options: .*meanshift.bins"):
        build_tracker("svk", settings={"bins": 3})
