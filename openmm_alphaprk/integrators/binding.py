"""What a step program knows of the Context it is bound to, and how it learns it.

OpenMM gives an integrator no handle on its Context, and a ``CustomIntegrator`` may be
bound again (``Context.reinitialize()`` binds it afresh to the Context's System, edited
or not). So nothing about the System is kept on the Python object:

- the **system check** (:meth:`SystemCheckedProgram._add_system_check`), run by the
  program at the first step of each ``step()`` call, counts the degrees of freedom the
  program moves (``ndof``: a sum over degrees of freedom skips particles without mass on
  every platform) and refuses the step when the System has particles without mass the
  step cannot be right for, or more particles than the integrator's per-DOF variables;
- :meth:`SystemCheckedProgram.check_context` is the explicit call for what needs the
  platform: whether virtual sites are placed at every constraint step (CUDA, OpenCL,
  HIP), and the precision behind the energy mode's default tolerance. Its findings
  last while that Context exists (a weak reference), and are taken again when the
  System's particles, forces or constraints change.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import openmm as mm
import openmm.unit as unit

from .. import platforms, start_blowup
from .._units import InputError

#: Degrees of freedom the program moves: 3 × the particles with mass (set by the system check).
NDOF = "ndof"
#: Particles of the System, with or without mass (set from Python before the first step).
N_PARTICLES = "n_particles"
#: What the system check at the next step does: 0 nothing, 1 check and refuse a System with
#: particles without mass, 2 check and allow them (set from Python before each ``step()``).
CHECK_SYSTEM = "check_system"
#: 1 if the system check refused the step, which then does nothing.
REFUSED = "refused"
_NO_CHECK, _CHECK_REFUSING_MASSLESS, _CHECK_ALLOWING_MASSLESS = 0, 1, 2


class IncompatibleSystemError(InputError):
    """Raised when an integrator cannot integrate a system: its step cannot be right for it.

    The one error for "this integrator cannot run this system": particles without mass
    (virtual sites) where the step takes a force at unconstrained positions, or on a
    platform that does not place them inside a step.
    """


class SystemSizeError(RuntimeError):
    """Raised when an integrator bound again runs a System with more particles than its first one."""


@dataclass(frozen=True)
class _CheckedContext:
    """What :meth:`SystemCheckedProgram.check_context` learnt from a Context, and a weak reference to it."""

    context: Callable[[], mm.Context | None]
    platform: str
    fingerprint: tuple[int, int, int]
    massless: tuple[int, ...]


def _fingerprint(system: mm.System) -> tuple[int, int, int]:
    """Particles, forces and constraints: what changes when a System is edited before ``reinitialize()``."""
    return system.getNumParticles(), system.getNumForces(), system.getNumConstraints()


class SystemCheckedProgram(mm.CustomIntegrator):
    """The system check of a step program, :meth:`check_context` and ``step()``: the base of StepProgram."""

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
        self.addComputeGlobal(
            REFUSED,
            f"step({N_PARTICLES} - 0.5)*max(step(massless - 0.5)*step(1.5 - {CHECK_SYSTEM}),"
            f" step(-massless - 0.5)); massless = 3*{N_PARTICLES} - {NDOF}",
        )
        self.addComputeGlobal(CHECK_SYSTEM, str(_NO_CHECK))
        self.endBlock()

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


def check_context(integrator: mm.Integrator, context: mm.Context) -> None:
    """Call ``integrator.check_context(context)`` if it is one of this package's; others need none.

    For code that builds any integrator by name (``openmm.VerletIntegrator`` among them)
    and then its Context.
    """
    if isinstance(integrator, SystemCheckedProgram):
        integrator.check_context(context)
