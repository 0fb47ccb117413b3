"""The base of every step program of this package, its RATTLE pieces, and the rules all pieces obey.

A step is velocity Verlet with SHAKE/SETTLE positions and RATTLE velocities, or the
α-RATTLE step whose implicit midpoint force is found by fixed-point iteration. Each
piece is an ``_add_*`` method that appends computations to the ``CustomIntegrator``:
the RATTLE pieces are here, on :class:`StepProgram`; the midpoint and triple-jump
pieces on :class:`~.midpoint.MidpointProgram`, the α* controller's on
:class:`~.controller.EnergyControllerProgram`. :meth:`StepProgram.program_listing`
prints the result.

**The frame of every program** (:meth:`StepProgram._add_step`): an update-context-state
step (RATTLE and fixed α; not the energy mode), then the system check, then the step
itself inside ``if (refused < 0.5)``. The system check (:mod:`~.binding`) runs at the
first step of each ``step()`` call: it counts the degrees of freedom the program moves,
and refuses the step (takes none of it) when the System has particles without mass
that the step cannot be right for. OpenMM gives an integrator no access to its
Context, so the program learns the System this way, and ``check_context`` is the
explicit call for what needs the platform.

**One program, two semantics** (see :mod:`openmm_alphaprk.platforms`). The pieces
are ordered so that Reference/CPU and the common platform (CUDA, OpenCL, HIP) take
the same step:

1. *Every position assignment whose force is read comes after every
   ``addConstrainPositions()`` in program text.* On the common platform an ``x``
   assignment with a constraint step anywhere after it in the text is stored as a
   displacement that forces do not see until that constraint step runs. The
   position solves are followed by their constraint step (forces are read only
   after it); the midpoint x_m = (x0 + x1)/2 — the one force taken at unconstrained
   positions — is set in the last block of the loop, after all constraint steps.
2. *Every position solve projects along G(x0).* Reference/CPU project along the
   positions of the previous constraint step, the common platform along the
   positions stored when the constraint step runs. The midpoint block therefore
   constrains x0 (a no-op on x0 that makes it the Reference/CPU reference) before
   setting x_m, and stores x = x0 again after taking the force (the common
   platform's reference). The update-context-state step comes before x0 is saved;
   on Reference/CPU the first solve of a step then projects along the positions
   before it, which are x0 up to round-off whenever a Monte Carlo barostat moved
   the molecules: it scales their centres and keeps each molecule rigid (OpenMM's
   default, ``scaleMoleculesAsRigid``).
3. *No position is written after the step's last force evaluation*, or the next
   step would evaluate the force again. A failed step falls back to its start
   inside the last position solve (``select(midpoint_failed, …)``), not after it.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import ClassVar

import openmm as mm
import openmm.unit as unit

from .._units import to_dimensionless, to_float
from .binding import REFUSED, SystemCheckedProgram

#: Name of the global variable that identifies the integrator class in serialized form.
KIND_VARIABLE = "alphaprk_kind"
#: Names of global variables read by name from outside the program.
STEPS_TAKEN = "steps_taken"
FORCE_EVALUATIONS = "force_evaluations"
STEP_FORCE_EVALUATIONS = "step_force_evaluations"
HOST_SYNCS = "host_syncs"

_STEP_TYPES = {
    mm.CustomIntegrator.ComputeGlobal: "global",
    mm.CustomIntegrator.ComputePerDof: "per-dof",
    mm.CustomIntegrator.ComputeSum: "sum",
    mm.CustomIntegrator.ConstrainPositions: "constrain positions",
    mm.CustomIntegrator.ConstrainVelocities: "constrain velocities",
    mm.CustomIntegrator.UpdateContextState: "update context state",
    mm.CustomIntegrator.IfBlockStart: "if",
    mm.CustomIntegrator.WhileBlockStart: "while",
    mm.CustomIntegrator.BlockEnd: "end",
}


class StepProgram(SystemCheckedProgram):
    """Common state, the frame of every program, RATTLE pieces and reporting of this package's integrators.

    Subclasses set ``_kind`` (stored in the global variable :data:`KIND_VARIABLE` so
    that ``restore_integrator`` can recognise a deserialized integrator) and build
    their step program from the ``_add_*`` pieces.
    """

    _kind: ClassVar[int] = 0

    def __init__(self, timestep: unit.Quantity | float, constraint_tolerance: float) -> None:
        step_size = to_float(timestep, unit.picoseconds, "timestep", positive=True)
        _warn_if_plain_step_is_large(timestep, step_size)
        tolerance = to_dimensionless(constraint_tolerance, "constraint_tolerance", positive=True)
        super().__init__(step_size)
        self.setConstraintTolerance(tolerance)
        self.addGlobalVariable(KIND_VARIABLE, self._kind)
        self.addGlobalVariable(FORCE_EVALUATIONS, 0)
        self.addGlobalVariable(STEPS_TAKEN, 0)
        self.addGlobalVariable(STEP_FORCE_EVALUATIONS, 0)
        self.addGlobalVariable(HOST_SYNCS, 0)
        self._add_system_check_variables()
        for name in ("x0", "v0"):
            self.addPerDofVariable(name, 0)

    # ------------------------------------------------------------ the frame
    def _add_step(self, body: Callable[[], None], update_context_state: bool) -> None:
        """Add the whole program: the update-context-state step, the system check, ``body`` unless refused.

        ``update_context_state`` adds OpenMM's update-context-state step first, where
        barostats, thermostats and the CMMotionRemover act, as at the start of a
        ``VerletIntegrator`` step.
        """
        if update_context_state:
            self.addUpdateContextState()
        self._add_system_check()
        self.beginIfBlock(f"{REFUSED} < 0.5")
        body()
        self.endBlock()

    # ------------------------------------------------------------ RATTLE pieces
    def _add_save_step_start(self, **copies: str) -> None:
        """Save the starting state (x0, v0) and ``copies``.

        One per-DOF kernel on the common platform (consecutive per-DOF steps merge).
        """
        self.addComputeGlobal("step_force_evaluations", "0")
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        for variable, expression in copies.items():
            self.addComputePerDof(variable, expression)

    def _add_position_solve(self, force_term: str, h: str = "dt", fallback: str | None = None) -> None:
        """X ← x0 + h v0 + h² M⁻¹(force_term), SHAKE/SETTLE along G(x0); or x ← ``fallback``."""
        expression = f"x0 + {h}*v0 + {h}*{h}*({force_term})/m"
        if fallback is not None:
            expression = f"select(midpoint_failed, {fallback}, {expression})"
        self.addComputePerDof("x", expression)
        self.addConstrainPositions()

    def _add_velocity_update(self, force_term: str, h: str = "dt", fallback: str | None = None) -> None:
        """V ← (x1 − x0)/h + h M⁻¹(force_term), RATTLE projection at x1; or v ← ``fallback``.

        ``force_term`` uses ``f``, the force at x1: the step's (or sub-step's) last
        force evaluation, reused at the start of the next one.
        """
        expression = f"(x - x0)/{h} + {h}*({force_term})/m"
        if fallback is not None:
            expression = f"select(midpoint_failed, {fallback}, {expression})"
        self.addComputePerDof("v", expression)
        self._add_count_force_evaluation()
        self.addConstrainVelocities()

    def _add_sum(self, variable: str, expression: str) -> None:
        """Sum over degrees of freedom into a global, counted in ``host_syncs``.

        On the common platform every sum downloads its value: a full synchronisation
        of the device with the host, the cost the program keeps count of.
        """
        self.addComputeSum(variable, expression)
        self.addComputeGlobal("host_syncs", "host_syncs + 1")

    def _add_count_force_evaluation(self) -> None:
        self.addComputeGlobal("step_force_evaluations", "step_force_evaluations + 1")

    def _add_end_step(self) -> None:
        """Add the step's force evaluations to the totals and count the step."""
        self.addComputeGlobal("force_evaluations", "force_evaluations + step_force_evaluations")
        self.addComputeGlobal("steps_taken", "steps_taken + 1")

    # -------------------------------------------------------------- reporting
    def program_listing(self) -> str:
        """Return the step program, one computation per line, indented by block.

        Numbered as OpenMM numbers the computations; useful when checking the block
        budget or the text order that the common platform's semantics depend on.
        """
        lines, depth = [], 0
        for index in range(self.getNumComputations()):
            kind, variable, expression = self.getComputationStep(index)
            name = _STEP_TYPES.get(kind, str(kind))
            if kind == mm.CustomIntegrator.BlockEnd:
                depth -= 1
            text = {
                "global": f"{variable} = {expression}",
                "per-dof": f"{variable} = {expression}  (per DOF)",
                "sum": f"{variable} = sum({expression})",
                "if": f"if ({expression}):",
                "while": f"while ({expression}):",
            }.get(name, name)
            lines.append(f"{index:3d}  {'    ' * depth}{text}")
            if kind in (mm.CustomIntegrator.IfBlockStart, mm.CustomIntegrator.WhileBlockStart):
                depth += 1
        return "\n".join(lines)

    @property
    def timestep(self) -> unit.Quantity:
        """The step size, as a Quantity in picoseconds."""
        return self.getStepSize()

    @property
    def constraint_tolerance(self) -> float:
        """Relative tolerance of SHAKE/CCMA/SETTLE position and velocity constraints."""
        return self.getConstraintTolerance()

    @property
    def steps_taken(self) -> int:
        """Number of steps taken with this integrator."""
        return int(self.getGlobalVariableByName(STEPS_TAKEN))

    @property
    def force_evaluations(self) -> int:
        """Force evaluations requested by the step program since it was created.

        The force at the start of a step is the one computed at the end of the
        previous step and is not counted; OpenMM recomputes it (uncounted) only after
        the user or a barostat changes the state, or on CUDA/OpenCL/HIP after it
        reorders the atoms (every 250 steps).
        """
        return int(self.getGlobalVariableByName(FORCE_EVALUATIONS))

    @property
    def host_syncs_per_step(self) -> float:
        """Mean sums over degrees of freedom per step (NaN before the first step).

        Each is a device-to-host synchronisation on CUDA, OpenCL and HIP. Not
        counted: reading ``energy`` in the program (on those platforms the energy comes
        with the force evaluation that needs it), and the one sum of the system check
        at the first step of each ``step()`` call.
        """
        steps = self.steps_taken
        return self.getGlobalVariableByName(HOST_SYNCS) / steps if steps else float("nan")

    @property
    def last_step_force_evaluations(self) -> int:
        """Force evaluations of the last step."""
        return int(self.getGlobalVariableByName(STEP_FORCE_EVALUATIONS))

    @property
    def force_evaluations_per_step(self) -> float:
        """Mean force evaluations per step (NaN before the first step)."""
        steps = self.steps_taken
        return self.force_evaluations / steps if steps else float("nan")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(timestep={self.timestep})"


#: A plain-number step (read in ps, as OpenMM does) above this many ps is probably meant in fs.
LARGE_PLAIN_STEP_PS = 0.01


class TimestepUnitWarning(UserWarning):
    """A plain-number timestep above 10 fs: OpenMM reads plain numbers in picoseconds."""


def _warn_if_plain_step_is_large(timestep: object, step_ps: float) -> None:
    """Warn when a plain number gives a step above :data:`LARGE_PLAIN_STEP_PS` (e.g. ``2`` = 2 ps)."""
    if unit.is_quantity(timestep) or step_ps <= LARGE_PLAIN_STEP_PS:
        return
    warnings.warn(
        TimestepUnitWarning(
            f"timestep {timestep!r} is a plain number, which OpenMM reads in picoseconds: a step of "
            f"{step_ps * 1000:g} fs, far above the 1-4 fs of constrained MD (the run will blow up). "
            "For 2 fs pass 2 * unit.femtoseconds or 0.002."
        ),
        stacklevel=4,  # this function, StepProgram.__init__, the integrator's __init__, the caller
    )
