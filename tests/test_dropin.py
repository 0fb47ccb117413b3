"""A drop-in for OpenMM's integrators: what the System's other forces do.

RATTLE and fixed α apply barostats, the Andersen thermostat and the CMMotionRemover as
``VerletIntegrator`` does; the energy mode does not and warns.
"""

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest
from conftest import make_context, velocities_of

from openmm_alphaprk import (
    AlphaRattleIntegrator,
    RattleIntegrator,
    StateChangingForceWarning,
)

H = 0.002
SEED = 2024
PLATFORMS = ["Reference", "CPU"]
FIXED = {
    "rattle": lambda: RattleIntegrator(H),
    "alpha=1/6": lambda: AlphaRattleIntegrator(H, 1 / 6),
    "alpha4=0": lambda: AlphaRattleIntegrator(H, 0.0, order=4),
}
WITH_VERLET = {"verlet": lambda: mm.VerletIntegrator(H), **FIXED}


def _with(system, *forces):
    copy = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(system))
    for force in forces:
        copy.addForce(force)
    return copy


def _seeded(integrator):
    """The integrator, seeded: a CustomIntegrator reseeds the host random numbers that barostats draw."""
    if isinstance(integrator, mm.CustomIntegrator):
        integrator.setRandomNumberSeed(SEED)
    return integrator


def _context(box, forces, integrator, platform, velocities=None):
    system = _with(box.system, *forces)
    velocities = box.velocities if velocities is None else velocities
    return make_context(
        system, integrator, box.positions, velocities, mm.Platform.getPlatformByName(platform)
    )


def _barostat(frequency):
    barostat = mm.MonteCarloBarostat(1.0 * unit.bar, 300.0 * unit.kelvin, frequency)
    barostat.setRandomNumberSeed(SEED)
    return barostat


def _volume(context):
    return context.getState().getPeriodicBoxVolume().value_in_unit(unit.nanometer**3)


def _volumes(box, integrator, platform, frequency, steps):
    context = _context(box, [_barostat(frequency)], _seeded(integrator), platform)
    volumes = [_volume(context)]
    for _ in range(steps):
        integrator.step(1)
        volumes.append(_volume(context))
    return np.array(volumes)


def _kinetic(context):
    return context.getState(getEnergy=True).getKineticEnergy().value_in_unit(unit.kilojoules_per_mole)


def _momentum(context):
    system = context.getSystem()
    masses = np.array(
        [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    )
    return masses @ velocities_of(context)


# ----------------------------------------------- forces applied between steps
@pytest.mark.parametrize("platform", PLATFORMS)
def test_a_barostat_moves_the_box_at_its_frequency_as_under_verlet(water_box, platform):
    frequency, steps = 3, 24
    for name, make in WITH_VERLET.items():
        volumes = _volumes(water_box, make(), platform, frequency, steps)
        moved = np.flatnonzero(np.diff(volumes)) + 1  # the steps after which the volume had changed
        assert len(moved) >= 2, name  # accepted moves
        assert np.all(moved % frequency == 0), (name, moved)  # at the barostat's steps only


@pytest.mark.parametrize("platform", PLATFORMS)
def test_every_fixed_alpha_program_makes_the_barostats_first_move_before_anything_else(water_box, platform):
    """The update-context-state step is the first computation: the same seed gives the same first move.

    A CustomIntegrator reseeds OpenMM's host random numbers with its own seed, and
    each of its global computations draws from them, so a later step in a program
    would meet the barostat with another random number.
    """
    first = {name: _volumes(water_box, make(), platform, 1, 1) for name, make in FIXED.items()}
    start = first["rattle"][0]
    assert len({volumes[1] for volumes in first.values()}) == 1
    assert first["rattle"][1] != start


@pytest.mark.parametrize("platform", PLATFORMS)
def test_an_andersen_thermostat_heats_the_box_as_under_verlet(water_box, platform):
    for name, make in WITH_VERLET.items():
        thermostat = mm.AndersenThermostat(3000.0 * unit.kelvin, 100.0 / unit.picosecond)  # 1 in 5 per step
        integrator = make()
        context = _context(water_box, [thermostat], integrator, platform)
        before = _kinetic(context)
        integrator.step(5)
        assert _kinetic(context) > 3.0 * before, name


@pytest.mark.parametrize("platform", PLATFORMS)
def test_a_cmmotion_remover_removes_the_centre_of_mass_momentum_as_under_verlet(water_box, platform):
    drifting = water_box.velocities + np.array([1.0, -0.5, 0.25])  # nm/ps, every particle
    for name, make in WITH_VERLET.items():
        integrator = make()
        context = _context(water_box, [mm.CMMotionRemover()], integrator, platform, drifting)
        before = np.linalg.norm(_momentum(context))
        integrator.step(1)
        assert np.linalg.norm(_momentum(context)) < 1e-6 * before, name


@pytest.mark.parametrize("order", [2, 4])
def test_the_energy_mode_warns_about_each_force_it_does_not_apply(water_box, order):
    drifting = water_box.velocities + np.array([1.0, -0.5, 0.25])
    cases = [  # what the force would change, and how much of that change is NVE's own
        (_barostat(1), "MonteCarloBarostat", _volume, 0.0),
        (mm.AndersenThermostat(3000.0, 100.0), "AndersenThermostat", _kinetic, 0.1),
        (mm.CMMotionRemover(), "CMMotionRemover", lambda context: _momentum(context)[0], 1e-6),
    ]
    for force, name, measure, nve in cases:
        integrator = AlphaRattleIntegrator(H, "energy", order=order)
        context = _context(water_box, [force], integrator, "CPU", drifting)
        before = measure(context)
        with pytest.warns(StateChangingForceWarning, match=name):
            integrator.step(3)
        assert measure(context) == pytest.approx(before, rel=nve, abs=0.0), name  # not applied
