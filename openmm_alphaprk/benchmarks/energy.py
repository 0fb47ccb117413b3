"""Energy benchmark: the energy modes and α-RATTLE-4 against RATTLE from the same start.

Every integrator runs NVE from the same equilibrated TIP3P state, on the same
platform and step, in the same process. After every step the total energy is read
from the context (``State`` potential + kinetic energy, on-step velocities) and
compared with the starting energy E_ref. Reported per integrator: drift (linear fit,
kJ/mol/ns per degree of freedom), RMS and max of H − E_ref, for the energy mode the
α* percentiles and the fractions of steps within tolerance / fallen back / at a
bound, force evaluations per step, and ms/step as a ratio to RATTLE from separate,
interleaved timing rounds without energy read-out. RATTLE also runs at h/k, with k
α-RATTLE-4's measured force evaluations per step (equal cost). ``--scan`` adds a
step-size scan for the largest stable step of each integrator.

``--system tip3p-3nm villin`` runs the package's systems one after the other in one
run. The command is ``alphaprk bench energy`` (:func:`main`, with the tables and JSON
it prints and writes); ``--help`` lists its options.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from functools import partial

import numpy as np
import openmm as mm
import openmm.unit as unit
from tqdm import tqdm

from ..equal_cost import equal_cost_divisor, gain, gain_text
from ..integrators import force_evaluations_per_step
from ..observables import (
    alpha_percentiles,
    degrees_of_freedom,
    drift_text,
    energy_residuals,
    fit_drift,
    rms,
)
from ..runs.integrator_names import SubStepped, at_divisor, label, make_integrator
from ..systems import PreparedSystem, build_water_box, list_systems, prepare_system
from ..systems.arguments import add_file_arguments, system_to_prepare, unknown_systems
from .cost import _context, add_box_arguments, build_platform, interleaved_timing, platform_properties
from .schema import keyed_rows


@dataclass
class EnergyRow:
    """One integrator's measurements (energies in kJ/mol)."""

    name: str
    steps: int
    drift_per_dof: float  # kJ/mol/ns per degree of freedom, linear fit (observables.fit_drift)
    rms_residual: float
    max_abs_residual: float
    force_evaluations_per_step: float
    drift_per_dof_standard_error: float = float("nan")
    ms_per_step: float = float("nan")
    time_ratio: float = float("nan")
    alpha_percentiles: dict[str, float] = field(default_factory=dict)
    fraction_within_tolerance: float = float("nan")
    fraction_fallen_back: float = float("nan")
    fraction_at_bound: float = float("nan")
    reference_resets: int | None = None
    blew_up_at_step: int | None = None


#: The rows, by integrator name (:mod:`openmm_alphaprk.runs.integrator_names`); the first is the baseline.
INTEGRATOR_NAMES = ("rattle", "rattle+rescale", "energy", "alpha4=0", "rattle4+rescale", "energy4")
#: α-RATTLE-4's fixed α values scanned beside the energy modes (with ``alpha4=0``: the fixed-α scan).
FIXED_ALPHA_SCAN = (0.005, 0.01, 0.015, 0.02)
#: Label of the row whose force evaluations per step set k for the equal-cost RATTLE row.
EQUAL_COST_REFERENCE = label("energy4")


def energy_benchmark_integrators(
    timestep: float, names: Sequence[str] = INTEGRATOR_NAMES
) -> dict[str, SubStepped]:
    """RATTLE (the baseline), both energy modes and α-RATTLE-4 at α = 0, by label.

    The equal-cost row (RATTLE at h/k, k = α-RATTLE-4's mean force evaluations per
    step) is added by :func:`run_energy_benchmark` once k is measured.
    """
    return {label(name): at_divisor(name, timestep) for name in names}


def equal_cost_label(k: int | str) -> str:
    """Return the label of the equal-cost row, ``RATTLE h/k``."""
    return f"{label('rattle')} h/{k}"


def equal_cost_rattle(timestep: float, k: int) -> SubStepped:
    """RATTLE at h/k, k sub-steps per benchmark step: the same force evaluations as k per step."""
    return at_divisor("rattle", timestep, k)


def _run_one(
    name: str,
    spec: SubStepped,
    box: PreparedSystem,
    plat: mm.Platform,
    samples: int,
    dof: int,
    progress: bool,
    every: int = 1,
    properties: dict[str, str] | None = None,
) -> tuple[EnergyRow, np.ndarray, mm.Integrator, mm.Context]:
    integrator = spec.make()
    context = _context(box, integrator, plat, properties=properties)
    step_ps = integrator.getStepSize().value_in_unit(unit.picoseconds) * spec.substeps * every
    alphas = np.full(samples, np.nan)
    energy_mode = getattr(integrator, "energy_mode", False)

    def record_alpha(i: int, residual: float) -> None:
        if energy_mode:
            alphas[i] = integrator.alpha

    trace = energy_residuals(
        context,
        integrator,
        samples,
        steps_per_sample=spec.substeps * every,
        blow_up=BLOW_UP_ENERGY,
        each_sample=record_alpha,
        progress=partial(tqdm, desc=name, disable=not progress, mininterval=5.0, file=sys.stderr),
    )
    residuals = trace.residuals
    blew_up = None if trace.blew_up_at is None else trace.blew_up_at * every
    done = np.isfinite(residuals)
    times = (np.arange(samples) + 1) * step_ps
    drift, drift_error = fit_drift(times[done], residuals[done]).per_dof(dof)
    row = EnergyRow(
        name=name,
        steps=int(done.sum()) * every,
        drift_per_dof=drift,
        drift_per_dof_standard_error=drift_error,
        rms_residual=rms(residuals[done]),
        max_abs_residual=float(np.max(np.abs(residuals[done]))) if done.any() else float("nan"),
        force_evaluations_per_step=force_evaluations_per_step(integrator) * spec.substeps,
        blew_up_at_step=blew_up,
    )
    if energy_mode:
        totals = integrator.controller_totals()
        row.alpha_percentiles = alpha_percentiles(alphas)
        row.fraction_within_tolerance = totals["fraction_within_tolerance"]
        row.fraction_fallen_back = totals["fraction_fallen_back"]
        row.fraction_at_bound = totals["fraction_at_bound"]
        row.reference_resets = totals["reference_resets"]
    return row, residuals, integrator, context


#: |H − E_ref| (kJ/mol) above which a run counts as blown up.
BLOW_UP_ENERGY = 1e4


def run_energy_benchmark(
    box: PreparedSystem,
    integrators: dict[str, SubStepped],
    *,
    platform: str = "CPU",
    steps: int = 10_000,
    sample_every: int = 1,
    equal_cost: bool = True,
    timing_steps: int = 100,
    timing_rounds: int = 3,
    progress: bool = True,
    properties: dict[str, str] | None = None,
) -> tuple[list[EnergyRow], dict[str, np.ndarray]]:
    """Run each integrator for ``steps`` steps from the same state; time them after.

    Parameters
    ----------
    box
        System and equilibrated state.
    integrators
        Rows by name; the first is the baseline of the time ratios.
    platform
        OpenMM platform name.
    steps
        Benchmark steps per row (a row with ``substeps`` k takes k integrator steps each).
    sample_every
        Read the energy every this many benchmark steps (RMS and α* percentiles are
        over the samples).
    equal_cost
        If the row :data:`EQUAL_COST_REFERENCE` is present, add "RATTLE h/k" with k its
        measured force evaluations per step, rounded up.
    timing_steps, timing_rounds
        The interleaved timing rounds (no energy read-out) for the ms/step column.
    progress
        Progress bars on stderr.
    properties
        Platform properties (e.g. ``{"Precision": "mixed"}``).

    Returns
    -------
    rows
        One :class:`EnergyRow` per integrator, in order.
    residuals
        H − E_ref after every benchmark step, by row name (for plots).
    """
    run = dict(
        plat=mm.Platform.getPlatformByName(platform),
        samples=steps // sample_every,
        dof=degrees_of_freedom(box.system),
        progress=progress,
        every=sample_every,
        properties=properties,
    )
    rows, traces, runs = _run_rows(box, dict(integrators), equal_cost, run)
    _add_timing(rows, runs, timing_steps, timing_rounds)
    return rows, traces


def _run_rows(box: PreparedSystem, integrators: dict, equal_cost: bool, run: dict) -> tuple:
    """Run every row in turn; the equal-cost RATTLE row joins once its k is measured."""
    rows, traces, runs = [], {}, {}
    names = list(integrators)
    while names:
        name = names.pop(0)
        spec = integrators[name]
        row, residuals, integrator, context = _run_one(name, spec, box, **run)
        rows.append(row)
        traces[name] = residuals
        runs[name] = integrator, context, spec.substeps
        if equal_cost and name == EQUAL_COST_REFERENCE and row.blew_up_at_step is None:
            k = equal_cost_divisor(row.force_evaluations_per_step)
            timestep = integrator.getStepSize().value_in_unit(unit.picoseconds)
            equal_name = equal_cost_label(k)
            integrators[equal_name] = equal_cost_rattle(timestep, k)
            names.append(equal_name)
    return rows, traces, runs


def _add_timing(rows: list[EnergyRow], runs: dict, steps: int, rounds: int) -> None:
    """Fill ms/step and the time ratio to the first row from interleaved rounds (no energy read-out)."""
    medians = interleaved_timing(
        {
            row.name: (runs[row.name][0], runs[row.name][2], runs[row.name][1])
            for row in rows
            if row.blew_up_at_step is None
        },
        steps,
        rounds,
    )
    baseline = medians.get(rows[0].name, float("nan"))
    for row in rows:
        if row.name in medians:
            row.ms_per_step = medians[row.name]
            row.time_ratio = row.ms_per_step / baseline


def largest_stable_step(
    box: PreparedSystem,
    make: Callable[[float], mm.Integrator],
    steps_fs: Sequence[float],
    *,
    platform: str = "CPU",
    time_ps: float = 1.0,
    properties: dict[str, str] | None = None,
) -> tuple[float | None, dict[float, str]]:
    """Step-size scan: the largest step (fs) of ``steps_fs`` that runs ``time_ps`` without blowing up.

    A run blows up when a step raises (e.g. the midpoint iteration diverges), the
    energy is not finite, or |H − E_ref| exceeds :data:`BLOW_UP_ENERGY`. The scan
    goes up in ``steps_fs`` and stops at the first failure.

    Returns
    -------
    largest
        The largest stable step (fs), or None if the smallest already failed.
    outcomes
        "stable (max |H − E_ref| ...)" or the failure, by step size.
    """
    plat = mm.Platform.getPlatformByName(platform)
    largest, outcomes = None, {}
    for h_fs in sorted(steps_fs):
        integrator = make(h_fs / 1000.0)
        context = _context(box, integrator, plat, properties=properties)
        n = int(round(time_ps / (h_fs / 1000.0)))
        trace = energy_residuals(context, integrator, n, blow_up=BLOW_UP_ENERGY)
        failure = None
        if trace.error is not None:
            failure = f"failed: {trace.error}"
        elif trace.blew_up_at is not None:
            failure = f"blew up (|H - E_ref| = {abs(trace.residuals[trace.blew_up_at]):.3g} kJ/mol)"
        worst = float(np.nanmax(np.abs(trace.residuals))) if not failure else 0.0
        del context
        if failure:
            outcomes[h_fs] = failure
            break
        outcomes[h_fs] = f"stable (max |H - E_ref| {worst:.3g} kJ/mol)"
        largest = h_fs
    return largest, outcomes


def fixed_alpha_names(values: Sequence[float]) -> tuple[str, ...]:
    """Integrator names of α-RATTLE-4 with the fixed α ``values`` (``alpha4=0.01`` …)."""
    return tuple(f"alpha4={value:g}" for value in values)


def best_fixed_alpha(rows: Sequence[EnergyRow]) -> EnergyRow | None:
    """Return the α-RATTLE-4 fixed-α row (``alpha4=0`` included) with the lowest RMS(H − E_ref), if any."""
    prefix = label("alpha4=0").removesuffix("0")  # "α-RATTLE-4 α = "
    fixed = [
        row
        for row in rows
        if row.name.startswith(prefix) and row.blew_up_at_step is None and np.isfinite(row.rms_residual)
    ]
    return min(fixed, key=lambda row: row.rms_residual, default=None)


def ratios_to_rattle(rows: Sequence[EnergyRow]) -> dict[str, dict[str, float | str]]:
    """RMS(H − E_ref) of the baselines over each row's: RATTLE (same step, equal cost), fixed α.

    ``rms_vs_rattle``: RATTLE's RMS / the row's (how many times lower the row is than
    RATTLE at the same step). ``rms_vs_rattle_equal_cost``: the equal-cost RATTLE row's
    RMS (RATTLE at h/k, k the force evaluations per step of :data:`EQUAL_COST_REFERENCE`)
    / the row's, given for the rows whose evaluations per step round up to that k.
    For the energy-mode rows also ``rms_vs_alpha4_0`` (the order-4 composition of RATTLE steps: its RMS / the
    row's) and ``rms_vs_best_fixed_alpha`` with ``best_fixed_alpha`` (the label of the
    fixed-α row with the lowest RMS), where those rows ran; a ratio below 1 means the
    baseline did better.
    """
    by_name = {row.name: row for row in rows}
    rattle = by_name.get(label("rattle"))
    equal = next((row for row in rows if row.name.startswith(equal_cost_label(""))), None)
    composition_at_alpha_0 = by_name.get(label("alpha4=0"))
    best = best_fixed_alpha(rows)
    energy_labels = {label("energy"), label("energy4")}
    ratios = {}
    for row in rows:
        if rattle is None or row is rattle or row is equal or not row.rms_residual > 0:
            continue
        entry: dict[str, float | str] = {"rms_vs_rattle": gain(rattle.rms_residual, row.rms_residual)}
        same_cost = equal is not None and equal_cost_divisor(row.force_evaluations_per_step) == round(
            equal.force_evaluations_per_step
        )
        if same_cost:
            entry["rms_vs_rattle_equal_cost"] = gain(equal.rms_residual, row.rms_residual)
        if row.name in energy_labels:
            if composition_at_alpha_0 is not None:
                entry["rms_vs_alpha4_0"] = gain(composition_at_alpha_0.rms_residual, row.rms_residual)
            if best is not None:
                entry["best_fixed_alpha"] = best.name
                entry["rms_vs_best_fixed_alpha"] = gain(best.rms_residual, row.rms_residual)
        ratios[row.name] = entry
    return ratios


def format_energy_table(rows: Sequence[EnergyRow], header: str = "") -> str:
    """Format the rows as a plain-text table."""
    lines = [header] if header else []
    width = max([16, *(len(row.name) for row in rows)])
    lines.append(
        f"{'integrator':<{width}} {'steps':>6} {'drift/DOF kJ/mol/ns ± SE':<26} {'RMS(H-Eref)':>11} "
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
            f"{row.name:<{width}} {row.steps:>6} {drift:<26} {row.rms_residual:>11.4g} "
            f"{row.max_abs_residual:>11.4g} {row.force_evaluations_per_step:>10.2f} {row.time_ratio:>10.2f} "
            f"{row.fraction_within_tolerance:>10.3f} {row.fraction_fallen_back:>9.3f} "
            f"{row.fraction_at_bound:>8.3f} "
            f"{'-' if row.reference_resets is None else row.reference_resets:>5}  "
            f"{alpha}"
            + (f"  BLEW UP at step {row.blew_up_at_step}" if row.blew_up_at_step is not None else "")
        )
    return "\n".join(lines)


def format_ratios(rows: Sequence[EnergyRow]) -> str:
    """One line per row: its RMS(H − E_ref) against RATTLE's, at the same step and at equal cost."""
    lines = [
        "RMS(H - E_ref) of each row against RATTLE's at the same step, at equal cost (RATTLE at h/k) and, "
        "for the energy modes, against alpha4=0's and the best fixed alpha's:"
    ]
    for name, entry in ratios_to_rattle(rows).items():
        line = f"  {name:<26} {gain_text(entry['rms_vs_rattle']):>12} than RATTLE"
        if "rms_vs_rattle_equal_cost" in entry:
            line += f";  at equal cost {gain_text(entry['rms_vs_rattle_equal_cost'])}"
        if "rms_vs_alpha4_0" in entry:
            line += f";  than alpha4=0 {gain_text(entry['rms_vs_alpha4_0'])}"
        if "rms_vs_best_fixed_alpha" in entry:
            line += f";  than {entry['best_fixed_alpha']} {gain_text(entry['rms_vs_best_fixed_alpha'])}"
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
        help="run only these integrators, by name (rattle+rescale, energy, alpha4=0, rattle4+rescale, "
        "energy4; rattle always runs)",
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
    add_file_arguments(parser)
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
        unknown = unknown_systems(args.system)
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
        prepared = prepare_system(system_to_prepare(name, args), progress=True)
        for change in prepared.changes:
            print(f"{prepared.name}: {change}", file=sys.stderr)
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
    integrators = energy_benchmark_integrators(timestep, names)
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
    print(format_energy_table(rows, header), flush=True)
    print(format_ratios(rows), flush=True)
    result = {
        "header": header,
        "rows": keyed_rows((asdict(row) for row in rows), names),
        "ratios": ratios_to_rattle(rows),
    }
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
