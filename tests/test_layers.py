"""The layer rules of docs/design.md ("Layers"), checked on the import graph of the source tree.

app → tasks → core, never back; inside core the controller, the map and the simulator never import one
another and the robot model imports none of them; the UI reads snapshots, never the solver or the map; the
bridge works without a browser. Every import counts, including those inside functions.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
PACKAGES = ("core", "tasks", "app", "bench")

NEVER = [
    ("core", "app", "core knows no application, screen or server"),
    ("core", "tasks", "core knows no task sequences"),
    ("core", "bench", "core knows no benchmarks"),
    ("tasks", "app", "tasks know no application"),
    ("tasks", "bench", "tasks know no benchmarks"),
    ("app", "bench", "the application knows no benchmarks"),
    ("core.robot", "core.htmpc", "the robot model knows no controller"),
    ("core.robot", "core.mapping", "the robot model knows no map"),
    ("core.robot", "core.sim", "the robot model knows no simulator"),
    ("core.htmpc", "core.mapping", "the controller sees a map only as a distance field"),
    ("core.htmpc", "core.sim", "the controller never reads the simulator"),
    ("core.mapping", "core.htmpc", "the map knows no controller"),
    ("core.mapping", "core.sim", "the map sees depth frames, never ground truth"),
    ("core.sim", "core.htmpc", "the simulator knows no controller"),
    ("core.sim", "core.mapping", "the simulator knows no map"),
    ("core.mapping", "core.localization", "the map exposes a reference surface, it never imports localization"),
    ("core.htmpc", "core.localization", "the controller sees only the state the loop re-posed"),
    ("core.localization", "core.mapping", "localization reads the map's ReferenceSurface only"),
    ("core.localization", "core.htmpc", "localization knows no controller"),
    ("core.localization", "core.sim", "localization never reads ground truth"),
    ("core.types", "core.", "the shared data types import no other core module"),
    ("app.ui", "core.htmpc", "the UI reads runtime snapshots only"),
    ("app.ui", "core.mapping", "the UI reads runtime snapshots only"),
    ("app.bridge", "app.ui", "the bridge works without a browser"),
    ("app.runtime", "app.ui", "the runtime publishes snapshots; it knows no screen"),
    ("app.runtime", "app.bridge", "the runtime drives any backend; it knows no server"),
    ("app.runtime", "app.recording", "recordings subscribe to the runtime, never back"),
    ("app.runtime", "app.cli", "the runtime knows no command line"),
    ("app.runtime", "app.foxglove_live", "the Foxglove server subscribes to the runtime, never back"),
    ("app.recording", "app.bridge", "recordings know no server"),
    ("app.recording", "app.cli", "recordings know no command line"),
]
"""(importing module prefix, imported module prefix, why not); a prefix ending in '.' means any module
below it."""


def _module_of(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, imported module or name) of every import in the file, relative ones resolved."""
    module, is_package = _module_of(path), path.name == "__init__.py"
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = module.split(".") if is_package else module.split(".")[:-1]
                package = package[: len(package) - (node.level - 1)]
                base = ".".join([*package, *([base] if base else [])])
            found += [(node.lineno, f"{base}.{alias.name}" if base else alias.name) for alias in node.names]
    return found


def _within(name: str, prefix: str) -> bool:
    if prefix.endswith("."):
        return name.startswith(prefix)
    return name == prefix or name.startswith(prefix + ".")


def import_graph() -> dict[str, list[tuple[int, str]]]:
    """Module → its imports, over the project's packages."""
    return {_module_of(path): _imports(path) for package in PACKAGES for path in sorted((ROOT / package).rglob("*.py"))}


@pytest.fixture(scope="module")
def graph() -> dict[str, list[tuple[int, str]]]:
    return import_graph()


def test_the_graph_covers_the_tree(graph):
    assert len(graph) > 100
    assert any(_within(name, "core.htmpc") for _, name in graph["app.runtime.components"])
    assert any(_within(name, "core.mapping") for _, name in graph["core.mapping.object_mapper"])


def test_no_import_crosses_a_layer(graph):
    crossings = [f"{module}:{line} imports {name}: {why}"
                 for module, imports in graph.items() for line, name in imports
                 for src, dst, why in NEVER if _within(module, src) and _within(name, dst)]
    assert not crossings, "\n".join(crossings)


APP_MODULES_ALLOWED = {
    "app.runtime": ("app.runtime", "app.map_kind", "app.object_label", "app.object_names", "app.target_check",
                    "app.thread_priority"),
    "app.recording": ("app.recording", "app.runtime", "app.object_label", "app.ui.colors"),
}
"""docs/design.md's layer table: the only modules of `app/` that the runtime and the recordings import."""


@pytest.mark.parametrize("package", sorted(APP_MODULES_ALLOWED))
def test_the_runtime_and_recordings_import_only_the_app_modules_the_table_names(graph, package):
    allowed = APP_MODULES_ALLOWED[package]
    beyond = sorted(f"{module}:{line} imports {name}" for module, imports in graph.items() if _within(module, package)
                    for line, name in imports
                    if _within(name, "app") and not any(_within(name, prefix) for prefix in allowed))
    assert not beyond, "\n".join(beyond)


@pytest.mark.parametrize(("module", "name", "crosses"), [
    ("core.htmpc.htmpc", "core.mapping.local_edf", True),
    ("core.htmpc.htmpc", "core.robot.model", False),
    ("core.types", "core.params", True),
    ("core.types", "numpy", False),
    ("app.ui.map_view", "core.mapping", True),
    ("app.ui.map_view", "core.params.MappingParams", False),
    ("tasks.sequencer", "app.runtime", True),
    ("app.runtime.closed_loop", "app.object_names.ObjectNames", False),
    ("app.runtime.live_loops", "app.recording.recorder", True),
])
def test_the_rules_tell_a_crossing_from_a_permitted_import(module, name, crosses):
    assert any(_within(module, src) and _within(name, dst) for src, dst, _ in NEVER) == crosses
