"""OpenMM's DHFR benchmark system exactly as OpenMM's benchmark script builds it, timed with our integrators.

OpenMM's ``examples/benchmarks/benchmark.py --test pme`` (the figure OpenMM publishes
for DHFR, 23,558 atoms) builds ``5dfr_solv-cube_equil.pdb`` with Amber99SB + TIP3P,
PME with a 0.9 nm cutoff and the default Ewald tolerance (5e-4), HBonds constraints,
hydrogen mass 1.5 amu, and runs ``LangevinMiddleIntegrator`` at 4 fs, constraint
tolerance 1e-5; it times ``step(n)`` between two ``getState(energy=True)`` calls
(the device synchronised before and after). This script builds the same system from
the PDB shipped in the package and times, the same way and interleaved in rounds,
that integrator, ``VerletIntegrator``, and the package's integrators named on the
command line, all at the same step and constraint tolerance, and prints ns/day and
each one's step time against ``LangevinMiddleIntegrator``'s and ``VerletIntegrator``'s.
The package's integrators run without the ``CMMotionRemover`` (an NVE run removes it;
OpenMM's benchmark keeps it, as the Langevin and Verlet rows here do), as a drop-in: with no
call but OpenMM's (the rescaling decides from the forces which rigid-body motion it keeps);
``--check-context`` calls ``check_context`` on each first, as the package's driver does.
``--smooth`` runs every row on the System made smooth as the package recommends for NVE
(:func:`openmm_alphaprk.smooth_forces.make_smooth`: Lennard-Jones switched over the last
0.1 nm, Ewald error tolerance 1e-5) instead of OpenMM's settings.

Example (CUDA)::

    python -m openmm_alphaprk.benchmarks.dhfr_openmm_settings --platform CUDA --precision mixed \
        --integrators rattle rattle+rescale rattle+rescale@10 --json dhfr.json
"""

from __future__ import annotations

import argparse
import copy
import gzip
import json
import sys
import time
from importlib import resources

import openmm as mm
import openmm.app as app
import openmm.unit as unit

from openmm_alphaprk.benchmarks.cost import interleaved_timing
from openmm_alphaprk.integrators.restore import counted_force_evaluations
from openmm_alphaprk.runs.integrator_names import label, make_integrator
from openmm_alphaprk.smooth_forces import make_smooth

PDB = "5dfr_solv-cube_equil.pdb.gz"


def openmm_benchmark_system(hydrogen_mass_amu: float = 1.5) -> tuple[mm.System, list, app.Topology]:
    """Return OpenMM's ``pme`` benchmark System (HBonds), its positions and topology."""
    with resources.as_file(resources.files("openmm_alphaprk.systems") / "data" / PDB) as path:
        with gzip.open(path, "rt") as handle:
            pdb = app.PDBFile(handle)
    forcefield = app.ForceField("amber99sb.xml", "tip3p.xml")
    system = forcefield.createSystem(
        pdb.topology,
        nonbondedMethod=app.PME,
        nonbondedCutoff=0.9 * unit.nanometers,
        constraints=app.HBonds,
        hydrogenMass=hydrogen_mass_amu * unit.amu,
    )
    return system, pdb.positions, pdb.topology


def _without_cm_remover(system: mm.System) -> mm.System:
    copied = copy.deepcopy(system)
    for index in reversed(range(copied.getNumForces())):
        if isinstance(copied.getForce(index), mm.CMMotionRemover):
            copied.removeForce(index)
    return copied


def _integrators(names: list[str], timestep_ps: float) -> dict[str, tuple[mm.Integrator, bool]]:
    """Integrators by label, each with whether it runs the System as OpenMM's benchmark has it."""
    step = timestep_ps * unit.picoseconds
    rows = {
        "LangevinMiddleIntegrator": (
            mm.LangevinMiddleIntegrator(300 * unit.kelvin, 1 / unit.picoseconds, step),
            True,
        ),
        label("verlet"): (mm.VerletIntegrator(step), True),
    }
    for name in names:
        rows[label(name)] = (make_integrator(name, timestep_ps, constraint_tolerance=1e-5), False)
    for integrator, _ in rows.values():
        integrator.setConstraintTolerance(1e-5)
    return rows


def _counts(integrator: mm.Integrator) -> tuple[float, float]:
    """Force evaluations and host synchronisations counted so far (NaN for OpenMM's integrators)."""
    evaluations = counted_force_evaluations(integrator)
    if evaluations is None:
        return float("nan"), float("nan")
    return float(evaluations), integrator.getGlobalVariableByName("host_syncs")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platform", default="CUDA")
    parser.add_argument("--precision", default=None, choices=("single", "mixed", "double"))
    parser.add_argument("--timestep", type=float, default=4.0, help="fs (default 4, OpenMM's)")
    parser.add_argument("--hydrogen-mass", type=float, default=1.5, help="amu (default 1.5, OpenMM's)")
    parser.add_argument(
        "--integrators",
        nargs="*",
        default=["rattle", "rattle+rescale", "rattle+rescale@10", "rattle+rescale@100"],
    )
    parser.add_argument("--smooth", action="store_true", help="every row on the System made smooth")
    parser.add_argument("--check-context", action="store_true", help="call check_context on each first")
    parser.add_argument("--cpu-threads", type=int, help="threads of the CPU platform (default: all cores)")
    parser.add_argument("--steps", type=int, default=500, help="steps per row per round (default 500)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    system, positions, _ = openmm_benchmark_system(args.hydrogen_mass)
    if args.smooth:
        make_smooth(system)
    nve_system = _without_cm_remover(system)
    platform = mm.Platform.getPlatformByName(args.platform)
    properties = {"Precision": args.precision} if args.precision else {}
    if args.cpu_threads:
        properties["Threads"] = str(args.cpu_threads)
    rows = _integrators(args.integrators, args.timestep / 1000.0)
    contexts = {}
    for name, (integrator, as_benchmark) in rows.items():
        context = mm.Context(system if as_benchmark else nve_system, integrator, platform, properties)
        if args.check_context and hasattr(integrator, "check_context"):  # as the package's driver does
            integrator.check_context(context)
        context.setPositions(positions)
        if not contexts:  # OpenMM's benchmark: velocities at 300 K (no minimization for this test)
            context.setVelocitiesToTemperature(300 * unit.kelvin, 2024)
            start = context.getState(getPositions=True, getVelocities=True)
        context.setPositions(start.getPositions())
        context.setVelocities(start.getVelocities())
        integrator.step(20)  # kernels compiled, program analysed
        contexts[name] = context
    print(
        f"built {system.getNumParticles()} atoms, contexts ready in {time.perf_counter() - started:.0f} s",
        file=sys.stderr,
        flush=True,
    )
    counted = {name: _counts(integrator) for name, (integrator, _) in rows.items()}
    medians = interleaved_timing(
        {name: (integrator, 1, contexts[name]) for name, (integrator, _) in rows.items()},
        args.steps,
        args.rounds,
    )
    timed = args.steps * args.rounds
    per_step = {
        name: [(after - before) / timed for after, before in zip(_counts(integrator), counted[name])]
        for name, (integrator, _) in rows.items()
    }
    langevin, verlet = medians["LangevinMiddleIntegrator"], medians[label("verlet")]
    precision = f" ({args.precision})" if args.precision else ""
    forces = (
        "LJ switched over the last 0.1 nm and Ewald tolerance 1e-5 (the package's smooth forces)"
        if args.smooth
        else "Ewald tolerance 5e-4"
    )
    checked = "check_context called" if args.check_context else "no call but OpenMM's"
    threads = f" ({args.cpu_threads} thread{'s' if args.cpu_threads > 1 else ''})" if args.cpu_threads else ""
    header = (
        f"DHFR as OpenMM's benchmark builds it ({system.getNumParticles()} atoms, Amber99SB/TIP3P, "
        f"PME 0.9 nm, {forces}, HBonds, H {args.hydrogen_mass:g} amu), {args.timestep:g} fs, platform "
        f"{args.platform}{precision}{threads}; the package's integrators NVE, {checked}; median of "
        f"{args.rounds} interleaved rounds x {args.steps} steps, each between two getState(energy=True)"
    )
    print(header)
    print(
        f"{'integrator':<34} {'ms/step':>8} {'ns/day':>8} {'vs Langevin':>11} {'vs Verlet':>9} "
        f"{'evals/step':>10} {'syncs/step':>10}"
    )
    result = []
    for name, ms in medians.items():
        ns_day = args.timestep * 1e-6 * 86400.0 / (ms * 1e-3)
        evaluations, syncs = per_step[name]
        print(
            f"{name:<34} {ms:>8.3f} {ns_day:>8.3g} {ms / langevin:>11.2f} {ms / verlet:>9.2f} "
            f"{evaluations:>10.2f} {syncs:>10.2f}"
        )
        result.append(
            {
                "integrator": name,
                "ms_per_step": ms,
                "ns_per_day": ns_day,
                "ratio_to_langevin_middle": ms / langevin,
                "ratio_to_verlet": ms / verlet,
                "force_evaluations_per_step": per_step[name][0],
                "host_syncs_per_step": per_step[name][1],
            }
        )
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump({"header": header, "rows": result, "openmm": mm.__version__}, handle, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
