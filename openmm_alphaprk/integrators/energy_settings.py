"""The energy mode's settings: their defaults by order, and their validation.

Used by :class:`~.energy_mode.AlphaRattleEnergyIntegrator`, which declares them as
global variables of its step program.
"""

from __future__ import annotations

from dataclasses import dataclass

import openmm.unit as unit

from .._units import InputError, InputTypeError, positive_int, to_dimensionless, to_float
from .compositions import TRIPLE_JUMP, Composition

DEFAULT_SLOPE_DAMPING = 0.5
#: Default midpoint tolerance (nm) of the energy mode without a periodic box, where angular
#: momentum is conserved: iterated to this, the midpoint keeps it to round-off.
NON_PERIODIC_MIDPOINT_TOLERANCE = 1e-13


#: Forgetting factor λ of the running AR(2) fits of D0 and S (an effective memory of
#: 1/(1 − λ) = 20 steps).
PREDICTOR_FORGETTING = 0.95
#: Steps with measured D0 and S before the first trial's α comes from the prediction.
PREDICTOR_WARMUP = 20
#: Energy tolerance (kJ/mol) until the first step sets the automatic one.
PROVISIONAL_ENERGY_TOLERANCE = 0.01


@dataclass(frozen=True)
class ControllerSettings:
    """The controller's validated settings.

    ``energy_tolerance`` in kJ/mol, None: automatic (from the platform's precision);
    ``automatic_midpoint_tolerance``: the user did not choose the midpoint tolerance, so
    it may be set for the System (tighter without a periodic box).
    """

    alpha_bounds: tuple[float, float]
    energy_tolerance: float | None
    max_trials: int
    max_alpha_change: float
    alpha_probe: float
    slope_damping: float
    predict: bool = True
    automatic_midpoint_tolerance: bool = True


@dataclass(frozen=True)
class ControllerDefaults:
    """Defaults of the energy mode that depend on the order of the method.

    Order 2: α* is O(1); a wide interval such as (−1, 3) lets the greedy controller
    take large excursions that spoil later steps (the interval comparison is in
    docs/research/energy_mode_first_build.md, "Defaults, and why"). Order 4 (any composition; the values are
    the triple jump's, with α on its middle sub-step, and scale by :func:`alpha_scale_of`
    for another α stage): α* is O(h²), a few 1e-2 for water at 2 fs on the triple
    jump; a large excursion of α turns the step into a poor second-order one, so the
    interval and the moves are small. The midpoint tolerance can be
    looser at order 4 because a midpoint error δ changes angular momentum by
    ≈ 2hα δ × F per step, and α is ~100× smaller. Order 4 allows one more trial:
    after the first, a trial is short (one force evaluation instead of three).
    """

    alpha_bounds: tuple[float, float]
    max_alpha_change: float
    alpha_probe: float
    midpoint_tolerance: float  # nm, RMS per DOF
    max_trials: int


CONTROLLER_DEFAULTS = {
    2: ControllerDefaults(
        alpha_bounds=(-0.5, 1.5),
        max_alpha_change=1.0,
        alpha_probe=0.05,
        midpoint_tolerance=1e-7,
        max_trials=3,
    ),
    4: ControllerDefaults(
        alpha_bounds=(-0.2, 0.2),
        max_alpha_change=0.05,
        alpha_probe=0.005,
        midpoint_tolerance=1e-5,
        max_trials=4,
    ),
}


def controller_settings(
    order: int,
    alpha_bounds: tuple[float, float] | None,
    energy_tolerance: unit.Quantity | float | None,
    max_trials: int | None,
    max_alpha_change: float | None,
    alpha_probe: float | None,
    slope_damping: float,
    automatic_midpoint_tolerance: bool = True,
    alpha_scale: float = 1.0,
) -> ControllerSettings:
    """Validate the energy mode's keyword options; None takes the default for ``order``.

    ``alpha_scale`` multiplies the default α interval, move limit and probe (not a
    value the user gave): a composition whose α stage is shorter than the triple
    jump's gives α less authority, by the cube of the stage's length
    (:func:`alpha_scale_of`).
    """
    defaults = CONTROLLER_DEFAULTS[order]
    alpha_bounds = (
        tuple(alpha_scale * b for b in defaults.alpha_bounds) if alpha_bounds is None else alpha_bounds
    )
    max_alpha_change = (
        alpha_scale * defaults.max_alpha_change if max_alpha_change is None else max_alpha_change
    )
    alpha_probe = alpha_scale * defaults.alpha_probe if alpha_probe is None else alpha_probe
    max_trials = defaults.max_trials if max_trials is None else max_trials
    settings = ControllerSettings(
        check_alpha_bounds(alpha_bounds),
        None
        if energy_tolerance is None
        else to_float(energy_tolerance, unit.kilojoules_per_mole, "energy_tolerance", positive=True),
        positive_int(max_trials, "max_trials"),
        to_dimensionless(max_alpha_change, "max_alpha_change", positive=True),
        to_dimensionless(alpha_probe, "alpha_probe", positive=True),
        to_dimensionless(slope_damping, "slope_damping"),
        predict=order == 4,
        automatic_midpoint_tolerance=automatic_midpoint_tolerance,
    )
    if settings.slope_damping < 0:
        raise InputError(f"slope_damping must be >= 0 (0 turns the damping off), got {slope_damping}.")
    if settings.max_trials < 2:
        raise InputError(
            f"max_trials={max_trials} never moves alpha: only a second trial in a step measures "
            "the slope dH/dalpha that moves it (order 2 starts each step at the last step's "
            "alpha; order 4 predicts it from the slopes of past steps), so alpha would stay at "
            "its start and the energy mode would be the fixed-alpha method at a higher cost. "
            f"Use max_trials >= 2 (default {defaults.max_trials} at order {order})."
        )
    return settings


def alpha_scale_of(composition: Composition) -> float:
    """How much larger α must be on ``composition``'s α stage than on the triple jump's for the same effect.

    α changes a sub-step of c h by O(α (c h)³) (its effect on the energy as well), so
    the order-4 defaults, set on the triple jump's middle stage (c = −1.702), scale by
    (1.702/|c_α|)³: 17.3 for Suzuki's middle stage (c = −0.658).
    """
    longest_alpha_stage = max(abs(composition.coefficients[k - 1]) for k in composition.alpha_stages)
    return (abs(TRIPLE_JUMP.coefficients[1]) / longest_alpha_stage) ** 3


def check_alpha_bounds(bounds: object) -> tuple[float, float]:
    """Validate an α interval ``(low, high)`` with low < high, both finite."""
    try:
        low, high = bounds  # type: ignore[misc]
    except (TypeError, ValueError):
        raise InputTypeError(f"alpha_bounds must be a pair (low, high), got {bounds!r}.") from None
    low = to_dimensionless(low, "alpha_bounds[0]")
    high = to_dimensionless(high, "alpha_bounds[1]")
    if not low < high:
        raise InputError(
            f"alpha_bounds must satisfy low < high, got ({low}, {high}); an empty or inverted "
            "interval leaves the controller nothing to choose. The defaults are "
            f"{CONTROLLER_DEFAULTS[2].alpha_bounds} (order 2) and "
            f"{CONTROLLER_DEFAULTS[4].alpha_bounds} (order 4)."
        )
    return low, high
