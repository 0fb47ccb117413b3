"""The pieces every step program of this package is built from, and the rules they obey.

A step is velocity Verlet with SHAKE/SETTLE positions and RATTLE velocities (RATTLE), or
the α-RATTLE step whose implicit midpoint force is found by fixed-point iteration::

    x1 = x0 + h v0 + h² M⁻¹[(½−α) F0 + α F(x_m)] − M⁻¹ G(x0)ᵀ λ,   g(x1) = 0,   x_m = (x0+x1)/2
    v1 = (x1 − x0)/h + h M⁻¹[α F(x_m) + (½−α) F(x1)] − M⁻¹ G(x1)ᵀ μ,  G(x1) v1 = 0

Each piece is an ``_add_*`` method of :class:`_StepProgram` that appends computations
to the ``CustomIntegrator``; the integrators (:mod:`~.rattle`, :mod:`~.alpha_rattle`)
build their whole step programs from them, and :meth:`_StepProgram.program_listing`
prints the result. The energy mode's controller pieces are on the class that has the
energy mode (:class:`~.energy_mode.AlphaRattleEnergyIntegrator`).

**The frame of every program** (:meth:`_StepProgram._add_step`): an update-context-state
step (RATTLE and fixed α; not the energy mode), then the system check, then the step
itself inside ``if (refused < 0.5)``. The system check runs at the first step of each
``step()`` call: it counts the degrees of freedom the program moves (``ndof``: a sum
over degrees of freedom skips particles without mass on every platform), and refuses
the step (takes none of it) when the System has particles without mass that the step
cannot be right for, or more particles than the integrator's per-DOF variables.

**What a program knows of its Context.** OpenMM gives an integrator no handle on its
Context, and a ``CustomIntegrator`` may be bound again (``Context.reinitialize()``
binds it afresh to the Context's System, edited or not). So nothing about the System is
kept on the Python object: the system check learns it inside the program, and
:meth:`_StepProgram.check_context` is the explicit call for what needs the platform:
whether virtual sites are placed at every constraint step (CUDA, OpenCL, HIP), and the
precision behind the energy mode's default tolerance. Its findings last while that
Context exists (a weak reference), and are taken again when the System's particles,
forces or constraints change.

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

The midpoint iteration: the position solve and the midpoint block
(:meth:`_StepProgram._add_midpoint_force`) alternate in a ``while`` loop, in the order
that rules 1–3 require. α-RATTLE-4 takes the sub-steps Ψ^0_{γ1 h} ∘ Ψ^α_{γ2 h} ∘
Ψ^0_{γ1 h} and, in general, a symmetric composition of such sub-steps
(:mod:`~.compositions`): the stages before the first one with α once, the rest in one
loop (:meth:`_StepProgram._add_composition_loop`).
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import openmm as mm
import openmm.unit as unit

from .. import platforms, start_blowup
from .._units import InputError, to_dimensionless, to_float
from ..errors import (  # defined there; importable from here too
    IncompatibleSystemError,
    MidpointConvergenceError,
    SystemSizeError,
    TimestepUnitWarning,
)
from ..smooth_forces import outside_stacklevel
from .compositions import COMPOSITIONS, Composition
from .splittings import RATTLE
from .stage_sets import Library, StageSet, SubStep
from .variables import (
    ALPHA,
    CHECK_SYSTEM,
    FORCE_EVALUATIONS,
    HOST_SYNCS,
    KIND_VARIABLE,
    MIDPOINT_CHANGE,
    MIDPOINT_ITERATIONS,
    N_PARTICLES,
    NDOF,
    REFUSED,
    STEP_FORCE_EVALUATIONS,
    STEPS_TAKEN,
    program_kind,
)

DEFAULT_CONSTRAINT_TOLERANCE = 1e-8
_NO_CHECK, _CHECK_REFUSING_MASSLESS, _CHECK_ALLOWING_MASSLESS = 0, 1, 2

#: The largest midpoint change (nm, RMS per DOF) a step is accepted with once the
#: iteration stopped: 1000 × the tolerance, and never below 1e-8 nm nor above 1e-3 nm.
ACCEPTED_MIDPOINT_CHANGE = "accepted = min(max(1000*midpoint_tolerance, 1e-8), 1e-3)"


def first_forces(alpha: str) -> str:
    """Force term of the position solve: (½−α) F(x0) + α F(x_m)."""
    return f"(0.5-{alpha})*fstart + {alpha}*fmid"


def last_forces(alpha: str) -> str:
    """Force term of the velocity update: α F(x_m) + (½−α) F(x1)."""
    return f"{alpha}*fmid + (0.5-{alpha})*f"


def _coefficient(value: float | str) -> str:
    """Write a kick coefficient into an expression: a number as Python writes it, or ``(expression)``."""
    return repr(value) if isinstance(value, float) else f"({value})"


def _substep_h(composition: Composition, stage: int) -> str:
    """Expression of stage ``stage``'s step size, c_stage·h."""
    return f"({composition.coefficients[stage - 1]!r}*dt)"


def _stage_select(composition: Composition, first: int, what: str) -> str:
    """Expression of the step size (``what="h"``) or α (``"alpha"``) of stage ``phase`` ≥ ``first``.

    Written for the stages that can follow: one term where they all agree (the
    triple jump's last stage), else a sum of ``delta(phase - k)`` terms.
    """
    stages = range(first, composition.stages + 1)
    if what == "h":
        values = {k: composition.coefficients[k - 1] for k in stages}
        if len(set(values.values())) == 1:
            return f"({next(iter(values.values()))!r}*dt)"
        return "(" + " + ".join(f"{c!r}*delta(phase - {k})" for k, c in values.items()) + ")*dt"
    on = [k for k in stages if k in composition.alpha_stages]
    if not on:
        return "0"
    if len(on) == len(stages):
        return "alpha"
    return "alpha*(" + " + ".join(f"delta(phase - {k})" for k in on) + ")"


@dataclass(frozen=True)
class _CheckedContext:
    """What :meth:`_StepProgram.check_context` learnt from a Context, and a weak reference to it."""

    context: Callable[[], mm.Context | None]
    platform: str
    fingerprint: tuple[int, int, int]
    massless: tuple[int, ...]


def _fingerprint(system: mm.System) -> tuple[int, int, int]:
    """Particles, forces and constraints: what changes when a System is edited before ``reinitialize()``."""
    return system.getNumParticles(), system.getNumForces(), system.getNumConstraints()


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


class _StepProgram(mm.CustomIntegrator):
    """The base of this package's integrators: their common state, pieces, stepping and listing.

    Not an integrator itself. Every program keeps :func:`~.variables.program_kind` of its
    class in the global :data:`~.variables.KIND_VARIABLE`, by which ``restore_integrator``
    recognises a deserialized integrator. Subclasses build their whole step program in
    ``__init__`` from the ``_add_*`` pieces, inside :meth:`_add_step`.
    """

    def __init__(self, timestep: unit.Quantity | float, constraint_tolerance: float) -> None:
        step_size = to_float(timestep, unit.picoseconds, "timestep", positive=True)
        _warn_if_plain_step_is_large(timestep, step_size)
        tolerance = to_dimensionless(constraint_tolerance, "constraint_tolerance", positive=True)
        super().__init__(step_size)
        self.setConstraintTolerance(tolerance)
        self.addGlobalVariable(KIND_VARIABLE, program_kind(type(self)))
        self.addGlobalVariable(FORCE_EVALUATIONS, 0)
        self.addGlobalVariable(STEPS_TAKEN, 0)
        self.addGlobalVariable(STEP_FORCE_EVALUATIONS, 0)
        self.addGlobalVariable(HOST_SYNCS, 0)
        self._add_system_check_variables()
        for name in ("x0", "v0"):
            self.addPerDofVariable(name, 0)

    # ------------------------------------------------------------ the frame
    def _add_step(self, body: Callable[[], None], update_context_state: bool, halted: str = "0") -> None:
        """Add the whole program: the update-context-state step, the system check, ``body`` unless refused.

        ``update_context_state`` adds OpenMM's update-context-state step first, where
        barostats, thermostats and the CMMotionRemover act, as at the start of a
        ``VerletIntegrator`` step. ``halted``: a global that, once a step set it, skips
        the body of the steps after it too.
        """
        if update_context_state:
            self.addUpdateContextState()
        self._add_system_check()
        self.beginIfBlock(f"{REFUSED} < 0.5" if halted == "0" else f"{REFUSED} + {halted} < 0.5")
        body()
        self.endBlock()

    def _add_system_check_variables(self) -> None:
        """Declare the globals of the system check (before any computation is added)."""
        self.addGlobalVariable(NDOF, 0)
        self.addGlobalVariable(N_PARTICLES, 0)
        # a copy deserialized as a plain CustomIntegrator still counts its DOFs at its first step
        self.addGlobalVariable(CHECK_SYSTEM, _CHECK_REFUSING_MASSLESS)
        self.addGlobalVariable(REFUSED, 0)

    def _add_system_check(self) -> None:
        """When ``check_system`` is set: count the moved DOFs into ``ndof``; refuse the step if it must.

        A sum over degrees of freedom skips particles without mass on every platform,
        so ``sum(1)`` is 3 × the particles with mass. The step is refused when some
        particles have no mass and ``check_system`` is 1, and when the System has more
        particles than ``n_particles`` (OpenMM keeps a ``CustomIntegrator``'s per-DOF
        variables at the size of the first System it was bound to). A System larger by
        as many particles as it has without mass looks like the first one. With
        ``n_particles`` unset (a deserialized plain ``CustomIntegrator``) nothing is
        refused. The block reads no force and moves nothing, so it adds no path to
        OpenMM's analysis of the program; its sum is not counted in ``host_syncs``.
        """
        self.beginIfBlock(f"{CHECK_SYSTEM} > 0.5")
        self.addComputeSum(NDOF, "1")
        self._add_system_measurements()
        self.addComputeGlobal(
            REFUSED,
            f"step({N_PARTICLES} - 0.5)*max(step(massless - 0.5)*step(1.5 - {CHECK_SYSTEM}),"
            f" step(-massless - 0.5)); massless = 3*{N_PARTICLES} - {NDOF}",
        )
        self.addComputeGlobal(CHECK_SYSTEM, str(_NO_CHECK))
        self.endBlock()

    def _add_system_measurements(self) -> None:
        """Measure what a program needs of the System, at the system check (inside its block)."""

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

    def _add_midpoint_variables(
        self, alpha: float, tolerance: float, max_iterations: int, order: int, composition: Composition | None
    ) -> None:
        """Declare α, the midpoint iteration's state and settings, and (a composition) the sub-step state.

        A composition's coefficients and α's stages are kept as globals
        ``stage_coefficient_<i>`` and ``alpha_on_stage_<i>`` (read back by
        :attr:`composition`; the program itself
        has them written into its expressions).
        """
        self.addGlobalVariable(ALPHA, alpha)
        self.addGlobalVariable("midpoint_tolerance", tolerance)
        self.addGlobalVariable("max_midpoint_iterations", max_iterations)
        for name in (
            MIDPOINT_ITERATIONS,
            MIDPOINT_CHANGE,
            "previous_midpoint_change",
            "need_midpoint",
            "solving",
            "midpoint_failed",
            "midpoint_failures",
            "sum_change2",
        ):
            self.addGlobalVariable(name, 0)
        self.addGlobalVariable("order", order)
        for name in ("fstart", "fmid", "x1"):
            self.addPerDofVariable(name, 0)
        if composition is not None:
            for name in ("phase", "hsub", "alpha_sub", "substep_done"):
                self.addGlobalVariable(name, 0)
            if len(composition.alpha_stages) > 1:
                self.addGlobalVariable("next_stage_midpoint", 0)
            for name in ("xstep", "vstep"):
                self.addPerDofVariable(name, 0)
            self._add_record(composition)

    def _add_record(self, stages: StageSet) -> None:
        """Keep a composition's or splitting's coefficients as globals (read back by :meth:`_recorded`)."""
        for name, value in stages.recorded().items():
            self.addGlobalVariable(name, value)

    def _recorded(self, kind: type[StageSet], library: Library) -> StageSet | None:
        """Read back the ``kind`` of set the program's globals record; None without one."""
        names = self._global_names()
        return kind.from_record({name: self.getGlobalVariableByName(name) for name in names}, library)

    def _global_names(self) -> frozenset[str]:
        """Return the names of the program's global variables, read again only when there are more.

        A program declares its globals as it is built, so the names are read again only
        when there are more of them (during construction); after that a call costs one count.
        """
        names = vars(self).get("_names", frozenset())
        if len(names) != self.getNumGlobalVariables():
            names = frozenset(self.getGlobalVariableName(i) for i in range(self.getNumGlobalVariables()))
            self._names = names
        return names

    # ------------------------------------------------------- α's midpoint: what the user is told
    def _midpoint_failures(self) -> float:
        """Failed midpoint iterations since the program was created (0 for a program without α)."""
        if "midpoint_failures" not in self._global_names():
            return 0.0
        return self.getGlobalVariableByName("midpoint_failures")

    def _raise_if_midpoint_failed(self, failures_before: float) -> None:
        """Raise :class:`MidpointConvergenceError` if a step failed its midpoint iteration since then."""
        if self._midpoint_failures() <= failures_before:
            return
        get = self.getGlobalVariableByName
        energy_mode = "energy mode, " if getattr(self, "energy_mode", False) else ""
        raise MidpointConvergenceError(
            f"α-RATTLE midpoint iteration did not converge (last RMS change "
            f"{get(MIDPOINT_CHANGE):.3g} nm after {int(get(MIDPOINT_ITERATIONS))} iterations; tolerance "
            f"{get('midpoint_tolerance') * unit.nanometers}, alpha={energy_mode}{get(ALPHA)}, "
            f"timestep={self.timestep}). The context was left at the start "
            "of the failed step. Reduce the timestep or |alpha|, raise midpoint_tolerance if it "
            "is below the platform's precision, or check the system for overlapping atoms."
        )

    def _midpoint_force_refusal(self, count: int, method: str) -> str:
        """Why ``count`` particles without mass cannot be integrated by a step with α's midpoint force."""
        return (
            f"{type(self).__name__} with {method} cannot integrate "
            f"this system: {count} particle(s) have zero mass (virtual sites). "
            "α ≠ 0 takes a force at the unconstrained midpoint of the step, where no OpenMM "
            "platform places virtual sites. With virtual sites use alpha=0 (RATTLE, or order=4 for "
            "a fourth-order composition of RATTLE steps) on CUDA, OpenCL or HIP after "
            "integrator.check_context(context), or "
            "openmm.VerletIntegrator."
        )

    @property
    def composition(self) -> Composition | None:
        """The composition of steps the program is made of, α's stages marked (None: one step).

        Read back from the program's globals (:meth:`_add_record`) for an integrator
        restored from XML or taken from a Context.
        """
        if "_composition" in vars(self):
            return self._composition
        return self._recorded(Composition, COMPOSITIONS)

    # ------------------------------------------------------ α-RATTLE's midpoint
    def _add_midpoint_setup(self, need_midpoint: str) -> None:
        """Reset the midpoint iteration; ``need_midpoint``: whether the first solve is a predictor."""
        for name, expression in (
            ("midpoint_iterations", "0"),
            ("midpoint_change", "0"),
            ("previous_midpoint_change", "1e30"),
            ("midpoint_failed", "0"),
            ("need_midpoint", need_midpoint),
        ):
            self.addComputeGlobal(name, expression)

    def _add_midpoint_force(self, h: str, alpha: str) -> None:
        """Take F(x_m), x_m = (x0 + x1)/2 with x1 the last solve; decide whether to solve again.

        One force evaluation.

        The body of the last block of a loop (rule 1 of :mod:`~.pieces`). Leaves x = x0,
        ``fmid`` = F(x_m), ``midpoint_change`` = RMS change per degree of freedom that
        the new force makes to the next position solve (h²|α ΔF|/m before
        projection), and ``need_midpoint`` = 0 once that change is below
        ``midpoint_tolerance``, stops decreasing (the round-off floor, or divergence)
        or the iteration cap is reached; ``midpoint_failed`` = 1 if it then exceeds
        max(1000 × tolerance, 1e-8 nm) or is not finite.
        """
        self._add_midpoint_reference()
        self._add_midpoint_evaluation(h, alpha)
        self.addComputeGlobal(
            "need_midpoint",
            "step(max_midpoint_iterations - midpoint_iterations - 0.5)"
            "*step(midpoint_change - midpoint_tolerance)"
            "*(1 - step(midpoint_change - previous_midpoint_change))",
        )
        self.addComputeGlobal(
            "midpoint_failed",
            "max(midpoint_failed, (1 - need_midpoint)*(1 - step(accepted - midpoint_change)));"
            + ACCEPTED_MIDPOINT_CHANGE,
        )
        self.addComputeGlobal("previous_midpoint_change", "midpoint_change")

    def _add_midpoint_reference(self) -> None:
        """Keep the last solve as x1 and make x0 the reference of the constraint steps (rule 2)."""
        self.addComputePerDof("x1", "x")
        self.addComputePerDof("x", "x0")
        self.addConstrainPositions()

    def _add_midpoint_evaluation(self, h: str, alpha: str) -> None:
        """Take F(x_m) into ``fmid``, leave x = x0, and measure the change it makes (``midpoint_change``)."""
        self.addComputePerDof("x", "0.5*(x0 + x1)")
        self._add_sum("sum_change2", f"({h}*{h}*{alpha}*(f - fmid)/m)^2")
        self.addComputePerDof("fmid", "f")
        self.addComputePerDof("x", "x0")
        self._add_count_force_evaluation()
        self.addComputeGlobal("midpoint_iterations", "midpoint_iterations + 1")
        self.addComputeGlobal("midpoint_change", "sqrt(sum_change2/max(ndof, 1))")

    def _add_midpoint_end_step(self) -> None:
        """Count a failed midpoint iteration, then end the step as every program does."""
        self.addComputeGlobal("midpoint_failures", "midpoint_failures + midpoint_failed")
        self._add_end_step()

    # ------------------------------------------------ a composition's sub-steps
    def _add_substeps(self, substeps: tuple[SubStep, ...], first_force: str = "f") -> None:
        """Take the constrained sub-steps (c, p, q) from x0, v0, F(x0) in ``first_force``: the one emitter.

        Every explicit base step is emitted here (:mod:`~.stage_sets`): RATTLE (one
        sub-step (1, ½, ½), written with ``dt``), a composition's stages at α = 0, a
        splitting's drifts with their kicks. Straight-line code, one position solve and one
        velocity update per sub-step (one force evaluation each, counted): each solve is
        followed by its constraint step, so the force read after it sees the solved
        positions on every platform (rule 1), and projects along the positions of the
        previous constraint step, the sub-step's start (rule 2). Leaves x, v at the end;
        x0, v0 at the last sub-step's start. A kick coefficient may be an expression of the
        program's globals (the energy mode's splitting base: of ``alpha``).
        """
        for i, (c, before, after) in enumerate(substeps, start=1):
            h = "dt" if c == 1.0 else f"({c!r}*dt)"
            if i > 1:
                self.addComputePerDof("x0", "x")
                self.addComputePerDof("v0", "v")
            self._add_position_solve(f"{_coefficient(before)}*{first_force if i == 1 else 'f'}", h)
            self._add_velocity_update(f"{_coefficient(after)}*f", h)

    def _add_leading_substeps(self, composition: Composition) -> None:
        """Take the RATTLE stages before the first α stage from the step's start (F(x0) in ``fstart``)."""
        self._add_substeps(composition.substeps()[: composition.first_alpha_stage - 1], first_force="fstart")

    def _add_alpha_step(self, composition: Composition | None, first_force: str = "f") -> None:
        """Take the α-RATTLE step (or a composition with α) from x0, v0, F(x0) in ``first_force``.

        The implicit base step: the explicit sub-steps of :meth:`_add_substeps` with the
        midpoint loop added. One step: at α = 0 the RATTLE block, the same computations as
        :class:`~.rattle.RattleIntegrator`'s (its kernels read no global, so on CUDA, OpenCL
        and HIP it needs no upload of globals); the α ≠ 0 block follows it in program text,
        a loop of solves and midpoint forces, so that its midpoint assignment comes after
        every constraint step. ``fmid`` must hold F(x0) and ``fstart`` too (``first_force``
        is one of them or ``f``). A composition: its stages before the first α stage, then
        one loop over the rest (:meth:`_add_composition_loop`), ``xstep``, ``vstep`` holding
        the step's start. A failed midpoint iteration returns the step's start.
        """
        if composition is not None:
            self._add_leading_substeps(composition)
            self._add_alpha_substeps_start(composition, "1 - delta(alpha)", fmid="f")
            self._add_composition_loop(composition)
            return
        self._add_midpoint_setup("1")
        self.beginIfBlock("alpha = 0")
        self._add_substeps(RATTLE.substeps(), first_force)
        self.endBlock()
        self.beginIfBlock("alpha != 0")
        self.addComputeGlobal("solving", "1")
        self.beginWhileBlock("solving > 0.5")
        self.addComputeGlobal("solving", "0")
        self._add_position_solve(first_forces("alpha"), "dt", fallback="x0")
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_midpoint_force("dt", "alpha")
        self.addComputeGlobal("solving", "1")
        self.endBlock()
        self.endBlock()
        self._add_velocity_update(last_forces("alpha"), "dt", fallback="v0")
        self.endBlock()

    def _add_alpha_substeps_start(self, composition: Composition, need_midpoint: str, **copies: str) -> None:
        """Start the first stage with α here; the loop then takes it and every stage after it."""
        first = composition.first_alpha_stage
        self.addComputeGlobal("phase", str(first))
        self.addComputeGlobal("hsub", _substep_h(composition, first))
        self.addComputeGlobal("alpha_sub", "alpha")
        self._add_midpoint_setup(need_midpoint)
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self.addComputePerDof("fstart", "f")
        for variable, expression in copies.items():
            self.addComputePerDof(variable, expression)

    def _add_substep_solve(self, fallback: str) -> None:
        """Solve the positions of the current sub-step (a predictor or a midpoint re-solve)."""
        self._add_position_solve(first_forces("alpha_sub"), "hsub", fallback)
        self.addComputeGlobal("substep_done", "1 - need_midpoint")

    def _add_substep_end(self, composition: Composition, fallback: str, **copies: str) -> None:
        """Body of ``if substep_done``: the velocity update, then start the next sub-step.

        A next stage with α starts its midpoint iteration from F at its start, after
        its predictor solve (``next_stage_midpoint``, taken at the loop's top); the
        iteration count and the failure flag run on over the step's stages.
        """
        self._add_velocity_update(last_forces("alpha_sub"), "hsub", fallback)
        for variable, expression in copies.items():
            self.addComputePerDof(variable, expression)
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self.addComputePerDof("fstart", "f")
        later_alpha = len(composition.alpha_stages) > 1  # stages are distinct and sorted
        if later_alpha:
            self.addComputePerDof("fmid", "f")
        self.addComputeGlobal("phase", "phase + 1")
        self.addComputeGlobal("hsub", _stage_select(composition, composition.first_alpha_stage + 1, "h"))
        self.addComputeGlobal(
            "alpha_sub", _stage_select(composition, composition.first_alpha_stage + 1, "alpha")
        )
        self.addComputeGlobal("need_midpoint", "0")
        if later_alpha:
            self.addComputeGlobal("next_stage_midpoint", "1 - delta(alpha_sub)")
        self.addComputeGlobal("previous_midpoint_change", "1e30")

    def _add_composition_loop(self, composition: Composition) -> None:
        """Add the loop over the stages from the first with α, after :meth:`_add_alpha_substeps_start`.

        Each pass solves the current sub-step's positions; a finished sub-step takes its
        velocity update and starts the next one (:meth:`_add_next_stage_midpoint` first);
        the midpoint block comes last (rule 1), with the fixed-α midpoint force of the
        sub-step. The energy mode writes its own loop around the same pieces, with its
        trial ends (``energy_mode.AlphaRattleEnergyIntegrator._add_trial_loop``).
        """
        self.beginWhileBlock(f"phase < {composition.stages}.5")
        self._add_next_stage_midpoint(composition)
        self._add_substep_solve(fallback="xstep")
        self.beginIfBlock("substep_done > 0.5")
        self._add_substep_end(composition, fallback="vstep")
        self.endBlock()
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_midpoint_force("hsub", "alpha_sub")
        self.endBlock()
        self.endBlock()

    def _add_next_stage_midpoint(self, composition: Composition) -> None:
        """With more than one α stage: a sub-step just started on an α stage needs its midpoint iteration."""
        if len(composition.alpha_stages) > 1:
            self.addComputeGlobal("need_midpoint", "max(need_midpoint, next_stage_midpoint)")
            self.addComputeGlobal("next_stage_midpoint", "0")

    # ---------------------------------------------------------------- stepping
    def step(self, steps: int) -> None:
        """Advance the context by ``steps`` steps.

        The first step of every call checks the System (the program counts the
        particles without mass); where :meth:`check_context` was given the Context,
        the call is also checked against its platform before any step.

        Raises
        ------
        IncompatibleSystemError
            If the System has particles without mass (virtual sites) and the step
            cannot be right for them: before any step where :meth:`check_context`
            saw them, else at the call's first step, which is not taken (positions
            and velocities stay as they were; the Context's step count and time
            advance by one step).
        SystemSizeError
            If the integrator, bound again, runs a System with more particles than
            the first one it was bound to (the step is not taken).
        StartBlowUpError
            If the state went to NaN in the first 100 steps
            (:mod:`openmm_alphaprk.start_blowup`).
        """
        steps = int(steps)
        if steps <= 0:
            return
        mm.CustomIntegrator.step(self, 0)  # OpenMM's own error if the integrator is not bound
        context = self._checked_context()
        self._request_system_check(context)
        self._check_before_steps(context)
        velocities = self._start_check_velocities(context)
        start_blowup.take_steps(self, 1, velocities)
        self._raise_if_refused(context)
        if steps > 1:
            start_blowup.take_steps(self, steps - 1, velocities)

    def check_context(self, context: mm.Context) -> None:
        """Check this integrator against the System and platform of ``context``, the Context it is bound to.

        OpenMM gives an integrator no access to its Context; what depends on the
        platform is decided here. Particles without mass (virtual sites, e.g. TIP4P-Ew
        M-sites) are integrated by RATTLE and α = 0 on CUDA, OpenCL and HIP once this
        call has seen the platform; without it they are refused on every platform,
        since Reference and CPU place virtual sites only at the end of a step. The
        energy mode takes its default energy tolerance from the platform's precision
        and warns about the System here (:class:`~openmm_alphaprk.NonSmoothForcesWarning`,
        :class:`~openmm_alphaprk.nve.StateChangingForceWarning`).

        Call it after creating the Context (``simulation.context``), and again after
        binding the integrator to another Context. The check lasts as long as that
        Context exists, and is taken again at the next ``step()`` if the System's
        particles, forces or constraints changed (an edit followed by
        ``context.reinitialize()``).

        Parameters
        ----------
        context
            The Context this integrator is bound to.

        Raises
        ------
        ValueError
            If ``context`` runs another integrator.
        IncompatibleSystemError
            If the System has particles without mass that this integrator, as it is
            set now, cannot integrate right on this platform.
        """
        if int(context.getIntegrator().this) != int(self.this):
            raise InputError(
                f"check_context() was given a Context that runs another integrator "
                f"({type(context.getIntegrator()).__name__}); pass the Context this {type(self).__name__} "
                "is bound to (simulation.context)."
            )
        system = context.getSystem()
        self._checked = _CheckedContext(
            context=weakref.ref(context),
            platform=context.getPlatform().getName(),
            fingerprint=_fingerprint(system),
            massless=tuple(platforms.massless_particles(system)),
        )
        self._check_system(context)
        self._check_before_steps(context)

    def _checked_context(self) -> mm.Context | None:
        """Return the checked Context while it exists; check it again if its System changed."""
        checked = getattr(self, "_checked", None)
        context = checked.context() if checked is not None else None
        if context is None:
            self._checked = None
        elif _fingerprint(context.getSystem()) != checked.fingerprint:
            self.check_context(context)
        return context

    def _platform(self, context: mm.Context | None) -> str | None:
        return self._checked.platform if context is not None else None

    def _check_system(self, context: mm.Context) -> None:
        """Check what a subclass needs of the System and platform (called by :meth:`check_context`)."""

    def _check_before_steps(self, context: mm.Context | None) -> None:
        """Refuse, before any step, what the checked ``context`` shows cannot be right."""
        if context is None:
            return
        massless = self._checked.massless
        message = self._massless_refusal(len(massless), self._checked.platform)
        if message is not None:
            raise IncompatibleSystemError(f"{message} (First particle without mass: index {massless[0]}.)")

    def virtual_sites_refusal(self, platform: str | None) -> str | None:
        """Why this integrator, as set now, cannot integrate a System with virtual sites on ``platform``.

        Returns None where it can. ``platform`` None: not known (no :meth:`check_context`),
        where virtual sites are refused. The one place that decides which of this
        package's integrators can run a System with particles without mass.
        """
        return self._massless_refusal(1, platform)

    def _massless_refusal(self, count: int, platform: str | None) -> str | None:
        """Why ``count`` particles without mass cannot be integrated right on ``platform`` (None: unknown).

        Returns None if they can: none, or CUDA, OpenCL or HIP, which place virtual
        sites at every constraint step. Subclasses refuse more.
        """
        if count == 0 or platform in platforms.COMMON_PLATFORMS:
            return None
        where = f" on the {platform} platform" if platform is not None else ""
        message = (
            f"{type(self).__name__} cannot integrate this System{where}: {count} particle(s) have zero "
            "mass, e.g. virtual sites such as the M-sites of TIP4P-Ew or OPC water. The Reference and CPU "
            "platforms place virtual sites only at the end of a CustomIntegrator step, so forces taken "
            "inside the step would see stale sites; CUDA, OpenCL and HIP place them at every constraint "
            "step, where RATTLE and alpha=0 are right."
        )
        if platform is None:
            message += (
                " OpenMM gives an integrator no access to its Context: on CUDA, OpenCL or HIP call "
                "integrator.check_context(context) (e.g. simulation.context) once after creating it."
            )
        else:
            message += " Run it on CUDA, OpenCL or HIP."
        return (
            message
            + " Otherwise use a water model without virtual sites (TIP3P, SPC/E) or openmm.VerletIntegrator."
        )

    def _request_system_check(self, context: mm.Context | None) -> None:
        """Set what the system check at the next step needs: the particle count, and whether to refuse."""
        if not self.getGlobalVariableByName(N_PARTICLES):
            self.setGlobalVariableByName(N_PARTICLES, len(self.getPerDofVariableByName("x0")))
        allowed = self._massless_refusal(1, self._platform(context)) is None
        self.setGlobalVariableByName(
            CHECK_SYSTEM, _CHECK_ALLOWING_MASSLESS if allowed else _CHECK_REFUSING_MASSLESS
        )

    def _raise_if_refused(self, context: mm.Context | None) -> None:
        """Raise for a step the system check refused (it did nothing)."""
        if not self.getGlobalVariableByName(REFUSED):
            return
        self.setGlobalVariableByName(REFUSED, 0)  # a serialized copy must not stay refused
        self.setGlobalVariableByName(CHECK_SYSTEM, _CHECK_REFUSING_MASSLESS)
        particles = int(self.getGlobalVariableByName(N_PARTICLES))
        moved = round(self.getGlobalVariableByName(NDOF)) // 3
        untaken = (
            " The step was not taken: positions and velocities are as they were (the Context's step count "
            "and time advanced by one step)."
        )
        if moved > particles:
            raise SystemSizeError(
                f"{type(self).__name__} was first bound to a System of {particles} particles and now runs "
                f"one of at least {moved}. OpenMM keeps a CustomIntegrator's per-DOF variables at the size "
                f"of the first System it was bound to, so this cannot run: create a new integrator.{untaken}"
            )
        message = self._massless_refusal(particles - moved, self._platform(context))
        raise IncompatibleSystemError(
            (message or f"{particles - moved} particle(s) of this System have zero mass.") + untaken
        )

    def _start_check_velocities(self, context: mm.Context | None) -> Callable[[], tuple[np.ndarray, int]]:
        """Return what the start check reads: velocities (nm/ps) and the step after which they were taken.

        From the checked Context, the velocities now; without it, the program's copy
        of the velocities at the start of the last step (``v0``).
        """
        if context is not None:

            def current() -> tuple[np.ndarray, int]:
                state = context.getState(getVelocities=True)
                values = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
                return values, self._steps()

            return current

        def start_of_last_step() -> tuple[np.ndarray, int]:
            return np.array(self.getPerDofVariableByName("v0")), self._steps() - 1

        return start_of_last_step

    def _steps(self) -> int:
        return int(self.getGlobalVariableByName("steps_taken"))

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
        chosen = self.composition
        extra = f", composition={chosen.name!r}" if chosen is not None else ""
        return f"{type(self).__name__}(timestep={self.timestep}{extra})"


#: A plain-number step (read in ps, as OpenMM does) above this many ps is probably meant in fs.
LARGE_PLAIN_STEP_PS = 0.01


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
        stacklevel=outside_stacklevel() + 1,  # the user's call that made the integrator
    )


def check_context(integrator: mm.Integrator, context: mm.Context) -> None:
    """Call ``integrator.check_context(context)`` if it is one of this package's; others need none.

    For code that builds any integrator by name (``openmm.VerletIntegrator`` among them)
    and then its Context.

    Parameters
    ----------
    integrator : openmm.Integrator
        Any integrator; only this package's are checked.
    context : openmm.Context
        The Context the integrator is bound to.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk import RattleRescaleIntegrator
    >>> from openmm_alphaprk.integrators import check_context
    >>> from openmm_alphaprk.systems import prepare_system
    >>> cluster = prepare_system("water-cluster")
    >>> cpu = openmm.Platform.getPlatformByName("CPU")
    >>> for integrator in (openmm.VerletIntegrator(0.002), RattleRescaleIntegrator(0.002)):
    ...     context = openmm.Context(cluster.system, integrator, cpu)
    ...     check_context(integrator, context)  # the platform's checks and defaults; none for Verlet
    """
    if isinstance(integrator, _StepProgram):
        integrator.check_context(context)
