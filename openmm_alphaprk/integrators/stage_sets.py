"""What compositions and splittings share: sub-steps, checks, stability, a library, a record in a program.

Every explicit base step of this package is a sequence of constrained sub-steps
(c_i, p_i, q_i), each a step of c_i h from (x0, v0) with F0 = F(x0)::

    x = x0 + c h v0 + (c h)² p M⁻¹F0, SHAKE along G(x0)
    v = (x − x0)/(c h) + c h q M⁻¹F(x), RATTLE projection at x

RATTLE is one sub-step (1, ½, ½); a composition of RATTLE steps (:mod:`~.compositions`) is
(c_i, ½, ½) for its coefficients; a kick-drift splitting (:mod:`~.splittings`) is its
drifts with the kicks around them. One emitter writes every such sequence into a step
program (:meth:`~.pieces._StepProgram._add_substeps`), and the NumPy reference takes the
same sub-steps (:mod:`openmm_alphaprk.reference`).

:class:`StageSet` is the shared base of :class:`~.compositions.Composition` and
:class:`~.splittings.Splitting`: the checks on symmetric coefficients, the number of
stages, the linear stability limit, and the record of the coefficients as globals of a
step program with its read-back. :class:`Library` is a named collection of them, the
one place a new set is added (:meth:`Library.register`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import ClassVar, Generic, TypeVar

import numpy as np
from numpy.polynomial import Polynomial

from .._units import InputError

#: One constrained sub-step: (c, p, q), a step of c h with p, q the kicks before and after per c.
SubStep = tuple[float, float, float]


class StageSet:
    """The shared base of compositions and splittings: sub-steps and what follows from them.

    A subclass is a frozen dataclass with ``name``, ``order`` and ``source`` and defines
    :meth:`substeps`, :meth:`recorded` (its coefficients as named globals) and
    :meth:`from_record` (the inverse); ``what`` names the kind in messages.
    """

    what: ClassVar[str] = "set"
    #: The prefix of the globals :meth:`recorded` names: a program with one holds such a set.
    record_prefix: ClassVar[str] = ""
    name: str
    order: int

    def substeps(self) -> tuple[SubStep, ...]:
        """Return the sub-steps (c_i, p_i, q_i) of one step, in step order."""
        raise NotImplementedError

    @property
    def stages(self) -> int:
        """The number of sub-steps s: force evaluations per step (at α = 0)."""
        return len(self.substeps())

    def _check_palindrome(self, what: str, values: tuple[float, ...]) -> None:
        """Refuse coefficients that are not finite, do not sum to 1 or are not symmetric."""
        if not values or not all(math.isfinite(x) for x in values):
            raise InputError(f"{self.what} {self.name!r}: {what} must be finite numbers, got {values!r}.")
        if abs(sum(values) - 1.0) > 1e-12:
            raise InputError(f"{self.what} {self.name!r}: {what} must sum to 1, they sum to {sum(values)!r}.")
        if any(abs(x - y) > 1e-12 for x, y in zip(values, reversed(values))):
            raise InputError(f"{self.what} {self.name!r}: {what} must be symmetric (a palindrome).")

    def stability_limit(self) -> float:
        """Return the linear stability limit ωh_max of one step on the harmonic oscillator ẍ = −ω²x.

        On ẍ = −ω²x, in the variables (x, v/ω) and with z = ωh, a kick of b h is the matrix
        [[1, 0], [−b z, 1]] and a drift of a h is [[1, a z], [0, 1]]; sub-step (c, p, q) is
        kick(p c h) · drift(c h) · kick(q c h), and one step is their product M(z) in step
        order, det M = 1. The step is stable (its powers bounded) while |tr M(z)| < 2. The
        limit is the smallest z > 0 beyond which |tr M| exceeds 2: the smallest positive root
        of tr M = ±2 after which |tr M| > 2 (a root where |tr M| touches 2 and comes back, as
        for two Verlet steps at z = 2√2 where M = −I, does not end the interval). tr M is a
        polynomial of degree 2s in z; its roots are found by :func:`numpy.roots`.

        Returns
        -------
        float
            ωh_max for a step of h (s force evaluations); ωh_max / s per force evaluation.
            Velocity Verlet (one stage) is 2; s Verlet steps of h/s (``rattle/2``,
            ``rattle/3``) are 2s, the largest any s-stage splitting can have.

        Examples
        --------
        >>> from openmm_alphaprk.integrators.splittings import splitting, two_stage
        >>> round(two_stage(0.0).stability_limit(), 12)  # α = 0: one Verlet step of h
        2.0
        >>> [round(splitting(name).stability_limit(), 12) for name in ("rattle/2", "rattle/3")]
        [4.0, 6.0]
        >>> round(splitting("me2").stability_limit(), 4)
        2.5531
        """
        one, zero, z = Polynomial([1.0]), Polynomial([0.0]), Polynomial([0.0, 1.0])

        def times(a: list[list[Polynomial]], b: list[list[Polynomial]]) -> list[list[Polynomial]]:
            return [[a[i][0] * b[0][j] + a[i][1] * b[1][j] for j in range(2)] for i in range(2)]

        def kick(b: float) -> list[list[Polynomial]]:
            return [[one, zero], [-b * z, one]]

        step = [[one, zero], [zero, one]]
        for c, before, after in self.substeps():
            for factor in (kick(before * c), [[one, c * z], [zero, one]], kick(after * c)):
                step = times(factor, step)
        trace = step[0][0] + step[1][1]
        roots = []
        for edge in (trace - 2.0, trace + 2.0):
            coefficients = edge.trim(1e-300).coef
            for r in np.roots(coefficients[::-1]):
                if abs(r.imag) <= 1e-6 * max(1.0, abs(r.real)) and r.real > 1e-9:
                    roots.append(float(r.real))
        roots.sort()
        distinct = [r for i, r in enumerate(roots) if i == 0 or r - roots[i - 1] > 1e-6 * max(1.0, r)]
        for i, r in enumerate(distinct):
            after = 0.5 * (r + distinct[i + 1]) if i + 1 < len(distinct) else r + 0.1 * max(1.0, r)
            if abs(trace(after)) > 2.0:
                return r
        return math.inf

    # ------------------------------------------------------------ record in a program
    def recorded(self) -> dict[str, float]:
        """Return the globals that keep this set in a program (names start with :attr:`record_prefix`)."""
        raise NotImplementedError

    @classmethod
    def from_record(cls, values: dict[str, float], library: Library) -> StageSet | None:
        """Return the set a program's globals ``values`` record (a known one if ``library`` has it)."""
        raise NotImplementedError


S = TypeVar("S", bound=StageSet)


class Library(dict[str, S], Generic[S]):
    """Named compositions or splittings: look one up, add one (:meth:`register`), find one by value.

    Parameters
    ----------
    what : str
        What it holds, for messages (``"composition"``, ``"splitting"``).
    members : iterable of StageSet
        The sets, each under its ``name``.
    """

    def __init__(self, what: str, members: Iterable[S]) -> None:
        super().__init__()
        self.what = what
        for member in members:
            self.register(member)

    def register(self, member: S) -> S:
        """Add ``member`` under its name (a new name, or the same set again); return it.

        The integrators, the command line (``split:NAME``, ``rattle4:NAME``) and the
        read-back of a restored program find it from then on.
        """
        known = self.get(member.name)
        if known is not None and known != member:
            raise InputError(
                f"a {self.what} named {member.name!r} exists already; give the new one another name."
            )
        self[member.name] = member
        return member

    def lookup(self, name: str | S) -> S:
        """Return the set named ``name`` (a set is returned as it is)."""
        if isinstance(name, StageSet):
            return name
        try:
            return self[name]
        except (KeyError, TypeError):
            raise InputError(f"unknown {self.what} {name!r}; the named ones are {', '.join(self)}.") from None

    def find(self, matches: Callable[[S], bool]) -> S | None:
        """Return the first set for which ``matches`` is true, None if none."""
        return next((member for member in self.values() if matches(member)), None)
