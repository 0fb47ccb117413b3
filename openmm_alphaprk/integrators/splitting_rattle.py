"""The explicit α-family: α-RATTLE's quadrature as a kick-drift splitting with constraints.

α-RATTLE's step takes its forces with the weights (½−α, 2α, ½−α) at (0, ½, 1), the middle
one at the implicit midpoint x_m = (x0 + x1)/2. The splitting::

    kick((½−α)h) · drift(h/2) · kick(2αh) · drift(h/2) · kick((½−α)h)

with SHAKE/SETTLE and the velocity correction after each drift and RATTLE's projection
after each kick, takes the same weights at the same times with the middle force at the
explicit half-drift point x_½ = x0 + (h/2)(v0 + (½−α)h M⁻¹F0). It is symplectic,
symmetric, second order, keeps the constraints and the momenta, and costs two force
evaluations per step, with no iteration. α = ¼ is two RATTLE steps of h/2; the
minimum-error member (α = 0.306817) and Blanes, Casas & Sanz-Serna's (α = 0.288219),
and the three-stage sets, are in :mod:`~.splittings`.

The program is a sequence of constrained sub-steps (:meth:`~.splittings.Splitting.substeps`),
each a position solve followed by its constraint step and a velocity update with its
projection, built from the pieces RATTLE's step is built from
(:meth:`~.pieces._StepProgram._add_substeps`, the emitter of every explicit base step).
Every force is read after the
constraint step of the positions it is taken at, and each solve projects along the
positions of the previous constraint step, the sub-step's start: the program is the same
map on Reference, CPU and the common platform (CUDA, OpenCL, HIP), and virtual sites are
placed before every force there, as for RATTLE.
"""

from __future__ import annotations

import openmm.unit as unit

from .._units import InputError, to_dimensionless
from .pieces import DEFAULT_CONSTRAINT_TOLERANCE, _StepProgram
from .splittings import MINIMUM_ERROR2, SPLITTINGS, Splitting, two_stage
from .splittings import splitting as named_splitting


def requested_splitting(alpha: float | None, chosen: str | Splitting | None) -> Splitting:
    """Return the splitting ``alpha`` or ``splitting`` ask for (neither: the minimum-error two-stage one)."""
    if alpha is not None and chosen is not None:
        raise InputError("give alpha (the two-stage member) or splitting (a named set), not both.")
    if chosen is not None:
        return named_splitting(chosen)
    if alpha is None:
        return MINIMUM_ERROR2
    if isinstance(alpha, str):
        raise InputError(f"alpha must be a number, got {alpha!r}.")
    value = to_dimensionless(alpha, "alpha")
    return SPLITTINGS.find(lambda known: known.alpha == value) or two_stage(value)


class SplittingRattleIntegrator(_StepProgram):
    """The explicit α-family: α-RATTLE's quadrature as a kick-drift splitting with constraints.

    Each step is kick((½−α)h) · drift(h/2) · kick(2αh) · drift(h/2) · kick((½−α)h) (or a
    three-stage splitting, ``splitting=``), with SHAKE/SETTLE and the velocity correction
    after each drift and RATTLE's velocity projection after each kick. Symplectic,
    symmetric, second order, the constraints and the momenta kept; s force evaluations per
    step for s stages (the last kick's force is the next step's first), no iteration.
    Velocities are at the full step. Its step program, as OpenMM runs it:
    :meth:`program_listing`, and docs/step_programs.md; the family, its members and what
    they measured: docs/splitting.md.

    α = ¼ is two RATTLE steps of h/2; the default, α = 0.306817, is the minimum-error
    two-stage splitting (McLachlan 1995), which minimises the leading energy error term at
    the same two force evaluations but has a shorter stability interval than two RATTLE
    steps of h/2 on a harmonic oscillator (:meth:`~.splittings.Splitting.stability_limit`
    computes it); the numbers, and what it measured against RATTLE, are in docs/splitting.md.

    Each step starts with OpenMM's update-context-state step, as a ``VerletIntegrator``
    step does. Every force is taken at constrained positions, so virtual sites are right on
    CUDA, OpenCL and HIP (after :meth:`check_context`), as for RATTLE.

    Parameters
    ----------
    timestep : openmm.unit.Quantity or float
        Step size h (a time Quantity, or a number in picoseconds).
    alpha : float, optional
        α of the two-stage member (kicks ½−α, 2α, ½−α). Default, with no ``splitting``:
        the minimum-error α = 0.3068166724962164.
    constraint_tolerance : float, default 1e-8
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    splitting : str or Splitting, optional
        A named splitting of :data:`~openmm_alphaprk.integrators.splittings.SPLITTINGS`
        (``"me2"``, ``"bcss2"``, ``"me3"``, ``"bcss3"``, ``"rattle/2"``, ``"rattle/3"``) or a
        :class:`~openmm_alphaprk.integrators.splittings.Splitting`, instead of ``alpha``.

    Raises
    ------
    InputError
        For both ``alpha`` and ``splitting``, an α that is not a finite number, or an
        unknown splitting.

    See Also
    --------
    RattleIntegrator : one RATTLE step, one force evaluation.
    AlphaRattleIntegrator : the implicit family, with the force at the midpoint x_m.

    Examples
    --------
    Two argon atoms held 0.3 nm apart, spinning, with a spring to a third:

    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import SplittingRattleIntegrator
    >>> integrator = SplittingRattleIntegrator(2 * unit.femtoseconds)
    >>> integrator
    SplittingRattleIntegrator(timestep=0.002 ps, splitting='me2')
    >>> round(integrator.alpha, 6)
    0.306817
    >>> SplittingRattleIntegrator(0.002, alpha=0.25).splitting.substeps()  # RATTLE at h/2, twice
    ((0.5, 0.5, 0.5), (0.5, 0.5, 0.5))
    >>> system = openmm.System()
    >>> for _ in range(3):
    ...     _ = system.addParticle(39.9)
    >>> _ = system.addConstraint(0, 1, 0.3)
    >>> spring = openmm.HarmonicBondForce()
    >>> _ = spring.addBond(1, 2, 0.4, 1000.0)
    >>> _ = system.addForce(spring)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0], [0.7, 0.05, 0]])
    >>> context.setVelocities([[0, 0.5, 0], [0, -0.5, 0], [0, 0, 0]])
    >>> integrator.step(100)
    >>> x = context.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(unit.nanometers)
    >>> round(float(((x[1] - x[0]) ** 2).sum() ** 0.5), 8)  # the constraint, kept
    0.3
    >>> integrator.force_evaluations_per_step
    2.0
    >>> print(integrator.program_listing().splitlines()[0])
      0  update context state
    """

    def __init__(
        self,
        timestep: unit.Quantity | float,
        *,
        alpha: float | None = None,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
        splitting: str | Splitting | None = None,
    ) -> None:
        self._splitting = requested_splitting(alpha, splitting)
        super().__init__(timestep, constraint_tolerance)
        self._add_record(self._splitting)
        self._add_step(self._build_program, update_context_state=True)

    def _build_program(self) -> None:
        """Add the splitting's sub-steps from the step's start, F(x0) the cached force."""
        self._add_save_step_start()
        self._add_substeps(self._splitting.substeps())
        self._add_end_step()

    @property
    def splitting(self) -> Splitting:
        """The splitting the program is made of (read back from the program's globals when restored)."""
        if "_splitting" in vars(self):
            return self._splitting
        found = self._recorded(Splitting, SPLITTINGS)
        if found is None:  # pragma: no cover - every program of this class records one
            raise InputError("this program records no splitting.")
        return found

    @property
    def alpha(self) -> float | None:
        """α of a two-stage splitting (½ − its first kick); None for three stages."""
        return self.splitting.alpha

    def __repr__(self) -> str:
        return f"{type(self).__name__}(timestep={self.timestep}, splitting={self.splitting.name!r})"
