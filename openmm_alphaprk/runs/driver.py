"""NVE runs of a prepared system with a chosen integrator, written as they go and resumable.

:func:`run_nve` writes a run directory (see :mod:`openmm_alphaprk.runs.rundir`) with
OpenMM's own reporters — ``StateDataReporter`` (energies CSV), ``DCDReporter`` — and
checkpoints (:mod:`.checkpoints`), plus :class:`~openmm_alphaprk.runs.AlphaControllerReporter`
for the energy mode, and a JSON summary at the end. Calling it again on the same
directory with the same settings resumes from the last checkpoint (or reports the
finished run); other settings are refused.

A run is prepared (options, platform, system, directory), simulated (from its start
state or its last checkpoint, with the reporters) and written (``summary.json``).
Checkpoints are written every ``checkpoint_interval`` steps, after
``checkpoint_seconds`` of wall time, and when the run is interrupted (Ctrl-C) between
steps; the :class:`RunInterrupted` raised then says from which step the same call resumes.
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import openmm as mm
import openmm.app as app
import openmm.unit as unit
from tqdm import tqdm

from ..errors import AlphaPRKError
from ..integrators import check_context
from ..nve import LargeStepWarning, step_size_problem
from ..systems import PreparedSystem, prepare_system
from . import rundir
from .checkpoints import (
    CheckpointReporter,
    RunInterrupted,
    Tracked,
    TrackedControllerReporter,
    TrackedDCDReporter,
    TrackedStateDataReporter,
    TrackedTRRReporter,
    deferred_interrupt,
    interrupted,
)
from .integrator_names import IntegratorSpec, check_compatible, make_integrator, parse_integrator
from .options import RunOptions
from .summary import RunSummary, read_summary, summarize


class RunFailedError(AlphaPRKError, RuntimeError):
    """Raised when a run stops on a NaN or a failed step; the output up to then is kept.

    Examples
    --------
    A 20 fs step blows the water cluster up at once (the driver warns first):

    >>> import os, tempfile, warnings
    >>> from openmm_alphaprk.runs import run_nve
    >>> with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     run_nve("water-cluster", "rattle", os.path.join(folder, "run"), steps=20, timestep=0.02,
    ...             platform="Reference", progress=False)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.runs.driver.RunFailedError: run in .../run stopped at step 1 of 20 with ...
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    water-cluster: a 20 fs step is above about 4.5 fs, ...
    """


@dataclass
class _Run:
    """A prepared run: its system, integrator, options, directory and whether it resumes."""

    output: Path
    prepared: PreparedSystem
    spec: IntegratorSpec
    options: RunOptions
    platform: mm.Platform
    properties: dict[str, str]
    resume: bool
    lock: object = None  # the open lock file of the run directory (rundir.lock_run_directory)


def run_nve(
    system: str | PreparedSystem,
    integrator: str | IntegratorSpec,
    output: str | os.PathLike,
    options: RunOptions | None = None,
    *,
    extra_reporters: list | None = None,
    **keywords,
) -> RunSummary:
    """Run NVE dynamics and write energies, trajectory, checkpoints and a summary to ``output``.

    Parameters
    ----------
    system : str or PreparedSystem
        A system name (``alphaprk systems``) or a :class:`~openmm_alphaprk.systems.PreparedSystem`.
    integrator : str or IntegratorSpec
        ``rattle``, ``rattle4+rescale``, ``verlet``, ``energy4``, ``alpha=<number>``, …; see
        :mod:`openmm_alphaprk.runs.integrator_names`.
    output : str or os.PathLike
        Run directory; created if missing. If it holds this run (same settings except
        ``steps``), the run resumes from its last checkpoint, or is extended to ``steps``.
    options : RunOptions, optional
        A :class:`~openmm_alphaprk.runs.RunOptions` (steps, timestep, platform,
        precision, constraint_tolerance, intervals, checkpoint_seconds, velocity_seed,
        cpu_threads, cache_dir, progress); default: the defaults.
    extra_reporters : list of OpenMM reporters, optional
        More OpenMM reporters, added after the run's own.
    **keywords
        Fields of :class:`~openmm_alphaprk.runs.RunOptions`, which replace the
        ``options``' own, e.g. ``steps=2000, timestep=0.001``.

    Returns
    -------
    RunSummary
        Also written to ``summary.json``.

    Raises
    ------
    UnknownSystemError, UnknownIntegratorError, IncompatibleSystemError, RunDirectoryError
        Before any work, for an unknown system or integrator, a system the integrator
        cannot run (virtual sites), or a directory that holds a different run.
    ValueError, TypeError
        For bad numbers or units.
    RunFailedError
        If the run blows up (NaN energy, failed midpoint iteration); what was written stays.
    RunInterrupted
        On Ctrl-C (or another KeyboardInterrupt) while the run steps or writes its
        summary, checkpointed where the files are complete (see :mod:`.checkpoints`);
        the message says from which step the same call resumes.

    Examples
    --------
    RATTLE + rescaling with Suzuki's composition (``rattle4+rescale``) on the shipped
    water cluster, 20 steps; a second call extends the same run to 40:

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     summary = run_nve("water-cluster", "rattle4+rescale", run, steps=20, energy_interval=5,
    ...                       platform="Reference", progress=False)
    ...     files = sorted(name for name in os.listdir(run) if not name.startswith("."))
    ...     longer = run_nve("water-cluster", "rattle4+rescale", run, steps=40, energy_interval=5,
    ...                      platform="Reference", progress=False)
    >>> summary.integrator, summary.steps, summary.energy_samples, summary.force_evaluations_per_step
    ('rattle4+rescale', 20, 4, 5.0)
    >>> summary.rms_residual < 1e-6  # kJ/mol: H held at E_ref
    True
    >>> files  # doctest: +NORMALIZE_WHITESPACE
    ['checkpoint.chk', 'energies.csv', 'run.json', 'summary.json', 'system.xml',
     'topology.pdb', 'trajectory.dcd']
    >>> longer.steps, longer.steps_this_call
    (40, 20)
    """
    spec = parse_integrator(integrator)
    run = prepare_run(system, spec, Path(output), RunOptions.build(options, **keywords))
    try:
        simulation = _simulation(run)
        start_step = _restore(simulation, run) if run.resume else _start(simulation, run)
        if start_step > run.options.steps:  # an interrupted run whose checkpoint is past the length asked for
            raise rundir.RunDirectoryError(
                rundir.longer_run_message(run.output, start_step, run.options.steps)
            )
        return _complete(simulation, run, start_step, extra_reporters)
    finally:
        if run.lock is not None:
            run.lock.close()


def _complete(
    simulation: app.Simulation, run: _Run, start_step: int, extra_reporters: list | None
) -> RunSummary:
    """Step the run from ``start_step`` to its end and summarize it (or report it, if it is finished)."""
    options = run.options
    last = start_step if run.resume else None
    checkpoints = CheckpointReporter(
        run.output / rundir.CHECKPOINT_FILE,
        run.output / rundir.PREVIOUS_CHECKPOINT_FILE,
        options.checkpoint_interval,
        options.checkpoint_seconds,
        last,
    )
    try:
        if start_step >= options.steps:
            return _finished(simulation, run)
        (run.output / rundir.SUMMARY_FILE).unlink(missing_ok=True)  # extended: not complete until it ends
        wall = simulate(simulation, run, start_step, extra_reporters, checkpoints)
        return write_summary(simulation, run, wall, start_step)
    except KeyboardInterrupt as interrupt:
        if isinstance(interrupt, RunInterrupted):
            raise
        raise interrupted(simulation, run.output, options.steps, checkpoints, False) from None


def _finished(simulation: app.Simulation, run: _Run) -> RunSummary:
    """Return the summary of a finished run: the stored one, or a new one if it is missing or out of date."""
    summary_file = run.output / rundir.SUMMARY_FILE
    stored = read_summary(summary_file)
    if stored is not None:
        return stored
    # no summary (interrupted after the last step), or one lacking newer fields: summarize again
    old = json.loads(summary_file.read_text(encoding="utf-8")) if summary_file.is_file() else {}
    steps_before = simulation.currentStep - old.get("steps_this_call", 0)
    return write_summary(simulation, run, old.get("wall_seconds", 0.0), steps_before)


def prepare_run(
    system: str | PreparedSystem, spec: IntegratorSpec, output: Path, options: RunOptions
) -> _Run:
    """Check the platform, build (or load) the system, and set up the run directory.

    Everything that can be refused is refused here, before the directory is written.
    """
    platform, properties = options.openmm_platform()
    prepared = _prepare_system(system, spec, options)
    problem = step_size_problem(prepared.system, options.timestep_ps)
    if problem is not None:
        warnings.warn(f"{prepared.name}: {problem}.", LargeStepWarning, stacklevel=3)
    parameters = rundir.run_parameters(prepared, spec, options)
    rundir.check_run_directory(output, parameters)  # refused before anything is written
    output.mkdir(parents=True, exist_ok=True)
    lock = rundir.lock_run_directory(output)  # then nothing is touched while another run holds it
    try:
        stored = rundir.check_run_directory(output, parameters)
    except BaseException:
        if lock is not None:
            lock.close()
        raise
    resume = stored is not None and bool(rundir.checkpoint_files(output))
    if stored is not None and not resume:  # interrupted before its first checkpoint: start again
        rundir.remove_outputs(output)
    rundir.write_parameters(output, parameters)
    if not resume:
        (output / rundir.SYSTEM_FILE).write_text(
            mm.XmlSerializer.serialize(prepared.system), encoding="utf-8"
        )
        with open(output / rundir.TOPOLOGY_FILE, "w") as handle:
            app.PDBFile.writeFile(prepared.topology, prepared.state.getPositions(), handle, keepIds=True)
    return _Run(output, prepared, spec, options, platform, properties, resume, lock)


def _prepare_system(
    system: str | PreparedSystem, spec: IntegratorSpec, options: RunOptions
) -> PreparedSystem:
    """Return the prepared system, checked against the integrator (unknown names fail before a build)."""
    if isinstance(system, PreparedSystem):
        check_compatible(spec, system.system, repr(system.name), options.platform)
        return system
    from ..systems import load_definition

    load_definition(system)  # unknown names fail here, before a build
    return prepare_system(
        system,
        cache_dir=options.cache_dir,
        progress=options.progress,
        check=lambda built: check_compatible(spec, built, repr(str(system)), options.platform),
    )


def _simulation(run: _Run) -> app.Simulation:
    """Return the run's Simulation: its integrator, System and platform."""
    integrator = make_integrator(run.spec, run.options.timestep_ps, run.options.constraint_tolerance)
    simulation = app.Simulation(
        run.prepared.topology, run.prepared.system, integrator, run.platform, run.properties
    )
    check_context(integrator, simulation.context)  # the platform's precision, virtual sites
    return simulation


def _restore(simulation: app.Simulation, run: _Run) -> int:
    """Load the last readable checkpoint and cut the files back to it; return its step.

    A damaged last checkpoint (a disk full, a copy cut short) is said, and the one
    before it is used: at most one checkpoint interval is lost.

    Raises
    ------
    RunDirectoryError
        If no checkpoint can be read: the message names the files and the way out.
    """
    errors = []
    for path in rundir.checkpoint_files(run.output):
        try:
            simulation.loadCheckpoint(str(path))
        except mm.OpenMMException as error:
            errors.append(f"{path}: {str(error).strip()}")
            continue
        if errors:
            warnings.warn(
                f"{'; '.join(errors)}: unreadable; resumed from {path} "
                f"(step {simulation.currentStep}) instead.",
                RuntimeWarning,
                stacklevel=3,
            )
        break
    else:
        raise rundir.RunDirectoryError(
            f"no checkpoint of the run in {run.output} can be read ({'; '.join(errors)}). To start the run "
            f"again from step 0, remove {run.output} (or give another output directory)."
        )
    start_step = simulation.currentStep
    rundir.cut_back(run.output, start_step, run.options.intervals)
    return start_step


def _start(simulation: app.Simulation, run: _Run) -> int:
    """Set the start state (new velocities with ``velocity_seed``, kept in ``start_state.xml``); return 0."""
    context = simulation.context
    context.setState(run.prepared.state)
    seed = run.options.velocity_seed
    if seed is not None:
        kelvin = float(run.prepared.definition.equilibration["temperature_K"])
        context.setVelocitiesToTemperature(kelvin * unit.kelvin, seed)
        context.applyVelocityConstraints(run.options.constraint_tolerance)
        start = context.getState(getPositions=True, getVelocities=True)
        (run.output / rundir.START_STATE_FILE).write_text(mm.XmlSerializer.serialize(start), encoding="utf-8")
    context.setStepCount(0)
    context.setTime(0.0)
    return 0


def simulate(
    simulation: app.Simulation,
    run: _Run,
    start_step: int,
    extra_reporters: list | None,
    checkpoints: CheckpointReporter,
) -> float:
    """Attach the reporters, step to the end and checkpoint the last step; return the wall time (s)."""
    reporters = _reporters(run.output, run.spec, run.options.intervals, append=run.resume)
    if not run.resume:  # the start state's energy row: E_ref
        reporters[0].report(simulation, simulation.context.getState(getEnergy=True))
    simulation.reporters.extend([*reporters, checkpoints])
    simulation.reporters.extend(extra_reporters or [])
    wall = _advance(simulation, run, start_step, checkpoints, reporters)
    if checkpoints.last_step != simulation.currentStep:
        checkpoints.save(simulation)
    return wall


def _reporters(output: Path, spec: IntegratorSpec, intervals: dict, append: bool) -> list[Tracked]:
    """Return the run's reporters, energies first; the checkpoint reporter comes after them.

    A checkpoint at step k follows the rows and frames of step k. ``append``: the run
    resumes, and the files are appended to.
    """
    reporters: list[Tracked] = [
        TrackedStateDataReporter(
            str(output / rundir.ENERGIES_FILE),
            intervals["energy_interval"],
            step=True,
            time=True,
            potentialEnergy=True,
            kineticEnergy=True,
            totalEnergy=True,
            temperature=True,
            append=append,
        )
    ]
    if spec.kind == "energy":
        controller = str(output / rundir.CONTROLLER_FILE)
        interval = intervals["controller_interval"]
        reporters.append(TrackedControllerReporter(controller, interval, append=append))
    trajectory = output / rundir.TRAJECTORY_FILE
    reporters.append(
        TrackedDCDReporter(
            str(trajectory),
            intervals["trajectory_interval"],
            append=append and rundir.has_dcd_header(trajectory),  # no frame yet: no header to append to
            enforcePeriodicBox=False,
        )
    )
    if "velocity_interval" in intervals:
        frames = output / rundir.TRR_FILE
        reporters.append(
            TrackedTRRReporter(
                str(frames), intervals["velocity_interval"], append=append and frames.is_file()
            )
        )
    return reporters


def _advance(
    simulation: app.Simulation,
    run: _Run,
    start_step: int,
    checkpoints: CheckpointReporter,
    reporters: list[Tracked],
) -> float:
    """Step to ``steps`` in chunks of ``energy_interval`` (progress bar); return the wall time (s).

    After each chunk: a checkpoint if ``checkpoint_seconds`` have passed, or, after a
    Ctrl-C during the chunk, a checkpoint and :class:`RunInterrupted`.
    """
    steps, chunk = run.options.steps, run.options.energy_interval
    started = time.perf_counter()
    with _progress(run, start_step) as bar, deferred_interrupt() as ctrl_c_received:
        while simulation.currentStep < steps:
            n = min(chunk - simulation.currentStep % chunk, steps - simulation.currentStep)
            try:
                simulation.step(n)
            except KeyboardInterrupt:  # raised inside a step: its output may be incomplete
                step = simulation.currentStep
                complete = all(reporter.complete_at(step) for reporter in reporters)
                raise interrupted(simulation, run.output, steps, checkpoints, complete) from None
            except (ValueError, ArithmeticError, RuntimeError, mm.OpenMMException) as error:
                raise _failure(simulation, run, checkpoints, error) from error
            bar.update(n)
            if ctrl_c_received():
                raise interrupted(simulation, run.output, steps, checkpoints, True)
            checkpoints.save_if_due(simulation)
    return time.perf_counter() - started


def _progress(run: _Run, start_step: int) -> tqdm:
    """Return the run's progress bar (on stderr; off without ``progress``)."""
    return tqdm(
        total=run.options.steps,
        initial=start_step,
        desc=f"NVE {run.output.name} ({run.options.platform})",
        unit="step",
        disable=not run.options.progress,
        file=sys.stderr,
        mininterval=1.0,
    )


def _failure(
    simulation: app.Simulation, run: _Run, checkpoints: CheckpointReporter, error: Exception
) -> RunFailedError:
    """Return the error of a run that stopped: its step, its last finite energy and its checkpoint, if any."""
    output, name = run.output, type(simulation.integrator).__name__
    if checkpoints.last_step is not None and checkpoints.path.is_file():
        kept = f"the last checkpoint, {checkpoints.path}, is of step {checkpoints.last_step}"
    else:
        kept = "no checkpoint was written"
    last_row = rundir.last_energy_step(output / rundir.ENERGIES_FILE)
    finite = "" if last_row is None else f" (last energy row: step {last_row})"
    return RunFailedError(
        f"run in {output} stopped at step {simulation.currentStep} of {run.options.steps} with {name}"
        f"{finite}: {error} The output up to then is kept; {kept}."
    )


def write_summary(simulation: app.Simulation, run: _Run, wall_seconds: float, start_step: int) -> RunSummary:
    """Summarize the run, write ``summary.json`` and return the summary."""
    summary = summarize(
        run.output,
        run.prepared,
        simulation.integrator,
        simulation,
        run.spec,
        wall_seconds,
        simulation.currentStep - start_step,
    )
    rundir.replace_text(run.output / rundir.SUMMARY_FILE, json.dumps(summary.as_dict(), indent=2) + "\n")
    return summary
