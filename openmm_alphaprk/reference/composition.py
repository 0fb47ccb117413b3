"""Compositions of α-RATTLE steps and energy-preserving steps in NumPy.

Φ_h^α = Ψ_{c_s h} ∘ … ∘ Ψ_{c_1 h} with the composition's coefficients
(:mod:`openmm_alphaprk.integrators.compositions`), α on the stages it marks and RATTLE
(α = 0) on the others: of the composition's order at α = 0, order 2 at a fixed α ≠ 0;
with α* chosen per step to hold the energy the composition's order again. α-RATTLE-4 is
the triple jump, Ψ^0_{γ1 h} ∘ Ψ^α_{γ2 h} ∘ Ψ^0_{γ1 h}.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from ..integrators.compositions import TRIPLE_JUMP, Composition
from ..integrators.compositions import composition as named_composition
from .step import Array, ConstrainedProblem, alpha_rattle_step

Step = Callable[..., tuple[Array, Array, Array]]

GAMMA1, GAMMA2 = TRIPLE_JUMP.coefficients[:2]


def composition_step(
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    alpha: float,
    *,
    composition: str | Composition = TRIPLE_JUMP,
    f0: Array | None = None,
    **step_options,
) -> tuple[Array, Array, Array]:
    """One step of a composition: stage i an α-RATTLE step of c_i h, α on the marked stages.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : numpy.ndarray
        A consistent state.
    h : float
        Step size.
    alpha : float
        α on the stages the composition marks.
    composition : str or Composition, default TRIPLE_JUMP
        A name of :data:`~openmm_alphaprk.integrators.compositions.COMPOSITIONS` or a
        :class:`~openmm_alphaprk.integrators.compositions.Composition`.
    f0 : numpy.ndarray, optional
        F(x0) if already known.
    **step_options
        Passed on to :func:`~.step.alpha_rattle_step`.

    Returns
    -------
    x1, v1, f1 : numpy.ndarray
        The new state and the force at x1.

    Examples
    --------
    Suzuki's five stages of RATTLE, fourth order: one step of 0.1 against ten of 0.01:

    >>> from openmm_alphaprk.reference import (
    ...     composition_step, integrate, planar_pendulum, planar_pendulum_start)
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> x1, v1, f1 = composition_step(pendulum, x0, v0, 0.1, 0.0, composition="suzuki5")
    >>> x10, v10 = integrate(pendulum, x0, v0, 0.01, 10, step=composition_step, composition="suzuki5")
    >>> bool(abs(x1 - x10).max() < 1e-8)
    True
    """
    chosen = named_composition(composition)
    x, v, f = x0, v0, f0
    for i, c in enumerate(chosen.coefficients, start=1):
        a = alpha if i in chosen.alpha_stages else 0.0
        x, v, f = alpha_rattle_step(problem, x, v, c * h, a, f0=f, **step_options)
    return x, v, f


def alpha_rattle4_step(
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    alpha: float,
    *,
    f0: Array | None = None,
    **step_options,
) -> tuple[Array, Array, Array]:
    """One α-RATTLE-4 step: RATTLE (γ1 h), α-RATTLE (γ2 h), RATTLE (γ1 h) — the triple jump.

    Parameters
    ----------
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : numpy.ndarray
        A consistent state.
    h : float
        Step size.
    alpha : float
        α of the middle stage.
    f0 : numpy.ndarray, optional
        F(x0) if already known.
    **step_options
        Passed on to :func:`~.step.alpha_rattle_step`.

    Returns
    -------
    x1, v1, f1 : numpy.ndarray
        The new state and the force at x1.

    Examples
    --------
    >>> from openmm_alphaprk.reference import (
    ...     GAMMA1, GAMMA2, alpha_rattle4_step, planar_pendulum, planar_pendulum_start)
    >>> round(2 * GAMMA1 + GAMMA2, 12), round(GAMMA1, 6), round(GAMMA2, 6)  # the sub-steps
    (1.0, 1.351207, -1.702414)
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x1, v1, f1 = alpha_rattle4_step(pendulum, *planar_pendulum_start(0.5), 0.1, 0.05)
    >>> round(float(x1 @ x1), 12)
    1.0
    """
    return composition_step(problem, x0, v0, h, alpha, composition=TRIPLE_JUMP, f0=f0, **step_options)


def energy_preserving_step(
    step: Step,
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    e_ref: float,
    *,
    bounds: tuple[float, float] = (-1.0, 3.0),
    f0: Array | None = None,
    **step_options,
) -> tuple[Array, Array, Array, float]:
    """Take a step of ``step`` (α-RATTLE or α-RATTLE-4) with α* such that H(x1, v1) = e_ref.

    The root is bracketed by scanning outwards from α = 0 inside ``bounds`` and found
    with Brent's method to round-off; without a root inside the bounds the bound with
    the smaller |H − e_ref| is taken (the fallback).

    Parameters
    ----------
    step : callable
        The step with α: :func:`~.step.alpha_rattle_step`, :func:`alpha_rattle4_step` or
        :func:`composition_step`.
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : numpy.ndarray
        A consistent state.
    h : float
        Step size.
    e_ref : float
        The energy to hold.
    bounds : tuple of (float, float), default (-1.0, 3.0)
        Where α* is looked for.
    f0 : numpy.ndarray, optional
        F(x0) if already known.
    **step_options
        Passed on to ``step``.

    Returns
    -------
    x1, v1, f1 : numpy.ndarray
        The new state and the force at x1.
    alpha : float
        α* of the step.

    Examples
    --------
    >>> from openmm_alphaprk.reference import (
    ...     alpha_rattle_step, energy_preserving_step, planar_pendulum, planar_pendulum_start)
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> e_ref = pendulum.energy(x0, v0)
    >>> x1, v1, f1, alpha = energy_preserving_step(alpha_rattle_step, pendulum, x0, v0, 0.1, e_ref)
    >>> round(alpha, 4), abs(pendulum.energy(x1, v1) - e_ref) < 1e-14
    (0.9222, True)
    """
    f0 = problem.force(x0) if f0 is None else f0

    def trial(alpha: float):
        return step(problem, x0, v0, h, alpha, f0=f0, **step_options)

    def residual(alpha: float) -> float:
        x1, v1, _ = trial(alpha)
        return problem.energy(x1, v1) - e_ref

    low, high = bounds
    r0 = residual(0.0)
    if r0 == 0.0:
        return (*trial(0.0), 0.0)
    grid = sorted(
        {float(a) for a in np.concatenate([np.geomspace(1e-8, 1, 17) * s for s in (low, high) if s != 0])},
        key=abs,
    )
    previous = {1.0: (0.0, r0), -1.0: (0.0, r0)}
    for alpha in grid:
        side = 1.0 if alpha > 0 else -1.0
        r = residual(alpha)
        a_prev, r_prev = previous[side]
        if np.sign(r) != np.sign(r_prev):
            root = brentq(residual, min(a_prev, alpha), max(a_prev, alpha), xtol=1e-15, rtol=1e-15)
            return (*trial(root), root)
        previous[side] = (alpha, r)
    best = min((low, high), key=lambda a: abs(residual(a)))
    return (*trial(best), best)


def integrate_energy_preserving(
    step: Step,
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    h: float,
    n_steps: int,
    **options,
) -> tuple[Array, Array, Array]:
    """``n_steps`` energy-preserving steps holding H at its starting value.

    Parameters
    ----------
    step : callable
        The step with α (see :func:`energy_preserving_step`).
    problem : ConstrainedProblem
        The constrained system.
    x0, v0 : array_like
        A consistent start; its energy is held.
    h : float
        Step size.
    n_steps : int
        Number of steps.
    **options
        Passed on to :func:`energy_preserving_step` (``bounds``, step options).

    Returns
    -------
    x, v : numpy.ndarray
        The final state.
    alphas : numpy.ndarray
        α* of every step.

    Examples
    --------
    The triple jump with α* on its middle stage: α* = O(h²), H held to round-off:

    >>> from openmm_alphaprk.reference import (
    ...     alpha_rattle4_step, integrate_energy_preserving, planar_pendulum, planar_pendulum_start)
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> x0, v0 = planar_pendulum_start(0.5)
    >>> x, v, alphas = integrate_energy_preserving(alpha_rattle4_step, pendulum, x0, v0, 0.1, 20)
    >>> abs(pendulum.energy(x, v) - pendulum.energy(x0, v0)) < 1e-14, bool(abs(alphas).max() < 0.01)
    (True, True)
    """
    x, v = np.array(x0, dtype=float), np.array(v0, dtype=float)
    e_ref = problem.energy(x, v)
    f = problem.force(x)
    alphas = np.empty(n_steps)
    for i in range(n_steps):
        x, v, f, alphas[i] = energy_preserving_step(step, problem, x, v, h, e_ref, f0=f, **options)
    return x, v, alphas
