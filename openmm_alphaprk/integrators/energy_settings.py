"""The energy mode's controller settings: the public :class:`ControllerSettings`, the defaults by order.

:class:`~.energy_mode.AlphaRattleEnergyIntegrator` takes its controller's options as one
:class:`ControllerSettings` (``controller=``); a field left None takes the default of the
order (:data:`CONTROLLER_DEFAULTS`), resolved by :func:`controller_settings` into the
values the step program declares as its globals.
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
    """The options of the energy mode's controller; a field left None takes the order's default.

    Given to :class:`~.energy_mode.AlphaRattleEnergyIntegrator` as ``controller=``. Each
    field is checked when the settings are made (numbers as plain floats, an energy in
    kJ/mol); the defaults depend on the order (:data:`CONTROLLER_DEFAULTS`, one α-RATTLE
    step or a composition) and are filled in by the integrator.

    Parameters
    ----------
    alpha_bounds : tuple of (float, float), optional
        The interval (low, high) α* is kept in; default (−0.5, 1.5) at order 2; on a
        composition (−0.2, 0.2) × s, s = (1.702/|c_α|)³ the α stage's authority against
        the triple jump's middle stage (:func:`alpha_scale_of`: 1 for the triple jump,
        17.3 for Suzuki's five stages).
    energy_tolerance : openmm.unit.Quantity or float, optional
        Target |H − E_ref| after each step (kJ/mol). Default: 3× the noise of OpenMM's
        energy for the system's size and the platform's precision
        (:func:`openmm_alphaprk.platforms.default_energy_tolerance`), set by
        ``check_context``; without it each ``step()`` call sets the single-precision
        value. A target inside the noise only buys trials that chase round-off.
    max_trials : int, optional
        Trials per step that may change α (at least 2: only a second trial measures the
        slope dH/dα). Default 3 at order 2, 4 on a composition.
    max_alpha_change : float, optional
        The largest change of α one secant update may make (default 1 at order 2,
        0.05 × s on a composition).
    alpha_probe : float, optional
        The smallest first move of α in a step, so that the step measures its own slope
        dH/dα (default 0.05 at order 2, 0.005 × s on a composition).
    slope_damping : float, optional
        d in the damped secant step Δα = −r S/(S² + (d S̄)²), S̄ a running mean of the
        measured slopes |S| (default 0.5; 0 turns the damping off).

    Raises
    ------
    InputError
        For a value out of its range (an empty interval, ``max_trials=1``, a probe ≤ 0 …).

    Examples
    --------
    >>> import openmm.unit as unit
    >>> from openmm_alphaprk import AlphaRattleEnergyIntegrator, ControllerSettings
    >>> tolerance = 0.02 * unit.kilojoule_per_mole
    >>> settings = ControllerSettings(alpha_bounds=(-0.1, 0.1), energy_tolerance=tolerance)
    >>> settings.energy_tolerance  # kJ/mol
    0.02
    >>> integrator = AlphaRattleEnergyIntegrator(0.002, order=4, controller=settings)
    >>> print(integrator.alpha_bounds, integrator.energy_tolerance)
    (-0.1, 0.1) 0.02 kJ/mol
    >>> ControllerSettings(max_trials=1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.InputError: max_trials=1 never moves alpha: ...
    """

    alpha_bounds: tuple[float, float] | None = None
    energy_tolerance: unit.Quantity | float | None = None
    max_trials: int | None = None
    max_alpha_change: float | None = None
    alpha_probe: float | None = None
    slope_damping: float | None = None

    def __post_init__(self) -> None:
        checks = {
            "alpha_bounds": check_alpha_bounds,
            "energy_tolerance": lambda value: to_float(
                value, unit.kilojoules_per_mole, "energy_tolerance", positive=True
            ),
            "max_trials": _check_max_trials,
            "max_alpha_change": lambda value: to_dimensionless(value, "max_alpha_change", positive=True),
            "alpha_probe": lambda value: to_dimensionless(value, "alpha_probe", positive=True),
            "slope_damping": _check_slope_damping,
        }
        for name, check in checks.items():
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, check(value))


@dataclass(frozen=True)
class _Controller:
    """The controller's resolved settings, the order's defaults filled in: the program's globals.

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
    for another α stage): α* is O(h²), far below order 2's; a large excursion of α
    turns the step into a poor second-order one, so the interval and the moves are small.
    The midpoint tolerance can be looser at order 4 because a midpoint error δ changes
    angular momentum by ≈ 2hα δ × F per step, and α is far smaller. Order 4 allows one more trial:
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
    settings: ControllerSettings | None,
    automatic_midpoint_tolerance: bool = True,
    alpha_scale: float = 1.0,
) -> _Controller:
    """Fill the fields of ``settings`` left None (all, for None) with the defaults for ``order``.

    ``alpha_scale`` multiplies the default α interval, move limit and probe (not a
    value the user gave): a composition whose α stage is shorter than the triple
    jump's gives α less authority, by the cube of the stage's length
    (:func:`alpha_scale_of`).
    """
    given = ControllerSettings() if settings is None else settings
    if not isinstance(given, ControllerSettings):
        raise InputTypeError(
            f"controller must be a ControllerSettings (from openmm_alphaprk import ControllerSettings), "
            f"got {given!r}."
        )
    defaults = CONTROLLER_DEFAULTS[order]

    def default(value: object, fallback: object) -> object:
        return fallback if value is None else value

    return _Controller(
        alpha_bounds=default(given.alpha_bounds, tuple(alpha_scale * b for b in defaults.alpha_bounds)),
        energy_tolerance=given.energy_tolerance,
        max_trials=default(given.max_trials, defaults.max_trials),
        max_alpha_change=default(given.max_alpha_change, alpha_scale * defaults.max_alpha_change),
        alpha_probe=default(given.alpha_probe, alpha_scale * defaults.alpha_probe),
        slope_damping=default(given.slope_damping, DEFAULT_SLOPE_DAMPING),
        predict=order == 4,
        automatic_midpoint_tolerance=automatic_midpoint_tolerance,
    )


def _check_max_trials(value: object) -> int:
    trials = positive_int(value, "max_trials")
    if trials < 2:
        raise InputError(
            f"max_trials={value} never moves alpha: only a second trial in a step measures "
            "the slope dH/dalpha that moves it (order 2 starts each step at the last step's "
            "alpha; order 4 predicts it from the slopes of past steps), so alpha would stay at "
            "its start and the energy mode would be the fixed-alpha method at a higher cost. "
            f"Use max_trials >= 2 (default {CONTROLLER_DEFAULTS[2].max_trials} at order 2, "
            f"{CONTROLLER_DEFAULTS[4].max_trials} on a composition)."
        )
    return trials


def _check_slope_damping(value: object) -> float:
    damping = to_dimensionless(value, "slope_damping")
    if damping < 0:
        raise InputError(f"slope_damping must be >= 0 (0 turns the damping off), got {value}.")
    return damping


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
