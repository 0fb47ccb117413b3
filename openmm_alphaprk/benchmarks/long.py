"""Long NVE runs from one start: drift, windowed RMS |H − E_ref| and ns/day of every row.

Every integrator runs NVE from the same equilibrated state, on the platform and
precision asked, as a run directory of :func:`~openmm_alphaprk.runs.run_nve`
(``OUTPUT/<system>/<integrator>/``: energies every ``--energy-interval`` steps,
checkpoints, the energy mode's ``controller.csv``), so that results are written as
the run goes and the same command resumes an interrupted run (or extends a finished
one to a longer ``--time``). The rows that take one force evaluation per step
(VerletIntegrator, RATTLE, RATTLE + rescaling) run ``--time``; the others
(compositions, the energy modes) ``--time-multi``.

Per row, from its ``energies.csv`` (E_ref = the start's total energy):
drift per ns per degree of freedom with its standard error from ``--blocks`` block
means (:func:`~openmm_alphaprk.observables.block_drift`), RMS and max |H − E_ref|
over the run and over each ``--window`` (:func:`~openmm_alphaprk.observables.residual_windows`),
and the speed of the run as it ran (energy read and checkpoints included): ms/step,
ns/day and the step time against VerletIntegrator's of the same command. Written to
``OUTPUT/long.json`` and ``OUTPUT/<system>/table.txt``, with the figure
``OUTPUT/<system>/energy_residuals.png`` (H − E_ref against time). ``--report`` only
reads what is there (also from an interrupted run) and writes the same files.

The command is ``alphaprk bench long`` (:func:`main`); ``--help`` lists its options.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import openmm.unit as unit

from .._units import InputError
from ..integrators import RattleRescaleIntegrator
from ..observables import block_drift, degrees_of_freedom, masses, residual_windows, rms
from ..runs import RunFailedError, RunInterrupted, RunOptions, read_energies, run_nve, rundir
from ..runs.integrator_names import label, parse_integrator
from ..systems import PreparedSystem, list_systems, prepare_system
from ..systems.arguments import add_file_arguments, system_to_prepare, unknown_systems
from .cost import add_platform_arguments

#: The rows, by integrator name; ``verlet`` is the baseline of the step-time ratios.
LONG_INTEGRATORS = ("verlet", "rattle", "rattle+rescale", "alpha4=0", "rattle4+rescale", "energy4")
#: Where each row's speed is kept across calls, in its run directory (a resumed run's calls add up).
TIMING_FILE = "bench_timing.json"
#: Where a rescaling row's carried momentum is compared with the state's, in its run directory.
MOMENTUM_FILE = "carried_momentum.csv"
#: What the table's columns are, printed under it.
TABLE_NOTE = (
    "E_ref = total energy of the start state. drift/DOF: slope of a least-squares line through the means "
    "of {blocks} consecutive blocks of H - E_ref, per degree of freedom, ± its standard error from those "
    "block means; RMS and max |H - E_ref| over the run; worst window: the largest RMS over any {window:g} ps "
    "window; ms/step and ns/day as the run ran (energy read every {interval} steps, checkpoints), "
    "against VerletIntegrator's in this command. VerletIntegrator is leapfrog: its State kinetic energy "
    "is a half-step estimate, so its RMS is not comparable with the others'; its drift is."
)


@dataclass
class LongRow:
    """One integrator's long run (energies in kJ/mol, drift in kJ/mol/ns per DOF, times in ps).

    ``complete`` is False for a run that stopped before ``planned_steps`` (interrupted,
    or failed: ``failure`` says why); its numbers are over the steps it took.
    """

    system: str
    integrator: str
    label: str
    planned_steps: int
    steps: int
    simulated_ps: float
    complete: bool
    samples: int
    drift_per_dof: float = float("nan")
    drift_per_dof_standard_error: float = float("nan")
    drift_resolved: bool = False
    #: For a row that rescales every N > 1 steps whose energy rows fall on its rescaling steps only
    #: in part: the drift over those rows alone (NaN otherwise).
    drift_at_rescaling_per_dof: float = float("nan")
    drift_at_rescaling_standard_error: float = float("nan")
    rescaling_samples: int = 0
    rms_residual: float = float("nan")
    max_abs_residual: float = float("nan")
    worst_window_rms: float = float("nan")
    windows: dict = field(default_factory=dict)
    force_evaluations_per_step: float = float("nan")
    ms_per_step: float = float("nan")
    ns_per_day: float = float("nan")
    time_ratio_to_verlet: float = float("nan")
    timed_steps: int = 0
    controller: dict = field(default_factory=dict)
    carried_momentum_error: float = float("nan")
    failure: str = ""


class CarriedMomentumReporter:
    """An OpenMM reporter: |P − P_carried| of RATTLE + rescaling, the state's momentum against its program's.

    In a periodic box the rescaling carries the total momentum P from when E_ref was taken
    (RATTLE keeps it, and PME's reciprocal-space forces sum to round-off, not zero). Every
    ``interval`` steps, and at ``last_step``, this writes the step, |P| and |P − P_carried|
    (amu nm/ps) to ``path`` as the run goes; integrators without a carried momentum get no rows.
    """

    def __init__(self, path: Path, interval: int, last_step: int) -> None:
        self._path = Path(path)
        self._interval = interval
        self._last_step = last_step
        self._masses: np.ndarray | None = None

    def describeNextReport(self, simulation) -> dict:
        steps = self._interval - simulation.currentStep % self._interval
        if simulation.currentStep < self._last_step:
            steps = min(steps, self._last_step - simulation.currentStep)
        return {"steps": steps, "periodic": None, "include": ["velocities"]}

    def report(self, simulation, state) -> None:
        integrator = simulation.integrator
        if not isinstance(integrator, RattleRescaleIntegrator):
            return
        if self._masses is None:  # lazy set-up on the first report
            self._masses = masses(simulation.system)
            if not self._path.is_file():
                self._path.write_text("step,P (amu nm/ps),|P - P_carried| (amu nm/ps)\n", encoding="utf-8")
        velocities = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
        actual = (self._masses[:, None] * velocities).sum(axis=0)
        carried = np.array([integrator.getGlobalVariableByName(f"momentum_{axis}") for axis in "xyz"])
        with self._path.open("a", encoding="utf-8") as handle:
            change = np.linalg.norm(actual - carried)
            handle.write(f"{simulation.currentStep},{np.linalg.norm(actual):.9g},{change:.9g}\n")


def one_evaluation(name: str) -> bool:
    """Tell whether the integrator ``name`` takes one force evaluation per step (runs ``--time``).

    Examples
    --------
    >>> from openmm_alphaprk.benchmarks.long import one_evaluation
    >>> [one_evaluation(n) for n in ("verlet", "rattle+rescale", "alpha=0", "alpha4=0", "energy")]
    [True, True, True, False, False]
    >>> one_evaluation("split:me2+rescale")  # two per step, as its splitting
    False
    """
    return parse_integrator(name).force_evaluations == 1


def planned_steps(name: str, timestep_fs: float, time_ps: float, time_multi_ps: float) -> int:
    """Return the steps of the row ``name``: ``time_ps`` for one-evaluation rows, else ``time_multi_ps``."""
    length = time_ps if one_evaluation(name) else time_multi_ps
    return max(1, int(round(length / timestep_fs * 1000.0)))


def run_rows(
    prepared: PreparedSystem,
    names: Sequence[str],
    folder: Path,
    options: RunOptions,
    steps: dict[str, int],
) -> dict[str, str]:
    """Run (or resume, or extend) each row's run directory under ``folder``; return the failures.

    A row that fails (blows up) is recorded and the next one runs. The wall time and
    steps of each call that completes are added to the row's ``bench_timing.json``
    (one file per row: commands running different rows into one folder do not collide).

    Raises
    ------
    RunInterrupted
        On Ctrl-C (or SIGTERM); the rows done and the checkpoint of the one running stay.
    """
    folder.mkdir(parents=True, exist_ok=True)
    failures = {}
    for name in names:
        run = folder / rundir.folder_name(name)
        momentum = CarriedMomentumReporter(run / MOMENTUM_FILE, 20 * options.energy_interval, steps[name])
        try:
            summary = run_nve(prepared, name, run, options, steps=steps[name], extra_reporters=[momentum])
        except RunFailedError as error:
            failures[name] = str(error)
            print(f"{name}: {error}", file=sys.stderr, flush=True)
            continue
        if summary.steps_this_call > 0:
            _add_timing(run, summary.steps_this_call, summary.wall_seconds)
    return failures


def _add_timing(run: Path, steps: int, wall_seconds: float) -> None:
    path = run / TIMING_FILE
    calls = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else []
    calls.append({"steps": steps, "wall_seconds": wall_seconds, "at": time.time()})
    rundir.replace_text(path, json.dumps(calls, indent=1) + "\n")


def _timing(run: Path) -> list[dict]:
    path = run / TIMING_FILE
    return json.loads(path.read_text(encoding="utf-8")) if path.is_file() else []


def analyse_rows(
    system: str,
    names: Sequence[str],
    folder: Path,
    dof: int,
    steps: dict[str, int],
    *,
    timestep_ps: float,
    window_ps: float,
    blocks: int,
    failures: dict[str, str] | None = None,
) -> tuple[list[LongRow], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Read each row's ``energies.csv`` (what is there) and measure it; return the rows and traces.

    Traces map the row's integrator name to (time in ps, H − E_ref in kJ/mol), for the figure.
    """
    failures = failures or {}
    rows, traces = [], {}
    for name in names:
        run = folder / rundir.folder_name(name)
        energies_file = run / rundir.ENERGIES_FILE
        if not energies_file.is_file():
            continue
        energies = read_energies(energies_file)
        residuals = energies[:, 4] - energies[:, 4][0]
        times = energies[:, 1] - energies[:, 1][0]
        done = max(int(energies[-1, 0]), _summary_steps(run))
        row = LongRow(
            system=system,
            integrator=name,
            label=label(name),
            planned_steps=steps[name],
            steps=done,
            simulated_ps=done * timestep_ps,
            complete=done >= steps[name],
            samples=len(energies) - 1,
            failure=failures.get(name, ""),
        )
        _energy_statistics(row, times, residuals, dof, window_ps, blocks)
        _rescaling_step_drift(row, energies[:, 0], times, residuals, dof, blocks)
        _speed(row, _timing(run), timestep_ps)
        _summary_fields(row, run)
        if (run / MOMENTUM_FILE).is_file():
            momentum = np.loadtxt(run / MOMENTUM_FILE, delimiter=",", skiprows=1, ndmin=2)
            if momentum.size:
                row.carried_momentum_error = float(momentum[-1, 2])
        rows.append(row)
        traces[row.integrator] = (times, residuals)
    verlet = next(
        (row.ms_per_step for row in rows if parse_integrator(row.integrator).kind == "verlet"), None
    )
    for row in rows:
        if verlet:
            row.time_ratio_to_verlet = row.ms_per_step / verlet
    return rows, traces


def _energy_statistics(
    row: LongRow, times: np.ndarray, residuals: np.ndarray, dof: int, window_ps: float, blocks: int
) -> None:
    after = residuals[1:]
    if after.size == 0:
        return
    row.rms_residual = rms(after)
    row.max_abs_residual = float(np.max(np.abs(after)))
    windows = residual_windows(times, residuals, window_ps)
    row.windows = windows.as_dict()
    row.worst_window_rms = float(np.max(windows.rms))
    if after.size >= blocks and np.all(np.isfinite(after)):
        fit = block_drift(times[1:], after, blocks)
        row.drift_per_dof, row.drift_per_dof_standard_error = fit.per_dof(dof)
        row.drift_resolved = fit.resolved


def _rescaling_step_drift(
    row: LongRow, steps: np.ndarray, times: np.ndarray, residuals: np.ndarray, dof: int, blocks: int
) -> None:
    """Fit the drift over the energy rows at rescaling steps, for ``@N`` rows with rows between them too.

    Where the energy interval divides N (e.g. 50 and N = 100) every other row samples H between
    rescalings, where it moves as RATTLE's does; the rows at multiples of N hold H = E_ref.
    """
    interval = getattr(parse_integrator(row.integrator), "rescale_interval", 1)
    at_rescaling = (np.rint(steps).astype(np.int64) % interval == 0)[1:]
    if interval <= 1 or at_rescaling.all():
        return
    row.rescaling_samples = int(at_rescaling.sum())
    after = residuals[1:][at_rescaling]
    if after.size >= blocks and np.all(np.isfinite(after)):
        fit = block_drift(times[1:][at_rescaling], after, blocks)
        row.drift_at_rescaling_per_dof, row.drift_at_rescaling_standard_error = fit.per_dof(dof)


def _rescaling_step_note(rows: Sequence[LongRow]) -> str:
    """Say the drift at the rescaling steps of the rows :func:`_rescaling_step_drift` measured."""
    return "".join(
        f" {row.label}: at its rescaling steps alone ({row.rescaling_samples} energy rows) drift "
        f"{row.drift_at_rescaling_per_dof:+.2e} ± {row.drift_at_rescaling_standard_error:.1e} kJ/mol/ns/DOF."
        for row in rows
        if row.drift_at_rescaling_per_dof == row.drift_at_rescaling_per_dof
    )


def _speed(row: LongRow, calls: list[dict], timestep_ps: float) -> None:
    steps = sum(call["steps"] for call in calls)
    wall = sum(call["wall_seconds"] for call in calls)
    if steps <= 0 or wall <= 0:
        return
    row.timed_steps = steps
    row.ms_per_step = wall / steps * 1e3
    row.ns_per_day = timestep_ps * 1e-3 * 86400.0 / (row.ms_per_step * 1e-3)


def _summary_steps(run: Path) -> int:
    """Return the steps of a finished call's ``summary.json`` (0 without one).

    The run's length where its last energy row falls before its end.
    """
    summary_file = run / rundir.SUMMARY_FILE
    if not summary_file.is_file():
        return 0
    return int(json.loads(summary_file.read_text(encoding="utf-8")).get("steps", 0))


def _summary_fields(row: LongRow, run: Path) -> None:
    summary_file = run / rundir.SUMMARY_FILE
    if not summary_file.is_file():
        return
    summary = json.loads(summary_file.read_text(encoding="utf-8"))
    row.force_evaluations_per_step = summary.get("force_evaluations_per_step", float("nan"))
    row.controller = summary.get("controller", {})


def format_long_table(rows: Sequence[LongRow], header: str = "") -> str:
    """Format the rows as a plain-text table (units in the column titles)."""
    lines = [header] if header else []
    titles = (
        f"{'integrator':<34}",
        f"{'time ps':>8}",
        f"{'drift/DOF kJ/mol/ns':>24}",
        f"{'RMS kJ/mol':>11}",
        f"{'max kJ/mol':>11}",
        f"{'worst window':>12}",
        f"{'evals/step':>10}",
        f"{'ms/step':>8}",
        f"{'vs Verlet':>9}",
        f"{'ns/day':>8}",
    )
    lines.append(" ".join(titles))
    for row in rows:
        drift = f"{row.drift_per_dof:+.2e} ± {row.drift_per_dof_standard_error:.1e}"
        state = "" if row.complete else (" (failed)" if row.failure else " (stopped)")
        lines.append(
            f"{row.label + state:<34} {row.simulated_ps:>8.1f} {drift:>24} {row.rms_residual:>11.3g} "
            f"{row.max_abs_residual:>11.3g} {row.worst_window_rms:>12.3g} "
            f"{row.force_evaluations_per_step:>10.2f} {row.ms_per_step:>8.3f} "
            f"{row.time_ratio_to_verlet:>9.2f} {row.ns_per_day:>8.1f}"
        )
    return "\n".join(lines)


def windows_against(rows: Sequence[LongRow], name: str, base: str) -> dict:
    """Compare the windowed RMS of row ``name`` with row ``base`` over their common windows.

    Returns the number of common windows, how many of them ``name``'s RMS exceeds
    ``base``'s, and the largest ratio; empty if either row is missing.

    Examples
    --------
    >>> from openmm_alphaprk.benchmarks.long import LongRow, windows_against
    >>> a = LongRow("s", "energy4", "a", 1, 1, 1.0, True, 1, windows={"rms": [0.1, 0.3]})
    >>> b = LongRow("s", "alpha4=0", "b", 1, 1, 1.0, True, 1, windows={"rms": [0.2, 0.2]})
    >>> windows_against([a, b], "energy4", "alpha4=0")
    {'windows': 2, 'above': 1, 'largest_ratio': 1.5}
    """
    by_name = {row.integrator: row for row in rows}
    if name not in by_name or base not in by_name:
        return {}
    first = np.asarray(by_name[name].windows.get("rms", []), dtype=float)
    second = np.asarray(by_name[base].windows.get("rms", []), dtype=float)
    n = min(first.size, second.size)
    if n == 0:
        return {}
    ratio = first[:n] / second[:n]
    return {"windows": n, "above": int(np.sum(ratio > 1.0)), "largest_ratio": round(float(np.max(ratio)), 4)}


def _figure(traces: dict, path: Path, title: str, caption: str, dof: int) -> str | None:
    try:
        from ..workflows.plots import plot_energy_residuals
    except ImportError:  # matplotlib missing: the table and JSON are the result
        return None
    try:
        return plot_energy_residuals(traces, path, title, caption=caption, dof=dof)
    except ImportError:
        print("matplotlib is not installed: no figure (pip install matplotlib)", file=sys.stderr)
        return None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="alphaprk bench long",
        description=(
            "Long NVE runs of every row from one start: drift per ns per DOF (block standard error), RMS "
            "and max |H - E_ref| per window, ns/day and step time against VerletIntegrator's; written as "
            "it goes, resumed by the same command."
        ),
    )
    parser.add_argument(
        "--system",
        nargs="+",
        default=["tip3p-2nm"],
        metavar="NAME",
        help="package systems (alphaprk systems; e.g. tip3p-2nm tip3p-3nm villin dhfr) or a system file, "
        "one after the other (default tip3p-2nm)",
    )
    parser.add_argument(
        "--integrators",
        nargs="+",
        default=list(LONG_INTEGRATORS),
        metavar="NAME",
        help=f"integrator names (default: {' '.join(LONG_INTEGRATORS)})",
    )
    parser.add_argument(
        "--time", type=float, default=200.0, help="ps of the one-evaluation rows (default 200)"
    )
    parser.add_argument(
        "--time-multi",
        type=float,
        default=None,
        help="ps of the rows that take more than one force evaluation per step (default: --time)",
    )
    add_platform_arguments(parser)
    parser.add_argument(
        "--energy-interval", type=int, default=50, help="steps between energy rows (default 50)"
    )
    parser.add_argument("--window", type=float, default=10.0, help="ps per RMS window (default 10)")
    parser.add_argument(
        "--blocks", type=int, default=10, help="blocks of the drift's standard error (default 10)"
    )
    parser.add_argument("--output", default="alphaprk-long", help="output folder (default alphaprk-long)")
    parser.add_argument(
        "--report", action="store_true", help="run nothing: measure what the output folder holds"
    )
    parser.add_argument(
        "--cpu-threads", type=int, default=None, help="threads of the CPU platform (default: all cores)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_file_arguments(parser)
    return parser


def _check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    if args.time_multi is None:
        args.time_multi = args.time
    if min(args.time, args.time_multi, args.timestep, args.window) <= 0:
        parser.error("--time, --time-multi, --timestep and --window must be positive")
    if args.energy_interval < 1 or args.blocks < 3:
        parser.error("--energy-interval must be a positive integer and --blocks at least 3")
    unknown = unknown_systems(args.system)
    if unknown:
        parser.error(f"unknown system(s) {unknown}; choose from {', '.join(list_systems())}")
    for name in args.integrators:
        try:
            parse_integrator(name)
        except InputError as error:
            parser.error(str(error))


def _options(args: argparse.Namespace) -> RunOptions:
    frames = max(args.energy_interval, int(round(100.0 / args.timestep * 1000.0)))  # a frame per 100 ps
    return RunOptions(
        timestep=args.timestep / 1000.0,
        platform=args.platform,
        precision=args.precision,
        energy_interval=args.energy_interval,
        trajectory_interval=frames,
        checkpoint_interval=args.energy_interval * max(1, 5000 // args.energy_interval),
        cpu_threads=args.cpu_threads,
        progress=not args.no_progress,
    )


def _interval_note(names: Sequence[str], energy_interval: int) -> str:
    """Say which rows rescale every N steps with N dividing the energy interval: sampled when held.

    Examples
    --------
    >>> from openmm_alphaprk.benchmarks.long import _interval_note
    >>> _interval_note(["rattle", "rattle+rescale@10"], 50)[:60]
    ' RATTLE + rescaling every 10 steps: every energy row falls o'
    >>> _interval_note(["rattle+rescale@10"], 25)
    ''
    """
    held = [
        label(name)
        for name in names
        if getattr(parse_integrator(name), "rescale_interval", 1) > 1
        and energy_interval % parse_integrator(name).rescale_interval == 0
    ]
    if not held:
        return ""
    return (
        f" {', '.join(held)}: every energy row falls on a rescaled step (the energy interval is a multiple "
        "of N), where H = E_ref; between them H moves as RATTLE's does (an energy interval that N does "
        "not divide samples those steps too)."
    )


def _one_system(name: str, args: argparse.Namespace, output: Path) -> tuple[dict, bool]:
    """Run (unless ``--report``) and measure one system; return its JSON entry and if it was interrupted."""
    prepared = prepare_system(system_to_prepare(name, args), progress=not args.no_progress)
    prepared.system.setDefaultPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
    folder = output / rundir.folder_name(prepared.name)
    steps = {n: planned_steps(n, args.timestep, args.time, args.time_multi) for n in args.integrators}
    failures, interrupted = {}, False
    if not args.report:
        try:
            failures = run_rows(prepared, args.integrators, folder, _options(args), steps)
        except RunInterrupted as stop:
            print(str(stop), file=sys.stderr, flush=True)
            interrupted = True
    dof = degrees_of_freedom(prepared.system)
    rows, traces = analyse_rows(
        prepared.name,
        args.integrators,
        folder,
        dof,
        steps,
        timestep_ps=args.timestep / 1000.0,
        window_ps=args.window,
        blocks=args.blocks,
        failures=failures,
    )
    precision = f" ({args.precision} precision)" if args.precision else ""
    header = (
        f"system {prepared.name}, {prepared.n_atoms} atoms, {dof} DOF, {args.timestep:g} fs, platform "
        f"{args.platform}{precision}; one-evaluation rows {args.time:g} ps, the others {args.time_multi:g} ps"
    )
    table = format_long_table(rows, header)
    note = TABLE_NOTE.format(blocks=args.blocks, window=args.window, interval=args.energy_interval)
    comparisons = {
        f"{n} vs {base}": windows_against(rows, n, base)
        for n, base in (("energy4", "alpha4=0"), ("energy", "rattle"))
        if windows_against(rows, n, base)
    }
    note += _interval_note(args.integrators, args.energy_interval) + _rescaling_step_note(rows)
    note += "".join(
        f" {row.label}: |P - P_carried| = {row.carried_momentum_error:.2g} amu nm/ps after "
        f"{row.simulated_ps:g} ps (the momentum its rescaling carries against the state's)."
        for row in rows
        if row.carried_momentum_error == row.carried_momentum_error
    )
    text = (
        table
        + "\n\n"
        + note
        + "".join(
            f"\nwindows ({args.window:g} ps) where {key.replace(' vs ', ' is above ')}: {value['above']} of "
            f"{value['windows']} (largest ratio {value['largest_ratio']})"
            for key, value in comparisons.items()
        )
    )
    print(text, flush=True)
    (folder / "table.txt").write_text(text + "\n", encoding="utf-8")
    figure = None
    if traces:
        figure = _figure(traces, folder / "energy_residuals.png", f"H - E_ref, {prepared.name}", header, dof)
    entry = {
        "header": header,
        "note": note,
        "rows": [asdict(row) for row in rows],
        "windows_compared": comparisons,
        "figure": figure,
        "interrupted": interrupted,
    }
    return entry, interrupted


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point: 0 when every row is complete, 130 when interrupted, 1 if a row failed."""
    parser = _parser()
    args = parser.parse_args(argv)
    _check_arguments(parser, args)
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)
    results_file = output / "long.json"
    results = json.loads(results_file.read_text(encoding="utf-8")) if results_file.is_file() else {}
    for name in args.system:
        entry, interrupted = _one_system(name, args, output)
        results[name] = entry
        rundir.replace_text(results_file, json.dumps(results, indent=1) + "\n")
        if interrupted:
            print(
                f"interrupted: the same command resumes it (results so far in {results_file})",
                file=sys.stderr,
            )
            return 130
    failed = any(row["failure"] for entry in results.values() for row in entry["rows"])
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
