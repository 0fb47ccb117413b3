"""α-RATTLE's implicit midpoint force: its variables, the pieces that solve for it, α-RATTLE-4's sub-steps.

The α-RATTLE step from a consistent state (x0, v0) with F0 = F(x0)::

    x1 = x0 + h v0 + h² M⁻¹[(½−α) F0 + α F(x_m)] − M⁻¹ G(x0)ᵀ λ,   g(x1) = 0,   x_m = (x0+x1)/2
    v1 = (x1 − x0)/h + h M⁻¹[α F(x_m) + (½−α) F(x1)] − M⁻¹ G(x1)ᵀ μ,  G(x1) v1 = 0

The midpoint force is found by fixed-point iteration: the position solve (a
:class:`~.base.StepProgram` piece) and the midpoint block (:meth:`MidpointProgram._add_midpoint_force`)
alternate in a ``while`` loop, in the order that rules 1–3 of :mod:`~.base` require.
α-RATTLE-4 takes the sub-steps Ψ^0_{γ1 h} ∘ Ψ^α_{γ2 h} ∘ Ψ^0_{γ1 h}, the
last two in one loop; the sub-step pieces are here too.
"""

from __future__ import annotations

import openmm.unit as unit

from .._units import to_dimensionless, to_float
from ..observables import positive_int
from .base import StepProgram
from .triple_jump import GAMMA1, GAMMA2

#: Sub-step sizes of α-RATTLE-4: Ψ^0_{γ1 h} ∘ Ψ^α_{γ2 h} ∘ Ψ^0_{γ1 h}.
OUTER_H = f"({GAMMA1!r}*dt)"
MIDDLE_H = f"({GAMMA2!r}*dt)"
#: Names of global variables read by name from outside the program.
ALPHA = "alpha"
MIDPOINT_CHANGE = "midpoint_change"
MIDPOINT_ITERATIONS = "midpoint_iterations"


def first_forces(alpha: str) -> str:
    """Force term of the position solve: (½−α) F(x0) + α F(x_m)."""
    return f"(0.5-{alpha})*fstart + {alpha}*fmid"


def last_forces(alpha: str) -> str:
    """Force term of the velocity update: α F(x_m) + (½−α) F(x1)."""
    return f"{alpha}*fmid + (0.5-{alpha})*f"


class MidpointConvergenceError(RuntimeError):
    """Raised when the implicit midpoint iteration of α-RATTLE fails to converge."""


class MidpointProgram(StepProgram):
    """A step program with α-RATTLE's midpoint iteration: its variables, pieces and reporting.

    :meth:`_add_midpoint_variables` declares every variable that the pieces of this
    class (and of :class:`~.base.StepProgram` with a ``fallback``) read.
    """

    def _add_midpoint_variables(
        self, alpha: float, tolerance: float, max_iterations: int, order: int
    ) -> None:
        """Declare α, the midpoint iteration's state and settings, and (order 4) the sub-step state."""
        self.addGlobalVariable(ALPHA, alpha)
        self.addGlobalVariable("midpoint_tolerance", tolerance)
        self.addGlobalVariable("max_midpoint_iterations", max_iterations)
        for name in (
            MIDPOINT_ITERATIONS,
            MIDPOINT_CHANGE,
            "previous_midpoint_change",
            "need_midpoint",
            "solving",
            "midpoint_failed",
            "midpoint_failures",
            "sum_change2",
        ):
            self.addGlobalVariable(name, 0)
        self.addGlobalVariable("order", order)
        for name in ("fstart", "fmid", "x1"):
            self.addPerDofVariable(name, 0)
        if order == 4:
            for name in ("phase", "hsub", "alpha_sub", "substep_done"):
                self.addGlobalVariable(name, 0)
            for name in ("xstep", "vstep"):
                self.addPerDofVariable(name, 0)

    # ------------------------------------------------------ α-RATTLE's midpoint
    def _add_midpoint_setup(self, need_midpoint: str) -> None:
        """Reset the midpoint iteration; ``need_midpoint``: whether the first solve is a predictor."""
        for name, expression in (
            ("midpoint_iterations", "0"),
            ("midpoint_change", "0"),
            ("previous_midpoint_change", "1e30"),
            ("midpoint_failed", "0"),
            ("need_midpoint", need_midpoint),
        ):
            self.addComputeGlobal(name, expression)

    def _add_midpoint_force(self, h: str, alpha: str) -> None:
        """Take F(x_m), x_m = (x0 + x1)/2 with x1 the last solve; decide whether to solve again.

        One force evaluation.

        The body of the last block of a loop (rule 1 of :mod:`~.base`). Leaves x = x0,
        ``fmid`` = F(x_m), ``midpoint_change`` = RMS change per degree of freedom that
        the new force makes to the next position solve (h²|α ΔF|/m before
        projection), and ``need_midpoint`` = 0 once that change is below
        ``midpoint_tolerance``, stops decreasing (the round-off floor, or divergence)
        or the iteration cap is reached; ``midpoint_failed`` = 1 if it then exceeds
        max(1000 × tolerance, 1e-8 nm) or is not finite.
        """
        self._add_midpoint_reference()
        self._add_midpoint_evaluation(h, alpha)
        self.addComputeGlobal(
            "need_midpoint",
            "step(max_midpoint_iterations - midpoint_iterations - 0.5)"
            "*step(midpoint_change - midpoint_tolerance)"
            "*(1 - step(midpoint_change - previous_midpoint_change))",
        )
        self.addComputeGlobal(
            "midpoint_failed",
            "max(midpoint_failed, (1 - need_midpoint)*(1 - step(accepted - midpoint_change)));"
            "accepted = max(1000*midpoint_tolerance, 1e-8)",
        )
        self.addComputeGlobal("previous_midpoint_change", "midpoint_change")

    def _add_midpoint_reference(self) -> None:
        """Keep the last solve as x1 and make x0 the reference of the constraint steps (rule 2)."""
        self.addComputePerDof("x1", "x")
        self.addComputePerDof("x", "x0")
        self.addConstrainPositions()

    def _add_midpoint_evaluation(self, h: str, alpha: str) -> None:
        """Take F(x_m) into ``fmid``, leave x = x0, and measure the change it makes (``midpoint_change``)."""
        self.addComputePerDof("x", "0.5*(x0 + x1)")
        self._add_sum("sum_change2", f"({h}*{h}*{alpha}*(f - fmid)/m)^2")
        self.addComputePerDof("fmid", "f")
        self.addComputePerDof("x", "x0")
        self._add_count_force_evaluation()
        self.addComputeGlobal("midpoint_iterations", "midpoint_iterations + 1")
        self.addComputeGlobal("midpoint_change", "sqrt(sum_change2/max(ndof, 1))")

    def _add_end_step(self) -> None:
        """Count a failed midpoint iteration, then end the step as every program does."""
        self.addComputeGlobal("midpoint_failures", "midpoint_failures + midpoint_failed")
        super()._add_end_step()

    # ------------------------------------------- α-RATTLE-4's inner sub-steps
    def _add_first_outer_substep(self) -> None:
        """Take the first RATTLE sub-step (γ1 h) from the step's start, F(x0) saved as ``fstart``."""
        self._add_position_solve("0.5*fstart", OUTER_H)
        self._add_velocity_update("0.5*f", OUTER_H)

    def _add_inner_substeps_start(self, need_midpoint: str, **copies: str) -> None:
        """Start the middle sub-step (γ2 h, α) here; the loop then takes the last one (γ1 h, 0)."""
        self.addComputeGlobal("phase", "2")
        self.addComputeGlobal("hsub", MIDDLE_H)
        self.addComputeGlobal("alpha_sub", "alpha")
        self._add_midpoint_setup(need_midpoint)
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self.addComputePerDof("fstart", "f")
        for variable, expression in copies.items():
            self.addComputePerDof(variable, expression)

    def _add_substep_solve(self, fallback: str) -> None:
        """Solve the positions of the current inner sub-step (a predictor or a midpoint re-solve)."""
        self._add_position_solve(first_forces("alpha_sub"), "hsub", fallback)
        self.addComputeGlobal("substep_done", "1 - need_midpoint")

    def _add_substep_end(self, fallback: str, **copies: str) -> None:
        """Body of ``if substep_done``: the velocity update, then start the next sub-step."""
        self._add_velocity_update(last_forces("alpha_sub"), "hsub", fallback)
        for variable, expression in copies.items():
            self.addComputePerDof(variable, expression)
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self.addComputePerDof("fstart", "f")
        self.addComputeGlobal("phase", "phase + 1")
        self.addComputeGlobal("hsub", OUTER_H)
        self.addComputeGlobal("alpha_sub", "0")
        self.addComputeGlobal("need_midpoint", "0")
        self.addComputeGlobal("previous_midpoint_change", "1e30")

    # -------------------------------------------------------------- parameters
    @property
    def alpha(self) -> float:
        """The method parameter α; may be changed between steps.

        In the energy mode: α* of the last step, and setting it sets the α the next
        step's controller starts from.
        """
        return self.getGlobalVariableByName(ALPHA)

    @alpha.setter
    def alpha(self, value: float) -> None:
        self.setGlobalVariableByName(ALPHA, to_dimensionless(value, "alpha"))

    @property
    def midpoint_tolerance(self) -> unit.Quantity:
        """Stopping tolerance of the midpoint iteration (RMS change of x1 per DOF)."""
        return self.getGlobalVariableByName("midpoint_tolerance") * unit.nanometers

    @midpoint_tolerance.setter
    def midpoint_tolerance(self, value: unit.Quantity | float) -> None:
        tolerance = to_float(value, unit.nanometers, "midpoint_tolerance", positive=True)
        self.setGlobalVariableByName("midpoint_tolerance", tolerance)
        if getattr(self, "energy_mode", False):  # the user's choice: not changed for the system
            self.setGlobalVariableByName("midpoint_tolerance_automatic", 0)

    @property
    def max_midpoint_iterations(self) -> int:
        """Cap on midpoint force evaluations per step."""
        return int(self.getGlobalVariableByName("max_midpoint_iterations"))

    @max_midpoint_iterations.setter
    def max_midpoint_iterations(self, value: int) -> None:
        self.setGlobalVariableByName(
            "max_midpoint_iterations", positive_int(value, "max_midpoint_iterations")
        )

    @property
    def midpoint_iterations(self) -> int:
        """Midpoint force evaluations used in the last step (0 at α = 0)."""
        return int(self.getGlobalVariableByName(MIDPOINT_ITERATIONS))

    @property
    def midpoint_change(self) -> unit.Quantity:
        """RMS change of x1 in the last midpoint iteration of the last step."""
        return self.getGlobalVariableByName(MIDPOINT_CHANGE) * unit.nanometers

    @property
    def order(self) -> int:
        """2 (α-RATTLE) or 4 (α-RATTLE-4)."""
        return int(self.getGlobalVariableByName("order"))
