"""RATTLE (velocity Verlet with SHAKE/SETTLE and RATTLE) as an OpenMM ``CustomIntegrator``."""

from __future__ import annotations

import openmm.unit as unit

from .compositions import Composition, requested_composition
from .pieces import DEFAULT_CONSTRAINT_TOLERANCE, _StepProgram
from .splittings import RATTLE


class RattleIntegrator(_StepProgram):
    """Velocity Verlet with SHAKE/SETTLE positions and RATTLE velocities.

    Its step program, as OpenMM runs it: :meth:`program_listing`, and docs/step_programs.md.

    The standard constrained integrator, written with the same pieces as
    :class:`~openmm_alphaprk.integrators.AlphaRattleIntegrator` to be the baseline of
    every comparison. Velocities are at the full step, so ``State.getKineticEnergy()``
    is the kinetic energy of the current velocities. One force evaluation per step.

    Each step starts with OpenMM's update-context-state step, as a
    ``VerletIntegrator`` step does: a Monte Carlo barostat, an ``AndersenThermostat``
    or a ``CMMotionRemover`` in the System acts as it does with ``VerletIntegrator``.
    With particles without mass (virtual sites) call :meth:`check_context` on CUDA,
    OpenCL or HIP; they are refused elsewhere.

    Parameters
    ----------
    timestep : openmm.unit.Quantity or float
        Step size (a time Quantity, or a number in picoseconds).
    constraint_tolerance : float, default 1e-8
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    order : {2, 4, 6}, optional
        Instead of one RATTLE step (2, the default), a symmetric composition of RATTLE
        steps (:mod:`~.compositions`): ``order=4`` (Suzuki's five stages), ``order=6``
        (McLachlan's nine); s force evaluations per step for s stages.
    composition : str or Composition, optional
        A composition by name (:data:`~.compositions.COMPOSITIONS`) or a
        :class:`~.compositions.Composition`, instead of ``order``.

    See Also
    --------
    RattleRescaleIntegrator : RATTLE with velocity rescaling, which holds the energy.
    AlphaRattleIntegrator : the α-RATTLE family; α = 0 is this integrator.

    Examples
    --------
    Two argon atoms held 0.3 nm apart, spinning:

    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import RattleIntegrator
    >>> integrator = RattleIntegrator(2 * unit.femtoseconds)
    >>> integrator
    RattleIntegrator(timestep=0.002 ps)
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(39.9)
    >>> _ = system.addConstraint(0, 1, 0.3)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0]])
    >>> context.setVelocities([[0, 0.5, 0], [0, -0.5, 0]])
    >>> integrator.step(100)
    >>> x = context.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(unit.nanometers)
    >>> round(float(((x[1] - x[0]) ** 2).sum() ** 0.5), 8)  # the constraint, kept
    0.3
    """

    def __init__(
        self,
        timestep: unit.Quantity | float,
        *,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
        order: int | None = None,
        composition: str | Composition | None = None,
    ) -> None:
        self._composition = requested_composition(order, composition)
        super().__init__(timestep, constraint_tolerance)
        if self._composition is not None:
            self._add_record(self._composition)
        self._add_step(self._build_program, update_context_state=True)

    def _build_program(self) -> None:
        """One RATTLE step, or the composition's RATTLE steps, in straight-line code."""
        self._add_save_step_start()
        self._add_substeps((self._composition or RATTLE).substeps())
        self._add_end_step()
