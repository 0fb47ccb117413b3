"""The package's layout: dependencies run one way.

Rooms, bottom to top: shared foundations (units, platforms, smooth forces, start
checks, observables) → integrators (step programs) → systems, analysis and the NumPy
reference → runs → workflows and benchmarks → the CLI. A module may import from its
own room or a lower one; benchmarks are imported only by the CLI. The generators of
docs/ (tools/, outside the package) may import anything of it.
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


def _imported_rooms(path: Path, source: str | None = None):
    package = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)[:-1]
    source = path.read_text(encoding="utf-8") if source is None else source
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                module = package[: len(package) - node.level + 1] + (node.module or "").split(".")
            elif (node.module or "").split(".")[0] == "openmm_alphaprk":
                module = node.module.split(".")
            else:
                continue
            module = [part for part in module if part]
            targets = module[1:2] or [alias.name for alias in node.names]
            yield from (target if target in LAYERS else "__init__" for target in targets)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("openmm_alphaprk."):
                    yield alias.name.split(".")[1]


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
