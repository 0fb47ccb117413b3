"""A plain-number timestep above 10 fs warns that OpenMM reads plain numbers in picoseconds."""

import warnings

import openmm.unit as unit
import pytest

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    RattleIntegrator,
    TimestepUnitWarning,
)


@pytest.mark.parametrize("make", [AlphaRattleIntegrator, RattleIntegrator])
def test_a_plain_two_is_two_picoseconds_and_warns_at_the_callers_line(make):
    with pytest.warns(TimestepUnitWarning, match=r"plain number.*2000 fs.*2 \* unit.femtoseconds") as caught:
        integrator = make(2)
    assert caught[0].filename == __file__  # points at the user's call, not the package
    assert integrator.getStepSize() == 2.0 * unit.picoseconds  # OpenMM's convention kept, only flagged


@pytest.mark.parametrize(
    "timestep", [0.002, 0.01, 2 * unit.femtoseconds, 20 * unit.femtoseconds, 0.004 * unit.picoseconds]
)
def test_plain_steps_up_to_10_fs_and_any_quantity_do_not_warn(timestep):
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimestepUnitWarning)
        AlphaRattleEnergyIntegrator(timestep, order=4)
        RattleIntegrator(timestep)


def test_the_vocabulary_takes_plain_picoseconds_on_purpose():
    """The CLI converts ``--timestep 20fs`` to 0.02 ps; that must not warn as if the user wrote 0.02."""
    from openmm_alphaprk.runs.integrator_names import make_integrator

    with warnings.catch_warnings():
        warnings.simplefilter("error", TimestepUnitWarning)
        for name in ("rattle", "alpha=1/6", "energy4", "verlet"):
            assert make_integrator(name, 0.02).getStepSize() == 0.02 * unit.picoseconds
