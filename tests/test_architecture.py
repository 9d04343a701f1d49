"""The package layout holds: the data flow reads off the tree (DESIGN §2).

Layers: ``sim`` (MuJoCo, hands, scenes, the validator, shared record types) at the bottom;
``augment`` (the paper's augmenter) and ``teleop`` (capture, retargeting, bridge, recording)
each on ``sim`` only, never on each other; ``dexaug`` (CLI, pipeline, dashboard) on top. Every
import counts — module level, inside functions, under ``TYPE_CHECKING`` — and so does a module
named in a string (a fork-server preload list, a ``monkeypatch`` target), since both tie code
together as much as an import does.
"""

from __future__ import annotations

import ast
import re
import subprocess
from collections import defaultdict
from pathlib import Path

import pytest

from sim.paths import REPO_ROOT

PACKAGES = ("sim", "augment", "teleop", "dexaug")
#: what each top-level package may import
ALLOWED = {"sim": {"sim"}, "augment": {"sim", "augment"}, "teleop": {"sim", "teleop"},
           "dexaug": set(PACKAGES)}


def _modules(root: Path = REPO_ROOT) -> dict[str, Path]:
    files = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "*.py"],
                           cwd=root, capture_output=True, text=True, check=True).stdout.split()
    out = {}
    for f in files:
        if f.split("/")[0] not in PACKAGES or not (root / f).is_file():
            continue
        name = f[:-3].replace("/", ".")
        out[name.removesuffix(".__init__")] = root / f
    return out


def _target(name: str, modules: dict[str, Path]) -> str | None:
    """The project module that an imported dotted name lives in (longest known prefix)."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        cand = ".".join(parts[:k])
        if cand in modules:
            return cand
    return None


_DOTTED = re.compile(r"^(?:sim|augment|teleop|dexaug)(?:\.\w+)+$")


def import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """module → the project modules it imports (or names in a string literal)."""
    graph: dict[str, set[str]] = defaultdict(set)
    for mod, path in modules.items():
        tree = ast.parse(path.read_text(), str(path))
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in ast.walk(tree):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join([*up, base] if base else up)
                # ``from pkg import mod`` names the module, ``from mod import name`` the module
                names = [f"{base}.{a.name}" for a in node.names]
            elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
                  and _DOTTED.match(node.value) and node.value in modules):
                names = [node.value]   # a module named in a string (not "dexaug.session")
            for n in names:
                t = _target(n, modules)
                if t is not None and t != mod:
                    graph[mod].add(t)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one member (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def _collapse(graph: dict[str, set[str]], depth: int) -> dict[str, set[str]]:
    """The graph between packages ``depth`` levels deep (``sim.hand``, ``augment.fsg``, …)."""
    def key(m: str) -> str:
        return ".".join(m.split(".")[:depth])

    out: dict[str, set[str]] = defaultdict(set)
    for a, bs in graph.items():
        for b in bs:
            if key(a) != key(b):
                out[key(a)].add(key(b))
    return out


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(_modules())


def test_no_module_import_cycles(graph: dict[str, set[str]]) -> None:
    assert cycles(graph) == []


def test_no_subpackage_import_cycles(graph: dict[str, set[str]]) -> None:
    """``sim.hand`` → ``sim.world`` → ``sim.hand`` would be a cycle even without a module one."""
    assert cycles(_collapse(graph, 2)) == []


def test_layers(graph: dict[str, set[str]]) -> None:
    bad = sorted(f"{a} -> {b}" for a, bs in graph.items() for b in bs
                 if b.split(".")[0] not in ALLOWED[a.split(".")[0]])
    assert bad == []


def test_cycle_finder_finds_cycles() -> None:
    """The checks above can fail: a planted two-module and three-module cycle are found."""
    g = {"a.x": {"a.y"}, "a.y": {"a.x"}, "b.p": {"b.q"}, "b.q": {"b.r"}, "b.r": {"b.p", "a.x"}}
    assert sorted(cycles(g)) == [["a.x", "a.y"], ["b.p", "b.q", "b.r"]]
    assert cycles(_collapse({"s.h.m": {"s.w.n"}, "s.w.k": {"s.h.j"}}, 2)) == [["s.h", "s.w"]]


def test_graph_sees_every_kind_of_reference(tmp_path: Path) -> None:
    """Function-level imports, relative imports and module names in strings are edges."""
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "__init__.py").write_text("")
    (tmp_path / "sim" / "a.py").write_text("def f():\n    from sim import b\n")
    (tmp_path / "sim" / "b.py").write_text("from . import c\n")
    (tmp_path / "sim" / "c.py").write_text("PRELOAD = ('sim.a',)\n")
    mods = {"sim": tmp_path / "sim" / "__init__.py", "sim.a": tmp_path / "sim" / "a.py",
            "sim.b": tmp_path / "sim" / "b.py", "sim.c": tmp_path / "sim" / "c.py"}
    g = import_graph(mods)
    assert g["sim.a"] == {"sim.b"} and g["sim.b"] == {"sim.c"} and g["sim.c"] == {"sim.a"}
    assert cycles(g) == [["sim.a", "sim.b", "sim.c"]]


def test_every_project_import_resolves() -> None:
    """Imports inside functions run only when their command does (``make demo``'s rerecord,
    say); after a module moves, each must still name a module and a name that exist."""
    import importlib

    missing = []
    modules = _modules()
    for mod, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.ImportFrom) or node.level or not node.module:
                continue
            if node.module.split(".")[0] not in PACKAGES:
                continue
            try:
                names = set(dir(importlib.import_module(node.module)))
            except ImportError as exc:
                if (exc.name or "").split(".")[0] in PACKAGES or node.module not in modules:
                    missing.append(f"{mod}:{node.lineno}: {exc}")
                    continue
                # an optional third-party package is missing here (MuJoCo Warp): the module
                # exists; its top-level definitions say what it provides
                names = _top_level_names(modules[node.module])
            for alias in node.names:
                if alias.name not in names and f"{node.module}.{alias.name}" not in modules:
                    missing.append(f"{mod}:{node.lineno}: {node.module} has no {alias.name}")
    assert missing == []


def _top_level_names(path: Path) -> set[str]:
    """The names a module's top level defines or imports (AST only: nothing runs)."""
    names: set[str] = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    return names
