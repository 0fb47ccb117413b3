"""RATTLE and α-RATTLE as OpenMM ``CustomIntegrator`` step programs.

The α-RATTLE step from a consistent state (x0, v0) with F0 = F(x0) (design doc §3)::

    x1 = x0 + h v0 + h² M⁻¹[(½−α) F0 + α F(x_m)] − M⁻¹ G(x0)ᵀ λ,   g(x1) = 0,   x_m = (x0+x1)/2
    v1 = (x1 − x0)/h + h M⁻¹[α F(x_m) + (½−α) F(x1)] − M⁻¹ G(x1)ᵀ μ,  G(x1) v1 = 0

The implicit midpoint force is found by fixed-point iteration started from the RATTLE
predictor and iterated to a tolerance (a single pass is not symplectic). The programs
are built from the pieces of :mod:`openmm_alphaprk.step_program`, whose ordering rules
make the same program correct on the Reference, CPU and common (CUDA, OpenCL, HIP)
platforms.
"""

from __future__ import annotations

import openmm as mm
import openmm.unit as unit

from . import platforms
from ._units import to_dimensionless, to_float
from .energy_mode import (
    CONTROLLER_DEFAULTS,
    DEFAULT_MAX_TRIALS,
    DEFAULT_SLOPE_DAMPING,
    _EnergyModeProgram,
    check_alpha_bounds,
)
from .observables import positive_int
from .smooth_forces import warn_if_not_smooth
from .step_program import (
    KIND_VARIABLE,
    MasslessParticleError,
    _StepProgram,
    first_forces,
    last_forces,
)

__all__ = [
    "KIND_VARIABLE",
    "AlphaRattleIntegrator",
    "MasslessParticleError",
    "MidpointConvergenceError",
    "RattleIntegrator",
    "restore_integrator",
]

DEFAULT_CONSTRAINT_TOLERANCE = 1e-8
DEFAULT_MIDPOINT_TOLERANCE = 1e-10  # nm, RMS change of x1 per degree of freedom
DEFAULT_MAX_MIDPOINT_ITERATIONS = 20


class MidpointConvergenceError(RuntimeError):
    """Raised when the implicit midpoint iteration of α-RATTLE fails to converge."""


class RattleIntegrator(_StepProgram):
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
        self._add_save_step_start()
        self._add_position_solve("0.5*f")
        self._add_velocity_update("0.5*f")
        self._add_end_step()


class AlphaRattleIntegrator(_EnergyModeProgram):
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
        The midpoint iteration stops when the change that the last midpoint force
        makes to the next solve of x1, h²α ΔF/m, falls below this (nm, RMS per
        degree of freedom). Default 1e-10 nm for fixed α (symplectic to that
        level); in the energy mode 1e-7 nm (order 2) or 1e-6 nm (order 4, where α*
        is ~100× smaller), since there it only limits how well angular momentum is
        kept: ΔL ≈ 2hα δx_m × F per step.
    max_midpoint_iterations
        Cap on midpoint force evaluations per step (in the energy mode summed over the
        trials; a trial takes one or more midpoint evaluations and one (order 2) or two
        (order 4) more).
    alpha_bounds
        Energy mode: the interval (low, high) α* is kept in; default (−0.5, 1.5) at
        order 2, (−0.2, 0.2) at order 4.
    energy_tolerance
        Energy mode: target |H − E_ref| after each step (Quantity or kJ/mol). The
        default (None) is set at the first step from the system's size and the
        platform's precision, 3× the measured noise of OpenMM's energy
        (:func:`openmm_alphaprk.platforms.default_energy_tolerance`): 0.011 kJ/mol for
        2,661 atoms in mixed precision or on the CPU platform, 0.053 for 21k atoms,
        0.00075 for 2,661 atoms in double precision (Reference). A target inside the
        noise only buys trials that chase round-off.
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
    _has_midpoint = True

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
                None
                if energy_tolerance is None
                else to_float(energy_tolerance, unit.kilojoules_per_mole, "energy_tolerance", positive=True),
                positive_int(max_trials, "max_trials"),
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
        max_iterations = positive_int(max_midpoint_iterations, "max_midpoint_iterations")
        super().__init__(timestep, constraint_tolerance)
        self.addGlobalVariable("alpha", start_alpha)
        self.addGlobalVariable("midpoint_tolerance", tolerance)
        self.addGlobalVariable("max_midpoint_iterations", max_iterations)
        for name in (
            "midpoint_iterations",
            "midpoint_change",
            "previous_midpoint_change",
            "need_midpoint",
            "solving",
            "ndof",
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
        if energy_mode:
            self._add_energy_mode_variables(*energy_settings, order)
        builders = {
            (2, False): self._build_program,
            (4, False): self._build_order4_program,
            (2, True): self._build_energy_program,
            (4, True): self._build_order4_energy_program,
        }
        builders[order, energy_mode]()

    def _build_program(self) -> None:
        """Order 2, fixed α: RATTLE at α = 0, else a loop of solves and midpoint forces.

        At α = 0 the step is the RATTLE block, the same computations as
        :class:`RattleIntegrator`; its kernels read no global variable, so on CUDA,
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
        MasslessParticleError
            If the system has massless particles (virtual sites) and α ≠ 0, the
            energy mode, or a platform that places virtual sites only at the end of a
            step (Reference, CPU).
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

    def _prepare(self, context: mm.Context) -> None:
        super()._prepare(context)
        system = context.getSystem()
        self._set_degrees_of_freedom(3 * (system.getNumParticles() - self._massless_count))
        if self.energy_mode:
            self._set_automatic_energy_tolerance(system.getNumParticles(), platforms.force_precision(context))
            warn_if_not_smooth(system)  # points at the user's step() call

    def _prepare_without_context(self) -> None:
        super()._prepare_without_context()
        atoms = len(self.getPerDofVariableByName("x0"))
        self._set_degrees_of_freedom(3 * atoms)
        if self.energy_mode:
            self._set_automatic_energy_tolerance(atoms, "single")

    def _set_degrees_of_freedom(self, ndof: int) -> None:
        self.setGlobalVariableByName("ndof", ndof)

    def _check_before_steps(self) -> None:
        if self._massless_count and (self.energy_mode or self.alpha != 0.0):
            raise MasslessParticleError(
                f"{type(self).__name__} with "
                f"{'the energy mode' if self.energy_mode else f'alpha={self.alpha}'} cannot integrate "
                f"this system: {self._massless_count} particle(s) have zero mass (virtual sites). "
                "α ≠ 0 takes a force at the unconstrained midpoint of the step, where no OpenMM "
                "platform places virtual sites. With virtual sites use alpha=0 (RATTLE, or order=4 for "
                "triple-jump RATTLE) on CUDA, OpenCL or HIP, or openmm.VerletIntegrator."
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
            "max_midpoint_iterations", positive_int(value, "max_midpoint_iterations")
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


_CLASSES_BY_KIND: dict[int, type[_StepProgram]] = {
    cls._kind: cls for cls in (RattleIntegrator, AlphaRattleIntegrator)
}


def restore_integrator(integrator: mm.Integrator) -> _StepProgram:
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
    if isinstance(integrator, _StepProgram):
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
