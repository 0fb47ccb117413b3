"""Smooth forces and an NVE System, the energy mode's preconditions: checked, reported and fixed.

The energy mode chooses α every step so that the total energy returns to E_ref. It can
only do so if the energy is a smooth function of the positions. With OpenMM's default
cutoff settings it is not: the Lennard-Jones energy jumps when a pair crosses the
cutoff, and PME's default error tolerance (5e-4) adds noise of the same size. On a
water box those jumps made up RATTLE's whole energy error, which did not shrink with h,
and the energy mode cannot remove them.

:func:`smoothness_problems` lists what is not smooth in a System, :func:`make_smooth`
fixes the nonbonded settings in place, and :func:`warn_if_not_smooth` issues a
:class:`NonSmoothForcesWarning` for them (from the energy mode's ``check_context``).
The forces that change the state between steps, and :func:`~openmm_alphaprk.nve.prepare_for_nve`,
are in :mod:`openmm_alphaprk.nve`.
"""

from __future__ import annotations

import os
import sys
import warnings

import openmm as mm
import openmm.unit as unit

from ._units import InputError, to_dimensionless, to_float
from .errors import NonSmoothForcesWarning  # defined there; importable from here too

__all__ = [
    "DEFAULT_SWITCH_WIDTH",
    "SMOOTH_EWALD_TOLERANCE",
    "NonSmoothForcesWarning",
    "make_smooth",
    "polarizable_forces",
    "smoothness_problems",
    "warn_if_not_smooth",
]

#: Width of the Lennard-Jones switching region make_smooth sets up (nm).
DEFAULT_SWITCH_WIDTH = 0.1
#: The loosest Ewald/PME/LJPME error tolerance the energy mode accepts (OpenMM's default: 5e-4).
SMOOTH_EWALD_TOLERANCE = 1e-5

_EWALD_METHODS = (mm.NonbondedForce.Ewald, mm.NonbondedForce.PME, mm.NonbondedForce.LJPME)
_FIX_NONBONDED = "call openmm_alphaprk.make_smooth(system) before creating the Context"
_SMALL = 1e-12  # nm: switching distances this close count as equal (round-off of cutoff − width)


def label_force(index: int, force: mm.Force) -> str:
    """``NonbondedForce (force 3)``, with the force's name if it is not its class name."""
    kind, name = type(force).__name__, force.getName()
    return f"{kind} (force {index})" if name == kind else f"{kind} {name!r} (force {index})"


def _has_cutoff(force: mm.Force) -> bool:
    if isinstance(force, mm.NonbondedForce):
        return force.getNonbondedMethod() != mm.NonbondedForce.NoCutoff
    if isinstance(force, mm.CustomNonbondedForce):
        return force.getNonbondedMethod() != mm.CustomNonbondedForce.NoCutoff
    return False


def _nm(quantity: unit.Quantity | float) -> float:
    return quantity.value_in_unit(unit.nanometers) if unit.is_quantity(quantity) else float(quantity)


def polarizable_forces(system: mm.System) -> list[str]:
    """List the forces whose energy is converged to a tolerance, not a smooth function of the positions.

    Drude particles (``DrudeForce``) and AMOEBA's or HIPPO's mutual induced dipoles are
    found by an iteration (OpenMM's self-consistent solvers, or a Drude integrator's),
    stopped at a tolerance: the energy holds their error, and the energy mode, which
    chooses α to put H back to E_ref, would chase that error.
    """
    found = []
    for index, force in enumerate(system.getForces()):
        name = type(force).__name__
        if name == "DrudeForce":
            found.append(f"{label_force(index, force)}: Drude particles")
        elif name == "AmoebaMultipoleForce" and force.getPolarizationType() == force.Mutual:
            found.append(f"{label_force(index, force)}: mutual induced dipoles (AMOEBA)")
        elif name == "HippoNonbondedForce":
            found.append(f"{label_force(index, force)}: induced dipoles (HIPPO)")
    return found


def smoothness_problems(system: mm.System) -> list[str]:
    """List what keeps the energy of ``system`` from being a smooth function of the positions.

    Parameters
    ----------
    system : openmm.System
        The System to check (not changed).

    Returns
    -------
    list of str
        One message per problem, each naming the force, the setting and the fix;
        empty if there is none. Reported: a ``NonbondedForce`` or
        ``CustomNonbondedForce`` with a cutoff and no switching function; an
        Ewald/PME/LJPME error tolerance above 1e-5. Forces that change the state
        between steps are listed by :func:`state_changing_forces` instead.

    Examples
    --------
    >>> import openmm
    >>> from openmm_alphaprk import smoothness_problems
    >>> system = openmm.System()
    >>> system.setDefaultPeriodicBoxVectors(openmm.Vec3(3, 0, 0), openmm.Vec3(0, 3, 0), openmm.Vec3(0, 0, 3))
    >>> nonbonded = openmm.NonbondedForce()  # OpenMM's defaults: no switch, Ewald tolerance 5e-4
    >>> nonbonded.setNonbondedMethod(openmm.NonbondedForce.PME)
    >>> for charge in (0.5, -0.5):
    ...     _ = system.addParticle(39.9)
    ...     _ = nonbonded.addParticle(charge, 0.34, 1.0)
    >>> _ = system.addForce(nonbonded)
    >>> for problem in smoothness_problems(system):
    ...     print(problem)  # doctest: +ELLIPSIS
    NonbondedForce (force 0) cuts interactions off at 1 nm without a switching function: ...
    NonbondedForce (force 0) has an Ewald error tolerance of 0.0005 (OpenMM's default is 5e-4); ...
    >>> from openmm_alphaprk.systems import prepare_system
    >>> smoothness_problems(prepare_system("tip3p-2nm").system)  # the package's systems are smooth
    []
    """
    problems = []
    for index, force in enumerate(system.getForces()):
        label = label_force(index, force)
        if _has_cutoff(force) and not force.getUseSwitchingFunction():
            cutoff = _nm(force.getCutoffDistance())
            problems.append(
                f"{label} cuts interactions off at {cutoff:g} nm without a switching function: the "
                "energy jumps whenever a pair crosses the cutoff, an error that does not shrink with the "
                "step and that no choice of α can remove (unless the energy expression of a custom force "
                f"already goes smoothly to zero there). Fix: {_FIX_NONBONDED}, which switches it off over "
                f"the last {DEFAULT_SWITCH_WIDTH:g} nm."
            )
        if isinstance(force, mm.NonbondedForce) and force.getNonbondedMethod() in _EWALD_METHODS:
            tolerance = force.getEwaldErrorTolerance()
            if tolerance > SMOOTH_EWALD_TOLERANCE:
                problems.append(
                    f"{label} has an Ewald error tolerance of {tolerance:g} (OpenMM's default is 5e-4); "
                    "its reciprocal-space error adds noise to every energy the energy mode aims at. Fix: "
                    f"{_FIX_NONBONDED}, or setEwaldErrorTolerance({SMOOTH_EWALD_TOLERANCE:g})."
                )
    return problems


def make_smooth(
    system: mm.System,
    switch_width: unit.Quantity | float | None = DEFAULT_SWITCH_WIDTH * unit.nanometers,
    ewald_error_tolerance: float | None = SMOOTH_EWALD_TOLERANCE,
) -> list[str]:
    """Make the nonbonded forces of ``system`` smooth at the cutoff, in place.

    For every ``NonbondedForce`` and ``CustomNonbondedForce`` with a cutoff the
    Lennard-Jones (custom: the whole) interaction is switched off between
    cutoff − ``switch_width`` and the cutoff, unless it already is switched from that
    distance or closer in. A ``NonbondedForce`` with Ewald, PME or LJPME gets the
    error tolerance ``ewald_error_tolerance`` if its own is looser. Nothing else is
    changed; forces without a cutoff are left alone.

    Parameters
    ----------
    system : openmm.System
        The System to change (before creating a Context from it: an existing Context
        does not see the change).
    switch_width : openmm.unit.Quantity or float or None, default 0.1 nm
        Width of the switching region (Quantity or nm); None leaves switching
        functions as they are.
    ewald_error_tolerance : float or None, default 1e-5
        The loosest Ewald error tolerance to keep; None leaves it.

    Returns
    -------
    list of str
        One line per change made (force index and name, old → new value); empty if
        the System already was smooth.

    Raises
    ------
    ValueError
        If cutoff − ``switch_width`` ≤ 0 for some force (nothing is changed then).

    Examples
    --------
    >>> import openmm, openmm.unit as unit
    >>> from openmm_alphaprk import make_smooth
    >>> system = openmm.System()
    >>> system.setDefaultPeriodicBoxVectors(openmm.Vec3(3, 0, 0), openmm.Vec3(0, 3, 0), openmm.Vec3(0, 0, 3))
    >>> nonbonded = openmm.NonbondedForce()  # OpenMM's defaults: no switch, Ewald tolerance 5e-4
    >>> nonbonded.setNonbondedMethod(openmm.NonbondedForce.PME)
    >>> for charge in (0.5, -0.5):
    ...     _ = system.addParticle(39.9)
    ...     _ = nonbonded.addParticle(charge, 0.34, 1.0)
    >>> _ = system.addForce(nonbonded)
    >>> for change in make_smooth(system, switch_width=0.2 * unit.nanometers):
    ...     print(change)
    NonbondedForce (force 0): no switching function → switching from 0.8 nm (cutoff 1 nm)
    NonbondedForce (force 0): Ewald error tolerance 0.0005 → 1e-05
    >>> make_smooth(system)  # already switched from 0.8 nm, closer in than 0.9 nm
    []
    """
    width = None
    if switch_width is not None:
        width = to_float(switch_width, unit.nanometers, "switch_width", positive=True)
    tolerance = None
    if ewald_error_tolerance is not None:
        tolerance = to_dimensionless(ewald_error_tolerance, "ewald_error_tolerance", positive=True)
    forces = [(i, f) for i, f in enumerate(system.getForces()) if _has_cutoff(f)]
    if width is not None:  # check every force before changing any
        for index, force in forces:
            _check_switch_width(index, force, width)
    changes = []
    for index, force in forces:
        if width is not None:
            changes.extend(_switch(index, force, width))
        if tolerance is not None:
            changes.extend(_tighten_ewald(index, force, tolerance))
    return changes


def _check_switch_width(index: int, force: mm.Force, width: float) -> None:
    cutoff = _nm(force.getCutoffDistance())
    if cutoff - width <= 0:
        raise InputError(
            f"{label_force(index, force)}: cutoff {cutoff:g} nm minus switch_width {width:g} nm is "
            f"{cutoff - width:g} nm, not a switching distance. Pass a switch_width below "
            f"{cutoff:g} nm (e.g. {0.1 * cutoff:g} nm), or a larger cutoff."
        )


def _switch(index: int, force: mm.Force, width: float) -> list[str]:
    """Switch ``force`` over its last ``width`` nm unless it already is (from there or closer in)."""
    cutoff = _nm(force.getCutoffDistance())
    target = cutoff - width
    on, distance = force.getUseSwitchingFunction(), _nm(force.getSwitchingDistance())
    if on and distance <= target + _SMALL:
        return []
    old = f"switching from {distance:g} nm" if on else "no switching function"
    force.setUseSwitchingFunction(True)
    force.setSwitchingDistance(target)
    return [f"{label_force(index, force)}: {old} → switching from {target:g} nm (cutoff {cutoff:g} nm)"]


def _tighten_ewald(index: int, force: mm.Force, tolerance: float) -> list[str]:
    if not isinstance(force, mm.NonbondedForce) or force.getNonbondedMethod() not in _EWALD_METHODS:
        return []
    old = force.getEwaldErrorTolerance()
    if old <= tolerance:
        return []
    force.setEwaldErrorTolerance(tolerance)
    return [f"{label_force(index, force)}: Ewald error tolerance {old:g} → {tolerance:g}"]


def apply_build_settings(
    system: mm.System, cutoff: float, switch_distance: float | None, ewald_error_tolerance: float | None
) -> None:
    """Give a System fresh from ``createSystem`` a builder's settings exactly, through make_smooth.

    For :func:`openmm_alphaprk.systems.build_water_box` and the ``systems/``
    definitions, the same System ``createSystem(switchDistance=..., ewaldErrorTolerance=...)``
    gives: the LJ switch from ``switch_distance`` (nm; None: no switch), and the Ewald
    tolerance ``ewald_error_tolerance`` (None: OpenMM's default) even where it is
    looser than OpenMM's default, which make_smooth would keep. make_smooth switches
    from cutoff − (cutoff − s), which differs from s by round-off when s < cutoff/2;
    s itself is set then.
    """
    width = None if switch_distance is None else cutoff - switch_distance
    make_smooth(system, width, ewald_error_tolerance)
    for force in system.getForces():
        if switch_distance is not None and _has_cutoff(force):
            force.setSwitchingDistance(switch_distance)
        if ewald_error_tolerance is not None and isinstance(force, mm.NonbondedForce):
            force.setEwaldErrorTolerance(ewald_error_tolerance)


def warn_if_not_smooth(
    system: mm.System, stacklevel: int | None = None, who: str = "the energy-preserving mode"
) -> bool:
    """Issue one :class:`NonSmoothForcesWarning` listing every :func:`smoothness_problems` entry, if any.

    Parameters
    ----------
    system
        The System an energy-mode integrator is about to run.
    stacklevel
        As for ``warnings.warn``, counted from the caller of this function (1: the
        line that calls it). None (the default) points at the first frame outside
        this package and OpenMM: the user's ``integrator.step(...)`` or
        ``simulation.step(...)``.
    who
        The integrator that needs them, as the warning names it.

    Returns
    -------
    bool
        True if a warning was issued.

    """
    problems = smoothness_problems(system)
    heading = f"{who} needs smooth forces; {len(problems)} problem(s) found"
    return warn_listing(
        problems, heading, "openmm_alphaprk.smooth_forces", NonSmoothForcesWarning, stacklevel
    )


def warn_listing(
    items: list[str], heading: str, module: str, category: type[Warning], stacklevel: int | None
) -> bool:
    """Issue one ``category`` warning: ``heading``, a line per item, where to read more; False if none.

    ``stacklevel`` as for :func:`warn_if_not_smooth`, counted from the caller of that function.
    """
    if not items:
        return False
    level = outside_stacklevel() if stacklevel is None else int(stacklevel) + 1
    listed = "\n".join(f"  - {item}" for item in items)
    warnings.warn(f"{heading}:\n{listed}\nSee help({module}).", category, stacklevel=level + 1)
    return True


_INTERNAL_DIRS = tuple(os.path.dirname(os.path.abspath(path)) + os.sep for path in (__file__, mm.__file__))


def outside_stacklevel() -> int:
    """Return the stack level of the first frame outside this package and OpenMM (1: our caller's caller)."""
    frame, level = sys._getframe(2), 1
    while frame.f_back is not None and os.path.abspath(frame.f_code.co_filename).startswith(_INTERNAL_DIRS):
        frame, level = frame.f_back, level + 1
    return level
