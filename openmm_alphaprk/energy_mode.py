"""The energy-preserving mode of α-RATTLE: the step program pieces of the α* controller.

Each step chooses α so that the total energy after the step equals the reference
energy E_ref, the energy of the state the run started from (design doc §4). The
controller runs entirely inside the ``CustomIntegrator`` step program, in one
``while`` loop; each *trial* of an α is:

1. the position solve with the current midpoint force (at the first trial of a
   step a predictor: the force extrapolated from the previous step);
2. the force at the midpoint x_m = (x0 + x1)/2 and the solve again: one midpoint
   force per trial, so the midpoint converges along with α (the loop ends once α
   stops moving and the last midpoint force changed x1 by less than
   ``midpoint_tolerance``; trials after α froze only refine the midpoint);
3. the force and energy at x1, v1 (RATTLE projection), the residual
   r = U(x1) + K(v1) − E_ref;
4. the next α by a damped secant step, Δα = −r S/(S² + (d S̄)²), with S = dr/dα
   measured inside this step, S̄ a running geometric mean of |S| over past steps and
   d = ``slope_damping``: where the slope nearly vanishes no bounded α can help, and
   throwing α far would spoil the steps after it. The first trial has no slope yet;
   it uses the last step's and moves α by at least ``alpha_probe`` so that the
   second trial measures one (at a bound, where that move would leave the interval,
   it probes inwards). Every move is limited to ``max_alpha_change`` (at order 4 a
   limit that halves when α swings back and forth, see ``_add_trust_update``) and clipped to
   the α bounds. A new trial first solves x1 again with the new α and the last
   midpoint force, then goes on with step 2.

At order 4 (α-RATTLE-4) the first RATTLE sub-step is taken once, and a trial redoes
the middle α-RATTLE sub-step (steps 1–2 with h scaled by γ2) and the last RATTLE
sub-step: three force evaluations per trial.

α stops moving when the energy is within tolerance, when α sits at a bound and the
root lies beyond it (the *fallback*: the best α inside the bounds), or after
``max_trials`` trials (also a fallback); ``max_midpoint_iterations`` caps the midpoint
forces of a step. E_ref is never moved by the controller, so a residual left by a
fallback is corrected by later steps and cannot accumulate into drift. A non-finite
residual or a midpoint iteration that ran away rejects the step (the context keeps
the state at its start; ``step`` raises).

E_ref is taken from the state at the first step, after :meth:`reset_reference_energy`,
and when the user changed the state between steps: the positions or velocities at the
start of a step differ from those the previous step ended with *and* the total energy
differs from the one it ended with by more than max(tolerance, 1e-6 |E|). The energy
test is what tells a user's change from the common platform's reordering and
re-wrapping of atoms every 250 steps, which moves coordinates but not the energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import openmm.unit as unit

from . import platforms
from ._units import to_dimensionless, to_float
from .step_program import MIDDLE_H, _StepProgram, first_forces, last_forces

#: Energy tolerance (kJ/mol) until the first step sets the automatic one.
PROVISIONAL_ENERGY_TOLERANCE = 0.01
#: Relative energy change between steps below which a moved state counts as the same
#: state (the common platform's reordering), unless the energy tolerance is larger.
_SAME_ENERGY = 1e-6
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


class _EnergyModeProgram(_StepProgram):
    """The α* controller's variables, step programs and reporting.

    Base of :class:`~openmm_alphaprk.AlphaRattleIntegrator`; built from the pieces
    of :class:`~openmm_alphaprk.step_program._StepProgram`.
    """

    def _add_energy_mode_variables(
        self,
        alpha_bounds: tuple[float, float],
        energy_tolerance: float | None,
        max_trials: int,
        max_alpha_change: float,
        alpha_probe: float,
        slope_damping: float,
        order: int,
    ) -> None:
        low, high = alpha_bounds
        automatic = energy_tolerance is None
        for name, value in (
            ("alpha_min", low),
            ("alpha_max", high),
            ("energy_tolerance", PROVISIONAL_ENERGY_TOLERANCE if automatic else energy_tolerance),
            ("energy_tolerance_automatic", float(automatic)),
            ("max_trials", max_trials),
            ("max_alpha_change", max_alpha_change),
            ("alpha_probe", alpha_probe),
            ("slope_damping", slope_damping),
            ("trust", max_alpha_change),  # the move limit; adapted at order 4 only
        ):
            self.addGlobalVariable(name, value)
        for name in (
            "reference_energy",
            "reference_set",
            "reference_resets",
            "state_moved",
            "start_energy",
            "end_energy",
            "retake",
            "retry",
            "kinetic_energy",
            "residual",
            "residual_last",
            "alpha_last",
            "alpha_next",
            "alpha_start",
            "slope",
            "slope_scale",
            "slope_measured",
            "trials",
            "last_move",
            "controller_done",
            "restarting",
            "fell_back",
            "alpha_at_bound",
            "steps_within_tolerance",
            "steps_fallen_back",
            "steps_at_bound",
            "predictor_valid",
        ):
            self.addGlobalVariable(name, 0)
        for name in ("xend", "vend", "fmid_last") + (("xa", "va", "fa", "fstart_last") if order == 4 else ()):
            self.addPerDofVariable(name, 0)

    def _set_automatic_energy_tolerance(self, n_atoms: int, precision: str) -> None:
        """Set the default energy tolerance for the system and platform, unless the user chose one."""
        if self.getGlobalVariableByName("energy_tolerance_automatic"):
            tolerance = platforms.default_energy_tolerance(n_atoms, precision)
            self.setGlobalVariableByName("energy_tolerance", tolerance)

    # ---------------------------------------------------------------- programs
    def _build_energy_program(self) -> None:
        """Order 2: one loop over trials; a trial ends with its velocity update and residual."""
        self._add_save_step_start(fstart="f")
        self._add_reference_check()
        # F(x_m) predicted by linear extrapolation in time from the previous step's midpoint force
        self.addComputePerDof("fmid", "select(predictor_valid, 2*fstart - fmid_last, fstart)")
        self._add_midpoint_setup("1")
        self._add_controller_start()
        self.addComputeGlobal("solving", "1")
        self.beginWhileBlock("solving > 0.5")
        self._add_position_solve(first_forces("alpha"), "dt", fallback="x0")
        self.beginIfBlock("need_midpoint < 0.5")
        self._add_velocity_update(last_forces("alpha"), "dt", fallback="v0")
        self._add_trial_end(next_start={})
        self.addComputeGlobal("solving", "restarting")
        self.endBlock()
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_midpoint_force("dt", "alpha", iterate=False)
        self.endBlock()
        self.endBlock()
        self._add_controller_bookkeeping()
        self._add_end_step()

    def _build_order4_energy_program(self) -> None:
        """α-RATTLE-4: the first RATTLE sub-step once, then a loop over trials of the other two.

        A trial redoes the middle α-RATTLE sub-step (γ2 h; midpoint force
        warm-started from the previous trial) and the last RATTLE sub-step: three
        force evaluations per trial.
        """
        # F(x0) is read before the reference check's energy: see _add_reference_check
        self._add_save_step_start(xstep="x", vstep="v", fstart="f")
        self._add_reference_check()
        self._add_first_outer_substep()
        self._add_controller_start()
        # the midpoint force's offset from the sub-step's start force changes little between steps
        self._add_inner_substeps_start(
            "1",
            xa="x",
            va="v",
            fa="f",
            fmid="f + select(predictor_valid, fmid_last - fstart_last, 0)",
            fstart_last="f",
        )
        self.beginWhileBlock("phase < 3.5")
        self._add_substep_solve(fallback="xstep")
        self.beginIfBlock("substep_done > 0.5")
        self._add_substep_end(fallback="vstep")
        self.endBlock()
        self.beginIfBlock("phase > 3.5")
        self._add_trial_end(next_start={"x0": "xa", "v0": "va", "fstart": "fa"})
        self.addComputeGlobal("phase", "select(restarting, 2, phase)")
        self.addComputeGlobal("hsub", f"select(restarting, {MIDDLE_H}, hsub)")
        self.addComputeGlobal("alpha_sub", "alpha*restarting")
        self.endBlock()
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_midpoint_force("hsub", "alpha_sub", iterate=False)
        self.endBlock()
        self.endBlock()
        self._add_controller_bookkeeping()
        self._add_trust_update()
        self._add_end_step()

    # ------------------------------------------------------------------ pieces
    def _add_reference_check(self) -> None:
        """Take E_ref at the first step, after a reset, and after the user changed the state.

        A start state that differs from the end of the previous step (a sum over
        degrees of freedom, zero when nothing moved) opens the block; inside it the
        energy decides: the common platform's reordering and re-wrapping of atoms move
        coordinates but keep the energy.

        The force at x0 must have been read (copied) before this block: with the
        energy read here as a step's first evaluation and ``f`` read after it, the
        forces were wrong on CUDA and NVIDIA's OpenCL (measured on an H100: +32
        kJ/mol in one step; not seen with pocl or Reference).
        """
        self._add_sum("state_moved", "(x - xend)^2 + (v - vend)^2")
        self.beginIfBlock("state_moved + 1 - reference_set > 0")
        self._add_sum("kinetic_energy", "0.5*m*v*v")
        self.addComputeGlobal("start_energy", "energy + kinetic_energy")
        self.addComputeGlobal(
            "retake",
            "max(1 - reference_set, step(abs(start_energy - end_energy) - same));"
            f"same = max(energy_tolerance, {_SAME_ENERGY}*abs(end_energy))",
        )
        self.addComputeGlobal("reference_energy", "select(retake, start_energy, reference_energy)")
        self.addComputeGlobal("reference_resets", "reference_resets + retake")
        self.addComputeGlobal("predictor_valid", "predictor_valid*(1 - retake)")
        self.addComputeGlobal("slope", "select(retake, 0, slope)")
        self.addComputeGlobal("reference_set", "1")
        self.endBlock()

    def _add_controller_start(self) -> None:
        """Reset the per-step controller state; the first trial uses the last step's α*."""
        self.addComputeGlobal("alpha_start", "alpha")
        self.addComputeGlobal("alpha", "min(max(alpha, alpha_min), alpha_max)")
        for name in ("trials", "slope_measured", "controller_done", "restarting"):
            self.addComputeGlobal(name, "0")

    def _add_trial_end(self, next_start: dict[str, str]) -> None:
        """Residual of the trial, the next α, and either the end of the step or a new trial.

        A new trial restarts the α sub-step from ``next_start`` (the state after the
        first sub-step at order 4) and goes straight to its midpoint block, which
        solves x1 with the new α before taking the midpoint force.
        """
        self._add_sum("kinetic_energy", "0.5*m*v*v")
        self.addComputeGlobal("residual", "energy + kinetic_energy - reference_energy")
        self.addComputeGlobal("trials", "trials + 1")
        self._add_alpha_update()
        # a midpoint that ran away: one more pass without a midpoint force falls back to the start
        self.addComputeGlobal(
            "retry",
            "controller_done*(1 - midpoint_failed)*(1 - step(accepted - midpoint_change));"
            "accepted = max(1000*midpoint_tolerance, 1e-8)",
        )
        self.addComputeGlobal("midpoint_failed", "max(midpoint_failed, retry)")
        self.addComputeGlobal("restarting", "1 - controller_done + retry")
        self.addComputeGlobal("alpha", "select(restarting, alpha_next, alpha)")
        self.addComputeGlobal("need_midpoint", "restarting")
        self.addComputeGlobal("previous_midpoint_change", "1e30")
        self.addComputeGlobal("end_energy", "residual + reference_energy")
        self.addComputePerDof("xend", "x")
        self.addComputePerDof("vend", "v")
        self.addComputePerDof("fmid_last", "fmid")
        for variable, expression in next_start.items():
            self.addComputePerDof(variable, f"select(restarting, {expression}, {variable})")

    def _add_alpha_update(self) -> None:
        """Secant step on r(α) with the in-step slope; bounded; decide whether to stop.

        Written with ``select``/``step`` so that no division by a vanishing slope
        can reach α: the Newton step is −r S/(S² + ε), then limited and clipped.
        """
        secant = "step(trials - 1.5)*step(abs(alpha - alpha_last) - 0.5*min(alpha_probe, trust))"
        self.addComputeGlobal(
            "slope",
            "select(new_secant, (residual - residual_last)/(alpha - alpha_last), slope);"
            f"new_secant = {secant}",
        )
        self.addComputeGlobal("slope_measured", f"max(slope_measured, {secant})")
        self.addComputeGlobal("residual_last", "residual")
        self.addComputeGlobal("alpha_last", "alpha")
        self.addComputeGlobal(
            "alpha_next",
            "select(frozen, alpha, min(max(moved, alpha_min), alpha_max));"
            "frozen = max(step(energy_tolerance - abs(residual)), step(trials - max_trials + 0.5));"
            "moved = select(slope_measured + 1 - delta(clipped - alpha), clipped, inwards);"
            "inwards = alpha - outward*probe;"
            "outward = 2*step(change) - 1;"
            "clipped = min(max(alpha + change, alpha_min), alpha_max);"
            "change = select(slope_measured, limited, select(limited, probe_sized, probe));"
            "probe_sized = (2*step(limited) - 1)*max(abs(limited), probe);"
            "probe = min(alpha_probe, trust);"
            "limited = min(max(newton, -trust), trust);"
            "newton = -residual*slope/(slope*slope + (slope_damping*slope_scale)^2 + 1e-30)",
        )
        self.addComputeGlobal(
            "controller_done",
            "max(max(stays*step(midpoint_tolerance - midpoint_change), capped),"
            " max(not_finite, midpoint_failed));"
            "not_finite = 1 - step(1e30 - abs(residual));"
            "capped = step(midpoint_iterations - max_midpoint_iterations + 0.5);"
            "stays = 1 - step(abs(alpha_next - alpha) - 1e-12)",
        )

    def _add_controller_bookkeeping(self) -> None:
        """Per-step diagnostics and totals."""
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
        self._add_slope_scale_update()
        self.addComputeGlobal("predictor_valid", "1 - midpoint_failed")

    def _add_slope_scale_update(self) -> None:
        """S̄, the damping scale: a running geometric mean of the in-step slopes |S|.

        One measured |S| moves S̄ by at most ×10^0.2 up and ×10^-0.6 down, so that
        a secant over a noise-sized move of α cannot inflate S̄ (an inflated S̄ damps
        every Newton step to nothing: the *dead controller*, S̄ ≈ 6e8 kJ/mol measured on
        water and villin at order 2 before this rule) and an inflated S̄ is back within
        about a dozen steps.
        """
        self.addComputeGlobal(
            "slope_scale",
            "select(slope_measured, select(slope_scale, running, max(abs(slope), 1e-12)), slope_scale);"
            "running = exp(0.8*log(slope_scale) + 0.2*log(bounded));"
            "bounded = min(max(abs(slope), 1e-3*slope_scale), 10*slope_scale)",
        )

    def _add_trust_update(self) -> None:
        """Halve the per-trial move limit when α swings back and forth by a full limit and misses.

        A step that moved α by more than the limit, opposite to the previous step's
        move of more than the limit, and still missed E_ref is the signature of a
        controller that cannot reach E_ref (a residual beyond α's authority, or a slope
        that changes sign across the move):
        at order 4 on villin it ran into a limit cycle, α swinging between ±0.05 each
        step for 500 steps while H − E_ref grew to 18 kJ/mol. A step within tolerance
        grows the limit again by ×1.5, up to ``max_alpha_change``; it never drops below
        a quarter of ``alpha_probe``. Order 4 only: at order 2 it made the water box
        drift (CUDA mixed, 10 ps: RMS 6.8 against 0.47 kJ/mol without it), so there the
        limit stays ``max_alpha_change``.
        """
        self.addComputeGlobal(
            "trust",
            "select(missed_far, max(0.5*trust, 0.25*alpha_probe), select(fell_back, trust, grown));"
            "grown = min(1.5*trust, max_alpha_change);"
            "missed_far = fell_back*far*step(-move*last_move);"
            "far = step(abs(move) - trust)*step(abs(last_move) - trust);"
            "move = alpha - alpha_start",
        )
        self.addComputeGlobal("last_move", "alpha - alpha_start")

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
