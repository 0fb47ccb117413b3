r"""docs/energy_program.md: the energy mode's step programs as a state machine, and their variables.

Part of ``python -m tools.reports``: the page's generated blocks: an outline of each
program (order 2 and order 4), its blocks and the pieces (the ``_add_*`` methods) that
fill them, with the globals each writes; and the table of every global (and per-DOF
variable), grouped by the stage of the step that owns it, with its meaning (hand-written,
:mod:`tools.reports.energy_globals`) and who writes it. Who writes it is read from the
programs themselves: each program is built once more with its computations recorded, so
that every computation OpenMM holds (``getComputationStep``) is known with the piece that
added it; the Python side (setters, ``check_context()``, ``step()``,
``reset_reference_energy()``) is read from the source of the integrator's classes.
"""

from __future__ import annotations

import ast
import inspect
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import openmm as mm

import openmm_alphaprk.integrators as integrators_package
from openmm_alphaprk.integrators.energy_mode import AlphaRattleEnergyIntegrator
from tools.reports import markdown
from tools.reports.energy_globals import MEANINGS, PER_DOF_MEANINGS, PLACEHOLDERS, STAGES

PAGE = Path(__file__).resolve().parents[2] / "docs" / "energy_program.md"
#: The programs: the order-2 one (one α-RATTLE step) and the order-4 one (Suzuki's composition).
ORDERS = (2, 4)
#: Pieces that only help others: a sum over degrees of freedom (the sum is written by the piece
#: that asked for it; the count of sums by this helper) and the count of a force evaluation.
HELPERS = ("_add_sum", "_add_count_force_evaluation")

_INTEGRATORS = Path(integrators_package.__file__).parent
#: The methods of a CustomIntegrator that add a computation (or open or close a block).
_ADD = [
    n
    for n in dir(mm.CustomIntegrator)
    if n.startswith(("addCompute", "addConstrain", "addUpdate", "begin", "end"))
]
_BEGIN = (mm.CustomIntegrator.IfBlockStart, mm.CustomIntegrator.WhileBlockStart)
_WRITES_GLOBAL = (mm.CustomIntegrator.ComputeGlobal, mm.CustomIntegrator.ComputeSum)
#: How the outline names the computations that assign no variable.
_ACTIONS = {
    mm.CustomIntegrator.ConstrainPositions: "*constrain positions*",
    mm.CustomIntegrator.ConstrainVelocities: "*constrain velocities*",
    mm.CustomIntegrator.UpdateContextState: "*update context state*",
}


@dataclass(frozen=True)
class Program:
    """A step program and, for each of its computations, the pieces that added it (outermost first)."""

    integrator: mm.CustomIntegrator
    steps: list[tuple[int, str, str]]
    pieces: list[tuple[str, ...]]

    def globals(self) -> list[str]:
        """Return the program's global variables."""
        names = self.integrator.getGlobalVariableName
        return [names(i) for i in range(self.integrator.getNumGlobalVariables())]

    def per_dof(self) -> list[str]:
        """Return the program's per-DOF variables (besides x, v, f)."""
        names = self.integrator.getPerDofVariableName
        return [names(i) for i in range(self.integrator.getNumPerDofVariables())]

    def writer(self, index: int) -> str:
        """Return the piece that wrote computation ``index``: the innermost; a sum: the one asking for it."""
        pieces = self.pieces[index]
        kind = self.steps[index][0]
        if kind == mm.CustomIntegrator.ComputeSum and pieces[-1] == "_add_sum" and len(pieces) > 1:
            return pieces[-2]
        return pieces[-1]


def _pieces_on_stack() -> tuple[str, ...]:
    """Return the ``_add_*`` and ``_build_*`` methods of the integrators now running, outermost first."""
    frame, names = sys._getframe(2), []
    while frame is not None:
        code = frame.f_code
        if Path(code.co_filename).parent == _INTEGRATORS and code.co_name.startswith(("_add_", "_build_")):
            names.append(code.co_name)
        frame = frame.f_back
    names.reverse()
    # the frame of every program (_add_program, _add_step) and the program's own build method
    # are the outline's top; the pieces below them are what the outline names
    while len(names) > 1 and (names[0] in ("_add_program", "_add_step") or names[0].startswith("_build_")):
        names.pop(0)
    return tuple(names)


def record_program(order: int) -> Program:
    """Build the order-``order`` energy mode with each computation's pieces recorded."""
    recorded: list[tuple[str, ...]] = []

    def recording(name: str) -> Callable:
        add = getattr(mm.CustomIntegrator, name)

        def add_recorded(self, *args):
            recorded.append(_pieces_on_stack())
            return add(self, *args)

        return add_recorded

    recorder = {name: recording(name) for name in _ADD}
    cls = type(AlphaRattleEnergyIntegrator.__name__, (AlphaRattleEnergyIntegrator,), recorder)
    integrator = cls(0.002, order=None if order == 2 else order)  # h = 2 fs, the defaults
    steps = [integrator.getComputationStep(i) for i in range(integrator.getNumComputations())]
    if len(recorded) != len(steps):
        raise RuntimeError(f"recorded {len(recorded)} computations of {len(steps)}: a piece added one unseen")
    return Program(integrator, steps, recorded)


def program_writers(program: Program) -> dict[str, list[str]]:
    """For each global and per-DOF variable the program assigns, the pieces that do, in program order."""
    writers: dict[str, list[str]] = {}
    for index, (kind, variable, _) in enumerate(program.steps):
        if kind in (*_WRITES_GLOBAL, mm.CustomIntegrator.ComputePerDof):
            names = writers.setdefault(variable, [])
            if program.writer(index) not in names:
                names.append(program.writer(index))
    return writers


# ------------------------------------------------------------------ the Python side
def _functions(cls: type) -> list[tuple[type, ast.FunctionDef]]:
    """Return the methods of ``cls`` and its bases in this package, each with its class, as parsed."""
    found = []
    for c in [c for c in cls.__mro__ if c.__module__.startswith("openmm_alphaprk.")]:
        (node,) = ast.parse(inspect.getsource(c)).body
        found += [(c, f) for f in node.body if isinstance(f, ast.FunctionDef)]
    return found


def _label(function: ast.FunctionDef) -> str:
    """Name a method as the page does: ``setter `name``` or ```name()```."""
    setter = any(isinstance(d, ast.Attribute) and d.attr == "setter" for d in function.decorator_list)
    return f"setter `{function.name}`" if setter else f"`{function.name}()`"


def python_writers(cls: type = AlphaRattleEnergyIntegrator) -> dict[str, list[str]]:
    """For each global that Python sets (``setGlobalVariableByName``), who does: public calls that reach it.

    Read from the source of ``cls`` and its bases in this package: each method that sets a
    global, and the public methods and setters from which it is reached through calls on
    ``self`` or ``super()`` (by name, as Python dispatches them).
    """
    definitions = []  # (name, label, callees, globals set)
    for c, function in _functions(cls):
        module = vars(sys.modules[c.__module__])
        callees, sets = set(), []
        for node in ast.walk(function):
            if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Attribute):
                continue
            owner = ast.unparse(node.func.value)
            if owner in ("self", "super()"):
                callees.add(node.func.attr)
            if node.func.attr == "setGlobalVariableByName":
                name = node.args[0]
                if isinstance(name, ast.Constant):
                    sets.append(name.value)
                elif isinstance(name, ast.Name):
                    sets.append(module[name.id])
                else:
                    raise ValueError(f"{c.__name__}.{function.name}: cannot read {ast.unparse(name)!r}")
        definitions.append((function.name, _label(function), callees, sets))
    calls: dict[str, set[str]] = {}
    for name, _, callees, _ in definitions:
        calls.setdefault(name, set()).update(callees)

    def reached(callees: set[str]) -> set[str]:
        seen, todo = set(), sorted(callees)
        while todo:
            name = todo.pop()
            if name not in seen:
                seen.add(name)
                todo += sorted(calls.get(name, ()))
        return seen

    entries = [
        (label, reached(callees)) for name, label, callees, _ in definitions if not name.startswith("_")
    ]
    writers: dict[str, set[str]] = {}
    for name, label, _, sets in definitions:
        if name.startswith("_"):
            reaching = sorted({entry for entry, names in entries if name in names})
            label = f"{', '.join(reaching) or 'nothing public'} via `{name}`"
        for variable in sets:
            writers.setdefault(variable, set()).add(label)
    return {variable: sorted(labels) for variable, labels in writers.items()}


# ------------------------------------------------------------------ the meanings
def _pattern(name: str) -> re.Pattern:
    """Return the pattern of the variables a meaning's name stands for (its placeholders expanded)."""
    text = re.escape(name)
    for placeholder, expression in PLACEHOLDERS.items():
        text = text.replace(re.escape(placeholder), f"(?:{expression})")
    return re.compile(text)


def rows_of(variables: list[str], meanings: dict[str, str]) -> dict[str, list[str]]:
    """For each entry of ``meanings``, the variables it stands for (a name may hold placeholders)."""
    return {row: [v for v in variables if _pattern(row).fullmatch(v)] for row in meanings}


def _who(names: list[str], by_order: dict[int, dict[str, list[str]]], python: dict[str, list[str]]) -> str:
    """Return who writes ``names``: program pieces (marked where one order only has them), Python."""
    pieces: list[str] = []
    for order in ORDERS:
        for name in names:
            pieces += [p for p in by_order[order].get(name, []) if p not in pieces]
    shown = []
    for piece in pieces:
        orders = [o for o in ORDERS if any(piece in by_order[o].get(n, []) for n in names)]
        shown.append(f"`{piece}`" + (f" ({orders[0]})" if len(orders) == 1 else ""))
    from_python = sorted({label for name in names for label in python.get(name, [])})
    parts = [", ".join(shown)] if shown else []
    if from_python:
        parts.append("Python: " + "; ".join(from_python))
    return "; ".join(parts) or "—"


def variables_table(
    title: str, meanings: dict[str, str], variables: dict[int, list[str]], writers, python
) -> str:
    """Return the table of ``meanings``: each entry, the orders that have it, its meaning, its writers.

    ``variables`` and ``writers`` are each program's variables and :func:`program_writers`, by
    order; ``python`` is :func:`python_writers`. A meaning's ``|`` (|H − E_ref|) is escaped.
    """
    every = sorted({v for names in variables.values() for v in names})
    rows = [
        [
            f"`{row}`",
            ", ".join(str(o) for o in ORDERS if any(n in variables[o] for n in names)),
            meanings[row].replace("|", "\\|"),
            _who(names, writers, python),
        ]
        for row, names in rows_of(every, meanings).items()
    ]
    return markdown.markdown_table([title, "order", "meaning", "written by"], rows)


# ------------------------------------------------------------------ the outline
def _opens_blocks(program: Program) -> set[str]:
    """Return the pieces that open or close a block of ``program``."""
    return {
        program.pieces[i][-1]
        for i, (kind, _, _) in enumerate(program.steps)
        if kind in _BEGIN or kind == mm.CustomIntegrator.BlockEnd
    }


def _outline_path(pieces: tuple[str, ...], openers: set[str]) -> tuple[str, ...]:
    """Return the pieces an outline shows for a computation: from the outermost that opens no block down.

    A piece that opens blocks is shown by its blocks; the helpers are not shown.
    """
    kept = [piece for piece in pieces if piece not in HELPERS] or [pieces[-1]]
    for level, piece in enumerate(kept):
        if piece not in openers:
            return tuple(kept[level:])
    return (kept[-1],)


def outline(program: Program) -> str:
    """Return the program as a nested list: its blocks, in each its pieces and the variables they write.

    Nested by block and, inside a block, by call: a piece's line holds what it writes
    itself, the lines below it what the pieces it calls write. Consecutive computations
    of one piece are one line, with their computation numbers (as in
    docs/step_programs.md), the variables (global or per DOF) written there, the helpers'
    counts of sums and force evaluations left out, and the constraint steps.
    """
    openers = _opens_blocks(program)
    lines: list[list] = []  # [indent, text, first, last, what it writes]
    calls: list[tuple[str, list]] = []  # the pieces of the last computation, with their lines
    depth = 0
    for index, (kind, variable, expression) in enumerate(program.steps):
        if kind == mm.CustomIntegrator.BlockEnd or kind in _BEGIN:
            calls = []
            if kind == mm.CustomIntegrator.BlockEnd:
                depth -= 1
                continue
            word = "if" if kind == mm.CustomIntegrator.IfBlockStart else "while"
            lines.append([depth, f"`{word} ({expression}):`", index, index, []])
            depth += 1
            continue
        path = _outline_path(program.pieces[index], openers)
        shared = 0
        while shared < min(len(calls), len(path)) and calls[shared][0] == path[shared]:
            shared += 1
        calls = calls[:shared]
        for level in range(shared, len(path)):
            line = [depth + level, f"`{path[level]}`", index, index, []]
            lines.append(line)
            calls.append((path[level], line))
        for _, line in calls:
            line[3] = index
        assigns = kind in (*_WRITES_GLOBAL, mm.CustomIntegrator.ComputePerDof)
        what = f"`{variable}`" if assigns else _ACTIONS.get(kind)
        written = calls[-1][1][4]
        if what and program.writer(index) not in HELPERS and what not in written:
            written.append(what)
    text = []
    for indent, what, first, last, written in lines:
        where = f"{first}" if first == last else f"{first}–{last}"
        writes = f": {', '.join(written)}" if written else ""
        text.append(f"{'  ' * indent}- {what} ({where}){writes}")
    return "\n".join(text)


# ------------------------------------------------------------------ the page
def render() -> dict[Path, dict[str, str]]:
    """Return the page's generated blocks, by page and name."""
    return {PAGE: render_blocks()}


def render_blocks(programs: dict[int, Program] | None = None) -> dict[str, str]:
    """Return the page's generated blocks, by name."""
    programs = programs or {order: record_program(order) for order in ORDERS}
    writers = {order: program_writers(p) for order, p in programs.items()}
    python, variables = python_writers(), {order: p.globals() for order, p in programs.items()}
    stages = [
        f"### {stage}\n\n{STAGES[stage]}\n\n{variables_table('global', meanings, variables, writers, python)}"
        for stage, meanings in MEANINGS.items()
    ]
    per_dof = {order: p.per_dof() for order, p in programs.items()}
    blocks = {f"outline-order{order}": outline(p) for order, p in programs.items()}
    blocks["globals"] = "\n\n".join(stages)
    blocks["per-dof"] = variables_table("per-DOF variable", PER_DOF_MEANINGS, per_dof, writers, {})
    counts = "; ".join(
        f"order {order}: {len(p.globals())} globals, {len(p.per_dof())} per-DOF variables, "
        f"{len(p.steps)} computations"
        for order, p in programs.items()
    )
    blocks["counts"] = f"{counts}."
    return blocks
