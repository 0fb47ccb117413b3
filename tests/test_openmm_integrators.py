"""The OpenMM integrators: RATTLE equivalence, agreement with the NumPy reference,
geometric properties on real water, and the OpenMM plumbing (Simulation,
serialization, checkpoints, errors)."""

import io
import pickle
import time

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
import pytest
from conftest import (
    REFERENCE,
    analysed_blocks,
    constraint_errors,
    make_context,
    positions_of,
    total_energy,
    velocities_of,
)

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    IncompatibleSystemError,
    MidpointConvergenceError,
    RattleIntegrator,
    restore_integrator,
)
from openmm_alphaprk.reference import (
    angular_momentum,
    integrate,
    rigid_diatomics,
    symplecticity_defect,
    to_openmm_system,
    water_cluster,
)

ALPHAS = [0.0, 1 / 6, 0.5, 1.0]


def _step_and_read(context, integrator, steps):
    integrator.step(steps)
    return positions_of(context), velocities_of(context)


# ------------------------------------------------------------------ RATTLE
def test_alpha_zero_reproduces_verlet_integrator_positions(water_box):
    system, x0, v0 = water_box.system, water_box.positions, water_box.velocities
    h = 0.002
    rattle = AlphaRattleIntegrator(h, alpha=0.0, constraint_tolerance=1e-10)
    ctx = make_context(system, rattle, x0, v0)
    # VerletIntegrator is leapfrog: it reads velocities as v(-h/2)
    verlet = mm.VerletIntegrator(h)
    verlet.setConstraintTolerance(1e-10)
    forces = (
        ctx.getState(getForces=True)
        .getForces(asNumpy=True)
        .value_in_unit(unit.kilojoules_per_mole / unit.nanometer)
    )
    masses = np.array([system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(len(x0))])
    leap = make_context(system, verlet, x0, v0 - 0.5 * h * forces / masses[:, None])
    leap.applyVelocityConstraints(1e-12)
    rattle.step(50)
    verlet.step(50)
    assert np.max(np.abs(positions_of(ctx) - positions_of(leap))) < 1e-10
    # the unshifted start differs at the percent level: the comparison can fail
    unshifted = mm.VerletIntegrator(h)
    plain = make_context(system, unshifted, x0, v0)
    unshifted.step(50)
    assert np.max(np.abs(positions_of(plain) - positions_of(leap))) > 1e-4


def test_alpha_zero_is_rattle_step_for_step(water_box):
    system, x0, v0 = water_box.system, water_box.positions, water_box.velocities
    a, b = AlphaRattleIntegrator(0.002, alpha=0.0), RattleIntegrator(0.002)
    ca, cb = make_context(system, a, x0, v0), make_context(system, b, x0, v0)
    for _ in range(5):
        xa, va = _step_and_read(ca, a, 4)
        xb, vb = _step_and_read(cb, b, 4)
        assert np.array_equal(xa, xb) and np.array_equal(va, vb)
    assert a.force_evaluations_per_step == b.force_evaluations_per_step == 1.0
    assert total_energy(ca) == total_energy(cb)


# -------------------------------------------------- against the NumPy reference
# OpenMM's SETTLE keeps rigid water at its own geometry, ~6e-9 relative (5.7e-10 nm on
# O-H) off the exact constraint lengths on Reference and CPU alike, while CCMA/SHAKE
# bonds are exact to the tolerance: the tight comparison uses diatomics.
@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize(
    ("make_problem", "position_tolerance"), [(rigid_diatomics, 1e-11), (water_cluster, 2e-9)]
)
def test_openmm_agrees_with_numpy_reference_step_for_step(alpha, make_problem, position_tolerance):
    problem, x0, v0 = make_problem(seed=2)
    system = to_openmm_system(problem)
    integrator = AlphaRattleIntegrator(
        0.002, alpha=alpha, constraint_tolerance=1e-12, midpoint_tolerance=1e-14
    )
    ctx = make_context(system, integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    x, v = x0, v0
    worst = 0.0
    for _ in range(20):
        x, v = integrate(problem, x, v, 0.002, 1, alpha)
        xo, vo = _step_and_read(ctx, integrator, 1)
        worst = max(worst, np.max(np.abs(xo.ravel() - x)))
        # compare the maps step by step: restart the reference from OpenMM's state
        x, v = xo.ravel(), vo.ravel()
    assert worst < position_tolerance
    # different α give steps that differ far beyond that agreement
    x_rattle, _ = integrate(problem, x0, v0, 0.002, 20, 0.0)
    x_alpha, _ = integrate(problem, x0, v0, 0.002, 20, 0.7)
    assert np.max(np.abs(x_rattle - x_alpha)) > 100 * position_tolerance


def _openmm_map(system, integrator, steps):
    ctx = mm.Context(system, integrator, REFERENCE)

    def step_map(x, v):
        ctx.setPositions(x.reshape(-1, 3))
        ctx.setVelocities(v.reshape(-1, 3))
        integrator.step(steps)
        return positions_of(ctx).ravel(), velocities_of(ctx).ravel()

    return step_map


def test_openmm_symplectic_at_default_tolerance_and_one_pass_is_not():
    problem, x0, v0 = water_cluster(3, seed=4)
    system = to_openmm_system(problem)
    alpha = 0.5
    default = AlphaRattleIntegrator(0.002, alpha=alpha, constraint_tolerance=1e-12)
    one_pass = AlphaRattleIntegrator(
        0.002, alpha=alpha, constraint_tolerance=1e-12, midpoint_tolerance=1e-3, max_midpoint_iterations=1
    )
    defect = symplecticity_defect(problem, _openmm_map(system, default, 10), x0, v0, 4)
    defect_one_pass = symplecticity_defect(problem, _openmm_map(system, one_pass, 10), x0, v0, 4)
    assert defect < 1e-7
    assert defect_one_pass > 1e-6


# ------------------------------------------------------- geometry on water
@pytest.mark.parametrize("alpha", [1 / 6, 1.0])
def test_constraints_held_on_a_water_box(water_box, alpha):
    system = water_box.system
    integrator = AlphaRattleIntegrator(0.002, alpha=alpha, constraint_tolerance=1e-10)
    ctx = make_context(system, integrator, water_box.positions, water_box.velocities)
    # SETTLE holds OpenMM's TIP3P at its own geometry, ~3e-8 relative off the nominal
    # lengths (already so in the start state): the error must not grow from there
    start_err, _ = constraint_errors(system, water_box.positions, water_box.velocities)
    for _ in range(10):
        x, v = _step_and_read(ctx, integrator, 2)
        pos_err, vel_err = constraint_errors(system, x, v)
        assert pos_err < start_err + 1e-10
        assert vel_err < 1e-10
    assert integrator.midpoint_iterations >= 2


@pytest.mark.parametrize("alpha", ALPHAS)
def test_water_cluster_in_vacuum_keeps_linear_and_angular_momentum(alpha):
    problem, x0, v0 = water_cluster(8, spacing=0.3, seed=5)
    system = to_openmm_system(problem)
    # L changes by 2hα (x_m − x̃_m) × F(x̃_m) per step when the midpoint x̃_m is off by
    # the iteration error, so iterate to the round-off floor here
    integrator = AlphaRattleIntegrator(
        0.002, alpha=alpha, constraint_tolerance=1e-12, midpoint_tolerance=1e-14
    )
    ctx = make_context(system, integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    masses = problem.masses.reshape(-1, 3)[:, 0]
    l0 = angular_momentum(problem, x0, v0)
    p_err = l_err = 0.0
    for _ in range(20):
        x, v = _step_and_read(ctx, integrator, 10)
        p_err = max(p_err, np.linalg.norm(masses @ v))
        l_err = max(l_err, np.linalg.norm(angular_momentum(problem, x.ravel(), v.ravel()) - l0))
    assert np.linalg.norm(l0) > 1.0
    assert p_err < 1e-10
    assert l_err < 1e-9


def test_pme_momentum_change_is_no_worse_than_rattle(water_box):
    masses = np.array(
        [water_box.system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(water_box.n_atoms)]
    )
    p0 = masses @ water_box.velocities
    changes = {}
    for alpha in (0.0, 0.5):
        integrator = AlphaRattleIntegrator(0.002, alpha=alpha)
        ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
        _, v = _step_and_read(ctx, integrator, 20)
        changes[alpha] = np.linalg.norm(masses @ v - p0)
    assert changes[0.5] < 3 * changes[0.0] + 1e-12


def test_rattle_is_time_reversible_on_a_water_box(water_box):
    integrator = AlphaRattleIntegrator(0.002, alpha=0.0, constraint_tolerance=1e-12)
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    x, v = _step_and_read(ctx, integrator, 15)
    ctx.setVelocities(-v)
    xb, vb = _step_and_read(ctx, integrator, 15)
    assert np.max(np.abs(xb - water_box.positions)) < 1e-9
    assert np.max(np.abs(-vb - water_box.velocities)) < 1e-5


# With α ≠ 0 the step is implicit, and a PME box's truncated direct-space and LJ
# forces jump where a pair crosses the cutoff: the midpoint equation can then have
# no exact solution and the iteration stalls (seen: ~6e-9 nm RMS on single steps).
# Reversibility to solver tolerance is therefore checked on smooth forces.
@pytest.mark.parametrize("alpha", [0.0, 0.5, 1.0])
def test_time_reversible_on_a_water_cluster(alpha):
    problem, x0, v0 = water_cluster(8, spacing=0.3, seed=6)
    integrator = AlphaRattleIntegrator(
        0.002, alpha=alpha, constraint_tolerance=1e-12, midpoint_tolerance=1e-13
    )
    ctx = make_context(to_openmm_system(problem), integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    ctx.applyConstraints(1e-12)  # onto SETTLE's own water geometry
    ctx.applyVelocityConstraints(1e-12)
    x0, v0 = positions_of(ctx).ravel(), velocities_of(ctx).ravel()
    x, v = _step_and_read(ctx, integrator, 50)
    assert np.max(np.abs(x.ravel() - x0)) > 1e-2
    ctx.setVelocities(-v)
    xb, vb = _step_and_read(ctx, integrator, 50)
    assert np.max(np.abs(xb.ravel() - x0)) < 1e-10
    assert np.max(np.abs(-vb.ravel() - v0)) < 1e-7


def test_system_without_constraints():
    system = mm.System()
    nb = mm.NonbondedForce()
    nb.setNonbondedMethod(mm.NonbondedForce.NoCutoff)
    rng = np.random.default_rng(0)
    grid = np.array([(i, j, k) for i in range(2) for j in range(2) for k in range(2)], dtype=float) * 0.38
    for _ in grid:
        system.addParticle(39.9)
        nb.addParticle(0.0, 0.34, 0.99)
    system.addForce(nb)
    v0 = rng.normal(scale=0.2, size=grid.shape)
    energies = {}
    for alpha in (0.0, 1 / 6):
        integrator = AlphaRattleIntegrator(0.002, alpha=alpha)
        ctx = make_context(system, integrator, grid, v0)
        e0 = total_energy(ctx)
        integrator.step(200)
        energies[alpha] = abs(total_energy(ctx) - e0)
    assert max(energies.values()) < 1e-3


# ----------------------------------------------------------------- plumbing
def test_works_in_simulation_with_openmm_reporters(water_box):
    integrator = AlphaRattleIntegrator(2 * unit.femtoseconds, alpha=1 / 6)
    sim = app.Simulation(water_box.topology, water_box.system, integrator, REFERENCE)
    sim.context.setPositions(water_box.positions)
    sim.context.setVelocities(water_box.velocities)
    out = io.StringIO()
    sim.reporters.append(app.StateDataReporter(out, 5, step=True, totalEnergy=True, temperature=True))
    sim.step(10)
    lines = out.getvalue().strip().splitlines()
    assert len(lines) == 3 and lines[-1].startswith("10,")
    assert integrator.steps_taken == 10
    assert integrator.timestep == 0.002 * unit.picoseconds


def test_xml_round_trip_and_get_integrator_give_the_class_back(water_box):
    original = AlphaRattleIntegrator(0.002, alpha=0.5, midpoint_tolerance=1e-11, max_midpoint_iterations=7)
    copy = restore_integrator(mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(original)))
    assert isinstance(copy, AlphaRattleIntegrator)
    assert copy.alpha == 0.5 and copy.max_midpoint_iterations == 7
    assert copy.midpoint_tolerance == 1e-11 * unit.nanometers
    ca = make_context(water_box.system, original, water_box.positions, water_box.velocities)
    cb = make_context(water_box.system, copy, water_box.positions, water_box.velocities)
    original.step(5)
    copy.step(5)
    assert np.array_equal(positions_of(ca), positions_of(cb))
    bound = restore_integrator(cb.getIntegrator())
    assert isinstance(bound, AlphaRattleIntegrator) and bound.steps_taken == 5
    bound.alpha = 0.25
    assert copy.alpha == 0.25  # the same C++ object
    rattle = restore_integrator(
        mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(RattleIntegrator(0.001)))
    )
    assert type(rattle) is RattleIntegrator
    assert isinstance(pickle.loads(pickle.dumps(original)), AlphaRattleIntegrator)
    with pytest.raises(TypeError, match="not created by openmm_alphaprk"):
        restore_integrator(mm.VerletIntegrator(0.001))


def test_checkpoint_restart_continues_identically(water_box):
    integrator = AlphaRattleIntegrator(0.002, alpha=0.5)
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    integrator.step(5)
    checkpoint = ctx.createCheckpoint()
    integrator.step(5)
    expected = positions_of(ctx), velocities_of(ctx), integrator.force_evaluations

    fresh = AlphaRattleIntegrator(0.002, alpha=0.5)
    ctx2 = mm.Context(water_box.system, fresh, REFERENCE)
    ctx2.loadCheckpoint(checkpoint)
    assert fresh.steps_taken == 5
    fresh.step(5)
    assert np.array_equal(positions_of(ctx2), expected[0])
    assert np.array_equal(velocities_of(ctx2), expected[1])
    assert fresh.force_evaluations == expected[2]


def test_virtual_sites_are_stale_inside_a_step_and_are_refused():
    forcefield = app.ForceField("tip4pew.xml")
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, model="tip4pew", boxSize=mm.Vec3(1.6, 1.6, 1.6) * unit.nanometers)
    system = forcefield.createSystem(
        modeller.topology, nonbondedMethod=app.PME, nonbondedCutoff=0.7, rigidWater=True, removeCMMotion=False
    )
    massive = np.array(
        [system.getParticleMass(i).value_in_unit(unit.dalton) > 0 for i in range(system.getNumParticles())]
    )
    # the platform fact behind the refusal: a force taken inside a CustomIntegrator
    # step does not see virtual sites placed at the moved positions
    probe = mm.CustomIntegrator(0.001)
    probe.addPerDofVariable("x_start", 0)
    probe.addPerDofVariable("f_inside", 0)
    probe.addComputePerDof("x_start", "x")
    probe.addComputePerDof("x", "x + 0.01*v")
    probe.addComputePerDof("f_inside", "f")
    probe.addComputePerDof("x", "x_start")
    ctx = mm.Context(system, probe, REFERENCE)
    ctx.setPositions(modeller.positions)
    ctx.computeVirtualSites()
    x0 = positions_of(ctx)
    displacement = np.random.default_rng(0).normal(size=x0.shape) * massive[:, None]
    ctx.setVelocities(displacement)
    probe.step(1)
    inside = np.array([list(f) for f in probe.getPerDofVariableByName("f_inside")])
    ctx.setPositions(x0 + 0.01 * displacement)
    ctx.computeVirtualSites()
    true = (
        ctx.getState(getForces=True)
        .getForces(asNumpy=True)
        .value_in_unit(unit.kilojoules_per_mole / unit.nanometer)
    )
    assert np.max(np.abs(inside - true)[massive]) > 1.0

    for integrator in (AlphaRattleIntegrator(0.002, alpha=0.5), RattleIntegrator(0.002)):
        ctx = mm.Context(system, integrator, REFERENCE)
        ctx.setPositions(modeller.positions)
        with pytest.raises(IncompatibleSystemError, match="virtual sites|zero mass"):
            integrator.step(3)


def test_unconverged_midpoint_iteration_is_refused_and_leaves_the_last_good_state(water_box):
    # contraction factor of the iteration ≈ |α| h²ω²/4 > 1 at α = 50: it diverges
    integrator = AlphaRattleIntegrator(0.002, alpha=50.0)
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    with pytest.raises(MidpointConvergenceError, match="did not converge"):
        integrator.step(3)
    # the failed step falls back to its start inside its last constrained solve:
    # the start state re-constrained, equal to round-off
    assert np.max(np.abs(positions_of(ctx) - water_box.positions)) < 1e-12
    assert np.max(np.abs(velocities_of(ctx) - water_box.velocities)) < 1e-12


def test_iteration_cap_and_force_evaluation_counts(water_box):
    capped = AlphaRattleIntegrator(0.002, alpha=0.5, max_midpoint_iterations=2, midpoint_tolerance=1e-6)
    ctx = make_context(water_box.system, capped, water_box.positions, water_box.velocities)
    capped.step(4)
    assert capped.steps_taken == ctx.getStepCount() == 4
    assert capped.midpoint_iterations <= 2
    assert capped.last_step_force_evaluations == capped.midpoint_iterations + 1
    assert 2.0 <= capped.force_evaluations_per_step <= 3.0


def test_step_programs_are_small_and_start_quickly(water_box):
    for integrator, most in (
        (RattleIntegrator(0.002), 1),
        (AlphaRattleIntegrator(0.002, alpha=0.5), 5),
        (AlphaRattleEnergyIntegrator(0.002), 5),
        (AlphaRattleEnergyIntegrator(0.002, composition="triple-jump"), 6),
    ):
        assert analysed_blocks(integrator) <= most
        ctx = make_context(
            water_box.system,
            integrator,
            water_box.positions,
            water_box.velocities,
            mm.Platform.getPlatformByName("CPU"),
        )
        start = time.perf_counter()
        integrator.step(1)
        assert time.perf_counter() - start < 5.0
        del ctx


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"timestep": 0.0}, ValueError, "timestep must be positive"),
        ({"timestep": -0.002}, ValueError, "timestep must be positive"),
        ({"timestep": 2 * unit.nanometers}, TypeError, "cannot be converted"),
        ({"timestep": float("nan")}, ValueError, "finite"),
        ({"timestep": 0.002, "alpha": float("nan")}, ValueError, "alpha must be finite"),
        ({"timestep": 0.002, "alpha": float("inf")}, ValueError, "alpha must be finite"),
        ({"timestep": 0.002, "alpha": "big"}, ValueError, "alpha must be a number"),
        ({"timestep": 0.002, "alpha": 1 * unit.nanometers}, TypeError, "alpha must be dimensionless"),
        (
            {"timestep": 0.002, "constraint_tolerance": 0.0},
            ValueError,
            "constraint_tolerance must be positive",
        ),
        ({"timestep": 0.002, "midpoint_tolerance": -1e-9}, ValueError, "midpoint_tolerance must be positive"),
        ({"timestep": 0.002, "max_midpoint_iterations": 0}, ValueError, "positive integer"),
        ({"timestep": 0.002, "max_midpoint_iterations": 2.5}, ValueError, "positive integer"),
    ],
)
def test_bad_arguments_give_clear_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        AlphaRattleIntegrator(**kwargs)


def test_bad_values_set_later_give_clear_errors():
    integrator = AlphaRattleIntegrator(0.002)
    with pytest.raises(ValueError, match="alpha must be finite"):
        integrator.alpha = float("nan")
    with pytest.raises(ValueError, match="midpoint_tolerance must be positive"):
        integrator.midpoint_tolerance = 0
    with pytest.raises(ValueError, match="positive integer"):
        integrator.max_midpoint_iterations = -3
    with pytest.raises(ValueError, match="timestep must be positive"):
        RattleIntegrator(0)
    assert integrator.alpha == 0.0
