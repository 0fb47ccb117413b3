"""Cost benchmark: ms/step, ns/day and force evaluations/step against a baseline integrator.

Every integrator starts from the same equilibrated state (a TIP3P box built here, or a
package system such as ``tip3p-3nm``, ``villin`` or ``dhfr``) on the same platform and
step; the timings are interleaved over several rounds and the median is taken, so the
ratios to the first integrator (``VerletIntegrator`` in the core set) come from the same
run on the same machine. A separate short pass records the RMS of H − E0 (every step)
for each integrator.

The command is ``alphaprk bench cost``; ``--help`` lists its options.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from functools import partial

import openmm as mm
import openmm.unit as unit

from ..integrators import (
    PACKAGE_INTEGRATORS,
    check_context,
    counted_force_evaluations,
    force_evaluations_per_step,
)
from ..observables import energy_residuals, rms
from ..runs.integrator_names import UnknownIntegratorError, label, make_integrator, parse_integrator
from ..systems import PreparedSystem, build_water_box, list_systems, prepare_system
from ..systems.definitions import DefinitionError
from ..systems.files import repartition_hydrogen_mass
from .schema import keyed_rows


@dataclass
class BenchmarkRow:
    """One integrator's measurements.

    ``time_ratio`` is against the first row; ``ratio_per_evaluation`` is the step time
    per force evaluation against RATTLE's (NaN without that row); ``ns_per_day`` is the
    simulated time a day at ``ms_per_step`` and the integrator's step size (NaN where it
    has none).
    """

    name: str
    ms_per_step: float
    time_ratio: float
    force_evaluations_per_step: float
    energy_rms: float
    ratio_per_evaluation: float = float("nan")
    host_syncs_per_step: float = 0.0
    ns_per_day: float = float("nan")


#: Integrator names (:mod:`openmm_alphaprk.runs.integrator_names`) of the core benchmark; the first is
#: the baseline of the time ratios.
CORE = ("verlet", "rattle", "rattle+rescale", "alpha=0", "alpha=1/6", "alpha=1/2")
#: Every program: the core set, α-RATTLE-4 (α = 0 and 0.05), RATTLE-4 + rescaling, α-RATTLE-6 at α = 0
#: and both energy modes.
ALL = (*CORE, "alpha4=0", "alpha4=0.05", "rattle4+rescale", "alpha6=0", "energy", "energy4")


def cost_benchmark_integrators(
    timestep: float, names: Sequence[str] = CORE
) -> dict[str, Callable[[], mm.Integrator]]:
    """Return the integrators ``names`` (default: the core set) by label."""
    return {label(name): partial(make_integrator, name, timestep) for name in names}


def all_integrators(timestep: float) -> dict[str, Callable[[], mm.Integrator]]:
    """Return :data:`ALL`: every program."""
    return cost_benchmark_integrators(timestep, ALL)


#: Integrator sets of ``--integrators``.
INTEGRATOR_SETS = {"core": cost_benchmark_integrators, "all": all_integrators}
#: The names of each set of ``--integrators``.
INTEGRATOR_SET_NAMES = {"core": CORE, "all": ALL}


def integrator_names(choices: Sequence[str]) -> list[str]:
    """Return the integrator names of ``--integrators``: ``core``, ``all`` or names, in order.

    ``core`` and ``all`` stand for their sets; any other entry is a name of the package's
    vocabulary (:func:`~openmm_alphaprk.runs.integrator_names.parse_integrator`).

    Raises
    ------
    UnknownIntegratorError
        For a name the vocabulary does not have.
    ValueError
        For an integrator given twice (the same label).
    """
    names: list[str] = []
    for choice in choices:
        for name in INTEGRATOR_SET_NAMES.get(choice.strip().lower(), (choice,)):
            parse_integrator(name)
            names.append(name)
    labels = [label(name) for name in names]
    twice = sorted({text for text in labels if labels.count(text) > 1})
    if twice:
        raise ValueError(f"--integrators: {', '.join(twice)} given twice")
    return names


def ns_per_day(ms_per_step: float, timestep_ps: float) -> float:
    """Return the simulated ns a day at ``ms_per_step`` ms a step of ``timestep_ps`` ps."""
    if not ms_per_step > 0:
        return float("nan")
    return 86400.0 / (ms_per_step / 1e3) * timestep_ps / 1e3


def _context(
    box: PreparedSystem,
    integrator: mm.Integrator,
    platform: mm.Platform,
    tolerance: float | None = None,
    properties: dict[str, str] | None = None,
) -> mm.Context:
    """Make a context at the box's state; ``tolerance`` (if given) sets the constraint tolerance."""
    if tolerance is not None:
        integrator.setConstraintTolerance(tolerance)
    context = mm.Context(box.system, integrator, platform, properties or {})
    check_context(integrator, context)  # the energy modes' tolerance from the platform's precision
    context.setPositions(box.positions)
    context.setVelocities(box.velocities)
    return context


def interleaved_timing(
    integrators: dict[str, tuple],
    steps: int,
    rounds: int,
    progress: bool = False,
) -> dict[str, float]:
    """Median wall time (ms) per benchmark step of each integrator, from interleaved rounds.

    Each round steps every integrator in turn, so that any load on the machine falls on
    all of them alike; every second round takes them in reverse order, so that what ran
    just before an integrator (and the machine's drift within a round) does too.
    ``integrators`` maps a name to (integrator, integrator steps per
    benchmark step) or (integrator, steps per benchmark step, context); each round takes
    ``steps`` benchmark steps of each. Where the context is given, each timed stretch
    lies between two ``getState(getEnergy=True)`` calls, which wait for the device (as
    OpenMM's own benchmark script times it): on a GPU ``step()`` returns before the
    kernels it queued have run. With no rounds the result is empty.
    """
    times: dict[str, list[float]] = {name: [] for name in integrators}
    order = list(integrators)
    for round_index in range(rounds):
        for name in order if round_index % 2 == 0 else order[::-1]:
            integrator, substeps, *context = integrators[name]
            if progress:
                print(f"round {round_index + 1}/{rounds}: {name}", file=sys.stderr, flush=True)
            if context:
                context[0].getState(getEnergy=True)
            start = time.perf_counter()
            integrator.step(steps * substeps)
            if context:
                context[0].getState(getEnergy=True)
            times[name].append((time.perf_counter() - start) / steps * 1e3)
    return {name: statistics.median(values) for name, values in times.items() if values}


def run_benchmark(
    box: PreparedSystem,
    integrators: dict[str, Callable[[], mm.Integrator]],
    *,
    platform: str = "CPU",
    steps: int = 100,
    rounds: int = 3,
    energy_steps: int = 100,
    constraint_tolerance: float = 1e-8,
    progress: bool = True,
    properties: dict[str, str] | None = None,
) -> list[BenchmarkRow]:
    """Time each integrator and measure its energy fluctuation on the same state.

    Parameters
    ----------
    box
        The system and its equilibrated state.
    integrators
        Factories by display name; the first is the baseline of the time ratios.
    platform
        OpenMM platform name.
    steps
        Steps timed per integrator per round.
    rounds
        Interleaved timing rounds; the median ms/step is reported.
    energy_steps
        Steps of the separate energy pass (energy read after every step).
    constraint_tolerance
        Applied to every integrator.
    progress
        Print progress to stderr.
    properties
        Platform properties (e.g. ``{"Precision": "mixed"}``).

    Returns
    -------
    list of BenchmarkRow
        In the order of ``integrators``.

    """
    plat = mm.Platform.getPlatformByName(platform)
    # keep the Python integrator objects: Context.getIntegrator() returns a plain
    # CustomIntegrator whose step() skips this package's checks
    runs = {}
    for name, make in integrators.items():
        integrator = make()
        runs[name] = integrator, _context(box, integrator, plat, constraint_tolerance, properties)
    rows = _timed_rows(runs, steps, rounds, progress)
    del runs
    for row, make in zip(rows, integrators.values()):
        if progress:
            print(f"energy pass: {row.name}", file=sys.stderr, flush=True)
        context_args = (plat, constraint_tolerance, properties)
        row.energy_rms = _energy_rms(box, make(), context_args, energy_steps)
    return rows


def _timed_rows(runs: dict, steps: int, rounds: int, progress: bool) -> list[BenchmarkRow]:
    """Time the integrators of ``runs`` (name → (integrator, context)) in interleaved rounds."""
    for integrator, _ in runs.values():
        integrator.step(2)  # program analysis and first force evaluations
    evaluations_before = {
        name: counted_force_evaluations(integrator) for name, (integrator, _) in runs.items()
    }
    syncs_before = {name: _host_syncs(integrator) for name, (integrator, _) in runs.items()}
    medians = interleaved_timing(
        {name: (integrator, 1, context) for name, (integrator, context) in runs.items()},
        steps,
        rounds,
        progress,
    )
    rows = []
    baseline = medians[next(iter(medians))]
    for name, (integrator, _) in runs.items():
        step = _step_size_ps(integrator)
        evaluations = counted_force_evaluations(integrator)
        timed = steps * rounds
        per_step = (
            (evaluations - evaluations_before[name]) / timed
            if evaluations is not None
            else force_evaluations_per_step(integrator)
        )
        syncs = (_host_syncs(integrator) - syncs_before[name]) / timed
        ms = medians[name]
        rows.append(
            BenchmarkRow(
                name,
                ms,
                ms / baseline,
                per_step,
                float("nan"),
                host_syncs_per_step=syncs,
                ns_per_day=float("nan") if step is None else ns_per_day(ms, step),
            )
        )
    rattle = medians.get(label("rattle"))
    for row in rows:
        if rattle:
            row.ratio_per_evaluation = row.ms_per_step / row.force_evaluations_per_step / rattle
    return rows


def _step_size_ps(integrator: mm.Integrator) -> float | None:
    """Return the integrator's step size in ps (None where it has none)."""
    try:
        step = integrator.getStepSize()
    except (AttributeError, TypeError, mm.OpenMMException):
        return None
    value = step.value_in_unit(unit.picoseconds) if unit.is_quantity(step) else float(step)
    return value if value > 0 else None


def _energy_rms(box: PreparedSystem, integrator: mm.Integrator, context_args: tuple, steps: int) -> float:
    """RMS of H − E0 (kJ/mol) over ``steps`` steps, the energy read after every step."""
    context = _context(box, integrator, *context_args)
    return rms(energy_residuals(context, integrator, steps).residuals)


def _host_syncs(integrator: mm.Integrator) -> float:
    """Return the sums over degrees of freedom counted by our integrators (0 for others)."""
    if isinstance(integrator, PACKAGE_INTEGRATORS):
        return integrator.getGlobalVariableByName("host_syncs")
    return 0.0


def format_cost_table(rows: Sequence[BenchmarkRow], header: str = "") -> str:
    """Format benchmark rows as a plain-text table."""
    lines = [header] if header else []
    columns = (
        ("ms/step", 9),
        ("ns/day", 9),
        ("time ratio", 11),
        ("force evals/step", 17),
        ("per eval vs RATTLE", 19),
        ("syncs/step", 11),
        ("RMS(H-E0) kJ/mol", 17),
    )
    lines.append(f"{'integrator':<22} " + " ".join(f"{title:>{width}}" for title, width in columns))
    for row in rows:
        lines.append(
            f"{row.name:<22} {row.ms_per_step:>9.3f} {row.ns_per_day:>9.2f} {row.time_ratio:>11.2f} "
            f"{row.force_evaluations_per_step:>17.2f} {row.ratio_per_evaluation:>19.2f} "
            f"{row.host_syncs_per_step:>11.2f} {row.energy_rms:>17.4f}"
        )
    return "\n".join(lines)


def add_box_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the water-box options both benchmark commands share (--box, --cutoff, and the platform's)."""
    parser.add_argument(
        "--box", type=float, default=3.0, help="cubic box edge in nm (default 3.0: ~2,600 atoms)"
    )
    parser.add_argument(
        "--cutoff", type=float, default=0.9, help="PME direct-space cutoff in nm (default 0.9)"
    )
    add_platform_arguments(parser)


def add_platform_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options every benchmark command shares: --timestep, --platform, --precision."""
    parser.add_argument("--timestep", type=float, default=2.0, help="step size in fs (default 2)")
    parser.add_argument("--platform", default="CPU", help="OpenMM platform (default CPU)")
    parser.add_argument(
        "--precision",
        choices=("single", "mixed", "double"),
        default=None,
        help="precision on CUDA, OpenCL or HIP (default: the platform's, single)",
    )


def build_platform(args: argparse.Namespace) -> str:
    """Platform to build and equilibrate the box on: the benchmark's, except OpenCL (CPU).

    OpenMM's energy minimizer crashes on OpenCL through pocl (seen with OpenMM 8.6.1),
    the OpenCL platform CI has.
    """
    return "CPU" if args.platform == "OpenCL" else args.platform


def platform_properties(args: argparse.Namespace) -> dict[str, str]:
    """Platform properties from ``--precision`` (only on platforms that have one)."""
    return {"Precision": args.precision} if args.precision else {}


#: Precision of each platform where ``--precision`` is not given (OpenMM's defaults).
DEFAULT_PRECISION = {"Reference": "double", "CPU": "single (the CPU platform's)"}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="alphaprk bench cost",
        description="Time RATTLE and α-RATTLE against VerletIntegrator (or the first of --integrators), "
        "from the same start: a TIP3P box built here (--box) or a package system (--system).",
    )
    add_box_arguments(parser)
    parser.add_argument(
        "--system",
        default=None,
        metavar="NAME",
        help="time on this system of `alphaprk systems` (e.g. tip3p-3nm, villin, dhfr) instead of a --box: "
        "its equilibrated state from the package or the systems cache (built the first time); "
        "--box, --cutoff and --equilibration-steps do not apply to it",
    )
    parser.add_argument(
        "--hydrogen-mass",
        type=float,
        default=None,
        metavar="AMU",
        help="hydrogen mass repartitioning (e.g. 3 for a 4 fs step): hydrogens bonded to a heavy atom get "
        "this mass, taken from that atom (water's are left alone); applied to the equilibrated start",
    )
    parser.add_argument(
        "--steps", type=int, default=100, help="timed steps per integrator per round (default 100)"
    )
    parser.add_argument("--rounds", type=int, default=3, help="interleaved timing rounds (default 3)")
    parser.add_argument(
        "--energy-steps", type=int, default=100, help="steps of the energy pass (default 100)"
    )
    parser.add_argument(
        "--equilibration-steps",
        type=int,
        default=1000,
        help="2 fs Langevin steps at 300 K first (default 1000)",
    )
    parser.add_argument(
        "--integrators",
        nargs="+",
        default=["core"],
        metavar="NAME",
        help="core (default): Verlet, RATTLE, RATTLE + rescaling, α = 0, 1/6, 1/2; all: also α-RATTLE-4, "
        "RATTLE-4 + rescaling, α-RATTLE-6 and the energy modes; or integrator names, e.g. verlet rattle "
        "rattle+rescale alpha4=0 rattle4+rescale (`alphaprk run --help` lists them; core and all may be "
        "among them); the first is the baseline of the time ratios",
    )
    parser.add_argument("--json", help="also write the rows to this JSON file")
    return parser


def _start(args: argparse.Namespace) -> tuple[PreparedSystem, str]:
    """Return the start (the system's, or a TIP3P box built here) and its description for the header."""
    if args.system is None:
        print(f"building a {args.box} nm TIP3P box ...", file=sys.stderr, flush=True)
        box = build_water_box(
            args.box,
            cutoff=args.cutoff,
            equilibration_steps=args.equilibration_steps,
            platform=build_platform(args),
        )
        description = f"TIP3P box {args.box} nm, PME cutoff {args.cutoff} nm"
    else:
        box = prepare_system(args.system, progress=True)
        description = f"system {box.name} ({box.definition.description or 'see alphaprk systems'})"
    # a copy of the System (the shipped one may be shared), with the start's box as its default
    system = mm.XmlSerializer.clone(box.system)
    if system.usesPeriodicBoundaryConditions():
        system.setDefaultPeriodicBoxVectors(*box.state.getPeriodicBoxVectors())
    if args.hydrogen_mass is not None:
        for change in repartition_hydrogen_mass(system, args.hydrogen_mass, box.topology):
            print(f"{box.name}: {change}", file=sys.stderr, flush=True)
        description += f", hydrogen mass {args.hydrogen_mass:g} amu (repartitioned)"
    return dataclasses.replace(box, system=system), description


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.box <= 0 or args.timestep <= 0 or args.steps <= 0 or args.rounds <= 0:
        parser.error("--box, --timestep, --steps and --rounds must be positive")
    if args.hydrogen_mass is not None and not 1.0 <= args.hydrogen_mass <= 4.0:
        parser.error(
            f"--hydrogen-mass {args.hydrogen_mass:g} amu is outside 1-4 amu (3 or 4 for a 4 fs step)"
        )
    if args.system is not None and args.system not in list_systems() and not args.system.endswith(".toml"):
        parser.error(f"--system: unknown system {args.system!r}; choose from {', '.join(list_systems())}")
    try:
        names = integrator_names(args.integrators)
    except (UnknownIntegratorError, ValueError) as error:
        parser.error(str(error))
    try:
        box, description = _start(args)
    except DefinitionError as error:
        parser.error(str(error))
    timestep = args.timestep / 1000.0
    rows = run_benchmark(
        box,
        cost_benchmark_integrators(timestep, names),
        platform=args.platform,
        steps=args.steps,
        rounds=args.rounds,
        energy_steps=args.energy_steps,
        properties=platform_properties(args),
    )
    precision = args.precision or DEFAULT_PRECISION.get(args.platform, "single (the platform's default)")
    header = (
        f"{description}, {box.n_atoms} atoms, {args.timestep} fs, platform {args.platform}, "
        f"precision {precision}; time ratio against {rows[0].name}; ns/day from ms/step and the step; "
        f"per eval: ms/step per force evaluation against RATTLE's; median of {args.rounds} rounds "
        f"x {args.steps} steps; RMS(H-E0) over {args.energy_steps} steps (VerletIntegrator's kinetic "
        "energy is its leapfrog estimate)"
    )
    print(format_cost_table(rows, header))
    if args.json:
        result = {
            "header": header,
            "system": box.name if args.system is not None else f"tip3p-box-{args.box:g}nm",
            "atoms": box.n_atoms,
            "platform": args.platform,
            "precision": precision,
            "timestep_fs": args.timestep,
            "hydrogen_mass_amu": args.hydrogen_mass,
            "integrators": names,
            "rows": keyed_rows((asdict(row) for row in rows), names),
        }
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(result, handle, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
