"""The house's import graph, read from the source with the standard library alone (ast).

Every import counts: at module top, inside a function, and a package face's table of public names
(``_PUBLIC``, rotavat_cli/lazy.py: the face imports those modules when asked). What must hold:

- no circle of modules, and no circle of rooms (a room: a package or a top-level module of
  rotavat_cli), so the rooms stand on floors and every import goes down (docs/architecture.md);
- code inside rotavat_cli imports the module that defines a name, never a package's face;
- imports run at module top, except in the CLI layer (rotavat_cli/cli/: a command imports what it
  runs when it runs) and third-party imports kept lazy on purpose, each marked ``# lazy: why``;
- ``rotavat --version`` and ``rotavat --help`` import none of the API, nor numpy.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE_DIR = Path(__file__).resolve().parents[1] / "rotavat_cli"
PACKAGE = PACKAGE_DIR.name
ARCHITECTURE = PACKAGE_DIR.parent / "docs" / "architecture.md"


@dataclass(frozen=True)
class Import:
    """One import statement of module ``source``: the rotavat modules it names, and where it sits."""

    source: str
    targets: tuple[str, ...]
    line: int
    text: str
    at_top: bool
    comment: str  # the line's trailing comment, "" when none


def module_files(package_dir: Path = PACKAGE_DIR) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package (a package is its __init__.py)."""
    out = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = list(path.relative_to(package_dir.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = module_files()


def is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _known(name: str) -> str | None:
    """The longest prefix of ``name`` that is a rotavat module (``a.b.func`` -> ``a.b``), else None."""
    while name not in MODULES and "." in name:
        name = name.rpartition(".")[0]
    return name if name in MODULES else None


def import_targets(module: str, node: ast.Import | ast.ImportFrom) -> list[str]:
    """The rotavat modules an import statement of ``module`` loads (a name imported from a package
    that is itself a module counts as that module)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names if alias.name.split(".")[0] == PACKAGE]
    else:
        if node.level:
            base = module if is_package(module) else module.rpartition(".")[0]
            for _ in range(node.level - 1):
                base = base.rpartition(".")[0]
            origin = base + (f".{node.module}" if node.module else "")
        else:
            origin = node.module or ""
            if origin.split(".")[0] != PACKAGE:
                return []
        names = [f"{origin}.{alias.name}" if f"{origin}.{alias.name}" in MODULES else origin for alias in node.names]
    return sorted({t for t in map(_known, names) if t is not None and t != module})


def _top_level_ids(tree: ast.Module) -> set[int]:
    """ids of the statements that run when the module is imported (inside top-level if/try too)."""
    ids = set()
    for node in tree.body:
        for inner in ast.walk(node) if isinstance(node, (ast.If, ast.Try)) else [node]:
            ids.add(id(inner))
    return ids


def module_imports(module: str) -> list[Import]:
    """Every import statement of ``module``."""
    text = MODULES[module].read_text(encoding="utf-8")
    lines = text.splitlines()
    tree = ast.parse(text)
    top = _top_level_ids(tree)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            line = lines[node.lineno - 1]
            comment = line.split("#", 1)[1].strip() if "#" in line else ""
            out.append(Import(module, tuple(import_targets(module, node)), node.lineno, ast.unparse(node),
                              id(node) in top, comment))
    return out


def face_table(module: str) -> dict[str, tuple[str, ...]]:
    """A package face's ``_PUBLIC`` table (``{".fit": ("fit_camera", ...)}``), {} when it has none."""
    if not is_package(module):
        return {}
    for node in ast.parse(MODULES[module].read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_PUBLIC" for t in node.targets):
            return ast.literal_eval(node.value)
    return {}


IMPORTS = [imp for module in MODULES for imp in module_imports(module)]
FACES = {module: table for module in MODULES if (table := face_table(module))}


def import_graph() -> dict[str, set[str]]:
    """module -> the rotavat modules it imports: every statement, and each face's table."""
    graph: dict[str, set[str]] = defaultdict(set)
    for imp in IMPORTS:
        graph[imp.source].update(imp.targets)
    for face, table in FACES.items():
        graph[face].update(f"{face}{relative}" for relative in table)
    return graph


def room(module: str) -> str:
    """The room of a module: its package or top-level module right under rotavat_cli."""
    return ".".join(module.split(".")[:2])


def room_graph() -> dict[str, set[str]]:
    """room -> the other rooms its modules import."""
    graph: dict[str, set[str]] = defaultdict(set)
    for source, targets in import_graph().items():
        graph[room(source)].update(room(t) for t in targets if room(t) != room(source))
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    nodes = sorted(set(graph) | {t for targets in graph.values() for t in targets})
    for start in nodes:
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def floors(graph: dict[str, set[str]]) -> dict[str, int]:
    """Each node's floor in an acyclic graph: 0 for what imports nothing, else 1 + its highest import."""
    floor: dict[str, int] = {}

    def visit(node: str) -> int:
        if node not in floor:
            floor[node] = 1 + max((visit(t) for t in graph.get(node, ())), default=-1)
        return floor[node]

    for node in sorted(set(graph) | {t for targets in graph.values() for t in targets}):
        visit(node)
    return floor


def documented_floors(page: Path = ARCHITECTURE) -> dict[str, int]:
    """The floors docs/architecture.md gives the rooms: lines ``| N | `room`, `room` | ... |``."""
    out = {}
    for number, rooms in re.findall(r"^\|\s*(\d+)\s*\|([^|]*)\|", page.read_text(encoding="utf-8"), re.M):
        for name in re.findall(r"`([\w./]+)`", rooms):
            out[f"{PACKAGE}.{name.removesuffix('/').removesuffix('.py').replace('/', '.')}"] = int(number)
    return out


# ---- the tests ---------------------------------------------------------------------------------------
def test_the_reader_sees_the_whole_package():
    """The graph is read from every module (a reader that found nothing would pass everything)."""
    assert len(MODULES) > 80 and {"rotavat_cli.cli", "rotavat_cli.calibration.fit", "rotavat_cli.sequence"} <= set(MODULES)
    graph = import_graph()
    assert "rotavat_cli.geometry.camera" in graph["rotavat_cli.calibration.fit"]  # a top-level import
    assert "rotavat_cli.calibration.fit" in graph["rotavat_cli.calibration"]  # a face's table
    assert "rotavat_cli.cli.calibrate" not in graph["rotavat_cli.cli.group"]  # the group imports commands by name


def test_the_circle_finder_finds_circles():
    """Tarjan on a hand-made graph: the circle a -> b -> c -> a, and d on its own."""
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []
    assert floors({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == {"a": 2, "b": 1, "c": 0}


def test_no_module_imports_in_a_circle():
    assert circles(import_graph()) == []


def test_no_room_imports_in_a_circle():
    assert circles(room_graph()) == []


def test_every_import_goes_down_the_documented_floors():
    """docs/architecture.md names every room's floor; each room imports only rooms on lower floors."""
    documented = documented_floors()
    graph = room_graph()
    rooms = {room(m) for m in MODULES} - {PACKAGE}
    assert sorted(rooms - set(documented)) == [], "rooms missing from docs/architecture.md's floors"
    assert sorted(set(documented) - rooms) == [], "docs/architecture.md names rooms that do not exist"
    upward = [(source, target) for source in sorted(graph) if source != PACKAGE  # the root face: above all
              for target in sorted(graph[source]) if documented[target] >= documented[source]]
    assert upward == []


def test_code_imports_the_defining_module_not_a_face():
    through_faces = [f"{imp.source}:{imp.line}: {imp.text}" for imp in IMPORTS
                     if any(target in FACES for target in imp.targets) and not imp.source.startswith(f"{PACKAGE}.cli")]
    assert through_faces == []


def test_imports_run_at_module_top_outside_the_cli():
    """Only the CLI layer imports inside functions (a command loads what it runs); elsewhere a lazy
    import is third-party, kept lazy on purpose, and says why on its line (``# lazy: ...``)."""
    inside = [imp for imp in IMPORTS if not imp.at_top and not imp.source.startswith(f"{PACKAGE}.cli")]
    rotavat = [f"{imp.source}:{imp.line}: {imp.text}" for imp in inside if imp.targets or ".." in imp.text
               or imp.text.startswith("from .")]
    assert rotavat == []
    unexplained = [f"{imp.source}:{imp.line}: {imp.text}" for imp in inside if not imp.comment.startswith("lazy:")]
    assert unexplained == []


@pytest.mark.parametrize("argv", [["--version"], ["--help"]])
def test_version_and_help_import_none_of_the_api(argv):
    """A fresh interpreter: ``rotavat --version``/``--help`` load the CLI's group and its command list only."""
    code = ("import sys\nsys.argv = ['rotavat', *sys.argv[1:]]\nfrom rotavat_cli.cli import main\n"
            "try:\n    main()\nexcept SystemExit:\n    pass\n"
            "print(' '.join(sorted(m for m in sys.modules if m.startswith(('rotavat_cli', 'numpy', 'scipy', 'yaml')))),"
            " file=sys.stderr)")
    proc = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=60)
    loaded = set(proc.stderr.split())
    assert proc.returncode == 0 and "rotavat" in proc.stdout
    assert loaded <= {"rotavat_cli", "rotavat_cli.version", "rotavat_cli.lazy", "rotavat_cli.errors", "rotavat_cli.cli",
                      "rotavat_cli.cli.group", "rotavat_cli.cli.commands", "rotavat_cli.cli._run",
                      "rotavat_cli.allocator"}, loaded
