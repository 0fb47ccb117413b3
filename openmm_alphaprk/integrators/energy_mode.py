"""The energy-preserving mode's settings, their defaults, and what it reports.

The controller's step programs are in :mod:`~.controller`; :class:`EnergyModeProgram`
adds to them what a user sets and reads: E_ref, H − E_ref, the tolerance, the α bounds
and the totals of the run.
"""

from __future__ import annotations

from dataclasses import dataclass

import openmm.unit as unit

from .. import platforms
from .._units import InputError, InputTypeError, to_dimensionless, to_float
from ..observables import positive_int
from .controller import (
    FELL_BACK,
    REFERENCE_ENERGY,
    RESIDUAL,
    TRIALS,
    ControllerSettings,
    EnergyControllerProgram,
)

DEFAULT_MAX_TRIALS = 3
DEFAULT_SLOPE_DAMPING = 0.5
#: Default midpoint tolerance (nm) of the energy mode without a periodic box, where angular
#: momentum is conserved: iterated to this, the midpoint keeps it to round-off.
NON_PERIODIC_MIDPOINT_TOLERANCE = 1e-13


@dataclass(frozen=True)
class ControllerDefaults:
    """Defaults of the energy mode that depend on the order of the method.

    Order 2: α* is O(1); a wide interval such as (−1, 3) lets the greedy controller
    take large excursions that spoil later steps (the interval comparison is in
    docs/energy_mode.md, "Defaults, and why"). Order 4 (the
    triple jump with α on the middle sub-step): α* is O(h²), a few 1e-2 for
    water at 2 fs; a large excursion of α turns the step into a poor second-order
    one, so the interval and the moves are small. The midpoint tolerance can be
    looser at order 4 because a midpoint error δ changes angular momentum by
    ≈ 2hα δ × F per step, and α is ~100× smaller.
    """

    alpha_bounds: tuple[float, float]
    max_alpha_change: float
    alpha_probe: float
    midpoint_tolerance: float  # nm, RMS per DOF


CONTROLLER_DEFAULTS = {
    2: ControllerDefaults(
        alpha_bounds=(-0.5, 1.5), max_alpha_change=1.0, alpha_probe=0.05, midpoint_tolerance=1e-7
    ),
    4: ControllerDefaults(
        alpha_bounds=(-0.2, 0.2), max_alpha_change=0.05, alpha_probe=0.005, midpoint_tolerance=1e-6
    ),
}


def controller_settings(
    order: int,
    alpha_bounds: tuple[float, float] | None,
    energy_tolerance: unit.Quantity | float | None,
    max_trials: int,
    max_alpha_change: float | None,
    alpha_probe: float | None,
    slope_damping: float,
) -> ControllerSettings:
    """Validate the energy mode's keyword options; None takes the default for ``order``."""
    defaults = CONTROLLER_DEFAULTS[order]
    alpha_bounds = defaults.alpha_bounds if alpha_bounds is None else alpha_bounds
    max_alpha_change = defaults.max_alpha_change if max_alpha_change is None else max_alpha_change
    alpha_probe = defaults.alpha_probe if alpha_probe is None else alpha_probe
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
    )
    if settings.slope_damping < 0:
        raise InputError(f"slope_damping must be >= 0 (0 turns the damping off), got {slope_damping}.")
    return settings


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


class EnergyModeProgram(EnergyControllerProgram):
    """The α* controller with what the user sets and reads of it (energy mode only)."""

    def _set_automatic_energy_tolerance(self, n_atoms: int, precision: str) -> None:
        """Set the default energy tolerance for the system and platform, unless the user chose one."""
        if self.getGlobalVariableByName("energy_tolerance_automatic"):
            tolerance = platforms.default_energy_tolerance(n_atoms, precision)
            self.setGlobalVariableByName("energy_tolerance", tolerance)

    def _set_system_defaults(self, periodic: bool) -> None:
        """Set the midpoint tolerance for the system's box, unless the user chose one.

        With a periodic box angular momentum is not conserved by any integrator and the
        order's default stands. Without one (a cluster or molecule in vacuum) the
        midpoint is iterated to :data:`NON_PERIODIC_MIDPOINT_TOLERANCE`, which keeps
        angular momentum to round-off, at more midpoint forces per step.
        """
        if not periodic and self.getGlobalVariableByName("midpoint_tolerance_automatic"):
            self.setGlobalVariableByName("midpoint_tolerance", NON_PERIODIC_MIDPOINT_TOLERANCE)

    def reset_reference_energy(self) -> None:
        """Take E_ref from the state at the start of the next step.

        The integrator also notices by itself when positions or velocities were set
        between steps; call this to be explicit, e.g. after changing parameters of a
        force (which changes the energy without changing the state).
        """
        self._require_energy_mode("reset_reference_energy()")
        self.setGlobalVariableByName("reference_set", 0)

    @property
    def reference_energy(self) -> unit.Quantity:
        """E_ref, the total energy the energy mode holds (NaN before the first step)."""
        self._require_energy_mode("reference_energy")
        if not self.getGlobalVariableByName("reference_set") and not self.steps_taken:
            return float("nan") * unit.kilojoules_per_mole
        return self.getGlobalVariableByName(REFERENCE_ENERGY) * unit.kilojoules_per_mole

    @property
    def energy_residual(self) -> unit.Quantity:
        """H − E_ref after the last step (total energy with on-step velocities)."""
        self._require_energy_mode("energy_residual")
        return self.getGlobalVariableByName(RESIDUAL) * unit.kilojoules_per_mole

    @property
    def energy_tolerance(self) -> unit.Quantity:
        """The controller's target |H − E_ref| per step."""
        self._require_energy_mode("energy_tolerance")
        return self.getGlobalVariableByName("energy_tolerance") * unit.kilojoules_per_mole

    @energy_tolerance.setter
    def energy_tolerance(self, value: unit.Quantity | float) -> None:
        self._require_energy_mode("energy_tolerance")
        tolerance = to_float(value, unit.kilojoules_per_mole, "energy_tolerance", positive=True)
        self.setGlobalVariableByName("energy_tolerance", tolerance)
        self.setGlobalVariableByName("energy_tolerance_automatic", 0)

    @property
    def alpha_bounds(self) -> tuple[float, float]:
        """The interval α* is kept in."""
        self._require_energy_mode("alpha_bounds")
        return (self.getGlobalVariableByName("alpha_min"), self.getGlobalVariableByName("alpha_max"))

    @alpha_bounds.setter
    def alpha_bounds(self, bounds: tuple[float, float]) -> None:
        self._require_energy_mode("alpha_bounds")
        low, high = check_alpha_bounds(bounds)
        self.setGlobalVariableByName("alpha_min", low)
        self.setGlobalVariableByName("alpha_max", high)

    @property
    def fell_back(self) -> bool:
        """Whether the last step ended outside the energy tolerance (α at a bound or trial cap)."""
        self._require_energy_mode("fell_back")
        return bool(self.getGlobalVariableByName(FELL_BACK))

    @property
    def trials(self) -> int:
        """Trials of α in the last step (two force evaluations each)."""
        self._require_energy_mode("trials")
        return int(self.getGlobalVariableByName(TRIALS))

    def controller_totals(self) -> dict[str, float]:
        """Totals over every step since the integrator was created.

        Returns
        -------
        A dict with ``steps``, ``steps_within_tolerance``, ``steps_fallen_back``,
        ``steps_at_bound``, ``reference_resets`` (counts), the fractions
        ``fraction_within_tolerance`` and ``fraction_fallen_back``,
        ``force_evaluations_per_step``, and ``rms_residual`` and ``max_abs_residual``:
        RMS and maximum of H − E_ref after each step (kJ/mol; NaN before the first step),
        accumulated inside the step program, so that a reporter need not read the state
        every step.
        """
        self._require_energy_mode("controller_totals()")
        steps = self.steps_taken
        totals = {
            name: int(self.getGlobalVariableByName(name))
            for name in ("steps_within_tolerance", "steps_fallen_back", "steps_at_bound", "reference_resets")
        }
        fraction = (lambda n: n / steps) if steps else (lambda n: float("nan"))
        squares = self.getGlobalVariableByName("sum_residual_squared")
        return {
            "steps": steps,
            **totals,
            "fraction_within_tolerance": fraction(totals["steps_within_tolerance"]),
            "fraction_fallen_back": fraction(totals["steps_fallen_back"]),
            "force_evaluations_per_step": self.force_evaluations_per_step,
            "rms_residual": fraction(squares) ** 0.5 if steps else float("nan"),
            "max_abs_residual": self.getGlobalVariableByName("max_abs_residual") if steps else float("nan"),
        }

    @property
    def energy_mode(self) -> bool:
        """True if α is chosen each step to hold the energy (``alpha="energy"``)."""
        names = {self.getGlobalVariableName(i) for i in range(self.getNumGlobalVariables())}
        return REFERENCE_ENERGY in names

    def _require_energy_mode(self, what: str) -> None:
        if not self.energy_mode:
            raise AttributeError(
                f"{what} exists only in the energy-preserving mode; create the integrator with "
                "AlphaRattleIntegrator(timestep, alpha='energy')."
            )
