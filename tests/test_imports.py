"""No module of impact_fenics imports one that imports it back, at any depth.

Every ``import`` and ``from ... import`` of every module under impact_fenics/ counts,
at the top of the module and inside functions, classes and ``if`` blocks alike (an
import inside a function runs the first time the function is called: it still ties
the two modules together). The graph has an edge M -> T for each module T of the
package that an import in M brings in, resolved as Python resolves it:

* a relative import is resolved against M's package (M itself for an ``__init__``);
* ``from P import x`` imports P and, where x is a submodule of P, the submodule x
  (``from . import fused`` is an import of ``contact.fused``); a name that is not a
  submodule is taken from P's ``__init__``, so it counts as importing P;
* importing P.Q runs the ``__init__`` of every package on the way (P, then P.Q) that
  is not already a package M lives in (those are initialised before M's first line);
  a package is its ``__init__``.

The graph must be acyclic: no strongly connected component of more than one module
and no module importing itself. A failure names one cycle, each edge with the file
and line of its import. Pure file checks: the same on every rank.
"""
from __future__ import annotations

import ast
import os
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "impact_fenics"

# cycles allowed on purpose, as frozensets of module names, each with the reason it cannot
# be avoided: none
ALLOWED_CYCLES: dict[frozenset[str], str] = {}


def package_modules(root: str = ROOT, package: str = PACKAGE) -> dict[str, str]:
    """{dotted module name: file path} of every module of ``package`` (a package is its
    ``__init__.py``)."""
    modules = {}
    for folder, dirs, files in os.walk(os.path.join(root, package)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        rel = os.path.relpath(folder, root).split(os.sep)
        for name in sorted(files):
            if name.endswith(".py"):
                parts = rel if name == "__init__.py" else rel + [name[:-3]]
                modules[".".join(parts)] = os.path.join(folder, name)
    return modules


def _is_package(path: str) -> bool:
    return os.path.basename(path) == "__init__.py"


def _resolve(level: int, target: str | None, module: str, path: str) -> str:
    """The absolute name of a (possibly relative) import's module in ``module``."""
    if level == 0:
        return target or ""
    parts = module.split(".")
    if not _is_package(path):
        parts = parts[:-1]  # a module's package
    if level > 1:
        parts = parts[:len(parts) - (level - 1)]
    return ".".join(parts + ([target] if target else []))


def _with_packages(name: str, module: str, modules: dict[str, str]) -> list[str]:
    """The modules of the package that importing ``name`` from ``module`` runs: every
    package on the way to it that ``module`` does not live in, then ``name`` itself."""
    parts = name.split(".")
    own = module.split(".")
    if not _is_package(modules[module]):
        own = own[:-1]  # the packages module lives in: own[:1], own[:2], ..., own
    out = []
    for k in range(1, len(parts) + 1):
        prefix = ".".join(parts[:k])
        if prefix not in modules:
            continue
        lives_in = k <= len(own) and parts[:k] == own[:k]
        if prefix == name or not lives_in:
            out.append(prefix)
    return out


def import_edges(modules: dict[str, str]) -> tuple[dict[str, dict[str, int]], list[str]]:
    """({module: {imported module of the package: line of the first such import}},
    the imports that name no module of the package, as "module:line name")."""
    edges: dict[str, dict[str, int]] = defaultdict(dict)
    unresolved: list[str] = []
    for module, path in modules.items():
        with open(path, encoding="utf-8") as f:
            tree = ast.parse(f.read(), filename=path)
        for node in ast.walk(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(node.level, node.module, module, path)
                targets = [base]
                for alias in node.names:
                    sub = f"{base}.{alias.name}"
                    if sub in modules:
                        targets.append(sub)
                if base in modules and _is_package(modules[base]) and all(
                        f"{base}.{alias.name}" in modules for alias in node.names):
                    targets = targets[1:]  # only submodules: the package's names are not read
            else:
                continue
            for target in targets:
                if target != PACKAGE and not target.startswith(PACKAGE + "."):
                    continue
                if target not in modules:
                    unresolved.append(f"{module}:{node.lineno} {target}")
                    continue
                for imported in _with_packages(target, module, modules):
                    edges[module].setdefault(imported, node.lineno)
    return edges, unresolved


def strongly_connected(graph: dict[str, set[str] | dict[str, int]]) -> list[list[str]]:
    """Tarjan's strongly connected components of ``graph`` (node -> successors), each
    sorted, in no particular order."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    nodes = set(graph) | {t for succ in graph.values() for t in succ}

    for start in sorted(nodes):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for nxt in successors:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph.get(nxt, ())))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        top = stack.pop()
                        on_stack.discard(top)
                        component.append(top)
                        if top == node:
                            break
                    out.append(sorted(component))
    return out


def cycles(graph: dict[str, set[str] | dict[str, int]]) -> list[list[str]]:
    """The cyclic components of ``graph``: more than one node, or one node with an edge
    to itself."""
    return [c for c in strongly_connected(graph)
            if len(c) > 1 or c[0] in graph.get(c[0], ())]


def one_cycle(graph: dict[str, set[str] | dict[str, int]], component: list[str]) -> list[str]:
    """A closed path a -> ... -> a through the first node of a cyclic ``component``
    (the shortest, by breadth-first search inside the component)."""
    inside = set(component)
    start = component[0]
    parent: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt_frontier = []
        for node in frontier:
            for nxt in sorted(graph.get(node, ())):
                if nxt == start:
                    path = [node]  # back from node to start by the parents, then reversed
                    while path[-1] != start:
                        path.append(parent[path[-1]])
                    return path[::-1] + [start]
                if nxt in inside and nxt not in parent:
                    parent[nxt] = node
                    nxt_frontier.append(nxt)
        frontier = nxt_frontier
    raise AssertionError(f"{component} is not cyclic")


# ------------------------------------------------------------------ the finder itself

def test_the_cycle_finder_finds_a_known_cycle_and_passes_a_dag():
    dag = {"a": {"b", "c"}, "b": {"d"}, "c": {"d"}, "d": set()}
    assert cycles(dag) == []
    assert sorted(map(tuple, strongly_connected(dag))) == [("a",), ("b",), ("c",), ("d",)]
    ring = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"e"}}
    found = sorted(map(tuple, cycles(ring)))
    assert found == [("a", "b", "c"), ("e",)]
    assert one_cycle(ring, ["a", "b", "c"]) == ["a", "b", "c", "a"]
    assert one_cycle(ring, ["e"]) == ["e", "e"]


def test_imports_resolve_as_python_resolves_them(tmp_path):
    """A small package on disk: relative imports, a submodule named in ``from . import``,
    a name of a package's ``__init__``, an absolute import inside a function (which runs
    the ``__init__`` of the package on the way) all give edges; an import of a module
    that is not there is reported, not dropped."""
    pkg = tmp_path / PACKAGE
    (pkg / "sub").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "top.py": "import os\nfrom .sub import thing\n",
        "sub/__init__.py": "from .low import thing\n",
        "sub/low.py": "def f():\n    from . import high\n",
        "sub/high.py": "from .. import top\nfrom . import low\nfrom .gone import x\n",
        "other.py": f"def g():\n    import {PACKAGE}.sub.low\n",
    }
    for rel, text in files.items():
        (pkg / rel).write_text(text)
    modules = package_modules(str(tmp_path))
    found_edges, unresolved = import_edges(modules)
    assert unresolved == [f"{PACKAGE}.sub.high:3 {PACKAGE}.sub.gone"]  # refused, not dropped
    edges = {m: set(e) for m, e in found_edges.items()}
    p = PACKAGE
    assert edges == {
        f"{p}.top": {f"{p}.sub"},  # a name of sub's __init__: sub, not os
        f"{p}.sub": {f"{p}.sub.low"},
        f"{p}.sub.low": {f"{p}.sub.high"},  # inside a function, a submodule by from-import
        f"{p}.sub.high": {f"{p}.top", f"{p}.sub.low"},  # not sub: high lives in it
        f"{p}.other": {f"{p}.sub", f"{p}.sub.low"},
    }
    found = cycles(edges)
    assert sorted(map(tuple, found)) == [(f"{p}.sub", f"{p}.sub.high", f"{p}.sub.low",
                                          f"{p}.top")]


# ------------------------------------------------------------------ the package

def test_no_module_imports_one_that_imports_it_back():
    """The package's import graph has no cycle; each one found is named edge by edge."""
    modules = package_modules()
    edges, unresolved = import_edges(modules)
    assert f"{PACKAGE}.contact.interface" in edges  # the walk found the package
    assert not unresolved, f"imports of no module of the package: {unresolved}"
    problems = []
    for component in cycles(edges):
        if frozenset(component) in ALLOWED_CYCLES:
            continue
        path = one_cycle(edges, component)
        steps = [f"{a} ({os.path.relpath(modules[a], ROOT)}:{edges[a][b]}) -> {b}"
                 for a, b in zip(path, path[1:])]
        problems.append(f"{len(component)} modules in a cycle: {', '.join(component)}\n    "
                        + "\n    ".join(steps))
    assert not problems, "import cycles:\n" + "\n".join(problems)
