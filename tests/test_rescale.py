"""RATTLE + velocity rescaling: H held at E_ref, P, L and the velocity constraints kept, clear refusals."""

import re

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest
from conftest import (
    REFERENCE,
    constraint_errors,
    counting,
    path_on_the_water_cluster,
    positions_of,
    total_energy,
    velocities_of,
)
from platform_options import configured, platform_and_properties

from openmm_alphaprk import (
    AlphaRattleIntegrator,
    RattleIntegrator,
    RattleRescaleIntegrator,
    SplittingRattleIntegrator,
    StateChangingForceWarning,
    VelocityRescaleError,
    restore_integrator,
)
from openmm_alphaprk._units import InputError
from openmm_alphaprk.observables import energy_residuals, masses, momenta, rms
from openmm_alphaprk.systems import prepare_system

H = 0.002


@pytest.fixture(scope="module")
def spinning_cluster():
    """The shipped water cluster (222 atoms, no cutoff, no box) moving and turning as a whole.

    Its start has P and L near zero; a rigid translation and rotation added to the
    velocities (they keep every distance, so the velocity constraints still hold) makes
    both invariants large enough to test.
    """
    cluster = prepare_system("water-cluster")
    x = cluster.state.getPositions(asNumpy=True).value_in_unit(unit.nanometers)
    v = cluster.state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
    weights = masses(cluster.system)
    centre = (weights[:, None] * x).sum(axis=0) / weights.sum()
    v = v + np.array([0.3, -0.2, 0.1]) + np.cross(np.array([0.4, 0.7, -0.5]), x - centre)
    return cluster.system, x, v


def _kj(quantity):
    return quantity.value_in_unit(unit.kilojoules_per_mole)


def _context(system, integrator, positions, velocities, platform=REFERENCE, properties=None):
    context = mm.Context(system, integrator, platform, properties or {})
    context.setPositions(positions)
    context.setVelocities(velocities)
    return context


def _invariants(system, context):
    return momenta(masses(system), positions_of(context), velocities_of(context))


def _run(system, integrator, positions, velocities, steps, check=True):
    """Residuals H − H(start), P and L after every step, and the context."""
    context = _context(system, integrator, positions, velocities)
    if check:
        integrator.check_context(context)
    e_start = total_energy(context)
    residuals, linear, angular = [], [], []
    for _ in range(steps):
        integrator.step(1)
        residuals.append(total_energy(context) - e_start)
        p, angular_momentum = _invariants(system, context)
        linear.append(p)
        angular.append(angular_momentum)
    return np.array(residuals), np.array(linear), np.array(angular), context


def test_holds_energy_and_keeps_momenta_and_constraints_on_a_spinning_cluster(spinning_cluster):
    """Reference platform, double precision, 200 steps.

    Measured: RMS(H − E_ref) 4.3e-13 kJ/mol (RATTLE 0.24); max |ΔP| 5.7e-11 and |ΔL| 3.4e-11
    against |P| 499, |L| 346 (RATTLE's own 3.2e-11 and 3.3e-11); velocity-constraint error
    9e-16 (RATTLE 1.5e-15). Scaled without taking the rigid rotation out (as with a periodic
    box), max |ΔL| is 0.070.
    """
    system, x, v = spinning_cluster
    rattle, rattle_p, rattle_l, rattle_context = _run(system, RattleIntegrator(H), x, v, 200)
    integrator = RattleRescaleIntegrator(H)
    held, p, angular, context = _run(system, integrator, x, v, 200)
    assert integrator.removes_rotation
    p0, l0 = _invariants(system, _context(system, mm.VerletIntegrator(H), x, v))
    assert np.linalg.norm(p0) > 10 and np.linalg.norm(l0) > 50  # the test is not of zeros
    assert rms(held) < 1e-9 < rms(rattle) / 1e5
    assert np.abs(p - p0).max() < 1e-9 * np.linalg.norm(p0)
    assert np.abs(angular - l0).max() < 1e-9 * np.linalg.norm(l0)
    assert np.abs(rattle_l - l0).max() < 1e-9 * np.linalg.norm(l0)  # RATTLE keeps it too
    _, velocity_error = constraint_errors(system, positions_of(context), velocities_of(context))
    _, rattle_velocity_error = constraint_errors(
        system, positions_of(rattle_context), velocities_of(rattle_context)
    )
    assert velocity_error < max(10 * rattle_velocity_error, 1e-10)
    # the check can fail: scaling the rotation with the rest changes L by (s − 1) L per step
    translation_only = RattleRescaleIntegrator(H)
    context = _context(system, translation_only, x, v)
    translation_only.setGlobalVariableByName("rotation", 0)
    translation_only.setGlobalVariableByName("context_checked", 1)  # decided: the program keeps it
    translation_only.step(200)
    assert np.abs(_invariants(system, context)[1] - l0).max() > 1e-6 * np.linalg.norm(l0)


def test_holds_energy_to_a_hundredth_of_rattles_error_on_the_shipped_boxes(spinning_cluster):
    """tip3p-2nm on the CPU platform and the water cluster on Reference, 100 steps each.

    Measured 2026-11-27, RMS(H − E_ref) in kJ/mol. tip3p-2nm (|H| 8,238; 18 runs): 1.8e-12
    to 2.2e-12 in 13 runs; in 5 the CPU platform's energy of a state differed from the
    integrator's own evaluation of it by a float32 rounding unit (2^-17 or 2^-16 kJ/mol, those
    of single-precision terms of 64-256 kJ/mol) on one or two steps, or at the start: RMS
    7.6e-7, 1.5e-6, 1.5e-6, 2.2e-6, 1.5e-5, max |H − E_ref| 7.6e-6 or 1.5e-5. RATTLE
    0.5306-0.5307. The cluster (|H| 2,030; Reference, bitwise repeatable): 4.54e-13, max
    1.1e-12 (a double's rounding unit at 2,030 is 4.5e-13), against RATTLE's 0.193.
    """
    box = prepare_system("tip3p-2nm")
    cpu = mm.Platform.getPlatformByName("CPU")
    results = {}
    for make in (lambda: RattleIntegrator(H), lambda: RattleRescaleIntegrator(H)):
        integrator = make()
        context = mm.Context(box.system, integrator, cpu)
        context.setState(box.state)
        if isinstance(integrator, RattleRescaleIntegrator):
            integrator.check_context(context)
            assert not integrator.removes_rotation  # a periodic box
        results[type(integrator).__name__] = energy_residuals(context, integrator, 100).residuals
    held_box, rattle_box = results["RattleRescaleIntegrator"], results["RattleIntegrator"]
    assert rms(held_box) <= rms(rattle_box) / 100, (rms(held_box), rms(rattle_box))
    # the binding bound: H at the CPU platform's energy round-off, a few float32 units of 2^-16
    # kJ/mol (measured: RMS 2e-12 or, on some runs, 7.6e-7 to 1.5e-5; max 1.5e-5)
    assert rms(held_box) <= 5e-5 and np.abs(held_box).max() <= 5e-5, (rms(held_box), np.abs(held_box).max())
    system, x, v = spinning_cluster
    rattle, *_ = _run(system, RattleIntegrator(H), x, v, 100)
    held, *_ = _run(system, RattleRescaleIntegrator(H), x, v, 100)
    assert rms(held) <= rms(rattle) / 100
    # the binding bound: a few doubles' rounding units of |H| = 2,030 kJ/mol (measured 4.54e-13)
    assert rms(held) <= 2e-12, rms(held)


def test_a_box_keeps_ps_change_as_rattles_periodic_forces_make_it(water_box):
    """With PME the net force is not zero, so P changes; the scaling adds nothing to that change."""
    changes = []
    for integrator in (RattleIntegrator(H), RattleRescaleIntegrator(H)):
        context = _context(water_box.system, integrator, water_box.positions, water_box.velocities)
        if isinstance(integrator, RattleRescaleIntegrator):
            integrator.check_context(context)
        p0, _ = _invariants(water_box.system, context)
        integrator.step(50)
        changes.append(_invariants(water_box.system, context)[0] - p0)
    assert np.abs(changes[1] - changes[0]).max() < 1e-3 * np.abs(changes[0]).max()


def _with_pulling_force(system):
    """A copy of ``system`` with a weak uniform pull whose strength is a global parameter ``k``."""
    copy = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(system))
    pull = mm.CustomExternalForce("k*(x + y + z)")
    pull.addGlobalParameter("k", 0.0)
    for index in range(copy.getNumParticles()):
        pull.addParticle(index, [])
    copy.addForce(pull)
    return copy


@pytest.mark.parametrize("order", [None, 4])
def test_no_real_factor_raises_before_anything_is_lost_and_says_why(spinning_cluster, order):
    """A force parameter changed between steps raises V above E_ref, the state unchanged.

    The integrator cannot tell that from a user's change (the state did not move), so
    the step finds E_ref − V − K_rigid < 0: no real factor. It is not taken, nor are the
    steps after it in the call; the error says what to do.
    """
    system, x, v = spinning_cluster
    pulled = _with_pulling_force(system)
    integrator = RattleRescaleIntegrator(H, order=order)
    context = _context(pulled, integrator, x, v)
    integrator.check_context(context)
    assert not integrator.removes_translation  # the pull breaks momentum: every velocity is scaled
    integrator.step(5)
    before = positions_of(context), velocities_of(context), integrator.steps_taken
    context.setParameter("k", 500.0)  # raises V by ~5,000 kJ/mol: more than the kinetic energy
    with pytest.raises(VelocityRescaleError, match="no real velocity scale") as raised:
        integrator.step(10)
    message = str(raised.value)
    assert "reset_reference_energy()" in message and "advanced by 10 step(s)" in message
    assert np.array_equal(positions_of(context), before[0])
    assert np.array_equal(velocities_of(context), before[1])
    assert integrator.steps_taken == before[2]
    assert np.isfinite(positions_of(context)).all()
    # the fix the message names
    integrator.reset_reference_energy()
    integrator.step(5)
    assert integrator.steps_taken == before[2] + 5
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 1e-8


def test_a_state_set_between_steps_gives_a_new_reference_energy(spinning_cluster):
    system, x, v = spinning_cluster
    integrator = RattleRescaleIntegrator(H)
    context = _context(system, integrator, x, v)
    integrator.check_context(context)
    integrator.step(10)
    first = integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole)
    context.setVelocities(1.1 * velocities_of(context))  # hotter: the velocity constraints still hold
    new = total_energy(context)
    integrator.step(10)
    assert integrator.rescale_totals()["reference_resets"] == 2
    assert integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole) == pytest.approx(new, abs=1e-9)
    assert abs(new - first) > 10
    assert abs(total_energy(context) - new) < 1e-8


def test_barostats_and_thermostats_are_warned_about_as_by_the_energy_mode(water_box):
    system = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(water_box.system))
    system.addForce(mm.MonteCarloBarostat(1 * unit.bar, 300 * unit.kelvin))
    integrator = RattleRescaleIntegrator(H)
    context = _context(system, integrator, water_box.positions, water_box.velocities)
    with pytest.warns(StateChangingForceWarning, match="RATTLE with velocity rescaling runs NVE"):
        integrator.check_context(context)


def test_survives_serialization_and_restore(spinning_cluster):
    system, x, v = spinning_cluster
    integrator = RattleRescaleIntegrator(H, energy_tolerance=0.05 * unit.kilojoules_per_mole)
    copy = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(integrator))
    context = _context(system, copy, x, v)
    restored = restore_integrator(context.getIntegrator())
    assert isinstance(restored, RattleRescaleIntegrator)
    restored.step(20)
    assert restored.energy_tolerance.value_in_unit(unit.kilojoules_per_mole) == 0.05
    assert abs(total_energy(context) - _kj(restored.reference_energy)) < 1e-8


@pytest.mark.parametrize("spec", ["Reference", "CPU", *configured()])
def test_one_force_and_energy_evaluation_per_step_on_every_platform(water_box, spec):
    """Counted by OpenMM, not by the program: forces and energy at x1 come from one evaluation."""
    system, calls = counting(water_box.system)
    if ":" in spec:
        platform, properties = platform_and_properties(spec)
    else:
        platform, properties = mm.Platform.getPlatformByName(spec), {}
    integrator = RattleRescaleIntegrator(H)
    context = _context(system, integrator, water_box.positions, water_box.velocities, platform, properties)
    integrator.check_context(context)
    integrator.step(2)  # the first step also evaluates the start (E_ref)
    calls[0] = 0
    integrator.step(20)
    assert calls[0] == 20
    assert integrator.last_step_force_evaluations == 1
    # H as the platform computes it: at its energy's round-off (mixed/single: ~1e-3 kJ/mol here)
    e_ref = integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole)
    assert abs(total_energy(context) - e_ref) < 0.01


def test_a_composition_of_rattle_steps_then_rescaling_holds_energy_and_keeps_the_trajectory(spinning_cluster):
    """order=4: Suzuki's five RATTLE stages, then the rescaling (Reference, 50 steps).

    H held at E_ref, P and L kept, as for one RATTLE step; the positions are the
    composition's (``AlphaRattleIntegrator(order=4)`` at α = 0) but for the velocity scale,
    whose effect after 50 steps is far below the distance to RATTLE's positions.
    """
    system, x, v = spinning_cluster
    integrator = RattleRescaleIntegrator(H, order=4)
    assert integrator.composition.name == "suzuki5"
    held, p, angular, context = _run(system, integrator, x, v, 50)
    p0, l0 = _invariants(system, _context(system, mm.VerletIntegrator(H), x, v))
    assert rms(held) < 1e-9
    assert np.abs(p - p0).max() < 1e-9 * np.linalg.norm(p0)
    assert np.abs(angular - l0).max() < 1e-9 * np.linalg.norm(l0)
    assert integrator.last_step_force_evaluations == 5
    composed = AlphaRattleIntegrator(H, alpha=0.0, order=4)
    composed_context = _context(system, composed, x, v)
    composed.step(50)
    rattle = RattleIntegrator(H)
    rattle_context = _context(system, rattle, x, v)
    rattle.step(50)
    from_composition = np.abs(positions_of(context) - positions_of(composed_context)).max()
    from_rattle = np.abs(positions_of(rattle_context) - positions_of(composed_context)).max()
    assert from_composition < 0.05 * from_rattle, (from_composition, from_rattle)
    restored = restore_integrator(mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(integrator)))
    assert restored.composition.coefficients == integrator.composition.coefficients


def test_a_composition_is_named_by_order_or_name():
    assert RattleRescaleIntegrator(H).composition is None
    assert RattleRescaleIntegrator(H, order=6).composition.name == "mclachlan9"
    assert RattleRescaleIntegrator(H, composition="triple-jump").composition.stages == 3
    with pytest.raises(ValueError, match="order 4"):
        RattleRescaleIntegrator(H, order=6, composition="suzuki5")


# ---------------------------------------------------------------- the cost: sums per step
def _per_step_sums(integrator: RattleRescaleIntegrator, once_per_interval: bool = False) -> list[str]:
    """The sums of the program outside the blocks that run once per call or when the state was set.

    With ``rescale_interval`` > 1 the rescaling block (every N-th step) is left out too, or,
    with ``once_per_interval``, only the sums inside it are given.
    """
    once = ("check_system", "state_check", "state_moved", "rotation > 0.5")
    interval = "rescale_count > rescale_interval"
    sums, open_blocks, in_interval = [], [], []
    for line in integrator.program_listing().splitlines():
        text = line.split(maxsplit=1)[1] if line.strip() else ""
        if text.startswith(("if (", "while (")):
            open_blocks.append(any(name in text for name in once))
            in_interval.append(interval in text)
        elif text == "end":
            open_blocks.pop()
            in_interval.pop()
        elif "= sum(" in text and not any(open_blocks) and any(in_interval) == once_per_interval:
            sums.append(text)
    return sums


@pytest.mark.parametrize("order", [None, 4])
def test_a_periodic_box_sums_the_kinetic_energy_alone_per_step(order):
    """Per step in a periodic box: the energy read and one sum, K; P is carried from when it was measured.

    Counted twice: in the listing (outside the once-per-call and state-set blocks) and in
    a run (``host_syncs``: 100 steps in one call take 100 sums of K and the call's one
    comparison of its start with the last step's end).
    """
    integrator = RattleRescaleIntegrator(H, order=order)
    assert [text.split(" =")[0] for text in _per_step_sums(integrator)] == ["kinetic_energy"]
    water = prepare_system("tip3p-2nm")
    context = mm.Context(water.system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setState(water.state)
    integrator.check_context(context)
    assert not integrator.removes_rotation and integrator.removes_translation
    integrator.step(2)
    before = integrator.getGlobalVariableByName("host_syncs")
    integrator.step(100)
    assert integrator.getGlobalVariableByName("host_syncs") - before == 101


def test_the_carried_momentum_stays_what_the_state_has_over_a_thousand_steps():
    """PME's reciprocal-space force sums to round-off, not zero: P drifts from the value carried.

    Measured on tip3p-2nm (CPU, 2026-11-27; the shipped start has |P| = 149 amu nm/ps):
    |P − P_carried| 0.0060 after 1,000 steps, 0.019 after 10,000, and |H − E_ref| at most
    3.3e-8 kJ/mol over those 10,000 (the scaling's error from it is (1 − s) V_cm·δP).
    Bounds 5x above the 1,000-step values.
    """
    water = prepare_system("tip3p-2nm")
    integrator = RattleRescaleIntegrator(H)
    context = mm.Context(water.system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setState(water.state)
    integrator.check_context(context)
    integrator.step(1000)
    mass = masses(context.getSystem())
    velocities = velocities_of(context)
    actual = (mass[:, None] * velocities).sum(axis=0)
    carried = np.array([integrator.getGlobalVariableByName(f"momentum_{axis}") for axis in "xyz"])
    assert np.linalg.norm(actual - carried) < 0.03
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 5e-5


@pytest.mark.parametrize("order", [None, 4])
def test_a_harmonic_oscillator_in_an_external_potential_is_scaled_whole(order):
    """One particle on a spring to the origin: no momentum to keep, so every velocity is scaled.

    Before, the particle's whole kinetic energy counted as rigid-body motion and every step
    was refused ("no real velocity scale").
    """
    system = mm.System()
    system.addParticle(1.0)
    spring = mm.CustomExternalForce("0.5*k*(x^2 + y^2 + z^2)")
    spring.addGlobalParameter("k", 1000.0)
    spring.addParticle(0, [])
    system.addForce(spring)
    integrator = RattleRescaleIntegrator(H, order=order)
    context = _context(system, integrator, [[0.1, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    integrator.check_context(context)
    assert not integrator.removes_translation and not integrator.removes_rotation
    energies = []
    for _ in range(50):
        integrator.step(4)
        energies.append(total_energy(context))
    assert np.ptp(energies) < 1e-9 and abs(energies[0] - _kj(integrator.reference_energy)) < 1e-9
    assert abs(integrator.velocity_scale - 1) > 0  # it did scale


def test_a_step_too_large_for_the_system_is_named_when_no_factor_exists():
    """Flexible water at 2 fs: one RATTLE step's energy error exceeds K, and the message says so."""
    import openmm.app as app

    forcefield = app.ForceField("amber14/tip3p.xml")
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, boxSize=mm.Vec3(1.5, 1.5, 1.5) * unit.nanometers)
    system = forcefield.createSystem(
        modeller.topology,
        nonbondedMethod=app.PME,
        nonbondedCutoff=0.7 * unit.nanometers,
        rigidWater=False,
        removeCMMotion=False,
    )
    integrator = RattleRescaleIntegrator(2 * unit.femtoseconds)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setPositions(modeller.positions)
    mm.LocalEnergyMinimizer.minimize(context, 10.0, 200)
    context.setVelocitiesToTemperature(300 * unit.kelvin, 1)
    with pytest.raises(VelocityRescaleError, match=r"\(1\) too large a step for the system") as raised:
        integrator.step(20)
    message = str(raised.value)
    assert "flexible water" in message
    # the step's own error is the cause: H − E_ref after one RATTLE step above the kinetic energy
    # (measured 471 kJ/mol against 377 internal, 1.2x, 2026-11-27)
    import re

    assert float(re.search(r"\(here ([0-9.e+-]+) of it\)", message).group(1)) > 0.5


# ---------------------------------------------------------------- rescaling every N-th step
def _residual_trace(system, integrator, x, v, steps):
    """H − E_ref (the integrator's) and P, L after every step, one ``step(1)`` call each."""
    context = _context(system, integrator, x, v)
    integrator.check_context(context)
    residuals, linear, angular = [], [], []
    for _ in range(steps):
        integrator.step(1)
        residuals.append(total_energy(context) - _kj(integrator.reference_energy))
        p, angular_momentum = _invariants(system, context)
        linear.append(p)
        angular.append(angular_momentum)
    return np.array(residuals), np.array(linear), np.array(angular), context


@pytest.mark.parametrize("order", [None, 4])
def test_every_tenth_step_holds_energy_and_the_steps_between_are_rattles(spinning_cluster, order):
    """N = 10 on the spinning cluster (Reference, 40 steps): H = E_ref at steps 10, 20, 30, 40.

    Between them the steps are RATTLE's (the composition's): from the state after step 20,
    the integrator without rescaling takes the same 9 steps (positions to 1e-12 nm, H to
    1e-9 kJ/mol), and H − E_ref there is of RATTLE's size (measured RMS 0.17 kJ/mol for one
    RATTLE step, at the rescaling steps 4e-13). P and L are kept at every step.
    """
    system, x, v = spinning_cluster
    integrator = RattleRescaleIntegrator(H, order=order, rescale_interval=10)
    residuals, p, angular, context = _residual_trace(system, integrator, x, v, 40)
    rescaled = residuals[9::10]
    between = np.delete(residuals, np.s_[9::10])
    assert np.abs(rescaled).max() < 1e-9, rescaled
    assert rms(between) > 1e4 * max(np.abs(rescaled).max(), 1e-12)  # the check can fail
    assert integrator.rescalings == 4 and integrator.steps_taken == 40
    assert integrator.getGlobalVariableByName("rescale_count") == 0
    p0, l0 = _invariants(system, _context(system, mm.VerletIntegrator(H), x, v))
    assert np.abs(p - p0).max() < 1e-9 * np.linalg.norm(p0)
    assert np.abs(angular - l0).max() < 1e-9 * np.linalg.norm(l0)
    # the 9 steps after a rescaling are the unrescaled integrator's steps from that state
    integrator = RattleRescaleIntegrator(H, order=order, rescale_interval=10)
    context = _context(system, integrator, x, v)
    integrator.check_context(context)
    integrator.step(20)
    start = context.getState(getPositions=True, getVelocities=True)
    integrator.step(9)
    composed = RattleIntegrator(H) if order is None else AlphaRattleIntegrator(H, alpha=0.0, order=order)
    plain = _context(system, composed, start.getPositions(), start.getVelocities())
    composed.step(9)
    assert np.abs(positions_of(context) - positions_of(plain)).max() < 1e-12
    assert abs(total_energy(context) - total_energy(plain)) < 1e-9


def test_the_interval_runs_on_across_calls_checkpoints_and_restarts_at_a_new_reference(spinning_cluster):
    """``step(7)`` then ``step(3)`` rescale after the 10th step; a checkpoint keeps the count.

    A state the user sets retakes E_ref and restarts the count.
    """
    system, x, v = spinning_cluster
    integrator = RattleRescaleIntegrator(H, rescale_interval=10)
    context = _context(system, integrator, x, v)
    integrator.check_context(context)
    integrator.step(7)
    assert (integrator.rescalings, integrator.getGlobalVariableByName("rescale_count")) == (0, 7)
    checkpoint = context.createCheckpoint()
    integrator.step(3)
    assert integrator.rescalings == 1
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 1e-9
    after_ten = positions_of(context)
    context.loadCheckpoint(checkpoint)  # the count (7) and the rest of the program's state come back
    assert integrator.getGlobalVariableByName("rescale_count") == 7
    integrator.step(3)
    assert np.abs(positions_of(context) - after_ten).max() < 1e-12
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 1e-9
    integrator.step(4)  # count 4 when the user sets a new state: E_ref retaken, the count restarts
    context.setVelocities(1.1 * velocities_of(context))
    resets = integrator.rescale_totals()["reference_resets"]
    integrator.step(9)
    assert integrator.rescale_totals()["reference_resets"] == resets + 1
    assert integrator.getGlobalVariableByName("rescale_count") == 9  # not rescaled at the old count's 10th
    integrator.step(1)
    assert integrator.getGlobalVariableByName("rescale_count") == 0
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 1e-9


@pytest.mark.parametrize("order", [None, 4])
def test_a_periodic_box_sums_the_kinetic_energy_once_per_interval(order):
    """N = 10 in a periodic box: K's sum and the energy read sit in the rescaling block alone.

    Counted in the listing (the per-step sums of N = 1 are inside the block that runs at
    every 10th step) and in a run: 100 steps in one call take 10 sums of K and the call's
    one comparison of its start with the last step's end.
    """
    integrator = RattleRescaleIntegrator(H, order=order, rescale_interval=10)
    assert _per_step_sums(integrator) == []
    assert [text.split(" =")[0] for text in _per_step_sums(integrator, once_per_interval=True)] == [
        "kinetic_energy"
    ]
    listing = integrator.program_listing()
    interval_block = listing.split("if (rescale_count > rescale_interval - 0.5):")[1]
    assert (
        "= energy" in interval_block
        and "= energy"
        not in listing.split("rescale_count = rescale_count + 1")[1].split(
            "if (rescale_count > rescale_interval - 0.5):"
        )[0]
    )
    water = prepare_system("tip3p-2nm")
    context = mm.Context(water.system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setState(water.state)
    integrator.check_context(context)
    integrator.step(10)
    before = integrator.getGlobalVariableByName("host_syncs")
    integrator.step(100)
    assert integrator.getGlobalVariableByName("host_syncs") - before == 11
    assert integrator.rescalings == 11


#: Which block conditions hold on a step between rescalings that is not its call's first.
_BETWEEN_RESCALINGS = {
    "check_system > 0.5": False,
    "refused < 0.5": True,
    "refused + rescale_halted < 0.5": True,
    "state_check > 0.5": False,
    "state_moved + 1 - reference_set > 0": False,
    "rescale_count < rescale_interval - 0.5": True,
    "rescale_count > rescale_interval - 0.5": False,
    "call_steps_left < 0.5": False,
}
_COMPUTATION_KINDS = {
    mm.CustomIntegrator.ComputeGlobal: "global",
    mm.CustomIntegrator.ComputePerDof: "per DOF",
    mm.CustomIntegrator.ComputeSum: "sum",
    mm.CustomIntegrator.ConstrainPositions: "constrain positions",
    mm.CustomIntegrator.ConstrainVelocities: "constrain velocities",
    mm.CustomIntegrator.UpdateContextState: "update context state",
}


def _work_of_a_step(integrator, conditions):
    """The computations one step runs where each ``if`` condition holds as ``conditions`` says.

    Global computations (evaluated on the host, no pass over the degrees of freedom) are
    left out; an ``if`` whose condition is not in ``conditions`` fails the test.
    """
    steps = [integrator.getComputationStep(i) for i in range(integrator.getNumComputations())]
    block_end, open_blocks = {}, []
    for i, (kind, _variable, _expression) in enumerate(steps):
        if kind in (mm.CustomIntegrator.IfBlockStart, mm.CustomIntegrator.WhileBlockStart):
            open_blocks.append(i)
        elif kind == mm.CustomIntegrator.BlockEnd:
            block_end[open_blocks.pop()] = i
    work, i = [], 0
    while i < len(steps):
        kind, variable, expression = steps[i]
        assert kind != mm.CustomIntegrator.WhileBlockStart, "a loop: not a plain step"
        if kind == mm.CustomIntegrator.IfBlockStart and not conditions[expression]:
            i = block_end[i]
        elif kind in _COMPUTATION_KINDS and _COMPUTATION_KINDS[kind] != "global":
            work.append((_COMPUTATION_KINDS[kind], variable, expression))
        i += 1
    return work


def _per_dof_variables(integrator):
    return {integrator.getPerDofVariableName(i) for i in range(integrator.getNumPerDofVariables())}


@pytest.mark.parametrize(
    ("options", "unrescaled"),
    [
        ({}, lambda: RattleIntegrator(H)),
        ({"order": 4}, lambda: RattleIntegrator(H, order=4)),
        ({"splitting": "me2"}, lambda: SplittingRattleIntegrator(H, splitting="me2")),
    ],
    ids=["rattle", "rattle4", "split-me"],
)
def test_a_step_between_rescalings_is_the_unrescaled_integrators_step(options, unrescaled):
    """With N = 10 a step between rescalings runs the base integrator's per-step work and no more.

    From the listing: the passes over the degrees of freedom, the sums, the constraint
    steps and the energy reads of such a step (not its call's first) are those of
    :class:`RattleIntegrator`'s step (the composition's, the splitting's), in the same order,
    but for OpenMM's update-context-state step, which the NVE program leaves out; the step
    that rescales saves its start, reads the energy and sums K. With RATTLE as the
    base the program declares RATTLE's per-DOF variables (x0, v0) and P/M
    (``centre_velocity``, which spares the rescaling step a vector function) and no others:
    on the Reference and CPU platforms each per-DOF step copies every one of them per
    degree of freedom. No pass of such a step reads a global variable: on the common platform the
    globals a step changes on the host (the interval's count) are uploaded only before a
    kernel that reads one, so the steps between rescalings upload nothing.
    """
    integrator = RattleRescaleIntegrator(H, rescale_interval=10, **options)
    base = unrescaled()
    between = _work_of_a_step(integrator, _BETWEEN_RESCALINGS)
    base_step = _work_of_a_step(base, {"check_system > 0.5": False, "refused < 0.5": True})
    assert base_step[0][0] == "update context state"  # OpenMM's, which NVE leaves out
    assert between == base_step[1:]
    assert not [work for work in between if "energy" in work[2]]
    global_names = {integrator.getGlobalVariableName(i) for i in range(integrator.getNumGlobalVariables())}
    read = {
        name
        for kind, _variable, expression in between
        if kind in ("per DOF", "sum")
        for name in re.findall(r"[A-Za-z_]\w*", expression)
        if name in global_names
    }
    assert not read
    rescaling = _work_of_a_step(
        integrator,
        _BETWEEN_RESCALINGS
        | {
            "rescale_count < rescale_interval - 0.5": False,
            "rescale_count > rescale_interval - 0.5": True,
            "rotation > 0.5": False,
            "rotation < 0.5": True,
            "no_factor > 0.5": False,
            "no_factor < 0.5": True,
        },
    )
    assert ("sum", "kinetic_energy", "0.5*m*v*v") in rescaling
    # a periodic box's rescaling step: no vector function, which costs about ten plain
    # passes on the Reference and CPU platforms
    assert not [work for work in rescaling if "vector(" in work[2] or "cross(" in work[2]]
    assert len(rescaling) > len(between)
    if not options:
        assert _per_dof_variables(base) == {"x0", "v0"}
        assert _per_dof_variables(integrator) == {"x0", "v0", "centre_velocity"}
        # the program before this one: F(x0) copied and the end state copied at every step
        assert ("per DOF", "fstart", "f") not in between


@pytest.mark.parametrize(
    "options",
    [{}, {"rescale_interval": 10}, {"order": 4}, {"order": 4, "rescale_interval": 10}, {"splitting": "me2"}]
    + [{"splitting": "me2", "rescale_interval": 10}, {"alpha": 0.1}, {"alpha": 0.1, "rescale_interval": 10}]
    + [{"alpha": 0.01, "order": 4, "rescale_interval": 10}],
    ids=["rattle", "rattle@10", "rattle4", "rattle4@10", "split-me", "split-me@10", "alpha", "alpha@10"]
    + ["alpha4@10"],
)
def test_no_force_is_read_after_an_energy_read_before_the_positions_change(options):
    """In program text, after every read of ``energy`` the positions change before ``f`` is read.

    OpenMM evaluates the energy of such a read alone when no force read follows it before the
    positions change, and marks the forces valid; on CUDA and NVIDIA's OpenCL (not on pocl or
    Reference, where the tests run) the forces read after it were wrong. Text order covers
    every path here: the programs have no loops but α's midpoint loop, which reads no energy.
    """
    lines = [
        line.split(maxsplit=1)[1]
        for line in RattleRescaleIntegrator(H, **options).program_listing().splitlines()
    ]
    lines = [
        line for line in lines if not line.startswith(("global ", "per-dof ", "step size", "constraint"))
    ]
    reads_energy = [i for i, line in enumerate(lines) if re.search(r"\benergy\b", line.split(" = ", 1)[-1])]
    assert reads_energy
    for i in reads_energy:
        after = (
            line
            for line in lines[i + 1 :]
            if line == "constrain positions" or line.startswith("x = ") or re.search(r"\bf\b", line)
        )
        first = next(after, "")  # a step that assigns x reads its expression's f before it moves
        assert first == "constrain positions" or not re.search(r"\bf\b", first), (lines[i], first)


def test_a_rescaling_step_without_a_factor_returns_to_its_start_with_an_interval(spinning_cluster):
    """N = 10, no real factor at the 10th step: the Context holds that step's start; the fix works.

    The steps before it in the call (RATTLE's) are kept; the call's end is recorded where the
    halted step left it, so the next call sees no change of state.
    """
    system, x, v = spinning_cluster
    pulled = _with_pulling_force(system)
    integrator = RattleRescaleIntegrator(H, rescale_interval=10)
    context = _context(pulled, integrator, x, v)
    integrator.check_context(context)
    integrator.step(7)
    context.setParameter("k", 500.0)  # V rises by ~5,000 kJ/mol: no factor at the 10th step
    integrator.step(2)  # steps 8, 9: RATTLE's, no rescaling
    before = positions_of(context), velocities_of(context), integrator.steps_taken
    with pytest.raises(VelocityRescaleError, match="no real velocity scale"):
        integrator.step(5)
    assert np.array_equal(positions_of(context), before[0])
    assert np.array_equal(velocities_of(context), before[1])
    assert integrator.steps_taken == before[2] and integrator.rescalings == 0
    assert integrator.getGlobalVariableByName("rescale_count") == 9  # the next step rescales
    integrator.reset_reference_energy()
    integrator.step(10)
    assert integrator.rescalings == 1 and integrator.rescale_totals()["reference_resets"] == 2
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 1e-8


def test_a_copy_no_step_drives_compares_every_step_and_still_sees_a_change(spinning_cluster):
    """N = 10 deserialized as a plain CustomIntegrator: its steps record their end and see a set state.

    Without this package's ``step()`` (``call_steps_left`` stays 0) the program records the
    state every step ends in and compares every step's start with it: a state the user sets
    between OpenMM's own calls of ``step`` retakes E_ref, and the count restarts.
    """
    system, x, v = spinning_cluster
    copy = mm.XmlSerializer.deserialize(
        mm.XmlSerializer.serialize(RattleRescaleIntegrator(H, rescale_interval=10))
    )
    assert type(copy) is mm.CustomIntegrator
    context = _context(system, copy, x, v)
    copy.step(10)
    e_ref = copy.getGlobalVariableByName("reference_energy")
    assert abs(total_energy(context) - e_ref) < 1e-8
    copy.step(3)
    context.setVelocities(1.1 * velocities_of(context))
    hotter = total_energy(context)
    copy.step(10)
    assert copy.getGlobalVariableByName("reference_resets") == 2
    assert copy.getGlobalVariableByName("reference_energy") == pytest.approx(hotter, abs=1e-9)
    assert abs(total_energy(context) - hotter) < 1e-8  # rescaled at the 10th step after the change


def test_one_force_evaluation_per_step_with_an_interval(water_box):
    """Counted by OpenMM: at a rescaling step the energy comes with the step's force (CPU platform)."""
    system, calls = counting(water_box.system)
    integrator = RattleRescaleIntegrator(H, rescale_interval=5)
    context = _context(
        system, integrator, water_box.positions, water_box.velocities, mm.Platform.getPlatformByName("CPU")
    )
    integrator.check_context(context)
    integrator.step(5)
    calls[0] = 0
    integrator.step(20)
    assert calls[0] == 20 and integrator.rescalings == 5
    assert abs(total_energy(context) - _kj(integrator.reference_energy)) < 0.01


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "10", None, float("nan")])
def test_a_rescale_interval_that_is_not_a_positive_integer_is_refused(bad):
    with pytest.raises(InputError, match=r"rescale_interval must be a positive integer.*rescale_interval=10"):
        RattleRescaleIntegrator(H, rescale_interval=bad)


def test_an_interval_of_one_is_the_program_without_it():
    assert (
        RattleRescaleIntegrator(H, rescale_interval=1).program_listing()
        == RattleRescaleIntegrator(H).program_listing()
    )
    assert RattleRescaleIntegrator(H, rescale_interval=10.0).rescale_interval == 10
    assert RattleRescaleIntegrator(H).rescale_interval == 1
    restored = restore_integrator(
        mm.XmlSerializer.deserialize(
            mm.XmlSerializer.serialize(RattleRescaleIntegrator(H, order=4, rescale_interval=7))
        )
    )
    assert restored.rescale_interval == 7 and restored.composition.name == "suzuki5"


@pytest.mark.parametrize(
    ("name", "order", "composition", "interval", "shown"),
    [
        ("rattle+rescale@10", 2, None, 10, "RATTLE + rescaling every 10 steps"),
        ("rattle4+rescale@100", 4, None, 100, "RATTLE-4 + rescaling every 100 steps"),
        ("rattle6+rescale@3", 6, None, 3, "RATTLE-6 + rescaling every 3 steps"),
        (
            "rattle4+rescale:triple-jump@5",
            4,
            "triple-jump",
            5,
            "RATTLE-4 (triple-jump) + rescaling every 5 steps",
        ),
        ("rattle+rescale@1", 2, None, 1, "RATTLE + rescaling"),
    ],
)
def test_rescaling_intervals_are_names_of_the_vocabulary(name, order, composition, interval, shown):
    from openmm_alphaprk.runs.integrator_names import (
        INTEGRATOR_HELP,
        label,
        make_integrator,
        parse_integrator,
    )
    from openmm_alphaprk.runs.rundir import folder_name

    spec = parse_integrator(name)
    assert (spec.kind, spec.order, spec.composition, spec.rescale_interval) == (
        "rescale",
        order,
        composition,
        interval,
    )
    assert label(spec) == shown
    integrator = make_integrator(spec, 0.002)
    assert integrator.rescale_interval == interval
    assert parse_integrator(spec.name) == spec
    assert "rattle[4|6][:COMPOSITION][+rescale[@N]]" in INTEGRATOR_HELP
    assert folder_name(spec.name) == spec.name.replace("@", "_").replace(":", "_")


@pytest.mark.parametrize(
    "bad", ["rattle@10", "alpha=0.1@3", "rattle+rescale@0", "rattle+rescale@x", "rattle+rescale@2.5"]
)
def test_an_interval_on_a_name_that_cannot_take_it_is_refused(bad):
    from openmm_alphaprk.runs.integrator_names import UnknownIntegratorError, parse_integrator

    with pytest.raises(UnknownIntegratorError, match="rattle\\+rescale@10"):
        parse_integrator(bad)


def test_the_scalings_statistics_are_what_each_step_did_and_shrink_as_rattles_error(spinning_cluster):
    """mean/RMS of s − 1 and the energy removed, against s and H read after every step; h² scaling."""
    system, x, v = spinning_cluster
    shrink = []
    for h in (H, H / 2):
        integrator = RattleRescaleIntegrator(h)
        context = _context(system, integrator, x, v)
        integrator.check_context(context)
        steps = int(round(0.2 / h))
        changes, residuals = [], []
        for _ in range(steps):
            integrator.step(1)
            changes.append(integrator.getGlobalVariableByName("velocity_scale") - 1)
            residuals.append(integrator.getGlobalVariableByName("rattle_residual"))
        totals = integrator.rescale_totals()
        changes, residuals = np.array(changes), np.array(residuals)
        assert totals["rescalings"] == steps
        assert totals["mean_scale_change"] == pytest.approx(changes.mean(), rel=1e-9, abs=1e-15)
        assert totals["rms_scale_change"] == pytest.approx(rms(changes), rel=1e-9)
        assert totals["removed_energy"] == pytest.approx(residuals.sum(), rel=1e-9, abs=1e-12)
        simulated_ns = steps * h / 1000
        added = -residuals.sum() / simulated_ns
        assert totals["added_energy_per_ns"] == pytest.approx(added, rel=1e-9, abs=1e-9)
        assert 0 < totals["rms_scale_change"] <= totals["max_abs_scale_change"]
        shrink.append(totals["rms_scale_change"])
    # s − 1 removes one RATTLE step's energy error, O(h³): 8x smaller at h/2 (measured 8.1)
    assert 6 < shrink[0] / shrink[1] < 10


@pytest.mark.parametrize("options", [{"alpha": 0.1}, {"alpha": 0.01, "order": 4}])
def test_rescaling_after_a_fixed_alpha_is_alpha_rattles_step_with_the_energy_held(options):
    """the layer over the α base: the positions α-RATTLE's, the velocities scaled, H at E_ref, restorable."""
    from openmm_alphaprk import restore_integrator
    from openmm_alphaprk.systems import prepare_system

    water = prepare_system("water-cluster")
    held = RattleRescaleIntegrator(H, **options)
    plain = AlphaRattleIntegrator(H, **options)
    contexts = []
    for integrator in (held, plain):
        context = mm.Context(water.system, integrator, REFERENCE)
        context.setState(water.state)
        integrator.step(1)
        contexts.append(context)
    np.testing.assert_allclose(positions_of(contexts[0]), positions_of(contexts[1]), rtol=0, atol=1e-12)
    assert held.force_evaluations_per_step == plain.force_evaluations_per_step > 1
    held.step(19)
    state = contexts[0].getState(getEnergy=True)
    residual = state.getKineticEnergy() + state.getPotentialEnergy() - held.reference_energy
    assert abs(residual) < held.energy_tolerance and held.alpha == options["alpha"]
    restored = restore_integrator(mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(held)))
    assert isinstance(restored, RattleRescaleIntegrator) and restored.alpha == options["alpha"]
    with pytest.raises(ValueError, match="split=α"):
        RattleRescaleIntegrator(H, alpha=0.1, splitting="me2")


@pytest.mark.parametrize("options", [{"alpha": 0.1}, {"alpha": 0.01, "order": 4}])
def test_rescaling_every_fifth_step_after_a_fixed_alpha_takes_alpha_rattles_steps_between(options):
    """the interval over the α base: four steps α-RATTLE's to the bit, the fifth's positions too, H held."""
    from openmm_alphaprk.systems import prepare_system

    water = prepare_system("water-cluster")
    held = RattleRescaleIntegrator(H, rescale_interval=5, **options)
    plain = AlphaRattleIntegrator(H, **options)
    contexts = []
    for integrator in (held, plain):
        context = mm.Context(water.system, integrator, REFERENCE)
        context.setState(water.state)
        contexts.append(context)
    for step in range(1, 6):
        held.step(1)
        plain.step(1)
        np.testing.assert_array_equal(positions_of(contexts[0]), positions_of(contexts[1]))
        if step < 5:
            np.testing.assert_array_equal(velocities_of(contexts[0]), velocities_of(contexts[1]))
    assert held.rescalings == 1 and held.velocity_scale != 1.0
    held.step(5)
    state = contexts[0].getState(getEnergy=True)
    residual = state.getKineticEnergy() + state.getPotentialEnergy() - held.reference_energy
    assert abs(residual) < held.energy_tolerance and held.rescalings == 2


def test_rescaling_after_a_fixed_alpha_loses_to_rescaled_rattle_at_equal_evaluations():
    """why alpha=...+rescale is no name of the grammar (docs/integrators.md): farther from the true path."""
    error = path_on_the_water_cluster()
    alpha_error, alpha_cost = error(RattleRescaleIntegrator(H, alpha=0.1), 1)
    k = round(alpha_cost)
    rattle_error, rattle_cost = error(RattleRescaleIntegrator(H / k), k)
    assert rattle_cost <= alpha_cost
    assert rattle_error < alpha_error / 4


def test_rescaling_after_a_fixed_alpha_raises_when_the_midpoint_iteration_fails():
    """the α base's failure reaches the user as from AlphaRattleIntegrator, with the same message."""
    from openmm_alphaprk import MidpointConvergenceError

    system = mm.System()
    for _ in range(2):
        system.addParticle(1.0)
    bond = mm.HarmonicBondForce()
    bond.addBond(0, 1, 0.1, 1e7)  # far too stiff for the step: |α| h²ω²/4 ≈ 10
    system.addForce(bond)
    integrator = RattleRescaleIntegrator(H, alpha=0.5)
    context = _context(system, integrator, [[0, 0, 0], [0.11, 0, 0]], [[1, 2, 0], [0, 0, 3]])
    with pytest.raises(MidpointConvergenceError, match="midpoint iteration did not converge"):
        integrator.step(1)
    np.testing.assert_allclose(positions_of(context), [[0, 0, 0], [0.11, 0, 0]], atol=1e-12)  # its start
