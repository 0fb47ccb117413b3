"""The energy-preserving mode of α-RATTLE: the step program pieces of the α* controller.

Each step chooses α so that the total energy after the step equals the reference
energy E_ref, the energy of the state the run started from (design doc §4). The
controller runs entirely inside the ``CustomIntegrator`` step program, in one
``while`` block; each pass of it is one *trial*:

1. α ← the proposal of the previous pass (the first pass: the last step's α*);
2. predict x1 with the current midpoint force (a constraint solve, no force);
3. evaluate the force at the predicted midpoint x_m = (x0 + x1)/2;
4. re-solve x1 with that force (its change is the midpoint inconsistency);
5. evaluate force and energy at x1, set v1 (RATTLE projection) and the residual
   r = U(x1) + K(v1) − E_ref;
6. propose the next α by a damped secant step, Δα = −r S/(S² + (d S̄)²), with S =
   dr/dα measured inside this step, S̄ a running mean of |S| over past steps and
   d = ``slope_damping``: where the slope nearly vanishes no bounded α can help, and
   throwing α far would spoil the steps after it. The first pass has no slope yet; it
   uses the last step's and moves α by at least ``alpha_probe`` so that the second
   pass measures one (at a bound, where that move would leave the interval, it
   probes inwards). Every move is limited to ``max_alpha_change`` and clipped to the
   α bounds.

This is the second-order step. At order 4 (α-RATTLE-4) the first RATTLE sub-step is
taken once, and a trial redoes the middle α-RATTLE sub-step (steps 2–4 with h
scaled by γ2) and the last RATTLE sub-step: three force evaluations per trial.

α stops moving when the energy is within tolerance, when α sits at a bound and the
root lies beyond it (the *fallback*: the best α inside the bounds), or after
``max_trials`` passes (also a fallback). The loop ends once α stops moving and the
midpoint force is consistent with x1 to ``midpoint_tolerance``; passes after α froze
only refine the midpoint. ``max_midpoint_iterations`` caps all passes. E_ref is
never moved by the controller, so a residual left by a fallback is corrected by
later steps and cannot accumulate into drift. A non-finite residual or a midpoint
iteration that ran away rejects the step (the context keeps the state at its start;
``step`` raises).

E_ref is taken from the state at the first step, and again whenever the state at
the start of a step differs from the state the previous step ended in (the user set
positions or velocities), or after :meth:`reset_reference_energy`.
"""

from __future__ import annotations

from dataclasses import dataclass

import openmm.unit as unit

from ._units import to_dimensionless, to_float

DEFAULT_ENERGY_TOLERANCE = 0.01  # kJ/mol, absolute, on H − E_ref after the step
DEFAULT_MAX_TRIALS = 3
DEFAULT_SLOPE_DAMPING = 0.5


@dataclass(frozen=True)
class ControllerDefaults:
    """Defaults of the energy mode that depend on the order of the method.

    Order 2: α* is O(1) (design doc §4). The doc's interval (−1, 3) lets the greedy
    controller take large excursions that spoil later steps; over three 400-step
    runs (2.2 nm smooth TIP3P box, CPU) RMS(H − E_ref) relative to RATTLE was
    0.82/0.88/0.85 with (−1, 3), 0.25/0.50/0.37 with (−0.5, 1.5), 0.42/0.58/0.54 with
    (0, 1) and 0.57/0.86/0.76 with (−0.25, 0.75). Order 4 (the
    triple jump with α on the middle sub-step): α* is O(h²) (§8), a few 1e-2 for
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

#: Relative change of the positions/velocity checksums that counts as "the user
#: changed the state between steps" (sums of identical data agree far better).
_STATE_CHANGE_THRESHOLD = 1e-9


class _EnergyModeProgram:
    """Mixin of :class:`~openmm_alphaprk.AlphaRattleIntegrator`: the α* controller.

    Relies on the pieces of ``_ConstrainedVerletBase`` (``_add_begin_step`` …) and
    on the fixed-α pieces of the integrator (``_FIRST_FORCES``, ``_LAST_FORCES``,
    ``_add_save_start_force``, ``_add_reject_unconverged_step``).
    """

    def _add_energy_mode_variables(
        self,
        alpha_bounds: tuple[float, float],
        energy_tolerance: float,
        max_trials: int,
        max_alpha_change: float,
        alpha_probe: float,
        slope_damping: float,
    ) -> None:
        low, high = alpha_bounds
        for name, value in (
            ("alpha_min", low),
            ("alpha_max", high),
            ("energy_tolerance", energy_tolerance),
            ("max_trials", max_trials),
            ("max_alpha_change", max_alpha_change),
            ("alpha_probe", alpha_probe),
            ("reference_energy", 0),
            ("reference_set", 0),
            ("reference_resets", 0),
            ("kinetic_energy", 0),
            ("residual", 0),
            ("residual_last", 0),
            ("alpha_last", 0),
            ("alpha_next", 0),
            ("alpha_start", 0),
            ("slope", 0),
            ("slope_scale", 0),
            ("slope_damping", slope_damping),
            ("slope_measured", 0),
            ("trials", 0),
            ("controller_done", 0),
            ("fell_back", 0),
            ("alpha_at_bound", 0),
            ("steps_within_tolerance", 0),
            ("steps_fallen_back", 0),
            ("steps_at_bound", 0),
            ("predictor_valid", 0),
            ("position_checksum", 0),
            ("velocity_checksum", 0),
            ("end_position_checksum", 0),
            ("end_velocity_checksum", 0),
            ("state_changed", 0),
        ):
            self.addGlobalVariable(name, value)
        self.addPerDofVariable("fmid_last", 0)

    def _build_energy_program(self) -> None:
        self._add_begin_step()
        self._add_detect_state_change()
        self._add_reference_energy()
        self._add_save_start_force()
        self._add_midpoint_predictor()
        self._add_controller_loop()
        self._add_reject_unconverged_step()
        self.addComputePerDof("v", "select(midpoint_failed, v0, v)")
        self._add_controller_bookkeeping()
        self._add_end_step()

    # ------------------------------------------------------------------ pieces
    def _add_detect_state_change(self) -> None:
        """Flag a start state that differs from the end of the previous step."""
        self.addComputeSum("position_checksum", "x*x")
        self.addComputeSum("velocity_checksum", "m*v*v")
        self.addComputeGlobal(
            "state_changed",
            f"1 - step({_STATE_CHANGE_THRESHOLD}*(position_checksum + velocity_checksum + 1e-300)"
            " - abs(position_checksum - end_position_checksum)"
            " - abs(velocity_checksum - end_velocity_checksum))",
        )
        self.addComputeGlobal("reference_set", "reference_set*(1 - state_changed)")

    def _add_reference_energy(self) -> None:
        """E_ref = U(x0) + K(v0) on the first step and after a change of state."""
        self.beginIfBlock("reference_set < 0.5")
        self.addComputeGlobal("reference_energy", "energy + 0.5*velocity_checksum")
        self.addComputeGlobal("reference_set", "1")
        self.addComputeGlobal("reference_resets", "reference_resets + 1")
        self.addComputeGlobal("predictor_valid", "0")
        self.addComputeGlobal("slope", "0")
        self.endBlock()

    def _add_midpoint_predictor(self) -> None:
        """Start the midpoint force at F(x_m) ≈ 2 F(x0) − F(previous x_m) (else F(x0)).

        Linear extrapolation in time from the previous step's midpoint force; only
        the number of trials depends on it, not the converged step.
        """
        self.addComputePerDof("fmid", "select(predictor_valid, 2*fstart - fmid_last, fstart)")
        self._add_controller_start()

    def _add_controller_start(self) -> None:
        """Reset the per-step controller state; the first trial uses the last step's α*."""
        self.addComputeGlobal("alpha_start", "alpha")
        self.addComputeGlobal("alpha_next", "min(max(alpha, alpha_min), alpha_max)")
        self.addComputeGlobal("trials", "0")
        self.addComputeGlobal("slope_measured", "0")
        self.addComputeGlobal("controller_done", "0")
        self.addComputeSum("ndof", "1")

    def _add_controller_loop(self) -> None:
        """Trials of α with the midpoint force iterated along (see the module docstring)."""
        self.beginWhileBlock("controller_done < 0.5")
        self.addComputeGlobal("alpha", "alpha_next")
        self._add_midpoint_trial()
        self._add_velocity_update(self._LAST_FORCES)
        self._add_trial_residual()
        self._add_alpha_update()
        self.endBlock()

    def _build_order4_energy_program(self) -> None:
        """α-RATTLE-4 in the energy mode: only the middle and last sub-steps depend on α.

        The first RATTLE sub-step (γ1 h) is taken once; each trial of α redoes the
        middle α-RATTLE sub-step (γ2 h; midpoint force warm-started from the previous
        trial) and the last RATTLE sub-step: three force evaluations per trial.
        """
        self._add_begin_step()
        self._add_save_step_start()
        self._add_detect_state_change()
        self._add_reference_energy()
        self._add_rattle_substep(self._OUTER_H)
        self.addComputePerDof("xa", "x")
        self.addComputePerDof("va", "v")
        self.addComputePerDof("fstart", "f")
        # the midpoint force's offset from the sub-step's start force changes little between steps
        self.addComputePerDof("fmid", "fstart + select(predictor_valid, fmid_last - fstart_last, 0)")
        self.addComputePerDof("fstart_last", "fstart")
        self._add_controller_start()
        self.beginWhileBlock("controller_done < 0.5")
        self.addComputeGlobal("alpha", "alpha_next")
        self.addComputePerDof("x", "xa")
        self.addComputePerDof("v", "va")
        self._add_substep_start()
        self._add_midpoint_trial(self._MIDDLE_H)
        self._add_velocity_update(self._LAST_FORCES, self._MIDDLE_H)
        self._add_rattle_substep(self._OUTER_H)
        self._add_trial_residual()
        self._add_alpha_update()
        self.endBlock()
        self._add_reject_unconverged_step()
        self._add_restore_step_start_if_failed()
        self._add_controller_bookkeeping()
        self._add_end_step()

    def _add_midpoint_trial(self, h: str = "dt") -> None:
        """x1 predicted with the current midpoint force, the force at its midpoint, x1 again.

        Leaves x = x1 consistent with the new midpoint force, and ``midpoint_change``
        = RMS change of x1 (twice the distance between the midpoint the force was
        taken at and the final midpoint). One force evaluation.
        """
        self._add_reset_constraint_reference()
        self._add_position_solve(self._FIRST_FORCES, h)
        self.addComputePerDof("x1", "x")
        self._add_midpoint_pass(h)

    def _add_trial_residual(self) -> None:
        """Set the residual U(x) + K(v) − E_ref of the state the trial ended in."""
        self.addComputeSum("kinetic_energy", "0.5*m*v*v")
        self.addComputeGlobal("residual", "energy + kinetic_energy - reference_energy")
        self.addComputeGlobal("trials", "trials + 1")
        self.addComputeGlobal("midpoint_iterations", "trials")

    def _add_alpha_update(self) -> None:
        """Secant step on r(α) with the in-step slope; bounded; decide whether to stop.

        Written with ``select``/``step`` so that no division by a vanishing slope
        can reach α: the Newton step is −r S/(S² + ε), then limited and clipped.
        """
        self.addComputeGlobal(
            "slope",
            "select(new_secant, (residual - residual_last)/(alpha - alpha_last), slope);"
            "new_secant = step(trials - 1.5)*step(abs(alpha - alpha_last) - 1e-12)",
        )
        self.addComputeGlobal(
            "slope_measured",
            "max(slope_measured, step(trials - 1.5)*step(abs(alpha - alpha_last) - 1e-12))",
        )
        self.addComputeGlobal("residual_last", "residual")
        self.addComputeGlobal("alpha_last", "alpha")
        self.addComputeGlobal(
            "alpha_next",
            "select(frozen, alpha, min(max(moved, alpha_min), alpha_max));"
            "frozen = max(step(energy_tolerance - abs(residual)), step(trials - max_trials + 0.5));"
            "moved = select(slope_measured + 1 - delta(clipped - alpha), clipped, inwards);"
            "inwards = alpha - outward*alpha_probe;"
            "outward = 2*step(change) - 1;"
            "clipped = min(max(alpha + change, alpha_min), alpha_max);"
            "change = select(slope_measured, limited, select(limited, probe_sized, alpha_probe));"
            "probe_sized = (2*step(limited) - 1)*max(abs(limited), alpha_probe);"
            "limited = min(max(newton, -max_alpha_change), max_alpha_change);"
            "newton = -residual*slope/(slope*slope + (slope_damping*slope_scale)^2 + 1e-30)",
        )
        self.addComputeGlobal(
            "controller_done",
            "max(max(stays*step(midpoint_tolerance - midpoint_change), capped), not_finite);"
            "not_finite = 1 - step(1e30 - abs(residual));"
            "capped = step(trials - max_midpoint_iterations + 0.5);"
            "stays = 1 - step(abs(alpha_next - alpha) - 1e-12)",
        )

    def _add_controller_bookkeeping(self) -> None:
        """Per-step diagnostics and totals; remember what the next step starts from."""
        self.addComputeGlobal("alpha", "select(midpoint_failed, alpha_start, alpha)")
        self.addComputeGlobal(
            "fell_back", "(1 - midpoint_failed)*(1 - step(energy_tolerance - abs(residual)))"
        )
        self.addComputeGlobal(
            "alpha_at_bound", "(1 - midpoint_failed)*max(delta(alpha - alpha_min), delta(alpha - alpha_max))"
        )
        self.addComputeGlobal(
            "steps_within_tolerance", "steps_within_tolerance + (1 - midpoint_failed - fell_back)"
        )
        self.addComputeGlobal("steps_fallen_back", "steps_fallen_back + fell_back")
        self.addComputeGlobal("steps_at_bound", "steps_at_bound + alpha_at_bound")
        self.addComputeGlobal(
            "slope_scale",
            "select(slope_measured, select(slope_scale, running, abs(slope)), slope_scale);"
            "running = 0.9*slope_scale + 0.1*abs(slope)",
        )
        self.addComputePerDof("fmid_last", "fmid")
        self.addComputeGlobal("predictor_valid", "1 - midpoint_failed")
        self.addComputeSum("end_position_checksum", "x*x")
        self.addComputeSum("end_velocity_checksum", "m*v*v")

    # --------------------------------------------------------------- reporting
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
        if not self.getGlobalVariableByName("reference_set") and not self.getGlobalVariableByName(
            "steps_taken"
        ):
            return float("nan") * unit.kilojoules_per_mole
        return self.getGlobalVariableByName("reference_energy") * unit.kilojoules_per_mole

    @property
    def energy_residual(self) -> unit.Quantity:
        """H − E_ref after the last step (total energy with on-step velocities)."""
        self._require_energy_mode("energy_residual")
        return self.getGlobalVariableByName("residual") * unit.kilojoules_per_mole

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
        return bool(self.getGlobalVariableByName("fell_back"))

    @property
    def trials(self) -> int:
        """Trials of α in the last step (two force evaluations each)."""
        self._require_energy_mode("trials")
        return int(self.getGlobalVariableByName("trials"))

    def controller_totals(self) -> dict[str, float]:
        """Totals since the integrator was created: steps, within tolerance, fallbacks, at bound.

        Returns
        -------
        A dict with ``steps``, ``steps_within_tolerance``, ``steps_fallen_back``,
        ``steps_at_bound``, ``reference_resets`` (counts), the fractions
        ``fraction_within_tolerance`` and ``fraction_fallen_back``, and
        ``force_evaluations_per_step``.
        """
        self._require_energy_mode("controller_totals()")
        steps = self.steps_taken
        totals = {
            name: int(self.getGlobalVariableByName(name))
            for name in ("steps_within_tolerance", "steps_fallen_back", "steps_at_bound", "reference_resets")
        }
        fraction = (lambda n: n / steps) if steps else (lambda n: float("nan"))
        return {
            "steps": steps,
            **totals,
            "fraction_within_tolerance": fraction(totals["steps_within_tolerance"]),
            "fraction_fallen_back": fraction(totals["steps_fallen_back"]),
            "force_evaluations_per_step": self.force_evaluations_per_step,
        }

    @property
    def energy_mode(self) -> bool:
        """True if α is chosen each step to hold the energy (``alpha="energy"``)."""
        names = {self.getGlobalVariableName(i) for i in range(self.getNumGlobalVariables())}
        return "reference_energy" in names

    def _require_energy_mode(self, what: str) -> None:
        if not self.energy_mode:
            raise AttributeError(
                f"{what} exists only in the energy-preserving mode; create the integrator with "
                "AlphaRattleIntegrator(timestep, alpha='energy')."
            )


def check_alpha_bounds(bounds: object) -> tuple[float, float]:
    """Validate an α interval ``(low, high)`` with low < high, both finite."""
    try:
        low, high = bounds  # type: ignore[misc]
    except (TypeError, ValueError):
        raise TypeError(f"alpha_bounds must be a pair (low, high), got {bounds!r}.") from None
    low = to_dimensionless(low, "alpha_bounds[0]")
    high = to_dimensionless(high, "alpha_bounds[1]")
    if not low < high:
        raise ValueError(
            f"alpha_bounds must satisfy low < high, got ({low}, {high}); an empty or inverted "
            "interval leaves the controller nothing to choose. The defaults are "
            f"{CONTROLLER_DEFAULTS[2].alpha_bounds} (order 2) and "
            f"{CONTROLLER_DEFAULTS[4].alpha_bounds} (order 4)."
        )
    return low, high
