"""Integrators by name, for the driver and the command line: one vocabulary of names.

Names (:data:`VOCABULARY`, in the order ``--help`` lists them):

``rattle``
    :class:`~openmm_alphaprk.RattleIntegrator` (velocity Verlet with SHAKE/SETTLE and
    RATTLE velocities; one force evaluation per step).
``rattle+rescale``
    :class:`~openmm_alphaprk.RattleRescaleIntegrator` (RATTLE, then the velocities
    relative to the rigid-body motion scaled so that H = E_ref; one force evaluation per
    step): the cheapest way to hold the energy, the baseline of the energy modes.
``rattle4+rescale``, ``rattle6+rescale``
    :class:`~openmm_alphaprk.RattleRescaleIntegrator` on the default fourth- or
    sixth-order composition of RATTLE steps (``order=4``, ``order=6``): the
    composition's trajectory, its energy held at E_ref by the rescaling.
``rattle+rescale@<N>``, ``rattle4+rescale@<N>``, ``rattle6+rescale@<N>``
    The same, rescaling every N-th step only (``rescale_interval=N``; ``rattle+rescale@10``);
    the steps between are plain RATTLE (or the composition), with no energy read and no
    sum. ``@1`` is the name without it. Written after a composition:
    ``rattle4+rescale:triple-jump@10``.
``alpha=<number>``
    :class:`~openmm_alphaprk.AlphaRattleIntegrator` with that fixed α; fractions
    are accepted (``alpha=1/6``). ``alpha=0`` is RATTLE.
``energy``
    :class:`~openmm_alphaprk.AlphaRattleEnergyIntegrator`, the energy-preserving mode
    (α chosen every step so that H stays at E_ref).
``alpha4=<number>``
    α-RATTLE-4 (``order=4``: Suzuki's five-stage composition with α on the middle
    stage) with that fixed α; ``alpha4=0`` is its composition of RATTLE steps (fourth
    order, five force evaluations per step).
``energy4``
    α-RATTLE-4 in the energy-preserving mode (α* = O(h²)).
``alpha6=<number>``, ``energy6``
    The same on the default sixth-order composition.
``<name>:<composition>``
    ``alpha4``, ``energy4``, ``alpha6``, ``energy6``, ``rattle4+rescale`` or
    ``rattle6+rescale`` on a named composition of
    :data:`~openmm_alphaprk.integrators.compositions.COMPOSITIONS` instead of the
    order's default (``energy4:triple-jump``, ``alpha4=0:suzuki5``).
``split=<number>``
    :class:`~openmm_alphaprk.SplittingRattleIntegrator` with that α: the explicit
    α-family, kick((½−α)h) · drift(h/2) · kick(2αh) · drift(h/2) · kick((½−α)h) with
    constraints (two force evaluations per step, no iteration); ``split=1/4`` is RATTLE at h/2.
``split-me``, ``split-bcss``
    The minimum-error two-stage member (α = 0.306817, McLachlan) and Blanes, Casas &
    Sanz-Serna's (α = 0.288219).
``split3-me``, ``split3-bcss``
    The three-stage splittings (minimum error; Blanes, Casas & Sanz-Serna): three force
    evaluations per step.
``split-me+rescale``, ``split-bcss+rescale``, ``split3-me+rescale``, ``split3-bcss+rescale``
    :class:`~openmm_alphaprk.RattleRescaleIntegrator` after that splitting
    (``splitting=``); ``@N`` rescales every N-th step only (``split-me+rescale@10``).
``verlet``
    ``openmm.VerletIntegrator`` (leapfrog). Its ``State`` kinetic energy is a
    half-step average, so its H − E_ref is not comparable step for step with the
    velocity-Verlet integrators above (its fluctuation looks different for that
    reason alone); its drift is comparable.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from functools import partial

import openmm as mm
import openmm.unit as unit

from .._units import InputError
from ..integrators import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    IncompatibleSystemError,
    RattleIntegrator,
    RattleRescaleIntegrator,
    SplittingRattleIntegrator,
)
from ..integrators.compositions import COMPOSITIONS
from ..observables import VERLET_IS_LEAPFROG
from ..platforms import massless_particles
from ..smooth_forces import polarizable_forces


@dataclass(frozen=True)
class IntegratorName:
    """One name of the vocabulary: as written (``<number>`` for a value), what it makes, its help."""

    name: str
    kind: str
    order: int
    help: str

    @property
    def takes_number(self) -> bool:
        """True for ``alpha=<number>`` and ``alpha4=<number>``."""
        return self.name.endswith("=<number>")


VOCABULARY = (
    IntegratorName(
        "rattle",
        "rattle",
        2,
        "RattleIntegrator (velocity Verlet + SHAKE/SETTLE/RATTLE, 1 force evaluation/step)",
    ),
    IntegratorName(
        "rattle+rescale",
        "rescale",
        2,
        "RattleRescaleIntegrator (RATTLE, then the velocities relative to the rigid-body motion scaled "
        "so that H = E_ref; 1 force evaluation/step, its energy read with it)",
    ),
    IntegratorName(
        "rattle4+rescale",
        "rescale",
        4,
        "RattleRescaleIntegrator(order=4): Suzuki's 5-stage composition of RATTLE steps, then the "
        "rescaling (5 evaluations/step, the energy read with the last): H held at E_ref and, on "
        "water, positions 16-20x closer to the true dynamics than RATTLE's at equal cost",
    ),
    IntegratorName(
        "rattle6+rescale",
        "rescale",
        6,
        "RattleRescaleIntegrator(order=6): McLachlan's 9-stage composition of RATTLE steps, then the "
        "rescaling (9 evaluations/step)",
    ),
    IntegratorName(
        "rattle+rescale@<N>",
        "rescale",
        2,
        "the same rescaling every N-th step only (rattle+rescale@10; also rattle4+rescale@N, "
        "rattle6+rescale@N): the steps between are plain RATTLE, no energy read, no sum",
    ),
    IntegratorName(
        "alpha=<number>",
        "alpha",
        2,
        "AlphaRattleIntegrator with fixed alpha, fractions allowed (alpha=1/6; alpha=0 is RATTLE)",
    ),
    IntegratorName(
        "energy",
        "energy",
        2,
        "AlphaRattleEnergyIntegrator(h), alpha chosen per step to hold H at E_ref "
        "(a midpoint and an end force per trial of alpha, more where the midpoint iteration needs "
        "them; the run's table gives the measured evaluations/step)",
    ),
    IntegratorName(
        "alpha4=<number>",
        "alpha",
        4,
        "the same with order=4 (Suzuki's 5-stage composition, the most accurate per evaluation of the "
        "measured fourth-order sets, docs/compositions.md; alpha on the middle stage; alpha4=0 is its "
        "4th-order composition of RATTLE steps, 5 evaluations/step)",
    ),
    IntegratorName(
        "energy4",
        "energy",
        4,
        "order=4 in the energy mode (the stages before the middle once, then the middle stage and "
        "those after it again for each trial of alpha)",
    ),
    IntegratorName(
        "alpha6=<number>",
        "alpha",
        6,
        "the same with order=6 (McLachlan's 9-stage composition; alpha6=0 is its 6th-order composition "
        "of RATTLE steps, 9 evaluations/step)",
    ),
    IntegratorName("energy6", "energy", 6, "the energy mode on the default sixth-order composition"),
    IntegratorName(
        "split=<number>",
        "split",
        2,
        "SplittingRattleIntegrator with that alpha: the explicit alpha-family, kick((1/2-alpha)h) "
        "drift(h/2) kick(2 alpha h) drift(h/2) kick((1/2-alpha)h) with constraints (2 evaluations/step, "
        "no iteration; split=1/4 is RATTLE at h/2)",
    ),
    IntegratorName(
        "split-me",
        "split",
        2,
        "the minimum-error two-stage splitting (alpha = 0.306817, McLachlan 1995; 2 evaluations/step)",
    ),
    IntegratorName(
        "split-bcss",
        "split",
        2,
        "Blanes, Casas & Sanz-Serna's two-stage splitting (alpha = 0.288219; 2 evaluations/step)",
    ),
    IntegratorName(
        "split3-me",
        "split",
        2,
        "the minimum-error three-stage splitting (Predescu et al. 2012; 3 evaluations/step)",
    ),
    IntegratorName(
        "split3-bcss", "split", 2, "Blanes, Casas & Sanz-Serna's three-stage splitting (3 evaluations/step)"
    ),
    IntegratorName(
        "split-me+rescale",
        "rescale",
        2,
        "RattleRescaleIntegrator(splitting='me2'): the minimum-error splitting, then the rescaling "
        "(also split-bcss+rescale, split3-me+rescale, split3-bcss+rescale; @N every N-th step)",
    ),
    IntegratorName("verlet", "verlet", 2, VERLET_IS_LEAPFROG),
)
_BY_NAME = {
    entry.name.removesuffix("=<number>"): entry for entry in VOCABULARY if not entry.name.endswith("@<N>")
}
#: The named splittings of the vocabulary (:data:`~openmm_alphaprk.integrators.splittings.SPLITTINGS`).
SPLITTING_NAMES = {"split-me": "me2", "split-bcss": "bcss2", "split3-me": "me3", "split3-bcss": "bcss3"}
for _name, _chosen in SPLITTING_NAMES.items():
    if f"{_name}+rescale" not in _BY_NAME:
        _BY_NAME[f"{_name}+rescale"] = IntegratorName(
            f"{_name}+rescale", "rescale", 2, f"RattleRescaleIntegrator(splitting={_chosen!r})"
        )

#: The names, in the vocabulary's order (``rattle, alpha=<number>, …, verlet``), for ``--help``.
INTEGRATOR_NAMES = ", ".join(entry.name for entry in VOCABULARY)
#: One line per name, for ``--help``.
INTEGRATOR_HELP = "; ".join(f"{entry.name} = {entry.help}" for entry in VOCABULARY)


class UnknownIntegratorError(InputError):
    """Raised for an integrator name that is not in :data:`VOCABULARY`."""


@dataclass(frozen=True)
class IntegratorSpec:
    """A parsed integrator name: ``kind`` is rattle, rescale, alpha, energy or verlet; ``order`` 2 or 4."""

    kind: str
    alpha: float | None = None
    text: str = ""
    order: int = 2
    composition: str | None = None
    rescale_interval: int = 1
    splitting: str | None = None

    @property
    def name(self) -> str:
        """Canonical name (``alpha=0.1666…`` keeps the user's fraction text)."""
        return self.text or self.kind

    def supports_virtual_sites(self, platform: str) -> bool:
        """Tell whether the integrator is right for systems with virtual sites on ``platform``.

        VerletIntegrator everywhere; for this package's integrators their own answer
        (:meth:`~openmm_alphaprk.RattleIntegrator.virtual_sites_refusal`): RATTLE and α = 0
        (order 2 or 4) on CUDA, OpenCL and HIP, which place virtual sites at every
        constraint step; nothing else (α ≠ 0 takes a force at the unconstrained midpoint,
        where no platform places them).
        """
        if self.kind == "verlet":
            return True
        return make_integrator(self, 0.002).virtual_sites_refusal(platform) is None

    @property
    def velocity_verlet(self) -> bool:
        """True if the State's kinetic energy is that of on-step velocities."""
        return self.kind != "verlet"


def parse_integrator(text: str | IntegratorSpec) -> IntegratorSpec:
    """Parse an integrator name of :data:`VOCABULARY` (any case; white space is ignored).

    ``rattle``, ``rattle+rescale``, ``verlet``, ``energy``, ``energy4``, ``alpha=<x>``, ``alpha4=<x>``;
    ``rattle+rescale@<N>`` (and ``rattle4+rescale@<N>`` …) with ``rescale_interval`` N.

    Raises
    ------
    UnknownIntegratorError
        With the list of valid names.
    """
    if isinstance(text, IntegratorSpec):
        return text
    cleaned = re.sub(r"\s+", "", str(text)).lower()
    interval, cleaned = _rescale_interval_of(text, cleaned)
    named, colon, chosen = cleaned.partition(":")
    prefix, equals, number = named.partition("=")
    entry = _BY_NAME.get(prefix)
    if colon:
        if entry is None or entry.order == 2:
            raise UnknownIntegratorError(
                f"{text!r}: only alpha4, energy4, alpha6, energy6, rattle4+rescale and rattle6+rescale "
                "take a composition (e.g. energy4:triple-jump)."
            )
        found = COMPOSITIONS.get(chosen)
        if found is None or found.order != entry.order:
            fitting = [c.name for c in COMPOSITIONS.values() if c.order == entry.order]
            raise UnknownIntegratorError(
                f"{text!r}: no composition {chosen!r} of order {entry.order}; "
                f"use one of {', '.join(fitting)}."
            )
    composition_name = chosen if colon else None
    if interval is not None and (entry is None or entry.kind != "rescale" or equals):
        raise UnknownIntegratorError(
            f"{text!r}: only rattle+rescale, rattle4+rescale and rattle6+rescale take a rescaling "
            "interval @N (e.g. rattle+rescale@10)."
        )
    chosen_splitting = SPLITTING_NAMES.get(prefix.removesuffix("+rescale"))
    if interval is not None:
        canonical = cleaned if interval == 1 else f"{cleaned}@{interval}"
        return IntegratorSpec(
            entry.kind,
            text=canonical,
            order=entry.order,
            composition=composition_name,
            rescale_interval=interval,
            splitting=chosen_splitting,
        )
    if entry is not None and not entry.takes_number and not equals:
        return IntegratorSpec(
            entry.kind,
            text=cleaned,
            order=entry.order,
            composition=composition_name,
            splitting=chosen_splitting,
        )
    if entry is not None and entry.takes_number and re.fullmatch(r"[-+0-9.e/]+", number):
        try:
            value = float(Fraction(number))
        except (ValueError, ZeroDivisionError):
            value = None
        if value is not None and value == value and abs(value) != float("inf"):
            return IntegratorSpec(
                entry.kind, value, text=cleaned, order=entry.order, composition=composition_name
            )
    raise UnknownIntegratorError(
        f"unknown integrator {text!r}; use one of: rattle, rattle+rescale, verlet, energy, energy4, "
        "alpha=<number>, alpha4=<number> (e.g. alpha=0.5, alpha=1/6, alpha4=0), energy6, alpha6=<number>, "
        "rattle4+rescale, rattle6+rescale; the composed ones optionally on a named composition "
        "(energy4:triple-jump); the splittings split=<number>, split-me, split-bcss, split3-me, "
        "split3-bcss (and each +rescale); the rescaling ones optionally every N-th step (rattle+rescale@10)."
    )


def _rescale_interval_of(text: object, cleaned: str) -> tuple[int | None, str]:
    """Split a rescaling interval ``@N`` off a cleaned name (before or after a composition).

    Returns the interval (None without ``@``) and the name without it.
    """
    named, at, rest = cleaned.partition("@")
    if not at:
        return None, cleaned
    number, colon, composition = rest.partition(":")
    if not re.fullmatch(r"[0-9]+", number) or int(number) < 1 or "@" in composition:
        raise UnknownIntegratorError(
            f"{text!r}: the rescaling interval after '@' must be a positive integer, the rescaling every "
            "N-th step; write e.g. rattle+rescale@10 (or rattle4+rescale:triple-jump@10)."
        )
    return int(number), named + colon + composition


#: Display labels of the names without a number (tables, figures, benchmarks, reports).
_LABELS = {
    "rattle": "RATTLE",
    "rattle+rescale": "RATTLE + rescaling",
    "verlet": "VerletIntegrator",
    "energy": "α-RATTLE energy mode",
    "energy4": "α-RATTLE-4 energy mode",
    "split-me": "splitting, minimum error (α = 0.3068)",
    "split-bcss": "splitting, BCSS (α = 0.2882)",
    "split3-me": "3-stage splitting, minimum error",
    "split3-bcss": "3-stage splitting, BCSS",
}


def label(spec: str | IntegratorSpec) -> str:
    """Return the display label of an integrator name: ``alpha=1/6`` → ``α-RATTLE α = 1/6``.

    The one set of labels the benchmarks, reports and figures use (``RATTLE``,
    ``RATTLE + rescaling``, ``RATTLE + rescaling every 10 steps``, ``VerletIntegrator``,
    ``α-RATTLE α = x``, ``α-RATTLE-4 α = x``, ``α-RATTLE energy
    mode``, ``α-RATTLE-4 energy mode``); ``x`` is written as given (fractions kept).
    """
    spec = parse_integrator(spec)
    every = f" every {spec.rescale_interval} steps" if spec.rescale_interval > 1 else ""
    if spec.splitting is not None and spec.kind == "rescale":
        named = spec.name.partition("+rescale")[0]
        return f"{_LABELS[named]} + rescaling{every}"
    if spec.kind == "split":
        return (
            _LABELS[spec.name]
            if spec.splitting is not None
            else f"splitting α = {spec.name.partition('=')[2]}"
        )
    family = "α-RATTLE" if spec.order == 2 else f"α-RATTLE-{spec.order}"
    if spec.kind == "rescale" and spec.order != 2:
        family = f"RATTLE-{spec.order}"
    if spec.composition is not None:
        family += f" ({spec.composition})"
    every = f" every {spec.rescale_interval} steps" if spec.rescale_interval > 1 else ""
    if spec.kind == "rescale" and spec.order != 2:
        return f"{family} + rescaling{every}"
    if spec.kind == "rescale":
        return f"RATTLE + rescaling{every}"
    if spec.kind == "energy":
        return f"{family} energy mode"
    if spec.kind != "alpha":
        return _LABELS[spec.name]
    return f"{family} α = {spec.name.partition(':')[0].partition('=')[2]}"


def make_integrator(
    spec: str | IntegratorSpec, timestep: unit.Quantity | float, constraint_tolerance: float = 1e-8
) -> mm.Integrator:
    """Create the integrator named by ``spec`` (timestep: Quantity or ps).

    A plain number is taken as picoseconds deliberately (the driver, sweeps and
    benchmarks convert the user's units first), so it is passed on as a Quantity and
    does not raise the integrators' :class:`~openmm_alphaprk.TimestepUnitWarning`.
    """
    spec = parse_integrator(spec)
    if not unit.is_quantity(timestep):
        timestep = timestep * unit.picoseconds
    if spec.kind == "rattle":
        return RattleIntegrator(timestep, constraint_tolerance=constraint_tolerance)
    if spec.kind == "rescale":
        return RattleRescaleIntegrator(
            timestep,
            constraint_tolerance=constraint_tolerance,
            order=spec.order,
            composition=spec.composition,
            rescale_interval=spec.rescale_interval,
            splitting=spec.splitting,
        )
    if spec.kind == "split":
        return SplittingRattleIntegrator(
            timestep,
            alpha=spec.alpha if spec.splitting is None else None,
            constraint_tolerance=constraint_tolerance,
            splitting=spec.splitting,
        )
    if spec.kind == "alpha":
        return AlphaRattleIntegrator(
            timestep,
            alpha=spec.alpha,
            constraint_tolerance=constraint_tolerance,
            order=spec.order,
            composition=spec.composition,
        )
    if spec.kind == "energy":
        return AlphaRattleEnergyIntegrator(
            timestep,
            constraint_tolerance=constraint_tolerance,
            order=spec.order,
            composition=spec.composition,
        )
    integrator = mm.VerletIntegrator(timestep)
    integrator.setConstraintTolerance(constraint_tolerance)
    return integrator


@dataclass(frozen=True)
class SubStepped:
    """An integrator taken ``substeps`` steps at a time: one step of h of a row that runs at h/substeps.

    RATTLE at h/k, k steps per step of h, costs k force evaluations per step of h: the
    equal-cost rows of the benchmarks and comparisons.
    """

    make: Callable[[], mm.Integrator]
    substeps: int = 1


def at_divisor(
    spec: str | IntegratorSpec, timestep: float, divisor: int = 1, constraint_tolerance: float = 1e-8
) -> SubStepped:
    """Return the integrator ``spec`` at h/``divisor`` (h = ``timestep``, ps), ``divisor`` steps a step."""
    make = partial(make_integrator, spec, timestep / divisor, constraint_tolerance)
    return SubStepped(make, substeps=divisor)


def check_compatible(
    spec: str | IntegratorSpec, system: mm.System, system_name: str = "this system", platform: str = "CPU"
) -> None:
    """Refuse, before any step, an integrator that cannot integrate ``system`` on ``platform``.

    Raises
    ------
    IncompatibleSystemError
        If ``system`` has massless particles (virtual sites) and ``spec`` cannot be
        right for them on ``platform`` (see :meth:`IntegratorSpec.supports_virtual_sites`),
        or ``spec`` is an energy mode and ``system`` has polarizable forces
        (:func:`~openmm_alphaprk.smooth_forces.polarizable_forces`).
    """
    spec = parse_integrator(spec)
    if spec.kind == "energy":
        polarizable = polarizable_forces(system)
        if polarizable:
            raise IncompatibleSystemError(
                f"integrator {spec.name!r} cannot run {system_name}: {'; '.join(polarizable)}. Their energy "
                "is converged to a tolerance, not a smooth function of the positions, and the energy mode "
                "would chase that error instead of holding H. Instead use rattle, rattle+rescale or a fixed "
                "alpha (alpha4=0)."
            )
    if spec.supports_virtual_sites(platform):
        return
    massless = len(massless_particles(system))
    if not massless:
        return
    shown = system_name.strip("'\"") if system_name != "this system" else "SYSTEM"
    verlet = (
        f"use verlet (openmm.VerletIntegrator, any platform): `alphaprk run {shown} verlet` or "
        f"`alphaprk compare {shown} -i verlet`"
    )
    if spec.kind in ("rattle", "rescale", "split") or (spec.kind == "alpha" and spec.alpha == 0.0):
        reason = (
            f"on the {platform} platform OpenMM places virtual sites only at the end of a CustomIntegrator "
            "step, so forces inside the step would see stale sites. Instead run it with --platform CUDA, "
            "OpenCL or HIP, which place them at every constraint step: "
            f"`alphaprk run {shown} {spec.name} --platform CUDA`; or {verlet}"
        )
    else:
        reason = (
            "α ≠ 0 and the energy modes take a force at the unconstrained midpoint of the step, where no "
            f"OpenMM platform places virtual sites. Instead {verlet}; or use rattle or alpha4=0 on CUDA, "
            f"OpenCL or HIP: `alphaprk run {shown} rattle --platform CUDA`"
        )
    raise IncompatibleSystemError(
        f"integrator {spec.name!r} cannot run {system_name}: it has {massless} massless particle(s) "
        f"(virtual sites, e.g. TIP4P-Ew M-sites), and {reason}; or use a 3-site water model (tip3p-*, "
        "spce-3nm)."
    )
