"""Hunt for starts on which α-RATTLE-4's energy mode degrades on a platform; keep every start.

Usage: python tools/scripts/energy_mode_start_hunt.py FIRST_SEED LAST_SEED PLATFORM[:precision] OUT_DIR

For each seed: a 1.7 nm TIP3P box (PME 0.8 nm, LJ switched from 0.7 nm, Ewald 1e-5),
500 Langevin steps on the CPU (build_water_box), its start saved as OpenMM State XML in
OUT_DIR, then 600 steps of α-RATTLE-4's energy mode on PLATFORM with the energy read every
10 steps. A run above 0.02 kJ/mol RMS is repeated from the saved start on the same
platform, on the CPU and on the platform in double precision (race or start?).
docs/research/one_trial_per_step.md, "The intermittent OpenCL (pocl) failure", has the numbers.
"""

import sys
from pathlib import Path

import numpy as np
import openmm as mm
import openmm.unit as unit

from openmm_alphaprk import AlphaRattleIntegrator
from openmm_alphaprk.observables import total_energy
from openmm_alphaprk.systems import build_water_box


def main() -> None:
    first, last, platform_spec, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], Path(sys.argv[4])
    out.mkdir(parents=True, exist_ok=True)

    def run(box, spec: str) -> tuple[float, float]:
        name, _, precision = spec.partition(":")
        integrator = AlphaRattleIntegrator(2 * unit.femtoseconds, "energy", order=4)
        properties = {"Precision": precision} if precision else {}
        context = mm.Context(box.system, integrator, mm.Platform.getPlatformByName(name), properties)
        context.setPeriodicBoxVectors(*box.state.getPeriodicBoxVectors())
        context.setPositions(box.positions)
        context.setVelocities(box.velocities)
        start = total_energy(context)
        residuals = []
        for _ in range(60):
            integrator.step(10)
            residuals.append(total_energy(context) - start)
        fell_back = integrator.controller_totals()["fraction_fallen_back"]
        return float(np.sqrt(np.mean(np.square(residuals)))), fell_back

    for seed in range(first, last + 1):
        box = build_water_box(1.7, cutoff=0.8, equilibration_steps=500, seed=seed, platform="CPU")
        (out / f"start_{seed}.xml").write_text(mm.XmlSerializer.serialize(box.state), encoding="utf-8")
        rms, fell_back = run(box, platform_spec)
        print(f"seed {seed} {platform_spec}: RMS {rms:.4f} kJ/mol, fell back {fell_back:.2f}", flush=True)
        if rms > 0.02:
            for spec in (platform_spec, "CPU", platform_spec.partition(":")[0] + ":double"):
                rms, fell_back = run(box, spec)
                print(f"  same start, {spec}: RMS {rms:.4f} kJ/mol, fell back {fell_back:.2f}", flush=True)


if __name__ == "__main__":
    main()
