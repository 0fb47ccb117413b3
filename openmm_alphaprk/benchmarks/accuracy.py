"""Accuracy benchmark: how close each integrator's trajectory stays to the true one, at equal cost.

Every row starts from the same equilibrated state on the same platform. The true
trajectory is approximated by a *reference*: RATTLE at h/64 with constraint tolerance
1e-10 (:data:`REFERENCE_DIVISOR`); RATTLE at h/128 shows that it has converged (their
difference is printed beside the rows, and must be far below them). Each row's positions
and velocities are compared with the reference's after each *horizon* (a number of steps
of h: 10 fs to a few hundred fs, to show how the error grows; chaos makes every error
grow exponentially at long horizons), as the RMS over atoms and the maximum of the
per-atom distance (:func:`~openmm_alphaprk.observables.trajectory_error`). Each row also
reports RMS(H − E_ref) over the run, its force evaluations per step and its wall time per
step against RATTLE's (interleaved timing rounds).

The rows: the integrators asked for (default :data:`INTEGRATOR_NAMES`: RATTLE,
RATTLE + rescaling, α-RATTLE-4 at α = 0 and its energy mode) at h; for each of
them that costs k > 1 force evaluations per step (rounded up), RATTLE and RATTLE +
rescaling at h/k (equal force evaluations); and for each that costs r > 1 RATTLE steps
of wall time (rounded up), RATTLE at h/r (equal wall time on this platform).

With ``--equilibrium-ps`` each row at h (and RATTLE at h/4 as the reference) also runs
that long and reports equilibrium averages at fixed energy — ⟨K⟩ as a temperature, ⟨V⟩
and the first peak of the water O–O RDF — with standard errors from block averages, and
whether each row's difference from the reference is resolved at all (a t-test at 95 %).

For a System without a periodic box (``water-cluster``) the start gets a rigid
rotation and translation (:func:`with_rigid_motion`) so that linear and angular
momentum are far from zero, and every row reports their largest change.

The command is ``alphaprk bench accuracy`` (:func:`main`); ``--help`` lists its options.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import openmm.unit as unit

from ..equal_cost import equal_cost_divisor
from ..observables import block_average, degrees_of_freedom, rms, temperature
from ..runs.accuracy import (
    REFERENCE_DIVISOR,
    REFERENCE_TOLERANCE,
    Horizon,
    horizon_errors,
    periodic_box,
    reference,
    run_trajectory,
    start_context,
    with_rigid_motion,
)
from ..runs.integrator_names import SubStepped, at_divisor, label, parse_integrator
from ..systems import PreparedSystem, list_systems, prepare_system
from ..systems.arguments import add_file_arguments, system_to_prepare, unknown_systems
from .cost import interleaved_timing

#: Integrator names of the rows at h (the first is the baseline of the time ratios).
INTEGRATOR_NAMES = ("rattle", "rattle+rescale", "alpha4=0", "energy4")
#: Steps of h after which the errors are taken (2 fs: 10 fs … 200 fs).
HORIZONS = (5, 10, 25, 50, 100)
#: Rigid motion given to the start of a System without a periodic box: translation (nm/ps)
#: and angular velocity (1/ps), so that P and L are far from zero.
CLUSTER_TRANSLATION = (0.3, -0.2, 0.1)
CLUSTER_ROTATION = (0.4, 0.7, -0.5)


@dataclass
class AccuracyRow:
    """One row: what it is, its cost, its energy error and its errors at each horizon."""

    name: str
    integrator: str
    divisor: int
    role: str  # "at h", "equal evaluations", "equal wall time" (or both), "reference"
    force_evaluations_per_step: float
    rms_residual: float
    max_abs_residual: float
    horizons: list[Horizon] = field(default_factory=list)
    time_ratio: float = float("nan")
    momentum_change: dict[str, float] = field(default_factory=dict)
    blew_up_at_step: int | None = None


@dataclass
class AccuracyResult:
    """The rows of one system, the reference's convergence and the header."""

    system: str
    header: str
    reference_convergence: list[Horizon]
    rows: list[AccuracyRow]
    equilibrium: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return asdict(self)


def run_accuracy_benchmark(
    prepared: PreparedSystem,
    names: Sequence[str] = INTEGRATOR_NAMES,
    *,
    timestep: float = 0.002,
    horizons: Sequence[int] = HORIZONS,
    platform: str = "CPU",
    properties: dict[str, str] | None = None,
    equal_cost: bool = True,
    timing_steps: int = 50,
    timing_rounds: int = 3,
    convergence: bool = True,
    progress: bool = True,
    on_row=None,
) -> AccuracyResult:
    """Run the reference, the rows at h and their equal-cost and equal-wall-time RATTLE rows; compare.

    Parameters
    ----------
    prepared
        System and start state (every row starts from it).
    names
        Integrator names of the rows at h (:mod:`openmm_alphaprk.runs.integrator_names`);
        ``rattle`` is the baseline of the time ratios and is added first if missing.
    timestep
        h, in ps.
    horizons
        Steps of h after which errors are taken.
    platform, properties
        OpenMM platform name and its properties (e.g. ``{"Precision": "mixed"}``).
    equal_cost
        Add RATTLE and RATTLE + rescaling at h/k for each row of k > 1 force evaluations
        per step (rounded up), and RATTLE at h/r for each row of r > 1 times RATTLE's wall
        time per step (rounded up).
    timing_steps, timing_rounds
        The interleaved timing of the rows at h (steps of h per round).
    convergence
        Also run RATTLE at h/(2·64) and report its difference from the reference.
    progress
        Say on stderr what runs.
    on_row
        Called with each finished :class:`AccuracyRow` (e.g. to write results as they come).
    """
    names = ["rattle", *[n for n in names if parse_integrator(n).name != "rattle"]]
    box = periodic_box(prepared)
    timestep_fs = timestep * 1000.0
    say = (lambda text: print(text, file=sys.stderr, flush=True)) if progress else (lambda text: None)
    say(f"{prepared.name}: reference, RATTLE at h/{REFERENCE_DIVISOR}")
    run = partial(run_trajectory, platform=platform, properties=properties)
    reference_run = run(prepared, reference(timestep), horizons, read_energy=False)
    converged = []
    if convergence:
        say(f"{prepared.name}: RATTLE at h/{2 * REFERENCE_DIVISOR}, to show the reference has converged")
        finer = run(prepared, reference(timestep, 2 * REFERENCE_DIVISOR), horizons, read_energy=False)
        converged = horizon_errors(reference_run, finer, box, timestep_fs)
        del finer
    rows, runs = [], {}

    def add(row_name: str, spec: str, divisor: int, role: str) -> AccuracyRow:
        say(f"{prepared.name}: {row_name}")
        trajectory = run(prepared, at_divisor(spec, timestep, divisor), horizons)
        residuals = trajectory.residuals[np.isfinite(trajectory.residuals)]
        row = AccuracyRow(
            name=row_name,
            integrator=parse_integrator(spec).name,
            divisor=divisor,
            role=role,
            force_evaluations_per_step=trajectory.force_evaluations_per_step,
            rms_residual=rms(residuals) if residuals.size else float("nan"),
            max_abs_residual=float(np.max(np.abs(residuals))) if residuals.size else float("nan"),
            horizons=horizon_errors(trajectory, reference_run, box, timestep_fs),
            momentum_change=trajectory.momentum_change,
            blew_up_at_step=trajectory.blew_up_at_step,
        )
        rows.append(row)
        runs[row_name] = trajectory
        if on_row is not None:
            on_row(row)
        return row

    for name in names:
        add(label(name), name, 1, "at h")
    at_h = list(rows)
    if timing_rounds > 0:
        say(f"{prepared.name}: timing the rows at h ({timing_rounds} x {timing_steps} steps)")
        medians = interleaved_timing(
            {row.name: (runs[row.name].integrator, 1) for row in at_h if row.blew_up_at_step is None},
            timing_steps,
            timing_rounds,
        )
        for row in at_h:
            row.time_ratio = medians.get(row.name, float("nan")) / medians[label("rattle")]
    for trajectory in runs.values():
        trajectory.context = None  # each holds a Context: free them before the next rows
    if equal_cost:
        roles: dict[tuple[str, int], list[str]] = {}
        for row in at_h:
            k = equal_cost_divisor(row.force_evaluations_per_step)
            if k > 1:
                for name in ("rattle", "rattle+rescale"):
                    roles.setdefault((name, k), []).append(f"equal evaluations ({row.integrator})")
            r = equal_cost_divisor(row.time_ratio) if math.isfinite(row.time_ratio) else 1
            if r > 1:
                roles.setdefault(("rattle", r), []).append(f"equal wall time ({row.integrator})")
        for (name, k), why in sorted(roles.items(), key=lambda item: (item[0][1], item[0][0])):
            add(f"{label(name)} h/{k}", name, k, "; ".join(why))
    header = (
        f"{prepared.name}: {prepared.n_atoms} atoms, {degrees_of_freedom(prepared.system)} DOF, "
        f"h = {timestep_fs:g} fs, platform {platform}"
        + (f" ({properties['Precision']} precision)" if properties and "Precision" in properties else "")
        + f"; reference RATTLE at h/{REFERENCE_DIVISOR}, constraint tolerance {REFERENCE_TOLERANCE:g}; "
        "errors: RMS over atoms / max of the per-atom distance to the reference (positions nm, velocities "
        "nm/ps); RMS|H - E_ref| over every step of h (kJ/mol); time ratio: wall time per step of h against "
        "RATTLE's (interleaved rounds)"
    )
    return AccuracyResult(prepared.name, header, converged, rows)


# ------------------------------------------------------------------ equilibrium averages
#: RATTLE at h/EQUILIBRIUM_DIVISOR: the reference of the equilibrium averages.
EQUILIBRIUM_DIVISOR = 4


@dataclass
class Average:
    """A block average: mean ± standard error over ``blocks`` blocks, and the difference from the reference's.

    ``difference`` and its standard error are None for the reference itself.
    """

    mean: float
    standard_error: float
    blocks: int
    difference: float | None = None
    difference_standard_error: float | None = None

    @property
    def resolved(self) -> bool | None:
        """Whether the difference from the reference is significant at 95 % (two-sided t-test).

        The t quantile has 2 (blocks − 1) degrees of freedom (two runs of ``blocks`` block
        means each): with few blocks a standard error is itself uncertain, and 2 standard
        errors would call too many differences resolved.
        """
        if self.difference is None or self.difference_standard_error is None:
            return None
        return abs(self.difference) > _t_quantile(2 * (self.blocks - 1)) * self.difference_standard_error

    def as_dict(self) -> dict:
        return {**asdict(self), "resolved": self.resolved}


def equilibrium_run(
    prepared: PreparedSystem,
    row: SubStepped,
    length_ps: float,
    timestep: float,
    *,
    sample_every: int = 5,
    frame_every: int = 50,
    platform: str = "CPU",
    properties: dict[str, str] | None = None,
) -> dict[str, np.ndarray]:
    """Kinetic and potential energy every ``sample_every`` steps of h, positions every ``frame_every``."""
    integrator = row.make()
    context = start_context(prepared, integrator, platform, properties)
    steps = int(round(length_ps / timestep))
    kinetic, potential, frames = [], [], []
    for step in range(1, steps + 1):
        integrator.step(row.substeps)
        if step % sample_every == 0 or step % frame_every == 0:
            state = context.getState(getEnergy=True, getPositions=step % frame_every == 0)
            kinetic.append(state.getKineticEnergy().value_in_unit(unit.kilojoules_per_mole))
            potential.append(state.getPotentialEnergy().value_in_unit(unit.kilojoules_per_mole))
            if step % frame_every == 0:
                frames.append(state.getPositions(asNumpy=True).value_in_unit(unit.nanometers))
    return {"kinetic": np.array(kinetic), "potential": np.array(potential), "frames": np.array(frames)}


def _t_quantile(dof: int) -> float:
    """Return the two-sided 95 % quantile of Student's t with ``dof`` degrees of freedom."""
    from scipy.stats import t

    return float(t.ppf(0.975, dof))


def first_rdf_peak(prepared: PreparedSystem, frames: np.ndarray) -> tuple[float, float]:
    """Height and position (nm) of the first maximum of the water O–O RDF over ``frames`` (nm).

    The maximum is the vertex of the parabola through the highest bin and its neighbours,
    so that the position is not quantized to the bin width (0.025 Å).
    """
    import MDAnalysis as mda
    from MDAnalysis.coordinates.memory import MemoryReader

    from ..analysis import oxygen_rdf

    with warnings.catch_warnings():  # a topology without coordinates: the frames come next
        warnings.simplefilter("ignore", UserWarning)
        universe = mda.Universe(prepared.topology, topology_format="OPENMMTOPOLOGY")
    box = periodic_box(prepared) * 10.0
    universe.load_new(
        frames * 10.0, format=MemoryReader, dimensions=np.array([*box, 90.0, 90.0, 90.0], dtype=np.float32)
    )
    rdf = oxygen_rdf(universe, nbins=160, r_max=4.0)
    g, r = rdf.results.rdf, rdf.results.bins / 10.0
    peak = int(np.argmax(g))
    low, mid, high = g[peak - 1], g[peak], g[peak + 1]
    curvature = low - 2 * mid + high
    shift = 0.5 * (low - high) / curvature if curvature < 0 else 0.0
    width = r[1] - r[0]
    return float(mid - 0.25 * (low - high) * shift), float(r[peak] + shift * width)


def equilibrium_averages(
    prepared: PreparedSystem,
    rows: Sequence[tuple[str, SubStepped]],
    length_ps: float,
    timestep: float,
    *,
    blocks: int = 10,
    platform: str = "CPU",
    properties: dict[str, str] | None = None,
    progress: bool = True,
) -> dict[str, dict[str, dict]]:
    """⟨T⟩, ⟨V⟩ and the first O–O RDF peak (height, position) of each row and of RATTLE at h/4.

    Each average is a :func:`~openmm_alphaprk.observables.block_average` over ``blocks``
    blocks (the RDF peak: one RDF per block); each row's difference from the reference
    carries the combined standard error and whether it is resolved (:attr:`Average.resolved`).
    With many rows and quantities, a few differences pass the 95 % test by chance (1 in 20).
    """
    dof = degrees_of_freedom(prepared.system)
    waters = any(residue.name in ("HOH", "WAT", "SOL") for residue in prepared.topology.residues())
    reference_name = f"{label('rattle')} h/{EQUILIBRIUM_DIVISOR} (reference)"
    runs = [(reference_name, at_divisor("rattle", timestep, EQUILIBRIUM_DIVISOR)), *rows]
    results: dict[str, dict[str, Average]] = {}
    for name, row in runs:
        if progress:
            print(f"{prepared.name}: equilibrium run, {name}", file=sys.stderr, flush=True)
        samples = equilibrium_run(
            prepared, row, length_ps, timestep, platform=platform, properties=properties
        )
        averages = {
            "temperature_K": Average(*block_average(temperature(samples["kinetic"], dof), blocks), blocks),
            "potential_kJ_per_mol": Average(*block_average(samples["potential"], blocks), blocks),
        }
        if waters and prepared.system.usesPeriodicBoundaryConditions() and len(samples["frames"]) >= blocks:
            peaks = np.array(
                [first_rdf_peak(prepared, part) for part in np.array_split(samples["frames"], blocks)]
            )
            for column, key in ((0, "rdf_peak_height"), (1, "rdf_peak_position_nm")):
                values = peaks[:, column]
                averages[key] = Average(
                    float(values.mean()), float(values.std(ddof=1) / math.sqrt(blocks)), blocks
                )
        results[name] = averages
    baseline = results[reference_name]
    for name, averages in results.items():
        if name == reference_name:
            continue
        for key, average in averages.items():
            average.difference = average.mean - baseline[key].mean
            average.difference_standard_error = math.hypot(
                average.standard_error, baseline[key].standard_error
            )
    return {name: {key: a.as_dict() for key, a in averages.items()} for name, averages in results.items()}


# ------------------------------------------------------------------ tables
def format_accuracy_table(result: AccuracyResult) -> str:
    """Return the rows as a plain-text table: cost, energy, position (velocity) errors at each horizon."""
    horizons = result.rows[0].horizons if result.rows else []
    columns = "  ".join(f"{h.time_fs:>6g} fs pos." for h in horizons)
    lines = [result.header, f"{'row':<28} {'evals':>6} {'time':>6} {'RMS|H-Eref|':>11}  {columns}"]
    if result.reference_convergence:
        values = "  ".join(f"{h.position_rms:>13.2e}" for h in result.reference_convergence)
        lines.append(f"{'reference h/64 vs h/128':<28} {'':>6} {'':>6} {'':>11}  {values}")
    for row in result.rows:
        errors = {h.steps: h for h in row.horizons}
        values = "  ".join(
            f"{errors[h.steps].position_rms:>13.2e}" if h.steps in errors else f"{'-':>13}" for h in horizons
        )
        ratio = f"{row.time_ratio:6.2f}" if math.isfinite(row.time_ratio) else f"{'':>6}"
        blew = f"  BLEW UP at step {row.blew_up_at_step}" if row.blew_up_at_step is not None else ""
        evaluations = f"{row.force_evaluations_per_step:>6.2f}"
        lines.append(f"{row.name:<28} {evaluations} {ratio} {row.rms_residual:>11.3g}  {values}{blew}")
    lines.append("velocity errors (RMS, nm/ps) at the same horizons:")
    for row in result.rows:
        values = "  ".join(f"{h.velocity_rms:>13.2e}" for h in row.horizons)
        lines.append(f"{row.name:<28} {'':>6} {'':>6} {'':>11}  {values}")
    for row in result.rows:
        if row.role != "at h":
            lines.append(f"  {row.name}: {row.role}")
        if row.momentum_change:
            m = row.momentum_change
            lines.append(
                f"  {row.name}: max change of P {m['linear_amu_nm_per_ps']:.1e} amu nm/ps "
                f"(|P| {m['linear_start']:.3g}), of L {m['angular_amu_nm2_per_ps']:.1e} amu nm^2/ps "
                f"(|L| {m['angular_start']:.3g})"
            )
    return "\n".join(lines)


def format_equilibrium_table(equilibrium: dict) -> str:
    """Equilibrium averages ± standard error, and each row's difference from the reference."""
    lines = [
        "equilibrium averages (block averages ± standard error; difference from the reference, "
        "'not resolved' where a two-sided t-test at 95 % does not tell it from zero):"
    ]
    for name, averages in equilibrium.items():
        parts = []
        for key, a in averages.items():
            text = f"{key} {a['mean']:.4g} ± {a['standard_error']:.2g}"
            if a["difference"] is not None:
                verdict = "" if a["resolved"] else ", not resolved"
                text += f" (diff {a['difference']:+.2g} ± {a['difference_standard_error']:.2g}{verdict})"
            parts.append(text)
        lines.append(f"  {name}: " + "; ".join(parts))
    return "\n".join(lines)


# ------------------------------------------------------------------ command line
def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="alphaprk bench accuracy",
        description=(
            "Trajectory accuracy against a converged small-step reference (RATTLE at h/64), from the same "
            "start: position and velocity errors after several horizons, energy error, cost; RATTLE and "
            "RATTLE + rescaling at equal force evaluations and RATTLE at equal wall time."
        ),
    )
    parser.add_argument(
        "--system",
        nargs="+",
        default=["tip3p-2nm"],
        metavar="NAME",
        help="systems of `alphaprk systems` (default tip3p-2nm), one after the other",
    )
    parser.add_argument(
        "--integrators",
        nargs="+",
        default=list(INTEGRATOR_NAMES),
        metavar="NAME",
        help=f"rows at h (default {' '.join(INTEGRATOR_NAMES)}); RATTLE always runs",
    )
    parser.add_argument("--timestep", type=float, default=2.0, help="h in fs (default 2)")
    parser.add_argument(
        "--horizons",
        nargs="+",
        type=int,
        default=list(HORIZONS),
        metavar="STEPS",
        help=f"steps of h after which errors are taken (default {' '.join(map(str, HORIZONS))})",
    )
    parser.add_argument("--platform", default="CPU", help="OpenMM platform (default CPU)")
    parser.add_argument(
        "--precision",
        choices=("single", "mixed", "double"),
        default=None,
        help="precision on CUDA, OpenCL or HIP (default: the platform's)",
    )
    parser.add_argument(
        "--equilibrium-ps",
        type=float,
        default=0.0,
        help="also run each row this long (ps) for equilibrium averages (default 0: none)",
    )
    parser.add_argument("--timing-rounds", type=int, default=3, help="interleaved timing rounds (default 3)")
    parser.add_argument("--json", help="write the results here, after every row (resumes finished systems)")
    parser.add_argument("--figure", help="also plot the position errors against time into this PNG")
    add_file_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point."""
    parser = _parser()
    args = parser.parse_args(argv)
    unknown = unknown_systems(args.system)
    if unknown:
        parser.error(f"unknown system(s) {unknown}; choose from {', '.join(list_systems())}")
    if min(args.horizons) < 1 or args.timestep <= 0:
        parser.error("--horizons must be positive step counts and --timestep positive")
    for name in args.integrators:
        parse_integrator(name)
    properties = {"Precision": args.precision} if args.precision else {}
    settings = {
        "timestep_fs": args.timestep,
        "horizons": sorted(set(args.horizons)),
        "integrators": list(args.integrators),
        "platform": args.platform,
        "precision": args.precision,
        "equilibrium_ps": args.equilibrium_ps,
    }
    results = _read_results(args.json, settings)
    if results is None:
        parser.error(
            f"--json {args.json} holds the results of a run with other settings; give another file or "
            "remove it (nothing was run)"
        )
    for system in args.system:
        if system in results.get("systems", {}):
            print(f"{system}: done in {args.json}, skipped", file=sys.stderr)
            continue
        prepared = prepare_system(system_to_prepare(system, args), progress=True)
        for change in prepared.changes:
            print(f"{prepared.name}: {change}", file=sys.stderr)
        if not prepared.system.usesPeriodicBoundaryConditions():
            prepared = with_rigid_motion(prepared, CLUSTER_TRANSLATION, CLUSTER_ROTATION)
        partial_rows: list[dict] = []

        def keep(row: AccuracyRow, system: str = system, rows: list = partial_rows) -> None:
            rows.append(asdict(row))
            _write_results(args.json, {**results, "running": {system: rows}})

        result = run_accuracy_benchmark(
            prepared,
            args.integrators,
            timestep=args.timestep / 1000.0,
            horizons=settings["horizons"],
            platform=args.platform,
            properties=properties,
            timing_rounds=args.timing_rounds,
            on_row=keep,
        )
        print(format_accuracy_table(result), flush=True)
        if args.equilibrium_ps > 0:
            h = args.timestep / 1000.0
            rows = [(row.name, at_divisor(row.integrator, h)) for row in result.rows if row.divisor == 1]
            result.equilibrium = equilibrium_averages(
                prepared,
                rows,
                args.equilibrium_ps,
                args.timestep / 1000.0,
                platform=args.platform,
                properties=properties,
            )
            print(format_equilibrium_table(result.equilibrium), flush=True)
        results.setdefault("systems", {})[system] = result.as_dict()
        results.pop("running", None)
        _write_results(args.json, results)
    if args.figure:
        from ..workflows.plots import plot_accuracy

        plot_accuracy(results["systems"], args.figure)
    return 0


def _read_results(path: str | None, settings: dict) -> dict | None:
    """Return an earlier run's results with the same settings (its finished systems), or a new record.

    None if ``path`` holds results with other settings, which must not be overwritten.
    """
    if path and Path(path).is_file():
        earlier = json.loads(Path(path).read_text(encoding="utf-8"))
        if earlier.get("settings") != settings:
            return None
        earlier.pop("running", None)
        return earlier
    return {"settings": settings, "systems": {}}


def _write_results(path: str | None, results: dict) -> None:
    if path:
        Path(path).write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
