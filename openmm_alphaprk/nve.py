"""An NVE System: the forces that change the state between steps, and one call that prepares a System.

OpenMM applies a Monte Carlo barostat, an ``AndersenThermostat`` and a ``CMMotionRemover``
in an integrator's update-context-state step. ``RattleIntegrator`` and ``AlphaRattleIntegrator``
with a fixed α apply them like ``openmm.VerletIntegrator``; the energy mode does not.
:func:`state_changing_forces` lists them, :func:`warn_if_state_changing` issues a
:class:`StateChangingForceWarning` for them (from the energy mode's ``check_context``), and
:func:`prepare_for_nve` makes a System from ``createSystem``'s defaults smooth and removes them.
:func:`velocity_constraint_energy` measures how much kinetic energy a start's velocities
carry along the constraints (a Langevin integrator's do), which an integrator holding E_ref
would keep; :func:`warn_if_velocities_off_constraints` issues an
:class:`UnconstrainedVelocitiesWarning` for it (from ``step()`` after ``check_context``).
"""

from __future__ import annotations

import re
import warnings

import openmm as mm
import openmm.unit as unit

from .errors import (  # defined there; importable from here too
    LargeStepWarning,
    StateChangingForceWarning,
    UnconstrainedVelocitiesWarning,
)
from .observables import masses
from .platforms import massless_particles
from .smooth_forces import (
    DEFAULT_SWITCH_WIDTH,
    SMOOTH_EWALD_TOLERANCE,
    label_force,
    make_smooth,
    warn_listing,
)

__all__ = [
    "LargeStepWarning",
    "StateChangingForceWarning",
    "UnconstrainedVelocitiesWarning",
    "prepare_for_nve",
    "state_changing_forces",
    "step_size_problem",
    "velocity_constraint_energy",
    "warn_if_state_changing",
    "warn_if_velocities_off_constraints",
]

#: Largest step (fs) with hydrogens of natural mass on constrained X–H bonds; with repartitioned ones.
LARGEST_STEP_FS = 2.5
LARGEST_STEP_REPARTITIONED_FS = 4.5
#: A particle lighter than this (amu) is a hydrogen of natural mass; 3–4 amu after repartitioning.
LIGHT_HYDROGEN_AMU = 2.0

_BAROSTATS = tuple(
    getattr(mm, name)
    for name in (
        "MonteCarloBarostat",
        "MonteCarloAnisotropicBarostat",
        "MonteCarloMembraneBarostat",
        "MonteCarloFlexibleBarostat",
        "RPMDMonteCarloBarostat",
    )
    if hasattr(mm, name)
)
#: Why the energy mode leaves these forces alone (RATTLE and fixed α apply them).
_NOT_APPLIED = (
    "the energy mode does not apply it (OpenMM applies barostats, thermostats and the CMMotionRemover in "
    "an integrator's update-context-state step, which RattleIntegrator and fixed alpha have, like "
    "VerletIntegrator, and the energy mode has not: it holds the energy of its reference state, which "
    "these forces change by design)"
)


def step_size_problem(system: mm.System, timestep_ps: float) -> str | None:
    """Say why ``timestep_ps`` is too large for ``system``'s hydrogens, or return None.

    Hydrogens of natural mass outside rigid water (those in an H–H constraint) limit a
    RATTLE-type step with constrained X–H bonds to about 2.5 fs; repartitioned to 3–4
    amu (hydrogen mass repartitioning) to about 4 fs. Rigid water alone is fine at 4 fs.

    Parameters
    ----------
    system : openmm.System
        The System, its constraints set.
    timestep_ps : float
        The step in picoseconds.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk.nve import step_size_problem
    >>> ch = openmm.System()
    >>> for mass in (12.0, 1.008):
    ...     _ = ch.addParticle(mass)
    >>> _ = ch.addConstraint(0, 1, 0.109)  # a C-H bond constrained, as HBonds does
    >>> step_size_problem(ch, 0.002) is None
    True
    >>> print(step_size_problem(ch, 0.004))  # doctest: +ELLIPSIS
    a 4 fs step with 1 hydrogen(s) of 1.01 amu outside rigid water: ... use a step of 2 fs
    """
    masses = [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    rigid_water = set()
    for k in range(system.getNumConstraints()):
        i, j, _ = system.getConstraintParameters(k)
        if max(masses[i], masses[j]) < LIGHT_HYDROGEN_AMU:
            rigid_water |= {i, j}
    light = [i for i, m in enumerate(masses) if 0 < m < LIGHT_HYDROGEN_AMU and i not in rigid_water]
    step_fs = timestep_ps * 1000.0
    if light and step_fs > LARGEST_STEP_FS:
        return (
            f"a {step_fs:g} fs step with {len(light)} hydrogen(s) of {min(masses[i] for i in light):.3g} amu "
            f"outside rigid water: their X–H vibrations limit the step to about {LARGEST_STEP_FS:g} fs. For "
            "3–4 fs repartition the hydrogen masses (alphaprk --hydrogen-mass 3; "
            "createSystem(..., hydrogenMass=3*amu)), or use a step of 2 fs"
        )
    if step_fs > LARGEST_STEP_REPARTITIONED_FS:
        return (
            f"a {step_fs:g} fs step is above about {LARGEST_STEP_REPARTITIONED_FS:g} fs, the limit even with "
            "rigid water and repartitioned hydrogen masses; use 4 fs or less"
        )
    return None


def state_changing_forces(system: mm.System) -> list[str]:
    """List the forces of ``system`` that change its state between steps: the energy mode does not apply them.

    OpenMM applies a Monte Carlo barostat, an ``AndersenThermostat`` and a
    ``CMMotionRemover`` in an integrator's update-context-state step.
    ``RattleIntegrator`` and ``AlphaRattleIntegrator`` with a fixed α have that step
    at the start of each step, as ``openmm.VerletIntegrator`` does; the energy mode
    has not. It holds the total energy of its reference state E_ref, which a barostat
    or thermostat changes by design: were they applied, every change would have to
    be told apart from the common platform's reordering of atoms and E_ref taken
    again, and a change too small to tell (below max(tolerance, 1e-6 |E|)) would leave
    E_ref wrong. So the energy mode runs such a System NVE.

    Parameters
    ----------
    system : openmm.System
        The System to check (not changed).

    Returns
    -------
    list of str
        One message per force, naming it, what the energy mode does with it and the
        fix; empty if there is none.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk import state_changing_forces
    >>> system = openmm.System()
    >>> _ = system.addParticle(39.9)
    >>> _ = system.addForce(openmm.CMMotionRemover())
    >>> for message in state_changing_forces(system):
    ...     print(message)  # doctest: +ELLIPSIS
    CMMotionRemover (force 0): the energy mode does not apply it (...). ... or remove the force.
    """
    messages = []
    for index, force in enumerate(system.getForces()):
        label = label_force(index, force)
        if isinstance(force, mm.CMMotionRemover):
            messages.append(
                f"{label}: {_NOT_APPLIED}. It would remove nothing (the energy mode conserves "
                "centre-of-mass momentum, as any NVE method does), but OpenMM's temperature "
                "(StateDataReporter) counts 3 degrees of freedom fewer for it. Fix: "
                "createSystem(..., removeCMMotion=False), or remove the force."
            )
        elif isinstance(force, _BAROSTATS):
            messages.append(
                f"{label}: {_NOT_APPLIED}. The box volume stays fixed and the run is NVE, not the "
                "constant-pressure run the System asks for. Fix: remove the barostat and equilibrate "
                "the density first (with it, RattleIntegrator or a fixed alpha apply it)."
            )
        elif isinstance(force, mm.AndersenThermostat):
            messages.append(
                f"{label}: {_NOT_APPLIED}. No temperature is imposed and the run is NVE. Fix: remove "
                "it and equilibrate first (with it, RattleIntegrator or a fixed alpha apply it)."
            )
    return messages


#: Custom forces whose energy may use a particle's absolute coordinates (``x1``, ``y1``, ``z1`` …).
_COORDINATE_FORCES = (mm.CustomCompoundBondForce, mm.CustomCentroidBondForce)
_ABSOLUTE_COORDINATE = re.compile(r"(?<![\w.])[xyz]\d+\b")


def momentum_breaking_forces(system: mm.System) -> list[str]:
    """List what in ``system`` makes its forces not sum to zero: linear momentum is not conserved.

    A ``CustomExternalForce`` (positional restraints, an external field, a tethered
    particle), a ``CustomCompoundBondForce`` or ``CustomCentroidBondForce`` whose energy uses
    absolute coordinates (``x1``, ``y2`` …), and particles of zero mass that are not virtual
    sites (fixed in space, so the forces on them are not balanced by their motion). Read
    from the System, not from a run; PME's reciprocal-space force, whose small net value is
    round-off of the method, is not listed.

    Parameters
    ----------
    system : openmm.System
        The System to check (not changed).

    Returns
    -------
    list of str
        One line per force or group of particles; empty where the forces conserve
        momentum.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk.nve import momentum_breaking_forces
    >>> system = openmm.System()
    >>> _ = system.addParticle(1.0)
    >>> spring = openmm.CustomExternalForce("0.5*k*(x^2 + y^2 + z^2)")
    >>> _ = spring.addGlobalParameter("k", 100.0)
    >>> _ = spring.addParticle(0, [])
    >>> _ = system.addForce(spring)
    >>> momentum_breaking_forces(system)
    ['CustomExternalForce (force 0): an external potential on 1 particle(s)']
    """
    found = []
    for index, force in enumerate(system.getForces()):
        label = label_force(index, force)
        if isinstance(force, mm.CustomExternalForce) and force.getNumParticles():
            found.append(f"{label}: an external potential on {force.getNumParticles()} particle(s)")
        elif isinstance(force, _COORDINATE_FORCES) and _ABSOLUTE_COORDINATE.search(force.getEnergyFunction()):
            found.append(f"{label}: its energy uses absolute coordinates")
    fixed = [i for i in massless_particles(system) if not system.isVirtualSite(i)]
    if fixed:
        found.append(f"{len(fixed)} particle(s) of zero mass, fixed in space")
    return found


def prepare_for_nve(
    system: mm.System,
    switch_width: unit.Quantity | float | None = DEFAULT_SWITCH_WIDTH * unit.nanometers,
    ewald_error_tolerance: float | None = SMOOTH_EWALD_TOLERANCE,
) -> list[str]:
    """Make a System from ``ForceField.createSystem`` ready for energy-conserving NVE, in place.

    Calls :func:`make_smooth` (Lennard-Jones switched over the last ``switch_width``,
    Ewald/PME/LJPME error tolerance at most ``ewald_error_tolerance``), then removes
    every ``CMMotionRemover``, Monte Carlo barostat and ``AndersenThermostat``: the
    energy mode does not apply them, an NVE run needs none of them, and a
    ``CMMotionRemover`` makes OpenMM's temperature count 3 degrees of freedom fewer.
    With the default arguments, :func:`smoothness_problems` then finds nothing.

    Parameters
    ----------
    system : openmm.System
        The System to change (before creating a Context from it: an existing Context
        does not see the change).
    switch_width : openmm.unit.Quantity or float or None, default 0.1 nm
        As for :func:`make_smooth`.
    ewald_error_tolerance : float or None, default 1e-5
        As for :func:`make_smooth`.

    Returns
    -------
    list of str
        One line per change, make_smooth's first; force indices are those of the
        System as it was passed in.

    Raises
    ------
    ValueError
        As :func:`make_smooth`, before anything is changed.

    Notes
    -----
    Ewald tolerance 1e-5 is the loosest measured that keeps the energy mode's gain: on
    a 3 nm TIP3P box (CPU platform, 2 fs; two runs) α-RATTLE-4's energy mode held H to
    1/90–1/100 of RATTLE's RMS error at 1e-5, 1/12–1/30 at 5e-5, 1/3–1/8 at 1e-4 and was
    worse than RATTLE at 5e-4, while 1e-5 cost 1.3× a 5e-4 step (1.55× on solvated villin).
    Where only fixed-α integrators are compared, 1e-4 gives RATTLE the same error.

    Examples
    --------
    A PME System with OpenMM's defaults and a ``CMMotionRemover``, as ``createSystem``
    makes it:

    >>> import openmm
    >>> from openmm_alphaprk import prepare_for_nve, smoothness_problems
    >>> system = openmm.System()
    >>> system.setDefaultPeriodicBoxVectors(openmm.Vec3(3, 0, 0), openmm.Vec3(0, 3, 0), openmm.Vec3(0, 0, 3))
    >>> nonbonded = openmm.NonbondedForce()  # OpenMM's defaults: no switch, Ewald tolerance 5e-4
    >>> nonbonded.setNonbondedMethod(openmm.NonbondedForce.PME)
    >>> for charge in (0.5, -0.5):
    ...     _ = system.addParticle(39.9)
    ...     _ = nonbonded.addParticle(charge, 0.34, 1.0)
    >>> _ = system.addForce(nonbonded)
    >>> _ = system.addForce(openmm.CMMotionRemover())
    >>> for change in prepare_for_nve(system):
    ...     print(change)  # doctest: +ELLIPSIS
    NonbondedForce (force 0): no switching function → switching from 0.9 nm (cutoff 1 nm)
    NonbondedForce (force 0): Ewald error tolerance 0.0005 → 1e-05
    CMMotionRemover (force 1): removed (an NVE run conserves the centre-of-mass momentum without it; ...)
    >>> smoothness_problems(system), system.getNumForces()
    ([], 1)
    """
    changes = make_smooth(system, switch_width, ewald_error_tolerance)
    return changes + _remove_unapplied_forces(system)


def _remove_unapplied_forces(system: mm.System) -> list[str]:
    """Remove the CMMotionRemovers, barostats and Andersen thermostats; one line each, in index order."""
    reasons = (
        (mm.CMMotionRemover, "an NVE run conserves the centre-of-mass momentum without it"),
        (_BAROSTATS, "NVE keeps the box volume fixed"),
        (mm.AndersenThermostat, "NVE imposes no temperature"),
    )
    removed = []
    for index in reversed(range(system.getNumForces())):
        force = system.getForce(index)
        why = next((text for kinds, text in reasons if isinstance(force, kinds)), None)
        if why is not None:
            removed.append(f"{label_force(index, force)}: removed ({why}; the energy mode does not apply it)")
            system.removeForce(index)
    return removed[::-1]


def warn_if_state_changing(
    system: mm.System, stacklevel: int | None = None, who: str = "the energy-preserving mode"
) -> bool:
    """Issue one :class:`StateChangingForceWarning` listing every :func:`state_changing_forces` entry, if any.

    Parameters
    ----------
    system
        The System an energy-mode integrator is about to run.
    stacklevel, who
        As for :func:`warn_if_not_smooth`.

    Returns
    -------
    bool
        True if a warning was issued.

    """
    forces = state_changing_forces(system)
    heading = (
        f"{who} runs NVE; {len(forces)} force(s) of this System change the state "
        "between steps and are not applied"
    )
    return warn_listing(forces, heading, "openmm_alphaprk.nve", StateChangingForceWarning, stacklevel)


#: Share of the kinetic energy along the constraints above which a start is warned about.
UNCONSTRAINED_SHARE = 1e-5


def velocity_constraint_energy(context: mm.Context, tolerance: float = 1e-10) -> tuple[float, float]:
    """Return the kinetic energy of the velocities along the constraints, and the whole (kJ/mol).

    K(v) − K(P v), P the projection onto the velocity constraints
    (``context.applyVelocityConstraints``). The Context's velocities are put back as they
    were afterwards.

    Parameters
    ----------
    context
        A Context whose velocities are set.
    tolerance
        The projection's constraint tolerance.

    Returns
    -------
    tuple of float
        (energy along the constraints, kinetic energy), kJ/mol.
    """
    system = context.getSystem()
    m = masses(system)[:, None]
    nm_per_ps = unit.nanometer / unit.picosecond
    given = context.getState(getVelocities=True).getVelocities(asNumpy=True)
    v = given.value_in_unit(nm_per_ps)
    kinetic = 0.5 * float((m * v * v).sum())
    if system.getNumConstraints() == 0 or kinetic == 0.0:
        return 0.0, kinetic
    context.applyVelocityConstraints(tolerance)
    projected = context.getState(getVelocities=True).getVelocities(asNumpy=True).value_in_unit(nm_per_ps)
    context.setVelocities(given)
    return kinetic - 0.5 * float((m * projected * projected).sum()), kinetic


def warn_if_velocities_off_constraints(
    context: mm.Context, who: str = "the energy-preserving mode", stacklevel: int = 2
) -> bool:
    """Issue an :class:`UnconstrainedVelocitiesWarning` if the velocities move along the constraints.

    Warned above :data:`UNCONSTRAINED_SHARE` of the kinetic energy
    (:func:`velocity_constraint_energy`); a Langevin integrator's velocities are there.

    Parameters
    ----------
    context
        The Context whose state E_ref is about to be taken from.
    who
        How the warning names the integrator.
    stacklevel
        As for :func:`warnings.warn`.

    Returns
    -------
    bool
        True if a warning was issued.
    """
    along, kinetic = velocity_constraint_energy(context)
    if along <= UNCONSTRAINED_SHARE * kinetic:
        return False
    warnings.warn(
        f"{who} takes E_ref from velocities that move along the constraints: {along:.3g} kJ/mol of the "
        f"kinetic energy ({along / kinetic:.2g} of it; a Langevin integrator's velocities do this). RATTLE's "
        "first step removes it and the integrator would hold it in E_ref, putting it back into the motion. "
        "Call context.applyVelocityConstraints(1e-10) before the first step.",
        UnconstrainedVelocitiesWarning,
        stacklevel=stacklevel,
    )
    return True
