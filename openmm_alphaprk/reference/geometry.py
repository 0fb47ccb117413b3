"""Geometric checks of one-step maps: symplecticity on the constraint manifold."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .step import Array, ConstrainedProblem, project_to_manifold

StepMap = Callable[[Array, Array], tuple[Array, Array]]


def tangent_vectors(problem: ConstrainedProblem, x: Array, v: Array, count: int, seed: int = 0) -> Array:
    """Random tangent vectors ξ = (δq, δv) of the constrained phase space at (x, v).

    δq lies in ker G(x); δv satisfies the linearised hidden constraint
    G(x) δv + (DG(x)[δq]) v = 0. Returns an array of shape (count, 2n).

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x, v : numpy.ndarray
        A consistent state.
    count : int
        Number of vectors.
    seed : int, default 0
        Seed of the random vectors.

    Returns
    -------
    numpy.ndarray
        Shape (count, 2n): δq then δv.

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start, tangent_vectors
    >>> pendulum = planar_pendulum()
    >>> x, v = planar_pendulum_start(0.5)
    >>> xi = tangent_vectors(pendulum, x, v, count=3)
    >>> xi.shape, bool(abs(xi[0, :2] @ x) < 1e-12)  # δq along the circle
    ((3, 4), True)
    """
    rng = np.random.default_rng(seed)
    n = problem.n_dof
    G = problem.G(x)
    vectors = []
    for _ in range(count):
        dq = rng.normal(size=n)
        dv = rng.normal(size=n)
        if G.shape[0]:
            dq -= G.T @ np.linalg.solve(G @ G.T, G @ dq)
            eta = 1e-4
            dG = (problem.G(x + eta * dq) - problem.G(x - eta * dq)) / (2 * eta)
            rhs = -dG @ v - G @ dv
            dv += G.T @ np.linalg.solve(G @ G.T, rhs)
        vectors.append(np.concatenate([dq, dv]))
    return np.array(vectors)


def symplectic_form(problem: ConstrainedProblem, a: Array, b: Array) -> float:
    """ω(a, b) = a_qᵀ M b_v − a_vᵀ M b_q for a = (a_q, a_v), b = (b_q, b_v).

    Parameters
    ----------
    problem : ConstrainedProblem
        Gives the masses M.
    a, b : numpy.ndarray
        Tangent vectors of length 2n (positions, then velocities).

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> from openmm_alphaprk.reference import harmonic_oscillator, symplectic_form
    >>> oscillator = harmonic_oscillator()
    >>> symplectic_form(oscillator, np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    1.0
    """
    n = problem.n_dof
    m = problem.masses
    return float(a[:n] @ (m * b[n:]) - a[n:] @ (m * b[:n]))


def symplecticity_defect(
    problem: ConstrainedProblem,
    step_map: StepMap,
    x: Array,
    v: Array,
    count: int = 4,
    epsilon: float = 1e-6,
    seed: int = 0,
) -> float:
    """Relative change of the symplectic form under a map, on the constraint manifold.

    Tangent vectors ξ_i at (x, v) are pushed through ``step_map`` by central finite
    differences (perturbed starting points are re-projected onto the manifold), and
    max |ω(DΦξ_i, DΦξ_j) − ω(ξ_i, ξ_j)| / max |ω(ξ_i, ξ_j)| is returned.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    step_map : callable
        (x, v) → (x1, v1), the map to check.
    x, v : numpy.ndarray
        A consistent state.
    count : int, default 4
        Number of tangent vectors.
    epsilon : float, default 1e-6
        Finite-difference step.
    seed : int, default 0
        Seed of the tangent vectors.

    Returns
    -------
    float
        The relative defect: at the finite-difference error for a symplectic map.

    Examples
    --------
    α-RATTLE with its midpoint solved is symplectic; one midpoint pass is not:

    >>> from openmm_alphaprk.reference import (
    ...     alpha_rattle_step, planar_pendulum, planar_pendulum_start, symplecticity_defect)
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x, v = planar_pendulum_start(0.5)
    >>> def solved(x, v):
    ...     return alpha_rattle_step(pendulum, x, v, 0.1, 0.2)[:2]
    >>> def one_pass(x, v):
    ...     return alpha_rattle_step(pendulum, x, v, 0.1, 0.2, one_pass=True)[:2]
    >>> symplecticity_defect(pendulum, solved, x, v) < 1e-8 < symplecticity_defect(pendulum, one_pass, x, v)
    True
    """
    n = problem.n_dof
    xis = tangent_vectors(problem, x, v, count, seed)
    images = []
    for xi in xis:
        plus = step_map(*project_to_manifold(problem, x + epsilon * xi[:n], v + epsilon * xi[n:]))
        minus = step_map(*project_to_manifold(problem, x - epsilon * xi[:n], v - epsilon * xi[n:]))
        images.append(np.concatenate([plus[0] - minus[0], plus[1] - minus[1]]) / (2 * epsilon))
    before = np.array([[symplectic_form(problem, a, b) for b in xis] for a in xis])
    after = np.array([[symplectic_form(problem, a, b) for b in images] for a in images])
    return float(np.max(np.abs(after - before)) / np.max(np.abs(before)))
