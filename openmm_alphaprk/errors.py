"""The package's exceptions and warnings: every one on :class:`AlphaPRKError` or :class:`AlphaPRKWarning`.

Each also keeps the builtin class it has always had (``ValueError``, ``RuntimeError``,
``TypeError``, ``UserWarning``, OpenMM's ``OpenMMException``), so ``except RuntimeError``
still catches a :class:`MidpointConvergenceError`, and ``except AlphaPRKError`` catches
whatever this package raises on purpose. The classes are also importable from where they
were defined before (``openmm_alphaprk.integrators.pieces``, ``openmm_alphaprk._units``, …)
and the public ones from ``openmm_alphaprk``.

This module imports nothing of the package: every module may import it.
"""

from __future__ import annotations

import openmm as mm

__all__ = [
    "AlphaPRKError",
    "AlphaPRKWarning",
    "EnergyHoldWarning",
    "IncompatibleSystemError",
    "InputError",
    "InputTypeError",
    "LargeStepWarning",
    "MidpointConvergenceError",
    "NonSmoothForcesWarning",
    "StartBlowUpError",
    "StateChangingForceWarning",
    "SystemSizeError",
    "TimestepUnitWarning",
    "UnconstrainedVelocitiesWarning",
    "VelocityRescaleError",
]


class AlphaPRKError(Exception):
    """The base of every exception this package raises on purpose.

    Each subclass keeps a builtin base too (``ValueError`` for wrong input,
    ``RuntimeError`` for a step that failed, …).

    Examples
    --------
    >>> from openmm_alphaprk import AlphaPRKError, AlphaRattleIntegrator
    >>> try:
    ...     AlphaRattleIntegrator(0.002, alpha=float("nan"))
    ... except AlphaPRKError as error:
    ...     print(type(error).__name__, isinstance(error, ValueError))
    InputError True
    """


class AlphaPRKWarning(UserWarning):
    """The base of every warning this package issues.

    Examples
    --------
    Silence them all, and only them:

    >>> import warnings
    >>> from openmm_alphaprk import AlphaPRKWarning, RattleIntegrator
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("error")
    ...     warnings.simplefilter("ignore", AlphaPRKWarning)
    ...     integrator = RattleIntegrator(2)  # a TimestepUnitWarning: 2 ps
    """


# ---------------------------------------------------------------- exceptions
class InputError(AlphaPRKError, ValueError):
    """A value the user gave is wrong; the message names it and how to fix it."""


class InputTypeError(AlphaPRKError, TypeError):
    """A value the user gave has the wrong type or units; the message names it and how to fix it."""


class IncompatibleSystemError(InputError):
    """Raised when an integrator cannot integrate a system: its step cannot be right for it.

    The one error for "this integrator cannot run this system": particles without mass
    (virtual sites) where the step takes a force at unconstrained positions, or on a
    platform that does not place them inside a step.

    Examples
    --------
    A virtual site between two constrained atoms, and α ≠ 0:

    >>> import openmm
    >>> from openmm_alphaprk import AlphaRattleIntegrator
    >>> system = openmm.System()
    >>> for mass in (39.9, 39.9, 0.0):
    ...     _ = system.addParticle(mass)
    >>> _ = system.addConstraint(0, 1, 0.3)
    >>> system.setVirtualSite(2, openmm.TwoParticleAverageSite(0, 1, 0.5, 0.5))
    >>> integrator = AlphaRattleIntegrator(0.002, alpha=0.1)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0], [0.15, 0, 0]])
    >>> integrator.check_context(context)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.IncompatibleSystemError: AlphaRattleIntegrator with alpha=0.1 ...
    """


class SystemSizeError(AlphaPRKError, RuntimeError):
    """Raised when an integrator bound again runs a System with more particles than its first one.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk import RattleIntegrator
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(39.9)
    >>> integrator = RattleIntegrator(0.002)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0]])
    >>> integrator.step(1)
    >>> _ = system.addParticle(39.9)  # a third atom, then the same integrator
    >>> context.reinitialize()
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0], [0.6, 0, 0]])
    >>> integrator.step(1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.SystemSizeError: RattleIntegrator was first bound to a System of 2 ...
    """


class MidpointConvergenceError(AlphaPRKError, RuntimeError):
    """Raised when the implicit midpoint iteration of α-RATTLE fails to converge.

    Examples
    --------
    A bond far too stiff for the step (|α| h²ω²/4 ≈ 10):

    >>> import openmm
    >>> from openmm_alphaprk import AlphaRattleIntegrator
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(1.0)
    >>> bond = openmm.HarmonicBondForce()
    >>> _ = bond.addBond(0, 1, 0.1, 1e7)
    >>> _ = system.addForce(bond)
    >>> integrator = AlphaRattleIntegrator(0.002, alpha=0.5)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.11, 0, 0]])
    >>> context.setVelocities([[1, 2, 0], [0, 0, 3]])
    >>> integrator.step(1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.MidpointConvergenceError: α-RATTLE midpoint iteration did not ...
    """


class VelocityRescaleError(AlphaPRKError, RuntimeError):
    """Raised when RATTLE + velocity rescaling finds no real factor that makes the total energy E_ref.

    Examples
    --------
    A dimer at rest has no internal kinetic energy to scale:

    >>> import openmm
    >>> from openmm_alphaprk import RattleRescaleIntegrator
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(39.9)
    >>> _ = system.addConstraint(0, 1, 0.3)
    >>> integrator = RattleRescaleIntegrator(0.002)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.3, 0, 0]])
    >>> integrator.step(1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.VelocityRescaleError: no real velocity scale s makes K + V ...
    """


class StartBlowUpError(AlphaPRKError, mm.OpenMMException):
    """The state went to NaN in an integrator's first steps (a start it cannot take).

    The first :data:`~openmm_alphaprk.start_blowup.START_STEPS` steps, where a blow-up is
    almost always the start's fault (:mod:`~openmm_alphaprk.start_blowup`).

    Examples
    --------
    A bond far too stiff for a 2 fs step (ωh ≈ 90):

    >>> import openmm
    >>> from openmm_alphaprk import RattleIntegrator
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(1.0)
    >>> bond = openmm.HarmonicBondForce()
    >>> _ = bond.addBond(0, 1, 0.1, 1e9)
    >>> _ = system.addForce(bond)
    >>> integrator = RattleIntegrator(0.002)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.11, 0, 0]])
    >>> integrator.step(100)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.StartBlowUpError: RattleIntegrator blew up in its first 100 steps, ...
    """


# ---------------------------------------------------------------- warnings
class TimestepUnitWarning(AlphaPRKWarning):
    """A plain-number timestep above 10 fs: OpenMM reads plain numbers in picoseconds.

    Examples
    --------
    >>> import warnings
    >>> from openmm_alphaprk import RattleIntegrator
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     integrator = RattleIntegrator(2)  # meant 2 fs, reads 2 ps
    >>> caught[0].category.__name__
    'TimestepUnitWarning'
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    timestep 2 is a plain number, which OpenMM reads in picoseconds: a step of 2000 fs, ...
    """


class EnergyHoldWarning(AlphaPRKWarning):
    """The energy mode could not hold some steps at E_ref and took them as its base's α = 0 steps.

    Issued by :meth:`~openmm_alphaprk.integrators.AlphaRattleEnergyIntegrator.step` when
    such steps are frequent: once at least
    :data:`~openmm_alphaprk.integrators.energy_mode.ALPHA_ZERO_WARN_STEPS` steps, and
    :data:`~openmm_alphaprk.integrators.energy_mode.ALPHA_ZERO_WARN_FRACTION` of all its
    steps, were α = 0 steps (``controller_totals()["steps_alpha_zero"]``), then each time
    their count has doubled since the last warning. A few such steps are normal where
    the energy is held (a few per cent on water at 2 fs) and are not warned about.

    Examples
    --------
    A bond too stiff for α-RATTLE's midpoint iteration at the α the bounds allow (hω = 1.8
    at 2 fs: RATTLE is stable, the iteration diverges for α above about 1.2) makes every
    step an α = 0 step, RATTLE's:

    >>> import openmm, warnings
    >>> from openmm_alphaprk import AlphaRattleEnergyIntegrator, ControllerSettings
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(1.0)
    >>> bond = openmm.HarmonicBondForce()
    >>> _ = bond.addBond(0, 1, 0.1, 405000.0)
    >>> _ = system.addForce(bond)
    >>> settings = ControllerSettings(alpha_bounds=(1.4, 1.5))
    >>> integrator = AlphaRattleEnergyIntegrator(0.002, controller=settings)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0, 0, 0], [0.11, 0, 0]])
    >>> context.setVelocities([[0, 0, 0], [1, 0, 0]])
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     integrator.step(6)
    >>> caught[0].category.__name__
    'EnergyHoldWarning'
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    the energy-preserving mode could not hold 6 of its 6 steps at E_ref ...
    """


class NonSmoothForcesWarning(AlphaPRKWarning):
    """An energy-mode integrator was given a System whose energy is not smooth.

    What is not smooth, and how to fix it: :func:`~openmm_alphaprk.smooth_forces.smoothness_problems`.

    Examples
    --------
    Issued by the energy mode's ``check_context``, here for a PME System with OpenMM's
    defaults:

    >>> import openmm, warnings
    >>> from openmm_alphaprk import AlphaRattleEnergyIntegrator
    >>> system = openmm.System()
    >>> system.setDefaultPeriodicBoxVectors(openmm.Vec3(3, 0, 0), openmm.Vec3(0, 3, 0), openmm.Vec3(0, 0, 3))
    >>> nonbonded = openmm.NonbondedForce()  # OpenMM's defaults: no switch, Ewald tolerance 5e-4
    >>> nonbonded.setNonbondedMethod(openmm.NonbondedForce.PME)
    >>> for charge in (0.5, -0.5):
    ...     _ = system.addParticle(39.9)
    ...     _ = nonbonded.addParticle(charge, 0.34, 1.0)
    >>> _ = system.addForce(nonbonded)
    >>> integrator = AlphaRattleEnergyIntegrator(0.002)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     integrator.check_context(context)
    >>> caught[0].category.__name__
    'NonSmoothForcesWarning'
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    the energy-preserving mode needs smooth forces; 2 problem(s) found:
      - NonbondedForce (force 0) cuts interactions off at 1 nm without a switching function: ...
      - NonbondedForce (force 0) has an Ewald error tolerance of 0.0005 (OpenMM's default is 5e-4); ...
    See help(openmm_alphaprk.smooth_forces).
    """


class StateChangingForceWarning(AlphaPRKWarning):
    """An energy-mode integrator was given a System with a barostat, Andersen thermostat or CMMotionRemover.

    The energy mode does not apply them (see :func:`~openmm_alphaprk.nve.state_changing_forces`); RATTLE and
    fixed α do.

    Examples
    --------
    Issued by the energy mode's ``check_context``:

    >>> import openmm, warnings
    >>> from openmm_alphaprk import AlphaRattleEnergyIntegrator
    >>> system = openmm.System()
    >>> for _ in range(2):
    ...     _ = system.addParticle(39.9)
    >>> _ = system.addForce(openmm.CMMotionRemover())
    >>> integrator = AlphaRattleEnergyIntegrator(0.002)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     integrator.check_context(context)
    >>> caught[0].category.__name__
    'StateChangingForceWarning'
    >>> print(caught[0].message)  # doctest: +ELLIPSIS
    the energy-preserving mode runs NVE; 1 force(s) of this System change the state between steps and ...
      - CMMotionRemover (force 0): the energy mode does not apply it (...). ...
    See help(openmm_alphaprk.nve).
    """


class LargeStepWarning(AlphaPRKWarning):
    """The step is above what the System's lightest hydrogens allow.

    Why, and what step they allow: :func:`~openmm_alphaprk.nve.step_size_problem`.

    Examples
    --------
    >>> import warnings
    >>> from openmm_alphaprk.nve import LargeStepWarning
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("a 4 fs step with 1 hydrogen(s) of 1.01 amu ...", LargeStepWarning)
    >>> caught[0].category.__name__
    'LargeStepWarning'
    """


class UnconstrainedVelocitiesWarning(AlphaPRKWarning):
    """The velocities E_ref is about to be taken from move along the constraints.

    A Langevin integrator's velocities do (OpenMM's ``LangevinMiddleIntegrator`` leaves about
    0.1 % of the kinetic energy there on a TIP3P box). RATTLE's first step removes those
    components, so the energy of the constrained motion is lower than the start's; an
    integrator that holds the start's energy would put it back into the motion.
    :func:`~openmm_alphaprk.nve.velocity_constraint_energy` measures it, and
    ``context.applyVelocityConstraints(1e-10)`` before the first step removes it.

    Examples
    --------
    Issued by the first ``step()`` after ``check_context``: two atoms on a 0.1 nm
    constraint, one moving towards the other.

    >>> import openmm, warnings
    >>> from openmm_alphaprk import RattleRescaleIntegrator
    >>> system = openmm.System()
    >>> well = openmm.CustomExternalForce("x^2 + y^2 + z^2")
    >>> for i in range(2):
    ...     _ = system.addParticle(16.0)
    ...     _ = well.addParticle(i, [])
    >>> _ = system.addForce(well)
    >>> _ = system.addConstraint(0, 1, 0.1)
    >>> integrator = RattleRescaleIntegrator(0.002)
    >>> context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    >>> context.setVelocities([[0.0, 1.0, 0.0], [-0.1, 1.0, 0.0]])
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     integrator.check_context(context)
    ...     integrator.step(1)
    >>> [w.category.__name__ for w in caught]
    ['UnconstrainedVelocitiesWarning']
    >>> context.setVelocities([[0.0, 1.0, 0.0], [-0.1, 1.0, 0.0]])  # the same start again
    >>> context.applyVelocityConstraints(1e-10)  # the fix: E_ref of the constrained motion
    >>> integrator.reset_reference_energy()
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     integrator.step(1)
    >>> caught
    []
    """
