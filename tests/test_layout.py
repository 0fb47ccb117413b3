"""The package's layout: dependencies run one way.

Rooms, bottom to top: shared foundations (units, platforms, smooth forces, start
checks, observables) → integrators (step programs) → systems, analysis and the NumPy
reference → runs → workflows and benchmarks → the CLI. A module may import from its
own room or a lower one; benchmarks are imported only by the CLI. The generators of
docs/ (tools/, outside the package) may import anything of it.

And no circles: no module imports itself through others, inside a room either
(:func:`import_cycles`; imports inside functions count, those under ``if
TYPE_CHECKING:`` do not, and ``importlib.import_module`` is not seen).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import openmm_alphaprk

PACKAGE = Path(openmm_alphaprk.__file__).parent
LAYERS = {
    "errors": 0,  # imports nothing of the package (test_errors_import_nothing_of_the_package)
    "_units": 0,
    "platforms": 0,
    "smooth_forces": 0,
    "nve": 0,
    "start_blowup": 0,
    "observables": 0,
    "equal_cost": 0,
    "integrators": 1,
    "__init__": 1,  # the public API: the integrators and the precondition helpers
    "systems": 2,
    "analysis": 2,
    "reference": 2,
    "runs": 3,
    "workflows": 4,
    "benchmarks": 4,
    "cli": 5,
    "__main__": 6,
}


def _room(path: Path) -> str:
    return path.relative_to(PACKAGE).parts[0].removesuffix(".py")


def _module_name(path: Path, package: Path) -> str:
    """The dotted name of the module at ``path`` in the package at ``package`` (a package: its name)."""
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_names(package: Path) -> set[str]:
    return {_module_name(path, package) for path in package.rglob("*.py")}


def _outside_type_checking(tree: ast.AST):
    """Every node of ``tree`` but those only under ``if TYPE_CHECKING:`` (which never run)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, ast.If) and ast.unparse(node.test) in {"TYPE_CHECKING", "typing.TYPE_CHECKING"}:
            stack.extend(node.orelse)
        else:
            stack.extend(ast.iter_child_nodes(node))


def _imports(
    path: Path,
    package: Path = PACKAGE,
    source: str | None = None,
    type_checking: bool = True,
    modules: set[str] | None = None,
):
    """Yield ``(module, line)`` for each module of the package that the file ``path`` imports.

    Imports at module level and inside functions alike, relative or absolute. ``from X
    import y`` imports the module ``X.y`` where that is a module of the package, else
    ``X`` (a package: its ``__init__``). The parent packages Python runs first are not
    counted (each module would be in a circle with its package's ``__init__``).
    ``type_checking=False`` leaves out the imports under ``if TYPE_CHECKING:``;
    ``importlib.import_module`` is not seen.
    """
    modules = _module_names(package) if modules is None else modules
    own = _module_name(path, package).split(".")
    here = own if path.name == "__init__.py" else own[:-1]  # the package relative imports start from
    source = path.read_text(encoding="utf-8") if source is None else source
    tree = ast.parse(source)
    for node in ast.walk(tree) if type_checking else _outside_type_checking(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - node.level + 1] + (node.module.split(".") if node.module else [])
            elif (node.module or "").split(".")[0] == package.name:
                base = node.module.split(".")
            else:
                continue
            for alias in node.names:
                submodule = ".".join([*base, alias.name])
                yield (submodule if submodule in modules else ".".join(base)), node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == package.name:
                    yield alias.name, node.lineno


def _imported_rooms(path: Path, source: str | None = None):
    """The rooms the file ``path`` imports from (``__init__``: the package's own names); all imports."""
    for module, _ in _imports(path, PACKAGE, source, modules=PACKAGE_MODULES):
        parts = module.split(".")
        yield parts[1] if len(parts) > 1 else "__init__"


PACKAGE_MODULES = _module_names(PACKAGE)


def import_graph(package: Path) -> dict[str, dict[str, str]]:
    """The package's imports: for each module, the modules it imports and where (``file:line``).

    Imports under ``if TYPE_CHECKING:`` are left out: they never run.
    """
    graph: dict[str, dict[str, str]] = {}
    modules = _module_names(package)
    for path in sorted(package.rglob("*.py")):
        name = _module_name(path, package)
        edges = graph.setdefault(name, {})
        for target, line in _imports(path, package, type_checking=False, modules=modules):
            if target != name:
                edges.setdefault(target, f"{path.relative_to(package.parent)}:{line}")
    return graph


def _strongly_connected(graph: dict[str, dict[str, str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of ``graph`` with more than one module, each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in graph.get(node, {}):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(components)


def _shortest_circle(graph: dict[str, dict[str, str]], component: list[str]) -> list[str]:
    """A shortest circle through the component's first module, inside the component: a → b → a."""
    start, members = component[0], set(component)
    came_from: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for target in sorted(graph[node]):
                if target == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(came_from[path[-1]])
                    return [*reversed(path), start]
                if target in members and target not in came_from:
                    came_from[target] = node
                    following.append(target)
        frontier = following
    raise AssertionError(f"no circle through {start}")  # a strongly connected component has one


def import_cycles(package: Path) -> list[str]:
    """Each circle of imports among the modules of the package at ``package``, as ``a → b → a``.

    One per strongly connected component of :func:`import_graph` (a shortest circle
    through its first module; the component's other modules follow it), with where
    each import is.
    """
    graph = import_graph(package)
    found = []
    for component in _strongly_connected(graph):
        circle = _shortest_circle(graph, component)
        where = ", ".join(graph[a][b] for a, b in zip(circle, circle[1:]))
        others = sorted(set(component) - set(circle))
        also = f"; in the same knot: {', '.join(others)}" if others else ""
        found.append(f"{' → '.join(circle)} ({where}){also}")
    return found


MODULES = sorted(PACKAGE.rglob("*.py"))


def test_every_room_has_a_layer():
    assert {_room(path) for path in MODULES} <= set(LAYERS)


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_point_down(path):
    room = _room(path)
    for target in set(_imported_rooms(path)) - {room}:
        assert LAYERS[target] <= LAYERS[room], f"{room} imports {target}, a room above it"
        if target == "benchmarks":
            assert room == "cli", f"{room} imports a benchmark module"


def test_errors_import_nothing_of_the_package():
    """The exceptions and warnings (``errors.py``) are the foundation every module may import."""
    assert not set(_imported_rooms(PACKAGE / "errors.py"))


def test_the_import_walker_resolves_relative_and_absolute_imports():
    """An upward import in a step-program module would be seen (and fail the test above)."""
    probe = PACKAGE / "integrators" / "probe.py"
    source = (
        "from ..runs import run_nve\nfrom .. import benchmarks\nfrom .pieces import _StepProgram\n"
        "from openmm_alphaprk.workflows import compare\nfrom openmm_alphaprk import make_smooth\n"
    )
    assert set(_imported_rooms(probe, source)) == {
        "runs",
        "benchmarks",
        "integrators",
        "workflows",
        "__init__",
    }
    assert LAYERS["runs"] > LAYERS["integrators"]


def test_no_module_imports_itself_through_others():
    """No circle of imports among the package's modules, inside a room included.

    A circle a → b → a makes the modules' order of import matter and each half
    unreadable without the other; an import deferred into a function is still one.
    """
    cycles = import_cycles(PACKAGE)
    assert not cycles, "circles of imports:\n" + "\n".join(cycles)


def _write_package(root: Path, files: dict[str, str]) -> Path:
    for name, source in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source, encoding="utf-8")
    return root / next(iter(files)).split("/")[0]


def test_the_cycle_check_catches_a_circle_inside_a_subpackage(tmp_path):
    """A circle inside one room, closed by an import deferred into a function, is found and named."""
    package = _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "from .room import a\n",
            "pkg/base.py": "X = 1\n",
            "pkg/room/__init__.py": "",
            "pkg/room/a.py": "from ..base import X\nfrom .b import f\n",
            "pkg/room/b.py": "def f():\n    from . import a\n    return a\n",
            "pkg/room/c.py": "import pkg.room.d\n",
            "pkg/room/d.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import c\n",
        },
    )
    assert import_graph(package)["pkg.room.b"] == {"pkg.room.a": "pkg/room/b.py:2"}
    assert import_cycles(package) == [
        "pkg.room.a → pkg.room.b → pkg.room.a (pkg/room/a.py:2, pkg/room/b.py:2)"
    ]
    # the same package without the circle (and c ↔ d, an import for type checkers only, is none)
    (package / "room" / "b.py").write_text("def f():\n    return 1\n", encoding="utf-8")
    assert import_cycles(package) == []
    # an absolute import closes one too, and every module of a knot is named
    (package / "room" / "d.py").write_text("from pkg.room import c\n", encoding="utf-8")
    (package / "base.py").write_text("def g():\n    import pkg.room.a\n", encoding="utf-8")
    assert import_cycles(package) == [
        "pkg.base → pkg.room.a → pkg.base (pkg/base.py:2, pkg/room/a.py:1)",
        "pkg.room.c → pkg.room.d → pkg.room.c (pkg/room/c.py:1, pkg/room/d.py:1)",
    ]


SCRIPTS = sorted((PACKAGE.parent / "tools" / "scripts").glob("*.py"))


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_a_script_does_its_work_only_when_run(path):
    """Importing a script of tools/scripts defines things; its work is under ``if __name__ == "__main__"``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    definitions = (ast.Import, ast.ImportFrom, ast.FunctionDef, ast.ClassDef, ast.Assign, ast.AnnAssign)
    guarded = False
    for node in tree.body:
        if isinstance(node, ast.If) and "__main__" in ast.unparse(node.test):
            guarded = True
            continue
        docstring = isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
        assert isinstance(node, definitions) or docstring, f"{path.name}:{node.lineno} runs at import"
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            calls = [n for n in ast.walk(node) if isinstance(n, ast.Call)]
            assert not any("argv" in ast.unparse(c) for c in calls), f"{path.name}:{node.lineno} reads argv"
    assert guarded, f"{path.name} has no if __name__ == '__main__' block"


def test_the_command_line_imports_neither_mdanalysis_nor_dask_until_a_command_needs_them():
    """``openmm_alphaprk.workflows`` imports a module on first use of one of its names."""
    probe = (
        "import sys\n"
        "import openmm_alphaprk.cli\n"
        "from openmm_alphaprk.workflows import compare\n"
        "assert not {'MDAnalysis', 'dask'} & {name.split('.')[0] for name in sys.modules}, 'imported early'\n"
        "from openmm_alphaprk.workflows import analyze_run\n"
        "assert 'MDAnalysis' in sys.modules\n"
    )
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
