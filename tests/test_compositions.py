"""Compositions as data: every named set's order, and the OpenMM programs built from the coefficients.

The order of each named composition is measured (the error ratio at h and h/2 on a
pendulum) on the NumPy reference and on the OpenMM program; the programs agree with the
reference step for step with α on one stage and on all; α on several stages is
refused by the energy mode.
"""

import numpy as np
import openmm.unit as unit
import pytest
from conftest import PENDULUM_T_END, make_context, positions_of, velocities_of

from openmm_alphaprk import AlphaRattleEnergyIntegrator, AlphaRattleIntegrator
from openmm_alphaprk.integrators.compositions import COMPOSITIONS, TRIPLE_JUMP, Composition, composition
from openmm_alphaprk.observables import convergence_order
from openmm_alphaprk.reference import (
    composition_step,
    integrate,
    rigid_diatomics,
    to_openmm_system,
    water_cluster,
)

T_END = PENDULUM_T_END
#: Steps over T_END: inside every set's asymptotic range, errors far above the reference's (~1e-11).
COUNTS = (16, 32)


def _error(pendulum, chosen, n, alpha=0.0):
    problem, x0, v0, reference = pendulum
    x, v = integrate(problem, x0, v0, T_END / n, n, alpha, step=composition_step, composition=chosen)
    return np.linalg.norm(np.concatenate([x, v]) - reference)


@pytest.mark.parametrize("name", list(COMPOSITIONS))
def test_each_named_composition_has_its_order(pendulum, name):
    chosen = COMPOSITIONS[name]
    errors = [_error(pendulum, chosen, n) for n in COUNTS]
    # measured: 4.13 (triple jump), 4.01, 4.03; 6.08, 6.03, 6.04
    assert convergence_order(T_END / np.array(COUNTS), errors) == pytest.approx(chosen.order, abs=0.2)
    assert sum(chosen.coefficients) == pytest.approx(1.0, abs=1e-14)
    assert sum(c**3 for c in chosen.coefficients) == pytest.approx(0.0, abs=1e-13)


@pytest.mark.parametrize(("stages", "order"), [("middle", 2.0), ((1,), 2.0), ("all", 4.0)])
def test_a_fixed_alpha_on_one_stage_is_second_order_and_on_every_stage_keeps_the_order(
    pendulum, stages, order
):
    """α on every stage composes one symmetric second-order map (α-RATTLE at that α): order 4 stays."""
    chosen = COMPOSITIONS["suzuki5"].with_alpha_on(stages)
    errors = [_error(pendulum, chosen, n, alpha=0.3) for n in (32, 64)]
    # measured: 2.00 (middle), 2.01 (first), 4.00 (all)
    assert convergence_order(T_END / np.array([32, 64]), errors) == pytest.approx(order, abs=0.1)


def test_coefficients_that_are_not_a_composition_are_refused():
    with pytest.raises(ValueError, match="sum to 1"):
        Composition("bad", (0.5, 0.4, 0.5), 4, "test")
    with pytest.raises(ValueError, match="symmetric"):
        Composition("bad", (0.6, 0.1, 0.3), 4, "test")
    with pytest.raises(ValueError, match="alpha stages"):
        Composition("bad", (0.5, 0.5), 2, "test", alpha_stages=(3,))
    with pytest.raises(ValueError, match="unknown composition"):
        composition("no-such-set")


def _openmm_order(chosen: Composition, counts: tuple[int, int]) -> float:
    """Order of the OpenMM program (Reference platform) on rigid diatomics over 0.2 ps."""
    problem, x0, v0 = rigid_diatomics()
    t_end = 0.2
    x_ref, _ = integrate(problem, x0, v0, t_end / 512, 512, 0.0, step=composition_step, composition=chosen)
    errors = []
    for n in counts:
        h = t_end / n * unit.picoseconds
        integrator = AlphaRattleIntegrator(h, alpha=0.0, composition=chosen, constraint_tolerance=1e-13)
        ctx = make_context(to_openmm_system(problem), integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
        integrator.step(n)
        errors.append(np.linalg.norm(positions_of(ctx).ravel() - x_ref))
    return convergence_order(t_end / np.array(counts), errors)


@pytest.mark.parametrize("name", list(COMPOSITIONS))
def test_each_openmm_composition_program_has_its_order(name):
    chosen = COMPOSITIONS[name]
    # measured: 4.08, 4.08, 4.01; 6.01, 6.00, 6.02 (errors 1e-9 … 1e-4 nm, far above round-off)
    assert _openmm_order(chosen, (8, 16)) == pytest.approx(chosen.order, abs=0.2)


@pytest.mark.parametrize("stages", ["middle", "all"])
@pytest.mark.parametrize("alpha", [0.0, 0.2])
def test_openmm_program_is_the_reference_step_with_alpha_on_any_stages(stages, alpha):
    chosen = COMPOSITIONS["suzuki5"].with_alpha_on(stages)
    problem, x0, v0 = water_cluster(3)
    integrator = AlphaRattleIntegrator(
        0.002,
        alpha=alpha,
        composition=chosen,
        constraint_tolerance=1e-12,
        midpoint_tolerance=1e-14,
        max_midpoint_iterations=100,
    )
    ctx = make_context(to_openmm_system(problem), integrator, x0.reshape(-1, 3), v0.reshape(-1, 3))
    _, v_ref, xs, _ = integrate(
        problem, x0, v0, 0.002, 5, alpha, step=composition_step, composition=chosen, record=True
    )
    for k in range(1, 6):
        integrator.step(1)
        assert np.max(np.abs(positions_of(ctx).ravel() - xs[k])) < 2e-9
    assert np.max(np.abs(velocities_of(ctx).ravel() - v_ref)) < 2e-6
    midpoints = integrator.midpoint_iterations
    assert integrator.last_step_force_evaluations == chosen.stages + midpoints
    assert (midpoints > 0) == (alpha != 0.0)
    if alpha != 0.0:
        # one or more midpoint forces on each stage that carries α
        assert midpoints >= len(chosen.alpha_stages)


def test_the_triple_jump_by_name_is_order_four():
    assert AlphaRattleIntegrator(0.002, composition="triple-jump").composition == TRIPLE_JUMP
    with pytest.raises(ValueError, match="order 4"):
        AlphaRattleIntegrator(0.002, order=6, composition="triple-jump")


def test_energy_mode_takes_alpha_on_one_stage():
    with pytest.raises(ValueError, match="one stage"):
        AlphaRattleEnergyIntegrator(0.002, composition="suzuki5", alpha_stages="all")
    integrator = AlphaRattleEnergyIntegrator(0.002, composition="suzuki5", alpha_stages=(2,))
    assert integrator.composition.alpha_stages == (2,)


def test_the_default_energy_mode_holds_h_on_a_water_box_at_the_measured_cost(
    water_box, rattle_residuals_on_the_water_box
):
    """order=4 (Suzuki) energy mode, Reference, 40 steps of 2 fs on the 1.8 nm test box.

    Measured: RMS(H − E_ref) 0.00275 kJ/mol (RATTLE 0.88, Suzuki at α = 0 0.0083) at 8.20
    evaluations per step, every step within the automatic tolerance (over 60 steps: 0.0028,
    RATTLE 0.92, Suzuki at α = 0 0.011, 8.32 evaluations, 98 %); the benchmarks measured
    8.5–9.4 evaluations on the shipped boxes (docs/compositions.md).
    """
    from openmm_alphaprk.observables import energy_residuals, rms

    def energy_rms(integrator):
        context = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
        return rms(energy_residuals(context, integrator, 40).residuals)

    rattle = rms(rattle_residuals_on_the_water_box[:40])  # the first 40 steps of the session's RATTLE run
    composed = energy_rms(AlphaRattleIntegrator(0.002, alpha=0.0, order=4))
    integrator = AlphaRattleEnergyIntegrator(0.002, order=4)
    held = energy_rms(integrator)
    totals = integrator.controller_totals()
    assert integrator.composition.name == "suzuki5"
    assert held < 0.5 * composed < 0.02 * rattle
    assert held < 0.01 * rattle
    assert totals["fraction_within_tolerance"] > 0.9
    assert totals["steps_at_bound"] == 0
    assert integrator.force_evaluations_per_step < 9.5
