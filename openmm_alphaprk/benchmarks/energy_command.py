"""``alphaprk bench energy``: the energy benchmark's command line, tables and JSON.

The measurement itself is :mod:`openmm_alphaprk.benchmarks.energy`.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import asdict
from functools import partial

import numpy as np

from ..integrators.names import label, make_integrator
from ..observables import degrees_of_freedom, drift_text
from ..systems import PreparedSystem, build_water_box, list_systems, prepare_system
from .cost import add_box_arguments, build_platform, platform_properties
from .energy import (
    FIXED_ALPHA_SCAN,
    INTEGRATOR_NAMES,
    EnergyRow,
    default_integrators,
    fixed_alpha_names,
    largest_stable_step,
    ratios_to_rattle,
    run_energy_benchmark,
)


def format_table(rows: Sequence[EnergyRow], header: str = "") -> str:
    """Format the rows as a plain-text table."""
    lines = [header] if header else []
    lines.append(
        f"{'integrator':<16} {'steps':>6} {'drift/DOF kJ/mol/ns ± SE':<26} {'RMS(H-Eref)':>11} "
        f"{'max|H-Eref|':>11} "
        f"{'evals/step':>10} {'time ratio':>10} {'within tol':>10} {'fell back':>9} {'at bound':>8} "
        f"{'E_ref':>5}  alpha* p5/p50/p95"
    )
    for row in rows:
        alpha = (
            "/".join(f"{row.alpha_percentiles[k]:.2f}" for k in ("p5", "p50", "p95"))
            if row.alpha_percentiles
            else "-"
        )
        drift = drift_text(row.drift_per_dof, row.drift_per_dof_standard_error)
        lines.append(
            f"{row.name:<16} {row.steps:>6} {drift:<26} {row.rms_residual:>11.4f} "
            f"{row.max_abs_residual:>11.4f} {row.force_evaluations_per_step:>10.2f} {row.time_ratio:>10.2f} "
            f"{row.fraction_within_tolerance:>10.3f} {row.fraction_fallen_back:>9.3f} "
            f"{row.fraction_at_bound:>8.3f} "
            f"{'-' if row.reference_resets is None else row.reference_resets:>5}  "
            f"{alpha}"
            + (f"  BLEW UP at step {row.blew_up_at_step}" if row.blew_up_at_step is not None else "")
        )
    return "\n".join(lines)


def format_ratios(rows: Sequence[EnergyRow]) -> str:
    """One line per row: how many times RATTLE's RMS(H − E_ref) is the row's, at 2 fs and at equal cost."""
    lines = [
        "RMS(H - E_ref) of RATTLE / the row's (same step; at equal cost: RATTLE at h/k); for the energy "
        "modes also alpha4=0's and the best fixed alpha's RMS / the row's (below 1: the baseline did better):"
    ]
    for name, entry in ratios_to_rattle(rows).items():
        equal = entry.get("rms_vs_rattle_equal_cost")
        line = f"  {name:<24} {entry['rms_vs_rattle']:8.2f}x" + (
            f"   at equal cost {equal:6.2f}x" if equal is not None else ""
        )
        if "rms_vs_alpha4_0" in entry:
            line += f"   vs alpha4=0 {entry['rms_vs_alpha4_0']:6.2f}x"
        if "rms_vs_best_fixed_alpha" in entry:
            line += f"   vs best fixed ({entry['best_fixed_alpha']}) {entry['rms_vs_best_fixed_alpha']:6.2f}x"
        lines.append(line)
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="alphaprk bench energy",
        description=(
            "Energy drift and fluctuation of α-RATTLE's energy mode against RATTLE, NVE from the same "
            "start: a TIP3P box built here (--box) or the package's systems (--system, several in one run)."
        ),
    )
    add_box_arguments(parser)
    parser.add_argument(
        "--system",
        nargs="+",
        default=None,
        metavar="NAME",
        help="benchmark these systems of `alphaprk systems` (e.g. tip3p-3nm villin), one after the other, "
        "instead of a --box; their equilibrated states come from the systems cache (built the first time)",
    )
    parser.add_argument(
        "--time", type=float, default=20.0, help="simulated time per integrator in ps (default 20)"
    )
    parser.add_argument(
        "--only",
        nargs="*",
        default=None,
        help="run only these integrators, by name (energy, alpha4=0, energy4; rattle always runs)",
    )
    parser.add_argument(
        "--fixed-alpha",
        nargs="*",
        type=float,
        default=list(FIXED_ALPHA_SCAN),
        metavar="ALPHA",
        help=f"also run alpha-RATTLE-4 at these fixed alphas (default {' '.join(map(str, FIXED_ALPHA_SCAN))};"
        " none: no scan); the energy modes are compared with alpha4=0 and the best of them",
    )
    parser.add_argument(
        "--equilibration-steps", type=int, default=1000, help="2 fs Langevin steps first (default 1000)"
    )
    parser.add_argument(
        "--seed", type=int, default=2024, help="random seed of the equilibration (default 2024)"
    )
    parser.add_argument(
        "--sample-every",
        type=int,
        default=1,
        help="read the total energy every N steps (default 1: every step)",
    )
    parser.add_argument(
        "--scan",
        nargs="*",
        type=float,
        default=None,
        help="also scan these step sizes in fs (e.g. 2 3 4 5) for the largest stable step of each row's "
        "integrator, 1 ps each",
    )
    parser.add_argument("--json", help="also write the rows (and scan) to this JSON file")
    parser.add_argument(
        "--traces", help="also write H - E_ref per step of every integrator to this .npz file"
    )
    return parser


def _check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    if min(args.box, args.timestep, args.time) <= 0:
        parser.error("--box, --timestep and --time must be positive")
    if args.scan is not None and min(args.scan, default=1.0) <= 0:
        parser.error("--scan step sizes must be positive")
    if args.sample_every < 1:
        parser.error("--sample-every must be a positive integer")
    if any(not abs(alpha) < float("inf") for alpha in args.fixed_alpha):
        parser.error("--fixed-alpha values must be finite numbers")
    if args.only:
        unknown = set(args.only) - set(INTEGRATOR_NAMES)
        if unknown:
            parser.error(f"unknown integrator(s) {sorted(unknown)}; choose from {list(INTEGRATOR_NAMES)}")
    if args.system:
        if len(set(args.system)) < len(args.system):
            parser.error(f"--system: a system named twice in {args.system}")
        known = set(list_systems())
        unknown = [name for name in args.system if name not in known]
        if unknown:
            parser.error(f"unknown system(s) {unknown}; choose from {', '.join(list_systems())}")


def _benchmark_starts(args: argparse.Namespace) -> list[tuple[PreparedSystem, str]]:
    """Build or load the start states, each with the first part of its table header."""
    if not args.system:
        print(f"building a {args.box} nm TIP3P box ...", file=sys.stderr, flush=True)
        box = build_water_box(
            args.box,
            cutoff=args.cutoff,
            equilibration_steps=args.equilibration_steps,
            seed=args.seed,
            platform=build_platform(args),
        )
        return [
            (
                box,
                f"TIP3P box {args.box} nm, {box.n_atoms} atoms, {degrees_of_freedom(box.system)} DOF, PME "
                f"cutoff {args.cutoff} nm (LJ switched, Ewald tolerance 1e-5)",
            )
        ]
    starts = []
    for name in args.system:
        prepared = prepare_system(name, progress=True)
        # the contexts take the box from the System: make it the equilibrated state's
        prepared.system.setDefaultPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
        description = prepared.definition.description or "see alphaprk systems"
        dof = degrees_of_freedom(prepared.system)
        starts.append((prepared, f"system {name} ({description}), {prepared.n_atoms} atoms, {dof} DOF"))
    return starts


def _scan(box: PreparedSystem, integrators: dict, args: argparse.Namespace) -> dict:
    scan = {}
    print("\nlargest stable step (1 ps per step size):")
    for integrator_name in INTEGRATOR_NAMES:
        name = label(integrator_name)
        if name not in integrators:
            continue
        largest, outcomes = largest_stable_step(
            box,
            partial(make_integrator, integrator_name),
            args.scan,
            platform=args.platform,
            properties=platform_properties(args),
        )
        scan[name] = {"largest_fs": largest, "outcomes": {str(k): v for k, v in outcomes.items()}}
        detail = "; ".join(f"{h:g} fs {text}" for h, text in outcomes.items())
        print(f"  {name:<20} {largest} fs   ({detail})", flush=True)
    return scan


def _benchmark_one(box: PreparedSystem, description: str, args: argparse.Namespace) -> tuple[dict, dict]:
    """Run the rows on one start state, print the table; return the JSON result and the traces."""
    timestep = args.timestep / 1000.0
    names = [name for name in INTEGRATOR_NAMES if name == "rattle" or not args.only or name in args.only]
    names += [name for name in fixed_alpha_names(args.fixed_alpha) if name not in names]
    integrators = default_integrators(timestep, names)
    rows, traces = run_energy_benchmark(
        box,
        integrators,
        platform=args.platform,
        steps=int(round(args.time / args.timestep * 1000.0)),
        sample_every=args.sample_every,
        properties=platform_properties(args),
    )
    precision = f" ({args.precision} precision)" if args.precision else ""
    header = (
        f"{description}, {args.timestep} fs, {args.time} ps NVE, platform {args.platform}{precision}; "
        f"energy read every {args.sample_every} step(s); drift in kJ/mol/ns per DOF (linear fit); "
        "energies in kJ/mol; time ratio against RATTLE (median of 3 x 100 timed steps, no energy read-out)"
    )
    print(format_table(rows, header), flush=True)
    print(format_ratios(rows), flush=True)
    result = {"header": header, "rows": [asdict(row) for row in rows], "ratios": ratios_to_rattle(rows)}
    if args.scan:
        result["scan"] = _scan(box, integrators, args)
    return result, traces


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point."""
    parser = _parser()
    args = parser.parse_args(argv)
    _check_arguments(parser, args)
    results, all_traces = {}, {}
    for box, description in _benchmark_starts(args):
        result, traces = _benchmark_one(box, description, args)
        label = args.system[len(results)] if args.system else f"tip3p-box-{args.box:g}nm"
        results[label] = result
        all_traces.update({f"{label}/{name}": trace for name, trace in traces.items()})
        if args.json:  # written after every system: an interrupted run keeps the systems done
            with open(args.json, "w", encoding="utf-8") as handle:
                json.dump(results if args.system else result, handle, indent=2)
    if args.traces:
        traces_out = all_traces if args.system else {k.split("/", 1)[1]: v for k, v in all_traces.items()}
        np.savez_compressed(args.traces, timestep_ps=args.timestep / 1000.0, **traces_out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
