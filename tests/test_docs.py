"""The repository explains itself: no tracked file points to documents outside it, and every function and
test that docs/method.md names exists, so the method's map of equations → code → tests cannot rot."""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
METHOD_DOC = ROOT / "docs" / "method.md"

OUTSIDE = re.compile("|".join([
    r"\.\./" + "shared",
    "/work/" + "shared",
    r"\b(?:METHOD|DESIGN|FACTS|BENCH)" + r"\.md\b",  # the planning documents that a clone does not have
]))
"""References to documents outside the repository (split so that this file does not match itself)."""

CODE_REF = re.compile(r"`((?:core|tasks|app|bench)(?:\.\w+)+):([A-Za-z_][\w.]*)`")
"""`package.module:name` or `package.module:Class.method`."""
TEST_REF = re.compile(r"`(tests/[\w/]+\.py)::(\w+)`")


def tracked_files() -> list[Path]:
    """The files git tracks (a fresh clone's content); every file under the root when git is unavailable."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        return [ROOT / name for name in out.decode().split("\0") if name]
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", "__pycache__", "node_modules"}
        return [p for p in ROOT.rglob("*") if p.is_file() and not skip.intersection(p.relative_to(ROOT).parts)]


def test_no_tracked_file_points_outside_the_repository() -> None:
    found = []
    for path in tracked_files():
        if not path.is_file():  # deleted in the work tree, not yet committed
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:  # images
            continue
        for number, line in enumerate(text.splitlines(), start=1):
            if OUTSIDE.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "references outside the repository (use docs/*.md):\n" + "\n".join(found)


def test_the_outside_pattern_catches_what_it_should() -> None:
    outside = ("see ../" + "shared/x", "/work/" + "shared/y", "DESIGN" + ".md, Layout", "(FACTS" + ".md)",
               "BENCH" + ".md asks")
    for text in outside:
        assert OUTSIDE.search(text), text
    for text in ("docs/method.md", "docs/design.md", "test_removal_latency_matches_method_md"):
        assert not OUTSIDE.search(text), text


def method_doc() -> str:
    return METHOD_DOC.read_text(encoding="utf-8")


def test_method_doc_cites_code_and_tests() -> None:
    """The map is not empty: every section names implementers and tests (the parsing below finds them)."""
    assert len(CODE_REF.findall(method_doc())) >= 40
    assert len(TEST_REF.findall(method_doc())) >= 40


@pytest.mark.parametrize("module, name", sorted(set(CODE_REF.findall(method_doc()))))
def test_every_cited_function_exists(module: str, name: str) -> None:
    obj = importlib.import_module(module)
    for part in name.split("."):
        assert hasattr(obj, part), f"{module}:{name}: no attribute {part!r}"
        obj = getattr(obj, part)


@cache
def _test_functions(path: str) -> frozenset[str]:
    tree = ast.parse((ROOT / path).read_text(encoding="utf-8"))
    return frozenset(node.name for node in ast.walk(tree)
                     if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name.startswith("test_"))


POINTER = re.compile(r'docs/(method|design|decisions)\.md\)?,? \(?"([^"]+)"')
"""A pointer into a section: docs/decisions.md, "Removal speed" (the quoted words begin a heading)."""


def pointers() -> list[tuple[str, str, str]]:
    """(file, document, section) of every section pointer in the tracked text files."""
    out = []
    for path in tracked_files():
        if path.suffix not in (".py", ".md") or not path.is_file():
            continue
        flat = " ".join(path.read_text(encoding="utf-8").replace("#", " ").split())
        out += [(str(path.relative_to(ROOT)), doc, section) for doc, section in POINTER.findall(flat)]
    return out


@cache
def headings(doc: str) -> tuple[str, ...]:
    text = (ROOT / "docs" / f"{doc}.md").read_text(encoding="utf-8")
    return tuple(line.lstrip("#").strip() for line in text.splitlines() if line.startswith("#"))


def test_section_pointers_name_existing_sections() -> None:
    found = pointers()
    assert len(found) >= 20  # the docstrings do point into the docs
    broken = [f"{where}: docs/{doc}.md has no section {section!r}" for where, doc, section in found
              if not any(h.startswith(section) for h in headings(doc))]
    assert not broken, "\n".join(broken)


@pytest.mark.parametrize("path, name", sorted(set(TEST_REF.findall(method_doc()))))
def test_every_cited_test_exists(path: str, name: str) -> None:
    assert (ROOT / path).is_file(), f"{path} does not exist"
    assert name in _test_functions(path), f"{path} defines no {name}"
