"""What each variable of the energy mode's step programs means, by the stage of the step that owns it.

Hand-written (:mod:`tools.reports.energy_program` adds who writes each; tests/test_energy_program.py
checks that every variable has exactly one entry). A name may stand for several variables:
``<i>`` for a stage number of the composition, ``<series>`` for ``d0`` or ``slope``.
"""

from __future__ import annotations

#: What a placeholder of a name stands for (a regular expression).
PLACEHOLDERS = {"<i>": r"[0-9]+", "<series>": r"d0|slope"}

#: The stages of a step, in the order the program runs them, and what happens in each.
STAGES = {
    "Frame": (
        "What every program of the package has: the counters, the system check at the first step "
        "of each `step()` call, and the composition's record."
    ),
    "Settings": (
        "Read by the program, written only from Python: the constructor's arguments, their setters, "
        "and the defaults that `check_context()` and `step()` choose for the System and platform."
    ),
    "Reference energy": (
        "At the step's start: is E_ref taken (again)? The rule of `reference_energy.py`, shared with "
        "RATTLE + rescaling; a retake also forgets the predictor."
    ),
    "Predictor": (
        "Before the first trial: the α it takes. The step's energy change at α = 0 (D0) and its slope "
        "S = dH/dα are predicted by AR(2) fits over past steps; the fits are updated at the step's end."
    ),
    "Trial loop": (
        "The `while` loop: each pass solves the positions, takes a midpoint force or ends a trial; "
        "the flags that say which comes next and when the step ends."
    ),
    "Midpoint iteration": (
        "The midpoint force F(x_m), x_m = (x0 + x1)/2, converged along with α: one midpoint force per "
        "trial, and whether a new trial may keep the last one."
    ),
    "Short trials (order 4)": (
        "After the warm-up a trial after the first redoes only the α stage and predicts the later "
        "stages' energy change from the step's full trials; once α stops the later stages are taken "
        "(the trial is completed)."
    ),
    "Secant update": (
        "At each trial's end: the slope, the next α by the damped secant step, and the move limit."
    ),
    "Fallback and best trial": (
        "How the step ended: within the tolerance; or, where the α trials could not hold it, as the "
        "α = 0 step (a fallback) or in its best α trial where that ended closer to E_ref; α at a bound."
    ),
    "Bookkeeping": (
        "Totals over every step since the integrator was made (`controller_totals()`), kept inside the "
        "program so that a reporter need not read the state every step."
    ),
}

#: For each stage, its globals and what each means (units where it has them).
MEANINGS = {
    "Frame": {
        "alphaprk_kind": "Which of the package's integrators the program is (read by `restore_integrator` "
        "after an `XmlSerializer` round trip).",
        "steps_taken": "Steps taken since the integrator was made.",
        "force_evaluations": "Force evaluations since the integrator was made.",
        "step_force_evaluations": "Force evaluations of the step (of the last step, between steps); "
        "the restore of a best trial counts one.",
        "host_syncs": "Sums over degrees of freedom taken since the integrator was made: on CUDA, OpenCL "
        "and HIP each is a synchronisation of the device with the host.",
        "n_particles": "Particles of the System the integrator was first bound to (with or without mass).",
        "check_system": "What the system check at the next step does: 0 nothing, 1 check and refuse "
        "particles without mass, 2 check and allow them.",
        "ndof": "Degrees of freedom the program moves: 3 × the particles with mass (counted by the "
        "system check).",
        "refused": "1 if the system check refused the step, which then does nothing.",
        "order": "The order of the method: 2 (one α-RATTLE step) or the composition's (4, 6).",
        "stage_coefficient_<i>": "c_i, stage i's share of the step (it is a step of c_i h); read back by "
        "`composition`.",
        "alpha_on_stage_<i>": "1 if stage i of the composition carries α.",
    },
    "Settings": {
        "alpha_min": "Lower bound of α (`alpha_bounds`).",
        "alpha_max": "Upper bound of α (`alpha_bounds`).",
        "max_trials": "Trials per step that may move α (at least 2).",
        "max_alpha_change": "The largest move of α by one secant update; the move limit `trust` never "
        "exceeds it.",
        "alpha_probe": "The smallest first move of α in a step, so that the step measures its own slope.",
        "slope_damping": "d in the damped secant step Δα = −r S/(S² + (d S̄)²).",
        "predictor_forgetting": "λ, the forgetting factor of the predictor's weighted fits and of the "
        "short trials' fit of c (0.95: a memory of about 20 steps).",
        "predictor_warmup": "Steps with a slope (measured or predicted) after which the first trial's α "
        "is predicted; 1e30 where prediction is off.",
        "energy_tolerance": "Target |H − E_ref| after a step (kJ/mol); also the test of a state changed "
        "between steps.",
        "energy_tolerance_automatic": "1 while the energy tolerance is the default, which `check_context()` "
        "and `step()` set for the System's size and the platform's precision; 0 once the user set one.",
        "midpoint_tolerance": "Stopping tolerance of the midpoint iteration: the largest change a "
        "midpoint force may make to x1 for it to count as converged (nm, RMS per degree of freedom).",
        "midpoint_tolerance_automatic": "1 while the midpoint tolerance is the default, which "
        "`check_context()` tightens to 1e-13 nm for a System without a periodic box.",
        "max_midpoint_iterations": "Cap on the midpoint forces of a step, over all its trials.",
        "short_trials": "1 lets a trial after the first be short; 0 makes every trial full (for "
        "measurements).",
    },
    "Reference energy": {
        "reference_energy": "E_ref, the total energy the integrator holds (kJ/mol).",
        "reference_set": "0 until E_ref is taken, and after `reset_reference_energy()`; then 1.",
        "state_moved": "Σ (x − xend)² + (v − vend)² over degrees of freedom at the first step of a "
        "`step()` call: 0 when nothing changed the state since the last step (nm², (nm/ps)²); set "
        "to 0 again once the reference check's block has looked at it.",
        "state_check": "1 at the first step of a `step()` call (set by `step()`): the step compares "
        "its start with the last step's end; the program sets it to 1 − `driven`.",
        "driven": "1 while this package's `step()` runs the program, 0 between calls: a copy no "
        "`step()` drives keeps `state_check` at 1 and compares at every step.",
        "start_energy": "Total energy at the step's start, taken when the state moved (kJ/mol).",
        "retake": "1 if this step takes E_ref again: the first step, after a reset, or a state set "
        "between steps whose energy differs from `end_energy` by more than max(tolerance, 1e-6 |E|).",
        "end_energy": "Total energy the last step ended with, E_ref + `residual` (kJ/mol); the start "
        "energy after a retake.",
        "reference_resets": "Times E_ref was taken (count).",
    },
    "Predictor": {
        "alpha_start": "α at the step's start (the last step's α*): a rejected step ends with it; the "
        "step's move of α is `alpha` − `alpha_start`.",
        "start_residual": "H − E_ref the step starts with, `end_energy` − E_ref (kJ/mol).",
        "predicted_d0": "D0 predicted for this step: its energy change at α = 0 (kJ/mol).",
        "predicted_slope": "S = dH/dα predicted for this step (kJ/mol per unit α).",
        "use_prediction": "1 once `predictor_steps` reached `predictor_warmup`: the first trial's α, "
        "the probe and the damping use the prediction; short trials are allowed.",
        "alpha_typical": "ᾱ = −Σλ D0 S / Σλ S², the fixed α that would have held the energy best over "
        "past steps; the first trial's Newton step starts from it.",
        "slope_authority": "S_typ = (Σ(1−λ)λ S²)^½, the typical slope of past steps (kJ/mol per unit α).",
        "probe_size": "The step's probe, the smallest first move of α: min(`alpha_probe`, `trust`), after "
        "the warm-up also at most 2 · tolerance/S_typ.",
        "first_alpha": "α of the step's first trial.",
        "first_residual": "H − E_ref after the step's first trial (kJ/mol): D0 = r₁ − r_start − α₁ S.",
        "predictor_steps": "Steps that fed the predictor (with a measured or predicted slope) since E_ref "
        "was last taken (count).",
        "predictor_valid": "1 if the last step was accepted and E_ref not taken again since: its midpoint "
        "force seeds this step's (`fmid_last`).",
        "<series>_lag1": "The series' value at the last step (D0 in kJ/mol, S in kJ/mol per unit α).",
        "<series>_lag2": "Its value the step before.",
        "<series>_g11": "Σλ lag1², of the AR(2) fit's normal equations (exponentially weighted).",
        "<series>_g12": "Σλ lag1 · lag2, of the normal equations.",
        "<series>_g22": "Σλ lag2², of the normal equations.",
        "<series>_b1": "Σλ lag1 · x (x the value that followed), right-hand side of the normal equations.",
        "<series>_b2": "Σλ lag2 · x, right-hand side of the normal equations.",
        "fit_d0_slope": "Σλ D0 S, the numerator of ᾱ.",
        "fit_slope_slope": "Σλ S², the denominator of ᾱ and the sum behind S_typ.",
    },
    "Trial loop": {
        "solving": "Order 2: 1 while the loop goes on.",
        "phase": "The stage of the composition the loop is in (1, 2, …); the loop ends after the last.",
        "hsub": "The step size of the current stage, c_phase h (ps).",
        "alpha_sub": "The α of the current stage: `alpha` on the α stage, 0 on the others.",
        "substep_done": "1 when the stage's last position solve is taken (no midpoint force pending): "
        "its velocity update follows.",
        "alpha": "α of the current trial; after the step, α* of the step, where the next step starts "
        "(the user may set it between steps).",
        "kinetic_energy": "K = Σ ½ m v² at the last sum (kJ/mol): at the reference check, and at a "
        "trial's end (order 2) or a stage's end (order 4).",
        "residual": "r = H − E_ref after the current trial (kJ/mol; predicted for a short trial); "
        "after the step, the step's.",
        "trials": "Trials of α in this step (a completed short trial is not counted again).",
        "controller_done": "1 when the trial ending now is the step's last: α stopped and the midpoint "
        "converged, the midpoint forces ran out, the residual is not finite, or the midpoint failed.",
        "zero_trial": "1 once the α trials could not hold the step (the controller stopped on a full "
        "trial outside the tolerance, or the midpoint failed; order 2: and the trial neither ended "
        "closer to E_ref than the α = 0 step, estimated on the secant, nor moved `residual_mean` towards "
        "0): the next pass is the α = 0 trial, the base's step without a midpoint force, which ends the "
        "step; after the step, 1 if the step is that α = 0 step.",
        "zero_done": "The value of `zero_trial` when the trial ending now started: 1 at the α = 0 trial's "
        "end, which leaves the controller's records as they were.",
        "restarting": "1 when a new trial starts: its first midpoint pass solves x1 again with the new α.",
        "completing": "Order 4: 1 for the pass that takes the later stages at the α a short trial "
        "stopped at (its measured residual decides whether the step ends).",
    },
    "Midpoint iteration": {
        "need_midpoint": "1 when the next pass takes a midpoint force.",
        "midpoint_iterations": "Midpoint forces taken in this step, over all its trials (count).",
        "midpoint_change": "The change the last midpoint force made to x1, h²|α ΔF|/m (nm, RMS per "
        "degree of freedom); a kept midpoint force adds its bound `stale_midpoint_change`.",
        "previous_midpoint_change": "The change before it (nm; 1e30 at a new trial or stage).",
        "sum_change2": "Σ (h² α ΔF/m)² over degrees of freedom (nm²), behind `midpoint_change`.",
        "midpoint_failed": "1 when the step's midpoint iteration failed (it stopped above the accepted "
        "change) or a residual was not finite: the step is the α = 0 trial's, and the predictor is not "
        "updated from it.",
        "x1_sensitivity": "dx1/dα = h² |F(x_m) − F0|/m of the α stage (nm per unit α, RMS per degree of "
        "freedom).",
        "sum_sensitivity2": "Σ (h² (F(x_m) − F0)/m)² over degrees of freedom (nm²), behind `x1_sensitivity`.",
        "stale_midpoint_change": "Bound on the change the last midpoint force, kept under the new α, "
        "makes to x1: 2 |α Δα| dx1/dα (nm).",
        "last_trial_change": "`midpoint_change` at the previous α trial's end (nm; 1e30 at the step's "
        "start): a change that grew fourfold at the same α, above ten times the tolerance, is a "
        "diverging midpoint iteration.",
        "reuse_midpoint": "1 if the new trial keeps the last midpoint force (a short trial whose kept "
        "force stays within `midpoint_tolerance`).",
    },
    "Short trials (order 4)": {
        "virtual_trial": "1 while the trial is short: it ends after the α stage.",
        "trial_ready": "1 when the trial's end is reached: after the last stage, or after the α stage "
        "for a short trial.",
        "full_trial": "1 if the trial ending now took every stage.",
        "substep_energy": "H at the end of the latest stage (kJ/mol).",
        "middle_end_energy": "H at the end of the α stage (kJ/mol).",
        "last_substep_change": "ΔE_last, the energy change over the stages after the α stage measured "
        "by the latest full trial (kJ/mol).",
        "paired": "1 if the full trial ending now follows another trial of its step: it measures c.",
        "last_substep_fit_cross": "Σλ (ΔE_last change) · Δα over paired trials, kept across steps.",
        "last_substep_fit_norm": "Σλ Δα² over paired trials, kept across steps.",
        "last_substep_slope": "c = d(ΔE_last)/dα (kJ/mol per unit α): a short trial at α predicts "
        "ΔE_last + c (α − α_f).",
        "alpha_full": "α_f, the α of the step's latest full trial.",
        "residual_full": "H − E_ref after the step's latest full trial (kJ/mol).",
        "short_residual": "The predicted residual of the short trial being completed (kJ/mol).",
    },
    "Secant update": {
        "slope": "S = dr/dα (kJ/mol per unit α): the secant over the step's last two trials once it "
        "measured one, else the predicted (or last) slope.",
        "slope_measured": "1 once this step measured its own slope (a secant over a move of α of at "
        "least half the probe).",
        "residual_last": "r of the previous trial, for the secant (kJ/mol; a completed short trial "
        "measures against the latest full trial).",
        "alpha_last": "α of the previous trial, for the secant.",
        "alpha_next": "α of the next trial (the same α once it stops moving), clipped to the bounds.",
        "slope_scale": "S̄, the running geometric mean of the measured |S|, the damping's scale "
        "(kJ/mol per unit α).",
        "trust": "The move limit of one secant update; order 4 halves it after a swing that missed and "
        "grows it back ×1.5, up to `max_alpha_change` (order 2: `max_alpha_change`).",
        "last_move": "Order 4: the last step's move of α, `alpha_tried` − `alpha_start`.",
        "alpha_tried": "α of the step's last α trial (before an α = 0 trial), for the move limit.",
    },
    "Fallback and best trial": {
        "fell_back": "1 if the step ended outside the energy tolerance (the α = 0 step, or the best α "
        "trial where that ended closer to E_ref).",
        "alpha_at_bound": "1 if the step's α* is at a bound.",
        "trial_better": "1 if the α trial ending now is the step's best so far (smallest |r| of the full "
        "trials whose midpoint converged and whose r is finite).",
        "best_set": "1 once the step kept a best trial.",
        "residual_best": "r of the step's best trial (kJ/mol).",
        "alpha_best": "α of the step's best trial.",
        "residual_mean": "Order 2: the running mean of H − E_ref after each step (weight "
        "`predictor_forgetting`; kJ/mol): a missed α trial kept without the α = 0 trial must move it "
        "towards 0.",
        "restored_best": "1 if a step that took its α = 0 trial ends in its best α trial's state "
        "instead, which ended strictly closer to E_ref.",
    },
    "Bookkeeping": {
        "steps_within_tolerance": "Steps that ended within the energy tolerance.",
        "steps_fallen_back": "Steps that ended outside it.",
        "steps_alpha_zero": "Steps taken at α = 0 (the base's step) because the α trials could not "
        "hold them and none ended closer to E_ref.",
        "steps_at_bound": "Steps whose α* was at a bound.",
        "steps_restored": "Steps the α trials could not hold that ended in their best α trial, "
        "closer to E_ref than the α = 0 step.",
        "midpoint_failures": "Not written by the energy mode (0): a failed midpoint iteration makes "
        "the step the α = 0 step instead of an error.",
        "sum_residual_squared": "Σ r² over the steps ((kJ/mol)²), for the RMS residual.",
        "max_abs_residual": "The largest |r| after a step (kJ/mol).",
        "midpoints_reused": "Trials that kept the last midpoint force.",
        "short_trials_completed": "Short trials whose later stages were then taken (completed).",
        "sum_short_error_squared": "Σ (measured − predicted residual)² over the completed short trials "
        "((kJ/mol)²).",
    },
}

#: The per-DOF variables of the programs (besides OpenMM's x, v, f) and what each holds.
PER_DOF_MEANINGS = {
    "x0": "Positions at the start of the current stage; at order 2, of the step (nm).",
    "v0": "Velocities there (nm/ps).",
    "fstart": "The force there, F0 (kJ/mol/nm).",
    "fmid": "The midpoint force F(x_m) of the current trial; at a step's first trial its prediction "
    "from the last step (kJ/mol/nm).",
    "x1": "The last position solve, the end positions of the α stage the midpoint is taken from (nm).",
    "fmid_last": "The last trial's midpoint force, kept for the next step's prediction (kJ/mol/nm).",
    "xend": "Positions the step ended with, for the reference check (nm).",
    "vend": "Velocities the step ended with (nm/ps).",
    "xstep": "Declared by the composition's pieces; not used by the energy mode (nm).",
    "vstep": "Declared by the composition's pieces; not used by the energy mode (nm/ps).",
    "xa": "Positions at the start of the α stage, where a new trial starts (nm).",
    "va": "Velocities there (nm/ps).",
    "fa": "The force there (kJ/mol/nm).",
    "fstart_last": "The force at the start of the last step's α stage: the midpoint force is predicted as "
    "F there plus the last step's offset `fmid_last` − `fstart_last` (kJ/mol/nm).",
    "xbest": "Positions at the end of the step's best α trial (nm).",
    "vbest": "Velocities there (nm/ps).",
}
