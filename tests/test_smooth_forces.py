"""Smooth forces (make_smooth, smoothness_problems, state_changing_forces), the energy mode's warnings,
and StartBlowUpError."""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
import pytest

import openmm_alphaprk
from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    NonSmoothForcesWarning,
    RattleIntegrator,
    StartBlowUpError,
    StateChangingForceWarning,
    make_smooth,
    prepare_for_nve,
    smoothness_problems,
    state_changing_forces,
)
from openmm_alphaprk import start_blowup as start_blowup_module
from openmm_alphaprk.smooth_forces import SMOOTH_EWALD_TOLERANCE


@pytest.fixture(scope="module")
def water():
    """A ~2 nm TIP3P box from Modeller, briefly minimized with OpenMM's default (unsmooth) PME."""
    forcefield = app.ForceField("amber14/tip3p.xml")
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, model="tip3p", boxSize=mm.Vec3(2.0, 2.0, 2.0) * unit.nanometers)
    system = _create(forcefield, modeller.topology)
    context = mm.Context(system, mm.VerletIntegrator(0.001), mm.Platform.getPlatformByName("CPU"))
    context.setPositions(modeller.positions)
    mm.LocalEnergyMinimizer.minimize(context, 10.0, 50)
    positions = context.getState(getPositions=True).getPositions()
    return forcefield, modeller.topology, positions


def _create(forcefield, topology, **kwargs):
    return forcefield.createSystem(
        topology,
        nonbondedMethod=app.PME,
        nonbondedCutoff=0.9 * unit.nanometers,
        constraints=app.HBonds,
        rigidWater=True,
        removeCMMotion=False,
        **kwargs,
    )


def _context(system, integrator, positions, platform="CPU"):
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName(platform))
    context.setPositions(positions)
    context.setVelocitiesToTemperature(300, 7)
    context.applyVelocityConstraints(1e-10)
    return context


def _ours(record):
    return [w for w in record if issubclass(w.category, NonSmoothForcesWarning)]


# ------------------------------------------------------------------ the warning
@pytest.mark.parametrize("order", [2, 4])
def test_energy_mode_warns_at_check_context_pointing_at_the_users_call(water, order):
    forcefield, topology, positions = water
    integrator = AlphaRattleEnergyIntegrator(0.001, order=order)
    context = _context(_create(forcefield, topology), integrator, positions)
    with pytest.warns(NonSmoothForcesWarning, match="without a switching function") as record:
        integrator.check_context(context)
    (warning,) = _ours(record)
    assert warning.filename == __file__  # the line above, not inside the package
    assert "Ewald error tolerance of 0.0005" in str(warning.message)
    assert "openmm_alphaprk.make_smooth(system)" in str(warning.message)
    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        integrator.step(2)
    assert not _ours(again)  # the check is not repeated at every step
    del context


def test_energy_mode_without_check_context_cannot_see_the_system_and_says_nothing(water):
    """Without check_context the integrator cannot see its System: no warning, the noisiest tolerance."""
    forcefield, topology, positions = water
    integrator = AlphaRattleEnergyIntegrator(0.001, composition="triple-jump")
    context = _context(_create(forcefield, topology), integrator, positions)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        integrator.step(1)
    assert not _ours(record)
    atoms = context.getSystem().getNumParticles()
    single = openmm_alphaprk.platforms.default_energy_tolerance(atoms, "single")
    assert integrator.energy_tolerance.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(single)
    with pytest.warns(NonSmoothForcesWarning):
        integrator.check_context(context)
    mixed = openmm_alphaprk.platforms.default_energy_tolerance(atoms, "mixed")  # the CPU platform
    assert integrator.energy_tolerance.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(mixed)
    assert mixed < 0.8 * single


def test_a_barostat_added_before_reinitialize_is_reported_at_the_next_step_at_the_users_line(water):
    forcefield, topology, positions = water
    system = _create(forcefield, topology)
    make_smooth(system)
    integrator = AlphaRattleEnergyIntegrator(0.001, composition="triple-jump")
    simulation = app.Simulation(topology, system, integrator, mm.Platform.getPlatformByName("CPU"))
    simulation.context.setPositions(positions)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        integrator.check_context(simulation.context)
        simulation.step(1)
    assert not [
        w for w in record if issubclass(w.category, (NonSmoothForcesWarning, StateChangingForceWarning))
    ]
    system.addForce(mm.MonteCarloBarostat(1.0, 300.0))
    simulation.context.reinitialize(preserveState=True)
    with pytest.warns(StateChangingForceWarning, match="MonteCarloBarostat") as record:
        simulation.step(1)
    (warning,) = [w for w in record if issubclass(w.category, StateChangingForceWarning)]
    assert warning.filename == __file__  # not openmm/app/simulation.py


def test_no_warning_after_make_smooth(water):
    forcefield, topology, positions = water
    system = _create(forcefield, topology)
    assert len(make_smooth(system)) == 2  # switch on, Ewald tightened
    assert smoothness_problems(system) == []
    integrator = AlphaRattleEnergyIntegrator(0.001, composition="triple-jump")
    context = _context(system, integrator, positions)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        integrator.check_context(context)
        integrator.step(2)
    assert not _ours(record)
    del context


@pytest.mark.parametrize(
    "make",
    [
        lambda: AlphaRattleIntegrator(0.001, alpha=0.1),
        lambda: AlphaRattleIntegrator(0.001, alpha=0.0, composition="triple-jump"),
        lambda: RattleIntegrator(0.001),
    ],
    ids=["alpha=0.1", "alpha4=0", "rattle"],
)
def test_fixed_alpha_and_rattle_do_not_warn(water, make):
    forcefield, topology, positions = water
    integrator = make()
    system = _create(forcefield, topology)
    system.addForce(mm.CMMotionRemover())
    context = _context(system, integrator, positions)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        integrator.check_context(context)
        integrator.step(2)
    assert not [
        w for w in record if issubclass(w.category, (NonSmoothForcesWarning, StateChangingForceWarning))
    ]
    del context


# ------------------------------------------------------- smoothness_problems
def _particles(force, n=2):
    for _ in range(n):
        if isinstance(force, mm.NonbondedForce):
            force.addParticle(0.0, 0.3, 0.5)
        else:
            force.addParticle([])
    return force


def _small_system(*forces):
    system = mm.System()
    for _ in range(2):
        system.addParticle(16.0)
    system.setDefaultPeriodicBoxVectors(mm.Vec3(3, 0, 0), mm.Vec3(0, 3, 0), mm.Vec3(0, 0, 3))
    for force in forces:
        system.addForce(force)
    return system


def _nonbonded(method=mm.NonbondedForce.PME, switch=0.8, ewald=1e-5):
    force = _particles(mm.NonbondedForce())
    force.setNonbondedMethod(method)
    force.setCutoffDistance(0.9)
    if switch is not None:
        force.setUseSwitchingFunction(True)
        force.setSwitchingDistance(switch)
    force.setEwaldErrorTolerance(ewald)
    return force


def _custom(switch=None):
    force = _particles(mm.CustomNonbondedForce("4*((0.3/r)^12 - (0.3/r)^6)"))
    force.setNonbondedMethod(mm.CustomNonbondedForce.CutoffPeriodic)
    force.setCutoffDistance(0.9)
    if switch is not None:
        force.setUseSwitchingFunction(True)
        force.setSwitchingDistance(switch)
    return force


@pytest.mark.parametrize(
    ("force", "words"),
    [
        (lambda: _nonbonded(ewald=5e-4), ["Ewald error tolerance of 0.0005", "make_smooth(system)"]),
        (lambda: _nonbonded(method=mm.NonbondedForce.LJPME, ewald=1e-4), ["tolerance of 0.0001"]),
        (lambda: _nonbonded(switch=None), ["NonbondedForce", "without a switching function", "make_smooth"]),
        (lambda: _custom(), ["CustomNonbondedForce", "without a switching function", "make_smooth"]),
    ],
    ids=["loose-pme", "loose-ljpme", "unswitched", "unswitched-custom"],
)
def test_each_problem_is_reported_with_its_fix(force, words):
    system = _small_system(_nonbonded(), force())
    (problem,) = smoothness_problems(system)
    for word in words:
        assert word in problem
    assert "(force 1)" in problem
    assert state_changing_forces(system) == []


@pytest.mark.parametrize(
    ("force", "words"),
    [
        (lambda: mm.CMMotionRemover(), ["CMMotionRemover", "removeCMMotion=False", "3 degrees of freedom"]),
        (lambda: mm.MonteCarloBarostat(1.0, 300.0), ["MonteCarloBarostat", "remove the barostat", "NVE"]),
        (
            lambda: mm.MonteCarloAnisotropicBarostat(mm.Vec3(1, 1, 1), 300.0),
            ["MonteCarloAnisotropicBarostat", "NVE"],
        ),
        (
            lambda: mm.MonteCarloMembraneBarostat(
                1.0,
                0.0,
                300.0,
                mm.MonteCarloMembraneBarostat.XYIsotropic,
                mm.MonteCarloMembraneBarostat.ZFree,
            ),
            ["MonteCarloMembraneBarostat", "NVE"],
        ),
        (lambda: mm.MonteCarloFlexibleBarostat(1.0, 300.0), ["MonteCarloFlexibleBarostat", "NVE"]),
        (lambda: mm.AndersenThermostat(300.0, 1.0), ["AndersenThermostat", "No temperature is imposed"]),
    ],
    ids=["cmmotion", "barostat", "anisotropic", "membrane", "flexible", "andersen"],
)
def test_each_state_changing_force_is_reported_apart_from_smoothness(force, words):
    system = _small_system(_nonbonded(), force())
    (message,) = state_changing_forces(system)
    for word in [*words, "the energy mode does not apply it", "RattleIntegrator"]:
        assert word in message
    assert "(force 1)" in message
    assert smoothness_problems(system) == []


def test_a_smooth_system_and_forces_without_cutoff_have_no_problems():
    no_cutoff = _nonbonded(method=mm.NonbondedForce.NoCutoff, switch=None, ewald=5e-4)
    assert smoothness_problems(_small_system(_nonbonded(), _custom(switch=0.85), no_cutoff)) == []


def test_warn_if_not_smooth_issues_one_warning_listing_every_problem():
    system = _small_system(_nonbonded(switch=None, ewald=5e-4), mm.CMMotionRemover())
    with pytest.warns(NonSmoothForcesWarning) as record:
        assert openmm_alphaprk.smooth_forces.warn_if_not_smooth(system, stacklevel=1)
    assert len(record) == 1 and str(record[0].message).count("\n  - ") == 2
    assert "CMMotionRemover" not in str(record[0].message)
    assert record[0].filename == __file__
    assert not openmm_alphaprk.smooth_forces.warn_if_not_smooth(_small_system(_nonbonded()))


def test_warn_if_state_changing_issues_one_warning_of_its_own_class():
    system = _small_system(_nonbonded(switch=None), mm.CMMotionRemover(), mm.AndersenThermostat(300.0, 1.0))
    with pytest.warns(StateChangingForceWarning) as record:
        assert openmm_alphaprk.nve.warn_if_state_changing(system, stacklevel=1)
    (warning,) = record
    assert not issubclass(warning.category, NonSmoothForcesWarning)
    assert str(warning.message).count("\n  - ") == 2 and "switching" not in str(warning.message)
    assert warning.filename == __file__
    assert not openmm_alphaprk.nve.warn_if_state_changing(_small_system(_nonbonded(switch=None)))


# ------------------------------------------------------------------ make_smooth
def _attribute_changes(before: str, after: str) -> set[tuple[int, str, str, str]]:
    """(force index, attribute, old, new) for every attribute that differs between two System XMLs."""
    old_root, new_root = ET.fromstring(before), ET.fromstring(after)
    old_elements, new_elements = list(old_root.iter()), list(new_root.iter())
    assert [e.tag for e in old_elements] == [e.tag for e in new_elements]  # same structure
    forces = list(old_root.find("Forces"))
    owner = {id(sub): i for i, force in enumerate(forces) for sub in force.iter()}
    changes = set()
    for old, new in zip(old_elements, new_elements):
        assert old.text == new.text
        for key in set(old.attrib) | set(new.attrib):
            if old.attrib.get(key) != new.attrib.get(key):
                changes.add((owner.get(id(old), -1), key, old.attrib.get(key), new.attrib.get(key)))
    return changes


def test_make_smooth_changes_exactly_what_it_says(water):
    forcefield, topology, _ = water
    system = _create(forcefield, topology)  # NonbondedForce: PME, no switch, Ewald 5e-4
    custom = _particles(mm.CustomNonbondedForce("0"), system.getNumParticles())
    custom.setNonbondedMethod(mm.CustomNonbondedForce.CutoffPeriodic)
    custom.setCutoffDistance(1.0)
    custom.setUseSwitchingFunction(True)
    custom.setSwitchingDistance(0.95)  # switched, but over less than 0.1 nm: moved to 0.9
    close = _particles(mm.CustomNonbondedForce("0"), system.getNumParticles())
    close.setNonbondedMethod(mm.CustomNonbondedForce.CutoffPeriodic)
    close.setCutoffDistance(0.9)
    close.setUseSwitchingFunction(True)
    close.setSwitchingDistance(0.5)  # already switched from further in: left alone
    custom_index = system.addForce(custom)
    system.addForce(close)
    nonbonded_index = next(i for i, f in enumerate(system.getForces()) if isinstance(f, mm.NonbondedForce))
    before = mm.XmlSerializer.serialize(system)
    lines = make_smooth(system)
    after = mm.XmlSerializer.serialize(system)
    assert _attribute_changes(before, after) == {
        (nonbonded_index, "useSwitchingFunction", "0", "1"),
        (nonbonded_index, "switchingDistance", "-1", ".8"),
        (nonbonded_index, "ewaldTolerance", ".0005", "1e-05"),
        (custom_index, "switchingDistance", ".95", ".9"),
    }
    assert len(lines) == 3
    assert any(
        f"(force {nonbonded_index})" in x and "no switching function → switching from 0.8 nm" in x
        for x in lines
    )
    assert any(f"(force {nonbonded_index})" in x and "0.0005 → 1e-05" in x for x in lines)
    assert any(f"(force {custom_index})" in x and "0.95 nm → switching from 0.9 nm" in x for x in lines)
    assert make_smooth(system) == [] and mm.XmlSerializer.serialize(system) == after  # idempotent


@pytest.mark.parametrize("width", [0.2, 0.2 * unit.nanometers, 2.0 * unit.angstroms])
def test_make_smooth_takes_quantities_or_nanometres(width):
    system = _small_system(_nonbonded(switch=None, ewald=1e-6))
    (line,) = make_smooth(system, switch_width=width)  # Ewald 1e-6 is tighter: kept
    force = system.getForce(0)
    assert force.getSwitchingDistance().value_in_unit(unit.nanometers) == pytest.approx(0.7)
    assert force.getEwaldErrorTolerance() == 1e-6 and "0.7 nm" in line


def test_make_smooth_refuses_a_switch_wider_than_the_cutoff_and_changes_nothing():
    system = _small_system(_nonbonded(switch=None, ewald=5e-4))
    before = mm.XmlSerializer.serialize(system)
    with pytest.raises(
        ValueError, match=r"cutoff 0.9 nm minus switch_width 1 nm .*switch_width below 0.9 nm"
    ):
        make_smooth(system, switch_width=1.0)
    assert mm.XmlSerializer.serialize(system) == before


# ------------------------------------------------------------------ prepare_for_nve
def test_prepare_for_nve_readies_a_default_create_system_and_the_energy_mode_does_not_warn(water):
    forcefield, topology, positions = water
    system = forcefield.createSystem(  # OpenMM's defaults: CMMotionRemover, no switch, Ewald 5e-4
        topology, nonbondedMethod=app.PME, nonbondedCutoff=0.9 * unit.nanometers, constraints=app.HBonds
    )
    assert len(smoothness_problems(system)) == 2 and len(state_changing_forces(system)) == 1
    assert len(make_smooth(system)) == 2 and smoothness_problems(system) == []
    assert len(state_changing_forces(system)) == 1  # make_smooth leaves the CMMotionRemover
    system = forcefield.createSystem(
        topology, nonbondedMethod=app.PME, nonbondedCutoff=0.9 * unit.nanometers, constraints=app.HBonds
    )
    remover = next(i for i, f in enumerate(system.getForces()) if isinstance(f, mm.CMMotionRemover))
    changes = prepare_for_nve(system)
    assert len(changes) == 3 and changes[2].startswith(f"CMMotionRemover (force {remover}): removed (")
    assert smoothness_problems(system) == [] and state_changing_forces(system) == []
    nonbonded = next(f for f in system.getForces() if isinstance(f, mm.NonbondedForce))
    assert nonbonded.getEwaldErrorTolerance() == SMOOTH_EWALD_TOLERANCE
    integrator = AlphaRattleEnergyIntegrator(0.001, composition="triple-jump")
    context = _context(system, integrator, positions)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        integrator.check_context(context)  # where the energy mode warns
        integrator.step(2)
    assert not _ours(record)
    assert prepare_for_nve(system) == []  # idempotent
    del context


def test_prepare_for_nve_removes_barostats_and_thermostats_and_names_original_indices():
    system = _small_system(
        mm.MonteCarloBarostat(1.0, 300.0), _nonbonded(switch=None), mm.AndersenThermostat(300.0, 1.0)
    )
    changes = prepare_for_nve(system)
    assert changes[0].startswith("NonbondedForce (force 1): no switching function")
    assert changes[1].startswith("MonteCarloBarostat (force 0): removed (NVE keeps the box volume fixed")
    assert changes[2].startswith("AndersenThermostat (force 2): removed (NVE imposes no temperature")
    assert [type(f).__name__ for f in system.getForces()] == ["NonbondedForce"]


def test_prepare_for_nve_changes_nothing_when_the_switch_is_refused():
    system = _small_system(_nonbonded(switch=None, ewald=5e-4), mm.CMMotionRemover())
    before = mm.XmlSerializer.serialize(system)
    with pytest.raises(ValueError, match="switch_width"):
        prepare_for_nve(system, switch_width=1.0)
    assert mm.XmlSerializer.serialize(system) == before


# ------------------------------------------------------------------ start blow-up
def _hot_start(system, positions, integrator, platform):
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName(platform))
    context.setPositions(positions)
    rng = np.random.default_rng(3)
    context.setVelocities(rng.normal(0.0, 1e3, (system.getNumParticles(), 3)))  # ~1e3 nm/ps
    return context


@pytest.fixture(scope="module")
def cluster():
    """A few TIP3P waters in vacuum (NoCutoff): Reference goes to NaN without raising anything."""
    forcefield = app.ForceField("amber14/tip3p.xml")
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, model="tip3p", boxSize=mm.Vec3(1.0, 1.0, 1.0) * unit.nanometers)
    system = forcefield.createSystem(
        modeller.topology, nonbondedMethod=app.NoCutoff, rigidWater=True, removeCMMotion=False
    )
    return system, modeller.positions


def test_start_blow_up_on_cpu_names_the_causes_and_keeps_openmms_message(water):
    forcefield, topology, positions = water
    integrator = AlphaRattleIntegrator(0.002, alpha=0.0, composition="triple-jump")
    context = _hot_start(make_smooth_system(forcefield, topology), positions, integrator, "CPU")
    with pytest.raises(StartBlowUpError) as caught:
        integrator.step(5)
    message = str(caught.value)
    words_expected = ("first 100 steps", "LocalEnergyMinimizer", "minimizeEnergy", "too hot", "1.70h")
    for words in (*words_expected, "0.59× RATTLE's"):
        assert words in message
    assert "RattleIntegrator" in message and "1.2 fs" in message and "Suzuki" in message
    assert message.endswith(str(caught.value.__cause__))  # OpenMM's own message, appended
    assert "Particle coordinate is NaN" in message
    assert isinstance(caught.value, mm.OpenMMException)
    del context


def make_smooth_system(forcefield, topology):
    system = _create(forcefield, topology)
    make_smooth(system)
    return system


def test_start_blow_up_on_reference_is_found_from_the_velocities(cluster):
    system, positions = cluster
    integrator = RattleIntegrator(0.002)
    context = _hot_start(system, positions, integrator, "Reference")
    with pytest.raises(StartBlowUpError, match=r"velocities were NaN or infinite after step \d+") as caught:
        integrator.step(3)
    assert "unminimized" in str(caught.value) and "1.70h" not in str(caught.value)
    del context


def test_the_blow_up_scenarios_are_real_without_the_check(cluster, water, monkeypatch):
    """Without take_steps' check the same starts give NaN (Reference) or OpenMM's bare error (CPU)."""
    monkeypatch.setattr(
        start_blowup_module,
        "take_steps",
        lambda integrator, steps, *velocities: mm.CustomIntegrator.step(integrator, steps),
    )
    system, positions = cluster
    integrator = RattleIntegrator(0.002)
    context = _hot_start(system, positions, integrator, "Reference")
    integrator.step(3)  # raises nothing
    velocities = context.getState(getVelocities=True).getVelocities(asNumpy=True)._value
    assert not np.isfinite(velocities).all()
    forcefield, topology, water_positions = water
    integrator = AlphaRattleIntegrator(0.002, alpha=0.0, composition="triple-jump")
    context = _hot_start(make_smooth_system(forcefield, topology), water_positions, integrator, "CPU")
    with pytest.raises(mm.OpenMMException, match="NaN") as caught:
        integrator.step(5)
    assert type(caught.value) is mm.OpenMMException


def test_after_100_steps_openmms_error_passes_unchanged(water, cluster):
    forcefield, topology, positions = water
    integrator = AlphaRattleIntegrator(0.002, alpha=0.0, composition="triple-jump")
    context = _hot_start(make_smooth_system(forcefield, topology), positions, integrator, "CPU")
    integrator.setGlobalVariableByName("steps_taken", 100)
    with pytest.raises(mm.OpenMMException, match="Particle coordinate is NaN") as caught:
        integrator.step(5)
    assert type(caught.value) is mm.OpenMMException
    system, cluster_positions = cluster
    integrator = RattleIntegrator(0.002)
    context = _hot_start(system, cluster_positions, integrator, "Reference")
    integrator.setGlobalVariableByName("steps_taken", 100)
    integrator.step(2)  # NaN, but not checked after the start
    del context
