"""The energy mode's controller: a layer that chooses α each step over any base step with a parameter α.

The controller is written once and runs inside the ``CustomIntegrator`` step program over
a *base*: a step that depends on one parameter α, with α = 0 the base's own step. The
bases (:class:`~.energy_mode.AlphaRattleEnergyIntegrator`): α-RATTLE's step (α = 0:
RATTLE), a composition with α on one stage (α = 0: the composition of RATTLE steps), and
a two-stage splitting of the explicit family, whose member α₀ + α the step takes (α = 0:
the splitting itself). A base gives the controller its *trial*, the step from the saved
start at the current ``alpha`` ending with x, v at its end, and the midpoint iteration's
globals (``midpoint_change``, ``midpoint_failed`` …; a base without an implicit midpoint
leaves them at 0). Each trial's residual r = U(x1) + K(v1) − E_ref moves α:

1. the next α by a damped secant step, Δα = −r S/(S² + (d S̄)²), with S = dr/dα
   measured inside this step, S̄ a running geometric mean of |S| over past steps and
   d = ``slope_damping``: where the slope nearly vanishes no bounded α can help, and
   throwing α far would spoil the steps after it (:meth:`_EnergyController._add_alpha_update`);
2. the first trial's α predicted (:meth:`_EnergyController._add_alpha_prediction`, on
   a composition): the step's energy change at α = 0 and its slope S, fitted step by step
   as AR(2) series, give the α that should land on E_ref, found by a Newton step from ᾱ,
   the fixed α that best held the energy over past steps; the second trial starts from the
   predicted slope and moves α by at least the probe size (``alpha_probe``, or less where
   the typical slope says a smaller move already measures S above the energy tolerance);
   at a bound, where that move would leave the interval, it probes inwards;
3. every move limited to ``max_alpha_change`` (on a composition a limit that halves when α
   swings back and forth, :meth:`_EnergyController._add_trust_update`) and clipped to the
   α bounds.

α stops moving when the energy is within tolerance, when α sits at a bound and the root
lies beyond it, or after ``max_trials`` trials. **Where the controller cannot hold a step**
(its trials ended outside the tolerance, or the base's midpoint iteration failed, or the
residual is not finite), the step is taken once more at α = 0, the base's step, and ends
there unless its best α trial ended closer to E_ref; at order 2 a missed trial is kept
where it ends closer to E_ref than the α = 0 step, estimated, and moves the running mean
of H − E_ref towards 0 (:meth:`_EnergyController._add_trial_end`). The α = 0 steps are
counted and ``step()`` warns (:class:`EnergyHoldWarning`). E_ref is never moved by the
controller, so a residual left by a missed step is corrected by later steps and cannot
accumulate into drift. E_ref is taken by the rule of :mod:`~.reference_energy` (shared
with RATTLE + velocity rescaling).
"""

from __future__ import annotations

import warnings

import openmm.unit as unit

from ..errors import EnergyHoldWarning
from ..smooth_forces import NonSmoothForcesWarning, outside_stacklevel
from .energy_settings import PREDICTOR_FORGETTING, PREDICTOR_WARMUP, _Controller, check_alpha_bounds
from .pieces import ACCEPTED_MIDPOINT_CHANGE
from .reference_energy import _ReferenceEnergy
from .variables import (
    ALPHA_AT_BOUND,
    FELL_BACK,
    PREDICTED_D0,
    PREDICTED_SLOPE,
    RESIDUAL,
    SLOPE,
    SLOPE_SCALE,
    TRIALS,
)

#: Steps after which an energy mode never shown its Context reads its own record (``_diagnose``).
DIAGNOSIS_STEPS = 200
#: A composition's energy mode whose steps ended outside the tolerance more often than this says
#: its forces are not smooth: with smooth forces few steps end outside it, with OpenMM's defaults
#: (no LJ switch, or no tight Ewald tolerance) nearly all (the measurements: docs/energy_mode.md).
NON_SMOOTH_FALLBACK_FRACTION = 0.5
#: The energy mode warns that it cannot hold the energy once at least this many of its steps, and
#: at least :data:`ALPHA_ZERO_WARN_FRACTION` of them, were α = 0 steps: above the few per cent of
#: a run that holds the energy, below a run that cannot (the measurements: docs/energy_mode.md).
ALPHA_ZERO_WARN_STEPS = 5
ALPHA_ZERO_WARN_FRACTION = 0.2


#: The series the controller predicts: D0, the one-step energy change at α = 0, and S = dH/dα.
_PREDICTED_SERIES = ("d0", "slope")
#: Each series' last two values and its exponentially weighted normal equations.
_PREDICTOR_STATE = tuple(
    f"{series}_{part}"
    for series in _PREDICTED_SERIES
    for part in ("lag1", "lag2", "g11", "g12", "g22", "b1", "b2")
) + ("fit_d0_slope", "fit_slope_slope")

#: The controller's state, every base's (globals, 0 at the start).
_CONTROLLER_STATE = (
    "zero_trial",
    "zero_done",
    "alpha_tried",
    "last_trial_change",
    "residual_mean",
    "trial_better",
    "best_set",
    "residual_best",
    "alpha_best",
    "restored_best",
    "steps_restored",
    "steps_alpha_zero",
    RESIDUAL,
    "residual_last",
    "alpha_last",
    "alpha_next",
    "alpha_start",
    SLOPE,
    SLOPE_SCALE,
    "slope_measured",
    TRIALS,
    "last_move",
    "controller_done",
    "restarting",
    "completing",
    FELL_BACK,
    ALPHA_AT_BOUND,
    "steps_within_tolerance",
    "steps_fallen_back",
    "steps_at_bound",
    "predictor_valid",
    "sum_residual_squared",
    "max_abs_residual",
    "start_residual",
    "first_residual",
    "first_alpha",
    PREDICTED_D0,
    PREDICTED_SLOPE,
    "use_prediction",
    "predictor_steps",
    "alpha_typical",
    "slope_authority",
    "probe_size",
    *_PREDICTOR_STATE,
)


def _ar2_prediction(series: str) -> str:
    """Expression of the next value of ``series`` by its ridge-regularised AR(2) fit."""
    return (
        f"a1*{series}_lag1 + a2*{series}_lag2;"
        f"a1 = ((g22 + ridge)*{series}_b1 - {series}_g12*{series}_b2)/det;"
        f"a2 = ((g11 + ridge)*{series}_b2 - {series}_g12*{series}_b1)/det;"
        f"det = max((g11 + ridge)*(g22 + ridge) - {series}_g12^2, 1e-300);"
        "ridge = 0.005*(g11 + g22);"
        f"g11 = {series}_g11; g22 = {series}_g22"
    )


class _EnergyController(_ReferenceEnergy):
    """The energy mode's controller, mixed in before a step program whose base step has α.

    ``class X(_EnergyController, SomeStepProgram)``. The base gives :meth:`_add_trial_start`
    (before the controller's start, once per step), :meth:`_add_trial` (one trial at the
    current ``alpha``, ending with :meth:`_add_trial_end`), :meth:`_trial_takes_midpoint`,
    :meth:`_base_step_name` and the property ``order`` (2: one step, whose controller starts
    each step at the last α*; 4 or 6: a composition, whose first trial is predicted);
    :meth:`_build_trial_program` is the step program of a base whose trial is one loop.
    """

    def _add_controller_variables(self, settings: _Controller) -> None:
        """Declare E_ref, the controller's settings and its state (before the base's own)."""
        low, high = settings.alpha_bounds
        self._add_reference_energy_variables(settings.energy_tolerance)
        for name, value in (
            ("alpha_min", low),
            ("alpha_max", high),
            ("max_trials", settings.max_trials),
            ("max_alpha_change", settings.max_alpha_change),
            ("alpha_probe", settings.alpha_probe),
            ("slope_damping", settings.slope_damping),
            ("trust", settings.max_alpha_change),  # the move limit; adapted at order 4 only
            ("predictor_forgetting", PREDICTOR_FORGETTING),
            ("predictor_warmup", PREDICTOR_WARMUP if settings.predict else 1e30),
        ):
            self.addGlobalVariable(name, value)
        for name in _CONTROLLER_STATE:
            self.addGlobalVariable(name, 0)

    # ------------------------------------------------------------ what the base gives
    def _add_trial_start(self) -> None:
        """Prepare the step's trials (after the reference check, before the controller's start)."""
        raise NotImplementedError

    def _add_trial(self) -> None:
        """One trial at the current α from the step's start, ending with :meth:`_add_trial_end`."""
        raise NotImplementedError

    def _trial_takes_midpoint(self) -> bool:
        """Whether a trial takes α-RATTLE's midpoint force (``fmid``), which the controller carries."""
        return True

    def _base_step_name(self) -> str:
        """Name the base's step at α = 0, as the warnings do."""
        raise NotImplementedError

    # ------------------------------------------------------------ the program
    def _build_trial_program(self) -> None:
        """Build the step program of a base whose trials are one loop: start, trials, the step's end.

        The step's start is saved (F(x0) read before the reference check's energy: see
        :meth:`~.reference_energy._ReferenceEnergy._add_reference_check`); a step that ended
        in its best α trial (:meth:`_add_best_trial_restore`) left the last constraint step at
        the α = 0 trial's positions, so the step is projected along its start (a no-op on
        positions that satisfy the constraints; not in an if block, which would be one more
        block for the common platform's analysis to branch on). Then the trials, until the
        controller stops.
        """
        self._add_save_step_start(**self._step_start_copies())
        self._add_reference_check(self._predictor_resets())
        self.addConstrainPositions()
        self._add_trial_start()
        self._add_controller_start()
        self.addComputeGlobal("solving", "1")
        self.beginWhileBlock("solving > 0.5")
        self._add_trial()
        self.endBlock()
        self._add_best_trial_restore()
        self._add_controller_bookkeeping()
        self._add_end_step()

    def _step_start_copies(self) -> dict[str, str]:
        """Return the per-DOF copies the step's start saves besides x0, v0 (F(x0) in ``fstart``)."""
        return {"fstart": "f"}

    def _add_best_trial_record(self, full_trial: str) -> None:
        """Keep the end state of the step's α trial with the smallest |H − E_ref| so far.

        Only a full trial whose midpoint had converged (its last midpoint force changed
        x1 by less than ``midpoint_tolerance``) and whose residual is finite is a step
        of the method and may be kept. ``x`` and ``v`` still hold the trial's end here
        (a restart only resets ``x0``, ``v0``); ``alpha_tried`` is the trial's α.
        """
        self.addComputeGlobal(
            "trial_better",
            "candidate*max(1 - kept, 1 - step(abs(residual) - abs(residual_best)));"
            "kept = best_set*(1 - delta(trials - 1));"
            f"candidate = {full_trial}*step(midpoint_tolerance - midpoint_change)*step(1e30 - abs(residual))",
        )
        self.addComputeGlobal("best_set", "max(best_set*(1 - delta(trials - 1)), trial_better)")
        self.addComputeGlobal("residual_best", "select(trial_better, residual, residual_best)")
        self.addComputeGlobal("alpha_best", "select(trial_better, alpha_tried, alpha_best)")
        self.addComputePerDof("xbest", "select(trial_better, x, xbest)")
        self.addComputePerDof("vbest", "select(trial_better, v, vbest)")

    def _add_best_trial_restore(self) -> None:
        """End a step that took its α = 0 trial in its best α trial, where that is the better end.

        A step that ran its α = 0 trial (``zero_trial``, :meth:`_add_trial_end`) ends in
        the α = 0 state unless a converged α trial ended strictly closer to E_ref; then
        the step keeps that trial's x, v and α. So no step that took its α = 0 trial ends
        farther from E_ref than the base's step from the same start. At order 2 a missed α
        trial is kept without the α = 0 trial only where it ends closer to E_ref than the
        α = 0 step, estimated, and it moves the running mean of H − E_ref (``residual_mean``) towards 0
        (:meth:`_add_trial_end`): a step set near E_ref where the base's energy error is at
        a peak of its oscillation moves the centre of the oscillations after it away from
        E_ref, which is how order 2 ended above RATTLE's RMS(H − E_ref) before this rule
        (the measurements, against RATTLE and against |H − E_ref| alone as the rule:
        docs/energy_mode.md). The force at the restored positions is
        computed again at the next step's start: one more force evaluation, counted here.
        No constraint step follows the restore: on the common platform any
        ``addConstrainPositions`` after the midpoint assignment in program text would make
        that assignment a stored displacement, unseen by the midpoint force (§5a); the
        next step constrains its start state instead.
        """
        self.addComputeGlobal(
            "restored_best", "zero_trial*best_set*(1 - step(abs(residual_best) - abs(residual)))"
        )
        self.addComputePerDof("x", "select(restored_best, xbest, x)")
        self.addComputePerDof("v", "select(restored_best, vbest, v)")
        self.addComputePerDof("xend", "x")
        self.addComputePerDof("vend", "v")
        self.addComputeGlobal("residual", "select(restored_best, residual_best, residual)")
        self.addComputeGlobal("alpha", "select(restored_best, alpha_best, alpha)")
        self.addComputeGlobal("zero_trial", "zero_trial*(1 - restored_best)")
        self.addComputeGlobal("end_energy", "residual + reference_energy")
        self.addComputeGlobal("step_force_evaluations", "step_force_evaluations + restored_best")
        self.addComputeGlobal("steps_restored", "steps_restored + restored_best")

    # ------------------------------------------------------------------ pieces
    def _predictor_resets(self) -> tuple[tuple[str, str], ...]:
        """Forget the predictor when E_ref is taken again (``on_retake`` of the reference check)."""
        return (
            *((name, f"{name}*(1 - retake)") for name in ("predictor_steps", *_PREDICTOR_STATE)),
            ("predictor_valid", "predictor_valid*(1 - retake)"),
            ("residual_mean", "residual_mean*(1 - retake)"),
            ("slope", "select(retake, 0, slope)"),
        )

    def _add_controller_start(self) -> None:
        """Reset the per-step controller state; the first trial uses the last step's α*.

        After an α = 0 step (``zero_trial`` still set from it) the order-2 controller starts
        from its last α trial's α instead: α* is O(1) there, and three trials from 0 rarely
        reach it. A composition starts at α = 0 (:meth:`_add_alpha_prediction`).
        """
        if self.order == 2:
            self.addComputeGlobal("alpha", "select(zero_trial, alpha_tried, alpha)")
        self.addComputeGlobal("alpha_start", "alpha")
        self.addComputeGlobal("alpha", "min(max(alpha, alpha_min), alpha_max)")
        for name in ("trials", "slope_measured", "controller_done", "restarting", "zero_done"):
            self.addComputeGlobal(name, "0")
        self.addComputeGlobal("last_trial_change", "1e30")
        self._add_alpha_prediction()
        self.addComputeGlobal("zero_trial", "0")

    def _add_alpha_prediction(self) -> None:
        """Predict the first trial's α from the step's predicted D0 and S (after the warm-up).

        H − E_ref after a step taken with α is, to first order in α,
        r = r_start + D0 + α S: r_start the residual the step starts with, D0 the
        step's energy change at α = 0, S = dH/dα. Both D0 and S oscillate smoothly
        from step to step; each is predicted by an AR(2) model, x_n ≈ a1 x_{n−1} + a2
        x_{n−2}, fitted by exponentially weighted least squares (forgetting factor
        ``predictor_forgetting``, a ridge of 1 % of the mean diagonal) over the
        steps so far.

        The same weights give ᾱ = −Σλ D0 S / Σλ S² (``alpha_typical``), the fixed α
        that would have held the energy best over past steps, and the typical slope
        S_typ = (Σ(1−λ)λ S²)^½ (``slope_authority``). The first trial takes the
        Newton step from ᾱ, α = ᾱ − (r_start + D0 + ᾱ S) S / (S² + (d S_typ)²), within
        ``trust`` of ᾱ and the bounds: where the predicted S is small the damping
        keeps α near ᾱ rather than pulling it to 0. The probe size of the step is
        min(``alpha_probe``, trust, 2·tolerance/S_typ): a move that changes the energy
        by about twice the tolerance is enough to measure S. The second trial (if
        any) starts from the predicted slope. After an α = 0 step (the controller could
        not hold the last step, :meth:`_add_trial_end`) the first trial is at α = 0,
        where the last step ended. Before ``predictor_warmup`` steps with
        a measured S the first trial keeps the last α* and the probe is ``alpha_probe``
        (limited by trust).
        """
        self.addComputeGlobal("start_residual", "end_energy - reference_energy")
        for series, variable in zip(_PREDICTED_SERIES, (PREDICTED_D0, PREDICTED_SLOPE)):
            self.addComputeGlobal(variable, _ar2_prediction(series))
        self.addComputeGlobal("use_prediction", "step(predictor_steps - predictor_warmup + 0.5)")
        self.addComputeGlobal(
            "alpha_typical", "select(fit_slope_slope, -fit_d0_slope/fit_slope_slope, alpha_start)"
        )
        self.addComputeGlobal("slope_authority", "sqrt((1 - predictor_forgetting)*fit_slope_slope)")
        self.addComputeGlobal(
            "probe_size",
            "min(min(alpha_probe, trust), select(use_prediction, sized, alpha_probe));"
            "sized = max(2*energy_tolerance/(slope_authority + 1e-30), 1e-6)",
        )
        self.addComputeGlobal(
            "alpha",
            "select(use_prediction*(1 - zero_trial), min(max(limited, alpha_min), alpha_max), alpha);"
            "limited = min(max(centred, alpha_typical - trust), alpha_typical + trust);"
            "centred = alpha_typical - (start_residual + predicted_d0 + alpha_typical*predicted_slope)"
            "*predicted_slope/(predicted_slope^2 + (slope_damping*slope_authority)^2 + 1e-30)",
        )
        self.addComputeGlobal("slope", "select(use_prediction, predicted_slope, slope)")
        self.addComputeGlobal("first_alpha", "alpha")

    def _add_trial_end(
        self, next_start: dict[str, str], residual: str | None = None, full_trial: str = "1"
    ) -> None:
        """Residual of the trial, the next α, and either the end of the step, a new trial or the α = 0 trial.

        ``residual``: its expression where the caller measured the energy (order 4),
        else H − E_ref at the current state; ``full_trial``: whether this trial measured
        it (order 4: not a short trial). A new trial restarts the α sub-step from
        ``next_start`` (the state after the first sub-step at order 4) and goes to its
        midpoint block, which solves x1 with the new α before taking the midpoint force.

        **The α = 0 trial.** Where the α trials cannot hold the step (the controller
        stopped on a full trial outside ``energy_tolerance``: no α within the bounds
        reaches E_ref, or the trials ran out; or the midpoint iteration ran away or
        diverged, or the residual is not finite), the step is taken once more at α = 0
        (``zero_trial``), without a midpoint force: the base's step (RATTLE, or the
        composition of RATTLE steps), which ends the step (:meth:`_add_best_trial_restore`
        may still keep the best α trial). At order 2, where α* is O(1) and the α trials
        rarely reach the tolerance, a missed α trial is kept without the α = 0 trial where
        it ends closer to E_ref than the α = 0 step would, estimated on the in-step secant,
        and moves the running mean of H − E_ref (``residual_mean``) towards 0. The
        controller's records (slopes, fits, α of the last α trial in ``alpha_tried``) stay
        as the α trials left them.
        """
        if residual is None:
            self._add_sum("kinetic_energy", "0.5*m*v*v")
            residual = "energy + kinetic_energy - reference_energy"
        if full_trial == "1":
            self.addComputeGlobal("zero_done", "zero_trial")
        self.addComputeGlobal("residual", residual)
        self.beginIfBlock("zero_done < 0.5")
        self.addComputeGlobal("trials", "trials + 1 - completing")
        self.addComputeGlobal("first_residual", "select(delta(trials - 1), residual, first_residual)")
        self._add_alpha_update()
        # a midpoint that ran away or diverges (at the same α its change grew fourfold from one
        # pass to the next, above ten times the tolerance: not round-off at the iteration's
        # floor), or a residual that is not finite: the α trials failed
        self.addComputeGlobal(
            "midpoint_failed",
            "max(midpoint_failed, max(controller_done*max(1 - step(accepted - midpoint_change), not_finite),"
            " diverging));"
            "diverging = delta(alpha - alpha_tried)*step(trials - 1.5)"
            "*step(midpoint_change - 10*midpoint_tolerance)*step(midpoint_change - 4*last_trial_change);"
            "not_finite = 1 - step(1e30 - abs(residual));" + ACCEPTED_MIDPOINT_CHANGE,
        )
        self.addComputeGlobal("controller_done", "max(controller_done, midpoint_failed)")
        self.addComputeGlobal("last_trial_change", "midpoint_change")
        missed = f"{full_trial}*step(abs(residual) - energy_tolerance)"
        definitions = ""
        if self.order == 2:
            # order 2 keeps a missed α trial that ends closer to E_ref than the α = 0 step would,
            # r0 = r − α S on the in-step secant (H is close to linear in α there), and moves the
            # running mean of H − E_ref towards 0 (``_add_best_trial_restore``); else the α = 0 trial
            missed += (
                "*(1 - (1 - step(abs(residual) - abs(zero_estimate)))"
                "*step(abs(residual_mean) - abs(residual_mean + residual - zero_estimate)))"
            )
            definitions = ";zero_estimate = residual - alpha*slope"
        self.addComputeGlobal("zero_trial", f"controller_done*max(midpoint_failed, {missed}){definitions}")
        self.addComputeGlobal("alpha_tried", "alpha")
        self._add_best_trial_record(full_trial)
        self.addComputeGlobal("restarting", "1 - controller_done + zero_trial")
        self.addComputeGlobal("alpha", "select(zero_trial, 0, select(restarting, alpha_next, alpha))")
        self.addComputeGlobal("need_midpoint", "restarting*(1 - zero_trial)")
        if self._trial_takes_midpoint():
            self.addComputePerDof("fmid_last", "fmid")
        self.endBlock()
        self.beginIfBlock("zero_done > 0.5")
        for name, value in (("controller_done", "1"), ("restarting", "0"), ("need_midpoint", "0")):
            self.addComputeGlobal(name, value)
        self.endBlock()
        self.addComputeGlobal("previous_midpoint_change", "1e30")
        self._add_end_state_record("residual + reference_energy")
        for variable, expression in next_start.items():
            self.addComputePerDof(variable, f"select(restarting, {expression}, {variable})")
        if self._trial_takes_midpoint():
            # α = 0 weighs the midpoint force by 0: a finite one (a failed midpoint may have left NaN)
            self.addComputePerDof("fmid", "select(zero_trial*restarting, fstart, fmid)")

    def _add_alpha_update(self) -> None:
        """Secant step on r(α) with the in-step slope; bounded; decide whether to stop.

        Written with ``select``/``step`` so that no division by a vanishing slope
        can reach α: the Newton step is −r S/(S² + (d s)²), then limited and clipped.
        The damping scale s is S̄ (``slope_scale``) once the step measured its own
        slope or before the predictor's warm-up, else the typical slope of past steps
        (``slope_authority``) for a move made with the predicted S. A secant counts
        as a measurement when α moved by at least half the step's probe size.
        """
        secant = "step(trials - 1.5)*step(abs(alpha - alpha_last) - 0.5*probe_size)"
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
            "frozen = max(step(energy_tolerance - abs(residual)), step(trials - trial_cap + 0.5));"
            f"trial_cap = {self._trial_cap()};"
            "moved = select(slope_measured + 1 - delta(clipped - alpha), clipped, inwards);"
            "inwards = alpha - outward*probe;"
            "outward = 2*step(change) - 1;"
            "clipped = min(max(alpha + change, alpha_min), alpha_max);"
            "change = select(slope_measured, limited, select(limited, probe_sized, probe));"
            "probe_sized = (2*step(limited) - 1)*max(abs(limited), probe);"
            "probe = probe_size;"
            "limited = min(max(newton, -trust), trust);"
            "newton = -residual*slope/(slope*slope + (slope_damping*scale)^2 + 1e-30);"
            "scale = select(slope_measured + 1 - use_prediction, slope_scale, slope_authority)",
        )
        self.addComputeGlobal(
            "controller_done",
            "max(max(stays*step(midpoint_tolerance - midpoint_change), capped),"
            " max(not_finite, midpoint_failed));"
            "not_finite = 1 - step(1e30 - abs(residual));"
            "capped = step(midpoint_iterations - max_midpoint_iterations + 0.5);"
            "stays = 1 - step(abs(alpha_next - alpha) - 1e-12)",
        )

    def _trial_cap(self) -> str:
        """Return the cap on a step's trials: ``max_trials``; at order 4 at most 3 during the warm-up.

        During the predictor's warm-up every trial is full and a step starts at the last
        step's α*, so a step that carried α far passes it on to the next; a fourth trial
        let it reach a bound (docs/research/short_trials.md).
        """
        if self.order != 2:
            return "select(use_prediction, max_trials, min(max_trials, 3))"
        return "max_trials"

    def _add_controller_bookkeeping(self) -> None:
        """Per-step diagnostics and totals."""
        self.addComputeGlobal("fell_back", "1 - step(energy_tolerance - abs(residual))")
        self.addComputeGlobal(
            "alpha_at_bound", "(1 - zero_trial)*max(delta(alpha - alpha_min), delta(alpha - alpha_max))"
        )
        self.addComputeGlobal("steps_within_tolerance", "steps_within_tolerance + 1 - fell_back")
        self.addComputeGlobal("steps_alpha_zero", "steps_alpha_zero + zero_trial")
        self.addComputeGlobal("steps_fallen_back", "steps_fallen_back + fell_back")
        self.addComputeGlobal("steps_at_bound", "steps_at_bound + alpha_at_bound")
        # every step's H − E_ref, for the run's RMS and maximum without reading the state each step
        self.addComputeGlobal("sum_residual_squared", "sum_residual_squared + residual^2")
        self.addComputeGlobal(
            "residual_mean", "predictor_forgetting*residual_mean + (1 - predictor_forgetting)*residual"
        )
        self.addComputeGlobal("max_abs_residual", "max(max_abs_residual, abs(residual))")
        self._add_slope_scale_update()
        self._add_predictor_update()
        self.addComputeGlobal("predictor_valid", "1 - midpoint_failed")

    def _add_predictor_update(self) -> None:
        """Add the step's D0 and S to the AR(2) fits (not after a step whose α trials failed).

        S is the in-step secant slope when the step took a second trial, else the
        slope the step assumed (the prediction; during the warm-up the last
        measured one); D0 = r₁ − r_start − α₁ S from the first trial's residual r₁.
        The weighted sums Σλ D0 S and Σλ S² (the fit of ᾱ) are updated with the same
        weights.
        """
        self.addComputeGlobal(
            "predictor_steps", "predictor_steps + (1 - midpoint_failed)*max(slope_measured, use_prediction)"
        )
        observed = {"d0": "first_residual - start_residual - first_alpha*slope", "slope": "slope"}
        lam = "predictor_forgetting"
        for series in _PREDICTED_SERIES:
            x = f"({observed[series]})"
            lag1, lag2 = f"{series}_lag1", f"{series}_lag2"
            for part, term in (
                ("g11", f"{lag1}*{lag1}"),
                ("g12", f"{lag1}*{lag2}"),
                ("g22", f"{lag2}*{lag2}"),
                ("b1", f"{lag1}*{x}"),
                ("b2", f"{lag2}*{x}"),
            ):
                name = f"{series}_{part}"
                self.addComputeGlobal(name, f"select(midpoint_failed, {name}, {lam}*{name} + {term})")
            self.addComputeGlobal(lag2, f"select(midpoint_failed, {lag2}, {lag1})")
            self.addComputeGlobal(lag1, f"select(midpoint_failed, {lag1}, {x})")
        for name, term in (("fit_d0_slope", "d0_lag1*slope_lag1"), ("fit_slope_slope", "slope_lag1^2")):
            self.addComputeGlobal(name, f"select(midpoint_failed, {name}, {lam}*{name} + {term})")

    def _add_slope_scale_update(self) -> None:
        """S̄, the damping scale: a running geometric mean of the in-step slopes |S|.

        One measured |S| moves S̄ by at most ×10^0.2 up and ×10^-0.6 down, so that
        a secant over a noise-sized move of α cannot inflate S̄ (an inflated S̄ damps
        every Newton step to nothing: the *dead controller*, seen on water and villin at
        order 2 before this rule, docs/research/controller_robustness.md) and an inflated
        S̄ falls by up to ×10^0.6 with each slope measured below it.
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
        that changes sign across the move): without this rule such a controller can
        run into a limit cycle, α swinging between ± the limit every step while H − E_ref
        grows (seen at order 4 on villin). A step within tolerance
        grows the limit again by ×1.5, up to ``max_alpha_change``; it never drops below
        a quarter of ``alpha_probe``. Order 4 only: at order 2 the rule made the water box
        drift, so there the limit stays ``max_alpha_change`` (the measurements:
        docs/research/controller_robustness.md).
        """
        self.addComputeGlobal(
            "trust",
            "select(missed_far, max(0.5*trust, 0.25*alpha_probe), select(fell_back, trust, grown));"
            "grown = min(1.5*trust, max_alpha_change);"
            "missed_far = fell_back*far*step(-move*last_move);"
            "far = step(abs(move) - trust)*step(abs(last_move) - trust);"
            "move = alpha_tried - alpha_start",
        )
        self.addComputeGlobal("last_move", "alpha_tried - alpha_start")

    # ---------------------------------------------------------------- what the user sets and reads
    @property
    def energy_residual(self) -> unit.Quantity:
        """H − E_ref after the last step (total energy with on-step velocities)."""
        return self.getGlobalVariableByName(RESIDUAL) * unit.kilojoules_per_mole

    @property
    def alpha_bounds(self) -> tuple[float, float]:
        """The interval α* is kept in."""
        return (self.getGlobalVariableByName("alpha_min"), self.getGlobalVariableByName("alpha_max"))

    @alpha_bounds.setter
    def alpha_bounds(self, bounds: tuple[float, float]) -> None:
        low, high = check_alpha_bounds(bounds)
        self.setGlobalVariableByName("alpha_min", low)
        self.setGlobalVariableByName("alpha_max", high)

    @property
    def fell_back(self) -> bool:
        """Whether the last step ended outside the energy tolerance (α at a bound or trial cap)."""
        return bool(self.getGlobalVariableByName(FELL_BACK))

    @property
    def trials(self) -> int:
        """Trials of α in the last step.

        Order 2: a midpoint and an end force each (more where the midpoint needs them).
        Order 4: the first takes three force evaluations, a short one one; taking the last
        sub-step once α stopped (one more) is not counted as a trial.
        """
        return int(self.getGlobalVariableByName(TRIALS))

    def controller_totals(self) -> dict[str, float]:
        """Totals over every step since the integrator was created.

        Returns
        -------
        A dict with ``steps``, ``steps_within_tolerance`` and ``steps_fallen_back`` (steps
        that ended within / outside the energy tolerance); of the latter, the steps the α
        trials could not hold: ``steps_alpha_zero`` (taken at α = 0, the base's step, see
        ``_add_trial_end``) and ``steps_restored`` (ended in their best α trial, closer to
        E_ref than the α = 0 step, see ``_add_best_trial_restore``); ``steps_at_bound``,
        ``reference_resets`` (counts), the fractions of the steps
        ``fraction_within_tolerance``, ``fraction_fallen_back``, ``fraction_alpha_zero`` and
        ``fraction_at_bound``,
        ``force_evaluations_per_step``, and ``rms_residual`` and ``max_abs_residual``:
        RMS and maximum of H − E_ref after each step (kJ/mol; NaN before the first step),
        accumulated inside the step program, so that a reporter need not read the state
        every step. Order 4 adds the short trials (see ``_add_substep_energy``):
        ``short_trials_completed``, ``midpoints_reused`` (trials that kept the last
        midpoint force) and ``rms_short_trial_error``, the RMS difference between a
        completed short trial's predicted and measured residual (kJ/mol; NaN before the
        first); at order 2 the counts are 0.
        """
        steps = self.steps_taken
        totals = {
            name: int(self.getGlobalVariableByName(name))
            for name in (
                "steps_within_tolerance",
                "steps_fallen_back",
                "steps_alpha_zero",
                "steps_restored",
                "steps_alpha_zero",
                "steps_at_bound",
                "reference_resets",
            )
        }
        for name in ("short_trials_completed", "midpoints_reused"):
            totals[name] = int(self.getGlobalVariableByName(name)) if self.order != 2 else 0
        completed = totals["short_trials_completed"]
        short_error = (
            (self.getGlobalVariableByName("sum_short_error_squared") / completed) ** 0.5
            if completed
            else float("nan")
        )
        fraction = (lambda n: n / steps) if steps else (lambda n: float("nan"))
        squares = self.getGlobalVariableByName("sum_residual_squared")
        return {
            "steps": steps,
            **totals,
            "fraction_within_tolerance": fraction(totals["steps_within_tolerance"]),
            "fraction_fallen_back": fraction(totals["steps_fallen_back"]),
            "fraction_alpha_zero": fraction(totals["steps_alpha_zero"]),
            "fraction_at_bound": fraction(totals["steps_at_bound"]),
            "force_evaluations_per_step": self.force_evaluations_per_step,
            "rms_residual": fraction(squares) ** 0.5 if steps else float("nan"),
            "max_abs_residual": self.getGlobalVariableByName("max_abs_residual") if steps else float("nan"),
            "rms_short_trial_error": short_error,
        }

    def step(self, steps: int) -> None:
        """Advance by ``steps`` steps (see :meth:`AlphaRattleIntegrator.step`).

        Where the controller cannot hold a step at E_ref (its α trials missed the
        energy tolerance, or its midpoint iteration failed), the step is the base's
        α = 0 step, unless an α trial ended closer to E_ref (``_add_trial_end``,
        ``_add_best_trial_restore``). When α = 0 steps are frequent this warns
        (:class:`EnergyHoldWarning`; see there when).

        An energy mode on a composition that was never shown its Context
        (:meth:`check_context`, which inspects the System) reads its own record once,
        after :data:`DIAGNOSIS_STEPS` steps: if more than half of them ended outside the
        energy tolerance, it warns (:class:`~openmm_alphaprk.smooth_forces.NonSmoothForcesWarning`)
        that the forces are likely not smooth. The second-order mode is not diagnosed:
        it ends most steps outside the tolerance with smooth forces too.
        """
        fallen_before = self.getGlobalVariableByName("steps_alpha_zero")
        try:
            self._step_and_diagnose(steps)
        finally:
            self._warn_if_fallen_back(fallen_before)

    def _step_and_diagnose(self, steps: int) -> None:
        before = self.steps_taken
        due = not getattr(self, "_diagnosed", False) and before < DIAGNOSIS_STEPS <= before + steps
        if not due:
            super().step(steps)
            return
        first = DIAGNOSIS_STEPS - before
        super().step(first)
        self._diagnose()
        if steps > first:
            super().step(steps - first)

    def _warn_if_fallen_back(self, fallen_before: float) -> None:
        """Warn (:class:`EnergyHoldWarning`) once α = 0 steps are frequent, then when their count doubled."""
        fallen = int(self.getGlobalVariableByName("steps_alpha_zero"))
        if fallen <= fallen_before:
            return
        if fallen < ALPHA_ZERO_WARN_STEPS or fallen < ALPHA_ZERO_WARN_FRACTION * self.steps_taken:
            return
        warned = getattr(self, "_fallen_back_warned", 0)
        if warned and fallen < 2 * warned:
            return
        self._fallen_back_warned = fallen
        steps = self.steps_taken
        step_fs = self.getStepSize().value_in_unit(unit.femtoseconds)
        base = self._base_step_name()
        tolerance = self.getGlobalVariableByName("energy_tolerance")
        low, high = self.alpha_bounds
        trials = int(self.getGlobalVariableByName("max_trials"))
        warnings.warn(
            f"the energy-preserving mode could not hold {fallen} of its {steps} steps at E_ref and took "
            f"them as alpha = 0 steps of its base ({base}; the last {fallen - int(fallen_before)} in this "
            f"call): on those steps no alpha within the bounds ({low:.3g}, {high:.3g}) brought H - E_ref "
            f"within the tolerance {tolerance:.3g} kJ/mol in {trials} "
            "trials, or the midpoint iteration failed, and the alpha = 0 step ended at least as close to "
            f"E_ref. Likely causes: too large a step ({step_fs:g} fs; the energy mode holds the energy at "
            "about 2 fs with constraints on bonds to hydrogen, at 4 fs only with hydrogen masses "
            "repartitioned to 3-4 amu, e.g. ForceField.createSystem(..., hydrogenMass=3*unit.amu)), "
            "forces that are not smooth (openmm_alphaprk.prepare_for_nve(system); "
            "integrator.check_context(context) names what is not smooth), or order=2, which cannot hold "
            "the energy. Fix: a smaller step or repartitioned hydrogen masses; for exact energy at "
            "RATTLE's cost, RattleRescaleIntegrator. controller_totals() counts these steps "
            "(steps_alpha_zero).",
            EnergyHoldWarning,
            stacklevel=outside_stacklevel() + 1,
        )

    def _diagnose(self) -> None:
        """Warn once if the record of the first steps shows forces that are not smooth (see :meth:`step`)."""
        self._diagnosed = True
        if self.order == 2 or self._checked_context() is not None:
            return
        totals = self.controller_totals()
        if not totals["fraction_fallen_back"] > NON_SMOOTH_FALLBACK_FRACTION:
            return
        tolerance = self.getGlobalVariableByName("energy_tolerance")
        warnings.warn(
            f"the energy-preserving mode ended {totals['fraction_fallen_back']:.0%} of its first "
            f"{totals['steps']} steps outside its energy tolerance (RMS |H - E_ref| "
            f"{totals['rms_residual']:.3g} kJ/mol, tolerance {tolerance:.3g}): "
            "the System's energy is likely not a smooth function of the positions (a Lennard-Jones cutoff "
            "without a switching function, PME's default error tolerance 5e-4, or another force that "
            "jumps). Make the forces smooth with openmm_alphaprk.prepare_for_nve(system) before creating "
            "the Context, or call integrator.check_context(context), which names what is not smooth.",
            NonSmoothForcesWarning,
            stacklevel=outside_stacklevel() + 1,  # counted from step(), the frame above this one
        )
