"""The α* controller recovers from the states that broke it, and is never worse than RATTLE.

Regression cases from measured failures (issue 13): the *dead controller* (order 2:
the slope scale S̄ inflated to ~6e8 kJ/mol by secants over noise-sized moves of α,
after which every Newton step was damped to nothing) and the *limit cycle* (order 4
on villin: α swinging across its whole move limit every step while H − E_ref grew).
Both are reproduced here from a constructed controller state on a small box.
"""

from __future__ import annotations

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
import pytest
from conftest import REFERENCE, make_context, total_energy

from openmm_alphaprk import AlphaRattleIntegrator, RattleIntegrator, make_smooth

CPU = mm.Platform.getPlatformByName("CPU")
#: S̄ measured in the dead state (2,661-atom water box, order 2).
DEAD_SLOPE_SCALE = 5.9e8


def _energy_mode(order: int) -> AlphaRattleIntegrator:
    return AlphaRattleIntegrator(2 * unit.femtosecond, alpha="energy", order=order, energy_tolerance=0.01)


def test_inflated_slope_scale_recovers_within_a_dozen_steps(water_box):
    integrator = _energy_mode(2)
    context = make_context(water_box.system, integrator, water_box.positions, water_box.velocities, CPU)
    integrator.step(10)
    healthy = integrator.getGlobalVariableByName("slope_scale")
    integrator.setGlobalVariableByName("slope_scale", DEAD_SLOPE_SCALE)
    integrator.step(15)
    assert context.getStepCount() == 25
    # the old running mean (0.9 per step) would still be at ~1e8 here
    assert integrator.getGlobalVariableByName("slope_scale") < 100 * healthy


def test_residual_beyond_alpha_authority_is_reduced_not_grown(water_box):
    """Order 4 with E_ref moved 10 kJ/mol away: α's small authority walks the residual back.

    A property of the controller, not the villin limit cycle itself (which this
    constructed case does not reproduce; see docs/energy_mode.md).
    """
    integrator = _energy_mode(4)
    context = make_context(water_box.system, integrator, water_box.positions, water_box.velocities, CPU)
    integrator.step(5)
    integrator.setGlobalVariableByName("reference_energy", total_energy(context) + 10.0)
    residuals = []
    for _ in range(60):
        integrator.step(1)
        residuals.append(abs(integrator.getGlobalVariableByName("residual")))
    assert max(residuals) < 10.5
    assert residuals[-1] < 9.0, residuals[::10]


def _rms_and_max(integrator: mm.Integrator, system, positions, velocities, steps: int, platform):
    context = make_context(system, integrator, positions, velocities, platform)
    start = total_energy(context)
    residuals = np.empty(steps)
    for i in range(steps):
        integrator.step(1)
        residuals[i] = total_energy(context) - start
    return float(np.sqrt(np.mean(residuals**2))), float(np.abs(residuals).max())


ORDER2_NOT_YET = pytest.mark.xfail(
    strict=True,
    reason="order 2 is not yet never-worse than RATTLE (issue 13; measured in docs/energy_mode.md)",
)


@pytest.mark.parametrize("order", [2, 4])
def test_energy_modes_never_worse_than_rattle_on_a_water_box(water_box, order):
    args = (water_box.system, water_box.positions, water_box.velocities, 200, REFERENCE)
    rattle_rms, rattle_max = _rms_and_max(RattleIntegrator(2 * unit.femtosecond), *args)
    rms, worst = _rms_and_max(_energy_mode(order), *args)
    assert rms <= rattle_rms and worst <= rattle_max, (rms, rattle_rms, worst, rattle_max)


@pytest.fixture(scope="module")
def solute_in_vacuum():
    """Villin headpiece (OpenMM's test.pdb) without water, in vacuum, X–H bonds constrained."""
    pdb = app.PDBFile(str(__import__("pathlib").Path(app.__file__).parent / "data" / "test.pdb"))
    modeller = app.Modeller(pdb.topology, pdb.positions)
    modeller.delete([r for r in modeller.topology.residues() if r.name.upper() in ("HOH", "CL", "NA")])
    forcefield = app.ForceField("amber14-all.xml")
    system = forcefield.createSystem(
        modeller.topology, nonbondedMethod=app.NoCutoff, constraints=app.HBonds, removeCMMotion=False
    )
    make_smooth(system)
    integrator = mm.LangevinMiddleIntegrator(300, 5, 0.002)
    integrator.setRandomNumberSeed(11)
    context = mm.Context(system, integrator, CPU)
    context.setPositions(modeller.positions)
    mm.LocalEnergyMinimizer.minimize(context, 10.0, 200)
    context.setVelocitiesToTemperature(300, 11)
    integrator.step(500)
    state = context.getState(getPositions=True, getVelocities=True)
    return system, state.getPositions(asNumpy=True), state.getVelocities(asNumpy=True)


@pytest.mark.parametrize("order", [pytest.param(2, marks=ORDER2_NOT_YET), 4])
def test_energy_modes_never_worse_than_rattle_on_a_solute_with_hbond_constraints(solute_in_vacuum, order):
    system, positions, velocities = solute_in_vacuum
    args = (system, positions, velocities, 300, REFERENCE)
    rattle_rms, rattle_max = _rms_and_max(RattleIntegrator(2 * unit.femtosecond), *args)
    rms, worst = _rms_and_max(_energy_mode(order), *args)
    assert rms <= rattle_rms and worst <= rattle_max, (rms, rattle_rms, worst, rattle_max)
