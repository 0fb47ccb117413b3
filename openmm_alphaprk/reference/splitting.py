"""Kick-drift splittings with constraints in NumPy: the explicit α-family's reference step.

One step is the splitting's constrained sub-steps
(:meth:`~openmm_alphaprk.integrators.splittings.Splitting.substeps`), each a SHAKE position
solve along G at the sub-step's start and a RATTLE velocity projection: the map the OpenMM
program (:class:`~openmm_alphaprk.SplittingRattleIntegrator`) takes.
"""

from __future__ import annotations

from ..integrators.splittings import Splitting, two_stage
from ..integrators.splittings import splitting as named_splitting
from .step import Array, ConstrainedProblem, project_velocities, solve_positions


def splitting_step(
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    alpha: float = 0.25,
    *,
    splitting: str | Splitting | None = None,
    f0: Array | None = None,
) -> tuple[Array, Array, Array]:
    """One step of a splitting: the two-stage member with ``alpha``, or a named ``splitting``.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : numpy.ndarray
        A consistent state.
    h : float
        Step size.
    alpha : float, default 0.25
        α of the two-stage member (kicks ½−α, 2α, ½−α); ignored with ``splitting``.
    splitting : str or Splitting, optional
        A name of :data:`~openmm_alphaprk.integrators.splittings.SPLITTINGS` or a
        :class:`~openmm_alphaprk.integrators.splittings.Splitting`.
    f0 : numpy.ndarray, optional
        F(x0) if already known.

    Returns
    -------
    x1, v1, f1 : numpy.ndarray
        The new state and the force at x1.

    Examples
    --------
    α = ¼ is two RATTLE steps of h/2:

    >>> import numpy as np
    >>> from openmm_alphaprk.reference import (
    ...     alpha_rattle_step, planar_pendulum, planar_pendulum_start, splitting_step)
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> x1, v1, _ = splitting_step(pendulum, x0, v0, 0.1, 0.25)
    >>> xa, va, fa = alpha_rattle_step(pendulum, x0, v0, 0.05, 0.0)
    >>> xb, vb, _ = alpha_rattle_step(pendulum, xa, va, 0.05, 0.0, f0=fa)
    >>> bool(np.allclose(x1, xb, atol=1e-14) and np.allclose(v1, vb, atol=1e-14))
    True
    """
    chosen = two_stage(alpha) if splitting is None else named_splitting(splitting)
    minv = problem.inverse_masses
    x, v = x0, v0
    f = problem.force(x0) if f0 is None else f0
    for c, before, after in chosen.substeps():
        step = c * h
        x_start = x
        x = solve_positions(problem, x_start, x_start + step * v + step * step * before * minv * f)
        f = problem.force(x)
        v = project_velocities(problem, x, (x - x_start) / step + step * after * minv * f)
    return x, v, f
