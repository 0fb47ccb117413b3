"""The ``alphaprk`` command: ``systems``, ``run``, ``compare``, ``analyze`` over the library functions."""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from collections.abc import Sequence

import openmm as mm

from . import rundir
from .compare import DEFAULT_INTEGRATORS, DEFAULT_SYSTEM, VERLET_NOTE, run_directory_name
from .integrators.names import (
    INTEGRATOR_HELP,
    IncompatibleSystemError,
    UnknownIntegratorError,
    parse_integrator,
)
from .systems import DefinitionError, UnknownSystemError

_TIME_UNITS = {"fs": 1e-3, "ps": 1.0, "ns": 1e3}
_LENGTH_UNITS = {"a": 1.0, "å": 1.0, "angstrom": 1.0, "nm": 10.0}


class QuantityError(ValueError):
    """A command-line quantity with a missing or wrong unit."""


def parse_time(text: str, option: str) -> float:
    """Parse ``2fs``, ``2 fs``, ``0.002ps`` or ``1ns`` into picoseconds."""
    return _parse(text, option, _TIME_UNITS, "a time", "fs, ps or ns")


def parse_length(text: str, option: str) -> float:
    """Parse ``8A``, ``8 Å`` or ``0.8nm`` into Ångström."""
    return _parse(text, option, _LENGTH_UNITS, "a length", "A (Ångström) or nm")


def _parse(text: str, option: str, units: dict[str, float], what: str, allowed: str) -> float:
    match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*([^\s0-9]*)\s*", str(text))
    if not match:
        raise QuantityError(f"{option} {text!r} is not a number with a unit; write e.g. 2fs or 0.8nm.")
    value, symbol = float(match.group(1)), match.group(2)
    if not symbol:
        raise QuantityError(f"{option} {text!r} has no unit; give {what} with a unit ({allowed}), e.g. 2fs.")
    factor = units.get(symbol.lower())
    if factor is None:
        raise QuantityError(f"{option} {text!r}: {symbol!r} is not a unit of {what}; use {allowed}.")
    if not value > 0:
        raise QuantityError(f"{option} must be positive, got {text!r}.")
    return value * factor


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {value}")
    return value


def _add_run_options(parser: argparse.ArgumentParser, default_steps: int) -> None:
    length = parser.add_mutually_exclusive_group()
    length.add_argument(
        "--steps", type=_positive, default=None, help=f"number of MD steps (default {default_steps})"
    )
    length.add_argument(
        "--length", default=None, help="simulated time instead of --steps, with a unit: 10ps, 0.5ns"
    )
    parser.add_argument(
        "--timestep", default="2fs", help="step size with a unit: 2fs (default), 0.001ps; fs, ps or ns"
    )
    parser.add_argument(
        "--platform",
        default="CPU",
        help="OpenMM platform: CPU (default), Reference (double precision, slow), CUDA, OpenCL",
    )
    parser.add_argument(
        "--precision",
        choices=("single", "mixed", "double"),
        default=None,
        help="floating-point precision for CUDA/OpenCL (default: the platform's own)",
    )
    parser.add_argument(
        "--constraint-tolerance",
        type=float,
        default=1e-8,
        help="relative tolerance of SHAKE/SETTLE/CCMA and velocity constraints (dimensionless; default 1e-8)",
    )
    parser.add_argument(
        "--energy-interval",
        type=_positive,
        default=10,
        help="steps between rows of energies.csv (default 10; each costs an extra energy evaluation)",
    )
    parser.add_argument(
        "--trajectory-interval", type=_positive, default=100, help="steps between DCD frames (default 100)"
    )
    parser.add_argument(
        "--checkpoint-interval",
        type=_positive,
        default=500,
        help="steps between checkpoints; an interrupted run resumes from the last one (default 500)",
    )
    _add_common(parser)


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--cache-dir",
        default=None,
        help="cache of equilibrated systems (default $ALPHAPRK_CACHE_DIR, else ~/.cache/openmm_alphaprk)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def _add_bench_parser(sub) -> None:
    bench = sub.add_parser(
        "bench",
        help="benchmarks against RATTLE: `bench cost` (time per step), `bench energy` (H - E_ref)",
        description=(
            "cost: time per step and per force evaluation of each integrator against RattleIntegrator, "
            "interleaved rounds on one water box. energy: H - E_ref of the energy modes against RATTLE from "
            "the same start, at the same step and at equal cost; --system tip3p-3nm villin runs the "
            "package's systems in one run. `alphaprk bench cost --help` and `alphaprk bench energy --help` "
            "list their options."
        ),
    )
    bench.add_argument("benchmark", choices=BENCHMARKS, help="which benchmark")
    bench.add_argument(
        "options", nargs=argparse.REMAINDER, help="the benchmark's own options (see its --help)"
    )


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of ``alphaprk`` (all subcommands)."""
    parser = argparse.ArgumentParser(
        prog="alphaprk",
        description=(
            "NVE molecular dynamics with alpha-RATTLE (openmm_alphaprk): ready-made systems, runs that "
            "write energies/trajectory/checkpoints as they go and resume, side-by-side comparisons of "
            "integrators, and MDAnalysis analyses. Units: energies kJ/mol, drift kJ/mol/ns per degree of "
            "freedom, times with explicit units on input (2fs, 10ps)."
        ),
        epilog=f"Integrators: {INTEGRATOR_HELP}.",
    )
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="{systems,run,compare,analyze,sweep,bench}"
    )

    systems = sub.add_parser(
        "systems",
        help="list the ready-made systems (and build/cache them)",
        description="List the system definitions; with --build, build and cache the named ones now.",
    )
    systems.add_argument(
        "--build", nargs="+", metavar="SYSTEM", default=None, help="build and cache these systems now"
    )
    _add_common(systems)

    run = sub.add_parser(
        "run",
        help="one NVE run of a system with one integrator",
        description=(
            "Run NVE dynamics and write run.json, energies.csv (step, time ps, potential/kinetic/total "
            "energy kJ/mol, temperature K), controller.csv (energy mode: alpha*, H - E_ref per step), "
            "trajectory.dcd (unwrapped), checkpoint.chk and summary.json to the output directory. "
            "Running the same command again resumes an interrupted run; a directory holding a different "
            "run is refused."
        ),
        epilog=f"Integrators: {INTEGRATOR_HELP}.",
    )
    run.add_argument("system", help="system name (see `alphaprk systems`) or path to a .toml definition")
    run.add_argument("integrator", help="rattle, verlet, energy or alpha=<number> (see below)")
    run.add_argument(
        "-o", "--output", default=None, help="run directory (default alphaprk-run-<system>-<integrator>)"
    )
    _add_run_options(run, 1000)

    comp = sub.add_parser(
        "compare",
        help="several integrators from the same start: table and H - E_ref figure",
        description=(
            "Run every integrator from the same equilibrated state (one run directory each, resumable), "
            "print a table (drift kJ/mol/ns per DOF from a linear fit, RMS and max |H - E_ref| kJ/mol, "
            "max relative constraint error, force evaluations per step, ns/day) and write "
            "comparison.json, table.txt and energy_residuals.png. " + VERLET_NOTE
        ),
        epilog=f"Integrators: {INTEGRATOR_HELP}.",
    )
    comp.add_argument(
        "system", nargs="?", default=DEFAULT_SYSTEM, help=f"system name (default {DEFAULT_SYSTEM})"
    )
    comp.add_argument(
        "-i",
        "--integrators",
        nargs="+",
        default=list(DEFAULT_INTEGRATORS),
        help=f"integrators to compare (default: {' '.join(DEFAULT_INTEGRATORS)})",
    )
    comp.add_argument(
        "-o", "--output", default=None, help="output folder (default alphaprk-compare-<system>)"
    )
    comp.add_argument("--no-plot", action="store_true", help="skip the figure (no matplotlib needed)")
    _add_run_options(comp, 1000)

    analyze = sub.add_parser(
        "analyze",
        help="energy drift, constraint deviation, O-O RDF and MSD of a run directory",
        description=(
            "Analyse a run directory with MDAnalysis: energy drift fit (kJ/mol/ns per DOF), constraint "
            "length deviation per frame (relative), O-O radial distribution function (InterRDF, periodic "
            "systems), mean-squared displacement and diffusion coefficient (EinsteinMSD, 1e-5 cm^2/s). "
            "Writes analysis.json and energy.png, constraint_deviation.png, rdf_OO.png, msd.png."
        ),
    )
    analyze.add_argument("run", help="a run directory (or one integrator's folder of a comparison)")
    analyze.add_argument(
        "--select",
        default=None,
        help="MDAnalysis selection for RDF and MSD (default: water oxygens)",
    )
    analyze.add_argument("--rdf-bins", type=_positive, default=100, help="RDF histogram bins (default 100)")
    analyze.add_argument(
        "--rdf-max",
        default="8A",
        help="largest RDF distance with a unit: 8A (default), 0.8nm; capped at half the box",
    )
    analyze.add_argument("--no-plot", action="store_true", help="skip the figures (no matplotlib needed)")
    analyze.add_argument("--quiet", action="store_true", help="no progress bars")

    sweep = sub.add_parser(
        "sweep",
        help="run a grid of NVE runs (systems x integrators x step sizes x alpha x seeds) with dask",
        description=(
            "Expand the grids of a sweep configuration (TOML, see openmm_alphaprk.sweep) into independent "
            "runs, execute them on a dask.distributed cluster (a local one by default) and collect their "
            "summaries into sweep.csv in the output folder, rewritten as cells finish. Failed cells are "
            "recorded with their error; running the same command again skips finished cells and resumes "
            "interrupted ones. Needs the sweep extra: pip install 'openmm-alphaprk[sweep]'."
        ),
    )
    sweep.add_argument("config", help="sweep configuration file (TOML)")
    sweep.add_argument("--output", default=None, help="output folder (default: the configuration's `output`)")
    sweep.add_argument(
        "--scheduler", default=None, help="address of a running dask scheduler, e.g. tcp://host:8786"
    )
    sweep.add_argument(
        "--workers",
        type=_positive,
        default=None,
        help="workers of the local cluster (default: the configuration's, else 1)",
    )
    sweep.add_argument("--retry-failed", action="store_true", help="run failed cells again")
    sweep.add_argument("--list", action="store_true", help="list the cells and their state, run nothing")
    _add_bench_parser(sub)
    _add_common(sweep)
    return parser


def _steps(args) -> tuple[int, float]:
    timestep = parse_time(args.timestep, "--timestep")
    if args.length is not None:
        steps = round(parse_time(args.length, "--length") / timestep)
        if steps < 1:
            raise QuantityError(f"--length {args.length} is shorter than one step of {args.timestep}.")
        return steps, timestep
    return (args.steps or 1000), timestep


def _run_kwargs(args) -> dict:
    steps, timestep = _steps(args)
    return {
        "steps": steps,
        "timestep": timestep,
        "platform": args.platform,
        "precision": args.precision,
        "constraint_tolerance": args.constraint_tolerance,
        "energy_interval": args.energy_interval,
        "trajectory_interval": args.trajectory_interval,
        "checkpoint_interval": args.checkpoint_interval,
        "cache_dir": args.cache_dir,
        "progress": not args.quiet,
    }


def cmd_systems(args) -> int:
    from .systems import is_cached, list_systems, load_definition, prepare_system

    if args.build:
        for name in args.build:
            prepared = prepare_system(name, cache_dir=args.cache_dir, progress=not args.quiet)
            print(f"{prepared.name}: {prepared.n_atoms} atoms, cached in {prepared.path}")
        return 0
    print(f"{'system':<14} {'cached':<7} description")
    for name in list_systems():
        definition = load_definition(name)
        cached = "yes" if is_cached(definition, args.cache_dir) else "no"
        print(f"{name:<14} {cached:<7} {definition.description}")
    return 0


def cmd_run(args) -> int:
    from .driver import run_nve

    spec = parse_integrator(args.integrator)
    kwargs = _run_kwargs(args)
    output = args.output or f"alphaprk-run-{args.system}-{run_directory_name(spec)}"
    summary = run_nve(args.system, spec, output, **kwargs)
    print(json.dumps(summary.as_dict(), indent=2))
    print(f"run directory: {output}", file=sys.stderr)
    return 0


def cmd_compare(args) -> int:
    from .compare import compare

    for name in args.integrators:
        parse_integrator(name)
    kwargs = _run_kwargs(args)
    output = args.output or f"alphaprk-compare-{args.system}"
    result = compare(args.system, args.integrators, output, plot=not args.no_plot, **kwargs)
    print(result.table)
    print(
        f"\nresults: {result.output / 'comparison.json'}"
        + (f", figure: {result.figure}" if result.figure else "")
    )
    return 0


def cmd_analyze(args) -> int:
    from .analysis import WATER_OXYGENS, analyze_run

    rdf_max = parse_length(args.rdf_max, "--rdf-max")
    result = analyze_run(
        args.run,
        select=args.select or WATER_OXYGENS,
        rdf_bins=args.rdf_bins,
        rdf_max=rdf_max,
        plot=not args.no_plot,
        progress=not args.quiet,
    )
    energy = result["energy"]
    print(
        f"energy: drift {energy['drift_per_dof']:.3e} kJ/mol/ns per DOF, RMS |H - E_ref| "
        f"{energy['rms_residual']:.4f} kJ/mol, max {energy['max_abs_residual']:.4f} kJ/mol "
        f"({energy['samples']} samples over {energy['duration_ps']:g} ps)"
    )
    if "constraints" in result:
        c = result["constraints"]
        print(
            f"constraints: max relative deviation {c['overall_max_relative_deviation']:.2e} "
            f"over {c['frames']} frames"
        )
    if "rdf" in result:
        r = result["rdf"]
        print(f"O-O RDF: first peak g = {r['first_peak_g']:.2f} at r = {r['first_peak_r_angstrom']:.2f} A")
    if "msd" in result:
        m = result["msd"]
        print(
            f"MSD: D = {m['diffusion_coefficient_1e-5_cm2_per_s']:.3g} x 1e-5 cm^2/s "
            f"(fit over lags {m['fit_window_ps']} ps)"
        )
    for note in result["notes"]:
        print(f"note: {note}")
    print(f"written: {args.run}/analysis.json" + "".join(f", {path}" for path in result["figures"].values()))
    return 0


def cmd_sweep(args) -> int:
    from pathlib import Path

    from .sweep import cell_status, load_config, run_sweep

    config = load_config(args.config)
    if args.list:
        root = Path(args.output) if args.output else config.output
        for cell in config.cells:
            row = cell_status(cell, root / cell.name)
            state = "to run" if row is None else row["status"]
            print(f"{cell.name:60s} {cell.steps:8d} steps  {state}")
        print(f"{len(config.cells)} cells -> {root}")
        return 0
    result = run_sweep(
        config,
        output=args.output,
        scheduler=args.scheduler,
        n_workers=args.workers,
        retry_failed=args.retry_failed,
        cache_dir=args.cache_dir,
        progress=not args.quiet,
    )
    print(
        f"{len(result.rows)} cells: {len(result.ran)} run now, {len(result.skipped)} finished before, "
        f"{len(result.failed)} failed -> {result.table}"
    )
    return 0  # failed cells are results (a step-size scan expects some); they are in the table


#: ``alphaprk bench`` subcommands: the module whose ``main(argv)`` runs each.
BENCHMARKS = {
    "cost": "openmm_alphaprk.benchmarks.cost",
    "energy": "openmm_alphaprk.benchmarks.energy_command",
}


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark's own command line with the remaining options."""
    import importlib

    return importlib.import_module(BENCHMARKS[args.benchmark]).main(args.options)


_COMMANDS = {
    "systems": cmd_systems,
    "run": cmd_run,
    "compare": cmd_compare,
    "analyze": cmd_analyze,
    "sweep": cmd_sweep,
    "bench": cmd_bench,
}

#: Errors that are the user's to fix: reported in one line, exit status 2.
_INPUT_ERRORS = (
    UnknownSystemError,
    UnknownIntegratorError,
    IncompatibleSystemError,
    rundir.RunDirectoryError,
    DefinitionError,
    QuantityError,
    FileNotFoundError,
    ImportError,
    ValueError,
    TypeError,
)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``alphaprk`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from .driver import RunFailedError

    if os.environ.get("ALPHAPRK_DEBUG"):  # full tracebacks
        return _COMMANDS[args.command](args)
    try:
        return _COMMANDS[args.command](args)
    except RunFailedError as error:
        print(f"alphaprk {args.command}: run failed: {error}", file=sys.stderr)
        return 1
    except mm.OpenMMException as error:
        print(f"alphaprk {args.command}: OpenMM error: {error}", file=sys.stderr)
        return 1
    except _INPUT_ERRORS as error:
        print(f"alphaprk {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"alphaprk {args.command}: interrupted; run the same command again to resume from the "
            "last checkpoint.",
            file=sys.stderr,
        )
        return 130
