"""Load YAML into a pydantic model with errors that name the field and the line (task and scene files).

Parsing and validation both happen before anything is returned, so a bad file loads nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from core.errors import StudioError

M = TypeVar("M", bound=BaseModel)

MAX_DEPTH = 50
"""Deepest nesting of lists and mappings a file may have (our files need 6). PyYAML's composer and
pydantic recurse once a level and hit Python's recursion limit near 300–500 levels, so deeper input is
refused from the event stream (which PyYAML parses without recursion) before either sees it."""


class FileFormatError(StudioError, ValueError):
    """A task or scene file that does not follow its schema; `problems` lists (field, line, message)."""

    def __init__(self, source: str, problems: list[tuple[str, int | None, str]]) -> None:
        self.source = source
        self.problems = problems
        lines = [f"{source}: {len(problems)} problem{'' if len(problems) == 1 else 's'}"]
        for field, line, msg in problems:
            where = f"line {line}" if line is not None else "line ?"
            lines.append(f"  {where}: {field or '<root>'}: {msg}")
        super().__init__("\n".join(lines))


def _mapping_child(node: yaml.MappingNode, key) -> tuple[yaml.Node, yaml.Node] | None:
    return next(((k, v) for k, v in node.value if getattr(k, "value", None) == str(key)), None)


def _locate(node: yaml.Node | None, loc: tuple, missing: bool = False) -> tuple[int | None, tuple]:
    """1-based line of the YAML node at pydantic location `loc`, and `loc` without union tags.

    pydantic puts a tagged union's tag (e.g. 'ee') into the location; it names no YAML key, so a key
    that is absent while the next one is present is skipped, and so is an absent last key unless the
    error is about a `missing` field.
    """
    line = node.start_mark.line + 1 if node is not None else None
    clean: list = []
    for i, key in enumerate(loc):
        if isinstance(node, yaml.MappingNode):
            found = _mapping_child(node, key)
            if found is None:
                nxt = loc[i + 1] if i + 1 < len(loc) else None
                if (nxt is not None and _mapping_child(node, nxt) is not None) or (nxt is None and not missing):
                    continue
                return line, (*clean, *loc[i:])
            key_node, node = found
            line = key_node.start_mark.line + 1
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            item: yaml.Node = node.value[key]
            node, line = item, item.start_mark.line + 1
        else:
            return line, (*clean, *loc[i:])
        clean.append(key)
    return line, tuple(clean)


def _too_deep_at(text: str) -> int | None:
    """1-based line where the nesting of `text` first exceeds `MAX_DEPTH` (aliases count as the depth of
    what they repeat), else None."""
    depth, anchors, open_anchors = 0, {}, []  # anchor → levels it spans; [anchor, start depth, deepest]
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        reached = depth
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            reached = depth
            if event.anchor:
                open_anchors.append([event.anchor, depth - 1, depth])
        elif isinstance(event, yaml.CollectionEndEvent):
            if open_anchors and open_anchors[-1][1] == depth - 1:
                anchor, start, deepest = open_anchors.pop()
                anchors[anchor] = deepest - start
            depth -= 1
        elif isinstance(event, yaml.AliasEvent):
            reached = depth + anchors.get(event.anchor, 0)
        for frame in open_anchors:
            frame[2] = max(frame[2], reached)
        if reached > MAX_DEPTH:
            return event.start_mark.line + 1
    return None
def line_of(text: str, field: str) -> int | None:
    """1-based line of the node at a dotted field (e.g. 'subtasks.1.target') in YAML text; None if unknown."""
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError:
        return None
    loc = tuple(int(k) if k.isdigit() else k for k in field.split(".")) if field else ()
    return _locate(root, loc, missing=True)[0]


def load_yaml_model(text: str, model: type[M], source: str = "<string>") -> M:
    """Parse YAML `text` and validate it as `model`; raise `FileFormatError` naming field and line."""
    try:
        too_deep = _too_deep_at(text)
        if too_deep is not None:
            raise FileFormatError(source, [("", too_deep, f"nested more than {MAX_DEPTH} levels deep")])
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except RecursionError as err:  # not expected after the depth check; refused all the same
        raise FileFormatError(source, [("", None, "nested too deeply to read")]) from err
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        raise FileFormatError(source, [("", line, f"not valid YAML: {getattr(err, 'problem', err)}")]) from err
    if data is None:
        raise FileFormatError(source, [("", 1, "the file is empty")])
    try:
        return model.model_validate(data)
    except RecursionError as err:
        raise FileFormatError(source, [("", None, "nested too deeply to validate")]) from err
    except ValidationError as err:
        problems = []
        for e in err.errors():
            loc = tuple(x for x in e["loc"] if not (isinstance(x, str) and x.startswith("function-")))
            line, loc = _locate(root, loc, missing=e["type"] == "missing")
            problems.append((".".join(str(x) for x in loc), line, e["msg"]))
        raise FileFormatError(source, problems) from err


def load_yaml_file(path: str | Path, model: type[M]) -> M:
    """Read and validate a YAML file; see `load_yaml_model`."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise FileFormatError(str(path), [("", None, f"cannot read: {err}")]) from err
    return load_yaml_model(text, model, source=str(path))


def dump_yaml_model(obj: BaseModel) -> str:
    """YAML text of a model (lists in flow style for short numeric vectors)."""
    return yaml.safe_dump(obj.model_dump(mode="json", exclude_none=True), sort_keys=False, default_flow_style=None)
