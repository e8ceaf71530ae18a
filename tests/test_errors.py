"""One exception root (docs/design.md, "Errors"): every exception class the project defines derives from
`StudioError`, and no code raises a bare `RuntimeError`."""

import ast
import importlib
from pathlib import Path

import pytest

from core.errors import NotSupportedError, StudioError

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "tasks", "app")


def _sources() -> list[Path]:
    files = [f for pkg in PACKAGES for f in sorted((ROOT / pkg).rglob("*.py"))]
    assert len(files) > 100, "the source tree was not found"
    return files


def _exception_classes() -> list[tuple[str, str]]:
    """(module, class) of every class whose name ends in Error or Exception."""
    found = []
    for f in _sources():
        module = ".".join(f.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ClassDef) and node.name.endswith(("Error", "Exception")):
                found.append((module, node.name))
    return found


def test_every_project_error_derives_from_the_root():
    classes = _exception_classes()
    assert len(classes) >= 15
    outside = [f"{m}.{c}" for m, c in classes if not issubclass(getattr(importlib.import_module(m), c), StudioError)]
    assert outside == [], f"errors outside StudioError: {outside}"


def test_no_bare_runtime_error_is_raised():
    bare = []
    for f in _sources():
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call) and \
                    isinstance(node.exc.func, ast.Name) and node.exc.func.id == "RuntimeError":
                bare.append(f"{f.relative_to(ROOT)}:{node.lineno}")
    assert bare == [], f"bare RuntimeError raised at {bare}"


def test_the_root_keeps_the_standard_bases_callers_catch():
    from app.runtime import FaultError
    from core.yaml_validation import FileFormatError

    assert issubclass(FileFormatError, ValueError) and issubclass(FaultError, RuntimeError)
    assert issubclass(NotSupportedError, RuntimeError)
    with pytest.raises(StudioError):
        raise FileFormatError("x.yaml", [("field", 3, "bad")])
