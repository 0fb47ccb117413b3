"""A drop-in for OpenMM's integrators: what the System's other forces do, and binding to a Context.

RATTLE and fixed α apply barostats, the Andersen thermostat and the CMMotionRemover as
``VerletIntegrator`` does; the energy mode does not and warns. The integrators never look
for their Context: the program counts the System's particles itself at each ``step()``
call, and ``check_context`` is where the platform is seen.
"""

import gc

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest
from conftest import make_context, positions_of, velocities_of

import openmm_alphaprk
from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    IncompatibleSystemError,
    RattleIntegrator,
    StateChangingForceWarning,
    SystemSizeError,
    restore_integrator,
)
from openmm_alphaprk.platforms import default_energy_tolerance

H = 0.002
SEED = 2024
PLATFORMS = ["Reference", "CPU"]
FIXED = {
    "rattle": lambda: RattleIntegrator(H),
    "alpha=1/6": lambda: AlphaRattleIntegrator(H, alpha=1 / 6),
    "alpha4=0": lambda: AlphaRattleIntegrator(H, alpha=0.0, order=4),
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

    A CustomIntegrator reseeds OpenMM's host random numbers with its own seed, and its
    computations draw from them (on Reference/CPU every global and per-DOF one), so an
    update step placed later in one of the programs would meet the barostat with
    other random numbers.
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
        integrator = AlphaRattleEnergyIntegrator(H, order=order)
        context = _context(water_box, [force], integrator, "CPU", drifting)
        with pytest.warns(StateChangingForceWarning, match=name):
            integrator.check_context(context)
        before = measure(context)
        integrator.step(3)
        assert measure(context) == pytest.approx(before, rel=nve, abs=0.0), name  # not applied


# ---------------------------------------------------------- the bound Context
def _particles(masses):
    """Particles (amu) in a harmonic well."""
    system = mm.System()
    well = mm.CustomExternalForce("10*(x^2 + y^2 + z^2)")
    for i, mass in enumerate(masses):
        system.addParticle(mass)
        well.addParticle(i, [])
    system.addForce(well)
    return system


def _start(context, n):
    rng = np.random.default_rng(1)
    context.setPositions(np.column_stack([0.1 * np.arange(n), np.zeros(n), np.zeros(n)]))
    context.setVelocities(rng.normal(0.0, 0.5, (n, 3)))
    context.computeVirtualSites()


@pytest.mark.parametrize("make", [FIXED["rattle"], FIXED["alpha=1/6"], FIXED["alpha4=0"]], ids=list(FIXED))
def test_an_integrator_bound_again_follows_the_edited_system(make):
    """Context.reinitialize() binds the integrator to the edited System afresh; the checks follow it."""
    system = _particles([12.0] * 6)
    integrator = make()
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("Reference"))
    _start(context, 6)
    integrator.step(2)
    assert integrator.getGlobalVariableByName("ndof") == 18
    # a particle without mass: refused at the next step, which is not taken
    system.setParticleMass(5, 0.0)
    context.reinitialize(preserveState=True)
    x, v, steps = positions_of(context), velocities_of(context), integrator.steps_taken
    with pytest.raises(IncompatibleSystemError, match="1 particle.*zero mass.*check_context"):
        integrator.step(3)
    assert integrator.getGlobalVariableByName("ndof") == 15
    assert np.array_equal(positions_of(context), x) and np.array_equal(velocities_of(context), v)
    assert integrator.steps_taken == steps
    # massive again: it runs
    system.setParticleMass(5, 12.0)
    context.reinitialize(preserveState=True)
    integrator.step(2)
    assert integrator.getGlobalVariableByName("ndof") == 18 and integrator.steps_taken == steps + 2
    # a virtual site
    system.setParticleMass(5, 0.0)
    system.setVirtualSite(5, mm.TwoParticleAverageSite(0, 1, 0.5, 0.5))
    context.reinitialize(preserveState=True)
    with pytest.raises(IncompatibleSystemError, match="virtual sites"):
        integrator.step(1)


def test_an_integrator_bound_again_to_a_larger_system_is_refused():
    """OpenMM keeps a CustomIntegrator's per-DOF variables at the size of its first System."""
    system = _particles([12.0] * 6)
    integrator = RattleIntegrator(H)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("Reference"))
    _start(context, 6)
    integrator.step(1)
    system.addParticle(12.0)
    system.getForce(0).addParticle(6, [])
    context.reinitialize()
    _start(context, 7)
    with pytest.raises(SystemSizeError, match="System of 6 particles.*at least 7.*create a new integrator"):
        integrator.step(1)
    assert len(integrator.getPerDofVariableByName("x0")) == 6


def test_check_context_decides_what_depends_on_the_platform():
    system = _particles([12.0, 12.0, 12.0, 0.0])
    system.setVirtualSite(3, mm.TwoParticleAverageSite(0, 1, 0.5, 0.5))
    reference = mm.Platform.getPlatformByName("Reference")
    # not shown the platform: refused at the first step, which is not taken
    rattle = RattleIntegrator(H)
    context = mm.Context(system, rattle, reference)
    _start(context, 4)
    x = positions_of(context)
    with pytest.raises(IncompatibleSystemError, match=r"integrator\.check_context\(context\)"):
        rattle.step(2)
    assert np.array_equal(positions_of(context), x) and rattle.steps_taken == 0
    # shown the Reference platform: refused by check_context, before any step
    rattle = RattleIntegrator(H)
    context = mm.Context(system, rattle, reference)
    with pytest.raises(IncompatibleSystemError, match="on the Reference platform.*index 3"):
        rattle.check_context(context)
    with pytest.raises(IncompatibleSystemError, match="Reference platform"):
        rattle.step(1)
    assert context.getStepCount() == 0
    # α ≠ 0 on any platform
    alpha = AlphaRattleIntegrator(H, alpha=0.5)
    context = mm.Context(system, alpha, reference)
    with pytest.raises(IncompatibleSystemError, match="alpha=0.5.*midpoint"):
        alpha.check_context(context)
    # a Context that runs another integrator
    other = mm.Context(_particles([12.0]), mm.VerletIntegrator(H), reference)
    with pytest.raises(ValueError, match="runs another integrator"):
        RattleIntegrator(H).check_context(other)


@pytest.mark.parametrize(
    ("platform", "precision"), [("Reference", "double"), ("CPU", "mixed"), (None, "single")]
)
def test_the_energy_modes_default_tolerance_follows_the_checked_platform(water_box, platform, precision):
    integrator = AlphaRattleEnergyIntegrator(H, order=4)
    context = _context(water_box, [], integrator, platform or "Reference")
    if platform is not None:
        integrator.check_context(context)
    integrator.step(1)
    expected = default_energy_tolerance(water_box.system.getNumParticles(), precision)
    assert integrator.energy_tolerance.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(expected)


def test_stepping_never_looks_for_the_context_in_the_garbage_collector(water_box, monkeypatch):
    def refuse(*objects):
        raise AssertionError("gc.get_referrers called")

    monkeypatch.setattr(gc, "get_referrers", refuse)
    for integrator in (
        RattleIntegrator(H),
        AlphaRattleIntegrator(H, alpha=0.5),
        AlphaRattleEnergyIntegrator(H),
    ):
        context = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
        integrator.step(2)
        assert integrator.getGlobalVariableByName("ndof") == 3 * water_box.system.getNumParticles()
        del context
    assert not hasattr(openmm_alphaprk.platforms, "find_context")


def test_a_deserialized_plain_copy_counts_its_own_degrees_of_freedom(water_box):
    original = AlphaRattleIntegrator(H, alpha=0.5)
    copy = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(original))  # a plain CustomIntegrator
    contexts = [
        make_context(water_box.system, i, water_box.positions, water_box.velocities) for i in (original, copy)
    ]
    original.step(3)
    copy.step(3)  # OpenMM's step: nothing of this package runs in Python
    assert type(copy) is mm.CustomIntegrator
    assert copy.getGlobalVariableByName("ndof") == 3 * water_box.system.getNumParticles()
    assert np.array_equal(positions_of(contexts[0]), positions_of(contexts[1]))
    assert restore_integrator(copy).midpoint_iterations == original.midpoint_iterations


# ----------------------------------------------------------- rescaling with no call but OpenMM's
def _rescaled_run(system, state, checked: bool, steps: int = 20):
    from openmm_alphaprk import RattleRescaleIntegrator

    integrator = RattleRescaleIntegrator(H)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setState(state)
    if checked:
        integrator.check_context(context)
    integrator.step(steps)
    return integrator, context


@pytest.mark.parametrize("name, rotation", [("water-cluster", True), ("tip3p-2nm", False)])
def test_rescaling_decides_the_rigid_motion_it_keeps_without_check_context(name, rotation):
    """no periodic box: P and L kept; a box: P alone, the fast path, the same steps as after check_context."""
    from openmm_alphaprk.systems import prepare_system

    prepared = prepare_system(name)
    plain, plain_context = _rescaled_run(prepared.system, prepared.state, checked=False)
    checked, checked_context = _rescaled_run(prepared.system, prepared.state, checked=True)
    assert (plain.removes_rotation, plain.removes_translation) == (rotation, True)
    assert (checked.removes_rotation, checked.removes_translation) == (rotation, True)
    # the same steps (the CPU platform's threads make two runs of one program differ by ~1e-8 nm)
    np.testing.assert_allclose(positions_of(plain_context), positions_of(checked_context), rtol=0, atol=1e-6)
    # the decision's own sums come once, with E_ref: per step the two programs sum alike
    assert plain.host_syncs_per_step - checked.host_syncs_per_step <= 12 / 20
    state = plain_context.getState(getEnergy=True)
    residual = state.getKineticEnergy() + state.getPotentialEnergy() - plain.reference_energy
    assert abs(residual) < plain.energy_tolerance


def test_rescaling_one_particle_in_an_external_well_needs_no_check_context():
    """a particle in a harmonic well (openmmtools' HarmonicOscillator): every velocity scaled, H held."""
    from openmm_alphaprk import RattleRescaleIntegrator

    system = mm.System()
    system.addParticle(39.9)
    well = mm.CustomExternalForce("0.5*100*(x^2 + y^2 + z^2)")
    well.addParticle(0, [])
    system.addForce(well)
    integrator = RattleRescaleIntegrator(H)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("Reference"))
    context.setPositions([[0.0, 0.0, 0.0]])  # at the minimum: no force at the state E_ref is taken from
    context.setVelocities([[0.3, 0.1, 0.0]])
    integrator.step(200)
    assert not integrator.removes_translation
    state = context.getState(getEnergy=True)
    residual = state.getKineticEnergy() + state.getPotentialEnergy() - integrator.reference_energy
    assert abs(residual) < integrator.energy_tolerance and integrator.rescalings == 200
