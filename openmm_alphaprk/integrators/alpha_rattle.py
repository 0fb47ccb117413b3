"""α-RATTLE and its compositions with a fixed α: the whole step programs, and what the energy mode shares.

The classes (the pieces they are built from are in :mod:`~.pieces`)::

    _StepProgram                      pieces.py: common state, pieces, stepping, listing
    ├ RattleIntegrator                rattle.py
    └ _AlphaRattleBase                here: the midpoint iteration's variables and
      │                               properties, step(), the refusal of virtual sites
      ├ AlphaRattleIntegrator         here: a fixed α, one step or a composition
      └ AlphaRattleEnergyIntegrator   energy_mode.py: α chosen every step to hold the energy

The energy mode is its own class, :class:`~.energy_mode.AlphaRattleEnergyIntegrator`
(its programs are in :mod:`~.energy_mode`, its controller in :mod:`~.energy_controller`),
beside the fixed-α class on
the private base :class:`_AlphaRattleBase`; this module does not import it. The two
fixed-α programs (one step, or a composition) are the ``_build_*`` methods below; a
composition's program runs its stages from the first α stage in one loop
(:meth:`~.pieces._StepProgram._add_composition_loop`; the energy mode's loop adds its
trial ends, ``energy_mode``), built from the composition's coefficients
(:mod:`~.compositions`).
"""

from __future__ import annotations

from typing import ClassVar

import openmm.unit as unit

from .._units import InputError, to_dimensionless, to_float
from ..observables import positive_int
from .compositions import Composition, requested_composition
from .pieces import (
    DEFAULT_CONSTRAINT_TOLERANCE,
    _StepProgram,
)
from .variables import (
    ALPHA,
    MIDPOINT_CHANGE,
    MIDPOINT_ITERATIONS,
)

DEFAULT_MIDPOINT_TOLERANCE = 1e-10  # nm, RMS change of x1 per degree of freedom
DEFAULT_MAX_MIDPOINT_ITERATIONS = 20


class _AlphaRattleBase(_StepProgram):
    """What α-RATTLE with a fixed α and its energy mode share (not an integrator of its own).

    The midpoint iteration's variables and options (``midpoint_tolerance``,
    ``max_midpoint_iterations``), the order or composition, :attr:`alpha`,
    :meth:`step` (which raises :class:`~openmm_alphaprk.errors.MidpointConvergenceError`)
    and the refusal of virtual sites where a step takes the midpoint force. A subclass
    adds its program (:meth:`_add_program`) and sets :attr:`energy_mode`.
    """

    #: True if α is chosen each step to hold the energy (:class:`~.energy_mode.AlphaRattleEnergyIntegrator`).
    energy_mode: ClassVar[bool] = False

    def _set_up(
        self,
        timestep: unit.Quantity | float,
        start_alpha: float,
        constraint_tolerance: float,
        midpoint_tolerance: unit.Quantity | float,
        max_midpoint_iterations: int,
        order: int,
        composition: Composition | None,
    ) -> None:
        """Check the shared options, declare the variables, add the subclass's program."""
        self._composition = composition
        tolerance = to_float(midpoint_tolerance, unit.nanometers, "midpoint_tolerance", positive=True)
        max_iterations = positive_int(max_midpoint_iterations, "max_midpoint_iterations")
        _StepProgram.__init__(self, timestep, constraint_tolerance)
        self._add_midpoint_variables(start_alpha, tolerance, max_iterations, order, composition)
        self._add_program()

    def _add_program(self) -> None:
        """Add the step program (after the midpoint variables)."""
        raise NotImplementedError

    def step(self, steps: int) -> None:
        """Advance by ``steps`` steps; raise if the midpoint iteration failed on the way.

        Raises
        ------
        MidpointConvergenceError
            If the midpoint iteration did not converge (|α| h²ω²/4 ≳ 1, a tolerance
            below the platform's precision, or non-finite forces or energies). The
            context is left at the start of the failed step.
        IncompatibleSystemError
            If the system has massless particles (virtual sites) and α ≠ 0, the
            energy mode, a platform that places virtual sites only at the end of a
            step (Reference, CPU), or a platform not shown to :meth:`check_context`.
        SystemSizeError
            If the integrator, bound again, runs a System with more particles than
            the first one it was bound to.
        StartBlowUpError
            If the state went to NaN in the first 100 steps (:mod:`openmm_alphaprk.start_blowup`).
        """
        failures = self._midpoint_failures()
        super().step(steps)
        self._raise_if_midpoint_failed(failures)

    def _massless_refusal(self, count: int, platform: str | None) -> str | None:
        if count and (self.energy_mode or self.alpha != 0.0):
            return self._midpoint_force_refusal(
                count, "the energy mode" if self.energy_mode else f"alpha={self.alpha}"
            )
        return super()._massless_refusal(count, platform)

    # -------------------------------------------------------------- parameters
    @property
    def alpha(self) -> float:
        """The method parameter α; may be changed between steps.

        In the energy mode: α* of the last step, and setting it sets the α the next
        step's controller starts from.
        """
        return self.getGlobalVariableByName(ALPHA)

    @alpha.setter
    def alpha(self, value: float) -> None:
        self.setGlobalVariableByName(ALPHA, to_dimensionless(value, "alpha"))

    @property
    def midpoint_tolerance(self) -> unit.Quantity:
        """Stopping tolerance of the midpoint iteration (RMS change of x1 per DOF)."""
        return self.getGlobalVariableByName("midpoint_tolerance") * unit.nanometers

    @midpoint_tolerance.setter
    def midpoint_tolerance(self, value: unit.Quantity | float) -> None:
        tolerance = to_float(value, unit.nanometers, "midpoint_tolerance", positive=True)
        self.setGlobalVariableByName("midpoint_tolerance", tolerance)
        if self.energy_mode:  # the user's choice: not changed for the system
            self.setGlobalVariableByName("midpoint_tolerance_automatic", 0)

    @property
    def max_midpoint_iterations(self) -> int:
        """Cap on midpoint force evaluations per step."""
        return int(self.getGlobalVariableByName("max_midpoint_iterations"))

    @max_midpoint_iterations.setter
    def max_midpoint_iterations(self, value: int) -> None:
        self.setGlobalVariableByName(
            "max_midpoint_iterations", positive_int(value, "max_midpoint_iterations")
        )

    @property
    def midpoint_iterations(self) -> int:
        """Midpoint force evaluations used in the last step (0 at α = 0)."""
        return int(self.getGlobalVariableByName(MIDPOINT_ITERATIONS))

    @property
    def midpoint_change(self) -> unit.Quantity:
        """RMS change of x1 in the last midpoint iteration of the last step."""
        return self.getGlobalVariableByName(MIDPOINT_CHANGE) * unit.nanometers

    @property
    def order(self) -> int:
        """2 (the α-RATTLE step), or the order of the composition at α = 0 (4, 6)."""
        return int(self.getGlobalVariableByName("order"))

    def __repr__(self) -> str:
        chosen = self.composition
        extra = "" if self.energy_mode else f", alpha={self.alpha}"
        if chosen is not None:
            extra += f", composition={chosen.name!r}"
            if chosen.alpha_stages != chosen.with_alpha_on("middle").alpha_stages:
                extra += f", alpha_stages={chosen.alpha_stages}"
        return f"{type(self).__name__}(timestep={self.timestep}{extra})"


class AlphaRattleIntegrator(_AlphaRattleBase):
    """α-RATTLE with a fixed α: a one-parameter family of symplectic constrained integrators.

    The potential is integrated along the straight path x0 → x1 with weights
    (½−α, 2α, ½−α) at (0, ½, 1); α = 0 is RATTLE. For every fixed α the map is
    symplectic on the constraint manifold, symmetric, keeps the constraints and
    quadratic invariants (linear and angular momentum), and is of order 2
    (Li & Wang, J. Comput. Math. 41, 2023).

    With ``order=4`` or ``6``, or a ``composition``, the step is a symmetric composition
    of such steps (:mod:`~.compositions`), α on its middle stage unless ``alpha_stages``
    says otherwise. ``AlphaRattleIntegrator(h, alpha=0.0, order=4)`` (``alpha4=0`` on the
    command line) is Suzuki's fourth-order composition of RATTLE steps. The energy mode,
    which chooses α every step to hold the total energy, is
    :class:`~.energy_mode.AlphaRattleEnergyIntegrator`.

    :meth:`program_listing` prints the step program OpenMM runs; docs/step_programs.md
    lists every configuration's.

    Parameters
    ----------
    timestep : openmm.unit.Quantity or float
        Step size (a time Quantity, or a number in picoseconds).
    alpha : float, default 0.0
        The method parameter α (a finite number). α = 0 takes the RATTLE path with one
        force evaluation per step; α ≠ 0 needs the implicit midpoint force.
    constraint_tolerance : float, default 1e-8
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    midpoint_tolerance : openmm.unit.Quantity or float, optional
        The midpoint iteration stops when the change that the last midpoint force
        makes to the next solve of x1, h²α ΔF/m, falls below this (nm, RMS per degree
        of freedom). Default 1e-10 nm: symplectic to that level.
    max_midpoint_iterations : int, default 20
        Cap on midpoint force evaluations per step.
    order : {2, 4, 6}, optional
        2 (default): the α-RATTLE step. 4: Suzuki's five stages (p, p, 1 − 4p, p, p),
        p = 1/(4 − 4^{1/3}): fourth order at α = 0 (five force evaluations per step),
        second order at a fixed α ≠ 0 on one stage. Its sub-steps are 0.41h and −0.66h.
        6: McLachlan's nine stages. ``docs/compositions.md`` has the measurements
        behind the defaults.
    composition : str or Composition, optional
        A name of :data:`~.compositions.COMPOSITIONS` (``"triple-jump"``, three stages
        1.35h, −1.70h, 1.35h; ``"suzuki5"``, ``"mclachlan5"``, ``"yoshida7"``,
        ``"kahan-li-s9odr6a"``, ``"mclachlan9"``) or a
        :class:`~.compositions.Composition`; sets the order.
    alpha_stages : {"middle", "all"} or tuple of int, optional
        The stages of a composition that carry α: ``"middle"`` (default), ``"all"`` or
        stage numbers (1-based). With α on every stage a fixed α keeps the
        composition's order (it composes one symmetric second-order method).

    Raises
    ------
    openmm_alphaprk.errors.IncompatibleSystemError
        From :meth:`check_context` or the first step, for a System the program cannot
        integrate (virtual sites with α ≠ 0).

    See Also
    --------
    RattleIntegrator : α = 0 as its own class.
    AlphaRattleEnergyIntegrator : α chosen every step to hold the energy.
    RattleRescaleIntegrator : RATTLE (or a composition) with velocity rescaling.

    Notes
    -----
    Where the force is constant, every member of the family is the same map as
    RATTLE: α acts only through how the force varies along the step.

    Each step starts with OpenMM's update-context-state step, as a ``VerletIntegrator``
    step does: a Monte Carlo barostat, an ``AndersenThermostat`` or a
    ``CMMotionRemover`` acts as it does there. :meth:`check_context` warns about
    forces that are not smooth.

    Examples
    --------
    Suzuki's composition of RATTLE steps (``alpha4=0``), then one α-RATTLE step with
    α = 0.1, on two constrained argon atoms:

    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import AlphaRattleIntegrator
    >>> integrator = AlphaRattleIntegrator(2 * unit.femtoseconds, alpha=0.0, order=4)
    >>> integrator
    AlphaRattleIntegrator(timestep=0.002 ps, alpha=0.0, composition='suzuki5')
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(39.9)
    >>> _ = system.addConstraint(0, 1, 0.3)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0]])
    >>> context.setVelocities([[0, 0.1, 0], [0, -0.1, 0]])
    >>> integrator.step(10)
    >>> integrator.alpha = 0.1  # between steps: the program reads α each step
    >>> integrator.step(10)
    >>> x = context.getState(getPositions=True).getPositions(asNumpy=True)
    >>> round(float(((x[1] - x[0]) ** 2).sum().value_in_unit(unit.nanometers**2) ** 0.5), 9)  # kept
    0.3
    """

    def __init__(
        self,
        timestep: unit.Quantity | float,
        *,
        alpha: float = 0.0,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
        midpoint_tolerance: unit.Quantity | float | None = None,
        max_midpoint_iterations: int = DEFAULT_MAX_MIDPOINT_ITERATIONS,
        order: int | None = None,
        composition: str | Composition | None = None,
        alpha_stages: str | tuple[int, ...] | None = None,
    ) -> None:
        if isinstance(alpha, str):
            raise InputError(_energy_mode_refusal(alpha))
        order, chosen = _order_and_composition(order, composition, alpha_stages)
        self._set_up(
            timestep,
            to_dimensionless(alpha, "alpha"),
            constraint_tolerance,
            DEFAULT_MIDPOINT_TOLERANCE if midpoint_tolerance is None else midpoint_tolerance,
            max_midpoint_iterations,
            order,
            chosen,
        )

    def _add_program(self) -> None:
        """Add the fixed-α program, starting with the update-context-state step."""
        build = self._build_program if self._composition is None else self._build_composition_program
        self._add_step(build, update_context_state=True)

    # ---------------------------------------------------------------- programs
    def _build_program(self) -> None:
        """Order 2, fixed α: the α-RATTLE step (:meth:`~.pieces._StepProgram._add_alpha_step`)."""
        self._add_save_step_start(fstart="f", fmid="f")
        self._add_alpha_step(None)
        self._add_midpoint_end_step()

    def _build_composition_program(self) -> None:
        """Build a composition with fixed α: its stages before the first α stage, then a loop over the rest.

        For the triple jump: RATTLE (γ1 h), then the loop over α-RATTLE (γ2 h) and
        RATTLE (γ1 h). Every stage after the first α stage is inside the loop, before
        its midpoint block, so that its position constraint precedes the midpoint
        assignment in program text. A failed midpoint iteration makes every remaining
        sub-step return the state the step started from.
        """
        self._add_save_step_start(xstep="x", vstep="v", fstart="f")
        self._add_alpha_step(self._composition)
        self._add_midpoint_end_step()


def _order_and_composition(
    order: object, name: str | Composition | None, alpha_stages: str | tuple[int, ...] | None
) -> tuple[int, Composition | None]:
    """Return the order and the composition (None: one α-RATTLE step) that the options ask for."""
    chosen = requested_composition(order, name)
    if chosen is None:
        if alpha_stages is not None:
            raise InputError("alpha_stages applies to a composition; give order=4 or 6, or a composition.")
        return 2, None
    if alpha_stages is not None:
        chosen = chosen.with_alpha_on(alpha_stages)
    return chosen.order, chosen


def _energy_mode_refusal(alpha: str) -> str:
    """Return the message for a string ``alpha``: the energy mode is its own class."""
    if alpha == "energy":
        return (
            "alpha='energy' asks for the energy mode, which is its own class: use "
            "AlphaRattleEnergyIntegrator(timestep, order=4, ...) (from openmm_alphaprk import "
            "AlphaRattleEnergyIntegrator); AlphaRattleIntegrator takes a number."
        )
    return f"alpha must be a number (the method parameter), got {alpha!r}."
