"""Every public class and function has a numpydoc ``Examples`` section and typed parameters.

The names a user imports (the ``__all__`` of the package and of its public subpackages,
the public names of :mod:`openmm_alphaprk.workflows`, and the
functions the command line is built on) each show at least one ``>>>`` example, which
the default suite runs as a doctest (``--doctest-modules`` in pyproject.toml), and give
every parameter of the function or constructor a type (``name : type``) in ``Parameters``.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import re

import pytest

#: Modules whose ``__all__`` is public.
PUBLIC_MODULES = (
    "openmm_alphaprk",
    "openmm_alphaprk.runs",
    "openmm_alphaprk.systems",
    "openmm_alphaprk.analysis",
    "openmm_alphaprk.reference",
    "openmm_alphaprk.workflows",
)
#: Functions the command line is built on, outside those ``__all__`` lists.
COMMAND_FACING = (
    "openmm_alphaprk.systems.definitions.file_definition",
    "openmm_alphaprk.integrators.check_context",
    "openmm_alphaprk.integrators.force_evaluations_per_step",
    "openmm_alphaprk.integrators.counted_force_evaluations",
    "openmm_alphaprk.nve.LargeStepWarning",
    "openmm_alphaprk.nve.step_size_problem",
    "openmm_alphaprk.platforms.fastest_platform",
    "openmm_alphaprk.workflows.comparison.verdict",
)
NOT_HERE: set[str] = set()

_HEADER_LINE = re.compile(r"^-{3,}$")


def _public_objects() -> dict[str, object]:
    """``{qualified name: class or function}`` of every public name (constants left out)."""
    objects = {}
    for module_name in PUBLIC_MODULES:
        module = importlib.import_module(module_name)
        for name in module.__all__:  # workflows: its __getattr__ imports lazily
            qualified = f"{module_name}.{name}"
            obj = getattr(module, name)
            if qualified in NOT_HERE or not (inspect.isclass(obj) or inspect.isfunction(obj)):
                continue
            objects[qualified] = obj
    for qualified in COMMAND_FACING:
        module_name, name = qualified.rsplit(".", 1)
        objects[qualified] = getattr(importlib.import_module(module_name), name)
    return objects


PUBLIC = _public_objects()


def numpydoc_sections(doc: str | None) -> dict[str, list[str]]:
    """The sections of a numpydoc docstring: ``{title: lines below its underline}``."""
    lines = inspect.cleandoc(doc or "").splitlines()
    sections: dict[str, list[str]] = {}
    current: list[str] | None = None
    i = 0
    while i < len(lines):
        line = lines[i]
        following = lines[i + 1] if i + 1 < len(lines) else ""
        if line.strip() and not line[0].isspace() and _HEADER_LINE.match(following.rstrip()):
            current = sections.setdefault(line.strip(), [])
            i += 2
            continue
        if current is not None:
            current.append(line)
        i += 1
    return sections


def documented_parameters(lines: list[str]) -> dict[str, str]:
    """``{name: type}`` of the entries of a Parameters section (``a, b : int`` gives two)."""
    entries = {}
    for line in lines:
        if not line.strip() or line[0].isspace():
            continue
        names, _, type_ = line.partition(" : ")
        if not _ and names.rstrip().endswith(" :"):  # "name :" with nothing after it
            names = names.rstrip()[:-2]
        for name in names.split(","):
            entries[name.strip().lstrip("*")] = type_.strip()
    return entries


def constructor_parameters(obj: object) -> list[inspect.Parameter]:
    """The parameters a caller passes: a function's, or a class's ``__init__`` (or ``__new__``)."""
    if inspect.isfunction(obj):
        return list(inspect.signature(obj).parameters.values())
    for attribute in ("__init__", "__new__"):
        # the first class in the MRO that defines it, if that is Python code (not object's or
        # a built-in exception's, which take whatever is passed)
        owner = next(c for c in obj.__mro__ if attribute in vars(c))
        method = vars(owner)[attribute]
        if isinstance(method, staticmethod):
            method = method.__func__
        if inspect.isfunction(method):
            return list(inspect.signature(method).parameters.values())[1:]  # without self / cls
    return []


def test_every_public_name_is_listed():
    """The walk finds the names it is meant to check (a broken import would make it vacuous)."""
    assert len(PUBLIC) > 60
    assert "openmm_alphaprk.runs.run_nve" in PUBLIC
    assert "openmm_alphaprk.workflows.run_sweep" in PUBLIC  # a lazily imported name
    assert "openmm_alphaprk.TimestepUnitWarning" in PUBLIC


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_examples_section(name):
    """The docstring has an ``Examples`` section with at least one ``>>>`` line."""
    examples = numpydoc_sections(PUBLIC[name].__doc__).get("Examples")
    assert examples is not None, f"{name}: no Examples section"
    assert any(line.lstrip().startswith(">>> ") for line in examples), f"{name}: Examples without >>>"


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_parameters_have_types(name):
    """Every parameter of the function (the class's constructor) is in Parameters with a type.

    A dataclass may list its fields, the constructor's parameters, under ``Attributes``.
    ``*args`` and ``**keywords`` must be listed; their type is optional.
    """
    obj = PUBLIC[name]
    parameters = constructor_parameters(obj)
    if not parameters:
        return
    sections = numpydoc_sections(obj.__doc__)
    lines = sections.get("Parameters", [])
    if inspect.isclass(obj) and dataclasses.is_dataclass(obj):
        lines = lines + sections.get("Attributes", [])
    documented = documented_parameters(lines)
    untyped = []
    for parameter in parameters:
        variadic = parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD)
        if parameter.name not in documented:
            untyped.append(f"{parameter.name} (not documented)")
        elif not documented[parameter.name] and not variadic:
            untyped.append(f"{parameter.name} (no type)")
    assert not untyped, f"{name}: " + ", ".join(untyped)


def test_numpydoc_sections_parser():
    doc = """Summary.

    Parameters
    ----------
    a, b : int
        Two.
    c
        No type.
    **keywords
        The rest.

    Examples
    --------
    >>> 1 + 1
    2
    """
    sections = numpydoc_sections(doc)
    assert set(sections) == {"Parameters", "Examples"}
    assert documented_parameters(sections["Parameters"]) == {"a": "int", "b": "int", "c": "", "keywords": ""}
