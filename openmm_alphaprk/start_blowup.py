"""A start the method cannot take: NaN in the first steps, reported with its likely causes.

When a run goes to NaN within its first :data:`START_STEPS` steps, the cause is almost
always the start, not the integrator's long-run stability: an unminimized structure,
velocities far too hot, or a step larger than the method takes; with a fixed |α| beyond
:data:`USUAL_ALPHA`, the α is named first. OpenMM's own message
("Particle coordinate is NaN") names none of these, and the Reference platform raises
nothing at all. :func:`take_steps` runs a step program's steps, checks the first ones
and raises :class:`StartBlowUpError` with the causes instead.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import numpy as np
import openmm as mm
import openmm.unit as unit

from .errors import StartBlowUpError  # defined there; importable from here too

__all__ = ["START_STEPS", "USUAL_ALPHA", "StartBlowUpError", "take_steps"]

#: Steps from an integrator's first during which a NaN is reported as a bad start.
START_STEPS = 100
#: Beyond this |α| a fixed α is named as the first cause of a blow-up at the start.
USUAL_ALPHA = 1.0

_NON_FINITE = re.compile(r"\bnan\b|\binfinite\b|non-finite|\binf\b", re.IGNORECASE)


def take_steps(
    integrator: mm.CustomIntegrator,
    steps: int,
    velocities: Callable[[], tuple[np.ndarray, int]] | None = None,
) -> None:
    """Run ``steps`` steps of ``integrator``'s program, checking those within the first :data:`START_STEPS`.

    Steps up to step :data:`START_STEPS` run as one call (the same steps as part of a
    longer one), after which ``velocities`` are checked for NaN; steps after it run
    unchecked.

    Parameters
    ----------
    integrator
        A step program of this package, bound to a Context.
    steps
        Number of steps.
    velocities
        Returns the velocities to check (nm/ps) and the step after which they were
        taken; None checks only OpenMM's own NaN error.

    Raises
    ------
    StartBlowUpError
        If the first steps raised OpenMM's NaN error, or left non-finite velocities
        (on the Reference platform, which raises nothing). The original message is
        appended.
    """
    checked = 0 if getattr(integrator, "_past_start", False) else START_STEPS - _steps_taken(integrator)
    if checked <= 0:
        integrator._past_start = True
        mm.CustomIntegrator.step(integrator, steps)
        return
    first = min(steps, checked)
    try:
        mm.CustomIntegrator.step(integrator, first)
    except mm.OpenMMException as error:
        if isinstance(error, StartBlowUpError) or not _NON_FINITE.search(str(error)):
            raise
        raise StartBlowUpError(_message(integrator, f"OpenMM said: {error}")) from error
    if velocities is not None:
        values, after = velocities()
        if not np.isfinite(values).all():
            found = f"The velocities were NaN or infinite after step {after}."
            raise StartBlowUpError(_message(integrator, found))
    if steps > first:
        take_steps(integrator, steps - first, velocities)


def _steps_taken(integrator: mm.CustomIntegrator) -> int:
    return int(integrator.getGlobalVariableByName("steps_taken"))


def _message(integrator: mm.CustomIntegrator, original: str) -> str:
    """Return the likely causes of a blow-up at the start, for this integrator, then ``original``."""
    step_fs = integrator.getStepSize().value_in_unit(unit.femtoseconds)
    name = type(integrator).__name__
    composition = getattr(integrator, "composition", None)
    if composition is not None and composition.largest_substep > 1.0:
        largest = composition.largest_substep
        large = (
            f"too large a step (this one is {step_fs:g} fs) for the {composition.name} composition: its "
            f"largest sub-step is {largest:.2f}h, so its largest stable step is {1 / largest:.2f}× RATTLE's; "
            f"use at most {2 / largest:.1f} fs with constraints (SETTLE, HBonds), a composition with "
            "shorter sub-steps (order=4, Suzuki's, whose sub-steps are at most 0.66h), or RattleIntegrator"
        )
    else:
        large = (
            f"too large a step (this one is {step_fs:g} fs): about 2 fs is the limit with constraints on "
            "bonds to hydrogen (SETTLE, HBonds), about 1 fs without, about 4 fs with hydrogen masses "
            "repartitioned to 3–4 amu (--hydrogen-mass 3)"
        )
    start_causes = (
        "an unminimized start: run openmm.LocalEnergyMinimizer.minimize "
        "(simulation.minimizeEnergy()) and equilibrate (e.g. with LangevinMiddleIntegrator) before "
        "the NVE run",
        "too hot a start: velocities far above the intended temperature (context.setVelocitiesToTemperature)",
        large,
    )
    alpha = _unusual_alpha(integrator)
    if alpha is None:
        head = f"{name} blew up in its first {START_STEPS} steps, which points at the start rather than at "
        head += "the method"
        causes = start_causes
    else:
        head = (
            f"{name} blew up in its first {START_STEPS} steps with alpha={alpha:g} at a {step_fs:g} fs "
            f"step, outside |alpha| <= {USUAL_ALPHA:g} where α-RATTLE is meant to be used: the α is the "
            "first suspect, then the start"
        )
        causes = (
            "the α: α-RATTLE weighs the force along a step by (1/2 - α, 2α, 1/2 - α), large and of "
            "opposite sign beyond |α| = 1; the step it can take shrinks as 1/sqrt(|α|), its midpoint "
            "iteration converging only while |α|h²ω²/4 < 1 (ω: the fastest motion); use alpha between "
            f"-{USUAL_ALPHA:g} and {USUAL_ALPHA:g} (alpha=0 is RATTLE; the energy mode, "
            "AlphaRattleEnergyIntegrator or energy4, chooses α every step)",
            *start_causes,
        )
    listed = "; ".join(f"({i}) {cause}" for i, cause in enumerate(causes, start=1))
    return f"{head}. Likely causes: {listed}.{_energy_mode_record(integrator)} {original}"


def _energy_mode_record(integrator: mm.CustomIntegrator) -> str:
    """For the energy mode: how many steps before the blow-up its controller could not hold (α = 0 steps)."""
    if not getattr(integrator, "energy_mode", False):
        return ""
    try:
        zero = int(integrator.getGlobalVariableByName("steps_alpha_zero"))
    except mm.OpenMMException:  # a program without the count
        return ""
    steps = _steps_taken(integrator)
    return (
        f" The energy mode's controller could not hold {zero} of the {steps} steps before and took them "
        "as alpha = 0 steps of its base (RATTLE or the composition of RATTLE steps): try the base "
        "(alpha=0) from this start; where it blows up too, the start or the step is the cause."
    )


def _unusual_alpha(integrator: mm.CustomIntegrator) -> float | None:
    """Return the fixed α of an α-RATTLE integrator if |α| > :data:`USUAL_ALPHA`, else None.

    The energy mode's α is its controller's choice (kept within its bounds), not the user's.
    """
    if getattr(integrator, "energy_mode", False):
        return None
    alpha = getattr(integrator, "alpha", None)
    if alpha is None or not abs(alpha) > USUAL_ALPHA:
        return None
    return float(alpha)
