"""A start whose velocities move along the constraints: measured, and warned about before E_ref is taken."""

import warnings

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest
from conftest import REFERENCE, total_energy, velocities_of

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    RattleRescaleIntegrator,
    UnconstrainedVelocitiesWarning,
)
from openmm_alphaprk.nve import velocity_constraint_energy
from openmm_alphaprk.observables import masses

H = 0.002
HOLDING = {
    "rattle+rescale": lambda: RattleRescaleIntegrator(H),
    "rattle+rescale@10": lambda: RattleRescaleIntegrator(H, rescale_interval=10),
    "energy": lambda: AlphaRattleEnergyIntegrator(H),
}


@pytest.fixture(scope="module")
def langevin_state(water_box):
    """The water box after 5 steps of OpenMM's LangevinMiddleIntegrator, its velocities as it leaves them."""
    integrator = mm.LangevinMiddleIntegrator(300 * unit.kelvin, 1 / unit.picosecond, H)
    integrator.setRandomNumberSeed(7)
    context = mm.Context(water_box.system, integrator, REFERENCE)
    context.setState(water_box.state)
    integrator.step(5)
    return context.getState(getPositions=True, getVelocities=True)


def _context(water_box, integrator, state):
    context = mm.Context(water_box.system, integrator, REFERENCE)
    context.setState(state)
    return context


def test_a_langevin_state_moves_along_the_constraints_and_the_measure_leaves_it_as_it_was(
    water_box, langevin_state
):
    context = _context(water_box, mm.VerletIntegrator(H), langevin_state)
    before = velocities_of(context)
    along, kinetic = velocity_constraint_energy(context)
    assert np.array_equal(velocities_of(context), before)  # put back
    m = masses(water_box.system)
    context.applyVelocityConstraints(1e-12)
    projected = velocities_of(context)
    expected = 0.5 * float((m[:, None] * (before**2 - projected**2)).sum())
    assert along == pytest.approx(expected, rel=1e-6) and 1e-4 < along / kinetic < 1e-2
    assert velocity_constraint_energy(context)[0] < 1e-8 * kinetic  # once projected: nothing left


@pytest.mark.parametrize("name", list(HOLDING))
def test_the_first_step_warns_and_names_the_fix_and_e_ref_is_the_given_states(
    water_box, langevin_state, name
):
    integrator = HOLDING[name]()
    context = _context(water_box, integrator, langevin_state)
    integrator.check_context(context)
    given = total_energy(context)
    with pytest.warns(UnconstrainedVelocitiesWarning, match=r"applyVelocityConstraints\(1e-10\)") as caught:
        integrator.step(2)
    assert len([w for w in caught if w.category is UnconstrainedVelocitiesWarning]) == 1
    # the check put the velocities back: E_ref is the energy of the state as it was given
    assert integrator.reference_energy.value_in_unit(unit.kilojoule_per_mole) == pytest.approx(
        given, abs=1e-6
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnconstrainedVelocitiesWarning)
        integrator.step(2)  # once per start


@pytest.mark.parametrize("name", list(HOLDING))
def test_a_projected_start_is_not_warned_about(water_box, langevin_state, name):
    integrator = HOLDING[name]()
    context = _context(water_box, integrator, langevin_state)
    context.applyVelocityConstraints(1e-10)
    integrator.check_context(context)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnconstrainedVelocitiesWarning)
        integrator.step(2)
    # a new start set and E_ref asked for again: looked at again
    context.setState(langevin_state)
    integrator.reset_reference_energy()
    with pytest.warns(UnconstrainedVelocitiesWarning):
        integrator.step(1)
