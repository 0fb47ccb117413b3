"""α-RATTLE's energy-preserving mode: its step programs and its controller, one room.

:class:`AlphaRattleEnergyIntegrator` is the fixed-α
:class:`~.alpha_rattle.AlphaRattleIntegrator`'s sibling on their private base
(:class:`~.alpha_rattle._AlphaRattleBase`), with programs that choose α. Its two programs,
one α-RATTLE step or a composition of them, are the ``_build_*`` methods below;
the controller's pieces follow them. docs/energy_program.md reads both programs as the state
machine described below: an outline of each by block and piece, and every global the controller
keeps, stage by stage, with its meaning and the pieces that write it (generated from the programs
by ``python -m tools.reports.energy_program``).

**The energy mode.** Each step chooses α so that the total energy after the step equals the reference
energy E_ref, the energy of the state the run started from. The
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
   throwing α far would spoil the steps after it. The first trial's α is predicted
   (:meth:`AlphaRattleEnergyIntegrator._add_alpha_prediction`): the step's energy change
   at α = 0 and its slope S, fitted step by step as AR(2) series, give the α that
   should land on E_ref, found by a Newton step from ᾱ, the fixed α that best held
   the energy over past steps. The
   second trial starts from the predicted slope and moves α by at least the probe
   size (``alpha_probe``, or less where the typical slope says a smaller move
   already measures S above the energy tolerance) so that the step measures its
   own slope (at a bound, where that move would leave the interval, it probes
   inwards). Every move is limited to
   ``max_alpha_change`` (on a composition a limit that halves when α swings back and forth,
   see ``_add_trust_update``) and clipped to the α bounds. A new trial first solves
   x1 again with the new α and the last midpoint force, then goes on with step 2.

On a composition (order 4 or 6) the RATTLE stages before the α stage are taken once,
and the first trial takes the α stage (steps 1–2 with h scaled by its coefficient) and
the RATTLE stages after it: for Suzuki's five stages 2 + 1 + 2 force evaluations
and the midpoint's. After the predictor's warm-up a later trial is *short*: it redoes
the α stage only, with the last midpoint force where the change of α is too small for
a new one to matter, and predicts the later stages' energy change from the full trials
(one force evaluation); once α stops, the later stages are taken at that α and their
measured residual decides whether the step ends.

α stops moving when the energy is within tolerance, when α sits at a bound and the
root lies beyond it, or after ``max_trials`` trials; ``max_midpoint_iterations`` caps the
midpoint forces of a step. **Where the controller cannot hold a step** (its trials ended
outside the tolerance, or the midpoint iteration ran away or diverged, or the residual is
not finite), the step is taken once more at α = 0, the base's step (RATTLE, or the
composition of RATTLE steps), and ends there unless its best α trial ended closer to
E_ref (one more force evaluation, at the next step's start); at order 2 a missed trial is
kept where it ends closer to E_ref than the α = 0 step, estimated, and moves the running
mean of H − E_ref towards 0 (:meth:`AlphaRattleEnergyIntegrator._add_trial_end`). The α = 0
steps are counted and ``step()`` warns (:class:`EnergyHoldWarning`). E_ref is never moved
by the controller, so a residual left by a missed step is corrected by later steps and
cannot accumulate into drift.

E_ref is taken from the state at the first step, after ``reset_reference_energy()``,
and when the user changed the state between steps, by the rule of
:mod:`~.reference_energy` (shared with RATTLE + velocity rescaling).
"""

from __future__ import annotations

import warnings
from typing import ClassVar

import openmm as mm
import openmm.unit as unit

from .._units import InputError
from ..errors import EnergyHoldWarning  # defined there; importable from here too
from ..smooth_forces import NonSmoothForcesWarning, outside_stacklevel
from .alpha_rattle import DEFAULT_MAX_MIDPOINT_ITERATIONS, _AlphaRattleBase, _order_and_composition
from .compositions import Composition
from .energy_settings import (
    CONTROLLER_DEFAULTS,
    NON_PERIODIC_MIDPOINT_TOLERANCE,
    PREDICTOR_FORGETTING,
    PREDICTOR_WARMUP,
    ControllerSettings,
    _Controller,
    alpha_scale_of,
    check_alpha_bounds,
    controller_settings,
)
from .pieces import (
    ACCEPTED_MIDPOINT_CHANGE,
    DEFAULT_CONSTRAINT_TOLERANCE,
    _substep_h,
    first_forces,
    last_forces,
)
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


class AlphaRattleEnergyIntegrator(_ReferenceEnergy, _AlphaRattleBase):
    """α-RATTLE's energy-preserving mode: α chosen every step so that H stays at E_ref.

    The method under study: measured against RATTLE + velocity rescaling
    (:class:`~.rescale.RattleRescaleIntegrator`, ``order=4`` for a composition), it costs
    more and tracks the dynamics less well everywhere measured (docs/energy_mode.md).

    Each step is a member of the α-RATTLE family (the fixed-α class's sibling on their
    shared private base, not a subclass of :class:`~.alpha_rattle.AlphaRattleIntegrator`)
    whose α (on one stage of a composition)
    the controller of this module's docstring chooses so that the total energy after the
    step equals E_ref, the energy of the state the run started from (taken and reset by
    the rule of :mod:`~.reference_energy`). Constraints and linear momentum are kept
    exactly and angular momentum to the midpoint tolerance; symplecticity is given up.
    The program runs NVE: it has no update-context-state step, so barostats, thermostats
    and a ``CMMotionRemover`` do not act (:meth:`check_context` warns about them).
    :meth:`program_listing` prints the program; docs/step_programs.md lists it.

    Parameters
    ----------
    timestep : openmm.unit.Quantity or float
        Step size (a time Quantity, or a number in picoseconds).
    constraint_tolerance : float, default 1e-8
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    midpoint_tolerance : openmm.unit.Quantity or float, optional
        Stopping tolerance of the midpoint iteration (nm, RMS change of x1 per degree of
        freedom). Default with a periodic box 1e-7 nm (order 2) or 1e-5 nm (a
        composition, where α* is O(h²), far smaller): there it only limits how well angular
        momentum is kept (ΔL ≈ 2hα δx_m × F per step), which a periodic box does not
        conserve anyway, and the energy is measured on the state the step ends in;
        without a periodic box 1e-13 nm, set by :meth:`check_context`, which keeps
        angular momentum to round-off.
    max_midpoint_iterations : int, default 20
        Cap on midpoint force evaluations per step, summed over the trials.
    order : {2, 4, 6}, optional
        2 (default): one α-RATTLE step, which cannot hold the energy of a real system
        (docs/energy_mode.md); 4: Suzuki's five stages, α on the middle one, fourth
        order since α* = O(h²); 6: McLachlan's nine stages.
    composition : str or Composition, optional
        A named composition (:data:`~.compositions.COMPOSITIONS`) or a
        :class:`~.compositions.Composition`; sets the order.
    alpha_stages : {"middle"} or tuple of int, optional
        The one stage of a composition that carries α (default the middle one).
    controller : ControllerSettings, optional
        The controller's options (:class:`~.energy_settings.ControllerSettings`: the α
        interval, the energy tolerance, the trials per step, the moves of α, the slope
        damping); a field left None, or no settings, takes the order's default
        (:data:`~.energy_settings.CONTROLLER_DEFAULTS`). The α interval and the energy
        tolerance can be changed between steps (:attr:`alpha_bounds`,
        :attr:`energy_tolerance`).

    See Also
    --------
    RattleRescaleIntegrator : holds the energy at RATTLE's cost (the recommended way).
    AlphaRattleIntegrator : the same family with a fixed α.

    Examples
    --------
    ``energy4`` on a 2 nm water box shipped with the package (four steps: the controller
    holds H − E_ref to its tolerance):

    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import AlphaRattleEnergyIntegrator
    >>> from openmm_alphaprk.systems import prepare_system
    >>> water = prepare_system("tip3p-2nm")
    >>> integrator = AlphaRattleEnergyIntegrator(2 * unit.femtoseconds, order=4)
    >>> context = openmm.Context(water.system, integrator, openmm.Platform.getPlatformByName("CPU"))
    >>> context.setState(water.state)
    >>> integrator.check_context(context)  # the tolerances for this system and platform
    >>> integrator.step(4)
    >>> abs(integrator.energy_residual) < integrator.energy_tolerance
    True
    """

    energy_mode: ClassVar[bool] = True

    def __init__(
        self,
        timestep: unit.Quantity | float,
        *,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
        midpoint_tolerance: unit.Quantity | float | None = None,
        max_midpoint_iterations: int = DEFAULT_MAX_MIDPOINT_ITERATIONS,
        order: int | None = None,
        composition: str | Composition | None = None,
        alpha_stages: str | tuple[int, ...] | None = None,
        controller: ControllerSettings | None = None,
    ) -> None:
        order, chosen = _order_and_composition(order, composition, alpha_stages)
        if chosen is not None and len(chosen.alpha_stages) != 1:
            raise InputError(
                "the energy mode takes alpha on one stage of a composition, got stages "
                f"{chosen.alpha_stages} of {chosen.name!r}; use alpha_stages='middle' or one stage "
                "number, or AlphaRattleIntegrator with a fixed alpha."
            )
        controls = 2 if chosen is None else 4  # the controller's defaults: one step, or a composition
        settings = controller_settings(
            controls,
            controller,
            automatic_midpoint_tolerance=midpoint_tolerance is None,
            alpha_scale=1.0 if chosen is None else alpha_scale_of(chosen),
        )
        low, high = settings.alpha_bounds
        default_tolerance = CONTROLLER_DEFAULTS[controls].midpoint_tolerance
        self._controller = settings  # read by _add_program
        self._set_up(
            timestep,
            min(max(0.0, low), high),
            constraint_tolerance,
            default_tolerance if midpoint_tolerance is None else midpoint_tolerance,
            max_midpoint_iterations,
            order,
            chosen,
        )

    def _add_program(self) -> None:
        """Add the controller's variables and the energy-mode program (NVE: no update step)."""
        composed = self._composition is not None
        self._add_energy_mode_variables(self._controller, composed)
        build = self._build_energy_program if not composed else self._build_composition_energy_program
        self._add_step(build, update_context_state=False)

    def _add_energy_mode_variables(self, settings: _Controller, composed: bool) -> None:
        """Declare the controller's settings and state (after :meth:`_add_midpoint_variables`)."""
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
        for name in (
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
        ):
            self.addGlobalVariable(name, 0)
        if composed:
            short_trial = (
                "virtual_trial",
                "trial_ready",
                "full_trial",
                "substep_energy",
                "middle_end_energy",
                "last_substep_change",
                "sum_sensitivity2",
                "x1_sensitivity",
                "stale_midpoint_change",
                "reuse_midpoint",
                "midpoints_reused",
                "short_residual",
                "alpha_full",
                "paired",
                "residual_full",
                "last_substep_fit_cross",
                "last_substep_fit_norm",
                "last_substep_slope",
                "short_trials_completed",
                "sum_short_error_squared",
            )
            for name in short_trial:
                self.addGlobalVariable(name, 0)
            self.addGlobalVariable("short_trials", 1)
        # 0: the user chose it
        self.addGlobalVariable("midpoint_tolerance_automatic", float(settings.automatic_midpoint_tolerance))
        for name in ("fmid_last", "xbest", "vbest") + (("xa", "va", "fa", "fstart_last") if composed else ()):
            self.addPerDofVariable(name, 0)

    # ---------------------------------------------------------------- programs
    def _build_energy_program(self) -> None:
        """Order 2: one loop over trials; a trial ends with its velocity update and residual."""
        self._add_save_step_start(fstart="f")
        self._add_reference_check(self._predictor_resets())
        # a step that ended in its best α trial (``_add_best_trial_restore``) left the last
        # constraint step at the α = 0 trial's positions: project this step along its start
        # (a no-op on positions that satisfy the constraints; not in an if block, which would
        # be one more block for the common platform's analysis to branch on)
        self.addConstrainPositions()
        # F(x_m) predicted by linear extrapolation in time from the previous step's midpoint force
        self.addComputePerDof("fmid", "select(predictor_valid, 2*fstart - fmid_last, fstart)")
        self._add_midpoint_setup("1")
        self._add_controller_start()
        self.addComputeGlobal("solving", "1")
        self.beginWhileBlock("solving > 0.5")
        self._add_position_solve(first_forces("alpha"), "dt")
        self.beginIfBlock("need_midpoint < 0.5")
        self._add_velocity_update(last_forces("alpha"), "dt")
        self._add_trial_end(next_start={})
        # the α = 0 trial follows this trial's end, not a midpoint block: make x0 the
        # reference of its solve (rule 2; the midpoint block does it for the α trials)
        self.addComputePerDof("x", "select(zero_trial*restarting, x0, x)")
        self.addConstrainPositions()
        self.addComputeGlobal("solving", "restarting")
        self.endBlock()
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_trial_midpoint_force("dt", "alpha")
        self.endBlock()
        self.endBlock()
        self._add_best_trial_restore()
        self._add_controller_bookkeeping()
        self._add_end_step()

    def _build_composition_energy_program(self) -> None:
        """Build a composition's program: the stages before the α stage once, then trials of the rest.

        The step's first trial takes the α stage (for the triple jump the middle
        sub-step, γ2 h) and the RATTLE stages after it (the last sub-step): for the
        triple jump three force evaluations (midpoint, middle end, last end).
        After the predictor's warm-up a later trial is *short*: it redoes the middle
        sub-step only, keeping the last midpoint force where that is within
        ``midpoint_tolerance`` (one evaluation), and predicts the rest
        (:meth:`_add_substep_energy`); once α stops, the last sub-step is taken at
        that α (one evaluation) and measures the residual the step ends with.
        """
        # F(x0) is read before the reference check's energy: see _add_reference_check
        self._add_save_step_start(fstart="f")
        self._add_reference_check(self._predictor_resets())
        # the projection of the first sub-step must start from this state, which may be
        # an earlier trial's (``_add_best_trial_restore``): constrain it once (a no-op on
        # positions that satisfy the constraints) so that Reference/CPU project along it;
        # placed before every position assignment in program text, it leaves the common
        # platform's delta storage of positions as it was (§5a)
        self.addConstrainPositions()
        composition = self._composition
        self._add_leading_substeps(composition)
        self._add_controller_start()
        # the midpoint force's offset from the sub-step's start force changes little between steps
        self._add_alpha_substeps_start(
            composition,
            "1",
            xa="x",
            va="v",
            fa="f",
            fmid="f + select(predictor_valid, fmid_last - fstart_last, 0)",
            fstart_last="f",
        )
        self.addComputeGlobal("virtual_trial", "0")
        self.addComputeGlobal("completing", "0")
        self.addComputeGlobal("trial_ready", "0")
        self._add_trial_loop(composition)
        self._add_best_trial_restore()
        self._add_controller_bookkeeping()
        self._add_trust_update()
        self._add_end_step()

    def _add_trial_loop(self, composition: Composition) -> None:
        """Add the loop over the stages from the α stage: sub-steps, trial ends and midpoint solves.

        The fixed-α loop (:meth:`~.pieces._StepProgram._add_composition_loop`) with the
        trials: each pass first constrains x0, the sub-step's start (a no-op on its
        positions that makes them the reference of the solve that follows on both
        semantics, rule 2, whichever block ran last); a finished sub-step also measures
        H (:meth:`_add_substep_energy`); where that set ``trial_ready`` the trial ends
        (:meth:`_add_order4_trial_end`: the controller picks the next α or ends the
        step); the midpoint block comes last (rule 1).
        """
        self.beginWhileBlock(f"phase < {composition.stages}.5")
        self._add_next_stage_midpoint(composition)
        self.addComputePerDof("x", "x0")
        self.addConstrainPositions()
        self._add_substep_solve(fallback=None)
        self.beginIfBlock("substep_done > 0.5")
        self._add_substep_end(composition, fallback=None)
        self._add_substep_energy()
        self.endBlock()
        self.beginIfBlock("trial_ready > 0.5")
        self._add_order4_trial_end()
        self.endBlock()
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_order4_trial_midpoint_force("hsub", "alpha_sub")
        self.endBlock()
        self.endBlock()

    def _add_substep_energy(self) -> None:
        """H at the end of a sub-step; after the middle one, whether the trial ends there.

        A short trial ends after the middle sub-step. Its residual is H there plus
        the last sub-step's energy change ΔE_last measured by the step's latest full
        trial (at α_f), corrected by c (α − α_f) (:meth:`_add_last_substep_fit`):
        a new α changes the middle sub-step's end velocities by h Δα (F(x_m) −
        F(x2))/m, small beside thermal velocities, and ΔE_last follows. Once α stops,
        the last sub-step is taken at that α (the trial is *completed*) and its
        measured residual decides: within tolerance, or out of trials, the step ends;
        else another short trial starts from it.
        """
        self._add_sum("kinetic_energy", "0.5*m*v*v")
        self.addComputeGlobal("substep_energy", "energy + kinetic_energy")
        after_alpha, ended = self._composition.first_alpha_stage + 1, self._composition.stages
        self.addComputeGlobal(
            "middle_end_energy", f"select(delta(phase - {after_alpha}), substep_energy, middle_end_energy)"
        )
        self.addComputeGlobal(
            "trial_ready", f"max(step(phase - {ended}.5), delta(phase - {after_alpha})*virtual_trial)"
        )

    def _add_last_substep_fit(self) -> None:
        """Fit c = d(ΔE_last)/dα, how the last sub-step's energy change follows α.

        A short trial at α predicts the last sub-step's energy change as the one
        measured at the latest full trial's α_f plus c (α − α_f). Every full trial
        that follows another in its step (a completed short trial, and during the
        predictor's warm-up, when every trial is full) measures the change over
        Δα = α − α_f; c is the weighted least-squares slope of these pairs, with the
        predictor's forgetting factor, kept across steps (c is steady along a run and
        depends on the system: docs/research/short_trials.md).
        """
        change = "(substep_energy - middle_end_energy - last_substep_change)"
        moved = "(alpha - alpha_full)"
        lam = "predictor_forgetting"
        self.addComputeGlobal("paired", "full_trial*step(trials - 0.5)")
        for name, term in (("cross", f"{change}*{moved}"), ("norm", f"{moved}^2")):
            fit = f"last_substep_fit_{name}"
            self.addComputeGlobal(fit, f"select(paired, {lam}*{fit} + {term}, {fit})")
        self.addComputeGlobal(
            "last_substep_slope",
            "select(last_substep_fit_norm, last_substep_fit_cross/last_substep_fit_norm, 0)",
        )

    def _add_order4_trial_midpoint_force(self, h: str, alpha: str) -> None:
        """Take the trial's midpoint pass and dx1/dα = h² (F(x_m) − F0)/m (RMS per DOF) for the next."""
        self._add_trial_midpoint_force(h, alpha)
        self._add_sum("sum_sensitivity2", f"({h}*{h}*(fmid - fstart)/m)^2")
        self.addComputeGlobal("x1_sensitivity", "sqrt(sum_sensitivity2/max(ndof, 1))")

    def _add_order4_trial_end(self) -> None:
        """End a trial: after the last sub-step, or after the middle one for a short trial.

        A new trial restarts the middle sub-step. It keeps the last midpoint force
        where the change it makes to the solve stays below ``midpoint_tolerance``:
        the new α moves x1 by |Δα| dx1/dα, the midpoint by half that, and the
        midpoint force by at most ω² times it, (hω)² < 4 on a stable sub-step, so the
        stale force changes x1 by less than 2 |α| |Δα| dx1/dα, added to the change
        the last midpoint force made (``midpoint_change``). The α = 0 trial
        (:meth:`_add_trial_end`) is a full trial without a midpoint force, and the
        controller's records are left as the α trials left them.
        """
        self.addComputeGlobal("zero_done", "zero_trial")
        self.addComputeGlobal("full_trial", f"step(phase - {self._composition.stages}.5)")
        self.beginIfBlock("zero_done < 0.5")
        self._add_last_substep_fit()
        self.addComputeGlobal(
            "last_substep_change",
            "select(full_trial, substep_energy - middle_end_energy, last_substep_change)",
        )
        self.addComputeGlobal("short_residual", "residual")
        # a completed short trial measures the slope against the latest full trial: both measured
        self.addComputeGlobal("residual_last", "select(completing, residual_full, residual_last)")
        self.addComputeGlobal("alpha_last", "select(completing, alpha_full, alpha_last)")
        self.endBlock()
        self._add_trial_end(
            next_start={"x0": "xa", "v0": "va", "fstart": "fa"},
            residual="substep_energy - reference_energy"
            " + (1 - full_trial)*(last_substep_change + last_substep_slope*(alpha - alpha_full))",
            full_trial="full_trial",
        )
        self.beginIfBlock("zero_done < 0.5")
        self.addComputeGlobal("alpha_full", "select(full_trial, alpha_last, alpha_full)")
        self.addComputeGlobal("residual_full", "select(full_trial, residual, residual_full)")
        # a completed short trial: how far its predicted residual was from the measured one
        self.addComputeGlobal("short_trials_completed", "short_trials_completed + completing")
        self.addComputeGlobal(
            "sum_short_error_squared", "sum_short_error_squared + completing*(residual - short_residual)^2"
        )
        self.addComputeGlobal("completing", "(1 - full_trial)*(1 - restarting)")
        self.addComputeGlobal(
            "stale_midpoint_change", "2*abs(alpha*(alpha - alpha_last))*x1_sensitivity*restarting"
        )
        self.addComputeGlobal(
            "reuse_midpoint",
            "restarting*(1 - zero_trial)*short_trials*use_prediction"
            "*step(midpoint_tolerance - midpoint_change - stale_midpoint_change)",
        )
        self.addComputeGlobal("need_midpoint", "restarting*(1 - zero_trial)*(1 - reuse_midpoint)")
        self.addComputeGlobal("midpoint_change", "midpoint_change + reuse_midpoint*stale_midpoint_change")
        self.addComputeGlobal("midpoints_reused", "midpoints_reused + reuse_midpoint")
        self.addComputeGlobal(
            "virtual_trial", "restarting*(1 - zero_trial)*short_trials*use_prediction*(1 - midpoint_failed)"
        )
        self.endBlock()
        self.addComputeGlobal("trial_ready", "0")
        first = self._composition.first_alpha_stage
        self.addComputeGlobal("phase", f"select(restarting, {first}, phase)")
        self.addComputeGlobal("hsub", f"select(restarting, {_substep_h(self._composition, first)}, hsub)")
        self.addComputeGlobal("alpha_sub", "alpha*restarting")

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

    def _add_trial_midpoint_force(self, h: str, alpha: str) -> None:
        """One pass of the midpoint block: the controller converges the midpoint along with α.

        Like :meth:`~.pieces._StepProgram._add_midpoint_force` but without its
        stopping test (``need_midpoint`` = 0 after one force); and when ``restarting``
        is set (a new trial of α), x1 is first solved again from x0 with the new α and
        the previous midpoint force.
        """
        self._add_midpoint_reference()
        self.addComputePerDof("x", f"select(restarting, x0 + {h}*v0 + {h}*{h}*({first_forces(alpha)})/m, x0)")
        self.addConstrainPositions()
        self.addComputePerDof("x1", "select(restarting, x, x1)")
        self.addComputeGlobal("restarting", "0")
        self.addComputePerDof("x", "x0")  # the reference of the next solve again (Reference/CPU)
        self.addConstrainPositions()
        self._add_midpoint_evaluation(h, alpha)
        self.addComputeGlobal("need_midpoint", "0")

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
    def _set_system_defaults(self, periodic: bool) -> None:
        """Set the midpoint tolerance for the system's box, unless the user chose one.

        With a periodic box angular momentum is not conserved by any integrator and the
        order's default stands. Without one (a cluster or molecule in vacuum) the
        midpoint is iterated to :data:`NON_PERIODIC_MIDPOINT_TOLERANCE`, which keeps
        angular momentum to round-off, at more midpoint forces per step.
        """
        if not periodic and self.getGlobalVariableByName("midpoint_tolerance_automatic"):
            self.setGlobalVariableByName("midpoint_tolerance", NON_PERIODIC_MIDPOINT_TOLERANCE)

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
        base = "RATTLE" if self.order == 2 else f"the {self.composition.name} composition of RATTLE steps"
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

    def _check_system(self, context: mm.Context) -> None:
        """Set the tolerances for the System and platform, and give the System's warnings."""
        super()._check_system(context)
        self._set_system_defaults(context.getSystem().usesPeriodicBoundaryConditions())
