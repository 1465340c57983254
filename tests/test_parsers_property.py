"""Property-based tests of the one box parser and its users: ``--init-box`` and ground-truth / result files.

Whatever the text, :meth:`vidtrack.types.Box.parse` returns a box or raises
ValueError, :func:`vidtrack.cli.common.parse_init_box` returns a valid box or
raises :class:`UsageError`, and :func:`vidtrack.eval.datasets.parse_boxes`
returns the rows or raises :class:`DatasetError`: never another exception.
Rows written with any of the separators and line ends found in the wild
(commas, tabs, spaces, CRLF, a byte-order mark, blank lines) read back exactly,
and the command line, the API and the datasets read the same text alike.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings, strategies as st

from vidtrack.api import as_box
from vidtrack.cli.common import join_negative_values, parse_init_box as parse_box
from vidtrack.errors import DatasetError, UsageError
from vidtrack.eval.datasets import parse_boxes, read_boxes
from vidtrack.types import Box

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
positive = st.floats(min_value=1e-3, max_value=1e6, allow_nan=False, allow_infinity=False)
any_float = st.floats(allow_nan=True, allow_infinity=True)
separators = st.sampled_from([",", ", ", " ", "\t", "  ", ",\t", ";"])
line_ends = st.sampled_from(["\n", "\r\n"])

SETTINGS = settings(max_examples=150, deadline=None, database=None)  # no .hypothesis/ folder


@SETTINGS
@given(x=finite, y=finite, w=positive, h=positive, sep=st.sampled_from([",", ", ", " "]))
def test_init_box_round_trips(x, y, w, h, sep):
    box = parse_box(sep.join(repr(v) for v in (x, y, w, h)))
    assert box.as_array().tolist() == [x, y, w, h]


@SETTINGS
@given(st.text(max_size=40))
def test_init_box_any_text_is_a_box_or_a_usage_error(text):
    try:
        box = parse_box(text)
    except UsageError as exc:
        assert "\n" not in str(exc)
    else:
        assert box.is_valid()


@SETTINGS
@given(values=st.lists(any_float, min_size=0, max_size=7))
def test_init_box_needs_four_finite_numbers_with_positive_size(values):
    text = ",".join(repr(v) for v in values)
    good = len(values) == 4 and all(math.isfinite(v) for v in values) and values[2] > 0 and values[3] > 0
    try:
        parse_box(text)
        assert good
    except UsageError:
        assert not good


@SETTINGS
@given(st.text(max_size=40))
def test_box_parse_any_text_is_a_box_or_a_value_error(text):
    try:
        box = Box.parse(text)
    except ValueError as exc:
        assert "\n" not in str(exc)
    else:
        assert isinstance(box, Box)


@SETTINGS
@given(values=st.lists(st.one_of(finite, st.just(float("nan"))), min_size=4, max_size=4), sep=separators)
def test_cli_api_and_datasets_read_one_row_alike(values, sep):
    text = sep.join(repr(v) for v in values)
    row = parse_boxes(text)[0]
    np.testing.assert_array_equal(Box.parse(text).as_array(), row)
    valid = all(math.isfinite(v) for v in values) and values[2] > 0 and values[3] > 0
    for parse in (parse_box, as_box):
        if valid:
            assert parse(text) == Box(*values)
        else:
            try:
                parse(text)
            except UsageError:
                pass
            else:
                raise AssertionError(f"{parse.__name__} accepted {text!r}")


@SETTINGS
@given(x=st.floats(min_value=-1e4, max_value=-1e-3), rest=st.lists(positive, min_size=3, max_size=3))
def test_negative_box_value_needs_no_equals_sign(x, rest):
    value = ",".join(repr(v) for v in (x, *rest))
    assert join_negative_values(["v.mp4", "--init-box", value, "-q"]) == ["v.mp4", f"--init-box={value}", "-q"]


rows_strategy = st.lists(st.lists(st.one_of(finite, st.just(float("nan")), st.just(float("inf")),
                                            st.just(-float("inf"))), min_size=4, max_size=4),
                         min_size=0, max_size=12)


def _file_text(rows, sep, end, bom, blank_every):
    lines = []
    for index, row in enumerate(rows):
        if blank_every and index % blank_every == 0:
            lines.append("   " if index % 2 else "")
        lines.append(sep.join(repr(v) for v in row))
    return ("\ufeff" if bom else "") + end.join(lines) + (end if lines else "")


@SETTINGS
@given(rows=rows_strategy, sep=separators, end=line_ends, bom=st.booleans(), blank_every=st.integers(0, 4))
def test_ground_truth_rows_read_back_exactly(rows, sep, end, bom, blank_every):
    parsed = parse_boxes(_file_text(rows, sep, end, bom, blank_every))
    np.testing.assert_array_equal(parsed, np.array(rows, dtype=float).reshape(-1, 4))


@SETTINGS
@given(rows=rows_strategy, sep=separators, end=line_ends, bom=st.booleans())
def test_ground_truth_file_with_bom_and_crlf(tmp_path_factory, rows, sep, end, bom):
    path = tmp_path_factory.mktemp("gt") / "groundtruth_rect.txt"
    path.write_bytes(_file_text(rows, sep, end, bom, 0).encode("utf-8"))
    np.testing.assert_array_equal(read_boxes(path), np.array(rows, dtype=float).reshape(-1, 4))


@SETTINGS
@given(good=st.lists(st.lists(finite, min_size=4, max_size=4), max_size=5),
       bad=st.lists(finite, min_size=0, max_size=9).filter(lambda r: len(r) not in (0, 4)),
       where=st.integers(0, 5))
def test_wrong_field_count_names_its_line(good, bad, where):
    rows = [",".join(repr(v) for v in row) for row in good]
    where = min(where, len(rows))
    rows.insert(where, ",".join(repr(v) for v in bad))
    try:
        parse_boxes("\n".join(rows))
    except DatasetError as exc:
        assert f"line {where + 1}:" in str(exc)
    else:
        raise AssertionError("a row without four numbers was accepted")


@SETTINGS
@given(st.text(max_size=200))
def test_any_text_is_rows_or_a_dataset_error(text):
    try:
        rows = parse_boxes(text)
    except DatasetError as exc:
        assert "\n" not in str(exc)
    else:
        assert rows.ndim == 2 and rows.shape[1] == 4
