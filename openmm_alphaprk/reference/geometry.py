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
    """ω(a, b) = a_qᵀ M b_v − a_vᵀ M b_q for a = (a_q, a_v), b = (b_q, b_v)."""
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
