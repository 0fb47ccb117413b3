"""α-RATTLE-4 (composition="triple-jump"): the triple-jump composition with α on the middle sub-step.

Theory on the NumPy reference (orders, α* = O(h²), symplecticity with a contrast
that must fail), then the OpenMM program against the reference and on water.
"""

import numpy as np
import openmm as mm
import pytest
from conftest import invariant_errors, make_context, positions_of, velocities_of

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    ControllerSettings,
    RattleIntegrator,
)
from openmm_alphaprk.observables import convergence_order, energy_residuals, rms
from openmm_alphaprk.reference import (
    GAMMA1,
    GAMMA2,
    alpha_rattle4_step,
    integrate,
    integrate_energy_preserving,
    planar_pendulum,
    planar_pendulum_start,
    rigid_diatomics,
    symplecticity_defect,
    to_openmm_system,
    water_cluster,
)

COUNTS = np.array([20, 40, 80, 160])
T_END = 2.0

#: The CPU platform where a test checks sizes, not Reference's bitwise repeatability.
CPU = mm.Platform.getPlatformByName("CPU")


_slope = convergence_order


@pytest.fixture(scope="module")
def pendulum():
    """Pendulum with a horizontal spring (position-dependent force) and a fine reference solution."""
    problem = planar_pendulum(kappa=2.0)
    x0, v0 = planar_pendulum_start(1.0)
    x_ref, v_ref = integrate(problem, x0, v0, T_END / 2048, 2048, 0.0, step=alpha_rattle4_step)
    return problem, x0, v0, np.concatenate([x_ref, v_ref])


def test_weights_are_the_triple_jump():
    assert 2 * GAMMA1 + GAMMA2 == pytest.approx(1.0, abs=1e-15)
    assert 2 * GAMMA1**3 + GAMMA2**3 == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize(("alpha", "order"), [(0.0, 4.0), (0.3, 2.0), (-0.2, 2.0)])
def test_order_four_at_alpha_zero_and_two_at_fixed_alpha(pendulum, alpha, order):
    problem, x0, v0, reference = pendulum
    errors = []
    for n in COUNTS:
        x, v = integrate(problem, x0, v0, T_END / n, int(n), alpha, step=alpha_rattle4_step)
        errors.append(np.linalg.norm(np.concatenate([x, v]) - reference))
    # measured: 4.03 at α = 0, 2.00 at α = 0.3 (design doc §8: 4.01 / 1.99)
    assert _slope(T_END / COUNTS, errors) == pytest.approx(order, abs=0.1)


def test_energy_mode_is_order_four_with_alpha_star_of_order_h_squared(pendulum):
    problem, x0, v0, reference = pendulum
    e0 = problem.energy(x0, v0)
    errors, largest = [], []
    for n in COUNTS:
        x, v, alphas = integrate_energy_preserving(alpha_rattle4_step, problem, x0, v0, T_END / n, int(n))
        assert problem.energy(x, v) == pytest.approx(e0, abs=1e-12)
        errors.append(np.linalg.norm(np.concatenate([x, v]) - reference))
        largest.append(np.max(np.abs(alphas)))
    assert _slope(T_END / COUNTS, errors) == pytest.approx(4.0, abs=0.15)
    # |α*| shrinks about 4× per halving of h (measured 4.04, 4.01, 4.00)
    ratios = np.array(largest[:-1]) / np.array(largest[1:])
    assert np.all(np.abs(ratios - 4.0) < 0.3)
    assert largest[-1] < 1e-3


@pytest.mark.parametrize("alpha", [0.0, 0.3])
def test_symplectic_for_fixed_alpha_and_one_pass_is_not(pendulum, alpha):
    problem, x0, v0, _ = pendulum

    def flow(x, v, **options):
        return integrate(problem, x, v, 0.1, 5, alpha, step=alpha_rattle4_step, **options)

    defect = symplecticity_defect(problem, flow, x0, v0, 2)
    assert defect < 1e-7
    if alpha != 0.0:
        one_pass = symplecticity_defect(problem, lambda x, v: flow(x, v, one_pass=True), x0, v0, 2)
        assert one_pass > 100 * defect


@pytest.mark.parametrize("alpha", [0.0, 0.3])
@pytest.mark.parametrize(
    ("make_problem", "tolerance"),
    [(rigid_diatomics, 1e-11), (lambda: water_cluster(3), 2e-9)],
    ids=["diatomics", "water-cluster"],
)
def test_openmm_agrees_with_numpy_reference_step_for_step(alpha, make_problem, tolerance):
    problem, x0, v0 = make_problem()
    integrator = AlphaRattleIntegrator(
        0.002, alpha=alpha, composition="triple-jump", constraint_tolerance=1e-12, midpoint_tolerance=1e-14
    )
    ctx = make_context(to_openmm_system(problem), integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    x_ref, v_ref, xs, _ = integrate(problem, x0, v0, 0.002, 10, alpha, step=alpha_rattle4_step, record=True)
    for k in range(1, 11):
        integrator.step(1)
        assert np.max(np.abs(positions_of(ctx).ravel() - xs[k])) < tolerance
    assert np.max(np.abs(velocities_of(ctx).ravel() - v_ref)) < 1e3 * tolerance
    expected = 3 if alpha == 0 else 3 + integrator.midpoint_iterations
    assert integrator.last_step_force_evaluations == expected


@pytest.mark.parametrize("alpha", [0.3, "energy"])
def test_water_cluster_keeps_constraints_and_angular_momentum(alpha):
    problem, x0, v0 = water_cluster(8, spacing=0.3, seed=5)
    options = dict(composition="triple-jump", constraint_tolerance=1e-12, midpoint_tolerance=1e-13)
    if alpha == "energy":
        integrator = AlphaRattleEnergyIntegrator(0.002, **options)
    else:
        integrator = AlphaRattleIntegrator(0.002, alpha=alpha, **options)
    ctx = make_context(to_openmm_system(problem), integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    found = invariant_errors(problem, ctx, integrator)
    assert found["l0"] > 1.0
    assert found["l_err"] < 1e-9
    assert found["p_err"] < 1e-10
    assert found["c_err"] < found["c_start"] + 1e-10


def _energy_rms(ctx, integrator, steps):
    return rms(energy_residuals(ctx, integrator, steps).residuals)


def test_energy_mode_on_a_water_box_is_far_below_rattle(water_box):
    steps = 40
    rattle = RattleIntegrator(0.002)
    rattle_rms = _energy_rms(
        make_context(water_box.system, rattle, water_box.positions, water_box.velocities, CPU), rattle, steps
    )
    triple_jump = AlphaRattleIntegrator(0.002, alpha=0.0, composition="triple-jump")
    triple_rms = _energy_rms(
        make_context(water_box.system, triple_jump, water_box.positions, water_box.velocities, CPU),
        triple_jump,
        steps,
    )
    integrator = AlphaRattleEnergyIntegrator(
        0.002, composition="triple-jump", controller=ControllerSettings(energy_tolerance=0.01)
    )
    ctx = make_context(water_box.system, integrator, water_box.positions, water_box.velocities, CPU)
    energy_rms = _energy_rms(ctx, integrator, steps)
    totals = integrator.controller_totals()
    lo, hi = integrator.alpha_bounds
    # measured (smooth 1.8 nm box, CPU platform, 40 steps, three runs): RMS RATTLE 0.88, triple
    # jump 0.044, energy mode 0.0069-0.0070 with 92% of steps within 0.01 kJ/mol, no step at a
    # bound, 5.95-6.03 evaluations/step
    assert triple_rms < 0.1 * rattle_rms
    assert energy_rms < 0.5 * triple_rms
    assert energy_rms < 0.02 * rattle_rms
    assert totals["fraction_within_tolerance"] > 0.7
    assert totals["steps_at_bound"] == 0
    assert lo < integrator.alpha < hi
    assert integrator.force_evaluations_per_step < 8


def test_order_is_checked_and_reported():
    with pytest.raises(ValueError, match="order must be 2"):
        AlphaRattleIntegrator(0.002, order=3)
    with pytest.raises(ValueError, match="order must be 2"):
        AlphaRattleIntegrator(0.002, order=True)
    integrator = AlphaRattleEnergyIntegrator(0.002, composition="triple-jump")
    assert integrator.order == 4
    assert integrator.alpha_bounds == (-0.2, 0.2)
    assert f"composition={integrator.composition.name!r}" in repr(integrator)
    assert AlphaRattleIntegrator(0.002).order == 2
    assert AlphaRattleIntegrator(0.002).composition is None
    restored = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(integrator))
    from openmm_alphaprk import restore_integrator

    assert restore_integrator(restored).order == 4
    assert restored.composition.coefficients == integrator.composition.coefficients
    assert restored.composition.alpha_stages == integrator.composition.alpha_stages
