"""What a RATTLE step followed by velocity rescaling costs on a GPU, by the sums it needs.

Research script behind docs/platforms.md ("RATTLE + rescaling on a GPU"): plain ``CustomIntegrator``
programs, not the package's, timed against RATTLE and ``VerletIntegrator`` on the same
water box in interleaved rounds. Each variant adds to RATTLE what a rescaling step
could need; every sum over degrees of freedom and every read of ``energy`` is a
device-to-host synchronisation on CUDA, OpenCL and HIP:

- ``energy``: the potential energy read once per step (the one synchronisation no
  rescaling can avoid) and a global computed from it;
- ``K``: that and the kinetic-energy sum, then a uniform rescaling kernel;
- ``K+moved``: ``K`` and the start-of-step check that the user did not change the
  state (the energy mode's ``state_moved`` sum);
- ``K+P``: ``K`` and the three components of the linear momentum (the centre-of-mass
  velocity of the current velocities, so the rescaling keeps P exactly);
- ``K+P+moved``: both.

Usage: ``python -m openmm_alphaprk.benchmarks.rescale_sync_cost --platform CUDA --box 3 6 9``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import openmm as mm

from openmm_alphaprk.systems import build_water_box


def _rattle(integrator: mm.CustomIntegrator) -> None:
    integrator.addPerDofVariable("x0", 0)
    integrator.addComputePerDof("x0", "x")
    integrator.addComputePerDof("x", "x0 + dt*v + 0.5*dt*dt*f/m")
    integrator.addConstrainPositions()
    integrator.addComputePerDof("v", "(x - x0)/dt + 0.5*dt*f/m")
    integrator.addConstrainVelocities()


def make(variant: str, h: float) -> mm.Integrator:
    if variant == "verlet":
        return mm.VerletIntegrator(h)
    integrator = mm.CustomIntegrator(h)
    integrator.setConstraintTolerance(1e-8)
    for name in ("e_ref", "potential", "kinetic", "px", "py", "pz", "s", "moved", "mass"):
        integrator.addGlobalVariable(name, 0)
    integrator.addPerDofVariable("xend", 0)
    integrator.addPerDofVariable("vend", 0)
    if variant.endswith("moved"):
        integrator.addComputeSum("moved", "(x - xend)^2 + (v - vend)^2")
    _rattle(integrator)
    if variant == "K+moved":
        variant = "K"
        integrator.addComputePerDof("xend", "x")
        integrator.addComputePerDof("vend", "v")
    if variant == "rattle":
        return integrator
    integrator.addComputeGlobal("potential", "energy")
    if variant == "energy":
        return integrator
    integrator.addComputeSum("kinetic", "0.5*m*v*v")
    if variant == "K":
        integrator.addComputeGlobal("s", "sqrt(max((e_ref - potential)/kinetic, 0))")
        integrator.addComputePerDof("v", "v*select(e_ref, s, 1)")
        return integrator
    integrator.addGlobalVariable("total_mass", 1.0)
    for axis, vector in (("px", "1,0,0"), ("py", "0,1,0"), ("pz", "0,0,1")):
        integrator.addComputeSum(axis, f"m*v*vector({vector})")
    integrator.addComputeGlobal("s", "1")
    integrator.addComputePerDof("v", "vector(px,py,pz)/total_mass + s*(v - vector(px,py,pz)/total_mass)")
    if variant.endswith("moved"):
        integrator.addComputePerDof("xend", "x")
        integrator.addComputePerDof("vend", "v")
    return integrator


VARIANTS = ("verlet", "rattle", "energy", "K", "K+moved", "K+P", "K+P+moved")


def time_variants(box, platform: str, precision: str, steps: int, rounds: int) -> dict[str, float]:
    plat = mm.Platform.getPlatformByName(platform)
    properties = {"Precision": precision} if platform in ("CUDA", "OpenCL", "HIP") else {}
    contexts = {}
    for variant in VARIANTS:
        integrator = make(variant, 0.002)
        context = mm.Context(box.system, integrator, plat, properties)
        context.setPositions(box.positions)
        context.setVelocities(box.velocities)
        integrator.step(20)  # program analysis, kernel compilation
        context.getState(getEnergy=True)
        contexts[variant] = (context, integrator)
    times = {variant: [] for variant in VARIANTS}
    for _ in range(rounds):
        for variant, (context, integrator) in contexts.items():
            context.getState(getEnergy=True)
            start = time.perf_counter()
            integrator.step(steps)
            context.getState(getEnergy=True)  # wait for the device
            times[variant].append((time.perf_counter() - start) / steps * 1000.0)
    return {variant: statistics.median(values) for variant, values in times.items()}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platform", default="CUDA")
    parser.add_argument("--precision", default="mixed")
    parser.add_argument("--box", type=float, nargs="+", default=[3.0, 6.0, 9.0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--equilibration-steps", type=int, default=200)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    results = {}
    for edge in args.box:
        box = build_water_box(edge, equilibration_steps=args.equilibration_steps, platform=args.platform)
        medians = time_variants(box, args.platform, args.precision, args.steps, args.rounds)
        rattle = medians["rattle"]
        print(f"{edge} nm box, {box.n_atoms} atoms, {args.platform} {args.precision}:")
        for variant, ms in medians.items():
            print(f"  {variant:<10} {ms:8.4f} ms/step   {ms / rattle:6.3f} x RATTLE")
        results[f"{box.n_atoms}"] = medians
        if args.json:
            with open(args.json, "w", encoding="utf-8") as handle:
                json.dump(results, handle, indent=2)


if __name__ == "__main__":
    main()
