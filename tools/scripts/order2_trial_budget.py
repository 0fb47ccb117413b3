"""The order-2 energy mode with its trials capped, against RATTLE, on a named system (CPU).

Usage: python tools/scripts/order2_trial_budget.py SYSTEM STEPS OUT.json [MAX_TRIALS ...]

Runs RATTLE, then the order-2 energy mode with each ``max_trials`` given (default 2 3),
every run from the system's shipped start for STEPS steps of 2 fs, H − E_ref read after
every step; writes RMS, max, the drift (kJ/mol per step, line fit), force evaluations
per step and the controller totals to OUT.json after each run. The numbers of
docs/research/one_trial_per_step.md "Order 2 at a budget of 4 evaluations" (there with 1 2 3; one trial
is now refused).
"""

import json
import sys

import numpy as np
import openmm as mm
import openmm.unit as u

from openmm_alphaprk import AlphaRattleIntegrator, RattleIntegrator
from openmm_alphaprk.integrators import check_context
from openmm_alphaprk.observables import energy_residuals, rms
from openmm_alphaprk.systems import prepare_system


def main() -> None:
    name, steps, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    caps = [int(a) for a in sys.argv[4:]] or [2, 3]
    prepared = prepare_system(name)
    rows = {}

    def run(label: str, integrator: mm.Integrator) -> None:
        context = mm.Context(prepared.system, integrator, mm.Platform.getPlatformByName("CPU"))
        if isinstance(integrator, AlphaRattleIntegrator):
            check_context(integrator, context)
        context.setPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
        context.setPositions(prepared.positions)
        context.setVelocities(prepared.velocities)
        residuals = energy_residuals(context, integrator, steps).residuals
        totals = integrator.controller_totals() if isinstance(integrator, AlphaRattleIntegrator) else {}
        rows[label] = {
            "rms": float(rms(residuals)),
            "max": float(np.abs(residuals).max()),
            "drift_per_step": float(np.polyfit(np.arange(len(residuals)), residuals, 1)[0]),
            "force_evaluations_per_step": float(totals.get("force_evaluations_per_step", 1.0)),
            "totals": {k: float(v) for k, v in totals.items()},
        }
        print(label, rows[label]["rms"], rows[label]["force_evaluations_per_step"], flush=True)
        with open(out, "w") as file:
            json.dump(rows, file, indent=1)

    run("rattle", RattleIntegrator(2 * u.femtosecond))
    for cap in caps:
        energy_mode = AlphaRattleIntegrator(2 * u.femtosecond, alpha="energy", order=2, max_trials=cap)
        run(f"max_trials={cap}", energy_mode)


if __name__ == "__main__":
    main()
