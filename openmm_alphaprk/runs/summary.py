"""The summary of a run (``summary.json``): energy conservation, constraints, cost, invariants."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit

from ..integrators import (
    AlphaRattleEnergyIntegrator,
    RattleRescaleIntegrator,
    force_evaluations_per_step,
)
from ..observables import (
    VERLET_IS_LEAPFROG,
    EnergyDrift,
    degrees_of_freedom,
    energy_drift,
    masses,
    momenta,
    system_constraint_errors,
)
from ..systems import PreparedSystem
from . import rundir
from .integrator_names import IntegratorSpec
from .reporters import read_controller_csv, summarize_controller


@dataclass
class RunSummary:
    """What ``summary.json`` holds (energies kJ/mol, drift kJ/mol/ns per degree of freedom).

    ``e_ref`` is the total energy of the start state (the first row of
    ``energies.csv``); ``drift_per_dof`` ± ``drift_per_dof_standard_error``,
    ``drift_resolved``, ``rms_residual`` and ``max_abs_residual`` are
    :func:`~openmm_alphaprk.observables.energy_drift` of the ``energy_samples`` rows
    after it. ``controller`` (energy mode) is a
    :class:`~openmm_alphaprk.runs.ControllerSummary` over every step of the run.

    Attributes
    ----------
    system : str
        Name of the system.
    integrator : str
        Name of the integrator (:mod:`~openmm_alphaprk.runs.integrator_names`).
    n_atoms : int
        Particles of the System.
    degrees_of_freedom : int
        3N (particles with mass) minus the constraints, minus 3 with a ``CMMotionRemover``.
    timestep_fs : float
        Step size (fs).
    steps : int
        Steps of the run, resumed calls included.
    simulated_ps : float
        Simulated time (ps).
    platform : str
        The OpenMM platform that ran it.
    e_ref : float
        Total energy of the start state (kJ/mol).
    drift_per_dof, drift_per_dof_standard_error : float
        Drift of H − E_ref and its standard error (kJ/mol/ns per degree of freedom).
    drift_resolved : bool
        Whether the drift is at least two standard errors.
    rms_residual, max_abs_residual : float
        RMS and max |H − E_ref| over the energy rows after the start (kJ/mol).
    energy_samples : int
        Energy rows after the start.
    max_relative_constraint_error : float
        Largest |r − d|/d over the constraints at the end.
    max_constraint_velocity_error : float
        Largest |relative velocity along a constrained pair| at the end (nm/ps).
    ns_per_day : float
        Speed of this call.
    wall_seconds : float
        Wall time of this call (s).
    steps_this_call : int
        Steps taken by this call (fewer than ``steps`` when it resumed).
    force_evaluations_per_step : float
        Mean force evaluations per step.
    velocity_verlet : bool
        Whether the velocities are full-step ones (False for ``verlet``, OpenMM's leapfrog).
    controller : dict
        The energy mode's :class:`~openmm_alphaprk.runs.ControllerSummary` as a dict;
        empty for the other integrators.
    rescaling : dict
        RATTLE + rescaling only (empty for the others): what the velocity scaling did over
        every step of the run, :meth:`~openmm_alphaprk.RattleRescaleIntegrator.rescale_totals`
        (``rescalings``, ``mean_scale_change`` and ``rms_scale_change`` of s − 1,
        ``removed_energy`` kJ/mol, ``added_energy_per_ns`` kJ/mol/ns, ...).
    momentum_change : dict
        Without a periodic box, the largest change of a component of linear and
        angular momentum over the run; empty with one.
    notes : list of str
        Caveats (leapfrog velocities) and what a rescaling removed.

    Examples
    --------
    Returned by :func:`~openmm_alphaprk.runs.run_nve` and written as ``summary.json``:

    >>> import json, os, tempfile
    >>> from openmm_alphaprk.runs import RunSummary, run_nve
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     summary = run_nve("water-cluster", "rattle", run, steps=20, energy_interval=5,
    ...                       platform="Reference", progress=False)
    ...     with open(os.path.join(run, "summary.json")) as stored:
    ...         same = RunSummary(**json.load(stored)) == summary
    >>> same
    True
    >>> summary.n_atoms, summary.degrees_of_freedom, summary.simulated_ps, summary.energy_samples
    (222, 444, 0.04, 4)
    >>> summary.max_relative_constraint_error < 1e-7, sorted(summary.momentum_change)
    (True, ['angular_amu_nm2_per_ps', 'angular_start_amu_nm2_per_ps', 'linear_amu_nm_per_ps'])
    """

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
    drift_per_dof_standard_error: float
    drift_resolved: bool
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
    rescaling: dict = field(default_factory=dict)
    momentum_change: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)


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
    dof = degrees_of_freedom(prepared.system)
    drift = _energy_fit(output, dof)
    timestep_ps = integrator.getStepSize().value_in_unit(unit.picoseconds)
    state = simulation.context.getState(getPositions=True, getVelocities=True)
    position_error, velocity_error = system_constraint_errors(
        prepared.system,
        state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
        state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
    )
    momentum_change = {}
    if not prepared.system.usesPeriodicBoundaryConditions():  # isolated: P and L are invariants
        momentum_change = _momentum_change(prepared, state, output)
    evaluations = force_evaluations_per_step(integrator)
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
        drift_per_dof_standard_error=drift.drift_per_dof_standard_error,
        drift_resolved=drift.drift_resolved,
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
        controller=_controller(output, integrator),
        rescaling=_rescaling(integrator),
        momentum_change=momentum_change,
        notes=_notes(spec, integrator),
    )


def _energy_fit(output: Path, dof: int) -> EnergyDrift:
    """Return the drift fit of the run's ``energies.csv`` (NaN statistics with only the start row)."""
    energies = rundir.read_energies(output / rundir.ENERGIES_FILE)
    if len(energies) >= 2:
        return energy_drift(energies[:, 1], energies[:, 4], dof)
    # fewer steps than energy_interval: only the start row
    nan = float("nan")
    return EnergyDrift(energies[0, 4], 1, 0.0, nan, nan, nan, nan, False, nan, nan, nan)


def _controller(output: Path, integrator: mm.Integrator) -> dict:
    """Return the energy mode's controller statistics; empty for other integrators.

    Counts and fractions (and RMS and max |H − E_ref| where the integrator accumulates
    them) are the integrator's totals over every step; α* percentiles come from the
    rows of ``controller.csv``.
    """
    if not isinstance(integrator, AlphaRattleEnergyIntegrator):
        return {}
    path = output / rundir.CONTROLLER_FILE
    rows = read_controller_csv(path) if path.is_file() and path.stat().st_size else np.empty((0, 0))
    if rows.size == 0:  # a run shorter than the controller interval: no row yet
        return {}
    totals = integrator.controller_totals()
    return summarize_controller(rows, totals=totals).as_dict()


def _rescaling(integrator: mm.Integrator) -> dict:
    """Return what a rescaling integrator's scalings did (empty for the others, and before a step)."""
    if isinstance(integrator, RattleRescaleIntegrator) and integrator.steps_taken:
        return integrator.rescale_totals()
    return {}


def read_summary(path: Path) -> RunSummary | None:
    """Return the summary stored in ``path``, None if it is missing or lacks fields of :class:`RunSummary`.

    A summary written by an earlier version of the package lacks newer fields (the
    drift's standard error); the driver then summarizes the finished run again.
    """
    if not path.is_file():
        return None
    stored = json.loads(path.read_text(encoding="utf-8"))
    names = {f.name for f in fields(RunSummary)}
    if not names <= stored.keys() or (stored["controller"] and "residuals_over" not in stored["controller"]):
        return None
    return RunSummary(**{key: value for key, value in stored.items() if key in names})


def _notes(spec: IntegratorSpec, integrator: mm.Integrator) -> list[str]:
    """Return the caveats of the integrator (leapfrog velocities) and what a rescaling removed."""
    if isinstance(integrator, RattleRescaleIntegrator) and integrator.steps_taken:
        totals = integrator.rescale_totals()
        scaled = "its RATTLE step" if integrator.composition is None else "its composition of RATTLE steps"
        return [
            f"{spec.name}: the velocity scaling removed the energy error of {scaled}: RMS "
            f"{totals['rms_rattle_residual']:.3g} kJ/mol per step (max |s - 1| "
            f"{totals['max_abs_scale_change']:.2g}, E_ref taken {totals['reference_resets']} time(s))."
        ]
    if spec.velocity_verlet:
        return []
    return [
        VERLET_IS_LEAPFROG + " Its velocities are half-step velocities, so the velocity-constraint "
        "error is not meaningful."
    ]


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
