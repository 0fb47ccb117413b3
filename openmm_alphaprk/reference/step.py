"""The α-RATTLE step in NumPy, for small constrained systems given by callables.

This is the reference the OpenMM integrator and the theory are tested against
(Li & Wang, J. Comput. Math. 41, 2023). All arrays are flat, of length n = number of degrees of freedom;
the units are whatever the problem uses (OpenMM units for molecular problems).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._units import InputError

Array = np.ndarray


@dataclass(frozen=True)
class ConstrainedProblem:
    """A Hamiltonian system with holonomic constraints.

    H = ½ vᵀ M v + U(q), g(q) = 0, with G = ∂g/∂q.

    Parameters
    ----------
    masses : numpy.ndarray
        Mass of each degree of freedom, shape (n,).
    potential : callable
        U(q) → float.
    force : callable
        F(q) = −∇U(q) → shape (n,).
    constraints : callable, optional
        g(q) → shape (k,); ``None`` for an unconstrained system.
    constraint_jacobian : callable, optional
        G(q) → shape (k, n).
    name : str, default "problem"
        A label.
    metadata : dict, optional
        Anything the problem's maker keeps with it (the molecular problems keep their
        model here, for :func:`~.problems.to_openmm_system`).

    Examples
    --------
    A particle on the unit circle under gravity (:func:`~.problems.planar_pendulum`
    with κ = 0), written out:

    >>> import numpy as np
    >>> from openmm_alphaprk.reference import ConstrainedProblem
    >>> pendulum = ConstrainedProblem(
    ...     masses=np.ones(2),
    ...     potential=lambda q: q[1],
    ...     force=lambda q: np.array([0.0, -1.0]),
    ...     constraints=lambda q: np.array([q @ q - 1.0]),
    ...     constraint_jacobian=lambda q: 2.0 * q[None, :],
    ...     name="pendulum",
    ... )
    >>> x, v = np.array([1.0, 0.0]), np.array([0.0, 0.5])
    >>> pendulum.n_dof, pendulum.g(x), pendulum.G(x) @ v  # a consistent state
    (2, array([0.]), array([0.]))
    >>> pendulum.energy(x, v)  # ½ vᵀMv + U
    0.125
    """

    masses: Array
    potential: Callable[[Array], float]
    force: Callable[[Array], Array]
    constraints: Callable[[Array], Array] | None = None
    constraint_jacobian: Callable[[Array], Array] | None = None
    name: str = "problem"
    metadata: dict = field(default_factory=dict)

    @property
    def n_dof(self) -> int:
        return int(np.size(self.masses))

    @property
    def inverse_masses(self) -> Array:
        return 1.0 / np.asarray(self.masses, dtype=float)

    def g(self, q: Array) -> Array:
        return np.zeros(0) if self.constraints is None else np.atleast_1d(self.constraints(q))

    def G(self, q: Array) -> Array:
        if self.constraint_jacobian is None:
            return np.zeros((0, self.n_dof))
        return np.atleast_2d(self.constraint_jacobian(q))

    def energy(self, q: Array, v: Array) -> float:
        """Total energy H = ½ vᵀMv + U(q)."""
        return 0.5 * float(np.sum(self.masses * v * v)) + float(self.potential(q))


def solve_positions(
    problem: ConstrainedProblem, x_ref: Array, x_free: Array, tol: float = 1e-14, max_iter: int = 100
) -> Array:
    """SHAKE: x = x_free − M⁻¹ G(x_ref)ᵀ λ with g(x) = 0, by Newton's method on λ.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x_ref : numpy.ndarray
        Positions whose constraint gradients G(x_ref) give the directions of the correction.
    x_free : numpy.ndarray
        The unconstrained positions.
    tol : float, default 1e-14
        Stop when max |g(x)| is below this.
    max_iter : int, default 100
        Cap on Newton iterations.

    Returns
    -------
    numpy.ndarray
        The constrained positions.

    Raises
    ------
    RuntimeError
        If Newton's method does not converge in ``max_iter`` iterations.

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> from openmm_alphaprk.reference import solve_positions
    >>> x = solve_positions(pendulum, x0, x0 + [0.01, 0.02])  # a free move, back onto |q| = 1
    >>> round(float(x @ x), 12)
    1.0
    """
    G_ref = problem.G(x_ref)
    if G_ref.shape[0] == 0:
        return x_free.copy()
    direction = problem.inverse_masses[:, None] * G_ref.T  # (n, k)
    lam = np.zeros(G_ref.shape[0])
    x = x_free.copy()
    for _ in range(max_iter):
        residual = problem.g(x)
        if np.max(np.abs(residual)) < tol:
            return x
        jac = -problem.G(x) @ direction
        lam -= np.linalg.solve(jac, residual)
        x = x_free - direction @ lam
    raise RuntimeError(
        f"SHAKE did not converge in {max_iter} iterations (|g| = {np.max(np.abs(residual)):.3g})."
    )


def project_velocities(problem: ConstrainedProblem, x: Array, v_free: Array) -> Array:
    """RATTLE: v = v_free − M⁻¹ G(x)ᵀ μ with G(x) v = 0.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x : numpy.ndarray
        Positions (on the constraint manifold).
    v_free : numpy.ndarray
        The unconstrained velocities.

    Returns
    -------
    numpy.ndarray
        The velocities tangent to the constraints.

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> from openmm_alphaprk.reference import project_velocities
    >>> v = project_velocities(pendulum, x0, [1.0, 0.0])
    >>> bool(abs(v @ x0) < 1e-12)  # no component along the rod
    True
    """
    G = problem.G(x)
    if G.shape[0] == 0:
        return v_free.copy()
    minv_Gt = problem.inverse_masses[:, None] * G.T
    mu = np.linalg.solve(G @ minv_Gt, G @ v_free)
    return v_free - minv_Gt @ mu


@dataclass
class StepInfo:
    """Diagnostics of one reference step.

    Parameters
    ----------
    midpoint_iterations : int, default 0
        Iterations of the midpoint solve.
    force_evaluations : int, default 0
        Force evaluations of the step (F(x0) not counted when it was passed in).
    midpoint_change : float, default 0.0
        The last iteration's max-norm change of x1.

    Examples
    --------
    Filled by :func:`alpha_rattle_step`:

    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> from openmm_alphaprk.reference import StepInfo, alpha_rattle_step
    >>> info = StepInfo()
    >>> _ = alpha_rattle_step(pendulum, x0, v0, 0.1, 0.2, info=info)
    >>> info.midpoint_iterations > 1, info.force_evaluations == info.midpoint_iterations + 1  # + F(x1)
    (True, True)
    >>> info.midpoint_change <= 1e-15  # the default midpoint_tolerance
    True
    """

    midpoint_iterations: int = 0
    force_evaluations: int = 0
    midpoint_change: float = 0.0


def alpha_rattle_step(
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    alpha: float,
    *,
    f0: Array | None = None,
    midpoint_tolerance: float = 1e-15,
    max_midpoint_iterations: int = 100,
    one_pass: bool = False,
    midpoint_solver: str = "fixed-point",
    info: StepInfo | None = None,
) -> tuple[Array, Array, Array]:
    """One α-RATTLE step.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : numpy.ndarray
        A consistent state (g(x0) = 0, G(x0) v0 = 0).
    h : float
        Step size (may be negative, as in composition methods).
    alpha : float
        The method parameter.
    f0 : numpy.ndarray, optional
        F(x0) if already known.
    midpoint_tolerance : float, default 1e-15
        Stop the midpoint iteration when the max-norm change of x1 is below this.
    max_midpoint_iterations : int, default 100
        Cap on midpoint iterations (an error is raised if it is reached).
    one_pass : bool, default False
        Take the midpoint force at the RATTLE-predicted midpoint only (the
        deliberately non-symplectic variant the tests must catch).
    midpoint_solver : {"fixed-point", "newton"}, default "fixed-point"
        ``"fixed-point"`` (what the OpenMM integrator does; converges while
        |α| h²ω²/4 < 1) or ``"newton"`` (finite-difference Jacobian; for small
        systems, e.g. to study the exact map's stability where fixed-point
        iteration diverges).
    info : StepInfo, optional
        Filled with diagnostics if given.

    Returns
    -------
    x1, v1, f1 : numpy.ndarray
        The new state and the force at x1.

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> from openmm_alphaprk.reference import alpha_rattle_step
    >>> x1, v1, f1 = alpha_rattle_step(pendulum, x0, v0, 0.1, 0.2)
    >>> round(float(x1 @ x1), 12), bool(abs(x1 @ v1) < 1e-12)  # on the manifold: |q| = 1, q·v = 0
    (1.0, True)
    >>> bool((f1 == pendulum.force(x1)).all())
    True
    """
    info = info if info is not None else StepInfo()
    minv = problem.inverse_masses
    f0 = problem.force(x0) if f0 is None else f0
    base = x0 + h * v0

    def positions(f_mid: Array) -> Array:
        return solve_positions(problem, x0, base + h * h * minv * ((0.5 - alpha) * f0 + alpha * f_mid))

    f_mid = f0
    x1 = positions(f_mid)
    if alpha != 0.0 and midpoint_solver == "newton":
        x1, f_mid = _newton_midpoint(
            problem, x0, x1, positions, midpoint_tolerance, max_midpoint_iterations, info
        )
    elif alpha != 0.0:
        if midpoint_solver != "fixed-point":
            raise InputError(f"midpoint_solver must be 'fixed-point' or 'newton', got {midpoint_solver!r}.")
        x1, f_mid = _fixed_point_midpoint(
            problem, x0, x1, positions, midpoint_tolerance, max_midpoint_iterations, one_pass, info
        )
    f1 = problem.force(x1)
    info.force_evaluations += 1
    v1 = project_velocities(problem, x1, (x1 - x0) / h + h * minv * (alpha * f_mid + (0.5 - alpha) * f1))
    return x1, v1, f1


def _fixed_point_midpoint(problem, x0, x1, positions, tol, max_iter, one_pass, info):
    """Iterate x1 = positions(F((x0 + x1)/2)) until x1 moves by at most ``tol`` (max-norm)."""
    for iteration in range(1, max_iter + 1):
        f_mid = problem.force(0.5 * (x0 + x1))
        info.force_evaluations += 1
        x1_new = positions(f_mid)
        change = float(np.max(np.abs(x1_new - x1)))
        x1 = x1_new
        info.midpoint_iterations = iteration
        info.midpoint_change = change
        if one_pass or change <= tol:
            return x1, f_mid
    raise RuntimeError(
        f"midpoint iteration did not converge in {max_iter} iterations "
        f"(last change {change:.3g}); reduce h or |alpha|."
    )


def _newton_midpoint(problem, x0, x1, positions, tol, max_iter, info):
    """Solve x1 = positions(F((x0 + x1)/2)) by Newton's method with a finite-difference Jacobian."""

    def residual(x):
        return x - positions(problem.force(0.5 * (x0 + x)))

    n = x1.size
    for iteration in range(1, max_iter + 1):
        r = residual(x1)
        scale = 1e-7 * max(1.0, float(np.max(np.abs(x1))))
        jac = np.empty((n, n))
        for k in range(n):
            e = np.zeros(n)
            e[k] = scale
            jac[:, k] = (residual(x1 + e) - residual(x1 - e)) / (2 * scale)
        info.force_evaluations += 2 * n + 1
        step = np.linalg.lstsq(jac, r, rcond=None)[0]
        x1 = positions(problem.force(0.5 * (x0 + (x1 - step))))
        info.midpoint_iterations = iteration
        info.midpoint_change = float(np.max(np.abs(step)))
        if info.midpoint_change <= tol or info.midpoint_change <= 1e-12 * max(1.0, float(np.max(np.abs(x1)))):
            f_mid = problem.force(0.5 * (x0 + x1))
            return positions(f_mid), f_mid
    raise RuntimeError(f"Newton midpoint solve did not converge in {max_iter} iterations.")


def integrate(
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    n_steps: int,
    alpha: float = 0.0,
    *,
    record: bool = False,
    step: Callable[..., tuple[Array, Array, Array]] | None = None,
    **step_options,
) -> tuple[Array, Array] | tuple[Array, Array, Array, Array]:
    """Take ``n_steps`` α-RATTLE steps; with ``record`` also return the trajectory.

    ``step`` replaces :func:`alpha_rattle_step` (e.g. by the fourth-order
    ``alpha_rattle4_step``). Returns (x, v) at the end, or (x, v, xs, vs) with xs,
    vs of shape (n_steps+1, n).

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : array_like
        A consistent start.
    h : float
        Step size.
    n_steps : int
        Number of steps.
    alpha : float, default 0.0
        The method parameter (0: RATTLE).
    record : bool, default False
        Also return every state.
    step : callable, optional
        The one-step map, called as ``step(problem, x, v, h, alpha, f0=f, **step_options)``;
        default :func:`alpha_rattle_step`.
    **step_options
        Passed on to ``step`` (``midpoint_tolerance``, ``composition``, …).

    Returns
    -------
    x, v : numpy.ndarray
        The final state.
    xs, vs : numpy.ndarray
        With ``record``: every state, shape (n_steps + 1, n).

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> from openmm_alphaprk.reference import integrate
    >>> x, v = integrate(pendulum, x0, v0, 0.05, 100, alpha=0.1)
    >>> round(float(x @ x), 12)
    1.0
    >>> bool(abs(pendulum.energy(x, v) - pendulum.energy(x0, v0)) < 1e-4)  # symplectic: bounded error
    True
    >>> x, v, xs, vs = integrate(pendulum, x0, v0, 0.05, 10, record=True)
    >>> xs.shape, vs.shape
    ((11, 2), (11, 2))
    """
    step = alpha_rattle_step if step is None else step
    x, v = np.array(x0, dtype=float), np.array(v0, dtype=float)
    f = problem.force(x)
    xs, vs = [x], [v]
    for _ in range(n_steps):
        x, v, f = step(problem, x, v, h, alpha, f0=f, **step_options)
        if record:
            xs.append(x)
            vs.append(v)
    if record:
        return x, v, np.array(xs), np.array(vs)
    return x, v


def project_to_manifold(problem: ConstrainedProblem, x: Array, v: Array) -> tuple[Array, Array]:
    """Nearest consistent state: positions onto g = 0 (along G(x)ᵀ), then velocities.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x, v : numpy.ndarray
        A state near the constraint manifold.

    Returns
    -------
    x, v : numpy.ndarray
        The consistent state: g(x) = 0, G(x) v = 0.

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> from openmm_alphaprk.reference import project_to_manifold
    >>> x, v = project_to_manifold(pendulum, 1.1 * x0, [1.0, 0.0])
    >>> round(float(x @ x), 12), bool(abs(x @ v) < 1e-12)
    (1.0, True)
    """
    x = solve_positions(problem, x, x)
    return x, project_velocities(problem, x, v)
