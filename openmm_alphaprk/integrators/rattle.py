"""RATTLE (velocity Verlet with SHAKE/SETTLE and RATTLE) as an OpenMM ``CustomIntegrator``."""

from __future__ import annotations

import openmm.unit as unit

from .pieces import DEFAULT_CONSTRAINT_TOLERANCE, _StepProgram


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
    timestep
        Step size (Quantity, or number in picoseconds).
    constraint_tolerance
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    """

    _kind = 1

    def __init__(
        self,
        timestep: unit.Quantity | float,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
    ) -> None:
        super().__init__(timestep, constraint_tolerance)
        self._add_step(self._build_program, update_context_state=True)

    def _build_program(self) -> None:
        """One RATTLE step: the position solve with F(x0), the velocity update with F(x1)."""
        self._add_save_step_start()
        self._add_position_solve("0.5*f")
        self._add_velocity_update("0.5*f")
        self._add_end_step()
