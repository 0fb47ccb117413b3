"""Record the order-4 energy mode's controller globals after every step on a named system (CPU).

Usage: python tools/scripts/energy_mode_step_record.py SYSTEM STEPS OUT.npy [MIDPOINT_TOLERANCE_NM]

Writes an array with one row per step and the columns of ``NAMES`` (saved every 100
steps, so an interrupted run leaves what it did). The numbers of docs/research/one_trial_per_step.md,
"Villin's excursions, step by step".
"""

import sys
import time

import numpy as np
import openmm as mm
import openmm.unit as u

from openmm_alphaprk import AlphaRattleIntegrator
from openmm_alphaprk.integrators import check_context
from openmm_alphaprk.systems import prepare_system

NAMES = (
    "residual start_residual first_residual first_alpha alpha alpha_start trials fell_back predicted_d0 "
    "predicted_slope slope slope_measured slope_scale trust use_prediction midpoint_iterations "
    "midpoint_change step_force_evaluations energy_tolerance midpoint_failed "
    "alpha_typical slope_authority probe_size restored_best residual_best"
).split()


def main() -> None:
    name, steps, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    tolerance = float(sys.argv[4]) if len(sys.argv) > 4 else None
    prepared = prepare_system(name)
    integrator = AlphaRattleIntegrator(
        2 * u.femtosecond, alpha="energy", order=4, midpoint_tolerance=tolerance
    )
    context = mm.Context(prepared.system, integrator, mm.Platform.getPlatformByName("CPU"))
    check_context(integrator, context)
    context.setPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
    context.setPositions(prepared.positions)
    context.setVelocities(prepared.velocities)
    rows, start = [], time.time()
    for step in range(1, steps + 1):
        integrator.step(1)
        rows.append([integrator.getGlobalVariableByName(n) for n in NAMES])
        if step % 100 == 0 or step == steps:
            np.save(out, np.array(rows))
            print(f"{step} steps, {time.time() - start:.0f} s", flush=True)


if __name__ == "__main__":
    main()
