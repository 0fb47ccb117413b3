"""The argument parser of ``alphaprk``: one ``_add_*_parser`` per command."""

from __future__ import annotations

import argparse
import os
import re

from ..platforms import AUTO
from ..runs.integrator_names import INTEGRATOR_HELP, INTEGRATOR_NAMES
from ..runs.options import DEFAULTS, PRECISIONS
from ..systems.arguments import add_file_arguments
from ..workflows.comparison import ACCURACY_STEPS, FULL_COMPARISON, MAIN_JOB, VERLET_NOTE
from .quantities import positive

SYSTEM_HELP = (
    "system name (see `alphaprk systems`), a .toml definition, or the system's own files: AMBER "
    ".prmtop/.parm7 (coordinates of the same stem or --coordinates), CHARMM .psf (--coordinates, "
    "--params), GROMACS .top (.gro of the same stem), .pdb/.cif (--forcefield), OpenMM System .xml "
    "(--state, --topology)"
)

#: ``alphaprk bench`` subcommands: the module whose ``main(argv)`` runs each.
BENCHMARKS = {
    "cost": "openmm_alphaprk.benchmarks.cost",
    "energy": "openmm_alphaprk.benchmarks.energy",
    "accuracy": "openmm_alphaprk.benchmarks.accuracy",
    "long": "openmm_alphaprk.benchmarks.long",
    "physics": "openmm_alphaprk.benchmarks.physics",
}


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
        dest="command", required=True, metavar="{systems,run,compare,analyze,validate,sweep,bench}"
    )
    _add_systems_parser(sub)
    _add_run_parser(sub)
    _add_compare_parser(sub)
    _add_analyze_parser(sub)
    _add_validate_parser(sub)
    _add_sweep_parser(sub)
    return parser


def _add_systems_parser(sub) -> None:
    systems = sub.add_parser(
        "systems",
        help="list the ready-made systems and where their start states come from (and build them)",
        description=(
            "List the system definitions and where each one's start state comes from: 'shipped' (with the "
            "package, the same on every machine), 'cached' (built here before) or 'to build'. With --build, "
            "prepare the named ones now: a shipped state is used as it is, anything else is built "
            "(minimized and equilibrated) and cached; --rebuild builds them here even so."
        ),
    )
    systems.add_argument(
        "--build", nargs="+", metavar="SYSTEM", default=None, help="prepare these systems now"
    )
    _add_rebuild(systems)
    _add_common(systems)


def _add_run_parser(sub) -> None:
    run = sub.add_parser(
        "run",
        help="one NVE run of a system with one integrator",
        description=(
            "Run NVE dynamics and write run.json, energies.csv (step, time ps, potential/kinetic/total "
            "energy kJ/mol, temperature K), controller.csv (energy mode: alpha*, H - E_ref, fallback of "
            "sampled steps), "
            "trajectory.dcd (unwrapped), checkpoint.chk and summary.json to the output directory, and print "
            "the summary as a table (the columns of `alphaprk compare`; --json for JSON). The output "
            "directory is alphaprk-run-<system>-<integrator> in the current directory unless -o names "
            "another. Running the same "
            "command again resumes an interrupted run, or extends a finished one with a larger --steps; a "
            "directory holding a different or a longer run is refused."
        ),
        epilog=f"Integrators: {INTEGRATOR_HELP}.",
    )
    run.add_argument("system", help=SYSTEM_HELP)
    run.add_argument("integrator", help=f"one of {INTEGRATOR_NAMES} (see below)")
    run.add_argument(
        "-o",
        "--output",
        default=None,
        help="run directory (default: alphaprk-run-<system>-<integrator> in the current directory)",
    )
    run.add_argument(
        "--json",
        action="store_true",
        help="print the summary as JSON (what summary.json holds) instead of the table",
    )
    _add_rebuild(run)
    _add_run_options(run)
    add_file_arguments(run)


def _add_compare_parser(sub) -> None:
    quick, full = MAIN_JOB, FULL_COMPARISON
    comp = sub.add_parser(
        "compare",
        help="several integrators from the same start: table, verdict and H - E_ref figure",
        description=(
            f"The main job: without arguments, {' '.join(quick.integrators)} on {quick.system} for "
            f"{quick.steps} steps of 2 fs, on the fastest platform present (a few minutes on two cores); "
            f"--full compares {' '.join(full.integrators)} on {full.system} for {full.steps} steps. "
            "Every integrator runs from the same equilibrated state (one run directory each, resumable); "
            "the table gives drift kJ/mol/ns per DOF from a linear fit with its standard error, RMS and max "
            "|H - E_ref| kJ/mol with E_ref the total energy of the start state, max relative constraint "
            "error, force evaluations per step, ns/day; comparison.json, table.txt and "
            "energy_residuals.png go into the output folder, by default alphaprk-compare-<system> in the "
            "current directory (-o to choose another). After the listed runs, RATTLE also runs at h/k "
            "for the same simulated time, k the force evaluations per step of each row that takes more than "
            "one, rounded up: the table states each such row's gain at equal cost (--no-equal-cost skips "
            "it). Each row's position error against RATTLE at h/64 after a few steps (--accuracy-steps, 0: "
            "none) is the table's last column: exact energy is not accurate dynamics. The last line is the "
            "verdict: the row that holds the energy and tracks the dynamics best at equal cost. "
            + VERLET_NOTE
        ),
        epilog=f"Integrators: {INTEGRATOR_HELP}.",
    )
    comp.add_argument(
        "system",
        nargs="?",
        default=None,
        help=f"{SYSTEM_HELP} (default {quick.system}; {full.system} with --full)",
    )
    comp.add_argument(
        "--full",
        action="store_true",
        help=f"the full comparison: {full.system}, {full.steps} steps, {' '.join(full.integrators)} "
        "(the system, --integrators and --steps given still apply)",
    )
    comp.add_argument(
        "-i",
        "--integrators",
        nargs="+",
        default=None,
        help=f"integrators to compare, each one of {INTEGRATOR_NAMES} (default: "
        f"{' '.join(quick.integrators)}; with --full {' '.join(full.integrators)})",
    )
    comp.add_argument(
        "-o",
        "--output",
        default=None,
        help="output folder (default: alphaprk-compare-<system> in the current directory, created there)",
    )
    comp.add_argument("--no-plot", action="store_true", help="skip the figure (no matplotlib needed)")
    comp.add_argument(
        "--no-equal-cost",
        action="store_true",
        help="skip the RATTLE h/k row(s) that give the energy modes' gain at equal cost",
    )
    comp.add_argument(
        "--accuracy-steps",
        type=int,
        default=ACCURACY_STEPS,
        metavar="N",
        help=f"steps after which each row's position error against RATTLE at h/64 is taken, from the "
        f"start (default {ACCURACY_STEPS}: 20 fs at 2 fs; 0 skips it)",
    )
    _add_rebuild(comp)
    _add_run_options(comp, f"{MAIN_JOB.steps}; {FULL_COMPARISON.steps} with --full")
    add_file_arguments(comp)


def _add_analyze_parser(sub) -> None:
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
    analyze.add_argument("--rdf-bins", type=positive, default=100, help="RDF histogram bins (default 100)")
    analyze.add_argument(
        "--rdf-max",
        default="8A",
        help="largest RDF distance with a unit: 8A (default), 0.8nm; capped at half the box",
    )
    analyze.add_argument("--no-plot", action="store_true", help="skip the figures (no matplotlib needed)")
    analyze.add_argument("--quiet", action="store_true", help="no progress bars")


def _add_validate_parser(sub) -> None:
    validate = sub.add_parser(
        "validate",
        help="does the integrator bend the physics? equipartition, order, rescaling, T and V against h",
        description=(
            "Check run directories written with `alphaprk run --velocity-interval N` (trajectory.trr: "
            "positions and velocities) with physical_validation (Merz & Shirts, PLOS ONE 2018): (a) the "
            "temperature (K) of each partition of the kinetic energy (translation, rotation, internal; "
            "solute and solvent; random halves of the molecules) against the run's own and against "
            "--reference, in combined standard errors; (b) the integrator's order from the fluctuations of "
            "H (kJ/mol) at several step sizes, or for +rescale integrators whether H sits at round-off; (c) "
            "what the velocity scaling did (summary.json's rescaling) and the power of h it shrinks with; "
            "(d) the mean kinetic temperature (K) and potential energy (kJ/mol) against h, with the h -> 0 "
            "limit from the rattle rows. Directories of the same system, integrator and step are "
            "independent segments: their spread gives the errors. Writes validation.json. Needs the "
            'validate extra: pip install "openmm-alphaprk[validate]".'
        ),
    )
    validate.add_argument("runs", nargs="+", metavar="RUN_DIR", help="run directories, all of one system")
    validate.add_argument(
        "--reference",
        nargs="+",
        default=None,
        metavar="RUN_DIR",
        help="run directories of one setting to compare the partition temperatures with",
    )
    validate.add_argument(
        "-o", "--output", default="validation.json", help="the JSON written (default validation.json here)"
    )
    validate.add_argument(
        "--seed", type=int, default=0, help="seed of the random halves and of the bootstrap (default 0)"
    )
    validate.add_argument(
        "--workers",
        type=positive,
        default=min(
            4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        ),
        help="processes reading the trajectories (default: the cores of this machine, at most 4); the "
        "temperatures do not depend on it",
    )
    validate.add_argument("--quiet", action="store_true", help="no progress bars")


def _add_sweep_parser(sub) -> None:
    sweep = sub.add_parser(
        "sweep",
        help="run a grid of NVE runs (systems x integrators x step sizes x alpha x seeds) with dask",
        description=(
            "Expand the grids of a sweep configuration (TOML, see openmm_alphaprk.workflows.sweep) into "
            "independent runs, execute them on a dask.distributed cluster (a local one by default) and "
            "collect their summaries into sweep.csv in the output folder, rewritten as cells finish. Failed "
            "cells are recorded with their error; running the same command again skips finished cells and "
            "resumes interrupted ones. Needs the sweep extra: pip install 'openmm-alphaprk[sweep]'."
        ),
    )
    sweep.add_argument("config", help="sweep configuration file (TOML)")
    sweep.add_argument("--output", default=None, help="output folder (default: the configuration's `output`)")
    sweep.add_argument(
        "--scheduler", default=None, help="address of a running dask scheduler, e.g. tcp://host:8786"
    )
    sweep.add_argument(
        "--workers",
        type=positive,
        default=None,
        help="workers of the local cluster (default: the configuration's, else 1)",
    )
    sweep.add_argument("--retry-failed", action="store_true", help="run failed cells again")
    sweep.add_argument("--list", action="store_true", help="list the cells and their state, run nothing")
    _add_bench_parser(sub)
    _add_common(sweep)


def _add_bench_parser(sub) -> None:
    bench = sub.add_parser(
        "bench",
        help="benchmarks against RATTLE: `bench cost` (time per step), `bench energy` (H - E_ref), "
        "`bench accuracy` (trajectory error against a small-step reference), `bench long` (long NVE runs: "
        "drift, windowed RMS, ns/day)",
        description=(
            "cost: time per step and per force evaluation of each integrator against RattleIntegrator, "
            "interleaved rounds on one water box. energy: H - E_ref of the energy modes against RATTLE from "
            "the same start, at the same step and at equal cost; --system tip3p-3nm villin runs the "
            "package's systems in one run. accuracy: position and velocity errors against RATTLE at h/64 "
            "after several horizons, with RATTLE and RATTLE + rescaling at equal force evaluations and "
            "RATTLE at equal wall time. long: long NVE runs of every row from one start (drift per ns per "
            "DOF with block standard errors, RMS |H - E_ref| per window, ns/day against VerletIntegrator), "
            "written as they go and resumed by the same command. `alphaprk bench NAME --help` lists each "
            "one's options."
        ),
    )
    bench.add_argument("benchmark", choices=BENCHMARKS, help="which benchmark")
    bench.add_argument(
        "options", nargs=argparse.REMAINDER, help="the benchmark's own options (see its --help)"
    )


def _add_run_options(parser: argparse.ArgumentParser, default_steps: str = f"{DEFAULTS.steps}") -> None:
    """Add the options of :class:`~openmm_alphaprk.runs.RunOptions`, with its defaults."""
    length = parser.add_mutually_exclusive_group()
    length.add_argument(
        "--steps", type=positive, default=None, help=f"number of MD steps (default {default_steps})"
    )
    length.add_argument(
        "--length", default=None, help="simulated time instead of --steps, with a unit: 10ps, 0.5ns"
    )
    timestep = f"{DEFAULTS.timestep_ps * 1000:g}fs"
    parser.add_argument(
        "--timestep",
        default=timestep,
        help=f"step size with a unit: {timestep} (default), 0.001ps; fs, ps or ns",
    )
    parser.add_argument(
        "--platform",
        default=AUTO,
        help=f"OpenMM platform: {AUTO} (default: the fastest present, CUDA, then HIP, then OpenCL on a "
        "GPU, else CPU; printed), CPU, Reference (double precision, slow), CUDA, OpenCL, HIP",
    )
    parser.add_argument(
        "--precision",
        choices=PRECISIONS,
        default=DEFAULTS.precision,
        help="floating-point precision for CUDA/OpenCL (default: the platform's own)",
    )
    tolerance = re.sub(r"e([-+])0*(\d)", r"e\1\2", f"{DEFAULTS.constraint_tolerance:g}")  # 1e-08 -> 1e-8
    parser.add_argument(
        "--constraint-tolerance",
        type=float,
        default=DEFAULTS.constraint_tolerance,
        help="relative tolerance of SHAKE/SETTLE/CCMA and velocity constraints "
        f"(dimensionless; default {tolerance})",
    )
    _add_interval_options(parser)
    _add_common(parser)


def _add_interval_options(parser: argparse.ArgumentParser) -> None:
    """Add the intervals (steps) and the checkpoint time of :class:`~openmm_alphaprk.runs.RunOptions`."""
    parser.add_argument(
        "--energy-interval",
        type=positive,
        default=DEFAULTS.energy_interval,
        help=f"steps between rows of energies.csv (default {DEFAULTS.energy_interval}; "
        "each costs an extra energy evaluation)",
    )
    parser.add_argument(
        "--trajectory-interval",
        type=positive,
        default=DEFAULTS.trajectory_interval,
        help=f"steps between DCD frames (default {DEFAULTS.trajectory_interval})",
    )
    parser.add_argument(
        "--velocity-interval",
        type=positive,
        default=DEFAULTS.velocity_interval,
        help="steps between frames of trajectory.trr: positions, velocities and box, as GROMACS writes "
        "them (default: none); what `alphaprk validate` and velocity autocorrelations read",
    )
    parser.add_argument(
        "--controller-interval",
        type=positive,
        default=DEFAULTS.controller_interval,
        help="energy mode: steps between rows of controller.csv (default: the energy interval; 1 records "
        "every step but steps one step at a time; statistics over every step come from the integrator)",
    )
    parser.add_argument(
        "--checkpoint-interval",
        type=positive,
        default=DEFAULTS.checkpoint_interval,
        help="steps between checkpoints; an interrupted run resumes from the last one "
        f"(default {DEFAULTS.checkpoint_interval})",
    )
    parser.add_argument(
        "--checkpoint-seconds",
        type=float,
        default=DEFAULTS.checkpoint_seconds,
        help="also write a checkpoint after this much wall time, in seconds (default "
        f"{DEFAULTS.checkpoint_seconds:g}); Ctrl-C writes one too and says from which step the same "
        "command resumes",
    )


def _add_rebuild(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--rebuild",
        action="store_true",
        help="build the start state here from the definition (minimize, equilibrate; replaces the cache "
        "entry) instead of using the shipped or cached one; a later call without --rebuild uses the "
        "shipped state again where there is one",
    )


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--cache-dir",
        default=None,
        help="cache of equilibrated systems (default $ALPHAPRK_CACHE_DIR, else ~/.cache/openmm_alphaprk)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
