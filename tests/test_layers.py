"""The rooms' import rules (docs/ARCHITECTURE.md), checked twice.

1. import-linter's contracts in pyproject.toml (``[tool.importlinter]``), one test per contract.
2. An own check that needs nothing but ``ast``: every import under nirl_mj/ (inside functions and
   under ``if TYPE_CHECKING:`` too) -> no cycle among modules, and each room imports only the rooms
   it may (``ALLOWED``) and none of the third-party packages it must not (``FORBIDDEN_EXTERNAL``).

The checker itself is tested on a small synthetic package with a cycle and forbidden imports.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import tomllib
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

ROOMS = ("data", "sim", "experts", "learn", "inspect", "gym", "experiments", "cli")
"""The sub-packages (and cli.py), bottom to top."""

ALLOWED: dict[str, frozenset[str]] = {
    "data": frozenset({"data"}),
    "sim": frozenset({"sim", "data"}),
    "experts": frozenset({"experts", "sim", "data"}),
    "learn": frozenset({"learn", "data"}),
    "inspect": frozenset({"inspect", "learn", "experts", "sim", "data"}),
    "gym": frozenset({"gym", "experts", "sim", "data"}),
    "experiments": frozenset({"experiments", "inspect", "gym", "learn", "experts", "sim", "data"}),
    "cli": frozenset(ROOMS),
    # The package's own __init__.py (make_env) may reach any room but cli; no room imports it.
    "": frozenset(ROOMS) - {"cli"},
}
"""Room -> the rooms whose modules it may import ("" is the top-level package module)."""

_GYM_EXTRA = frozenset({"gymnasium", "stable_baselines3", "minari", "h5py", "shimmy"})
FORBIDDEN_EXTERNAL: dict[str, frozenset[str]] = {
    "learn": frozenset({"mujoco", "dm_control", "dm_env"}) | _GYM_EXTRA,
    "data": frozenset({"mujoco", "dm_control", "dm_env", "torch"}) | _GYM_EXTRA,
    "sim": _GYM_EXTRA,
    "experts": _GYM_EXTRA,
    "inspect": _GYM_EXTRA,
}
"""Room -> third-party top-level packages it must not import."""


@dataclass(frozen=True)
class Import:
    """One imported name: ``importer`` (a module) imports ``imported`` at ``where`` (file:line)."""

    importer: str
    imported: str  # a module of the package, or a third-party top-level name
    where: str
    type_checking: bool  # only under ``if TYPE_CHECKING:``

    def __str__(self) -> str:
        guard = " (under TYPE_CHECKING)" if self.type_checking else ""
        return f"{self.where}: {self.importer} imports {self.imported}{guard}"


@dataclass(frozen=True)
class Graph:
    """A package's modules (dotted name -> file, relative to the package's parent) and imports."""

    modules: dict[str, str]
    imports: list[Import]


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _import_nodes(nodes: list[ast.AST], type_checking: bool = False) -> Iterator[tuple[ast.stmt, bool]]:
    """Every import statement in or below ``nodes``, with whether it is type-checking only."""
    for node in nodes:
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node, type_checking
        elif isinstance(node, ast.If) and _is_type_checking(node.test):
            yield from _import_nodes(node.body, True)
            yield from _import_nodes(node.orelse, type_checking)
        else:
            yield from _import_nodes(list(ast.iter_child_nodes(node)), type_checking)


def _resolve(dotted: str, package: str, modules: dict[str, str]) -> str:
    """Ours: the longest prefix of ``dotted`` that is a module; third-party: the top-level name."""
    parts = dotted.split(".")
    if parts[0] != package:
        return parts[0]
    while ".".join(parts) not in modules:
        parts.pop()
    return ".".join(parts)


def import_graph(package_dir: Path) -> Graph:
    """Every import of every module under ``package_dir`` (one entry per imported name)."""
    package = package_dir.name
    modules = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = path.relative_to(package_dir.parent).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    imports = []
    for importer, path in modules.items():
        where = path.relative_to(package_dir.parent).as_posix()
        for node, type_checking in _import_nodes([ast.parse(path.read_text(), str(path))]):
            if isinstance(node, ast.Import):
                dotted = [alias.name for alias in node.names]
            else:
                base = node.module or ""
                if node.level:  # relative: from the importer's package, one level up per extra dot
                    anchor = importer.split(".")[: None if path.name == "__init__.py" else -1]
                    anchor = anchor[: len(anchor) - node.level + 1]
                    base = ".".join(anchor + ([base] if base else []))
                # ``from a import b``: b is a submodule of a, or a name defined in a.
                dotted = [base if alias.name == "*" else f"{base}.{alias.name}" for alias in node.names]
            for imported in dict.fromkeys(_resolve(d, package, modules) for d in dotted):
                if imported != importer:
                    imports.append(Import(importer, imported, f"{where}:{node.lineno}", type_checking))
    names = {m: p.relative_to(package_dir.parent).as_posix() for m, p in modules.items()}
    return Graph(names, imports)


def room_of(module: str) -> str:
    """``nirl_mj.learn.loop`` -> ``learn``; ``nirl_mj.cli`` -> ``cli``; ``nirl_mj`` -> ``""``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def room_violations(
    graph: Graph,
    allowed: dict[str, frozenset[str]] = ALLOWED,
    forbidden_external: dict[str, frozenset[str]] = FORBIDDEN_EXTERNAL,
) -> list[str]:
    """One message per module outside every room, then per import that breaks the rules."""
    rooms = ", ".join(sorted(r for r in allowed if r))
    messages = [
        f"{where}: {module} is in no room (rooms: {rooms}); put it in one, or add a room to ALLOWED"
        for module, where in graph.modules.items()
        if room_of(module) not in allowed
    ]
    for i in graph.imports:
        room = room_of(i.importer)
        if room not in allowed:
            continue
        if i.imported in graph.modules:
            if room_of(i.imported) not in allowed[room]:
                may = ", ".join(sorted(allowed[room] - {room})) or "nothing of ours"
                messages.append(f"{i}: room {room or '(the package)'} may import only {may}")
        elif i.imported in forbidden_external.get(room, ()):
            messages.append(f"{i}: room {room} must not import {i.imported}")
    return messages


def find_cycles(graph: Graph) -> list[tuple[list[str], list[Import]]]:
    """Each group of modules that import one another in a circle (a strongly connected component)
    with one shortest cycle of it, as its imports."""
    edges: dict[str, dict[str, Import]] = {m: {} for m in graph.modules}
    for i in graph.imports:
        if i.imported in graph.modules:
            edges[i.importer].setdefault(i.imported, i)
    # Tarjan's strongly connected components.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = [stack.pop()]
            while group[-1] != v:
                group.append(stack.pop())
            if len(group) > 1:
                groups.append(sorted(group))

    for v in edges:
        if v not in index:
            visit(v)
    cycles = []
    for group in sorted(groups):
        start = group[0]  # breadth-first from start back to it, inside the group
        came_from: dict[str, str] = {}
        queue = deque([start])
        while start not in came_from:
            v = queue.popleft()
            for w in sorted(edges[v]):
                if w in group and w not in came_from:
                    came_from[w] = v
                    queue.append(w)
        path = [start]
        while len(path) == 1 or path[-1] != start:
            path.append(came_from[path[-1]])
        path.reverse()
        cycles.append((group, [edges[a][b] for a, b in zip(path, path[1:], strict=False)]))
    return cycles


def format_cycle(group: list[str], cycle: list[Import]) -> str:
    names = " -> ".join([cycle[0].importer] + [i.imported for i in cycle])
    return f"import cycle among {', '.join(group)}: {names}" + "".join(f"\n    {i}" for i in cycle)


def _contract_ids() -> list[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return [c["id"] for c in config["tool"]["importlinter"]["contracts"]]


# import-linter in a child process run from the repository, so that it analyses this tree's
# nirl_mj (the current directory comes first on sys.path) and leaves no cache behind.
_LINT = (
    "import sys; from importlinter.cli import lint_imports; "
    "sys.exit(lint_imports(config_filename='pyproject.toml', limit_to_contracts=(sys.argv[1],), "
    "no_cache=True, no_logo=True))"
)


@pytest.mark.parametrize("contract", _contract_ids())
def test_import_linter_contract(contract: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", _LINT, contract], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, f"import-linter contract {contract!r} broken:\n{done.stdout}{done.stderr}"


def test_no_import_cycles() -> None:
    cycles = find_cycles(import_graph(ROOT / "nirl_mj"))
    assert not cycles, "\n".join(format_cycle(*c) for c in cycles)


def test_rooms_import_only_rooms_below() -> None:
    violations = room_violations(import_graph(ROOT / "nirl_mj"))
    assert not violations, "imports that break the rooms' rules:\n" + "\n".join(violations)


def test_rules_are_closed() -> None:
    """Checking direct imports suffices: a room's allowed rooms allow nothing more, and forbid at
    least what the room forbids (so no forbidden module is reachable indirectly either)."""
    for room, rooms in ALLOWED.items():
        for below in rooms:
            assert ALLOWED[below] <= rooms, (room, below)
            assert FORBIDDEN_EXTERNAL.get(room, frozenset()) <= FORBIDDEN_EXTERNAL.get(below, frozenset())
    assert all("" not in rooms for rooms in ALLOWED.values())


def _write_package(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root / "pkg"


def test_checker_finds_cycles_and_forbidden_imports(tmp_path: Path) -> None:
    package = _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "",
            "pkg/extra.py": "import os\n",
            "pkg/data/__init__.py": "",
            "pkg/data/a.py": "import numpy\n\n\ndef f():\n    from pkg.sim import b\n",
            "pkg/sim/__init__.py": "",
            "pkg/sim/b.py": "from . import c\n",
            "pkg/sim/c.py": "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    import pkg.sim.b\n",
            "pkg/learn/__init__.py": "",
            "pkg/learn/d.py": "import mujoco.viewer\nimport torch\n\n"
            "from pkg.data.a import f\nfrom pkg.learn import e\n",
            "pkg/learn/e.py": "from pkg.learn.g import x\n",
            "pkg/learn/g.py": "from pkg.learn import d, e\n",
        },
    )
    graph = import_graph(package)
    assert Import("pkg.sim.b", "pkg.sim.c", "pkg/sim/b.py:1", False) in graph.imports  # relative
    assert Import("pkg.sim.c", "pkg.sim.b", "pkg/sim/c.py:4", True) in graph.imports
    assert Import("pkg.learn.e", "pkg.learn.g", "pkg/learn/e.py:1", False) in graph.imports  # a name

    cycles = find_cycles(graph)
    assert [(group, [i.where for i in cycle]) for group, cycle in cycles] == [
        (
            ["pkg.learn.d", "pkg.learn.e", "pkg.learn.g"],
            ["pkg/learn/d.py:5", "pkg/learn/e.py:1", "pkg/learn/g.py:1"],
        ),
        (["pkg.sim.b", "pkg.sim.c"], ["pkg/sim/b.py:1", "pkg/sim/c.py:4"]),
    ]
    assert format_cycle(*cycles[1]) == (
        "import cycle among pkg.sim.b, pkg.sim.c: pkg.sim.b -> pkg.sim.c -> pkg.sim.b"
        "\n    pkg/sim/b.py:1: pkg.sim.b imports pkg.sim.c"
        "\n    pkg/sim/c.py:4: pkg.sim.c imports pkg.sim.b (under TYPE_CHECKING)"
    )

    violations = room_violations(graph)
    assert len(violations) == 3, violations
    assert violations[0].startswith("pkg/extra.py: pkg.extra is in no room")
    assert violations[1:] == [
        "pkg/data/a.py:5: pkg.data.a imports pkg.sim.b: room data may import only nothing of ours",
        "pkg/learn/d.py:1: pkg.learn.d imports mujoco: room learn must not import mujoco",
    ]
