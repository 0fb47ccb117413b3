"""The integrators of the validation study and how they are run and measured on the NumPy reference.

A :class:`Method` is a fixed α or an energy mode (α* per step), at order 2
(α-RATTLE) or 4 (α-RATTLE-4); :func:`run_method` takes its steps on a
:class:`~openmm_alphaprk.reference.step.ConstrainedProblem`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from openmm_alphaprk.reference import alpha_rattle4_step, alpha_rattle_step, energy_preserving_step
from openmm_alphaprk.reference.step import Array, ConstrainedProblem

#: α of the fixed-α study.
ALPHAS = (0.0, 1 / 6, 1 / 3, 1 / 2, 1.0)
#: Bounds of the reference energy mode's exact (Brent) root search, design doc §4.
REFERENCE_BOUNDS = (-1.0, 3.0)
#: The reference's default midpoint tolerance (1e-15) can be below what the fixed-point
#: iteration reaches when SHAKE converges to 1e-14 (seen at α = 3 on the pendulum); the
#: energy modes' trials use this one.
ENERGY_MIDPOINT_TOLERANCE = 1e-14
#: Symplecticity defects below this are the finite-difference floor of the test (ε = 1e-6 and the
#: solver tolerances, accumulated over the steps); slopes are fitted above it.
FD_FLOOR = 1e-7


@dataclass(frozen=True)
class Method:
    """One integrator of the study: a fixed α, or an energy mode (α* per step).

    Parameters
    ----------
    key
        Name in the JSON (``alpha=1/6``, ``energy``, ``alpha4=0``, ``energy4``, ...).
    label
        Name in tables and figures.
    order
        2 (α-RATTLE) or 4 (α-RATTLE-4).
    alpha
        The fixed α, or None for the energy mode.
    one_pass
        Take the midpoint force at the RATTLE-predicted midpoint only (not symplectic).
    """

    key: str
    label: str
    order: int
    alpha: float | None
    one_pass: bool = False

    @property
    def step(self) -> Callable[..., tuple[Array, Array, Array]]:
        """Return the reference step of this order."""
        return alpha_rattle_step if self.order == 2 else alpha_rattle4_step

    @property
    def energy_mode(self) -> bool:
        """Tell whether α is chosen per step (the energy mode)."""
        return self.alpha is None


def _fraction(alpha: float) -> str:
    return str(Fraction(alpha).limit_denominator(12))


def fixed(alpha: float, order: int = 2, one_pass: bool = False) -> Method:
    """Return a fixed-α method (``alpha=1/6``, ``alpha4=0.3``, ``one-pass alpha=1``)."""
    text = _fraction(alpha)
    key = f"alpha{'4' if order == 4 else ''}={text}"
    if order == 2:
        label = "RATTLE (α = 0)" if alpha == 0 else f"α = {text}"
    else:
        label = f"α-RATTLE-4, α = {text}"
    if one_pass:
        key, label = f"one-pass {key}", f"{label}, one pass"
    return Method(key, label, order, alpha, one_pass)


ENERGY = Method("energy", "energy mode (order 2)", 2, None)
ENERGY4 = Method("energy4", "energy mode, α-RATTLE-4", 4, None)
CONVERGENCE_METHODS = (*(fixed(a) for a in ALPHAS), ENERGY, fixed(0.0, 4), fixed(0.3, 4), ENERGY4)


def run_method(
    method: Method, problem: ConstrainedProblem, x0: Array, v0: Array, h: float, n_steps: int
) -> tuple[Array, Array, Array | None, Array]:
    """Take ``n_steps`` steps of ``method``.

    Returns
    -------
    x, v
        The final state.
    alphas
        α* of every step (energy modes), else None.
    energies
        H after every step, shape (n_steps,).
    """
    x, v = np.array(x0, dtype=float), np.array(v0, dtype=float)
    e_ref = problem.energy(x, v)
    f = problem.force(x)
    alphas = np.empty(n_steps) if method.energy_mode else None
    energies = np.empty(n_steps)
    for i in range(n_steps):
        if method.energy_mode:
            x, v, f, alphas[i] = energy_preserving_step(
                method.step,
                problem,
                x,
                v,
                h,
                e_ref,
                f0=f,
                bounds=REFERENCE_BOUNDS,
                midpoint_tolerance=ENERGY_MIDPOINT_TOLERANCE,
            )
        else:
            x, v, f = method.step(problem, x, v, h, method.alpha, f0=f, one_pass=method.one_pass)
        energies[i] = problem.energy(x, v)
    return x, v, alphas, energies


def local_orders(errors: Array) -> list[float]:
    """Return log2 of the error ratio per halving of h (h listed from large to small)."""
    errors = np.asarray(errors)
    return [float(v) for v in np.log2(errors[:-1] / errors[1:])]


def alpha_statistics(alphas: Array) -> dict:
    """Return max, median and 90th percentile of |α*|, and the fraction of steps at a bound of the search."""
    magnitude = np.abs(alphas)
    at_bound = np.isclose(alphas, REFERENCE_BOUNDS[0]) | np.isclose(alphas, REFERENCE_BOUNDS[1])
    return {
        "max_abs": float(magnitude.max()),
        "median_abs": float(np.median(magnitude)),
        "p90_abs": float(np.percentile(magnitude, 90)),
        "fraction_at_bound": float(np.mean(at_bound)),
    }
