"""α-RATTLE and α-RATTLE-4 as an OpenMM ``CustomIntegrator``: fixed α or the energy mode.

The class hierarchy, each layer declaring the variables its pieces use::

    StepProgram               base.py: common counters, RATTLE pieces, stepping, listing
    └ MidpointProgram         midpoint.py: α, the midpoint iteration, α-RATTLE-4 sub-steps
      └ EnergyControllerProgram   controller.py: the α* controller's variables and programs
        └ EnergyModeProgram       energy_mode.py: its settings, defaults and reporting
          └ AlphaRattleIntegrator here: validation, the fixed-α programs, the checks at step()
"""

from __future__ import annotations

import openmm as mm
import openmm.unit as unit

from .. import platforms
from .._units import InputError, to_dimensionless, to_float
from ..nve import warn_if_state_changing
from ..observables import positive_int
from ..smooth_forces import warn_if_not_smooth
from .binding import N_PARTICLES
from .controller import ControllerSettings
from .energy_mode import (
    CONTROLLER_DEFAULTS,
    DEFAULT_MAX_TRIALS,
    DEFAULT_SLOPE_DAMPING,
    EnergyModeProgram,
    controller_settings,
)
from .midpoint import MidpointConvergenceError, first_forces, last_forces
from .rattle import DEFAULT_CONSTRAINT_TOLERANCE

DEFAULT_MIDPOINT_TOLERANCE = 1e-10  # nm, RMS change of x1 per degree of freedom
DEFAULT_MAX_MIDPOINT_ITERATIONS = 20


class AlphaRattleIntegrator(EnergyModeProgram):
    """α-RATTLE: a one-parameter family of symplectic constrained integrators.

    The potential is integrated along the straight path x0 → x1 with weights
    (½−α, 2α, ½−α) at (0, ½, 1); α = 0 is RATTLE. For every fixed α the map is
    symplectic on the constraint manifold, symmetric, keeps the constraints and
    quadratic invariants (linear and angular momentum), and is of order 2
    (Li & Wang, J. Comput. Math. 41, 2023).

    With ``order=4`` the step is α-RATTLE-4, a triple-jump composition with α on the
    middle sub-step only. With ``alpha="energy"`` α is chosen anew every step so that the total energy
    after the step equals E_ref, the energy of the starting state
    (see :mod:`openmm_alphaprk.integrators.controller`). Each step is still a member of the
    family, so constraints and linear momentum are kept exactly and angular momentum
    to the midpoint tolerance; symplecticity is given up.

    :meth:`program_listing` prints the step program OpenMM runs.

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
        The midpoint iteration stops when the change that the last midpoint force
        makes to the next solve of x1, h²α ΔF/m, falls below this (nm, RMS per
        degree of freedom). Default 1e-10 nm for fixed α (symplectic to that
        level). In the energy mode with a periodic box 1e-7 nm (order 2) or 1e-6 nm
        (order 4, where α* is ~100× smaller), since there it only limits how well
        angular momentum is kept (ΔL ≈ 2hα δx_m × F per step), which a periodic box
        does not conserve anyway; without a periodic box 1e-13 nm, set by
        :meth:`check_context`, which keeps angular momentum to round-off.
    max_midpoint_iterations
        Cap on midpoint force evaluations per step (in the energy mode summed over the
        trials; a trial takes one or more midpoint evaluations and one (order 2) or two
        (order 4) more).
    alpha_bounds
        Energy mode: the interval (low, high) α* is kept in; default (−0.5, 1.5) at
        order 2, (−0.2, 0.2) at order 4.
    energy_tolerance
        Energy mode: target |H − E_ref| after each step (Quantity or kJ/mol). The
        default (None) is 3× the measured noise of OpenMM's energy for the system's
        size and the platform's precision
        (:func:`openmm_alphaprk.platforms.default_energy_tolerance`), set by
        :meth:`check_context`: 0.011 kJ/mol for 2,661 atoms in mixed precision or on the
        CPU platform, 0.053 for 21k atoms, 0.00075 for 2,661 atoms in double precision
        (Reference). Without it the platform is not known, and each ``step()`` call
        sets the single-precision value (the noisiest: 0.016 kJ/mol for 2,661 atoms). A
        target inside the noise only buys trials that chase round-off.
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
        γ2 = 1 − 2γ1: fourth order at α = 0 (three force
        evaluations per step), second order at a fixed α ≠ 0, and fourth order
        again in the energy mode, where α* = O(h²). Its sub-steps are 1.35h, −1.70h
        and 1.35h (a scan on a water box found it, like RATTLE, stable up to 5 fs,
        the largest step scanned).

    Notes
    -----
    Where the force is constant, every member of the family is the same map as
    RATTLE: α acts only through how the force varies along the step.

    With a fixed α each step starts with OpenMM's update-context-state step, as a
    ``VerletIntegrator`` step does: a Monte Carlo barostat, an ``AndersenThermostat``
    or a ``CMMotionRemover`` acts as it does there. The energy mode leaves them out
    and runs NVE (:func:`openmm_alphaprk.nve.state_changing_forces` says why);
    :meth:`check_context` warns about them, and about forces that are not smooth.
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
        energy_tolerance: unit.Quantity | float | None = None,
        max_trials: int = DEFAULT_MAX_TRIALS,
        max_alpha_change: float | None = None,
        alpha_probe: float | None = None,
        slope_damping: float = DEFAULT_SLOPE_DAMPING,
        order: int = 2,
    ) -> None:
        _check_order(order)
        settings = None
        if _is_energy_mode(alpha):
            settings = controller_settings(
                order,
                alpha_bounds,
                energy_tolerance,
                max_trials,
                max_alpha_change,
                alpha_probe,
                slope_damping,
            )
            low, high = settings.alpha_bounds
            start_alpha = min(max(0.0, low), high)
            default_tolerance = CONTROLLER_DEFAULTS[order].midpoint_tolerance
        else:
            start_alpha = to_dimensionless(alpha, "alpha")
            default_tolerance = DEFAULT_MIDPOINT_TOLERANCE
        tolerance = to_float(
            default_tolerance if midpoint_tolerance is None else midpoint_tolerance,
            unit.nanometers,
            "midpoint_tolerance",
            positive=True,
        )
        max_iterations = positive_int(max_midpoint_iterations, "max_midpoint_iterations")
        super().__init__(timestep, constraint_tolerance)
        self._add_midpoint_variables(start_alpha, tolerance, max_iterations, order)
        self._build(order, settings)
        if settings is not None and midpoint_tolerance is not None:
            self.setGlobalVariableByName("midpoint_tolerance_automatic", 0)

    def _build(self, order: int, settings: ControllerSettings | None) -> None:
        """Build the program of ``order``: fixed α, or the energy mode with ``settings``.

        Either is the body of :meth:`~.base.StepProgram._add_step`; a fixed α starts
        with the update-context-state step.
        """
        if settings is not None:
            self._add_energy_mode_variables(settings, order)
        builders = {
            (2, False): self._build_program,
            (4, False): self._build_order4_program,
            (2, True): self._build_energy_program,
            (4, True): self._build_order4_energy_program,
        }
        self._add_step(builders[order, settings is not None], update_context_state=settings is None)

    def _build_program(self) -> None:
        """Order 2, fixed α: RATTLE at α = 0, else a loop of solves and midpoint forces.

        At α = 0 the step is the RATTLE block, the same computations as
        :class:`~.rattle.RattleIntegrator`; its kernels read no global variable, so on CUDA,
        OpenCL and HIP the step needs no upload of globals to the device (each is a
        synchronisation with the host). The α ≠ 0 block follows it in program text,
        so that its midpoint assignment comes after every constraint step.
        """
        self._add_save_step_start(fstart="f", fmid="f")
        self._add_midpoint_setup("1")
        self.beginIfBlock("alpha = 0")
        self._add_position_solve("0.5*f")
        self._add_velocity_update("0.5*f")
        self.endBlock()
        self.beginIfBlock("alpha != 0")
        self.addComputeGlobal("solving", "1")
        self.beginWhileBlock("solving > 0.5")
        self.addComputeGlobal("solving", "0")
        self._add_position_solve(first_forces("alpha"), "dt", fallback="x0")
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_midpoint_force("dt", "alpha")
        self.addComputeGlobal("solving", "1")
        self.endBlock()
        self.endBlock()
        self._add_velocity_update(last_forces("alpha"), "dt", fallback="v0")
        self.endBlock()
        self._add_end_step()

    def _build_order4_program(self) -> None:
        """α-RATTLE-4 with fixed α: RATTLE (γ1 h), then a loop over α-RATTLE (γ2 h) and RATTLE (γ1 h).

        The last sub-step is inside the loop, before its midpoint block, so that its
        position constraint precedes the midpoint assignment in program text. A
        failed midpoint iteration makes both remaining sub-steps return the state
        the step started from.
        """
        self._add_save_step_start(xstep="x", vstep="v", fstart="f")
        self._add_first_outer_substep()
        self._add_inner_substeps_start("1 - delta(alpha)", fmid="f")
        self.beginWhileBlock("phase < 3.5")
        self._add_substep_solve(fallback="xstep")
        self.beginIfBlock("substep_done > 0.5")
        self._add_substep_end(fallback="vstep")
        self.endBlock()
        self.beginIfBlock("need_midpoint > 0.5")
        self._add_midpoint_force("hsub", "alpha_sub")
        self.endBlock()
        self.endBlock()
        self._add_end_step()

    def step(self, steps: int) -> None:
        """Advance by ``steps`` steps; raise if the midpoint iteration failed on the way.

        Raises
        ------
        MidpointConvergenceError
            If the midpoint iteration did not converge (|α| h²ω²/4 ≳ 1, a tolerance
            below the platform's precision, or non-finite forces or energies). The
            context is left at the start of the failed step.
        IncompatibleSystemError
            If the system has massless particles (virtual sites) and α ≠ 0, the
            energy mode, a platform that places virtual sites only at the end of a
            step (Reference, CPU), or a platform not shown to :meth:`check_context`.
        SystemSizeError
            If the integrator, bound again, runs a System with more particles than
            the first one it was bound to.
        StartBlowUpError
            If the state went to NaN in the first 100 steps (:mod:`openmm_alphaprk.start_blowup`).
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

    def _check_system(self, context: mm.Context) -> None:
        """Energy mode: the default tolerance from the platform's precision, and the System's warnings."""
        if self.energy_mode:
            system = context.getSystem()
            self._set_automatic_energy_tolerance(system.getNumParticles(), platforms.force_precision(context))
            self._set_system_defaults(system.usesPeriodicBoundaryConditions())
            warn_if_not_smooth(system)  # both point at the user's call
            warn_if_state_changing(system)

    def _check_before_steps(self, context: mm.Context | None) -> None:
        super()._check_before_steps(context)
        if self.energy_mode and context is None:
            particles = int(self.getGlobalVariableByName(N_PARTICLES))
            self._set_automatic_energy_tolerance(particles, platforms.UNKNOWN_PRECISION)

    def _massless_refusal(self, count: int, platform: str | None) -> str | None:
        if count and (self.energy_mode or self.alpha != 0.0):
            return (
                f"{type(self).__name__} with "
                f"{'the energy mode' if self.energy_mode else f'alpha={self.alpha}'} cannot integrate "
                f"this system: {count} particle(s) have zero mass (virtual sites). "
                "α ≠ 0 takes a force at the unconstrained midpoint of the step, where no OpenMM "
                "platform places virtual sites. With virtual sites use alpha=0 (RATTLE, or order=4 for "
                "triple-jump RATTLE) on CUDA, OpenCL or HIP after integrator.check_context(context), or "
                "openmm.VerletIntegrator."
            )
        return super()._massless_refusal(count, platform)

    def __repr__(self) -> str:
        alpha = "'energy'" if self.energy_mode else self.alpha
        order = f", order={self.order}" if self.order != 2 else ""
        return f"{type(self).__name__}(timestep={self.timestep}, alpha={alpha}{order})"


def _check_order(order: object) -> None:
    if isinstance(order, bool) or order not in (2, 4):
        raise InputError(
            f"order must be 2 (α-RATTLE) or 4 (α-RATTLE-4, the triple-jump composition), got {order!r}."
        )


def _is_energy_mode(alpha: float | str) -> bool:
    """Tell whether ``alpha`` asks for the energy mode; refuse any other string."""
    if isinstance(alpha, str) and alpha != "energy":
        raise InputError(f"alpha must be a number or 'energy', got {alpha!r}.")
    return isinstance(alpha, str)
