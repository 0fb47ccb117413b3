"""The energy-preserving mode of α-RATTLE: the step programs of the α* controller.

Each step chooses α so that the total energy after the step equals the reference
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
   (:meth:`EnergyControllerProgram._add_alpha_prediction`): the step's energy change
   at α = 0 and its slope S, fitted step by step as AR(2) series, give the α that
   should land on E_ref; most steps on a water box need no second trial. The
   second trial starts from the predicted slope and moves α by at least
   ``alpha_probe`` so that the step measures its own slope (at a bound, where that
   move would leave the interval, it probes inwards). Every move is limited to
   ``max_alpha_change`` (at order 4 a limit that halves when α swings back and forth,
   see ``_add_trust_update``) and clipped to the α bounds. A new trial first solves
   x1 again with the new α and the last midpoint force, then goes on with step 2.

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

E_ref is taken from the state at the first step, after ``reset_reference_energy()``,
and when the user changed the state between steps: the positions or velocities at the
start of a step differ from those the previous step ended with *and* the total energy
differs from the one it ended with by more than max(tolerance, 1e-6 |E|). The energy
test is what tells a user's change from the common platform's reordering and
re-wrapping of atoms every 250 steps, which moves coordinates but not the energy.

:class:`EnergyControllerProgram` builds on :class:`~.midpoint.MidpointProgram` (its variables
and pieces); the mode's settings, defaults and reporting are in :mod:`~.energy_mode`. The
global variables that reporters and scripts read by name are exported as constants.
"""

from __future__ import annotations

from dataclasses import dataclass

from .base import STEP_FORCE_EVALUATIONS
from .midpoint import ALPHA, MIDDLE_H, MIDPOINT_CHANGE, MidpointProgram, first_forces, last_forces

__all__ = [
    "ALPHA",
    "ALPHA_AT_BOUND",
    "FELL_BACK",
    "MIDPOINT_CHANGE",
    "REFERENCE_ENERGY",
    "RESIDUAL",
    "SLOPE",
    "SLOPE_SCALE",
    "STEP_FORCE_EVALUATIONS",
    "TRIALS",
    "ControllerSettings",
    "EnergyControllerProgram",
]

#: Names of the controller's global variables read by name from outside the program.
REFERENCE_ENERGY = "reference_energy"
RESIDUAL = "residual"
TRIALS = "trials"
FELL_BACK = "fell_back"
ALPHA_AT_BOUND = "alpha_at_bound"
SLOPE = "slope"
SLOPE_SCALE = "slope_scale"

PREDICTED_D0 = "predicted_d0"
PREDICTED_SLOPE = "predicted_slope"

#: Forgetting factor λ of the running AR(2) fits of D0 and S (an effective memory of
#: 1/(1 − λ) = 20 steps).
PREDICTOR_FORGETTING = 0.95
#: Steps with measured D0 and S before the first trial's α comes from the prediction.
PREDICTOR_WARMUP = 20
#: The series the controller predicts: D0, the one-step energy change at α = 0, and S = dH/dα.
_PREDICTED_SERIES = ("d0", "slope")
#: Each series' last two values and its exponentially weighted normal equations.
_PREDICTOR_STATE = tuple(
    f"{series}_{part}"
    for series in _PREDICTED_SERIES
    for part in ("lag1", "lag2", "g11", "g12", "g22", "b1", "b2")
)

#: Energy tolerance (kJ/mol) until the first step sets the automatic one.
PROVISIONAL_ENERGY_TOLERANCE = 0.01
#: Relative energy change between steps below which a moved state counts as the same
#: state (the common platform's reordering), unless the energy tolerance is larger.
_SAME_ENERGY = 1e-6


@dataclass(frozen=True)
class ControllerSettings:
    """The controller's validated settings; ``energy_tolerance`` in kJ/mol, None: automatic."""

    alpha_bounds: tuple[float, float]
    energy_tolerance: float | None
    max_trials: int
    max_alpha_change: float
    alpha_probe: float
    slope_damping: float
    predict: bool = True


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


class EnergyControllerProgram(MidpointProgram):
    """The α* controller's variables, pieces and step programs (orders 2 and 4)."""

    def _add_energy_mode_variables(self, settings: ControllerSettings, order: int) -> None:
        """Declare the controller's settings and state (after :meth:`_add_midpoint_variables`)."""
        low, high = settings.alpha_bounds
        automatic = settings.energy_tolerance is None
        for name, value in (
            ("alpha_min", low),
            ("alpha_max", high),
            ("energy_tolerance", PROVISIONAL_ENERGY_TOLERANCE if automatic else settings.energy_tolerance),
            ("energy_tolerance_automatic", float(automatic)),
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
            REFERENCE_ENERGY,
            "reference_set",
            "reference_resets",
            "state_moved",
            "start_energy",
            "end_energy",
            "retake",
            "retry",
            "kinetic_energy",
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
            *_PREDICTOR_STATE,
        ):
            self.addGlobalVariable(name, 0)
        self.addGlobalVariable("midpoint_tolerance_automatic", 1)  # 0: the user chose it
        for name in ("xend", "vend", "fmid_last") + (("xa", "va", "fa", "fstart_last") if order == 4 else ()):
            self.addPerDofVariable(name, 0)

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
        self._add_trial_midpoint_force("dt", "alpha")
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
        self._add_trial_midpoint_force("hsub", "alpha_sub")
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
        # H − E_ref at the step's start is end_energy − E_ref (zero after a retake)
        self.addComputeGlobal("end_energy", "select(retake, start_energy, end_energy)")
        for name in ("predictor_steps", *_PREDICTOR_STATE):
            self.addComputeGlobal(name, f"{name}*(1 - retake)")
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
        self._add_alpha_prediction()

    def _add_alpha_prediction(self) -> None:
        """Predict the first trial's α from the step's predicted D0 and S (after the warm-up).

        H − E_ref after a step taken with α is, to first order in α,
        r = r_start + D0 + α S: r_start the residual the step starts with, D0 the
        step's energy change at α = 0, S = dH/dα. Both D0 and S oscillate smoothly
        from step to step; each is predicted by an AR(2) model, x_n ≈ a1 x_{n−1} + a2
        x_{n−2}, fitted by exponentially weighted least squares (forgetting factor
        ``predictor_forgetting``, a ridge of 1 % of the mean diagonal) over the
        steps so far. The first trial then takes the damped Newton α for the
        predicted r, within ``trust`` of the last α* and the bounds, and the second
        trial (if any) starts from the predicted slope. Before ``predictor_warmup``
        steps with a measured S the first trial keeps the last α*.
        """
        self.addComputeGlobal("start_residual", "end_energy - reference_energy")
        for series, variable in zip(_PREDICTED_SERIES, (PREDICTED_D0, PREDICTED_SLOPE)):
            self.addComputeGlobal(variable, _ar2_prediction(series))
        self.addComputeGlobal("use_prediction", "step(predictor_steps - predictor_warmup + 0.5)")
        self.addComputeGlobal(
            "alpha",
            "select(use_prediction, min(max(limited, alpha_min), alpha_max), alpha);"
            "limited = min(max(newton, alpha_start - trust), alpha_start + trust);"
            "newton = -(start_residual + predicted_d0)*predicted_slope"
            "/(predicted_slope^2 + (slope_damping*slope_scale)^2 + 1e-30)",
        )
        self.addComputeGlobal("slope", "select(use_prediction, predicted_slope, slope)")
        self.addComputeGlobal("first_alpha", "alpha")

    def _add_trial_midpoint_force(self, h: str, alpha: str) -> None:
        """One pass of the midpoint block: the controller converges the midpoint along with α.

        Like :meth:`~.midpoint.MidpointProgram._add_midpoint_force` but without its
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

    def _add_trial_end(self, next_start: dict[str, str]) -> None:
        """Residual of the trial, the next α, and either the end of the step or a new trial.

        A new trial restarts the α sub-step from ``next_start`` (the state after the
        first sub-step at order 4) and goes straight to its midpoint block, which
        solves x1 with the new α before taking the midpoint force.
        """
        self._add_sum("kinetic_energy", "0.5*m*v*v")
        self.addComputeGlobal("residual", "energy + kinetic_energy - reference_energy")
        self.addComputeGlobal("trials", "trials + 1")
        self.addComputeGlobal("first_residual", "select(delta(trials - 1), residual, first_residual)")
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
        # every step's H − E_ref, for the run's RMS and maximum without reading the state each step
        self.addComputeGlobal("sum_residual_squared", "sum_residual_squared + residual^2")
        self.addComputeGlobal("max_abs_residual", "max(max_abs_residual, abs(residual))")
        self._add_slope_scale_update()
        self._add_predictor_update()
        self.addComputeGlobal("predictor_valid", "1 - midpoint_failed")

    def _add_predictor_update(self) -> None:
        """Add the step's D0 and S to the AR(2) fits (not after a rejected step).

        S is the in-step secant slope when the step took a second trial, else the
        slope the step assumed (the prediction; during the warm-up the last
        measured one); D0 = r₁ − r_start − α₁ S from the first trial's residual r₁.
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
