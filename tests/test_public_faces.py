"""The packages' public faces (issue 24): every name a package's `__init__` lists in `__all__` is there, and the
names code imported from `app.runtime` before it became a package still are."""

import importlib

import pytest

FACES = ("app.runtime", "app.recording", "core.htmpc", "core.mapping", "core.sim", "tasks")

NAMES_FROM_THE_OLD_RUNTIME_MODULE = ("CONSTRAINT_KINDS", "DEFAULT_SCENE", "DEFAULT_SEQUENCE", "MAP_KINDS", "ROOT",
                                     "Runtime", "RuntimeConfig")
"""Every name a `from app.runtime import …` in the tree imported when `app/runtime.py` was one module (f07417a)."""


@pytest.mark.parametrize("package", FACES)
def test_every_public_name_resolves(package):
    module = importlib.import_module(package)
    assert module.__all__, f"{package} exports nothing"
    missing = [name for name in module.__all__ if getattr(module, name, None) is None]
    assert not missing, f"{package}.__all__ names what it does not hold: {missing}"


def test_the_old_runtime_imports_keep_working():
    runtime = importlib.import_module("app.runtime")
    assert set(NAMES_FROM_THE_OLD_RUNTIME_MODULE) <= set(runtime.__all__)
    from app.runtime import RuntimeConfig  # the import itself is what is tested

    assert RuntimeConfig().speed > 0
