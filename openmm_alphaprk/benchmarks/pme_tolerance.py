"""RMS(H - E_ref) and cost of RATTLE, energy4 and alpha4=0 against PME's Ewald error tolerance.

Usage: python -m openmm_alphaprk.benchmarks.pme_tolerance [--steps 400] [--tolerances 5e-4 1e-4 5e-5 1e-5]
       [--system tip3p-3nm] [--integrators rattle energy4 alpha4=0] [--cost-only] [--json out.json]

The numbers of docs/smooth_forces.md, "How tight a PME tolerance". For every tolerance
the System of the system's shipped start state is made again with only the
NonbondedForce's Ewald error tolerance changed (LJ switched as in the definition),
and RATTLE, alpha-RATTLE-4's energy mode and triple-jump RATTLE run NVE at 2 fs on
the CPU platform from that same start (openmm_alphaprk.benchmarks.energy). The time
per step comes after, from interleaved rounds over every (tolerance, integrator)
pair, so that load on the machine falls on all of them alike; the table gives the
fastest round (the least disturbed by other processes) and the JSON every round.
``--cost-only`` skips the energy runs (e.g. ``--system villin --integrators rattle
--cost-only``: the cost of a force evaluation alone). ``--table FILE.json`` prints the
table of a saved ``--json`` file again, running nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
import warnings
from pathlib import Path

import openmm as mm

from openmm_alphaprk import NonSmoothForcesWarning
from openmm_alphaprk.benchmarks.energy import energy_benchmark_integrators, run_energy_benchmark
from openmm_alphaprk.systems import prepare_system
from openmm_alphaprk.systems.build import build_model, create_system

NAMES = ("rattle", "energy4", "alpha4=0")


def with_tolerance(prepared, tolerance: float):
    """Return ``prepared`` with its System made again from its definition at Ewald tolerance ``tolerance``."""
    definition = prepared.definition.with_overrides({"build.ewald_error_tolerance": tolerance})
    topology, _, forcefield = build_model(definition)
    return dataclasses.replace(prepared, system=create_system(definition, topology, forcefield))


def context_at_start(box, integrator):
    """Return a CPU context of ``box``'s System with ``integrator``, at the start state."""
    context = mm.Context(box.system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setState(box.state)
    return context


def pme_parameters(box) -> str:
    """Return PME's alpha (1/nm) and grid for ``box``, as OpenMM chooses them (all platforms alike).

    Asked of a Reference context: on the CPU platform getPMEParametersInContext raised
    std::bad_cast for some Systems (OpenMM 8.6.1).
    """
    context = mm.Context(box.system, mm.VerletIntegrator(0.001), mm.Platform.getPlatformByName("Reference"))
    force = next(f for f in box.system.getForces() if isinstance(f, mm.NonbondedForce))
    alpha, nx, ny, nz = force.getPMEParametersInContext(context)
    del context
    return f"alpha {alpha:.3f}/nm, grid {nx}x{ny}x{nz}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--system", default="tip3p-3nm")
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--tolerances", type=float, nargs="+", default=[5e-4, 1e-4, 5e-5, 1e-5])
    parser.add_argument("--timing-steps", type=int, default=30)
    parser.add_argument("--timing-rounds", type=int, default=10)
    parser.add_argument("--integrators", nargs="+", default=list(NAMES))
    parser.add_argument("--cost-only", action="store_true", help="time the steps, skip the energy runs")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--table", type=Path, default=None, help="print the table of a saved --json file")
    args = parser.parse_args(argv)
    if args.table is not None:
        saved = json.loads(args.table.read_text(encoding="utf-8"))
        print(table({float(key): value for key, value in saved.items() if isinstance(value, dict)}))
        return 0
    warnings.simplefilter("ignore", NonSmoothForcesWarning)  # the loose tolerances are the point
    prepared = prepare_system(args.system)
    print(f"{args.system}: {prepared.n_atoms} atoms, start state {prepared.source}", file=sys.stderr)
    load = [os.getloadavg()[0]]
    results, timing, contexts = {}, {}, []
    for tolerance in args.tolerances:
        box = with_tolerance(prepared, tolerance)
        pme = pme_parameters(box)
        integrators = energy_benchmark_integrators(0.002, args.integrators)
        if args.cost_only:
            rows = [{"name": label, "rms_residual": float("nan")} for label in integrators]
        else:
            rows = run_energy_benchmark(
                box, integrators, steps=args.steps, equal_cost=False, timing_rounds=0, progress=False
            )[0]
            rows = [dataclasses.asdict(row) for row in rows]
        results[tolerance] = {"pme": pme, "rows": rows}
        for row, name in zip(rows, args.integrators):
            row["integrator"] = name
        for label, spec in integrators.items():
            integrator = spec.make()
            contexts.append(context_at_start(box, integrator))
            integrator.step(10)  # warm-up: the first step's set-up
            timing[(tolerance, label)] = integrator
    rounds = interleaved_rounds(timing, args.timing_steps, args.timing_rounds)
    load.append(os.getloadavg()[0])
    for tolerance, result in results.items():
        for row in result["rows"]:
            row["ms_per_step_rounds"] = rounds[(tolerance, row["name"])]
            row["ms_per_step"] = min(row["ms_per_step_rounds"])
            row.setdefault(
                "force_evaluations_per_step",
                getattr(timing[(tolerance, row["name"])], "force_evaluations_per_step", 1.0),
            )
    print(table(results))
    print(f"\nload average (1 min) at start and end: {load[0]:.2f}, {load[1]:.2f}; OpenMM {mm.__version__}")
    if args.json is not None:
        data = {f"{tol:g}": result for tol, result in results.items()}
        steps = 0 if args.cost_only else args.steps
        meta = {"system": args.system, "steps": steps, "load": load, "openmm": mm.__version__}
        args.json.write_text(json.dumps({**meta, **data}, indent=2), encoding="utf-8")
    return 0


def interleaved_rounds(integrators: dict, steps: int, rounds: int) -> dict:
    """Return ms per step of every integrator in each of ``rounds`` rounds that step each in turn."""
    times = {key: [] for key in integrators}
    for _ in range(rounds):
        for key, integrator in integrators.items():
            start = time.perf_counter()
            integrator.step(steps)
            times[key].append((time.perf_counter() - start) / steps * 1e3)
    return times


def table(results: dict) -> str:
    """Markdown table: per tolerance and integrator, RMS, gain over RATTLE, evaluations, ms/step, ratios."""
    tightest = min(results)
    base = {row["name"]: row["ms_per_step"] for row in results[tightest]["rows"]}
    lines = [
        "| Ewald tolerance | PME | integrator | RMS(H − E_ref) kJ/mol | RATTLE's RMS / this | "
        f"evaluations/step | fallen back | ms/step | time / RATTLE's | time / at {tightest:g} |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for tolerance in sorted(results, reverse=True):
        rows = results[tolerance]["rows"]
        rattle = rows[0]
        for row in rows:
            rms, ms = row["rms_residual"], row["ms_per_step"]
            fallen = row.get("fraction_fallen_back", float("nan"))
            lines.append(
                f"| {tolerance:g} | {results[tolerance]['pme']} | `{row['integrator']}` | {rms:.3g} | "
                f"{rattle['rms_residual'] / rms:.3g} | {row['force_evaluations_per_step']:.2f} | "
                + ("–" if fallen != fallen else f"{fallen:.0%}")
                + f" | {ms:.1f} | {ms / rattle['ms_per_step']:.2f} | {ms / base[row['name']]:.2f} |"
            )
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
