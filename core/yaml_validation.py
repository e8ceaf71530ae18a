"""Load YAML into a pydantic model with errors that name the field and the line (task and scene files).

Parsing and validation both happen before anything is returned, so a bad file loads nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

M = TypeVar("M", bound=BaseModel)


class FileFormatError(ValueError):
    """A task or scene file that does not follow its schema; `problems` lists (field, line, message)."""

    def __init__(self, source: str, problems: list[tuple[str, int | None, str]]) -> None:
        self.source = source
        self.problems = problems
        lines = [f"{source}: {len(problems)} problem(s)"]
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
            node, line = found[1], found[0].start_mark.line + 1
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
            line = node.start_mark.line + 1
        else:
            return line, (*clean, *loc[i:])
        clean.append(key)
    return line, tuple(clean)


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
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        raise FileFormatError(source, [("", line, f"not valid YAML: {getattr(err, 'problem', err)}")]) from err
    if data is None:
        raise FileFormatError(source, [("", 1, "the file is empty")])
    try:
        return model.model_validate(data)
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
