"""YAML nested deeper than any of our files is refused with its line, before PyYAML or pydantic recurse."""

from __future__ import annotations

import pytest

from core.scene import parse_scene
from core.yaml_validation import MAX_DEPTH, FileFormatError
from tasks.sequence_file import parse_sequence


def _lists(depth: int) -> str:
    return "[" * depth + "]" * depth


def _mappings(depth: int) -> str:
    return "{a: " * depth + "1" + "}" * depth


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 500, 5000])
@pytest.mark.parametrize("parse", [parse_sequence, parse_scene])
def test_deep_nesting_is_refused_with_a_line(parse, depth: int) -> None:
    for text in (f"name: x\nsubtasks: {_lists(depth)}\n", f"name: x\nboxes: {_mappings(depth)}\n"):
        with pytest.raises(FileFormatError, match="nested more than") as err:
            parse(text)
        assert err.value.problems[0][1] is not None


def test_aliases_count_as_the_depth_they_repeat() -> None:
    """An alias inside a deep list repeats its anchor's levels: 40 + 30 levels is too deep."""
    text = f"name: x\na: &a {_lists(40)}\nb: {'[' * 30}*a{']' * 30}\nsubtasks: []\n"
    with pytest.raises(FileFormatError, match="nested more than") as err:
        parse_sequence(text)
    assert err.value.problems[0][1] == 3


def test_ordinary_nesting_still_reaches_the_schema() -> None:
    """Shallow files go on to the schema, whose errors keep their field and line."""
    with pytest.raises(FileFormatError, match="Extra inputs") as err:
        parse_sequence(f"name: x\nsubtasks: []\nextra: {_lists(MAX_DEPTH - 1)}\n")
    assert err.value.problems[0][:2] == ("extra", 3)


def test_the_count_of_problems_reads_as_english() -> None:
    """'1 problem', '2 problems' (it read '1 problem(s)')."""
    one = FileFormatError("f.yaml", [("a", 1, "bad")])
    two = FileFormatError("f.yaml", [("a", 1, "bad"), ("b", 2, "bad")])
    assert str(one).splitlines()[0] == "f.yaml: 1 problem"
    assert str(two).splitlines()[0] == "f.yaml: 2 problems"
