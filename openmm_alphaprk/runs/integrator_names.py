"""Integrators by name, for the driver and the command line: one registry, one grammar.

Every name is ``BASE[:SET][=α][+rescale[@N]]`` (any case, white space ignored):

``BASE``
    A family of :data:`FAMILIES` with an optional digit, which is always the order:
    ``rattle`` (:class:`~openmm_alphaprk.RattleIntegrator`), ``alpha``
    (:class:`~openmm_alphaprk.AlphaRattleIntegrator`, fixed α), ``energy``
    (:class:`~openmm_alphaprk.AlphaRattleEnergyIntegrator`, α chosen every step), ``split``
    (:class:`~openmm_alphaprk.SplittingRattleIntegrator`, the explicit family) and ``verlet``
    (``openmm.VerletIntegrator``, leapfrog). ``rattle4``, ``alpha4``, ``energy4``: the order's
    default composition of steps (Suzuki's five stages; ``6``: McLachlan's nine).
``:SET``
    A named composition (:data:`~openmm_alphaprk.integrators.compositions.COMPOSITIONS`) for
    the composed bases (``alpha4:triple-jump=0.01``), a named splitting
    (:data:`~openmm_alphaprk.integrators.splittings.SPLITTINGS`) for ``split``
    (``split:me2``, ``split:bcss3``).
``=α``
    The fixed α of ``alpha`` (required) and of ``split`` (the two-stage member; instead of a
    set); fractions are accepted (``alpha=1/6``).
``+rescale[@N]``
    :class:`~openmm_alphaprk.RattleRescaleIntegrator` after the base (``rattle``, its
    compositions, any splitting): the velocities relative to the rigid-body motion scaled
    so that H = E_ref, every step or every N-th step (``rattle+rescale@10``).

Names from before this grammar keep working and are read as the canonical one:
``split-me`` = ``split:me2``, ``split-bcss`` = ``split:bcss2``, ``split3-me`` =
``split:me3``, ``split3-bcss`` = ``split:bcss3``, and a set written after ``=α`` or
``+rescale`` (``alpha4=0:triple-jump`` = ``alpha4:triple-jump=0``,
``rattle4+rescale:triple-jump@10`` = ``rattle4:triple-jump+rescale@10``).

The labels of tables and figures (:func:`label`), the ``--help`` text
(:data:`INTEGRATOR_HELP`), the unknown-name message and the names every test runs
(:func:`example_names`) all come from :data:`FAMILIES` and the two libraries: a splitting
registered in :data:`~openmm_alphaprk.integrators.splittings.SPLITTINGS` is ``split:NAME``
at once.
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
from ..integrators.compositions import COMPOSITIONS, DEFAULT_COMPOSITIONS
from ..integrators.restore import register_integrator_class
from ..integrators.splittings import MINIMUM_ERROR2, SPLITTINGS
from ..integrators.stage_sets import Library
from ..observables import VERLET_IS_LEAPFROG
from ..platforms import massless_particles
from ..smooth_forces import polarizable_forces


class UnknownIntegratorError(InputError):
    """Raised for an integrator name that the grammar does not read."""


@dataclass(frozen=True)
class IntegratorSpec:
    """A parsed integrator name.

    ``kind`` is the family's word (rattle, alpha, energy, split, verlet), or the layer's
    (``rescale``) for a base with a way of holding the energy over it (``layer``); ``order``
    the digit (2 without); ``composition`` and ``splitting`` the set named after ``:``
    (``splitting`` also for ``split`` without one: its default).
    """

    kind: str
    alpha: float | None = None
    text: str = ""
    order: int = 2
    composition: str | None = None
    rescale_interval: int = 1
    splitting: str | None = None
    layer: str | None = None

    @property
    def name(self) -> str:
        """Canonical name (``alpha=0.1666…`` keeps the user's fraction text)."""
        return self.text or self.kind

    @property
    def family(self) -> Family:
        """The family of the base step (``split`` for a rescaled splitting, else ``rattle``)."""
        if self.layer is None:
            return FAMILIES[self.kind]
        return FAMILIES["split" if self.splitting is not None else "rattle"]

    @property
    def force_evaluations(self) -> int | None:
        """Force evaluations per step where the program fixes them; None where α ≠ 0 iterates."""
        if self.kind == "verlet":
            return 1
        if self.kind == "energy" or (self.kind == "alpha" and self.alpha != 0.0):
            return None
        if self.splitting is not None:
            return SPLITTINGS.lookup(self.splitting).stages
        if self.kind == "split":
            return 2
        if self.order == 2:
            return 1
        return COMPOSITIONS.lookup(self.composition or DEFAULT_COMPOSITIONS[self.order]).stages

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


Make = Callable[[IntegratorSpec, unit.Quantity, float], mm.Integrator]


@dataclass(frozen=True)
class Family:
    """One base word of the grammar and all that is derived from it.

    Attributes
    ----------
    word
        The name's first word.
    title
        The label's first words (``RATTLE``; ``-<order>`` is added for a digit).
    help
        What the family is, for ``--help`` (no measured numbers: they live in docs/).
    make
        Creates the integrator of a parsed name (timestep a Quantity, the constraint tolerance).
    orders
        The digits it takes (2: none).
    sets
        What ``:SET`` names: the compositions (for a digit) or the splittings.
    alpha
        ``"required"``, ``"optional"`` (instead of a set) or ``"none"``.
    rescalable
        Whether ``+rescale[@N]`` may follow it.
    """

    word: str
    title: str
    help: str
    make: Make
    orders: tuple[int, ...] = (2,)
    sets: Library | None = None
    alpha: str = "none"
    rescalable: bool = False

    @property
    def form(self) -> str:
        """The family's names in the grammar's notation, e.g. ``rattle[4|6][:COMPOSITION][+rescale[@N]]``."""
        text = self.word
        if len(self.orders) > 1:
            text += "[" + "|".join(str(order) for order in self.orders if order != 2) + "]"
        if self.sets is not None:
            text += f"[:{self.sets.what.upper()}]"
        if self.alpha != "none":
            text += "=<number>" if self.alpha == "required" else "[=<number>]"
        if self.rescalable:
            text += "[+rescale[@N]]"
        return text


def _make_rattle(spec: IntegratorSpec, timestep: unit.Quantity, tolerance: float) -> mm.Integrator:
    return RattleIntegrator(
        timestep, constraint_tolerance=tolerance, order=spec.order, composition=spec.composition
    )


def _make_split(spec: IntegratorSpec, timestep: unit.Quantity, tolerance: float) -> mm.Integrator:
    return SplittingRattleIntegrator(
        timestep,
        alpha=spec.alpha if spec.splitting is None else None,
        constraint_tolerance=tolerance,
        splitting=spec.splitting,
    )


def _make_alpha(spec: IntegratorSpec, timestep: unit.Quantity, tolerance: float) -> mm.Integrator:
    return AlphaRattleIntegrator(
        timestep,
        alpha=spec.alpha,
        constraint_tolerance=tolerance,
        order=spec.order,
        composition=spec.composition,
    )


def _make_energy(spec: IntegratorSpec, timestep: unit.Quantity, tolerance: float) -> mm.Integrator:
    return AlphaRattleEnergyIntegrator(
        timestep, constraint_tolerance=tolerance, order=spec.order, composition=spec.composition
    )


def _make_verlet(spec: IntegratorSpec, timestep: unit.Quantity, tolerance: float) -> mm.Integrator:
    integrator = mm.VerletIntegrator(timestep)
    integrator.setConstraintTolerance(tolerance)
    return integrator


#: The families of the grammar, in the order ``--help`` lists them.
FAMILIES: dict[str, Family] = {
    family.word: family
    for family in (
        Family(
            "rattle",
            "RATTLE",
            "RattleIntegrator: velocity Verlet with SHAKE/SETTLE and RATTLE velocities, 1 force evaluation "
            "per step; rattle4, rattle6: a composition of RATTLE steps of that order (one evaluation per "
            "stage)",
            _make_rattle,
            orders=(2, 4, 6),
            sets=COMPOSITIONS,
            rescalable=True,
        ),
        Family(
            "alpha",
            "α-RATTLE",
            "AlphaRattleIntegrator with a fixed alpha, fractions allowed (alpha=1/6; alpha=0 is RATTLE); "
            "alpha4, alpha6: alpha on the middle stage of the order's composition (alpha4=0 is the "
            "composition of RATTLE steps)",
            _make_alpha,
            orders=(2, 4, 6),
            sets=COMPOSITIONS,
            alpha="required",
        ),
        Family(
            "energy",
            "α-RATTLE",
            "AlphaRattleEnergyIntegrator: alpha chosen every step to hold H at E_ref (a midpoint and an "
            "end force per trial of alpha; the run's table gives the evaluations per step); energy4, "
            "energy6 on the order's composition",
            _make_energy,
            orders=(2, 4, 6),
            sets=COMPOSITIONS,
        ),
        Family(
            "split",
            "splitting",
            "SplittingRattleIntegrator, the explicit alpha-family: split=<alpha> is kick((1/2-alpha)h) "
            "drift(h/2) kick(2 alpha h) drift(h/2) kick((1/2-alpha)h) with constraints (split=1/4 is RATTLE "
            "at h/2), split:SPLITTING a named splitting (split:me2, the minimum-error member, is the "
            "default), one force evaluation per stage, no iteration",
            _make_split,
            sets=SPLITTINGS,
            alpha="optional",
            rescalable=True,
        ),
        Family("verlet", "VerletIntegrator", VERLET_IS_LEAPFROG, _make_verlet),
    )
}


@dataclass(frozen=True)
class Layer:
    """A way of holding the energy over a base step, written ``+WORD[@N]`` after it.

    Attributes
    ----------
    word
        The word after ``+``.
    cls
        The integrator class: takes the base as ``order``/``composition`` or ``splitting``
        and the interval as ``rescale_interval`` (as :class:`~openmm_alphaprk.RattleRescaleIntegrator`).
    title
        The label's last words (``rescaling``).
    help
        What it does, for ``--help``.
    """

    word: str
    cls: type[RattleRescaleIntegrator]
    title: str
    help: str

    def make(self, spec: IntegratorSpec, timestep: unit.Quantity, tolerance: float) -> mm.Integrator:
        """Create the layer over the base ``spec`` names."""
        return self.cls(
            timestep,
            constraint_tolerance=tolerance,
            order=spec.order,
            composition=spec.composition,
            rescale_interval=spec.rescale_interval,
            splitting=spec.splitting,
        )


#: The ways of holding the energy over a base (``+rescale[@N]``), by word.
LAYERS: dict[str, Layer] = {}


def register_layer(layer: Layer) -> Layer:
    """Add a way of holding the energy to the grammar (``BASE+WORD[@N]``); return it."""
    if layer.word in LAYERS and LAYERS[layer.word] != layer:
        raise InputError(f"a layer {layer.word!r} exists already; give the new one another word.")
    LAYERS[layer.word] = layer
    register_integrator_class(layer.cls)  # restore_integrator gives its programs their class back
    return layer


register_layer(
    Layer(
        "rescale",
        RattleRescaleIntegrator,
        "rescaling",
        "RattleRescaleIntegrator: after the base step the velocities relative to the rigid-body motion "
        "are scaled so that H = E_ref, every step or every N-th step (+rescale@10)",
    )
)

#: Names from before the grammar, and the canonical names they are read as.
ALIASES = {
    "split-me": "split:me2",
    "split-bcss": "split:bcss2",
    "split3-me": "split:me3",
    "split3-bcss": "split:bcss3",
}

#: The grammar's forms, one per family (``rattle[4|6][:COMPOSITION][+rescale[@N]]`` …).
VOCABULARY = tuple(family.form for family in FAMILIES.values())
#: The forms, for ``--help``.
INTEGRATOR_NAMES = ", ".join(VOCABULARY)


def _integrator_help() -> str:
    sets = "; ".join(
        f"{library.what.upper()} one of {', '.join(library)}" for library in (COMPOSITIONS, SPLITTINGS)
    )
    families = "; ".join(f"{family.form} = {family.help}" for family in FAMILIES.values())
    layers = "; ".join(f"+{layer.word}[@N] = {layer.help}" for layer in LAYERS.values())
    return f"BASE[:SET][=alpha][+rescale[@N]], the digit the order: {families}; {layers}; {sets}"


#: One line per family and the named sets, for ``--help``.
INTEGRATOR_HELP = _integrator_help()


def _unknown(text: object, why: str) -> UnknownIntegratorError:
    """Return the one error for a name the grammar does not read: why, then the grammar and examples."""
    return UnknownIntegratorError(
        f"unknown integrator {text!r}: {why}. Names are BASE[:SET][=alpha][+rescale[@N]]: {INTEGRATOR_NAMES} "
        f"(compositions: {', '.join(COMPOSITIONS)}; splittings: {', '.join(SPLITTINGS)}); e.g. rattle, "
        "rattle+rescale@10, rattle4+rescale, alpha=1/6, alpha4=0, energy4:triple-jump, split:me2+rescale, "
        "verlet."
    )


def _number(text: object, number: str) -> float:
    try:
        value = float(Fraction(number)) if re.fullmatch(r"[-+0-9.e/]+", number) else None
    except (ValueError, ZeroDivisionError):
        value = None
    if value is None or value != value or abs(value) == float("inf"):
        raise _unknown(text, f"alpha must be a finite number or fraction, got {number!r}")
    return value


def _canonical_text(cleaned: str) -> str:
    """Read names from before the grammar as canonical (:data:`ALIASES`, a set after =α or +rescale)."""
    for old, new in ALIASES.items():
        if cleaned == old or cleaned.startswith((old + "+", old + "@")):
            cleaned = new + cleaned[len(old) :]
    after_alpha = re.fullmatch(r"([a-z]+[0-9]*)=([^:+@]+):([^+@]+)(.*)", cleaned)
    if after_alpha is not None:  # alpha4=0:triple-jump
        base, number, chosen, rest = after_alpha.groups()
        cleaned = f"{base}:{chosen}={number}{rest}"
    moved = re.fullmatch(r"([^:+]+)\+rescale(@[^:]*)?:([^@]+)(@.*)?", cleaned)
    if moved is not None:
        base, at_before, chosen, at_after = moved.groups()
        cleaned = f"{base}:{chosen}+rescale{at_before or ''}{at_after or ''}"
    return cleaned


def parse_integrator(text: str | IntegratorSpec) -> IntegratorSpec:
    """Parse an integrator name, ``BASE[:SET][=α][+rescale[@N]]`` (any case; white space is ignored).

    Raises
    ------
    UnknownIntegratorError
        Naming what is wrong, with the grammar, the named sets and examples.
    """
    if isinstance(text, IntegratorSpec):
        return text
    cleaned = _canonical_text(re.sub(r"\s+", "", str(text)).lower())
    base, plus, layer_text = cleaned.partition("+")
    interval = None
    layer = None
    if plus:
        found = re.fullmatch(r"([a-z]+)(?:@(.*))?", layer_text)
        layer = LAYERS.get(found.group(1)) if found else None
        if layer is None:
            raise _unknown(
                text,
                f"{'+' + layer_text!r} is not a way of holding the energy; use "
                + " or ".join(f"+{word}[@N]" for word in LAYERS),
            )
        if found.group(2) is not None:
            if not re.fullmatch(r"[0-9]+", found.group(2)) or int(found.group(2)) < 1:
                raise _unknown(
                    text,
                    "the rescaling interval after '@' must be a positive integer, the rescaling every N-th "
                    "step (rattle+rescale@10)",
                )
            interval = int(found.group(2))
    elif "@" in base:
        raise _unknown(text, "only a rescaled name takes an interval @N (rattle+rescale@10)")
    head, equals, number = base.partition("=")
    named, colon, chosen = head.partition(":")
    word_digit = re.fullmatch(r"([a-z]+)([0-9]*)", named)
    family = FAMILIES.get(word_digit.group(1)) if word_digit else None
    if family is None:
        raise _unknown(text, f"no integrator family {named!r}")
    order = int(word_digit.group(2)) if word_digit.group(2) else 2
    if order not in family.orders or word_digit.group(2) == "2":
        raise _unknown(
            text,
            f"{family.word} takes "
            + (
                "no order"
                if len(family.orders) == 1
                else "order " + " or ".join(str(order) for order in family.orders if order != 2)
            ),
        )
    composition = splitting = None
    if colon:
        if family.sets is None or (family.sets is COMPOSITIONS and order == 2):
            raise _unknown(
                text, f"{named} takes no set (a composition needs an order: {family.word}4:triple-jump)"
            )
        if chosen not in family.sets:
            raise _unknown(text, f"no {family.sets.what} {chosen!r}")
        if family.sets is COMPOSITIONS:
            if COMPOSITIONS[chosen].order != order:
                fitting = [c.name for c in COMPOSITIONS.values() if c.order == order]
                raise _unknown(text, f"{chosen!r} is not of order {order}; use one of {', '.join(fitting)}")
            composition = chosen
        else:
            splitting = chosen
    alpha = None
    if equals:
        if family.alpha == "none":
            raise _unknown(text, f"{named} takes no alpha")
        if splitting is not None:
            raise _unknown(text, "give a splitting or alpha, not both")
        alpha = _number(text, number)
    elif family.alpha == "required":
        raise _unknown(text, f"{named} needs alpha ({named}=0.1)")
    if family.word == "split" and alpha is None and splitting is None:
        splitting = MINIMUM_ERROR2.name
        base = f"split:{splitting}"
    if layer is not None and not family.rescalable:
        raise _unknown(
            text, f"+{layer.word} follows rattle (and its compositions) or a splitting, not {family.word}"
        )
    if layer is not None and alpha is not None:
        raise _unknown(
            text, f"+{layer.word} follows a named splitting (split:me2+{layer.word}), not split=<alpha>"
        )
    held = f"+{layer.word}" + (f"@{interval}" if interval and interval > 1 else "") if layer else ""
    return IntegratorSpec(
        layer.word if layer else family.word,
        alpha,
        text=base + held,
        order=order,
        composition=composition,
        rescale_interval=interval or 1,
        splitting=splitting,
        layer=layer.word if layer else None,
    )


def label(spec: str | IntegratorSpec) -> str:
    """Return the display label of an integrator name: ``alpha=1/6`` → ``α-RATTLE α = 1/6``.

    The one set of labels the benchmarks, reports and figures use (``RATTLE``,
    ``RATTLE + rescaling``, ``RATTLE + rescaling every 10 steps``, ``VerletIntegrator``,
    ``α-RATTLE α = x``, ``α-RATTLE-4 α = x``, ``α-RATTLE energy mode``, a splitting's own
    label); ``x`` is written as given (fractions kept).
    """
    spec = parse_integrator(spec)
    family = spec.family
    if spec.splitting is not None:
        text = SPLITTINGS.lookup(spec.splitting).label
    elif family.word == "split":
        text = f"splitting α = {spec.name.partition('=')[2]}"
    else:
        text = family.title + (f"-{spec.order}" if spec.order != 2 else "")
        if spec.composition is not None:
            text += f" ({spec.composition})"
        if spec.kind == "alpha":
            text += f" α = {spec.name.partition('=')[2]}"
        elif spec.kind == "energy":
            text += " energy mode"
    if spec.layer is not None:
        every = f" every {spec.rescale_interval} steps" if spec.rescale_interval > 1 else ""
        text += f" + {LAYERS[spec.layer].title}{every}"
    return text


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
    if spec.layer is not None:
        return LAYERS[spec.layer].make(spec, timestep, constraint_tolerance)
    return spec.family.make(spec, timestep, constraint_tolerance)


def example_names() -> tuple[str, ...]:
    """Return a name of every form the grammar reads: each family, order, kind of set and layer.

    The names the tests run every integrator by (stability, invariants, force evaluations)
    and the step programs stored as golden listings; every named splitting is among them.
    """
    names = ["rattle", "rattle4", "rattle6", "rattle4:triple-jump", "rattle+rescale", "rattle+rescale@10"]
    names += ["rattle4+rescale", "rattle6+rescale", "rattle4:triple-jump+rescale@10"]
    names += [
        "alpha=0",
        "alpha=0.1",
        "alpha4=0",
        "alpha4=0.01",
        "alpha4:triple-jump=0",
        "alpha4:triple-jump=0.01",
    ]
    names += ["alpha6=0", "energy", "energy4", "energy4:triple-jump", "split=0.25"]
    names += [f"split:{name}" for name in SPLITTINGS] + [f"split:{name}+rescale" for name in SPLITTINGS]
    names += ["split:me3+rescale@10", "verlet"]
    return tuple(names)


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
    if (
        spec.kind in ("rattle", "split")
        or spec.layer is not None
        or (spec.kind == "alpha" and spec.alpha == 0.0)
    ):
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
