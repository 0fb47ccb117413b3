"""NVE runs of a prepared system with a chosen integrator, written as they go and resumable.

:func:`run_nve` writes a run directory (see :mod:`openmm_alphaprk.rundir`) with
OpenMM's own reporters — ``StateDataReporter`` (energies CSV), ``DCDReporter``,
``CheckpointReporter`` — plus :class:`~openmm_alphaprk.reporters.AlphaControllerReporter`
for the energy mode, and a JSON summary at the end. Calling it again on the same
directory with the same settings resumes from the last checkpoint (or reports the
finished run); other settings are refused.
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
from tqdm import tqdm

from . import rundir
from ._units import to_dimensionless, to_float
from .analysis.energy import EnergyDrift, energy_drift
from .integrators import StepProgram
from .integrators.names import IntegratorSpec, check_compatible, make_integrator, parse_integrator
from .observables import (
    VERLET_IS_LEAPFROG,
    degrees_of_freedom,
    masses,
    momenta,
    positive_int,
    system_constraint_errors,
)
from .reporters import (
    AlphaControllerReporter,
    VelocityDCDReporter,
    read_controller_csv,
    summarize_controller,
)
from .systems import PreparedSystem, prepare_system

PRECISIONS = ("single", "mixed", "double")


class RunFailedError(RuntimeError):
    """Raised when a run stops on a NaN or a failed step; the output up to then is kept."""


@dataclass
class RunSummary:
    """What ``summary.json`` holds (energies kJ/mol, drift kJ/mol/ns per degree of freedom)."""

    system: str
    integrator: str
    n_atoms: int
    degrees_of_freedom: int
    timestep_fs: float
    steps: int
    simulated_ps: float
    platform: str
    e_ref: float
    drift_per_dof: float
    rms_residual: float
    max_abs_residual: float
    energy_samples: int
    max_relative_constraint_error: float
    max_constraint_velocity_error: float
    ns_per_day: float
    wall_seconds: float
    steps_this_call: int
    force_evaluations_per_step: float
    velocity_verlet: bool
    controller: dict = field(default_factory=dict)
    momentum_change: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)


def run_parameters(
    prepared: PreparedSystem,
    spec: IntegratorSpec,
    *,
    steps: int,
    timestep_ps: float,
    platform: str,
    precision: str | None,
    constraint_tolerance: float,
    energy_interval: int,
    trajectory_interval: int,
    checkpoint_interval: int,
    velocity_interval: int | None = None,
    velocity_seed: int | None = None,
) -> dict:
    """Return the parameters stored in ``run.json``; a directory with other values holds a different run.

    ``velocity_interval`` and ``velocity_seed`` are stored only when set, so run
    directories written before they existed stay valid.
    """
    optional = {"velocity_interval": velocity_interval, "velocity_seed": velocity_seed}
    return {
        "format": rundir.RUN_FORMAT,
        "system": prepared.name,
        "system_key": prepared.key,
        "integrator": spec.name,
        "timestep_ps": timestep_ps,
        "steps": steps,
        "platform": platform,
        "precision": precision,
        "constraint_tolerance": constraint_tolerance,
        "energy_interval": energy_interval,
        "trajectory_interval": trajectory_interval,
        "checkpoint_interval": checkpoint_interval,
    } | {key: value for key, value in optional.items() if value is not None}


def run_nve(
    system: str | PreparedSystem,
    integrator: str | IntegratorSpec,
    output: str | os.PathLike,
    *,
    steps: int = 1000,
    timestep: unit.Quantity | float = 0.002,
    platform: str = "CPU",
    precision: str | None = None,
    constraint_tolerance: float = 1e-8,
    energy_interval: int = 10,
    trajectory_interval: int = 100,
    checkpoint_interval: int = 500,
    velocity_interval: int | None = None,
    velocity_seed: int | None = None,
    cpu_threads: int | None = None,
    cache_dir: str | os.PathLike | None = None,
    progress: bool = True,
    extra_reporters: list | None = None,
) -> RunSummary:
    """Run NVE dynamics and write energies, trajectory, checkpoints and a summary to ``output``.

    Parameters
    ----------
    system
        A system name (``alphaprk systems``) or a :class:`~openmm_alphaprk.systems.PreparedSystem`.
    integrator
        ``rattle``, ``verlet``, ``energy`` or ``alpha=<number>``; see
        :mod:`openmm_alphaprk.integrators.names`.
    output
        Run directory; created if missing. If it holds this run (same settings except
        ``steps``), the run resumes from its last checkpoint, or is extended to ``steps``.
    steps
        Total number of steps of the run.
    timestep
        Step size: a Quantity, or a number in ps (default 0.002 ps = 2 fs).
    platform
        OpenMM platform name (``CPU``, ``Reference``, ``CUDA``, ``OpenCL``).
    precision
        ``single``, ``mixed`` or ``double`` for platforms with a Precision property
        (CUDA, OpenCL); None keeps the platform's default. Reference is double; CPU
        has no setting.
    constraint_tolerance
        Relative tolerance of SHAKE/SETTLE/CCMA and the velocity constraints.
    energy_interval, trajectory_interval, checkpoint_interval
        Steps between energy rows, DCD frames and checkpoints. Energies cost one extra
        force evaluation each on most platforms; the energy mode's controller CSV is
        written every step (free).
    velocity_interval
        Steps between frames of ``velocities.dcd`` (velocities in Å/ps stored as DCD
        coordinates, see :class:`~openmm_alphaprk.reporters.VelocityDCDReporter`); None
        (default) writes none.
    velocity_seed
        None (default): start from the prepared state's velocities. An integer: draw new
        Maxwell–Boltzmann velocities at the definition's temperature with this seed
        (constrained components removed), for independent runs from the same structure.
    cpu_threads
        Threads of the CPU platform (default: OpenMM's choice, all cores); not part of
        the run's identity.
    cache_dir
        Cache of equilibrated systems (default: see :func:`~openmm_alphaprk.systems.default_cache_dir`).
    progress
        Show progress bars on stderr.
    extra_reporters
        More OpenMM reporters, called after the run's own ones at each step.

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
    """
    spec = parse_integrator(integrator)
    timestep_ps = to_float(timestep, unit.picoseconds, "timestep", positive=True)
    steps = positive_int(steps, "steps")
    intervals = {
        name: positive_int(value, name)
        for name, value in (
            ("energy_interval", energy_interval),
            ("trajectory_interval", trajectory_interval),
            ("checkpoint_interval", checkpoint_interval),
        )
    }
    if velocity_interval is not None:
        intervals["velocity_interval"] = positive_int(velocity_interval, "velocity_interval")
    if velocity_seed is not None and (isinstance(velocity_seed, bool) or not isinstance(velocity_seed, int)):
        raise ValueError(f"velocity_seed must be an integer or None, got {velocity_seed!r}.")
    tolerance = to_dimensionless(constraint_tolerance, "constraint_tolerance", positive=True)
    plat, properties = _platform(platform, precision)
    if cpu_threads is not None:
        if platform != "CPU":
            raise ValueError(f"cpu_threads applies to the CPU platform only, not {platform}; leave it unset.")
        properties["Threads"] = str(positive_int(cpu_threads, "cpu_threads"))
    if not isinstance(system, PreparedSystem):
        from .systems import load_definition

        load_definition(system)  # unknown names fail here, before a build
    output = Path(output)
    prepared = system if isinstance(system, PreparedSystem) else None
    if prepared is not None:
        check_compatible(spec, prepared.system, repr(prepared.name), platform)
    else:
        prepared = prepare_system(
            system,
            cache_dir=cache_dir,
            progress=progress,
            check=lambda built: check_compatible(spec, built, repr(str(system)), platform),
        )
    parameters = run_parameters(
        prepared,
        spec,
        steps=steps,
        timestep_ps=timestep_ps,
        platform=platform,
        precision=precision,
        constraint_tolerance=tolerance,
        velocity_seed=velocity_seed,
        **intervals,
    )
    stored = rundir.check_run_directory(output, parameters)
    checkpoint = output / rundir.CHECKPOINT_FILE
    resume = stored is not None and checkpoint.is_file()
    if stored is not None and not resume:  # interrupted before its first checkpoint: start again
        for name in (
            rundir.ENERGIES_FILE,
            rundir.CONTROLLER_FILE,
            rundir.TRAJECTORY_FILE,
            rundir.VELOCITIES_FILE,
            rundir.START_STATE_FILE,
            rundir.SUMMARY_FILE,
        ):
            (output / name).unlink(missing_ok=True)
    output.mkdir(parents=True, exist_ok=True)
    rundir.write_parameters(output, parameters)
    if not resume:
        (output / rundir.SYSTEM_FILE).write_text(
            mm.XmlSerializer.serialize(prepared.system), encoding="utf-8"
        )
        with open(output / rundir.TOPOLOGY_FILE, "w") as handle:
            app.PDBFile.writeFile(prepared.topology, prepared.state.getPositions(), handle, keepIds=True)

    integ = make_integrator(spec, timestep_ps, tolerance)
    simulation = app.Simulation(prepared.topology, prepared.system, integ, plat, properties)
    if resume:
        simulation.loadCheckpoint(str(checkpoint))
        start_step = simulation.currentStep
        rundir.truncate_csv(output / rundir.ENERGIES_FILE, start_step)
        rundir.truncate_csv(output / rundir.CONTROLLER_FILE, start_step)
        rundir.truncate_dcd(output / rundir.TRAJECTORY_FILE, start_step // intervals["trajectory_interval"])
        if "velocity_interval" in intervals:
            rundir.truncate_dcd(output / rundir.VELOCITIES_FILE, start_step // intervals["velocity_interval"])
    else:
        simulation.context.setState(prepared.state)
        if velocity_seed is not None:
            kelvin = float(prepared.definition.equilibration["temperature_K"])
            simulation.context.setVelocitiesToTemperature(kelvin * unit.kelvin, velocity_seed)
            simulation.context.applyVelocityConstraints(tolerance)
            start = simulation.context.getState(getPositions=True, getVelocities=True)
            (output / rundir.START_STATE_FILE).write_text(mm.XmlSerializer.serialize(start), encoding="utf-8")
        simulation.context.setStepCount(0)
        simulation.context.setTime(0.0)
        start_step = 0
    if start_step >= steps and (output / rundir.SUMMARY_FILE).is_file():
        return RunSummary(**json.loads((output / rundir.SUMMARY_FILE).read_text(encoding="utf-8")))
    (output / rundir.SUMMARY_FILE).unlink(missing_ok=True)  # an extended run is not complete until it ends

    reporters = _reporters(output, spec, intervals, append=resume)
    if not resume:  # the start state's energy row: E_ref
        reporters[0].report(simulation, simulation.context.getState(getEnergy=True))
    simulation.reporters.extend(reporters)
    simulation.reporters.extend(extra_reporters or [])

    wall = _advance(simulation, integ, steps, start_step, intervals["energy_interval"], output, progress)
    if simulation.currentStep % intervals["checkpoint_interval"] != 0:
        simulation.saveCheckpoint(str(checkpoint))
    summary = summarize(output, prepared, integ, simulation, spec, wall, simulation.currentStep - start_step)
    (output / rundir.SUMMARY_FILE).write_text(json.dumps(summary.as_dict(), indent=2) + "\n")
    return summary


def _reporters(output: Path, spec: IntegratorSpec, intervals: dict, append: bool) -> list:
    """Energies first, checkpoint last: a checkpoint at step k follows the rows and frame of step k."""
    reporters: list = [
        app.StateDataReporter(
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
        reporters.append(AlphaControllerReporter(str(output / rundir.CONTROLLER_FILE), 1, append=append))
    reporters.append(
        app.DCDReporter(
            str(output / rundir.TRAJECTORY_FILE),
            intervals["trajectory_interval"],
            append=append,
            enforcePeriodicBox=False,
        )
    )
    if "velocity_interval" in intervals:
        reporters.append(
            VelocityDCDReporter(
                str(output / rundir.VELOCITIES_FILE), intervals["velocity_interval"], append=append
            )
        )
    reporters.append(
        app.CheckpointReporter(str(output / rundir.CHECKPOINT_FILE), intervals["checkpoint_interval"])
    )
    return reporters


def _advance(
    simulation: app.Simulation,
    integrator: mm.Integrator,
    steps: int,
    start_step: int,
    chunk: int,
    output: Path,
    progress: bool,
) -> float:
    """Step to ``steps`` in chunks (progress bar); return the wall time in seconds."""
    name = type(integrator).__name__
    started = time.perf_counter()
    with tqdm(
        total=steps,
        initial=start_step,
        desc=f"NVE {output.name}",
        unit="step",
        disable=not progress,
        file=sys.stderr,
        mininterval=1.0,
    ) as bar:
        while simulation.currentStep < steps:
            n = min(chunk - simulation.currentStep % chunk, steps - simulation.currentStep)
            try:
                simulation.step(n)
            except (ValueError, ArithmeticError, RuntimeError, mm.OpenMMException) as error:
                raise RunFailedError(
                    f"run in {output} stopped near step {simulation.currentStep} with {name}: {error} "
                    "The output up to then is kept; the last checkpoint is in "
                    f"{output / rundir.CHECKPOINT_FILE}."
                ) from error
            bar.update(n)
    return time.perf_counter() - started


def summarize(
    output: Path,
    prepared: PreparedSystem,
    integrator: mm.Integrator,
    simulation: app.Simulation,
    spec: IntegratorSpec,
    wall_seconds: float,
    steps_this_call: int,
) -> RunSummary:
    """Summary statistics from the files of the run and the final state of its context."""
    energies = rundir.read_energies(output / rundir.ENERGIES_FILE)
    dof = degrees_of_freedom(prepared.system)
    if len(energies) >= 2:
        drift = energy_drift(energies[:, 1], energies[:, 4], dof)
    else:  # fewer steps than energy_interval: only the start row
        drift = EnergyDrift(energies[0, 4], 1, 0.0, *(float("nan"),) * 4)
    timestep_ps = integrator.getStepSize().value_in_unit(unit.picoseconds)
    state = simulation.context.getState(getPositions=True, getVelocities=True)
    position_error, velocity_error = system_constraint_errors(
        prepared.system,
        state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
        state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
    )
    notes = []
    if not spec.velocity_verlet:
        notes.append(
            VERLET_IS_LEAPFROG + " Its velocities are half-step velocities, so the velocity-constraint "
            "error is not meaningful."
        )
    momentum_change = {}
    if not prepared.system.usesPeriodicBoundaryConditions():  # isolated: P and L are invariants
        momentum_change = _momentum_change(prepared, state, output)
    controller = {}
    if spec.kind == "energy":
        controller = summarize_controller(read_controller_csv(output / rundir.CONTROLLER_FILE)).as_dict()
    evaluations = integrator.force_evaluations_per_step if isinstance(integrator, StepProgram) else 1.0
    simulated_ns = steps_this_call * timestep_ps / 1000.0
    return RunSummary(
        system=prepared.name,
        integrator=spec.name,
        n_atoms=prepared.n_atoms,
        degrees_of_freedom=dof,
        timestep_fs=timestep_ps * 1000.0,
        steps=simulation.currentStep,
        simulated_ps=simulation.currentStep * timestep_ps,
        platform=simulation.context.getPlatform().getName(),
        e_ref=drift.e_ref,
        drift_per_dof=drift.drift_per_dof,
        rms_residual=drift.rms_residual,
        max_abs_residual=drift.max_abs_residual,
        energy_samples=drift.samples - 1,
        max_relative_constraint_error=position_error,
        max_constraint_velocity_error=velocity_error,
        ns_per_day=simulated_ns / (wall_seconds / 86400.0) if wall_seconds > 0 else float("nan"),
        wall_seconds=wall_seconds,
        steps_this_call=steps_this_call,
        force_evaluations_per_step=float(evaluations),
        velocity_verlet=spec.velocity_verlet,
        controller=controller,
        momentum_change=momentum_change,
        notes=notes,
    )


def _state_momenta(system: mm.System, state: mm.State) -> tuple[np.ndarray, np.ndarray]:
    """Linear and angular momentum of a State (see :func:`~openmm_alphaprk.observables.momenta`)."""
    return momenta(
        masses(system),
        state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
        state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
    )


def _momentum_change(prepared: PreparedSystem, final: mm.State, output: Path) -> dict:
    """Max component of the change of linear and angular momentum from the start state to ``final``.

    The start state is the prepared one, or the run's ``start_state.xml`` when its
    velocities were drawn anew (``velocity_seed``).
    """
    start_file = output / rundir.START_STATE_FILE
    start = (
        mm.XmlSerializer.deserialize(start_file.read_text(encoding="utf-8"))
        if start_file.is_file()
        else prepared.state
    )
    p0, l0 = _state_momenta(prepared.system, start)
    p1, l1 = _state_momenta(prepared.system, final)
    return {
        "linear_amu_nm_per_ps": float(np.abs(p1 - p0).max()),
        "angular_amu_nm2_per_ps": float(np.abs(l1 - l0).max()),
        "angular_start_amu_nm2_per_ps": float(np.abs(l0).max()),
    }


def _platform(name: str, precision: str | None) -> tuple[mm.Platform, dict]:
    names = [mm.Platform.getPlatform(i).getName() for i in range(mm.Platform.getNumPlatforms())]
    if name not in names:
        raise ValueError(f"unknown OpenMM platform {name!r}; available here: {', '.join(names)}.")
    platform = mm.Platform.getPlatformByName(name)
    if precision is None:
        return platform, {}
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {PRECISIONS}, got {precision!r}.")
    if "Precision" not in platform.getPropertyNames():
        raise ValueError(
            f"platform {name} has no precision setting (Reference computes in double, CPU in single with "
            "some double accumulation); leave precision unset, or use CUDA/OpenCL."
        )
    return platform, {"Precision": precision}
