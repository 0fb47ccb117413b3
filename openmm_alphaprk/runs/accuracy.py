"""Trajectory accuracy: how far a run from a start stays from a converged small-step reference.

The reference is RATTLE at h/:data:`REFERENCE_DIVISOR` with constraint tolerance
:data:`REFERENCE_TOLERANCE`, from the same start on the same platform. A run records its
positions and velocities after each *horizon* (a number of steps of h); its error there is
the RMS over atoms and the maximum of the per-atom distance to the reference's
(:func:`~openmm_alphaprk.observables.trajectory_error`). Used by ``alphaprk bench
accuracy`` (:mod:`openmm_alphaprk.benchmarks.accuracy`) and by ``alphaprk compare``, whose
table gives each row's position error at a short horizon.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import openmm as mm
import openmm.unit as unit

from .._units import InputError
from ..integrators import check_context
from ..observables import masses, momenta, total_energy, trajectory_error
from ..systems import PreparedSystem
from .integrator_names import SubStepped, at_divisor

#: The reference: RATTLE at h/REFERENCE_DIVISOR with constraint tolerance REFERENCE_TOLERANCE.
REFERENCE_DIVISOR = 64
REFERENCE_TOLERANCE = 1e-10


@dataclass
class Horizon:
    """Errors against the reference after ``steps`` steps of h (positions nm, velocities nm/ps)."""

    steps: int
    time_fs: float
    position_rms: float
    position_max: float
    velocity_rms: float
    velocity_max: float


@dataclass
class Trajectory:
    """What a run from the start recorded: the state at the horizons, H − E_ref, momenta, cost.

    ``residuals``: H − E_ref (E_ref the start's total energy) after every step of h, or at
    the horizons only; ``momentum_change`` (System without a periodic box): the largest
    change of a component of P and of L over the run, and their start norms.
    """

    positions: dict[int, np.ndarray]
    velocities: dict[int, np.ndarray]
    residuals: np.ndarray
    force_evaluations_per_step: float
    momentum_change: dict[str, float]
    blew_up_at_step: int | None
    integrator: mm.Integrator
    context: mm.Context | None


def start_context(
    prepared: PreparedSystem,
    integrator: mm.Integrator,
    platform: str,
    properties: dict[str, str] | None = None,
) -> mm.Context:
    """Return a Context of ``prepared``'s System at its start state (positions, velocities, box), checked."""
    plat = mm.Platform.getPlatformByName(platform)
    context = mm.Context(prepared.system, integrator, plat, properties or {})
    context.setState(prepared.state)
    check_context(integrator, context)
    return context


def reference(timestep: float, divisor: int = REFERENCE_DIVISOR) -> SubStepped:
    """Return RATTLE at h/``divisor`` with constraint tolerance :data:`REFERENCE_TOLERANCE`."""
    return at_divisor("rattle", timestep, divisor, REFERENCE_TOLERANCE)


def run_trajectory(
    prepared: PreparedSystem,
    row: SubStepped,
    horizons: Sequence[int],
    *,
    platform: str = "CPU",
    properties: dict[str, str] | None = None,
    read_energy: bool = True,
) -> Trajectory:
    """Run ``row`` from the start for max(``horizons``) steps of h, recording the state at each horizon.

    A step of h is ``row.substeps`` integrator steps. With ``read_energy`` the total
    energy is read after every step of h, else only at the horizons (a reference's
    sub-steps are not read). A step that raises, or a non-finite energy, ends the run
    (``blew_up_at_step``).
    """
    integrator = row.make()
    context = start_context(prepared, integrator, platform, properties)
    e_ref = total_energy(context)
    isolated = not prepared.system.usesPeriodicBoundaryConditions()
    weights = masses(prepared.system)
    p0, l0 = momenta(weights, prepared.positions, prepared.velocities)
    wanted, last = set(horizons), max(horizons)
    positions, velocities, residuals = {}, {}, []
    largest = {"linear": 0.0, "angular": 0.0}
    evaluations_before = getattr(integrator, "force_evaluations", None)
    blew_up = None
    for step in range(1, last + 1):
        try:
            integrator.step(row.substeps)
        except Exception:  # a failed step is the blow-up the caller reports
            blew_up = step
            break
        if read_energy or step in wanted:
            residuals.append(total_energy(context) - e_ref)
            if not math.isfinite(residuals[-1]):
                blew_up = step
                break
        if step in wanted or isolated:
            state = context.getState(getPositions=True, getVelocities=True)
            x = state.getPositions(asNumpy=True).value_in_unit(unit.nanometers)
            v = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
            if step in wanted:
                positions[step], velocities[step] = x, v
            if isolated:
                p, angular = momenta(weights, x, v)
                largest["linear"] = max(largest["linear"], float(np.abs(p - p0).max()))
                largest["angular"] = max(largest["angular"], float(np.abs(angular - l0).max()))
    steps_done = (blew_up - 1) if blew_up else last
    if evaluations_before is not None and steps_done:
        per_step = (integrator.force_evaluations - evaluations_before) / steps_done
    else:
        per_step = float(row.substeps)  # openmm.VerletIntegrator: one per step
    change = {}
    if isolated:
        change = {
            "linear_amu_nm_per_ps": largest["linear"],
            "angular_amu_nm2_per_ps": largest["angular"],
            "linear_start": float(np.linalg.norm(p0)),
            "angular_start": float(np.linalg.norm(l0)),
        }
    return Trajectory(
        positions, velocities, np.array(residuals), float(per_step), change, blew_up, integrator, context
    )


def horizon_errors(
    trajectory: Trajectory, reference_run: Trajectory, box: np.ndarray | None, timestep_fs: float
) -> list[Horizon]:
    """Return the errors of ``trajectory`` against ``reference_run`` at every horizon both reached."""
    errors = []
    for steps in sorted(trajectory.positions):
        if steps not in reference_run.positions:
            continue
        position = trajectory_error(trajectory.positions[steps], reference_run.positions[steps], box)
        velocity = trajectory_error(trajectory.velocities[steps], reference_run.velocities[steps])
        errors.append(Horizon(steps, steps * timestep_fs, *position, *velocity))
    return errors


def periodic_box(prepared: PreparedSystem) -> np.ndarray | None:
    """Return the edge lengths (nm) of a rectangular periodic box, None without one.

    Raises
    ------
    ValueError
        For a triclinic box, where the minimum image is not a per-axis rounding.
    """
    if not prepared.system.usesPeriodicBoundaryConditions():
        return None
    vectors = np.array(prepared.state.getPeriodicBoxVectors(asNumpy=True).value_in_unit(unit.nanometers))
    if np.abs(vectors - np.diag(np.diag(vectors))).max() > 0:
        raise InputError(
            f"system {prepared.name} has a triclinic box; trajectory errors are measured in rectangular "
            "boxes only."
        )
    return np.diag(vectors).copy()


def short_horizon_errors(
    prepared: PreparedSystem,
    rows: dict[str, SubStepped],
    timestep: float,
    steps: int,
    *,
    platform: str = "CPU",
    properties: dict[str, str] | None = None,
) -> dict[str, Horizon]:
    """Return each row's error against the reference after ``steps`` steps of h (``timestep``, ps)."""
    reference_run = run_trajectory(
        prepared, reference(timestep), [steps], platform=platform, properties=properties, read_energy=False
    )
    box = periodic_box(prepared)
    errors = {}
    for name, row in rows.items():
        run = run_trajectory(
            prepared, row, [steps], platform=platform, properties=properties, read_energy=False
        )
        found = horizon_errors(run, reference_run, box, timestep * 1000.0)
        if found:
            errors[name] = found[0]
    return errors


def with_rigid_motion(
    prepared: PreparedSystem, translation: Sequence[float], rotation: Sequence[float]
) -> PreparedSystem:
    """Return ``prepared`` with a rigid translation (nm/ps) and rotation (1/ps) added to its start.

    The rotation is about the centre of mass. Rigid motion keeps every distance, so the
    velocities still satisfy the constraints; it makes the linear and angular momentum of
    an isolated system large enough that their conservation can be measured.
    """
    x, v = prepared.positions, prepared.velocities
    weights = masses(prepared.system)
    centre = (weights[:, None] * x).sum(axis=0) / weights.sum()
    moving = v + np.asarray(translation) + np.cross(np.asarray(rotation), x - centre)
    moving[weights == 0] = 0.0
    reference_platform = mm.Platform.getPlatformByName("Reference")
    context = mm.Context(prepared.system, mm.VerletIntegrator(0.001), reference_platform)
    context.setState(prepared.state)
    context.setVelocities(moving)
    state = context.getState(getPositions=True, getVelocities=True, getEnergy=True)
    return PreparedSystem(
        prepared.name,
        prepared.definition,
        prepared.key,
        prepared.topology,
        prepared.system,
        state,
        prepared.path,
        prepared.source,
    )
