"""The import graph of ``sandbox/`` and ``web/``, read with ``ast`` (nothing is imported).

Rules (docs/style.md, "Import direction"):
- no import cycle among ``sandbox`` modules, counting function-level imports too: a lazy
  import only hides a circle until the day someone moves it to the top of the file;
- ``sandbox`` never imports ``web``, viser or the tests;
- ``web`` imports only the ``sandbox`` package itself, and only names its ``__all__`` lists.

An edge follows Python's own semantics: ``from .a import b`` in ``pkg.m`` imports ``pkg.a.b``
when that is a module, else ``pkg.a``. Importing ``pkg.a.b`` also runs ``pkg.a``'s
``__init__``, an edge too, unless ``pkg.a`` is a package the importer itself lives in (Python
has started that package before the importer), so ``from . import x`` inside a package's
``__init__``, or a submodule importing its siblings, is no cycle.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FORBIDDEN_IN_SANDBOX = ("web", "viser", "tests")


@pytest.fixture(scope="session")
def taichi_cpu():
    """Overrides conftest's autouse fixture: this file reads source only and needs no Taichi."""
    return None


@dataclass(frozen=True)
class Edge:
    source: str  # importing module, dotted
    target: str  # imported module (dotted, for ours) or top-level name (for a third party)
    line: int
    names: tuple[str, ...] = ()  # the names a `from X import ...` takes from a module


class ImportGraph:
    def __init__(self, root: Path, packages=("sandbox", "web")):
        self.root = root
        self.files: dict[str, Path] = {}
        for pkg in packages:
            for path in sorted((root / pkg).rglob("*.py")):
                parts = path.relative_to(root).with_suffix("").parts
                if parts[-1] == "__init__":
                    parts = parts[:-1]
                self.files[".".join(parts)] = path
        self.ours = {m.split(".")[0] for m in self.files}  # top-level names of the packages read
        self.edges: list[Edge] = []
        for module, path in self.files.items():
            self.edges += self._edges_of(module, path)

    def is_package(self, module: str) -> bool:
        return self.files.get(module, Path()).name == "__init__.py"

    def _edges_of(self, module: str, path: Path) -> list[Edge]:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        package = module if self.is_package(module) else module.rpartition(".")[0]
        edges = []
        for node in _runtime_nodes(tree):  # every depth: function-level imports count
            if isinstance(node, ast.Import):
                for alias in node.names:
                    edges += self._resolve(module, alias.name, (), node.lineno)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module
                submodules = [f"{target}.{a.name}" for a in node.names if f"{target}.{a.name}" in self.files]
                names = tuple(a.name for a in node.names if f"{target}.{a.name}" not in self.files)
                for sub in submodules:
                    edges += self._resolve(module, sub, (), node.lineno)
                if names or not submodules:
                    edges += self._resolve(module, target, names, node.lineno)
        return edges

    def _resolve(self, source: str, target: str, names: tuple, line: int) -> list[Edge]:
        """The edge to ``target`` and to each package on its way the importer is not inside."""
        if target.split(".")[0] not in self.ours:
            return [Edge(source, target.split(".")[0], line, names)]  # third party / stdlib
        edges = []
        parts = target.split(".")
        for depth in range(1, len(parts) + 1):
            step = ".".join(parts[:depth])
            inside = source == step or source.startswith(step + ".")
            if step != target and (inside or step not in self.files):
                continue
            if step == source:
                continue
            edges.append(Edge(source, step, line, names if step == target else ()))
        return edges

    def cycles(self, prefix: str) -> list[list[str]]:
        """The import cycles among modules under ``prefix``: for every import that closes a
        cycle, the shortest cycle through it (start, ..., start; rotated to start at its
        smallest name, duplicates dropped), so each import to cut is named at least once."""
        mine = [m for m in self.files if m == prefix or m.startswith(prefix + ".")]
        succ = {m: sorted({e.target for e in self.edges if e.source == m and e.target in mine}) for m in mine}
        found = set()
        for component in _strongly_connected(mine, succ):
            inner = {m: [t for t in succ[m] if t in component] for m in component}
            for source in component:
                for target in inner[source]:
                    loop = [source] + _shortest_path(target, source, inner)
                    turn = loop.index(min(loop))
                    found.add(tuple(loop[turn:] + loop[:turn] + [min(loop)]))
        return sorted(list(c) for c in found)

    def edge_lines(self, source: str, target: str) -> list[int]:
        return sorted({e.line for e in self.edges if e.source == source and e.target == target})


def _runtime_nodes(tree: ast.AST):
    """Every statement at any depth (imports are statements, so expressions are skipped, which
    keeps the walk fast), except the bodies of ``if TYPE_CHECKING:`` (never executed)."""
    pending = [tree]
    while pending:
        node = pending.pop()
        yield node
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            pending += node.orelse
            continue
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            children = getattr(node, field, None)
            if isinstance(children, list):
                pending += children


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _strongly_connected(nodes, succ) -> list[set]:
    """Tarjan's algorithm, iterative (no recursion limit on a deep chain)."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(succ[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.add(member)
                        if member == node:
                            break
                    out.append(component)
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(succ[child])))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return out


def _shortest_path(start: str, goal: str, succ) -> list[str]:
    """Breadth-first: start, ..., goal, without goal's repeat (empty when start is goal)."""
    if start == goal:
        return []
    previous, frontier = {start: None}, [start]
    while frontier:
        following = []
        for node in frontier:
            for child in succ[node]:
                if child in previous:
                    continue
                previous[child] = node
                if child == goal:
                    path = [node]
                    while previous[path[-1]] is not None:
                        path.append(previous[path[-1]])
                    return path[::-1]
                following.append(child)
        frontier = following
    raise AssertionError(f"no path from {start} to {goal} inside a strongly connected set")


def describe_cycle(graph: ImportGraph, cycle: list[str]) -> str:
    hops = []
    for source, target in zip(cycle, cycle[1:]):
        path = graph.files[source].relative_to(graph.root)
        lines = ",".join(str(n) for n in graph.edge_lines(source, target))
        hops.append(f"    {source} -> {target}  ({path}:{lines})")
    return " -> ".join(cycle) + "\n" + "\n".join(hops)


def public_names(graph: ImportGraph, package: str) -> set[str]:
    """The names listed in ``__all__`` of ``package``'s ``__init__.py``."""
    tree = ast.parse(graph.files[package].read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            return set(ast.literal_eval(node.value))
    raise AssertionError(f"{graph.files[package]} has no __all__")


def web_violations(graph: ImportGraph) -> list[str]:
    exported = public_names(graph, "sandbox")
    problems = []
    web_edges = sorted((e for e in graph.edges if e.source == "web" or e.source.startswith("web.")),
                       key=lambda e: (e.source, e.line, e.target))
    for e in web_edges:
        if any(o.line == e.line and o.source == e.source and o.target.startswith(e.target + ".") for o in web_edges):
            continue  # the package an import runs on its way to a deeper module: named once, by the deeper one
        where = f"{graph.files[e.source].relative_to(graph.root)}:{e.line}"
        if e.target.startswith("sandbox."):
            problems.append(f"{where}: imports {e.target} (use `from sandbox import ...`)")
        elif e.target == "sandbox":
            for name in e.names:
                if name not in exported:
                    problems.append(f"{where}: `from sandbox import {name}`: {name} is not in sandbox.__all__")
    return problems


@pytest.fixture(scope="module")
def graph() -> ImportGraph:
    return ImportGraph(ROOT)


def test_no_import_cycle_in_sandbox(graph):
    cycles = graph.cycles("sandbox")
    assert not cycles, f"{len(cycles)} import cycle(s) in sandbox/:\n" + "\n".join(
        describe_cycle(graph, c) for c in cycles)


def test_sandbox_never_imports_web_viser_or_tests(graph):
    bad = [f"{graph.files[e.source].relative_to(ROOT)}:{e.line}: imports {e.target}" for e in graph.edges
           if e.source.startswith("sandbox") and e.target.split(".")[0] in FORBIDDEN_IN_SANDBOX]
    assert not bad, "\n".join(bad)


def test_web_uses_only_the_sandbox_package_public_names(graph):
    problems = web_violations(graph)
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------------- the walker itself


def _tree(tmp_path: Path, files: dict[str, str]) -> ImportGraph:
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return ImportGraph(tmp_path, packages=("sandbox", "web"))


def test_a_package_init_importing_its_own_submodules_is_no_cycle(tmp_path):
    """Nor is an import only a type checker reads."""
    g = _tree(tmp_path, {
        "sandbox/__init__.py": "from .scene import Scene\n",
        "sandbox/errors.py": "",
        "sandbox/scene/__init__.py": "from . import spec\nfrom .loader import load\nfrom .spec import Scene\n",
        "sandbox/scene/spec.py": "from ..errors import E\nfrom . import rotations\n",
        "sandbox/scene/loader.py": "from .spec import Scene\nfrom sandbox.scene.rotations import q\n",
        "sandbox/scene/rotations.py": "import typing\nimport numpy as np\n"
                                      "if typing.TYPE_CHECKING:\n    from .loader import Loader\n",
        "web/__init__.py": "",
    })
    assert g.cycles("sandbox") == []
    pairs = {(e.source, e.target) for e in g.edges}
    assert ("sandbox.scene.spec", "sandbox.errors") in pairs
    assert ("sandbox.scene", "sandbox.scene.spec") in pairs
    assert not any(e.target == "sandbox.scene" for e in g.edges if e.source.startswith("sandbox.scene."))


def test_function_level_and_relative_cycles_are_named(tmp_path):
    g = _tree(tmp_path, {
        "sandbox/__init__.py": "",
        "sandbox/backend.py": "def pin():\n    from .solvers.team import x\n",
        "sandbox/solvers/__init__.py": "",
        "sandbox/solvers/team.py": "from .. import backend\n",
        "sandbox/a.py": "import sandbox.b\n",
        "sandbox/b.py": "from sandbox import c\n",
        "sandbox/c.py": "def f():\n    import sandbox.a\n",
        "web/__init__.py": "",
    })
    assert g.cycles("sandbox") == [["sandbox.a", "sandbox.b", "sandbox.c", "sandbox.a"],
                                   ["sandbox.backend", "sandbox.solvers.team", "sandbox.backend"]]
    assert "sandbox/backend.py:2" in describe_cycle(g, g.cycles("sandbox")[1])


def test_importing_a_package_from_outside_runs_its_init(tmp_path):
    """world -> scene.spec also runs scene/__init__, which imports world back: a real cycle."""
    g = _tree(tmp_path, {
        "sandbox/__init__.py": "",
        "sandbox/world.py": "from .scene.spec import Scene\n",
        "sandbox/scene/__init__.py": "from .loader import load\n",
        "sandbox/scene/spec.py": "",
        "sandbox/scene/loader.py": "def load():\n    from ..world import World\n",
        "web/__init__.py": "",
    })
    assert g.cycles("sandbox") == [["sandbox.scene", "sandbox.scene.loader", "sandbox.world", "sandbox.scene"]]


def test_web_may_take_only_exported_names_from_the_top_level(tmp_path):
    g = _tree(tmp_path, {
        "sandbox/__init__.py": "__all__ = ['Scene']\n",
        "sandbox/backend.py": "",
        "sandbox/scene/__init__.py": "",
        "sandbox/scene/spec.py": "",
        "web/__init__.py": "",
        "web/ok.py": "from sandbox import Scene\nimport sandbox\nfrom .other import x\n",
        "web/other.py": "from sandbox import backend, Scene\nfrom sandbox.scene import spec\n"
                        "import sandbox.scene\nfrom sandbox import World\n"
                        "def later():\n    from sandbox.scene.spec import Scene\n",
    })
    assert web_violations(g) == [
        "web/other.py:1: imports sandbox.backend (use `from sandbox import ...`)",
        "web/other.py:2: imports sandbox.scene.spec (use `from sandbox import ...`)",
        "web/other.py:3: imports sandbox.scene (use `from sandbox import ...`)",
        "web/other.py:4: `from sandbox import World`: World is not in sandbox.__all__",
        "web/other.py:6: imports sandbox.scene.spec (use `from sandbox import ...`)",
    ]
