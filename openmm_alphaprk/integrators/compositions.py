"""Symmetric compositions of RATTLE steps: the higher-order members as data.

A composition Φ_h = Ψ_{c_s h} ∘ … ∘ Ψ_{c_1 h} of a symmetric second-order step Ψ
(RATTLE, α-RATTLE) with symmetric coefficients (c_i = c_{s+1−i}) and Σ c_i = 1 is of
order 4 when Σ c_i³ = 0, and of higher order under further conditions
(Hairer, Lubich & Wanner, *Geometric Numerical Integration*, 2nd ed., Section V.3).
α goes on one stage or on several (:attr:`Composition.alpha_stages`); the other stages
are RATTLE steps. Every stage takes one force evaluation (α ≠ 0 adds the midpoint
forces of its stages).

The named sets are :data:`COMPOSITIONS`; :func:`composition` looks one up. The OpenMM
step programs (:mod:`~.pieces`, :mod:`~.alpha_rattle`) and the NumPy reference
(:mod:`openmm_alphaprk.reference.composition`) both take their sub-steps from here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar

from .._units import InputError
from .stage_sets import Library, StageSet, SubStep

_CBRT2 = 2.0 ** (1.0 / 3.0)
_SUZUKI_P = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))


@dataclass(frozen=True)
class Composition(StageSet):
    """A symmetric composition of a symmetric second-order step.

    Attributes
    ----------
    name
        The name it is looked up by (``composition=`` of the integrators, the
        command line's ``composition:NAME``).
    coefficients
        c_1, …, c_s: stage i is a step of c_i h.
    order
        The order of the composition with α = 0 on every stage.
    source
        Where the coefficients come from.
    alpha_stages
        The stages (1-based) whose step carries α; the others are RATTLE steps.
        Default: the middle stage.
    """

    name: str
    coefficients: tuple[float, ...]
    order: int
    source: str
    alpha_stages: tuple[int, ...] = field(default=())
    what: ClassVar[str] = "composition"
    record_prefix: ClassVar[str] = "stage_coefficient_"

    def __post_init__(self) -> None:
        c = tuple(map(float, self.coefficients))
        object.__setattr__(self, "coefficients", c)
        self._check_palindrome("coefficients", c)
        stages = self.alpha_stages or ((len(c) + 1) // 2,)
        if any(not 1 <= k <= len(c) for k in stages) or len(set(stages)) != len(stages):
            raise InputError(
                f"composition {self.name!r}: alpha stages must be distinct stage numbers 1..{len(c)}, "
                f"got {self.alpha_stages!r}."
            )
        object.__setattr__(self, "alpha_stages", tuple(sorted(stages)))

    def substeps(self) -> tuple[SubStep, ...]:
        """Return the stages as RATTLE sub-steps (c_i, ½, ½) (the α stages too: their α = 0 form)."""
        return tuple((c, 0.5, 0.5) for c in self.coefficients)

    @property
    def first_alpha_stage(self) -> int:
        """The first stage that carries α; the stages before it are taken once per step."""
        return self.alpha_stages[0]

    @property
    def largest_substep(self) -> float:
        """Max |c_i|: the largest sub-step in units of h (what limits the stable step)."""
        return max(abs(c) for c in self.coefficients)

    def with_alpha_on(self, stages: str | tuple[int, ...]) -> Composition:
        """Return the same composition with α on ``stages``: ``"middle"``, ``"all"`` or stage numbers."""
        if stages == "middle":
            chosen: tuple[int, ...] = ((self.stages + 1) // 2,)
        elif stages == "all":
            chosen = tuple(range(1, self.stages + 1))
        elif isinstance(stages, str):
            raise InputError(f"alpha stages must be 'middle', 'all' or stage numbers, got {stages!r}.")
        else:
            chosen = tuple(int(k) for k in stages)
        return replace(self, alpha_stages=chosen)

    def recorded(self) -> dict[str, float]:
        """Return the coefficients and α stages as ``stage_coefficient_<i>``, ``alpha_on_stage_<i>``."""
        values = {}
        for i, c in enumerate(self.coefficients, start=1):
            values[f"stage_coefficient_{i}"] = c
            values[f"alpha_on_stage_{i}"] = float(i in self.alpha_stages)
        return values

    @classmethod
    def from_record(cls, values: dict[str, float], library: Library) -> Composition | None:
        """Return the composition a program's globals record (:meth:`recorded`); None without one."""
        stages = sum(name.startswith(cls.record_prefix) for name in values)
        if not stages:
            return None
        coefficients = tuple(values[f"stage_coefficient_{i}"] for i in range(1, stages + 1))
        on = tuple(i for i in range(1, stages + 1) if values[f"alpha_on_stage_{i}"])
        known = library.find(lambda c: c.coefficients == coefficients)
        if known is not None:
            return known.with_alpha_on(on)
        order = int(values.get("order", 0))
        return cls("restored", coefficients, order, "read back from the step program", on)

    def listing(self) -> str:
        """One line: the name, the order and the coefficients, α's stages marked."""
        parts = [
            f"{c:.6g}{'(α)' if i + 1 in self.alpha_stages else ''}" for i, c in enumerate(self.coefficients)
        ]
        return f"{self.name}: order {self.order}, {self.stages} stages ({', '.join(parts)})"


def _mirror(first_half: tuple[float, ...]) -> tuple[float, ...]:
    """(c_1, …, c_m), c_m the middle stage → the symmetric (c_1, …, c_m, …, c_1)."""
    return first_half + first_half[-2::-1]


TRIPLE_JUMP = Composition(
    "triple-jump",
    (1.0 / (2.0 - _CBRT2), -_CBRT2 / (2.0 - _CBRT2), 1.0 / (2.0 - _CBRT2)),
    4,
    "Yoshida, Phys. Lett. A 150 (1990) 262; Creutz & Gocksch, Phys. Rev. Lett. 63 (1989) 9",
)
SUZUKI5 = Composition(
    "suzuki5",
    (_SUZUKI_P, _SUZUKI_P, 1.0 - 4.0 * _SUZUKI_P, _SUZUKI_P, _SUZUKI_P),
    4,
    "Suzuki, Phys. Lett. A 146 (1990) 319: (p, p, 1 − 4p, p, p), p = 1/(4 − 4^(1/3))",
)

MCLACHLAN5 = Composition(
    "mclachlan5",
    _mirror((0.28, 0.62546642846767004501, -0.81093285693534009002)),
    4,
    "McLachlan, SIAM J. Sci. Comput. 16 (1995) 151, the 5-stage order-4 set, as quoted in Leimkuhler & "
    "Reich, Simulating Hamiltonian Dynamics (2004), Table 6.2",
)
KAHAN_LI_S9ODR6A = Composition(
    "kahan-li-s9odr6a",
    _mirror(
        (
            0.39216144400731413927925056,
            0.33259913678935943859974864,
            -0.70624617255763935980996482,
            0.08221359629355080023149045,
            0.79854399093482996339895035,
        )
    ),
    6,
    "Kahan & Li, Math. Comp. 66 (1997) 1089, s9odr6a; Hairer, Lubich & Wanner, GNI, eq. V.3.12",
)
YOSHIDA7 = Composition(
    "yoshida7",
    _mirror(
        (
            0.78451361047755726381949763,
            0.23557321335935813368479318,
            -1.17767998417887100694641568,
            1.31518632068391121888424973,
        )
    ),
    6,
    "Yoshida, Phys. Lett. A 150 (1990) 262, order 6, solution A; Hairer, Lubich & Wanner, GNI, eq. V.3.11",
)
MCLACHLAN9 = Composition(
    "mclachlan9",
    _mirror(
        (
            0.1867,
            0.55549702371247839916,
            0.12946694891347535806,
            -0.84326562338773460855,
            0.9432033015235617027,
        )
    ),
    6,
    "McLachlan, SIAM J. Sci. Comput. 16 (1995) 151, the 9-stage order-6 set",
)

#: The named compositions, by name.
COMPOSITIONS: Library[Composition] = Library(
    "composition", (TRIPLE_JUMP, SUZUKI5, MCLACHLAN5, YOSHIDA7, KAHAN_LI_S9ODR6A, MCLACHLAN9)
)


def composition(name: str | Composition) -> Composition:
    """Return the named composition (a :class:`Composition` is returned as it is)."""
    return COMPOSITIONS.lookup(name)


#: The composition ``order=4`` and ``order=6`` give.
DEFAULT_COMPOSITIONS: dict[int, str] = {4: "suzuki5", 6: "mclachlan9"}


def requested_composition(order: object, name: str | Composition | None) -> Composition | None:
    """Return the composition that an integrator's ``order`` and ``composition`` options ask for.

    None for one step (``order`` None or 2 and no name); the order's default composition
    (:data:`DEFAULT_COMPOSITIONS`) for ``order`` 4 or 6; the named one otherwise, whose
    order must agree with an ``order`` given beside it.
    """
    if order is not None and (isinstance(order, bool) or order not in (2, 4, 6)):
        raise InputError(f"order must be 2 (one step), 4 or 6 (a composition of steps), got {order!r}.")
    if name is None and order in (None, 2):
        return None
    chosen = composition(DEFAULT_COMPOSITIONS[order] if name is None else name)
    if order is not None and order != chosen.order:
        raise InputError(
            f"composition {chosen.name!r} is of order {chosen.order}, but order={order} was given; "
            "leave order out or give a composition of that order."
        )
    return chosen
