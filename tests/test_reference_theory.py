"""The α-RATTLE family's numerical properties, checked on the NumPy reference.

Each test compares against a contrast that must fail (one-pass midpoint, a step
above the stability bound, RATTLE's phase error, α acting under a varying force)
so that the check can fail.
"""

import numpy as np
import pytest

from openmm_alphaprk.observables import convergence_order
from openmm_alphaprk.reference import (
    alpha_rattle_step,
    angular_momentum,
    harmonic_oscillator,
    integrate,
    linear_momentum,
    planar_pendulum,
    planar_pendulum_period,
    planar_pendulum_start,
    spherical_pendulum,
    spherical_pendulum_start,
    symplecticity_defect,
    water_cluster,
)

ALPHAS = [0.0, 1 / 6, 0.5, 1.0]


def test_pendulum_periods_and_spherical_pendulum_values_match_the_design_doc():
    assert planar_pendulum_period(np.pi / 2) == pytest.approx(7.416298709205487, rel=1e-14)
    assert planar_pendulum_period(np.pi / 3) == pytest.approx(6.743001419250384, rel=1e-14)
    assert planar_pendulum_period(2.0) == pytest.approx(8.349752926918493, rel=1e-14)
    problem = spherical_pendulum()
    x, v = spherical_pendulum_start()
    assert problem.energy(x, v) == pytest.approx(25.892498828624586, rel=1e-14)
    assert x[0] * v[1] - x[1] * v[0] == pytest.approx(6.263128205211754, rel=1e-14)


_slope = convergence_order


def test_order_two_at_the_exact_pendulum_period():
    theta0 = np.pi / 2
    period = planar_pendulum_period(theta0)
    problem = planar_pendulum()
    x0, v0 = planar_pendulum_start(theta0)
    counts = np.array([40, 80, 160, 320])
    errors = []
    for n in counts:
        x, v = integrate(problem, x0, v0, period / n, int(n), alpha=0.0)
        errors.append(np.linalg.norm(np.concatenate([x - x0, v - v0])))
    assert _slope(period / counts, errors) == pytest.approx(2.0, abs=0.1)


@pytest.mark.parametrize("alpha", [0.0, 1 / 6, 0.5, 1.0, -0.5])
def test_order_two_with_position_dependent_forces(alpha):
    problem = planar_pendulum(kappa=2.0)
    x0, v0 = planar_pendulum_start(1.0)
    t_end = 2.0
    x_ref, v_ref = integrate(problem, x0, v0, t_end / 4096, 4096, alpha=1 / 6)
    counts = np.array([20, 40, 80, 160])
    errors = []
    for n in counts:
        x, v = integrate(problem, x0, v0, t_end / n, int(n), alpha=alpha)
        errors.append(np.linalg.norm(np.concatenate([x - x_ref, v - v_ref])))
    assert _slope(t_end / counts, errors) == pytest.approx(2.0, abs=0.1)


def test_alpha_changes_nothing_under_a_constant_force_but_acts_otherwise():
    x0, v0 = planar_pendulum_start(1.2)
    constant = planar_pendulum(kappa=0.0)
    xa, va = integrate(constant, x0, v0, 0.1, 50, alpha=0.0)
    xb, vb = integrate(constant, x0, v0, 0.1, 50, alpha=0.7)
    assert np.max(np.abs(np.concatenate([xa - xb, va - vb]))) < 1e-13
    varying = planar_pendulum(kappa=2.0)
    xa, va = integrate(varying, x0, v0, 0.1, 50, alpha=0.0)
    xb, vb = integrate(varying, x0, v0, 0.1, 50, alpha=0.7)
    assert np.max(np.abs(xa - xb)) > 1e-4


@pytest.mark.parametrize("alpha", [0.0, 0.3, 1.0])
def test_symplectic_on_the_pendulum_and_one_pass_is_not(alpha):
    problem = planar_pendulum(kappa=2.0)
    x0, v0 = planar_pendulum_start(1.0)
    iterated = symplecticity_defect(problem, lambda x, v: integrate(problem, x, v, 0.1, 5, alpha), x0, v0, 2)
    assert iterated < 1e-7
    if alpha != 0.0:
        one_pass = symplecticity_defect(
            problem, lambda x, v: integrate(problem, x, v, 0.1, 5, alpha, one_pass=True), x0, v0, 2
        )
        assert one_pass > 1e-6
        assert one_pass > 100 * iterated


@pytest.mark.parametrize("alpha", [1 / 6, 0.5])
def test_symplectic_on_a_water_cluster_and_one_pass_is_not(alpha):
    problem, x0, v0 = water_cluster(3)
    defect = symplecticity_defect(problem, lambda x, v: integrate(problem, x, v, 0.002, 10, alpha), x0, v0, 4)
    one_pass = symplecticity_defect(
        problem, lambda x, v: integrate(problem, x, v, 0.002, 10, alpha, one_pass=True), x0, v0, 4
    )
    assert defect < 1e-7
    assert one_pass > 1e-6


@pytest.mark.parametrize("alpha", ALPHAS)
def test_constraints_and_quadratic_invariants_on_the_spherical_pendulum(alpha):
    problem = spherical_pendulum(kappa=0.5)
    x0, v0 = spherical_pendulum_start()
    _, _, xs, vs = integrate(problem, x0, v0, 0.01, 300, alpha, record=True)
    l3 = xs[:, 0] * vs[:, 1] - xs[:, 1] * vs[:, 0]
    assert np.max(np.abs(l3 - l3[0])) < 1e-12 * abs(l3[0]) * 300
    assert np.max(np.abs(np.einsum("ij,ij->i", xs, xs) - 1)) < 1e-13
    assert np.max(np.abs(np.einsum("ij,ij->i", xs, vs))) < 1e-11


@pytest.mark.parametrize("alpha", ALPHAS)
def test_water_cluster_keeps_momenta_and_constraints(alpha):
    problem, x0, v0 = water_cluster(4, seed=3)
    _, _, xs, vs = integrate(problem, x0, v0, 0.002, 100, alpha, record=True)
    l_start = angular_momentum(problem, x0, v0)
    p_drift = max(np.linalg.norm(linear_momentum(problem, v) - linear_momentum(problem, v0)) for v in vs)
    l_drift = max(np.linalg.norm(angular_momentum(problem, x, v) - l_start) for x, v in zip(xs, vs))
    assert p_drift < 1e-11
    assert l_drift < 1e-11
    assert max(np.max(np.abs(problem.g(x))) for x in xs) < 1e-13
    assert max(np.max(np.abs(problem.G(x) @ v)) for x, v in zip(xs, vs)) < 1e-10


@pytest.mark.parametrize("alpha", [0.0, 1 / 6, 1.0])
def test_time_reversible(alpha):
    problem, x0, v0 = water_cluster(3, seed=1)
    x, v = integrate(problem, x0, v0, 0.002, 30, alpha)
    xb, vb = integrate(problem, x, -v, 0.002, 30, alpha)
    assert np.max(np.abs(xb - x0)) < 1e-11
    assert np.max(np.abs(-vb - v0)) < 1e-8


def _max_amplitude(alpha, h_omega, steps=2000):
    problem = harmonic_oscillator(1.0)
    x, v = np.array([1.0]), np.array([0.0])
    f = problem.force(x)
    peak = 0.0
    for _ in range(steps):
        x, v, f = alpha_rattle_step(problem, x, v, h_omega, alpha, f0=f, midpoint_solver="newton")
        peak = max(peak, abs(x[0]))
        if peak > 1e6:
            break
    return peak


@pytest.mark.parametrize("alpha", [0.0, 0.25, 0.4])
def test_linear_stability_bound_below_one_half(alpha):
    bound = 2 / np.sqrt(1 - 2 * alpha)
    assert _max_amplitude(alpha, 0.98 * bound) < 100
    assert _max_amplitude(alpha, 1.02 * bound) > 1e6


@pytest.mark.parametrize("alpha", [0.5, 1.0])
def test_unconditionally_stable_from_one_half(alpha):
    for h_omega in (3.0, 10.0, 30.0):
        assert _max_amplitude(alpha, h_omega) < 10


def test_fixed_point_midpoint_iteration_diverges_beyond_its_contraction_limit():
    # contraction factor |α| h²ω²/4: 0.4 * 4.4² / 4 ≈ 1.9 > 1, so the iteration must fail loudly
    problem = harmonic_oscillator(1.0)
    with pytest.raises(RuntimeError, match="did not converge"):
        alpha_rattle_step(problem, np.array([1.0]), np.array([0.0]), 4.4, 0.4)


def _relative_phase_error(alpha, h_omega=0.3):
    problem = harmonic_oscillator(1.0)
    _, _, xs, _ = integrate(problem, np.array([1.0]), np.array([0.0]), h_omega, 3, alpha, record=True)
    # any solution of the two-step recurrence satisfies x_{k+1} + x_{k-1} = 2 cos(θ) x_k
    theta = np.arccos((xs[2, 0] + xs[0, 0]) / (2 * xs[1, 0]))
    return (theta - h_omega) / h_omega


def test_alpha_one_sixth_has_fourth_order_phase_accuracy():
    rattle = _relative_phase_error(0.0)
    sixth = _relative_phase_error(1 / 6)
    assert rattle == pytest.approx(3.8e-3, rel=0.02)
    assert abs(sixth) == pytest.approx(1.7e-5, rel=0.05)
    assert _relative_phase_error(1.0) == pytest.approx(-1.8e-2, rel=0.05)
