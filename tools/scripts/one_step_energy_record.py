"""Record, step by step, D0 (one-step energy change of triple-jump RATTLE) and S = dH/dα of α-RATTLE-4.

Usage: python tools/scripts/one_step_energy_record.py SYSTEM STEPS OUT.npy [DELTA]

Along the α = 0 (triple-jump RATTLE) trajectory of SYSTEM (a name of `alphaprk systems`)
from its cached start, CPU platform, 2 fs: before every step the state is copied into a
second context whose α-RATTLE-4 has the fixed α = DELTA (default 0.02, converged
midpoint); both take one step. Saved per step: H before the step, D0 = H(α = 0 step) −
H before, and S = (H(α = DELTA step) − H(α = 0 step)) / DELTA. These are the numbers of
docs/research/one_trial_per_step.md, "One trial per step". tools/scripts/controller_offline.py replays
controllers on them.
"""

import sys
import time

import numpy as np
import openmm as mm
import openmm.unit as unit

from openmm_alphaprk import AlphaRattleIntegrator
from openmm_alphaprk.observables import total_energy
from openmm_alphaprk.systems import prepare_system


def main() -> None:
    name, steps, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    delta = float(sys.argv[4]) if len(sys.argv) > 4 else 0.02
    prepared = prepare_system(name)
    platform = mm.Platform.getPlatformByName("CPU")

    def context(integrator):
        c = mm.Context(prepared.system, integrator, platform)
        c.setPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
        c.setPositions(prepared.positions)
        c.setVelocities(prepared.velocities)
        return c

    main = AlphaRattleIntegrator(2 * unit.femtoseconds, alpha=0.0, order=4)
    probe = AlphaRattleIntegrator(2 * unit.femtoseconds, alpha=delta, order=4)
    main_context, probe_context = context(main), context(probe)
    rows, start = [], time.time()
    for n in range(steps):
        state = main_context.getState(getPositions=True, getVelocities=True, getEnergy=True)
        before = total_energy(state)
        probe_context.setState(state)
        probe.step(1)
        main.step(1)
        after = total_energy(main_context)
        rows.append([before, after - before, (total_energy(probe_context) - after) / delta])
        if n % 100 == 0:
            print(f"step {n}, {time.time() - start:.0f} s", flush=True)
    rows = np.array(rows)
    np.save(out, rows)
    d0_rms, s_rms = np.sqrt(np.mean(rows[:, 1:] ** 2, axis=0))
    print(f"{name}: D0 RMS {d0_rms:.4g} kJ/mol, S RMS {s_rms:.4g}")


if __name__ == "__main__":
    main()
