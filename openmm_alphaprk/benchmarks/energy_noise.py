"""Noise of OpenMM's potential energy by platform and precision (the energy mode's tolerance).

For each box size, ten states from a short Langevin run are evaluated on every
platform/precision given and on a reference (double precision); the standard
deviation of the difference is the noise the energy mode's tolerance must sit above
(:func:`openmm_alphaprk.platforms.energy_noise` models it). Example (CUDA)::

    python -m openmm_alphaprk.benchmarks.energy_noise --boxes 3 6 9 --reference CUDA:double \
        --platforms CUDA:single CUDA:mixed --json noise.json
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import openmm as mm
import openmm.unit as unit

from openmm_alphaprk.platforms import default_energy_tolerance, energy_noise
from openmm_alphaprk.systems import build_water_box


def _platform(spec: str) -> tuple[mm.Platform, dict[str, str]]:
    name, _, precision = spec.partition(":")
    return mm.Platform.getPlatformByName(name), ({"Precision": precision} if precision else {})


def potential_energies(system: mm.System, states: list, spec: str) -> np.ndarray:
    """Potential energies (kJ/mol) of ``states`` on the platform ``NAME[:precision]``."""
    platform, properties = _platform(spec)
    context = mm.Context(system, mm.VerletIntegrator(0.001), platform, properties)
    energies = []
    for positions in states:
        context.setPositions(positions)
        energies.append(context.getState(getEnergy=True).getPotentialEnergy())
    return np.array([e.value_in_unit(unit.kilojoules_per_mole) for e in energies])


def measure(edge: float, specs: list[str], reference: str, build_platform: str) -> dict:
    """Noise of each platform spec against ``reference`` on a TIP3P box of edge ``edge`` nm."""
    box = build_water_box(
        edge, cutoff=min(0.9, edge / 2 - 0.05), equilibration_steps=200, platform=build_platform
    )
    platform, properties = _platform(build_platform)
    integrator = mm.LangevinMiddleIntegrator(300, 5, 0.002)
    context = mm.Context(box.system, integrator, platform, properties)
    context.setPositions(box.positions)
    context.setVelocities(box.velocities)
    states = []
    for _ in range(10):
        integrator.step(50)
        states.append(context.getState(getPositions=True).getPositions(asNumpy=True))
    exact = potential_energies(box.system, states, reference)
    result = {"atoms": box.n_atoms, "edge_nm": edge, "reference": reference, "std": {}}
    for spec in specs:
        difference = potential_energies(box.system, states, spec) - exact
        result["std"][spec] = float(np.std(difference))
        precision = spec.partition(":")[2] or ("double" if spec == "Reference" else "mixed")
        print(
            f"{box.n_atoms:>7} atoms  {spec:<14} std {np.std(difference):.2e} kJ/mol  "
            f"(model {energy_noise(box.n_atoms, precision):.2e}, default tolerance "
            f"{default_energy_tolerance(box.n_atoms, precision):.2e})",
            flush=True,
        )
    return result


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--boxes", type=float, nargs="+", default=[1.8, 3.0], help="box edges in nm")
    parser.add_argument("--platforms", nargs="+", default=["CPU", "OpenCL:mixed", "OpenCL:single"])
    parser.add_argument("--reference", default="Reference", help="NAME[:precision] taken as exact")
    parser.add_argument("--build-platform", default="CPU", help="NAME[:precision] for set-up and states")
    parser.add_argument("--json", help="write the results to this file")
    args = parser.parse_args(argv)
    results = [measure(edge, args.platforms, args.reference, args.build_platform) for edge in args.boxes]
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(results, handle, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
