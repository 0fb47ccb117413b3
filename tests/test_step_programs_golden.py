"""Every step program, computation for computation, against a stored listing.

The listings in ``tests/golden/step_programs.txt`` were written by this test; a change
to a program (a reordered piece, a renamed variable, a changed default) fails here
until the listing is written again on purpose::

    ALPHAPRK_UPDATE_GOLDEN=1 pytest tests/test_step_programs_golden.py
"""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path

import openmm as mm

from openmm_alphaprk import AlphaRattleEnergyIntegrator, AlphaRattleIntegrator, RattleRescaleIntegrator
from openmm_alphaprk.runs.integrator_names import example_names, make_integrator

GOLDEN = Path(__file__).parent / "golden" / "step_programs.txt"

#: Every form the registry names (``example_names``: each family, order, set and layer, every
#: named splitting), made by name at 2 fs, and the options no name reaches: α on every stage, the
#: rescaling after a fixed α and the energy mode over a splitting (combinations of a layer and a
#: base that no name offers).
INTEGRATORS = {
    **{name: partial(make_integrator, name, 0.002) for name in example_names() if name != "verlet"},
    "AlphaRattleIntegrator(0.002, alpha=0.01, order=4, alpha_stages='all')": lambda: AlphaRattleIntegrator(
        0.002, alpha=0.01, order=4, alpha_stages="all"
    ),
    "RattleRescaleIntegrator(0.002, alpha=0.1)": lambda: RattleRescaleIntegrator(0.002, alpha=0.1),
    "RattleRescaleIntegrator(0.002, alpha=0.01, order=4)": lambda: RattleRescaleIntegrator(
        0.002, alpha=0.01, order=4
    ),
    "RattleRescaleIntegrator(0.002, alpha=0.1, rescale_interval=10)": lambda: RattleRescaleIntegrator(
        0.002, alpha=0.1, rescale_interval=10
    ),
    "AlphaRattleEnergyIntegrator(0.002, splitting='me2')": lambda: AlphaRattleEnergyIntegrator(
        0.002, splitting="me2"
    ),
}


def describe(integrator: mm.CustomIntegrator) -> str:
    """The program listing, then every global with its value and every per-DOF variable."""
    globals_ = [
        f"global {integrator.getGlobalVariableName(i)} = {integrator.getGlobalVariable(i)!r}"
        for i in range(integrator.getNumGlobalVariables())
    ]
    per_dof = [
        f"per-dof {integrator.getPerDofVariableName(i)}" for i in range(integrator.getNumPerDofVariables())
    ]
    settings = [
        f"step size {integrator.getStepSize()!r}",
        f"constraint tolerance {integrator.getConstraintTolerance()!r}",
    ]
    return "\n".join([integrator.program_listing(), *globals_, *per_dof, *settings])


def all_descriptions() -> str:
    return "".join(f"=== {name}\n{describe(make())}\n" for name, make in INTEGRATORS.items())


def test_every_step_program_is_the_stored_one():
    text = all_descriptions()
    if os.environ.get("ALPHAPRK_UPDATE_GOLDEN"):
        GOLDEN.parent.mkdir(exist_ok=True)
        GOLDEN.write_text(text)
    stored = GOLDEN.read_text()
    for name, block in zip(INTEGRATORS, stored.split("=== ")[1:], strict=True):
        assert block == f"{name}\n{describe(INTEGRATORS[name]())}\n", f"the step program of {name} changed"
    assert text == stored


def test_the_documented_listings_are_the_programs():
    """docs/step_programs.md, linked from the integrators' docstrings, is what the package builds now."""
    from tools.reports.step_programs import PAGE, page_text

    assert PAGE.read_text(encoding="utf-8") == page_text(), "run python -m tools.reports.step_programs"
