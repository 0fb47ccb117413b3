"""Symmetric kick-drift splittings with constraints: the explicit α-family as data.

A splitting of velocity-Verlet type with s stages is the symmetric sequence::

    kick(b_0 h) · drift(a_1 h) · kick(b_1 h) · drift(a_2 h) · … · drift(a_s h) · kick(b_s h)

with Σ a_i = Σ b_j = 1, a_i = a_(s+1−i) and b_j = b_(s−j). Each drift is followed by
SHAKE/SETTLE and the velocity correction (x − x_start)/(a_i h), each kick by RATTLE's
velocity projection; the last kick's force is the next step's first, so a step costs s
force evaluations. Every such splitting is symplectic (a composition of symplectic maps),
symmetric, keeps the constraints and the momenta, and is of second order.

The two-stage member kick((½−α)h) · drift(h/2) · kick(2αh) · drift(h/2) · kick((½−α)h) is
α-RATTLE's quadrature — weights (½−α, 2α, ½−α) at (0, ½, 1) — with the implicit midpoint
replaced by the explicit half-drift point: :func:`two_stage`. α = ¼ is two RATTLE steps
of h/2. The named sets (:data:`SPLITTINGS`): the two-stage minimum-error splitting
(McLachlan 1995), Blanes, Casas & Sanz-Serna's two- and three-stage splittings (2014), the
three-stage minimum-error splitting (Predescu et al. 2012), and RATTLE at h/2 and h/3 as
two- and three-stage splittings. The OpenMM step programs
(:mod:`~.splitting_rattle`, :mod:`~.rescale`) and the NumPy reference
(:mod:`openmm_alphaprk.reference.splitting`) both take their sub-steps from
:meth:`Splitting.substeps`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from .._units import InputError
from .stage_sets import Library, StageSet, SubStep

#: McLachlan's minimum-error two-stage kick, b = ½ − α (SIAM J. Sci. Comput. 16 (1995) 151).
MCLACHLAN_B = 0.1931833275037836
#: Blanes, Casas & Sanz-Serna's two-stage kick, b = ½ − α (SIAM J. Sci. Comput. 36 (2014) A1556).
BCSS2_B = 0.211781


@dataclass(frozen=True)
class Splitting(StageSet):
    """A symmetric kick-drift splitting of velocity-Verlet type, with constraints.

    Attributes
    ----------
    name
        The name it is looked up by (``splitting=`` of the integrators).
    kicks
        b_0, …, b_s: kick j is a velocity update of b_j h with the force at the positions
        after drift j (b_0: at the step's start).
    drifts
        a_1, …, a_s: drift i moves the positions by a_i h times the velocities.
    order
        The order of the splitting (2 for every set here).
    source
        Where the coefficients come from.
    label
        How tables and figures name it (default ``splitting <name>``).
    """

    name: str
    kicks: tuple[float, ...]
    drifts: tuple[float, ...]
    order: int
    source: str
    label: str = ""
    what: ClassVar[str] = "splitting"
    record_prefix: ClassVar[str] = "splitting_drift_"

    def __post_init__(self) -> None:
        kicks, drifts = tuple(map(float, self.kicks)), tuple(map(float, self.drifts))
        object.__setattr__(self, "label", self.label or f"splitting {self.name}")
        object.__setattr__(self, "kicks", kicks)
        object.__setattr__(self, "drifts", drifts)
        if not drifts or len(kicks) != len(drifts) + 1:
            raise InputError(
                f"splitting {self.name!r}: give s drifts and s + 1 kicks, got {len(drifts)} and {len(kicks)}."
            )
        if any(a == 0.0 for a in drifts):
            raise InputError(f"splitting {self.name!r}: drifts must be non-zero.")
        self._check_palindrome("kicks", kicks)
        self._check_palindrome("drifts", drifts)

    @property
    def stages(self) -> int:
        """The number of drifts s: force evaluations per step."""
        return len(self.drifts)

    @property
    def alpha(self) -> float | None:
        """α of a two-stage splitting with equal drifts (b_0 = ½ − α); None for any other."""
        if self.stages == 2:
            return 0.5 - self.kicks[0]
        return None

    def substeps(self) -> tuple[SubStep, ...]:
        """Return the splitting as s constrained sub-steps (c_i, p_i, q_i), the form the programs take.

        Sub-step i is a step of c_i h = a_i h from (x0, v0), F0 = F(x0)::

            x = x0 + c h v0 + (c h)² p M⁻¹F0, SHAKE along G(x0)
            v = (x − x0)/(c h) + c h q M⁻¹F(x), RATTLE projection at x

        It takes drift i with the kick before it (whole for the first drift, its second half
        for the others) and the kick after it (whole for the last drift, its first half for
        the others): p_i c_i = kick before, q_i c_i = kick after. Splitting a kick between two
        sub-steps is the same map: the projection in between changes the velocity along
        G(x0)ᵀ only, which the next SHAKE's multiplier takes up. α = ¼ gives
        (½, ½, ½) twice: RATTLE's step of h/2, coefficient for coefficient.
        """
        s = self.stages
        result = []
        for i, c in enumerate(self.drifts, start=1):
            before = self.kicks[0] if i == 1 else 0.5 * self.kicks[i - 1]
            after = self.kicks[s] if i == s else 0.5 * self.kicks[i]
            result.append((c, before / c, after / c))
        return tuple(result)

    def recorded(self) -> dict[str, float]:
        """Return the kicks and drifts as globals ``splitting_kick_<j>``, ``splitting_drift_<i>``."""
        values = {f"splitting_kick_{j}": b for j, b in enumerate(self.kicks)}
        values.update({f"splitting_drift_{i}": a for i, a in enumerate(self.drifts, start=1)})
        return values

    @classmethod
    def from_record(cls, values: dict[str, float], library: Library) -> Splitting | None:
        """Return the splitting a program's globals record (:meth:`recorded`); None without one."""
        stages = sum(name.startswith(cls.record_prefix) for name in values)
        if not stages:
            return None
        kicks = tuple(values[f"splitting_kick_{j}"] for j in range(stages + 1))
        drifts = tuple(values[f"splitting_drift_{i}"] for i in range(1, stages + 1))
        known = library.find(lambda s: s.kicks == kicks and s.drifts == drifts)
        if known is not None:
            return known
        if stages == 2 and drifts == (0.5, 0.5):
            return two_stage(0.5 - kicks[0])
        return cls("restored", kicks, drifts, 2, "read back from the step program")

    def listing(self) -> str:
        """One line: the name, the order, the kicks and drifts in step order."""
        parts = [f"kick {self.kicks[0]:.6g}"]
        for a, b in zip(self.drifts, self.kicks[1:]):
            parts += [f"drift {a:.6g}", f"kick {b:.6g}"]
        return f"{self.name}: order {self.order}, {self.stages} stages ({', '.join(parts)})"


def two_stage(
    alpha: float, name: str | None = None, source: str = "α-RATTLE's quadrature", label: str = ""
) -> Splitting:
    """Return the two-stage member of the explicit α-family: kicks (½−α, 2α, ½−α), drifts (½, ½).

    Parameters
    ----------
    alpha : float
        α: the weight of the half-step force is 2α.
    name : str, optional
        Default ``split=<alpha>``.
    source : str
        Where α comes from.
    label : str, optional
        How tables name it (default ``splitting α = <alpha>`` for an unnamed member).

    Returns
    -------
    Splitting
        The splitting; α = ¼ is two RATTLE steps of h/2.

    Examples
    --------
    >>> from openmm_alphaprk.integrators.splittings import two_stage
    >>> print(two_stage(0.25).listing())
    split=0.25: order 2, 2 stages (kick 0.25, drift 0.5, kick 0.5, drift 0.5, kick 0.25)
    >>> two_stage(0.25).substeps()  # RATTLE at h/2, twice
    ((0.5, 0.5, 0.5), (0.5, 0.5, 0.5))
    """
    alpha = float(alpha)
    if not math.isfinite(alpha):
        raise InputError(f"alpha must be a finite number, got {alpha!r}.")
    return Splitting(
        name if name is not None else f"split={alpha!r}",
        (0.5 - alpha, 2.0 * alpha, 0.5 - alpha),
        (0.5, 0.5),
        2,
        source,
        label or (f"splitting α = {alpha!r}" if name is None else ""),
    )


def composed(base: Splitting, weights: tuple[float, ...], name: str, order: int, source: str) -> Splitting:
    """Return the composition base(w_1 h) · … · base(w_m h) as one splitting, adjacent kicks merged.

    The last kick of each stage and the first of the next act at the same positions, so
    they add up: m stages of an s-stage splitting are one splitting of m·s drifts (a
    negative weight gives negative drifts: that stage runs backwards in time, as in a
    composition of RATTLE steps) and m·s force evaluations per step.

    Parameters
    ----------
    base : Splitting
        The splitting composed.
    weights : tuple of float
        The stages' step fractions w_i (sum 1, symmetric), e.g. a composition's coefficients.
    name, order, source
        The result's name, order and where the weights come from.

    Examples
    --------
    >>> from openmm_alphaprk.integrators.splittings import RATTLE2, composed
    >>> twice = composed(RATTLE2, (0.5, 0.5), "rattle/4", 2, "two steps of RATTLE/2 at h/2")
    >>> twice.kicks, twice.drifts  # four RATTLE steps of h/4
    ((0.125, 0.25, 0.25, 0.25, 0.125), (0.25, 0.25, 0.25, 0.25))
    """
    kicks, drifts = [0.0], []
    for w in weights:
        kicks[-1] += w * base.kicks[0]
        for a, b in zip(base.drifts, base.kicks[1:]):
            drifts.append(w * a)
            kicks.append(w * b)
    return Splitting(name, tuple(kicks), tuple(drifts), order, source)


def _three_stage(name: str, a: float, b: float, source: str, label: str = "") -> Splitting:
    """kick(b) drift(a) kick(½−b) drift(1−2a) kick(½−b) drift(a) kick(b)."""
    return Splitting(name, (b, 0.5 - b, 0.5 - b, b), (a, 1.0 - 2.0 * a, a), 2, source, label)


#: RATTLE itself: one sub-step, kick(h/2) drift(h) kick(h/2) (the base step of RattleIntegrator).
RATTLE = Splitting(
    "rattle",
    (0.5, 0.5),
    (1.0,),
    2,
    "velocity Verlet with SHAKE and RATTLE: Ryckaert, Ciccotti & Berendsen, J. Comput. Phys. 23 (1977) "
    "327; Andersen, J. Comput. Phys. 52 (1983) 24",
    "RATTLE",
)
RATTLE2 = two_stage(
    0.25, "rattle/2", "two RATTLE steps of h/2 (the two-stage splitting with α = 1/4)", "RATTLE at h/2, twice"
)
MINIMUM_ERROR2 = two_stage(
    0.5 - MCLACHLAN_B,
    "me2",
    "the minimum-error two-stage splitting, b = 0.1931833275037836 (alpha = 0.3068166724962164): "
    "McLachlan, SIAM J. Sci. Comput. 16 (1995) 151; Omelyan, Mryglod & Folk, Phys. Rev. E 65 "
    "(2002) 056706",
    "splitting, minimum error (α = 0.3068)",
)
BCSS2 = two_stage(
    0.5 - BCSS2_B,
    "bcss2",
    "Blanes, Casas & Sanz-Serna, SIAM J. Sci. Comput. 36 (2014) A1556, the two-stage integrator, "
    "b = 0.211781 (alpha = 0.288219)",
    "splitting, BCSS (α = 0.2882)",
)
RATTLE3 = _three_stage(
    "rattle/3", 1.0 / 3.0, 1.0 / 6.0, "three RATTLE steps of h/3", "RATTLE at h/3, three times"
)
MINIMUM_ERROR3 = _three_stage(
    "me3",
    0.290485609075128726,
    0.108991425403425322,
    "the minimum-error three-stage splitting, drift a = 0.290485609075128726, kick b = "
    "0.108991425403425322: Predescu, Lippert, Eastwood, Ierardi, Xu, Jensen, Bergdorf, Tillman & "
    "Shaw, Mol. Phys. 110 (2012) 967, eq. 26 (where the kick is called a and the drift b); written "
    "here in the form kick(b) drift(a) kick(1/2-b) drift(1-2a) kick(1/2-b) drift(a) kick(b) of Blanes, "
    "Casas & Sanz-Serna (2014)",
    "3-stage splitting, minimum error",
)
BCSS3 = _three_stage(
    "bcss3",
    0.29619504261126,
    0.11888010966548,
    "Blanes, Casas & Sanz-Serna, SIAM J. Sci. Comput. 36 (2014) A1556, the three-stage integrator "
    "kick(b) drift(a) kick(1/2-b) drift(1-2a) kick(1/2-b) drift(a) kick(b), drift a = 0.29619504261126, "
    "kick b = 0.11888010966548",
    "3-stage splitting, BCSS",
)

#: The named splittings, by name.
SPLITTINGS: Library[Splitting] = Library(
    "splitting", (RATTLE2, MINIMUM_ERROR2, BCSS2, RATTLE3, MINIMUM_ERROR3, BCSS3)
)


def splitting(name: str | Splitting) -> Splitting:
    """Return the named splitting (a :class:`Splitting` is returned as it is).

    Parameters
    ----------
    name : str or Splitting
        A name of :data:`SPLITTINGS`.

    Examples
    --------
    >>> from openmm_alphaprk.integrators.splittings import splitting
    >>> print(splitting("bcss3").listing())  # doctest: +NORMALIZE_WHITESPACE
    bcss3: order 2, 3 stages (kick 0.11888, drift 0.296195, kick 0.38112, drift 0.40761,
    kick 0.38112, drift 0.296195, kick 0.11888)
    >>> round(splitting("me2").alpha, 6)
    0.306817
    """
    return SPLITTINGS.lookup(name)
