"""RATTLE followed by velocity rescaling to E_ref: the cheapest way to hold the energy.

Each step is a RATTLE step (:class:`~.rattle.RattleIntegrator`'s), then the velocities
relative to the rigid-body motion are scaled so that the total energy is E_ref again::

    v ← v_rigid + s (v − v_rigid),   s² = (E_ref − V − K_rigid) / (K − K_rigid)

v_rigid = V_cm + ω × (x − x_cm) is the rigid-body motion: the centre-of-mass velocity
V_cm = P/M always, and, unless the System has a periodic box (see
:meth:`RattleRescaleIntegrator._add_conservation_test`), the rigid rotation ω = I⁻¹L about the centre
of mass. RATTLE keeps P and L (to round-off, and to the small net force of PME's reciprocal
part), so both are measured when E_ref is taken and whenever the state was set (the
reference check's block, :mod:`~.reference_energy`) and carried between steps; the centre
of mass and the inertia tensor, which move with the atoms, are summed every step where ω
is needed. The velocities relative to v_rigid carry no linear and no angular momentum, so
the scaling keeps P and L, and, since rigid motion keeps every distance, it keeps the
velocity constraints G v = 0. K = K_rigid + K_internal (the cross terms vanish), V is the
potential energy after the step, read with the step's one force evaluation. E_ref is taken
and reset by the rule of :mod:`~.reference_energy`, as the energy mode takes it.

A System whose forces do not conserve momentum (an external potential, a particle fixed in
space: :func:`openmm_alphaprk.nve.momentum_breaking_forces`) has no rigid-body motion to
keep: the program (or :meth:`RattleRescaleIntegrator.check_context`) turns it off
(``translation`` = 0) and the step scales all the velocities, v ← s v.

A step for which no real positive s exists (E_ref − V ≤ K_rigid, or no internal kinetic
energy) is not taken: the Context keeps the state it started from, the steps after it in
the same ``step()`` call do nothing, and ``step()`` raises
:class:`VelocityRescaleError`, which says why.

Sums over degrees of freedom (each a device synchronisation on CUDA, OpenCL and HIP): per
step the kinetic energy, with the energy read, and without a periodic box the centre of
mass and the inertia tensor (10 more); once per ``step()`` call the reference check's
one; when the state was set, P (and the centre of mass and L) besides. With
``rescale_interval`` N > 1 the per-step ones (and the energy read) come at every N-th step
only; the steps between are RATTLE's program (or the composition's, or the splitting's) and
nothing more, and the state the last step of a ``step()`` call ends in is copied once, for
the next call's comparison.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable

import openmm as mm
import openmm.unit as unit

from .._units import InputError, to_dimensionless
from ..errors import VelocityRescaleError  # defined there; importable from here too
from ..nve import momentum_breaking_forces
from .alpha_rattle import DEFAULT_MAX_MIDPOINT_ITERATIONS, DEFAULT_MIDPOINT_TOLERANCE
from .compositions import Composition, requested_composition
from .pieces import DEFAULT_CONSTRAINT_TOLERANCE, _StepProgram
from .reference_energy import _ReferenceEnergy, energy_tolerance_setting
from .splittings import RATTLE, SPLITTINGS, Splitting
from .splittings import splitting as named_splitting
from .stage_sets import StageSet
from .variables import ALPHA, N_PARTICLES, RATTLE_RESIDUAL, RESCALE_HALTED, STEPS_TAKEN, VELOCITY_SCALE

#: A global set to 1 by :meth:`RattleRescaleIntegrator.check_context`: the System's box and forces known.
CONTEXT_CHECKED = "context_checked"

_AXES = {"x": "vector(1,0,0)", "y": "vector(0,1,0)", "z": "vector(0,0,1)"}
#: The centre-of-mass velocity P/M, per degree of freedom, from the carried momentum.
_CENTRE_OF_MASS_VELOCITY = "vector(momentum_x, momentum_y, momentum_z)/total_mass"
#: The per-DOF variable that holds it (set where P is measured): the scaling reads it with no
#: vector function. On the Reference and CPU platforms a per-DOF step with one costs many
#: plain passes (its variables looked up by name per particle), while one more per-DOF
#: variable adds a copy per degree of freedom to every pass; docs/platforms.md counts both.
_CENTRE_VELOCITY = "centre_velocity"
#: The rotation's part of the rigid-body velocity at the positions x, per degree of freedom.
_ROTATION_VELOCITY = "cross(vector(omega_x, omega_y, omega_z), x - vector(centre_x, centre_y, centre_z))"
#: Relative size of the diagonal added to the inertia tensor before it is inverted: leaves ω
#: unchanged for any System that can rotate, and finite for a linear one (whose rotation
#: about its axis moves no atom).
_INERTIA_REGULARIZATION = 1e-12


#: On a retake of E_ref (``rescale_interval`` > 1): the interval starts again from the new E_ref.
_INTERVAL_RESTART = (("rescale_count", "select(retake, 0, rescale_count)"),)
#: Added to the reference check's energy tolerance after a step between rescalings, whose
#: end energy was not read: twice the largest |H − E_ref| a rescaling has removed.
_EXCURSION_TOLERANCE = "step(rescale_count - 0.5)*2*rescale_excursion"


def rescale_interval_setting(rescale_interval: object) -> int:
    """Validate a ``rescale_interval`` argument: a positive integer (``10``, ``10.0``), returned as int.

    Raises
    ------
    InputError
        For anything else (0, a negative number, a fraction, a bool, text).
    """
    value = rescale_interval
    integral = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and not integral:
        integral = math.isfinite(float(value)) and float(value).is_integer()
    if not integral or int(value) < 1:
        raise InputError(
            f"rescale_interval must be a positive integer (rescale every N-th step), got {value!r}: "
            "give e.g. rescale_interval=10, or 1 (the default) to rescale every step."
        )
    return int(value)


class RattleRescaleIntegrator(_ReferenceEnergy, _StepProgram):
    """RATTLE, then the velocities relative to the rigid-body motion scaled so that H = E_ref.

    Its step program, as OpenMM runs it: :meth:`program_listing`, and docs/step_programs.md.

    The baseline every energy-holding method must beat: one force evaluation per step
    (its energy comes with it), H held at E_ref to the round-off of OpenMM's energy,
    linear and angular momentum and the velocity constraints kept, and the trajectory
    RATTLE's but for a velocity scale s of order 1 ± RATTLE's one-step energy error / K.
    It is not symplectic, and exact energy is not accuracy: a rescaled step is no closer
    to the true dynamics than RATTLE's.

    E_ref is the total energy of the state at the first step, and is taken again after
    :meth:`reset_reference_energy` and when the user changed the state (the rule of
    :mod:`openmm_alphaprk.integrators.reference_energy`). NVE: no update-context-state
    step, so barostats, thermostats and a ``CMMotionRemover`` do not act;
    :meth:`check_context` warns about them and about forces that are not smooth.

    A drop-in: it needs no call beyond OpenMM's. What rigid-body motion the scaling keeps
    is decided in the program from the forces at the state E_ref is taken from (see
    :meth:`_add_conservation_test`): P and the rigid rotation without a periodic box, P
    alone with one (where the step then sums the kinetic energy alone), neither where
    the forces do not conserve momentum (an external potential: every velocity is
    scaled). :meth:`check_context` (e.g. ``integrator.check_context(simulation.context)``)
    is an optional check: it decides the same from the System itself, warns about what
    NVE does not suit (barostats, thermostats, forces that are not smooth) and takes the
    default energy tolerance from the platform's precision.

    Parameters
    ----------
    timestep : openmm.unit.Quantity or float
        Step size (a time Quantity, or a number in picoseconds).
    constraint_tolerance : float, default 1e-8
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    energy_tolerance : openmm.unit.Quantity or float, optional
        Total-energy change (Quantity or kJ/mol) below which a state set between steps
        keeps E_ref (see :attr:`energy_tolerance`); default: 3× the noise of OpenMM's
        energy for the system's size and the platform's precision (set by
        :meth:`check_context`; without it, for the least precise platform).
    order : {2, 4, 6}, optional
        Instead of one RATTLE step (2, the default), a symmetric composition of RATTLE
        steps (:mod:`~.compositions`): ``order=4`` (Suzuki's five stages), ``order=6``
        (McLachlan's nine). The rescaling follows its last stage: s force evaluations
        per step for s stages, the energy read with the last. The trajectory is the
        composition's (fourth or sixth order) but for the scale s.
    composition : str or Composition, optional
        A composition by name (:data:`~.compositions.COMPOSITIONS`) or a
        :class:`~.compositions.Composition`, instead of ``order``.
    alpha : float, optional
        Instead of RATTLE's step, α-RATTLE's with this fixed α (or, with ``order`` or
        ``composition``, the composition with α on its middle stage): the rescaling after a
        fixed α, built from the same pieces as :class:`~.alpha_rattle.AlphaRattleIntegrator`'s
        step; with ``rescale_interval`` 1 only. Not a name of the command line: at equal
        force evaluations it measured farther from the converged trajectory than the rescaled
        RATTLE rows (docs/integrators.md).
    splitting : str or Splitting, optional
        Instead of RATTLE, a kick-drift splitting with constraints (:mod:`~.splittings`,
        by name or a :class:`~.splittings.Splitting`; ``"me2"``: the minimum-error
        two-stage member of the explicit α-family): s force evaluations per step for s
        stages, the rescaling after the last; not with ``order`` or ``composition``.
    rescale_interval : int, default 1
        N: rescale after every N-th step only. The steps between are plain RATTLE (or
        the composition): no energy read and no sum, H drifting from E_ref as RATTLE's
        does until the next rescaling step puts it back. N = 1 is the program without
        the interval. The count (``rescale_count``, steps since the last rescaling) is a
        global of the program: it runs on across ``step()`` calls (``step(7)`` then
        ``step(3)`` with N = 10 rescales after the 10th step), is saved in checkpoints
        and with the integrator's XML, and starts again from 0 whenever E_ref is taken
        (the first step, :meth:`reset_reference_energy`, a state set by the user:
        ``setState`` and ``setPositions`` included), so the first rescaling is the N-th
        step after that. The steps between rescalings run RATTLE's program and nothing
        more (the listing: :meth:`program_listing`); the state a call's last step ends in
        is recorded for the comparison at the next call's first step. After a step
        between rescalings the energy the step ended with was not read: a state set then
        is told from the common platform's reordering by its energy against the last
        rescaled step's, within the tolerance plus twice the largest |H − E_ref| a
        rescaling has removed.

    Raises
    ------
    VelocityRescaleError
        From :meth:`step`, for a step after which no real scale factor exists.
    InputError
        For a ``rescale_interval`` that is not a positive integer.

    See Also
    --------
    RattleIntegrator : the same step without the rescaling.
    AlphaRattleEnergyIntegrator : α chosen every step to hold the energy (costs more).

    Examples
    --------
    ``rattle4+rescale`` (the recommended way to hold the energy) on the shipped
    cluster of 74 waters:

    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import RattleRescaleIntegrator
    >>> from openmm_alphaprk.systems import prepare_system
    >>> water = prepare_system("water-cluster")
    >>> integrator = RattleRescaleIntegrator(2 * unit.femtoseconds, order=4)
    >>> context = openmm.Context(water.system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setState(water.state)
    >>> integrator.step(5)  # no call but OpenMM's: the program finds the forces keep P and L
    >>> integrator.removes_rotation, integrator.removes_translation
    (True, True)
    >>> state = context.getState(getEnergy=True)
    >>> residual = state.getKineticEnergy() + state.getPotentialEnergy() - integrator.reference_energy
    >>> abs(residual) < integrator.energy_tolerance  # H held at E_ref
    True

    Rescaling every 10th step only: H is E_ref after steps 10, 20, …, and moves as
    RATTLE's between them.

    >>> every_tenth = RattleRescaleIntegrator(2 * unit.femtoseconds, rescale_interval=10)
    >>> context = openmm.Context(water.system, every_tenth, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setState(water.state)
    >>> every_tenth.check_context(context)  # optional: the System's own answer, and its warnings
    >>> every_tenth.step(7)
    >>> every_tenth.step(3)  # the count runs on across calls: this call ends with a rescaling
    >>> state = context.getState(getEnergy=True)
    >>> residual = state.getKineticEnergy() + state.getPotentialEnergy() - every_tenth.reference_energy
    >>> abs(residual) < every_tenth.energy_tolerance, every_tenth.rescalings
    (True, 1)
    """

    _holds_energy_as = "RATTLE with velocity rescaling"

    def __init__(
        self,
        timestep: unit.Quantity | float,
        *,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
        energy_tolerance: unit.Quantity | float | None = None,
        order: int | None = None,
        composition: str | Composition | None = None,
        rescale_interval: int = 1,
        splitting: str | Splitting | None = None,
        alpha: float | None = None,
    ) -> None:
        tolerance = energy_tolerance_setting(energy_tolerance)
        self._composition = requested_composition(order, composition)
        if splitting is not None and self._composition is not None:
            raise InputError("give a composition (order, composition) or a splitting, not both.")
        self._splitting = named_splitting(splitting) if splitting is not None else None
        if alpha is not None and self._splitting is not None:
            raise InputError("alpha applies to α-RATTLE's step or composition, not to a splitting (split=α).")
        #: α of an α-RATTLE base step (None: an explicit base)
        self._alpha = None if alpha is None else to_dimensionless(alpha, "alpha")
        #: the base step the rescaling follows: RATTLE, a composition of RATTLE steps or a splitting
        self._base: StageSet = self._composition or self._splitting or RATTLE
        #: the sub-steps of a step, where there are several (a composition or a splitting)
        self._stages = None if self._base is RATTLE else self._base
        self._rescale_interval = rescale_interval_setting(rescale_interval)
        super().__init__(timestep, constraint_tolerance)
        self._add_reference_energy_variables(tolerance, end_state=False)
        self._add_rescale_variables()
        if self._rescale_interval > 1:
            self._add_interval_variables(self._rescale_interval)
        if self._alpha is not None:  # declares fstart (and a composition's state and record) too
            order = 2 if self._composition is None else self._composition.order
            self._add_midpoint_variables(
                self._alpha,
                DEFAULT_MIDPOINT_TOLERANCE,
                DEFAULT_MAX_MIDPOINT_ITERATIONS,
                order,
                self._composition,
            )
        elif self._stages is not None:
            self._add_record(self._stages)
        self._add_step(self._build_program, update_context_state=False, halted=RESCALE_HALTED)
        if self._rescale_interval > 1:
            self._add_call_end_record()

    def _add_rescale_variables(self) -> None:
        self.addGlobalVariable("rotation", 1)  # 0 for a periodic System
        self.addGlobalVariable("translation", 1)  # 0 where the forces break momentum
        self.addGlobalVariable(CONTEXT_CHECKED, 0)  # 1 once check_context has decided both
        for name in (
            "net_force",
            "force_scale",
            "net_torque",
            "torque_scale",
            *(f"net_{kind}_{axis}" for kind in ("force", "torque") for axis in _AXES),
        ):
            self.addGlobalVariable(name, 0)
        self.addGlobalVariable("total_mass", 0)
        for name in (
            "potential_energy",
            "rigid_kinetic_energy",
            "scale_squared",
            "no_factor",
            RATTLE_RESIDUAL,
            RESCALE_HALTED,
            "sum_rattle_residual",
            "sum_rattle_residual_squared",
            "sum_scale_change",
            "sum_scale_change_squared",
            "max_abs_scale_change",
            "sum_inertia",
            *(f"{name}_{axis}" for name in ("momentum", "centre", "angular", "omega") for axis in _AXES),
            *(f"inertia_{pair}" for pair in ("xx", "yy", "zz", "xy", "xz", "yz")),
        ):
            self.addGlobalVariable(name, 0)
        self.addGlobalVariable(VELOCITY_SCALE, 1)
        # On the Reference and CPU platforms every per-DOF step copies every per-DOF variable
        # of the program, per degree of freedom: the program declares no more than it needs,
        # and with an interval the steps between rescalings have RATTLE's (x0, v0) and P/M.
        self.addPerDofVariable(_CENTRE_VELOCITY, 0)
        if self._rescale_interval == 1:
            if self._alpha is None:  # α declares its own
                self.addPerDofVariable("fstart", 0)
        if self._stages is not None and self._alpha is None:
            for name in ("xstep", "vstep"):
                self.addPerDofVariable(name, 0)

    def _add_interval_variables(self, interval: int) -> None:
        """Declare the interval's globals (``rescale_interval`` > 1 only: N = 1 is the plain program)."""
        self.addGlobalVariable("rescale_interval", interval)
        for name in ("rescale_count", "rescalings", "rescale_excursion", "call_steps_left"):
            self.addGlobalVariable(name, 0)

    # ---------------------------------------------------------------- the program
    def _build_program(self) -> None:
        """Add the base step, then the rigid-body motion, the scale factor and the scaled velocities.

        With N = 1 (every step): F(x0) copied, then the reference check, the base step from
        the copy and the rescaling. F(x0) is copied before the reference check, whose energy
        read would otherwise be the step's first evaluation (see
        :meth:`~.reference_energy._ReferenceEnergy._add_reference_check`: on CUDA the forces
        read after it were wrong).

        With ``rescale_interval`` N > 1, after the reference check, two blocks: the step
        between rescalings (``rescale_count`` < N), which is :class:`~.rattle.RattleIntegrator`'s
        program (or the composition's, or the splitting's) and nothing more, and the rescaling
        step. Each saves its own start (x0, v0; the rescaling step's also in ``xstep``,
        ``vstep`` where the stages overwrite x0, v0). OpenMM decides for each read of ``f``,
        once, whether the force evaluation it causes computes the energy too: it does if any
        path through the program (taking or skipping every ``if`` block, regardless of its
        condition) reads ``energy`` before the positions change. The only energy reads are
        the rescaling step's own, after its last force, and the reference check's, which
        follows an ``x = x`` (:meth:`_add_moved_start_invalidating`): so a step between
        rescalings computes no energy, and the rescaling step's last force read computes both
        in one evaluation, as for N = 1. The state the steps of a ``step()`` call end in is
        recorded (x0, v0) after the call's last step only
        (:meth:`_add_call_end_record`). Over α's step, one block: :meth:`_add_alpha_interval_steps`.
        """
        if self._rescale_interval == 1:
            self._add_step_start(on_moved=self._add_moved_start)
            self._add_base_step(first_force="fstart")
            self._add_rescaling()
            self._add_end_step()
            return
        self._add_reference_check(
            on_moved=self._add_moved_start_invalidating,
            previous=("x0", "v0"),
            on_retake=_INTERVAL_RESTART,
            carried_tolerance=_EXCURSION_TOLERANCE,
            after_energy=self._add_forces_invalidation,
        )
        self.addComputeGlobal("rescale_count", "rescale_count + 1")
        if self._alpha is not None:
            self._add_alpha_interval_steps()
            self._add_end_step()
            return
        self.beginIfBlock("rescale_count < rescale_interval - 0.5")  # RATTLE's program
        self._add_save_step_start()
        self._add_base_step(first_force="f")
        self.endBlock()
        self.beginIfBlock("rescale_count > rescale_interval - 0.5")
        self._add_save_step_start(**({} if self._stages is None else {"xstep": "x", "vstep": "v"}))
        self._add_base_step(first_force="f")
        self._add_rescaling()
        self._add_interval_restart()
        self.endBlock()
        self._add_end_step()

    def _add_alpha_interval_steps(self) -> None:
        """With ``alpha`` and N > 1: the α base step once in program text, the rescaling after it at the N-th.

        Two copies of the α loop, one per block, would put the first copy's midpoint
        assignment before the second's constraint steps in program text, where the common
        platform stores it as a displacement its force does not see (rule 1 of :mod:`~.pieces`).
        One copy keeps it after every constraint step. The cost: the rescaling block reads the
        energy after the step's last force read on one path through the program, so every
        step's last force evaluation computes the energy too.
        """
        copies = {"fstart": "f"}
        copies.update({"fmid": "f"} if self._composition is None else {"xstep": "x", "vstep": "v"})
        self._add_save_step_start(**copies)
        self._add_base_step(first_force="fstart")
        self.beginIfBlock("rescale_count > rescale_interval - 0.5")
        self._add_rescaling()
        self._add_interval_restart()
        self.endBlock()

    def _add_step_start(self, on_moved: Callable[[], None]) -> None:
        """F(x0) copied, then the reference check (and, for a composition, the step's start kept)."""
        if self._stages is None:
            # x0, v0 hold the last step's end (written at the end of the step): the start of
            # this one unless the state was set, which the reference check's block copies
            self.addComputeGlobal("step_force_evaluations", "0")
            self.addComputePerDof("fstart", "f")
            if self._alpha is not None:
                self.addComputePerDof("fmid", "f")
            self._add_reference_check(on_moved=on_moved, previous=("x0", "v0"))
        else:  # the stages overwrite x0, v0: the step's start kept for a step without a factor
            self.addComputePerDof("fstart", "f")
            self._add_reference_check(on_moved=self._add_rigid_body_measurement, previous=("x0", "v0"))
            self._add_save_step_start(xstep="x", vstep="v")

    def _add_base_step(self, first_force: str) -> None:
        """Add the base step from x0, v0, F(x0) in ``first_force``: RATTLE, a composition, a splitting, α's.

        With ``alpha``, α-RATTLE's step or composition (:meth:`~.pieces._StepProgram._add_alpha_step`),
        its failed midpoint iterations counted: a failed step returns its start, which the
        rescaling then scales by s ≈ 1, and :meth:`step` raises.
        """
        if self._alpha is None:
            self._add_substeps(self._base.substeps(), first_force=first_force)
            return
        self._add_alpha_step(self._composition, first_force=first_force)
        self.addComputeGlobal("midpoint_failures", "midpoint_failures + midpoint_failed")

    def _add_moved_start_invalidating(self) -> None:
        """Where the state was set (``rescale_interval`` > 1): P and L measured, then the forces invalidated.

        Before the reference check's energy read: the last force read of a step between
        rescalings then computes no energy for that read, which evaluates the energy here
        only (:meth:`_add_forces_invalidation`).
        """
        self._add_rigid_body_measurement()
        self._add_forces_invalidation()

    def _add_forces_invalidation(self) -> None:
        """Add ``x = x``: it ends the forces' validity for OpenMM's analysis of the program.

        The assignment changes nothing (on the common platform it comes before the step's
        constraint steps in program text, so it is stored as a zero displacement). With
        ``rescale_interval`` > 1 it stands on both sides of the reference check's energy read.
        Before it, so that no step between rescalings evaluates the energy with its forces.
        After it, because the blocks that follow read ``f`` in a step that moves the
        positions (``x = x0 + dt*v0 + ...``), so OpenMM's analysis evaluates that energy
        alone and marks the forces valid; on CUDA and NVIDIA's OpenCL the forces read after
        such an evaluation were wrong
        (:meth:`~.reference_energy._ReferenceEnergy._add_reference_check`). Invalidated
        again, they are evaluated at the step's force read: one force evaluation more, on
        the steps that open the reference check's block only.
        """
        self.addComputePerDof("x", "x")

    def _add_call_end_record(self) -> None:
        """After the last step of a ``step()`` call (``rescale_interval`` > 1): its end in x0, v0.

        :meth:`step` sets ``call_steps_left`` to the call's steps; the program counts it
        down and copies the state at 0, where the next call's first step compares its start
        with it (:mod:`~.reference_energy`). Outside the step's block, so that a call halted
        by a step without a factor records the start it went back to. A copy of the program
        that no :meth:`step` drives (``call_steps_left`` = 0) records after every step.
        """
        self.addComputeGlobal("call_steps_left", "max(call_steps_left - 1, 0)")
        self.beginIfBlock("call_steps_left < 0.5")
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self.endBlock()

    def _add_rescaling(self) -> None:
        """Add the rigid-body motion, the scale factor, the halt without one and the scaled velocities."""
        self._add_rigid_body_motion()
        self._add_scale_factor()
        self._add_halt_without_factor()
        self._add_scaling()

    def _add_interval_restart(self) -> None:
        """After a rescaling: count it, keep the largest |H − E_ref| it removed, start the next interval.

        A step without a factor (halted) leaves ``rescale_count`` at N − 1, so that the
        step taken again from the same start is a rescaling step.
        """
        self.addComputeGlobal("rescalings", "rescalings + 1 - no_factor")
        self.addComputeGlobal(
            "rescale_excursion", f"max(rescale_excursion, (1 - no_factor)*abs({RATTLE_RESIDUAL}))"
        )
        self.addComputeGlobal("rescale_count", "no_factor*(rescale_interval - 1)")

    def _add_scaling(self) -> None:
        """Scale the velocities relative to the rigid-body motion; record the state the step ends in."""
        self.beginIfBlock("no_factor < 0.5")
        self.beginIfBlock("rotation > 0.5")
        self.addComputePerDof(
            "v", f"rigid + {VELOCITY_SCALE}*(v - rigid); rigid = {_CENTRE_VELOCITY} + {_ROTATION_VELOCITY}"
        )
        self.endBlock()
        self.beginIfBlock("rotation < 0.5")  # no vector function at every step: large boxes
        self.addComputePerDof("v", f"centre + {VELOCITY_SCALE}*(v - centre); centre = {_CENTRE_VELOCITY}")
        self.endBlock()
        self._add_end_state_record(
            "potential_energy + rigid_kinetic_energy + scale_squared*internal;"
            "internal = kinetic_energy - rigid_kinetic_energy",
            into=self._end_state_variables(),
        )
        self.addComputeGlobal("sum_rattle_residual", f"sum_rattle_residual + {RATTLE_RESIDUAL}")
        self.addComputeGlobal(
            "sum_rattle_residual_squared", f"sum_rattle_residual_squared + {RATTLE_RESIDUAL}^2"
        )
        self.addComputeGlobal("sum_scale_change", f"sum_scale_change + ({VELOCITY_SCALE} - 1)")
        self.addComputeGlobal(
            "sum_scale_change_squared", f"sum_scale_change_squared + ({VELOCITY_SCALE} - 1)^2"
        )
        self.addComputeGlobal("max_abs_scale_change", f"max(max_abs_scale_change, abs({VELOCITY_SCALE} - 1))")
        self.endBlock()

    def _end_state_variables(self) -> tuple[str, str] | None:
        """Where a rescaling step records its end: x0, v0 (N = 1), read by the next step's reference check.

        None with ``rescale_interval`` > 1, where the call's last step records it
        (:meth:`_add_call_end_record`).
        """
        return None if self._rescale_interval > 1 else ("x0", "v0")

    def _add_system_measurements(self) -> None:
        self.addComputeSum("total_mass", "m/3")

    def _add_moved_start(self) -> None:
        """Where the state was set: the step starts from it (x0, v0), and P (and L) are measured."""
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self._add_rigid_body_measurement()

    def _add_rigid_body_measurement(self) -> None:
        """P and (with ``rotation``) L about the centre of mass, from the state a step starts from.

        In the reference check's block: at the first step, after a reset and where the
        state was set. Carried to the steps after it, which RATTLE keeps them for (P/M also
        per degree of freedom, in ``centre_velocity``); zero
        without ``translation`` (forces that do not conserve momentum). A Context that does
        not hold the program's per-DOF values (a new one, or one reinitialized without them)
        holds no x0, v0 either, so its first step measures them.
        """
        self.beginIfBlock(f"{CONTEXT_CHECKED} < 0.5")
        self._add_conservation_test()
        self.endBlock()
        for axis, unit_vector in _AXES.items():
            self._add_sum(f"momentum_{axis}", f"m*v*{unit_vector}")
            self.addComputeGlobal(f"momentum_{axis}", f"translation*momentum_{axis}")
        self.addComputePerDof(_CENTRE_VELOCITY, _CENTRE_OF_MASS_VELOCITY)
        self.beginIfBlock("rotation > 0.5")
        self._add_centre_of_mass()
        r = "(x - vector(centre_x, centre_y, centre_z))"
        for axis, unit_vector in _AXES.items():
            self._add_sum(f"angular_{axis}", f"m*cross({r}, v)*{unit_vector}")
        self.endBlock()

    def _add_conservation_test(self) -> None:
        """Decide from the forces whether they keep P (``translation``) and L (``rotation``).

        Without :meth:`check_context` the program cannot see the System, so it reads the
        answer off the forces at the state E_ref is taken from: pair forces without a
        periodic box sum to zero force and zero torque about the centre of mass (to
        round-off, far below the thresholds), an external potential (a particle held in
        space, a field) to a net force, and minimum-image pairs across a periodic boundary
        to a net torque (far above them). ``translation`` = 1 where |Σf| ≤ 1e-5 Σ|f| and the System
        has more than one particle (one particle has no motion but its centre's);
        ``rotation`` = 1 besides where |Σ r × f| ≤ 1e-6 Σ|r||f|. A state whose forces all
        vanish keeps both. Restraints on a few atoms of many can pass for momentum-keeping
        forces here: :meth:`check_context` reads the System's forces instead.
        """
        net = " + ".join(f"net_force_{axis}^2" for axis in _AXES)
        for axis, unit_vector in _AXES.items():
            self._add_sum(f"net_force_{axis}", f"f*{unit_vector}")
        self._add_sum("force_scale", "abs(f)")
        self.addComputeGlobal("net_force", f"sqrt({net})")
        self.addComputeGlobal(
            "translation",
            f"(1 - delta({N_PARTICLES} - 1))*step(1e-5*force_scale - net_force)",
        )
        self._add_centre_of_mass()
        r = "(x - vector(centre_x, centre_y, centre_z))"
        for axis, unit_vector in _AXES.items():
            self._add_sum(f"net_torque_{axis}", f"cross({r}, f)*{unit_vector}")
        self._add_sum("torque_scale", f"sqrt(dot({r}, {r})*dot(f, f))*vector(1, 0, 0)")
        self.addComputeGlobal("net_torque", "sqrt(" + " + ".join(f"net_torque_{a}^2" for a in _AXES) + ")")
        self.addComputeGlobal("rotation", "translation*step(1e-6*torque_scale - net_torque)")

    def _add_centre_of_mass(self) -> None:
        for axis, unit_vector in _AXES.items():
            self._add_sum(f"centre_{axis}", f"m*x*{unit_vector}/total_mass")

    def _add_rigid_body_motion(self) -> None:
        """K after the RATTLE step; with ``rotation`` the centre of mass, the inertia tensor and ω = I⁻¹L.

        P and L are the ones measured by :meth:`_add_rigid_body_measurement`. Without
        ``rotation`` ω stays 0 and the step sums K alone.
        """
        self._add_sum("kinetic_energy", "0.5*m*v*v")
        self.beginIfBlock("rotation > 0.5")
        self._add_centre_of_mass()
        r = "(x - vector(centre_x, centre_y, centre_z))"
        self._add_sum("sum_inertia", f"m*{r}^2")  # Σ m |r|²
        for axis, unit_vector in _AXES.items():  # Σ m r_a², the diagonal is Σ m |r|² − that
            self._add_sum(f"inertia_{axis}{axis}", f"m*{r}^2*{unit_vector}")
            self.addComputeGlobal(f"inertia_{axis}{axis}", f"sum_inertia - inertia_{axis}{axis}")
        for pair, (first, second) in (("xy", "xy"), ("xz", "xz"), ("yz", "yz")):
            self._add_sum(f"inertia_{pair}", f"-m*_{first}({r})*_{second}({r})*vector(1,0,0)")
        for axis in _AXES:
            self.addComputeGlobal(f"omega_{axis}", _angular_velocity(axis))
        self.endBlock()

    def _add_scale_factor(self) -> None:
        """Add s² = (E_ref − V − K_rigid)/(K − K_rigid); ``no_factor`` = 1 unless it is positive, finite."""
        self.addComputeGlobal("potential_energy", "energy")
        self.addComputeGlobal(RATTLE_RESIDUAL, "potential_energy + kinetic_energy - reference_energy")
        self.addComputeGlobal(
            "rigid_kinetic_energy",
            "0.5*(momentum_x^2 + momentum_y^2 + momentum_z^2)/total_mass"
            " + 0.5*(omega_x*angular_x + omega_y*angular_y + omega_z*angular_z)",
        )
        self.addComputeGlobal(
            "scale_squared",
            "(reference_energy - potential_energy - rigid_kinetic_energy)"
            "/(kinetic_energy - rigid_kinetic_energy)",
        )
        # step(NaN) is 0: a non-finite energy has no factor either
        self.addComputeGlobal(
            "no_factor",
            "1 - step(scale_squared - 1e-300)*step(1e300 - scale_squared)"
            "*step(kinetic_energy - rigid_kinetic_energy - 1e-300)",
        )
        self.addComputeGlobal(VELOCITY_SCALE, "select(no_factor, 1, sqrt(max(scale_squared, 0)))")

    def _add_halt_without_factor(self) -> None:
        """Without a factor: back to the step's start, not counted as a step, and halt the call.

        The position assignment comes after every constraint step in program text, so the
        common platform stores it as positions, not as a displacement (rule 1 of
        :mod:`~.pieces`).
        """
        self.beginIfBlock("no_factor > 0.5")
        self.addComputePerDof("x", "x0" if self._stages is None else "xstep")
        self.addComputePerDof("v", "v0" if self._stages is None else "vstep")
        self.addComputeGlobal(RESCALE_HALTED, "1")
        self.addComputeGlobal(STEPS_TAKEN, f"{STEPS_TAKEN} - 1")  # _add_end_step counts it again
        self.endBlock()

    # ---------------------------------------------------------------- stepping
    def step(self, steps: int) -> None:
        """Advance by ``steps`` steps; raise if a step found no real scale factor.

        Raises
        ------
        VelocityRescaleError
            If E_ref − V after a RATTLE step is at most the rigid-body kinetic energy (no
            real factor), or the step's energy is not finite. The Context is left in the
            state the failed step started from; OpenMM's step count and time advanced by
            the failed step and the rest of the call, which did nothing.
        IncompatibleSystemError, SystemSizeError, StartBlowUpError
            As for :meth:`RattleIntegrator.step <openmm_alphaprk.RattleIntegrator.step>`.
        """
        steps = int(steps)
        if steps <= 0:
            return
        self.setGlobalVariableByName(RESCALE_HALTED, 0)
        if "call_steps_left" in self._global_names():  # a program from before it records every step
            self.setGlobalVariableByName("call_steps_left", steps)
        before = self.steps_taken
        failures = self._midpoint_failures()
        super().step(steps)
        self._raise_if_midpoint_failed(failures)
        if self.getGlobalVariableByName(RESCALE_HALTED):
            raise VelocityRescaleError(self._no_factor_message(steps - (self.steps_taken - before)))

    def _checked_context(self) -> mm.Context | None:
        """As for every integrator; once the checked Context is gone the program decides again."""
        had_one = getattr(self, "_checked", None) is not None
        context = super()._checked_context()
        if had_one and context is None:
            self.setGlobalVariableByName(CONTEXT_CHECKED, 0)
        return context

    def _no_factor_message(self, idle_steps: int) -> str:
        get = self.getGlobalVariableByName
        potential, kinetic = get("potential_energy"), get("kinetic_energy")
        reference, rigid = get("reference_energy"), get("rigid_kinetic_energy")
        where = (
            f"{type(self).__name__} stopped at its step {self.steps_taken + 1}: the Context holds the state "
            f"that step started from (positions and velocities); OpenMM's step count and time advanced by "
            f"{idle_steps} step(s) that did nothing."
        )
        if not (math.isfinite(potential) and math.isfinite(kinetic)):
            return (
                f"the RATTLE step blew up (potential energy {potential:.6g} kJ/mol, kinetic energy "
                f"{kinetic:.6g} kJ/mol): reduce the step size, or minimize and equilibrate the start. {where}"
            )
        internal = kinetic - rigid
        residual = potential + kinetic - reference
        return (
            f"no real velocity scale s makes K + V = E_ref: after the RATTLE step H − E_ref = "
            f"{residual:.6g} kJ/mol, more than the internal kinetic energy the scaling takes it from, "
            f"{internal:.6g} kJ/mol (E_ref − V − K_rigid = {reference - potential - rigid:.6g}; E_ref "
            f"{reference:.6g}, V after the step {potential:.6g}, rigid-body kinetic energy {rigid:.6g}). "
            "Likely causes: (1) too large a step for the system: one RATTLE step's energy error should "
            f"be a small fraction of the kinetic energy (here {abs(residual) / max(kinetic, 1e-300):.2g} of "
            "it), e.g. flexible water or unconstrained bonds to hydrogen at 2 fs: reduce the step, or "
            "constrain them (rigidWater=True, constraints=HBonds); (2) the potential energy changed without "
            "the state changing (a force parameter set between steps): call "
            "integrator.reset_reference_energy() after such a change; (3) too little internal kinetic "
            f"energy to absorb the step's error (velocities near zero): give the system velocities. {where}"
        )

    def _check_system(self, context: mm.Context) -> None:
        """Choose what rigid-body motion the scaling keeps, from the System; warn (NVE).

        P and L where the forces conserve both (no periodic box), P alone with a periodic
        box, none where the forces do not conserve momentum
        (:func:`~openmm_alphaprk.nve.momentum_breaking_forces`): then all the velocities are
        scaled.
        """
        super()._check_system(context)
        system = context.getSystem()
        translation = not momentum_breaking_forces(system)
        rotation = translation and not system.usesPeriodicBoundaryConditions()
        if not translation and self.getGlobalVariableByName("translation"):
            self.reset_reference_energy()  # P measured as carried must be measured again (as 0)
        self.setGlobalVariableByName("translation", float(translation))
        self.setGlobalVariableByName("rotation", float(rotation))
        self.setGlobalVariableByName(CONTEXT_CHECKED, 1)

    # ---------------------------------------------------------------- what the user reads
    @property
    def velocity_scale(self) -> float:
        """The factor s the last step scaled the velocities relative to the rigid-body motion by."""
        return self.getGlobalVariableByName(VELOCITY_SCALE)

    @property
    def rattle_residual(self) -> unit.Quantity:
        """H − E_ref after the last RATTLE step, before the scaling: the energy error it removed."""
        return self.getGlobalVariableByName(RATTLE_RESIDUAL) * unit.kilojoules_per_mole

    def __repr__(self) -> str:
        text = super().__repr__()
        chosen, alpha = self.splitting, self.alpha
        if alpha is not None:
            text = f"{text[:-1]}, alpha={alpha})"
        return text if chosen is None else f"{text[:-1]}, splitting={chosen.name!r})"

    @property
    def splitting(self) -> Splitting | None:
        """The splitting the rescaling follows (None: RATTLE or a composition); read back when restored."""
        if "_splitting" in vars(self):
            return self._splitting
        return self._recorded(Splitting, SPLITTINGS)

    @property
    def alpha(self) -> float | None:
        """α of an α-RATTLE base step (None: RATTLE, a composition of RATTLE steps or a splitting)."""
        return self.getGlobalVariableByName(ALPHA) if ALPHA in self._global_names() else None

    def _massless_refusal(self, count: int, platform: str | None) -> str | None:
        alpha = self.alpha
        if count and alpha is not None and alpha != 0.0:
            return self._midpoint_force_refusal(count, f"alpha={alpha}")
        return super()._massless_refusal(count, platform)

    @property
    def rescale_interval(self) -> int:
        """N: the velocities are rescaled every N-th step (1: every step)."""
        if "rescale_interval" not in self._global_names():
            return 1
        return int(self.getGlobalVariableByName("rescale_interval"))

    @property
    def rescalings(self) -> int:
        """Number of steps that rescaled the velocities (every step for ``rescale_interval`` 1)."""
        if self.rescale_interval == 1:
            return self.steps_taken
        return int(self.getGlobalVariableByName("rescalings"))

    @property
    def removes_rotation(self) -> bool:
        """Whether the rigid rotation is kept out of the scaling (no periodic box, or not known)."""
        return bool(self.getGlobalVariableByName("rotation"))

    @property
    def removes_translation(self) -> bool:
        """Whether the centre-of-mass motion is kept out of the scaling (False: all velocities scaled).

        False once :meth:`check_context` found forces that do not conserve momentum.
        """
        return bool(self.getGlobalVariableByName("translation"))

    def rescale_totals(self) -> dict[str, float]:
        """Totals over every step since the integrator was created.

        Returns
        -------
        A dict with ``steps``, ``rescalings`` (steps that were scaled), ``reference_resets``,
        ``force_evaluations_per_step``, ``rms_rattle_residual`` (RMS of H − E_ref after each
        RATTLE step, before its scaling: the energy error the rescaling removed, kJ/mol; with
        ``rescale_interval`` N > 1 over the rescaling steps: the error of N steps),
        ``max_abs_scale_change`` (max |s − 1|), ``mean_scale_change`` and
        ``rms_scale_change`` (mean and RMS of s − 1 over the rescalings), ``removed_energy``
        (the sum of those H − E_ref, kJ/mol: what the scalings took out) and
        ``added_energy_per_ns`` (−``removed_energy`` per ns of simulated time, kJ/mol/ns);
        NaN before the first step.
        """
        steps = self.steps_taken
        rescaled = self.rescalings
        nan = float("nan")

        def mean(name: str) -> float:
            return self.getGlobalVariableByName(name) / rescaled if rescaled else nan

        removed = self.getGlobalVariableByName("sum_rattle_residual") if rescaled else nan
        simulated_ns = steps * self.getStepSize().value_in_unit(unit.nanoseconds)
        return {
            "steps": steps,
            "rescalings": rescaled,
            "reference_resets": int(self.getGlobalVariableByName("reference_resets")),
            "force_evaluations_per_step": self.force_evaluations_per_step,
            "rms_rattle_residual": mean("sum_rattle_residual_squared") ** 0.5,
            "max_abs_scale_change": self.getGlobalVariableByName("max_abs_scale_change") if rescaled else nan,
            "mean_scale_change": mean("sum_scale_change"),
            "rms_scale_change": mean("sum_scale_change_squared") ** 0.5,
            "removed_energy": removed,
            "added_energy_per_ns": -removed / simulated_ns if rescaled else nan,
        }


def _angular_velocity(axis: str) -> str:
    """Expression of ω_axis = ((I + εI₀) ⁻¹ L)_axis by the adjugate of the symmetric 3×3 inertia tensor."""
    row = {
        "x": "(a11*angular_x + a12*angular_y + a13*angular_z)",
        "y": "(a12*angular_x + a22*angular_y + a23*angular_z)",
        "z": "(a13*angular_x + a23*angular_y + a33*angular_z)",
    }[axis]
    return (
        f"{row}/det;"
        "det = ixx*a11 + ixy*a12 + ixz*a13;"
        "a11 = iyy*izz - iyz^2; a22 = ixx*izz - ixz^2; a33 = ixx*iyy - ixy^2;"
        "a12 = ixz*iyz - ixy*izz; a13 = ixy*iyz - iyy*ixz; a23 = ixy*ixz - ixx*iyz;"
        f"ixx = inertia_xx + eps; iyy = inertia_yy + eps; izz = inertia_zz + eps;"
        "ixy = inertia_xy; ixz = inertia_xz; iyz = inertia_yz;"
        f"eps = {_INERTIA_REGULARIZATION!r}*sum_inertia"
    )
