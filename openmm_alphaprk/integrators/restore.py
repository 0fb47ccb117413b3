"""Give an integrator that OpenMM handed back as a plain ``CustomIntegrator`` its class again."""

from __future__ import annotations

import openmm as mm

from .._units import InputTypeError
from .alpha_rattle import AlphaRattleIntegrator
from .energy_mode import AlphaRattleEnergyIntegrator
from .pieces import _StepProgram
from .rattle import RattleIntegrator
from .rescale import RattleRescaleIntegrator
from .splitting_rattle import SplittingRattleIntegrator
from .variables import KIND_VARIABLE, REFERENCE_ENERGY, program_kind

#: This package's integrator classes: ``isinstance(integrator, PACKAGE_INTEGRATORS)`` tells an
#: integrator that counts its force evaluations from one that does not (``openmm.VerletIntegrator``).
PACKAGE_INTEGRATORS = (
    RattleIntegrator,
    RattleRescaleIntegrator,
    AlphaRattleIntegrator,
    AlphaRattleEnergyIntegrator,
    SplittingRattleIntegrator,
)

#: The classes a program's kind names (:func:`~.variables.program_kind`), and the numbers that
#: programs written before it kept (1–4; 2 also for the energy mode, told apart by E_ref).
_CLASSES_BY_KIND: dict[int, type[_StepProgram]] = {}
_LEGACY_KINDS: dict[int, type[_StepProgram]] = {
    1: RattleIntegrator,
    2: AlphaRattleIntegrator,
    3: RattleRescaleIntegrator,
    4: SplittingRattleIntegrator,
}


def register_integrator_class(cls: type[_StepProgram]) -> type[_StepProgram]:
    """Let :func:`restore_integrator` give ``cls`` back to its programs (a subclass made elsewhere)."""
    _CLASSES_BY_KIND[program_kind(cls)] = cls
    return cls


for _cls in PACKAGE_INTEGRATORS:
    register_integrator_class(_cls)


def counted_force_evaluations(integrator: mm.Integrator) -> int | None:
    """Return the force evaluations this package's integrator has counted; None for any other.

    Parameters
    ----------
    integrator : openmm.Integrator
        Any integrator.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk import RattleIntegrator
    >>> from openmm_alphaprk.integrators import counted_force_evaluations
    >>> counted_force_evaluations(RattleIntegrator(0.002))  # none yet: no step taken
    0
    >>> counted_force_evaluations(openmm.VerletIntegrator(0.002)) is None
    True
    """
    return integrator.force_evaluations if isinstance(integrator, PACKAGE_INTEGRATORS) else None


def force_evaluations_per_step(integrator: mm.Integrator) -> float:
    """Return the mean force evaluations per step: counted by ours, one for others (``VerletIntegrator``).

    Parameters
    ----------
    integrator : openmm.Integrator
        Any integrator.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk import AlphaRattleIntegrator
    >>> from openmm_alphaprk.integrators import force_evaluations_per_step
    >>> from openmm_alphaprk.systems import prepare_system
    >>> cluster = prepare_system("water-cluster")
    >>> suzuki = AlphaRattleIntegrator(0.002, alpha=0.0, order=4)  # five RATTLE sub-steps
    >>> context = openmm.Context(cluster.system, suzuki, openmm.Platform.getPlatformByName("CPU"))
    >>> context.setState(cluster.state)
    >>> suzuki.step(2)
    >>> force_evaluations_per_step(suzuki), force_evaluations_per_step(openmm.VerletIntegrator(0.002))
    (5.0, 1.0)
    """
    return integrator.force_evaluations_per_step if isinstance(integrator, PACKAGE_INTEGRATORS) else 1.0


def restore_integrator(
    integrator: mm.Integrator,
) -> RattleIntegrator | RattleRescaleIntegrator | AlphaRattleIntegrator | SplittingRattleIntegrator:
    """Give a deserialized or ``Context.getIntegrator()`` object its Python class back.

    ``XmlSerializer.deserialize`` and ``Context.getIntegrator`` return a plain
    ``openmm.CustomIntegrator``. This function recognises integrators made by this
    package (by the global variable :data:`~.variables.KIND_VARIABLE`) and changes the class of
    the same object in place, so it stays bound to its context.

    Parameters
    ----------
    integrator : openmm.Integrator
        An integrator object.

    Returns
    -------
    RattleIntegrator or RattleRescaleIntegrator or AlphaRattleIntegrator
        The same object, now an instance of :class:`~.rattle.RattleIntegrator`,
        :class:`~.rescale.RattleRescaleIntegrator`, :class:`~.alpha_rattle.AlphaRattleIntegrator`,
        :class:`~.splitting_rattle.SplittingRattleIntegrator`
        or (a program of the energy mode) :class:`~.energy_mode.AlphaRattleEnergyIntegrator`.

    Raises
    ------
    TypeError
        If ``integrator`` was not made by this package.

    Examples
    --------
    An integrator read back from XML (as from a saved simulation):

    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import AlphaRattleIntegrator, restore_integrator
    >>> xml = openmm.XmlSerializer.serialize(AlphaRattleIntegrator(2 * unit.femtoseconds, alpha=0.1, order=4))
    >>> plain = openmm.XmlSerializer.deserialize(xml)
    >>> type(plain).__name__
    'CustomIntegrator'
    >>> restore_integrator(plain)
    AlphaRattleIntegrator(timestep=0.002 ps, alpha=0.1, composition='suzuki5')
    >>> plain.alpha  # the same object, with its class back
    0.1
    """
    if isinstance(integrator, _StepProgram):
        return integrator
    kind, names = None, []
    if isinstance(integrator, mm.CustomIntegrator):
        names = [integrator.getGlobalVariableName(i) for i in range(integrator.getNumGlobalVariables())]
        if KIND_VARIABLE in names:
            kind = int(integrator.getGlobalVariableByName(KIND_VARIABLE))
    if kind not in _CLASSES_BY_KIND and kind not in _LEGACY_KINDS:
        raise InputTypeError(
            f"{type(integrator).__name__} object was not created by openmm_alphaprk "
            f"(no global variable {KIND_VARIABLE!r} with a known value); cannot restore it."
        )
    cls = _CLASSES_BY_KIND.get(kind) or _LEGACY_KINDS[kind]
    if kind == 2 and REFERENCE_ENERGY in names:  # a program from before the kinds were names
        cls = AlphaRattleEnergyIntegrator
    integrator.__class__ = cls
    return integrator  # type: ignore[return-value]
