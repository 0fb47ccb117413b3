"""Several integrators from the same equilibrated start, side by side: table, JSON and figure."""

from __future__ import annotations

import json
import os
import textwrap
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from .._units import InputError
from ..equal_cost import equal_cost_baselines, equal_cost_divisor, gain, gain_text
from ..observables import VERLET_IS_LEAPFROG, drift_text
from ..runs import RunOptions, RunSummary, run_nve, rundir
from ..runs.accuracy import REFERENCE_DIVISOR, Horizon, short_horizon_errors
from ..runs.integrator_names import IntegratorSpec, at_divisor, check_compatible, parse_integrator
from ..runs.reporters import EVERY_STEP
from ..systems import PreparedSystem, load_definition, prepare_system


@dataclass(frozen=True)
class ComparisonPreset:
    """A comparison the command line runs by name: its system, integrators and length."""

    system: str
    integrators: tuple[str, ...]
    steps: int


#: The main job, ``alphaprk compare``: RATTLE, the recommended compositions with rescaling, the
#: composition without it and the energy mode on the 2 nm water box for 0.5 ps (under a minute
#: on two cores; docs/getting_started.md gives where the time goes).
MAIN_JOB = ComparisonPreset(
    "tip3p-2nm", ("rattle", "rattle+rescale", "rattle4+rescale", "alpha4=0", "energy4"), 250
)
#: ``alphaprk compare --full``: the 3 nm box for 2 ps, ``VerletIntegrator`` included.
FULL_COMPARISON = ComparisonPreset(
    "tip3p-3nm", ("rattle", "rattle+rescale", "rattle4+rescale", "alpha4=0", "energy4", "verlet"), 1000
)
DEFAULT_SYSTEM = MAIN_JOB.system
DEFAULT_INTEGRATORS = MAIN_JOB.integrators
#: A row holds the energy when its RMS(H − E_ref) is below RATTLE's over this.
HELD_FACTOR = 100.0
#: Steps of h after which each row's position error is taken against RATTLE at h/64 (2 fs: 20 fs).
ACCURACY_STEPS = 10
COMPARISON_FILE = "comparison.json"
FIGURE_FILE = "energy_residuals.png"

VERLET_NOTE = "verlet = " + VERLET_IS_LEAPFROG


@dataclass
class Comparison:
    """The runs of a comparison, its printed table and the files written.

    Attributes
    ----------
    system : str
        The system's name.
    summaries : list of RunSummary
        One per row, the listed integrators first, then RATTLE at h/k.
    table : str
        The printed table with its notes, the gains at equal cost and the verdict.
    output : pathlib.Path
        The comparison's folder.
    figure : pathlib.Path or None
        ``energy_residuals.png``, None without ``plot``.
    accuracy : dict of str to Horizon
        Each row's position and velocity errors against RATTLE at h/64.
    verdict : str
        The one-line verdict (:func:`verdict`), "" without a RATTLE row.

    Examples
    --------
    >>> from openmm_alphaprk.workflows import compare
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     result = compare("water-cluster", ["rattle", "rattle+rescale"], f"{folder}/cmp", steps=4,
    ...                      plot=False, progress=False, accuracy_steps=0)
    >>> [summary.integrator for summary in result.summaries]
    ['rattle', 'rattle+rescale']
    >>> result.verdict.startswith("verdict: rattle+rescale is best at equal cost")
    True
    """

    system: str
    summaries: list[RunSummary]
    table: str
    output: Path
    figure: Path | None
    accuracy: dict[str, Horizon] = field(default_factory=dict)
    verdict: str = ""


def compare(
    system: str | PreparedSystem = DEFAULT_SYSTEM,
    integrators: Sequence[str | IntegratorSpec] = DEFAULT_INTEGRATORS,
    output: str | os.PathLike = "alphaprk-compare",
    options: RunOptions | None = None,
    *,
    plot: bool = True,
    equal_cost: bool = True,
    accuracy_steps: int = ACCURACY_STEPS,
    **keywords,
) -> Comparison:
    """Run every integrator from the same start state and compare energy conservation and cost.

    Each integrator gets its own run directory ``output/<integrator>`` (see
    :func:`~openmm_alphaprk.runs.run_nve`; an interrupted comparison resumes where it
    stopped). Writes ``comparison.json``, the table (``table.txt``, with notes that define
    E_ref, the drift ± standard error and "fell back"), and ``energy_residuals.png``
    (H − E_ref against time for all integrators, with the table's RMS and drift).

    Parameters
    ----------
    system : str or PreparedSystem, default "tip3p-2nm"
        System name (``alphaprk systems``), path of a ``.toml`` definition, or a
        :class:`~openmm_alphaprk.systems.PreparedSystem`.
    integrators : sequence of str or IntegratorSpec
        Integrator names (``rattle``, ``rattle+rescale``, ``rattle4+rescale``, ``alpha4=0``,
        ``energy4``, ``verlet``, ``alpha=<number>``, ...); default the main job's
        (:data:`MAIN_JOB`).
    output : str or os.PathLike, default "alphaprk-compare"
        Folder of the comparison; a relative path is taken from the current directory
        (the default, ``alphaprk-compare``, is created there).
    options : RunOptions, optional
        The options of every run, a :class:`~openmm_alphaprk.runs.RunOptions` and/or
        its fields as keywords (``steps`` per integrator, ``timestep``, ``platform``,
        ``precision``, ``constraint_tolerance``, intervals, ``cache_dir``, ``progress``),
        as for :func:`~openmm_alphaprk.runs.run_nve`.
    **keywords
        Fields of :class:`~openmm_alphaprk.runs.RunOptions`, replacing those of ``options``.
    plot : bool, default True
        Write the figure (needs matplotlib).
    equal_cost : bool, default True
        After the listed runs, also run RATTLE at h/k for the same simulated time, k the
        measured force evaluations per step of a row that takes more than one, rounded
        up (one run per distinct k; folder ``rattle_h_k``), and state each such row's
        gain at equal cost, RMS(H − E_ref) of RATTLE at h/k over the row's (table, JSON).
    accuracy_steps : int, default 10
        Also give every row's position error against RATTLE at h/64 after this many
        steps from the start (a separate short run of each; 0: none), the table's
        ``pos. error`` column, and state it in the gains at equal cost. Not for
        ``verlet``, which reads the start's velocities as half-step velocities.

    Raises
    ------
    UnknownSystemError, UnknownIntegratorError, IncompatibleSystemError, RunDirectoryError
        Before any run starts.

    Examples
    --------
    RATTLE and the recommended ``rattle4+rescale`` on the water cluster, a few steps (the
    main job, :data:`MAIN_JOB`, runs 250 steps of five integrators on ``tip3p-2nm``):

    >>> from openmm_alphaprk.workflows import compare
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     result = compare("water-cluster", ["rattle", "rattle4+rescale"], f"{folder}/cmp", steps=4,
    ...                      plot=False, progress=False, accuracy_steps=2)
    >>> [summary.integrator for summary in result.summaries]  # RATTLE at h/5: the same cost
    ['rattle', 'rattle4+rescale', 'rattle h/5']
    >>> result.verdict.startswith("verdict: rattle4+rescale is best at equal cost")
    True
    >>> "closer than RATTLE at h/5" in result.verdict  # its positions, at the same cost
    True
    """
    specs = _integrators(integrators)
    options = RunOptions.build(options, **keywords)
    if not isinstance(system, PreparedSystem):
        load_definition(system)  # an unknown name fails before anything else
    output = Path(output)
    _check_output(output, plot)
    prepared = _prepare(system, specs, options)
    directories = {spec.name: output / run_directory_name(spec) for spec in specs}
    for spec in specs:  # refuse a directory holding different runs before running anything
        rundir.check_run_directory(directories[spec.name], rundir.run_parameters(prepared, spec, options))
    output.mkdir(parents=True, exist_ok=True)
    summaries = [run_nve(prepared, spec, directories[spec.name], options) for spec in specs]
    if equal_cost:
        for k in equal_cost_divisors(summaries):
            name = equal_cost_name(k)
            directories[name] = output / rundir.folder_name(name)
            summaries.append(_run_equal_cost_rattle(prepared, k, directories[name], options))
    accuracy = _accuracy(prepared, specs, summaries, options, accuracy_steps)
    gains = equal_cost_gains(summaries, accuracy)
    header = _header(prepared, summaries[0], options)
    table = format_comparison_table(
        summaries, header, any(spec.kind == "verlet" for spec in specs), gains, accuracy
    )
    said = verdict(summaries, accuracy)
    if said:
        table += "\n" + said
    leapfrog = [spec.name for spec in specs if spec.kind == "verlet"]
    figure = _figure(directories, output, summaries[0], options, leapfrog) if plot else None
    _write(output, prepared.name, header, directories, summaries, figure, table, gains, accuracy, said)
    return Comparison(prepared.name, summaries, table, output, figure, accuracy, said)


def _accuracy(
    prepared: PreparedSystem,
    specs: list[IntegratorSpec],
    summaries: list[RunSummary],
    options: RunOptions,
    steps: int,
) -> dict[str, Horizon]:
    """Each row's error against RATTLE at h/64 after ``steps`` steps of h (short runs from the start)."""
    if steps <= 0:
        return {}
    h = options.timestep_ps
    rows = {spec.name: at_divisor(spec, h) for spec in specs if spec.kind != "verlet"}
    for summary in summaries:
        if summary.integrator.startswith(equal_cost_name("")):
            k = int(summary.integrator.rpartition("/")[2])
            rows[summary.integrator] = at_divisor("rattle", h, k)
    properties = {"Precision": options.precision} if options.precision else None
    return short_horizon_errors(prepared, rows, h, steps, platform=options.platform, properties=properties)


def equal_cost_name(k: int) -> str:
    """Return the row name of RATTLE at h/k, ``rattle h/k``."""
    return f"rattle h/{k}"


def _costs_more_than_rattle(summary: RunSummary) -> bool:
    """Tell whether a row takes more than one force evaluation per step (not an equal-cost row)."""
    return (
        not summary.integrator.startswith(equal_cost_name(0)[:-1])
        and equal_cost_divisor(summary.force_evaluations_per_step) > 1
    )


def equal_cost_divisors(summaries: Sequence[RunSummary]) -> list[int]:
    """Return the distinct k = ⌈force evaluations per step⌉ > 1 of the rows, in row order."""
    divisors = []
    for summary in summaries:
        if _costs_more_than_rattle(summary):
            k = equal_cost_divisor(summary.force_evaluations_per_step)
            if k not in divisors:
                divisors.append(k)
    return divisors


def _run_equal_cost_rattle(
    prepared: PreparedSystem, k: int, directory: Path, options: RunOptions
) -> RunSummary:
    """Run RATTLE at h/k for the same simulated time, its energy read at the same simulated times."""
    intervals = {
        name: getattr(options, name) * k
        for name in ("energy_interval", "trajectory_interval", "checkpoint_interval", "velocity_interval")
        if getattr(options, name) is not None
    }
    rattle_options = replace(options, timestep=options.timestep_ps / k, steps=options.steps * k, **intervals)
    spec = parse_integrator("rattle")
    rundir.check_run_directory(directory, rundir.run_parameters(prepared, spec, rattle_options))
    return replace(run_nve(prepared, spec, directory, rattle_options), integrator=equal_cost_name(k))


def equal_cost_gains(
    summaries: Sequence[RunSummary], accuracy: dict[str, Horizon] | None = None
) -> list[dict]:
    """For each row of k > 1 evaluations per step: k, and RATTLE h/k's RMS(H − E_ref) over the row's.

    With ``accuracy`` (:func:`_accuracy`'s errors) also both rows' RMS position errors and
    their ratio, ``position_gain`` (RATTLE h/k's over the row's: below 1, RATTLE at equal
    cost is the more accurate).
    """
    accuracy = accuracy or {}
    by_name = {summary.integrator: summary for summary in summaries}
    baselines = equal_cost_baselines(
        {s.integrator: s.force_evaluations_per_step for s in summaries if _costs_more_than_rattle(s)},
        equal_cost_name,
        by_name,
    )
    gains = []
    for name, (k, baseline) in baselines.items():
        summary, rattle = by_name[name], by_name[baseline]
        entry = {
            "integrator": name,
            "k": k,
            "rattle_row": baseline,
            "rms_residual": summary.rms_residual,
            "rattle_rms_residual": rattle.rms_residual,
            "gain": gain(rattle.rms_residual, summary.rms_residual),
        }
        if name in accuracy and baseline in accuracy:
            mine, theirs = accuracy[name], accuracy[baseline]
            entry.update(
                position_time_fs=mine.time_fs,
                position_error=mine.position_rms,
                rattle_position_error=theirs.position_rms,
                position_gain=gain(theirs.position_rms, mine.position_rms),
            )
        gains.append(entry)
    return gains


@dataclass(frozen=True)
class EqualCostStanding:
    """One row against RATTLE at the same force evaluations (RATTLE itself for one per step)."""

    integrator: str
    baseline: str
    rms_residual: float
    baseline_rms_residual: float
    energy_gain: float
    holds_energy: bool
    position_gain: float | None


def equal_cost_standings(
    summaries: Sequence[RunSummary], accuracy: dict[str, Horizon] | None = None
) -> list[EqualCostStanding]:
    """Each row (RATTLE, ``verlet`` and the h/k rows excepted) against RATTLE at equal cost.

    A row of k force evaluations per step is set against RATTLE at h/k, a row of one
    (``rattle+rescale``) against RATTLE; rows whose baseline did not run are left out. A row
    holds the energy when its RMS(H − E_ref) is below RATTLE's over :data:`HELD_FACTOR`.
    """
    accuracy = accuracy or {}
    by_name = {summary.integrator: summary for summary in summaries}
    rattle = by_name.get("rattle")
    if rattle is None:
        return []
    standings = []
    for summary in summaries:
        name = summary.integrator
        if name == "rattle" or name.startswith(equal_cost_name(0)[:-1]) or name == "verlet":
            continue
        k = equal_cost_divisor(summary.force_evaluations_per_step)
        baseline = "rattle" if k == 1 else equal_cost_name(k)
        if baseline not in by_name:
            continue
        position = None
        if name in accuracy and baseline in accuracy:
            position = gain(accuracy[baseline].position_rms, accuracy[name].position_rms)
        standings.append(
            EqualCostStanding(
                name,
                baseline,
                summary.rms_residual,
                by_name[baseline].rms_residual,
                gain(by_name[baseline].rms_residual, summary.rms_residual),
                summary.rms_residual < rattle.rms_residual / HELD_FACTOR,
                position,
            )
        )
    return standings


def verdict(summaries: Sequence[RunSummary], accuracy: dict[str, Horizon] | None = None) -> str:
    """Return the comparison's one-line verdict: the best row at equal cost, and the energy mode's standing.

    The best row holds the energy (:func:`equal_cost_standings`) and has the largest
    position gain over RATTLE at equal cost (without position errors: the largest energy
    gain). Empty without a RATTLE row or a row to set against it.

    Parameters
    ----------
    summaries : sequence of RunSummary
        The comparison's rows, RATTLE and RATTLE at h/k among them.
    accuracy : dict of str to Horizon, optional
        Each row's errors against RATTLE at h/64 (:attr:`Comparison.accuracy`).

    Returns
    -------
    str
        ``"verdict: ROW is best at equal cost: ..."``, or "".

    Examples
    --------
    >>> from openmm_alphaprk.runs import RunSummary
    >>> from openmm_alphaprk.workflows.comparison import verdict
    >>> def row(name, rms, evaluations=1.0):
    ...     return RunSummary("box", name, 3, 6, 2.0, 10, 0.02, "CPU", 0.0, 0.0, 0.0, False, rms, rms,
    ...                       10, 0.0, 0.0, 1.0, 1.0, 10, evaluations, True)
    >>> verdict([row("rattle", 0.5), row("rattle+rescale", 1e-6), row("energy4", 0.004, 8.4),
    ...          row("rattle h/9", 0.015)])  # doctest: +NORMALIZE_WHITESPACE
    'verdict: rattle+rescale is best at equal cost: RMS|H - E_ref| 1e-06 kJ/mol (RATTLE 0.5);
     the energy mode energy4: energy error 3.75x lower than RATTLE at h/9'
    """
    standings = equal_cost_standings(summaries, accuracy)
    if not standings:
        return ""
    rattle = next(s for s in summaries if s.integrator == "rattle")

    def rank(standing: EqualCostStanding) -> tuple:
        position = standing.position_gain if standing.position_gain is not None else 0.0
        return (standing.holds_energy, position, standing.energy_gain)

    best = max(standings, key=rank)
    line = f"verdict: {best.integrator} is best at equal cost: RMS|H - E_ref| {best.rms_residual:.2g} kJ/mol"
    line += f" (RATTLE {rattle.rms_residual:.2g}"
    line += (
        ")" if best.baseline == "rattle" else f", at h/{best.baseline[9:]} {best.baseline_rms_residual:.2g})"
    )
    if best.position_gain is not None:
        line += f", positions {_position_text(best.position_gain)} {_against(best)}"
    for standing in standings:
        if standing.integrator.startswith("energy") and standing is not best:
            line += (
                f"; the energy mode {standing.integrator}: energy error "
                f"{gain_text(standing.energy_gain)} {_against(standing)}"
            )
            if standing.position_gain is not None:
                line += f", positions {_position_text(standing.position_gain)}"
    return line


def _position_text(ratio: float) -> str:
    """Say a position gain as "14.7x closer" or "1.4x farther"."""
    text = gain_text(ratio)
    return text.replace("lower", "closer").replace("higher", "farther")


def _against(standing: EqualCostStanding) -> str:
    return "than RATTLE's" if standing.baseline == "rattle" else f"than RATTLE at h/{standing.baseline[9:]}"


def _ratio_text(ratio: float) -> str:
    """Say a ratio of the baseline's error over the row's as lower or higher, never as '0.85x lower'."""
    return gain_text(ratio, loss="{}: no gain at equal cost")


def gain_line(gain: dict) -> str:
    """Return the table's line for one row's gain at equal cost (or its loss, said as such)."""
    line = (
        f"{gain['integrator']} at equal cost: RMS|H - E_ref| {gain['rms_residual']:.3g} kJ/mol against "
        f"{gain['rattle_row']} ({gain['k']} RATTLE steps of h/{gain['k']} per step of h, the same force "
        f"evaluations) {gain['rattle_rms_residual']:.3g}: {_ratio_text(gain['gain'])}"
    )
    if "position_gain" in gain:
        line += (
            f"; RMS position error after {gain['position_time_fs']:g} fs {gain['position_error']:.2g} nm "
            f"against {gain['rattle_position_error']:.2g}: {_ratio_text(gain['position_gain'])}"
        )
    return line


def _check_output(output: Path, plot: bool) -> None:
    """Refuse a folder that holds something else than a comparison; with ``plot``, check for matplotlib.

    A comparison folder is one with ``comparison.json``, or one that an interrupted comparison
    left: nothing in it but run directories (each empty or holding its ``run.json``).
    """
    if output.exists() and not _is_comparison_folder(output):
        raise rundir.RunDirectoryError(
            f"output directory {output} is not empty and holds neither {COMPARISON_FILE} nor only the run "
            "directories of an interrupted comparison: it is not a comparison directory. Choose a new or "
            "empty directory."
        )
    if plot:
        from .plots import pyplot

        pyplot()  # fail now, not after the runs, if matplotlib is missing


def _is_comparison_folder(output: Path) -> bool:
    """Whether ``output`` is empty, a finished comparison, or the run directories of an interrupted one."""
    if (output / COMPARISON_FILE).is_file():
        return True
    for entry in output.iterdir():
        if not entry.is_dir():
            return False
        if any(entry.iterdir()) and not (entry / rundir.PARAMETERS_FILE).is_file():
            return False
    return True


def _header(prepared: PreparedSystem, first: RunSummary, options: RunOptions) -> str:
    """Return the table's and figure's title line: system, step, length, platform, sampling."""
    steps, timestep_ps = options.steps, options.timestep_ps
    return (
        f"{prepared.name}: {prepared.n_atoms} atoms, {first.degrees_of_freedom} DOF, "
        f"{timestep_ps * 1000:g} fs, {steps} steps ({steps * timestep_ps:g} ps) NVE from the same start, "
        f"platform {first.platform}; H - E_ref sampled every {options.energy_interval} steps"
    )


def _integrators(integrators: Sequence[str | IntegratorSpec]) -> list[IntegratorSpec]:
    """Parse the integrators; refuse none and repeats."""
    specs = [parse_integrator(name) for name in integrators]
    if not specs:
        raise InputError("give at least one integrator to compare.")
    names = [spec.name for spec in specs]
    if len(set(names)) != len(names):
        raise InputError(f"integrators are repeated: {names}; give each once.")
    return specs


def _prepare(
    system: str | PreparedSystem, specs: list[IntegratorSpec], options: RunOptions
) -> PreparedSystem:
    """Build (or load) the system once, checked against every integrator."""
    prepared = (
        system
        if isinstance(system, PreparedSystem)
        else prepare_system(
            system,
            cache_dir=options.cache_dir,
            progress=options.progress,
            check=lambda built: [
                check_compatible(spec, built, repr(str(system)), options.platform) for spec in specs
            ],
        )
    )
    for spec in specs:
        check_compatible(spec, prepared.system, repr(prepared.name), options.platform)
    return prepared


def _figure(
    directories: dict[str, Path], output: Path, first: RunSummary, options: RunOptions, leapfrog: list[str]
) -> Path:
    """Plot H − E_ref of every run against time (leapfrog Verlet in its own panel); return the path."""
    from .plots import plot_energy_residuals, run_caption

    traces = {}
    for name, directory in directories.items():
        energies = rundir.read_energies(directory / rundir.ENERGIES_FILE)
        traces[name] = energies[:, 1], energies[:, 4] - energies[0, 4]
    caption = run_caption(
        first.system,
        first.n_atoms,
        first.timestep_fs,
        first.steps,
        first.platform,
        precision=options.precision,
        dof=first.degrees_of_freedom,
        energy_interval=options.energy_interval,
    )
    path = output / FIGURE_FILE
    return Path(
        plot_energy_residuals(
            traces, path, caption=caption, not_comparable=leapfrog, dof=first.degrees_of_freedom
        )
    )


def _write(
    output: Path,
    system: str,
    header: str,
    directories: dict[str, Path],
    summaries: list[RunSummary],
    figure: Path | None,
    table: str,
    gains: list[dict],
    accuracy: dict[str, Horizon],
    said: str,
) -> None:
    """Write ``comparison.json`` and ``table.txt``."""
    (output / COMPARISON_FILE).write_text(
        json.dumps(
            {
                "system": system,
                "header": header,
                "runs": {name: str(directory) for name, directory in directories.items()},
                "summaries": [summary.as_dict() for summary in summaries],
                "equal_cost": gains,
                "accuracy": {
                    "reference": f"RATTLE at h/{REFERENCE_DIVISOR}, constraint tolerance 1e-10, same start",
                    "rows": {name: asdict(horizon) for name, horizon in accuracy.items()},
                },
                "figure": str(figure) if figure else None,
                "verdict": said,
            },
            indent=2,
        )
        + "\n"
    )
    (output / "table.txt").write_text(table + "\n", encoding="utf-8")


def run_directory_name(spec: IntegratorSpec) -> str:
    """Return a folder name for an integrator (``alpha=1/6`` → ``alpha=1_6``)."""
    return rundir.folder_name(spec.name)


#: What the table's energy columns are, printed under it.
ENERGY_NOTE = (
    "E_ref = total energy of the start state (step 0). RMS and max |H - E_ref|: over the energy rows "
    "after step 0. drift/DOF: slope of a least-squares line through those rows per degree of freedom, "
    "± its standard error (widened for correlated rows); 'not resolved' when |drift| < 2 standard "
    "errors: the run is too short to tell it from zero."
)
#: What the position-error column is, printed under the table.
ACCURACY_NOTE = (
    "pos. error: RMS over atoms of the distance to RATTLE at h/64 (constraint tolerance 1e-10) after "
    "{after:g} fs, each row run again from the start; a measure of how close the dynamics stays to the "
    "true dynamics, which holding the energy does not make closer ('-': not measured; verlet reads the "
    "start's velocities as half-step velocities)."
)
#: What "fell back" and "at a bound" mean, printed under the energy mode's line.
CONTROLLER_NOTE = (
    "fell back = the step ended with |H - E_ref| above the energy tolerance (no alpha trial reached it "
    "within the bounds and max_trials; the step is then the alpha = 0 step of its base, unless an alpha "
    "trial ended closer to E_ref); at a bound = alpha* sat at an end of alpha_bounds."
)
_WRAP = 110


def format_comparison_table(
    summaries: Sequence[RunSummary],
    header: str = "",
    verlet_note: bool = True,
    gains: Sequence[dict] = (),
    accuracy: dict[str, Horizon] | None = None,
) -> str:
    """Format the comparison table as plain text (units in the column titles), with its notes.

    Drifts are printed by :func:`~openmm_alphaprk.observables.drift_text` (± standard
    error, or "not resolved"), energies with three significant digits, as in the figure.
    ``gains`` (:func:`equal_cost_gains`) adds a line per row of more than one evaluation per
    step; ``accuracy``
    (row name → :class:`~openmm_alphaprk.runs.accuracy.Horizon`) a column of RMS position
    errors against RATTLE at h/64.
    """
    accuracy = accuracy or {}
    width = max([14, *(len(s.integrator) + 1 for s in summaries)])
    after = next(iter(accuracy.values())).time_fs if accuracy else None
    position = f" {'pos. error':>10}" if accuracy else ""
    lines = [header] if header else []
    lines.append(
        f"{'integrator':<{width}} {'steps':>6}  {'drift/DOF':<26} {'RMS|H-Eref|':>11} {'max|H-Eref|':>11} "
        f"{'constraint':>11} {'evals/step':>10} {'ns/day':>8}{position}"
    )
    unit_line = f" {f'nm, {after:g} fs':>10}" if accuracy else ""
    lines.append(
        f"{'':<{width}} {'':>6}  {'kJ/mol/ns ± std. error':<26} {'kJ/mol':>11} {'kJ/mol':>11} "
        f"{'rel. error':>11} {'':>10} {'':>8}{unit_line}"
    )
    for s in summaries:
        drift = drift_text(s.drift_per_dof, s.drift_per_dof_standard_error)
        error = ""
        if accuracy:
            error = (
                f" {accuracy[s.integrator].position_rms:>10.2e}"
                if s.integrator in accuracy
                else f" {'-':>10}"
            )
        lines.append(
            f"{s.integrator:<{width}} {s.steps:>6}  {drift:<26} {s.rms_residual:>11.3g} "
            f"{s.max_abs_residual:>11.3g} {s.max_relative_constraint_error:>11.1e} "
            f"{s.force_evaluations_per_step:>10.2f} {s.ns_per_day:>8.2f}{error}"
        )
    lines += textwrap.wrap(ENERGY_NOTE, _WRAP)
    if accuracy:
        lines += textwrap.wrap(ACCURACY_NOTE.format(after=after), _WRAP)
    controllers = [s for s in summaries if s.controller]
    for s in controllers:
        lines += textwrap.wrap(controller_line(s.integrator, s.controller), _WRAP, subsequent_indent="  ")
    if controllers:
        lines += textwrap.wrap(CONTROLLER_NOTE, _WRAP)
    for entry in gains:
        lines += textwrap.wrap(gain_line(entry), _WRAP, subsequent_indent="  ")
    for s in summaries:
        if s.momentum_change:
            m = s.momentum_change
            lines.append(
                f"{s.integrator}: isolated system, max change of linear momentum "
                f"{m['linear_amu_nm_per_ps']:.1e} amu nm/ps, of angular momentum "
                f"{m['angular_amu_nm2_per_ps']:.1e} amu nm^2/ps"
            )
    for s in summaries:  # what a rescaling removed (the leapfrog caveat is VERLET_NOTE, below)
        for note in s.notes:
            if not note.startswith(VERLET_IS_LEAPFROG):
                lines += textwrap.wrap(note, _WRAP, subsequent_indent="  ")
    if verlet_note:
        lines.append(VERLET_NOTE)
    return "\n".join(lines)


def controller_line(name: str, controller: dict) -> str:
    """Return the energy mode's line under the table: its statistics over every step, α* over the samples."""
    c = controller
    p = c["alpha_percentiles"]
    residuals = (
        f"RMS |H - E_ref| {c['rms_residual']:.3g} kJ/mol, max {c['max_abs_residual']:.3g} kJ/mol; "
        if c["residuals_over"] == EVERY_STEP
        else ""
    )
    return (
        f"{name} (energy mode), over all {c['steps']} steps: {residuals}fell back on "
        f"{c['fraction_fallen_back']:.0%} of steps, alpha* at a bound on {c['fraction_at_bound']:.0%}, "
        f"{c['force_evaluations_per_step']:.2f} force evaluations per step; alpha* median {p['p50']:.2g} "
        f"(p5 {p['p5']:.2g}, p95 {p['p95']:.2g}) over {c['rows']} sampled steps (controller.csv)"
    )
