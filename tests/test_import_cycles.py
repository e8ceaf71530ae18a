"""No import cycle anywhere in the source tree (docs/design.md, "Layers"): every module can be read, and
imported, after the modules it needs. Every import counts, those under `TYPE_CHECKING` and inside functions
included: a cycle hidden there is still two modules that cannot be understood one without the other."""

import pytest

from tests.test_layers import import_graph


def _module_edges(graph: dict[str, list[tuple[int, str]]]) -> dict[str, set[str]]:
    """Module → the project modules it imports (an imported name resolves to the module that holds it)."""
    def resolve(name: str) -> str | None:
        parts = name.split(".")
        for n in range(len(parts), 0, -1):
            if ".".join(parts[:n]) in graph:
                return ".".join(parts[:n])
        return None

    return {module: {m for _, name in imports if (m := resolve(name)) not in (None, module)}
            for module, imports in graph.items()}


def find_cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan's algorithm), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return cycles


@pytest.fixture(scope="module")
def edges() -> dict[str, set[str]]:
    return _module_edges(import_graph())


def test_no_module_imports_itself_back(edges):
    cycles = find_cycles(edges)
    assert not cycles, "import cycles: " + "; ".join(" ↔ ".join(c) for c in cycles)


def test_a_cycle_is_found_where_there_is_one():
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert find_cycles({"a": {"b"}, "b": set()}) == []


def test_an_imported_name_resolves_to_its_module():
    graph = {"pkg": [(1, "pkg.mod.Thing")], "pkg.mod": [(1, "pkg.Other"), (2, "numpy")]}
    assert _module_edges(graph) == {"pkg": {"pkg.mod"}, "pkg.mod": {"pkg"}}
