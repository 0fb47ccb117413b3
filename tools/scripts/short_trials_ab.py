"""Run α-RATTLE-4's energy mode with short trials on or off, from a shipped start, and print its totals.

Usage: python tools/scripts/short_trials_ab.py SYSTEM STEPS SHORT(1/0) [MAX_TRIALS] [PLATFORM] [TOLERANCE]
(the numbers of docs/research/short_trials.md; MAX_TRIALS: default the order-4 default,
"-" for it; PLATFORM: default CPU; TOLERANCE: energy tolerance in kJ/mol, default automatic).
SHORT=0 makes every trial full (the global ``short_trials``).
"""

import sys
import time

import numpy as np
import openmm as mm
import openmm.unit as u

from openmm_alphaprk import AlphaRattleIntegrator
from openmm_alphaprk.integrators import check_context
from openmm_alphaprk.systems.cache import prepare_system


def main() -> None:
    name, steps, short = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    max_trials = int(sys.argv[4]) if len(sys.argv) > 4 and sys.argv[4] != "-" else None
    platform = sys.argv[5] if len(sys.argv) > 5 else "CPU"
    tolerance = float(sys.argv[6]) if len(sys.argv) > 6 else None
    prepared = prepare_system(name)
    integrator = AlphaRattleIntegrator(
        2 * u.femtosecond, alpha="energy", order=4, max_trials=max_trials, energy_tolerance=tolerance
    )
    integrator.setGlobalVariableByName("short_trials", short)
    context = mm.Context(prepared.system, integrator, mm.Platform.getPlatformByName(platform))
    check_context(integrator, context)
    context.setPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
    context.setPositions(prepared.positions)
    context.setVelocities(prepared.velocities)
    value = integrator.getGlobalVariableByName
    residuals, trials = [], []
    start = time.time()
    for _ in range(steps):
        integrator.step(1)
        residuals.append(value("residual"))
        trials.append(value("trials"))
    residuals, trials = np.array(residuals), np.array(trials)
    rms, rms_after_100 = np.sqrt(np.mean(residuals**2)), np.sqrt(np.mean(residuals[100:] ** 2))
    totals = integrator.controller_totals()
    print(
        f"{name} short={short:g} max_trials={int(value('max_trials'))} "
        f"tolerance={value('energy_tolerance'):.4g} steps={steps} "
        f"RMS={rms:.4g} (after step 100: {rms_after_100:.4g}) "
        f"max={np.abs(residuals).max():.3g} evaluations/step={integrator.force_evaluations_per_step:.3f} "
        f"trials 1/2/3+={np.mean(trials == 1):.2f}/{np.mean(trials == 2):.2f}/{np.mean(trials >= 3):.2f} "
        f"short completed={totals['short_trials_completed']} midpoints reused={totals['midpoints_reused']} "
        f"short-trial error={totals['rms_short_trial_error']:.3g} c={value('last_substep_slope'):.3g} "
        f"restored={totals['steps_restored']} fell back={totals['steps_fallen_back']} "
        f"{time.time() - start:.0f} s"
    )


if __name__ == "__main__":
    main()
