"""RATTLE and α-RATTLE as OpenMM ``CustomIntegrator`` step programs.

Both integrators are built from the same small pieces (``_add_*`` methods), one per
sub-step of the velocity-Verlet/RATTLE step, so that α-RATTLE at α = 0 performs the
same floating-point operations as :class:`RattleIntegrator`.

The α-RATTLE step from a consistent state (x0, v0) with F0 = F(x0) (design doc §3)::

    x1 = x0 + h v0 + h² M⁻¹[(½−α) F0 + α F(x_m)] − M⁻¹ G(x0)ᵀ λ,   g(x1) = 0,   x_m = (x0+x1)/2
    v1 = (x1 − x0)/h + h M⁻¹[α F(x_m) + (½−α) F(x1)] − M⁻¹ G(x1)ᵀ μ,  G(x1) v1 = 0

The implicit midpoint force is found by fixed-point iteration started from the RATTLE
predictor and iterated to a tolerance (a single pass is not symplectic).

OpenMM facts the program relies on (observed on OpenMM 8.6, see the design doc §5):

- ``addConstrainPositions`` projects along the constraint directions of the positions
  of the *previous* constraint application (at the start of a step: the positions at
  the start of the step).  Before every re-solve of x1 the program therefore sets
  x = x0 and constrains once, which resets that reference to x0.
- The force at the start of a step is reused from the end of the previous step; OpenMM
  recomputes it only if the state was changed in between.
- Per-DOF computations skip massless particles, and on the Reference and CPU platforms
  virtual sites are only placed at the end of a step, so forces taken inside a step see
  stale virtual sites.  Systems with massless particles are therefore refused.
"""

from __future__ import annotations

from typing import ClassVar

import openmm as mm
import openmm.unit as unit

from ._triple_jump import GAMMA1, GAMMA2
from ._units import to_dimensionless, to_float
from .energy_mode import (
    CONTROLLER_DEFAULTS,
    DEFAULT_ENERGY_TOLERANCE,
    DEFAULT_MAX_TRIALS,
    DEFAULT_SLOPE_DAMPING,
    _EnergyModeProgram,
    check_alpha_bounds,
)

#: Name of the global variable that identifies the integrator class in serialized form.
KIND_VARIABLE = "alphaprk_kind"

DEFAULT_CONSTRAINT_TOLERANCE = 1e-8
DEFAULT_MIDPOINT_TOLERANCE = 1e-10  # nm, RMS change of x1 per degree of freedom
DEFAULT_MAX_MIDPOINT_ITERATIONS = 20


class MasslessParticleError(RuntimeError):
    """Raised when a system with massless particles (e.g. virtual sites) is integrated."""


class MidpointConvergenceError(RuntimeError):
    """Raised when the implicit midpoint iteration of α-RATTLE fails to converge."""


class _ConstrainedVerletBase(mm.CustomIntegrator):
    """Common state, sub-step pieces and reporting of RATTLE-type integrators.

    Subclasses set ``_kind`` (stored in the global variable :data:`KIND_VARIABLE` so
    that :func:`restore_integrator` can recognise a deserialized integrator) and build
    their step program in ``_build_program``.
    """

    _kind: ClassVar[int] = 0

    def __init__(self, timestep: unit.Quantity | float, constraint_tolerance: float) -> None:
        step_size = to_float(timestep, unit.picoseconds, "timestep", positive=True)
        tolerance = to_dimensionless(constraint_tolerance, "constraint_tolerance", positive=True)
        super().__init__(step_size)
        self.setConstraintTolerance(tolerance)
        self.addGlobalVariable(KIND_VARIABLE, self._kind)
        self.addGlobalVariable("force_evaluations", 0)
        self.addGlobalVariable("steps_taken", 0)
        self.addGlobalVariable("step_force_evaluations", 0)
        for name in ("x0", "v0", "massive"):
            self.addPerDofVariable(name, 0)

    # ------------------------------------------------------------------ pieces
    def _add_begin_step(self) -> None:
        """Save the starting state (x0, v0); mark the DOFs the program can move."""
        self.addComputePerDof("massive", "1")
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self.addComputeGlobal("step_force_evaluations", "0")

    def _add_position_solve(self, force_term: str, h: str = "dt") -> None:
        """Set x ← x0 + h v0 + h² M⁻¹(force_term), then SHAKE/SETTLE along G(reference)."""
        self.addComputePerDof("x", f"x0 + {h}*v0 + {h}*{h}*({force_term})/m")
        self.addConstrainPositions()

    def _add_reset_constraint_reference(self) -> None:
        """Make x0 the reference of the next position constraint (a no-op on x0)."""
        self.addComputePerDof("x", "x0")
        self.addConstrainPositions()

    def _add_count_force_evaluation(self) -> None:
        self.addComputeGlobal("step_force_evaluations", "step_force_evaluations + 1")

    def _add_velocity_update(self, force_term: str, h: str = "dt") -> None:
        """Set v ← (x1 − x0)/h + h M⁻¹(force_term), then RATTLE velocity projection at x1.

        ``force_term`` uses ``f``, the force at the current positions x1: this is the
        step's final force evaluation, reused at the start of the next step.
        """
        self.addComputePerDof("v", f"(x - x0)/{h} + {h}*({force_term})/m")
        self._add_count_force_evaluation()
        self.addConstrainVelocities()

    def _add_end_step(self) -> None:
        self.addComputeGlobal("force_evaluations", "force_evaluations + step_force_evaluations")
        self.addComputeGlobal("steps_taken", "steps_taken + 1")

    # --------------------------------------------------------------- stepping
    def step(self, steps: int) -> None:
        """Advance the context by ``steps`` steps.

        The first call takes one step and then checks that every particle has mass;
        see :class:`MasslessParticleError`.
        """
        steps = int(steps)
        if steps > 0 and not getattr(self, "_massless_checked", False):
            mm.CustomIntegrator.step(self, 1)
            self._check_no_massless_particles()
            steps -= 1
        if steps > 0:
            mm.CustomIntegrator.step(self, steps)

    def _check_no_massless_particles(self) -> None:
        massive = self.getPerDofVariableByName("massive")
        massless = [i for i, flag in enumerate(massive) if flag[0] != 1.0]
        if massless:
            raise MasslessParticleError(
                f"{type(self).__name__} cannot integrate this system: {len(massless)} particle(s) "
                f"have zero mass (first index {massless[0]}). Virtual sites (e.g. the M-sites of "
                "TIP4P-Ew or OPC water) are only placed at the end of a CustomIntegrator step on "
                "the Reference and CPU platforms, so forces evaluated inside the step would be "
                "wrong. The context was advanced by one step and should be discarded. Use a "
                "water model without virtual sites (TIP3P, SPC/E) or openmm.VerletIntegrator."
            )
        self._massless_checked = True

    # -------------------------------------------------------------- reporting
    @property
    def timestep(self) -> unit.Quantity:
        """The step size, as a Quantity in picoseconds."""
        return self.getStepSize()

    @property
    def constraint_tolerance(self) -> float:
        """Relative tolerance of SHAKE/CCMA/SETTLE position and velocity constraints."""
        return self.getConstraintTolerance()

    @property
    def steps_taken(self) -> int:
        """Number of steps taken with this integrator."""
        return int(self.getGlobalVariableByName("steps_taken"))

    @property
    def force_evaluations(self) -> int:
        """Force evaluations requested by the step program since it was created.

        The force at the start of a step is the one computed at the end of the
        previous step and is not counted; OpenMM recomputes it (uncounted) only after
        the user changes the state.
        """
        return int(self.getGlobalVariableByName("force_evaluations"))

    @property
    def last_step_force_evaluations(self) -> int:
        """Force evaluations of the last step."""
        return int(self.getGlobalVariableByName("step_force_evaluations"))

    @property
    def force_evaluations_per_step(self) -> float:
        """Mean force evaluations per step (NaN before the first step)."""
        steps = self.steps_taken
        return self.force_evaluations / steps if steps else float("nan")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(timestep={self.timestep})"


class RattleIntegrator(_ConstrainedVerletBase):
    """Velocity Verlet with SHAKE/SETTLE positions and RATTLE velocities.

    The standard constrained integrator, written with the same pieces as
    :class:`AlphaRattleIntegrator` to be the baseline of every comparison.
    Velocities are at the full step, so ``State.getKineticEnergy()`` is the kinetic
    energy of the current velocities. One force evaluation per step.

    Parameters
    ----------
    timestep
        Step size (Quantity, or number in picoseconds).
    constraint_tolerance
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    """

    _kind = 1

    def __init__(
        self,
        timestep: unit.Quantity | float,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
    ) -> None:
        super().__init__(timestep, constraint_tolerance)
        self._build_program()

    def _build_program(self) -> None:
        self._add_begin_step()
        self._add_position_solve("0.5*f")
        self._add_velocity_update("0.5*f")
        self._add_end_step()


class AlphaRattleIntegrator(_EnergyModeProgram, _ConstrainedVerletBase):
    """α-RATTLE: a one-parameter family of symplectic constrained integrators.

    The potential is integrated along the straight path x0 → x1 with weights
    (½−α, 2α, ½−α) at (0, ½, 1); α = 0 is RATTLE. For every fixed α the map is
    symplectic on the constraint manifold, symmetric, keeps the constraints and
    quadratic invariants (linear and angular momentum), and is of order 2
    (design doc §3).

    With ``order=4`` the step is α-RATTLE-4, a triple-jump composition with α on the
    middle sub-step only. With ``alpha="energy"`` α is chosen anew every step so that the total energy
    after the step equals E_ref, the energy of the starting state (design doc §4;
    see :mod:`openmm_alphaprk.energy_mode`). Each step is still a member of the
    family, so constraints and linear momentum are kept exactly and angular momentum
    to the midpoint tolerance; symplecticity is given up.

    Parameters
    ----------
    timestep
        Step size (Quantity, or number in picoseconds).
    alpha
        The method parameter α (a finite number), or ``"energy"`` for the
        energy-preserving mode. α = 0 takes the RATTLE path with one force
        evaluation per step; α ≠ 0 needs the implicit midpoint force.
    constraint_tolerance
        Relative constraint tolerance passed to ``setConstraintTolerance``.
    midpoint_tolerance
        The midpoint iteration stops when the RMS change of x1 per degree of freedom
        falls below this (nm). Default 1e-10 nm for fixed α (symplectic to that
        level); in the energy mode 1e-7 nm (order 2) or 1e-6 nm (order 4, where α*
        is ~100× smaller), since there it only limits how well angular momentum is
        kept: ΔL ≈ 2hα δx_m × F per step.
    max_midpoint_iterations
        Cap on midpoint force evaluations per step (in the energy mode: on trials,
        each two (order 2) or three (order 4) force evaluations).
    alpha_bounds
        Energy mode: the interval (low, high) α* is kept in; default (−0.5, 1.5) at
        order 2, (−0.2, 0.2) at order 4.
    energy_tolerance
        Energy mode: target |H − E_ref| after each step (Quantity or kJ/mol; default
        0.01). It must sit above the platform's noise in ``energy``: measured
        3e-3 kJ/mol (standard deviation of CPU − Reference) on the single-precision
        CPU platform for a 2,661-atom water box; raise it for larger systems there.
        On the Reference platform 1e-4 works.
    max_trials
        Energy mode: trials per step that may change α; after them α is frozen
        and further trials only converge the midpoint force.
    max_alpha_change
        Energy mode: the largest change of α one secant update may make (default 1
        at order 2, 0.05 at order 4).
    alpha_probe
        Energy mode: the smallest first move of α in a step, so that the step can
        measure its own slope dH/dα (default 0.05 at order 2, 0.005 at order 4).
    slope_damping
        Energy mode: d in the damped secant step Δα = −r S/(S² + (d S̄)²), where S̄
        is a running mean of the measured slopes |S| (0 turns the damping off).
    order
        2: the α-RATTLE step. 4: α-RATTLE-4, the symmetric composition
        Ψ^0_{γ1 h} ∘ Ψ^α_{γ2 h} ∘ Ψ^0_{γ1 h} with γ1 = 1/(2 − 2^{1/3}),
        γ2 = 1 − 2γ1 (design doc §8): fourth order at α = 0 (three force
        evaluations per step), second order at a fixed α ≠ 0, and fourth order
        again in the energy mode, where α* = O(h²). Its sub-steps are 1.35h, −1.70h
        and 1.35h (a scan on a water box found it, like RATTLE, stable up to 5 fs,
        the largest step scanned).

    Notes
    -----
    Where the force is constant, every member of the family is the same map as
    RATTLE: α acts only through how the force varies along the step.
    """

    _kind = 2

    def __init__(
        self,
        timestep: unit.Quantity | float,
        alpha: float | str = 0.0,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
        midpoint_tolerance: unit.Quantity | float | None = None,
        max_midpoint_iterations: int = DEFAULT_MAX_MIDPOINT_ITERATIONS,
        *,
        alpha_bounds: tuple[float, float] | None = None,
        energy_tolerance: unit.Quantity | float = DEFAULT_ENERGY_TOLERANCE,
        max_trials: int = DEFAULT_MAX_TRIALS,
        max_alpha_change: float | None = None,
        alpha_probe: float | None = None,
        slope_damping: float = DEFAULT_SLOPE_DAMPING,
        order: int = 2,
    ) -> None:
        if isinstance(order, bool) or order not in (2, 4):
            raise ValueError(
                f"order must be 2 (α-RATTLE) or 4 (α-RATTLE-4, the triple-jump composition), got {order!r}."
            )
        energy_mode = isinstance(alpha, str)
        if energy_mode and alpha != "energy":
            raise ValueError(f"alpha must be a number or 'energy', got {alpha!r}.")
        if energy_mode:
            defaults = CONTROLLER_DEFAULTS[order]
            alpha_bounds = defaults.alpha_bounds if alpha_bounds is None else alpha_bounds
            max_alpha_change = defaults.max_alpha_change if max_alpha_change is None else max_alpha_change
            alpha_probe = defaults.alpha_probe if alpha_probe is None else alpha_probe
            low, high = check_alpha_bounds(alpha_bounds)
            start_alpha = min(max(0.0, low), high)
            energy_settings = (
                (low, high),
                to_float(energy_tolerance, unit.kilojoules_per_mole, "energy_tolerance", positive=True),
                _positive_int(max_trials, "max_trials"),
                to_dimensionless(max_alpha_change, "max_alpha_change", positive=True),
                to_dimensionless(alpha_probe, "alpha_probe", positive=True),
                to_dimensionless(slope_damping, "slope_damping"),
            )
            if energy_settings[-1] < 0:
                raise ValueError(
                    f"slope_damping must be >= 0 (0 turns the damping off), got {slope_damping}."
                )
            if midpoint_tolerance is None:
                midpoint_tolerance = defaults.midpoint_tolerance
        else:
            start_alpha = to_dimensionless(alpha, "alpha")
            if midpoint_tolerance is None:
                midpoint_tolerance = DEFAULT_MIDPOINT_TOLERANCE
        tolerance = to_float(midpoint_tolerance, unit.nanometers, "midpoint_tolerance", positive=True)
        max_iterations = _positive_int(max_midpoint_iterations, "max_midpoint_iterations")
        super().__init__(timestep, constraint_tolerance)
        self.addGlobalVariable("alpha", start_alpha)
        self.addGlobalVariable("midpoint_tolerance", tolerance)
        self.addGlobalVariable("max_midpoint_iterations", max_iterations)
        self.addGlobalVariable("midpoint_iterations", 0)
        self.addGlobalVariable("midpoint_change", 0)
        self.addGlobalVariable("iterate_midpoint", 0)
        self.addGlobalVariable("previous_midpoint_change", 0)
        self.addGlobalVariable("ndof", 0)
        self.addGlobalVariable("midpoint_failed", 0)
        self.addGlobalVariable("midpoint_failures", 0)
        self.addGlobalVariable("sum_change2", 0)
        self.addGlobalVariable("order", order)
        for name in ("fstart", "fmid", "x1"):
            self.addPerDofVariable(name, 0)
        if order == 4:
            for name in ("xstep", "vstep", "xa", "va", "fstart_last"):
                self.addPerDofVariable(name, 0)
        if energy_mode:
            self._add_energy_mode_variables(*energy_settings)
        builders = {
            (2, False): self._build_program,
            (4, False): self._build_order4_program,
            (2, True): self._build_energy_program,
            (4, True): self._build_order4_energy_program,
        }
        builders[order, energy_mode]()

    _FIRST_FORCES = "(0.5-alpha)*fstart + alpha*fmid"
    _LAST_FORCES = "alpha*fmid + (0.5-alpha)*f"
    #: Sub-step sizes of α-RATTLE-4: Ψ^0_{γ1 h} ∘ Ψ^α_{γ2 h} ∘ Ψ^0_{γ1 h}.
    _OUTER_H = f"({GAMMA1!r}*dt)"
    _MIDDLE_H = f"({GAMMA2!r}*dt)"

    def _build_program(self) -> None:
        self._add_begin_step()
        self._add_save_start_force()
        self._add_position_solve(self._FIRST_FORCES)
        self.addComputePerDof("x1", "x")
        self._add_midpoint_iteration()
        self._add_reject_unconverged_step()
        self._add_velocity_update(self._LAST_FORCES)
        self.addComputePerDof("v", "select(midpoint_failed, v0, v)")
        self._add_end_step()

    def _build_order4_program(self) -> None:
        """α-RATTLE-4 with fixed α: RATTLE (γ1 h), α-RATTLE (γ2 h), RATTLE (γ1 h)."""
        self._add_begin_step()
        self._add_save_step_start()
        self._add_rattle_substep(self._OUTER_H)
        self._add_substep_start()
        self._add_save_start_force()
        self._add_position_solve(self._FIRST_FORCES, self._MIDDLE_H)
        self.addComputePerDof("x1", "x")
        self._add_midpoint_iteration(self._MIDDLE_H)
        self._add_reject_unconverged_step()
        self._add_velocity_update(self._LAST_FORCES, self._MIDDLE_H)
        self._add_rattle_substep(self._OUTER_H)
        self._add_restore_step_start_if_failed()
        self._add_end_step()

    def _add_save_step_start(self) -> None:
        """Keep the state at the start of the whole step (restored if a sub-step fails)."""
        self.addComputePerDof("xstep", "x")
        self.addComputePerDof("vstep", "v")

    def _add_substep_start(self) -> None:
        """Start the next sub-step from the current state: (x0, v0) ← (x, v)."""
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")

    def _add_rattle_substep(self, h: str) -> None:
        """Take a RATTLE sub-step of size ``h`` from the current state (one force evaluation)."""
        self._add_substep_start()
        self._add_position_solve("0.5*f", h)
        self._add_velocity_update("0.5*f", h)

    def _add_restore_step_start_if_failed(self) -> None:
        self.addComputePerDof("x", "select(midpoint_failed, xstep, x)")
        self.addComputePerDof("v", "select(midpoint_failed, vstep, v)")

    def _add_save_start_force(self) -> None:
        """F0 = F(x0), reused from the previous step; predictor takes F(x_m) ≈ F0."""
        self.addComputePerDof("fstart", "f")
        self.addComputePerDof("fmid", "fstart")
        self.addComputeGlobal("midpoint_iterations", "0")

    def _add_midpoint_iteration(self, h: str = "dt") -> None:
        """Fixed-point iteration x1 ← solve(F((x0 + x1)/2)) to ``midpoint_tolerance``.

        The iteration stops when the RMS change of x1 falls below the tolerance, when
        it stops decreasing (the round-off floor of single-precision forces, or a
        divergent iteration), or at the iteration cap. On exit x = x1 is consistent
        with the last midpoint force. Skipped at α = 0.
        """
        self.addComputeSum("ndof", "1")
        self.addComputeGlobal("iterate_midpoint", "(1 - delta(alpha))*step(max_midpoint_iterations - 0.5)")
        self.addComputeGlobal("midpoint_change", "1e30*(1 - delta(alpha))")
        self.beginWhileBlock("iterate_midpoint > 0.5")
        self.addComputeGlobal("previous_midpoint_change", "midpoint_change")
        self._add_midpoint_pass(h)
        self.addComputeGlobal("midpoint_iterations", "midpoint_iterations + 1")
        self.addComputeGlobal(
            "iterate_midpoint",
            "step(max_midpoint_iterations - midpoint_iterations - 0.5)"
            "*step(midpoint_change - midpoint_tolerance)"
            "*(1 - step(midpoint_change - previous_midpoint_change))",
        )
        self.endBlock()

    def _add_midpoint_pass(self, h: str = "dt") -> None:
        """F at the midpoint of (x0, x1), then x1 solved again with it (one force evaluation).

        Leaves x = x1 and ``midpoint_change`` = RMS change of x1 per degree of freedom.
        """
        self.addComputePerDof("x", "0.5*(x0 + x1)")
        self.addComputePerDof("fmid", "f")
        self._add_count_force_evaluation()
        self._add_reset_constraint_reference()
        self._add_position_solve(self._FIRST_FORCES, h)
        self.addComputeSum("sum_change2", "(x - x1)^2")
        self.addComputeGlobal("midpoint_change", "sqrt(sum_change2/ndof)")
        self.addComputePerDof("x1", "x")

    def _add_reject_unconverged_step(self) -> None:
        """If the last change of x1 exceeds max(1000 × tolerance, 1e-8 nm) or is NaN, stay at x0.

        Stalling below 1e-8 nm RMS is accepted: that is the precision floor of
        single-precision forces (about 1e-10 nm on the CPU platform), not divergence.

        The remaining steps of the same ``step(n)`` call then repeat the failure
        without moving, and :meth:`step` raises :class:`MidpointConvergenceError`, so
        the context keeps the last good state.
        """
        self.addComputeGlobal(
            "midpoint_failed", "1 - step(max(1000*midpoint_tolerance, 1e-8) - midpoint_change)"
        )
        self.addComputeGlobal("midpoint_failures", "midpoint_failures + midpoint_failed")
        self.addComputePerDof("x", "select(midpoint_failed, x0, x)")

    def step(self, steps: int) -> None:
        """Advance by ``steps`` steps; raise if the midpoint iteration failed on the way.

        Raises
        ------
        MidpointConvergenceError
            If the midpoint iteration did not converge (|α| h²ω²/4 ≳ 1, a tolerance
            below the platform's precision, or non-finite forces or energies). The
            context is left at the start of the failed step.
        """
        failures = self.getGlobalVariableByName("midpoint_failures")
        super().step(steps)
        if self.getGlobalVariableByName("midpoint_failures") > failures:
            raise MidpointConvergenceError(
                f"α-RATTLE midpoint iteration did not converge (last RMS change "
                f"{self.getGlobalVariableByName('midpoint_change'):.3g} nm after "
                f"{self.midpoint_iterations} iterations; tolerance {self.midpoint_tolerance}, "
                f"alpha={'energy mode, ' if self.energy_mode else ''}{self.alpha}, "
                f"timestep={self.timestep}). The context was left at the start "
                "of the failed step. Reduce the timestep or |alpha|, raise midpoint_tolerance if it "
                "is below the platform's precision, or check the system for overlapping atoms."
            )

    # -------------------------------------------------------------- parameters
    @property
    def alpha(self) -> float:
        """The method parameter α; may be changed between steps.

        In the energy mode: α* of the last step, and setting it sets the α the next
        step's controller starts from.
        """
        return self.getGlobalVariableByName("alpha")

    @alpha.setter
    def alpha(self, value: float) -> None:
        self.setGlobalVariableByName("alpha", to_dimensionless(value, "alpha"))

    @property
    def midpoint_tolerance(self) -> unit.Quantity:
        """Stopping tolerance of the midpoint iteration (RMS change of x1 per DOF)."""
        return self.getGlobalVariableByName("midpoint_tolerance") * unit.nanometers

    @midpoint_tolerance.setter
    def midpoint_tolerance(self, value: unit.Quantity | float) -> None:
        tolerance = to_float(value, unit.nanometers, "midpoint_tolerance", positive=True)
        self.setGlobalVariableByName("midpoint_tolerance", tolerance)

    @property
    def max_midpoint_iterations(self) -> int:
        """Cap on midpoint force evaluations per step."""
        return int(self.getGlobalVariableByName("max_midpoint_iterations"))

    @max_midpoint_iterations.setter
    def max_midpoint_iterations(self, value: int) -> None:
        self.setGlobalVariableByName(
            "max_midpoint_iterations", _positive_int(value, "max_midpoint_iterations")
        )

    @property
    def midpoint_iterations(self) -> int:
        """Midpoint force evaluations used in the last step (0 at α = 0)."""
        return int(self.getGlobalVariableByName("midpoint_iterations"))

    @property
    def midpoint_change(self) -> unit.Quantity:
        """RMS change of x1 in the last midpoint iteration of the last step."""
        return self.getGlobalVariableByName("midpoint_change") * unit.nanometers

    def __repr__(self) -> str:
        alpha = "'energy'" if self.energy_mode else self.alpha
        order = f", order={self.order}" if self.order != 2 else ""
        return f"{type(self).__name__}(timestep={self.timestep}, alpha={alpha}{order})"

    @property
    def order(self) -> int:
        """2 (α-RATTLE) or 4 (α-RATTLE-4)."""
        return int(self.getGlobalVariableByName("order"))


def _positive_int(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}.")
    return int(value)


_CLASSES_BY_KIND: dict[int, type[_ConstrainedVerletBase]] = {
    cls._kind: cls for cls in (RattleIntegrator, AlphaRattleIntegrator)
}


def restore_integrator(integrator: mm.Integrator) -> _ConstrainedVerletBase:
    """Give a deserialized or ``Context.getIntegrator()`` object its Python class back.

    ``XmlSerializer.deserialize`` and ``Context.getIntegrator`` return a plain
    ``openmm.CustomIntegrator``. This function recognises integrators made by this
    package (by the global variable :data:`KIND_VARIABLE`) and changes the class of
    the same object in place, so it stays bound to its context.

    Parameters
    ----------
    integrator
        An integrator object.

    Returns
    -------
    The same object, now an instance of :class:`AlphaRattleIntegrator` or
    :class:`RattleIntegrator`.

    Raises
    ------
    TypeError
        If ``integrator`` was not made by this package.
    """
    if isinstance(integrator, _ConstrainedVerletBase):
        return integrator
    kind = None
    if isinstance(integrator, mm.CustomIntegrator):
        names = [integrator.getGlobalVariableName(i) for i in range(integrator.getNumGlobalVariables())]
        if KIND_VARIABLE in names:
            kind = int(integrator.getGlobalVariableByName(KIND_VARIABLE))
    if kind not in _CLASSES_BY_KIND:
        raise TypeError(
            f"{type(integrator).__name__} object was not created by openmm_alphaprk "
            f"(no global variable {KIND_VARIABLE!r} with a known value); cannot restore it."
        )
    integrator.__class__ = _CLASSES_BY_KIND[kind]
    return integrator
