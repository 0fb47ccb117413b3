"""The energy mode diagnoses non-smooth forces from its own record when it never saw its Context."""

from __future__ import annotations

import warnings

import openmm as mm
import openmm.app as app
import openmm.unit as unit
import pytest

from openmm_alphaprk import AlphaRattleEnergyIntegrator, AlphaRattleIntegrator, NonSmoothForcesWarning
from openmm_alphaprk.integrators.energy_controller import DIAGNOSIS_STEPS


def _rough(water_box) -> mm.System:
    """The same box as ForceField.createSystem makes it: no LJ switch, Ewald tolerance 5e-4."""
    return app.ForceField("amber14/tip3p.xml").createSystem(
        water_box.topology,
        nonbondedMethod=app.PME,
        nonbondedCutoff=0.8 * unit.nanometer,
        removeCMMotion=False,
    )


def _run(system, water_box, steps_per_call: int, total: int = DIAGNOSIS_STEPS + 10) -> AlphaRattleIntegrator:
    integrator = AlphaRattleEnergyIntegrator(0.002, order=4)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setPeriodicBoxVectors(*water_box.state.getPeriodicBoxVectors())
    context.setPositions(water_box.state.getPositions())
    context.setVelocities(water_box.state.getVelocities())
    for _ in range(total // steps_per_call):
        integrator.step(steps_per_call)
    return integrator


def test_rough_forces_are_named_after_the_first_steps_without_check_context(water_box):
    with pytest.warns(NonSmoothForcesWarning, match=r"prepare_for_nve\(system\)") as caught:
        integrator = _run(
            _rough(water_box), water_box, steps_per_call=DIAGNOSIS_STEPS + 10
        )  # one call, split inside
    (warning,) = [w for w in caught if issubclass(w.category, NonSmoothForcesWarning)]
    assert f"of its first {DIAGNOSIS_STEPS} steps outside its energy tolerance" in str(warning.message)
    assert warning.filename == __file__  # said where the user called step()
    assert integrator.steps_taken == DIAGNOSIS_STEPS + 10


def test_a_smooth_system_gets_no_warning(water_box):
    with warnings.catch_warnings():
        warnings.simplefilter("error", NonSmoothForcesWarning)
        integrator = _run(water_box.system, water_box, steps_per_call=30)
    assert integrator.controller_totals()["fraction_fallen_back"] < 0.5
