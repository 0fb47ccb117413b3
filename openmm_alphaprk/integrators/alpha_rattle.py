"""α-RATTLE and its compositions with a fixed α: the whole step programs.

The classes, each an integrator (the pieces they are built from are in :mod:`~.pieces`)::

    _StepProgram                      pieces.py: common state, pieces, stepping, listing
    ├ RattleIntegrator                rattle.py
    └ AlphaRattleIntegrator           here: fixed α, one step or a composition
      └ AlphaRattleEnergyIntegrator   energy_mode.py: α chosen every step to hold the energy

``AlphaRattleIntegrator(timestep, alpha="energy")`` returns an
:class:`~.energy_mode.AlphaRattleEnergyIntegrator` (its programs and controller are in
:mod:`~.energy_mode`). The two fixed-α programs (one step, or a composition) are the
``_build_*`` methods below; a composition's program runs its stages from the first
α stage in one loop (:meth:`~.pieces._StepProgram._add_composition_loop`; the energy
mode's loop adds its trial ends, ``energy_mode``), built from the composition's
coefficients (:mod:`~.compositions`).
"""

from __future__ import annotations

from functools import cache
from typing import ClassVar

import openmm.unit as unit

from .._units import InputError, to_dimensionless, to_float
from ..observables import positive_int
from .compositions import Composition, requested_composition
from .energy_settings import (
    CONTROLLER_DEFAULTS,
    DEFAULT_SLOPE_DAMPING,
    ControllerSettings,
    alpha_scale_of,
    controller_settings,
)
from .pieces import (
    DEFAULT_CONSTRAINT_TOLERANCE,
    MidpointConvergenceError,
    _StepProgram,
    first_forces,
    last_forces,
)
from .variables import (
    ALPHA,
    MIDPOINT_CHANGE,
    MIDPOINT_ITERATIONS,
)

DEFAULT_MIDPOINT_TOLERANCE = 1e-10  # nm, RMS change of x1 per degree of freedom
DEFAULT_MAX_MIDPOINT_ITERATIONS = 20


class AlphaRattleIntegrator(_StepProgram):
    """α-RATTLE: a one-parameter family of symplectic constrained integrators.

    The potential is integrated along the straight path x0 → x1 with weights
    (½−α, 2α, ½−α) at (0, ½, 1); α = 0 is RATTLE. For every fixed α the map is
    symplectic on the constraint manifold, symmetric, keeps the constraints and
    quadratic invariants (linear and angular momentum), and is of order 2
    (Li & Wang, J. Comput. Math. 41, 2023).

    With ``order=4`` or ``6``, or a ``composition``, the step is a symmetric composition
    of such steps (:mod:`~.compositions`), α on its middle stage unless ``alpha_stages``
    says otherwise. With ``alpha="energy"`` the call returns an
    :class:`AlphaRattleEnergyIntegrator`, which chooses α anew every step so that the
    total energy after the step equals E_ref, the energy of the starting state (the
    controller: this module's docstring). Each step is still a member of the family, so
    constraints and linear momentum are kept exactly and angular momentum to the
    midpoint tolerance; symplecticity is given up. The energy mode's options below are
    refused with a fixed α, where they would do nothing, and its properties and methods
    exist only on the energy-mode integrator.

    :meth:`program_listing` prints the step program OpenMM runs; docs/step_programs.md
    lists every configuration's.

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
        level). In the energy mode with a periodic box 1e-7 nm (order 2) or 1e-5 nm
        (order 4, where α* is ~100× smaller), since there it only limits how well
        angular momentum is kept (ΔL ≈ 2hα δx_m × F per step), which a periodic box
        does not conserve anyway, and the energy is measured on the state the step
        ends in whatever the midpoint; without a periodic box 1e-13 nm, set by
        :meth:`check_context`, which keeps angular momentum to round-off.
    max_midpoint_iterations
        Cap on midpoint force evaluations per step (in the energy mode summed over the
        trials; a trial takes one or more midpoint evaluations and one (order 2) or two
        (order 4) more).
    alpha_bounds
        Energy mode: the interval (low, high) α* is kept in; default (−0.5, 1.5) at
        order 2; on a composition (−0.2, 0.2) × s, s = (1.702/|c_α|)³ the α
        stage's authority against the triple jump's middle stage
        (:func:`~.energy_settings.alpha_scale_of`: 1 for the triple jump, 17.3 for
        Suzuki's 5-stage composition).
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
        and further trials only converge the midpoint force. At least 2: only a
        second trial measures the slope dH/dα that moves α. Default 3 at order 2,
        4 at order 4 (where a trial after the first is short; taking its last
        sub-step once α stopped does not count as a trial).
    max_alpha_change
        Energy mode: the largest change of α one secant update may make (default 1
        at order 2, 0.05 × s on a composition).
    alpha_probe
        Energy mode: the smallest first move of α in a step, so that the step can
        measure its own slope dH/dα (default 0.05 at order 2, 0.005 × s on a composition).
    slope_damping
        Energy mode: d in the damped secant step Δα = −r S/(S² + (d S̄)²), where S̄
        is a running mean of the measured slopes |S| (0 turns the damping off).
    order
        2 (default): the α-RATTLE step. 4: α-RATTLE-4, the default fourth-order
        composition, Suzuki's five stages (p, p, 1 − 4p, p, p), p = 1/(4 − 4^{1/3}):
        fourth order at α = 0 (five force evaluations per step), second order at a
        fixed α ≠ 0 on one stage, and fourth order again in the energy mode, where
        α* = O(h²). Its sub-steps are 0.41h and −0.66h. 6: the default sixth-order
        composition, McLachlan's nine stages. ``docs/compositions.md`` has the
        measurements behind the defaults.
    composition
        A name of :data:`~.compositions.COMPOSITIONS` (``"triple-jump"``, the former
        order-4 default, three stages 1.35h, −1.70h, 1.35h; ``"suzuki5"``,
        ``"mclachlan5"``, ``"yoshida7"``, ``"kahan-li-s9odr6a"``, ``"mclachlan9"``) or a
        :class:`~.compositions.Composition`; sets the order.
    alpha_stages
        The stages that carry α: ``"middle"`` (default), ``"all"`` or stage numbers
        (1-based). With α on every stage a fixed α keeps the composition's order (it
        composes one symmetric second-order method); the energy mode takes α on one
        stage.

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
    #: True if α is chosen each step to hold the energy (``alpha="energy"``).
    energy_mode: ClassVar[bool] = False

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
        max_trials: int | None = None,
        max_alpha_change: float | None = None,
        alpha_probe: float | None = None,
        slope_damping: float = DEFAULT_SLOPE_DAMPING,
        order: int | None = None,
        composition: str | Composition | None = None,
        alpha_stages: str | tuple[int, ...] | None = None,
    ) -> None:
        order, chosen = _order_and_composition(order, composition, alpha_stages)
        if chosen is not None and _is_energy_mode(alpha) and len(chosen.alpha_stages) != 1:
            raise InputError(
                "the energy mode takes alpha on one stage of a composition, got stages "
                f"{chosen.alpha_stages} of {chosen.name!r}; use alpha_stages='middle' or one stage "
                "number, or a fixed alpha."
            )
        self._composition = chosen
        controls = 2 if chosen is None else 4  # the controller's defaults: one step, or a composition
        if _is_energy_mode(alpha) != self.energy_mode:
            raise InputError(
                f"{type(self).__name__} was given alpha={alpha!r}; create integrators with "
                "AlphaRattleIntegrator(timestep, alpha), where alpha='energy' gives the energy mode."
            )
        if self.energy_mode:
            settings = controller_settings(
                controls,
                alpha_bounds,
                energy_tolerance,
                max_trials,
                max_alpha_change,
                alpha_probe,
                slope_damping,
                automatic_midpoint_tolerance=midpoint_tolerance is None,
                alpha_scale=1.0 if chosen is None else alpha_scale_of(chosen),
            )
            low, high = settings.alpha_bounds
            start_alpha = min(max(0.0, low), high)
            default_tolerance = CONTROLLER_DEFAULTS[controls].midpoint_tolerance
        else:
            _refuse_energy_options(
                alpha,
                alpha_bounds=alpha_bounds is not None,
                energy_tolerance=energy_tolerance is not None,
                max_trials=max_trials is not None,
                max_alpha_change=max_alpha_change is not None,
                alpha_probe=alpha_probe is not None,
                slope_damping=slope_damping != DEFAULT_SLOPE_DAMPING,
            )
            settings = None
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
        self._add_midpoint_variables(start_alpha, tolerance, max_iterations, order, chosen)
        self._add_program(settings)

    def __new__(cls, *args: object, **kwargs: object) -> AlphaRattleIntegrator:
        """``alpha="energy"`` makes an :class:`AlphaRattleEnergyIntegrator`."""
        alpha = args[1] if len(args) > 1 else kwargs.get("alpha", 0.0)
        if cls is AlphaRattleIntegrator and _is_energy_mode(alpha):  # type: ignore[arg-type]
            from .energy_mode import AlphaRattleEnergyIntegrator

            cls = AlphaRattleEnergyIntegrator
        return super().__new__(cls)

    def _add_program(self, settings: ControllerSettings | None) -> None:
        """Add the fixed-α program, starting with the update-context-state step."""
        build = self._build_program if self._composition is None else self._build_composition_program
        self._add_step(build, update_context_state=True)

    # ---------------------------------------------------------------- programs
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
        self._add_midpoint_end_step()

    def _build_composition_program(self) -> None:
        """Build a composition with fixed α: its stages before the first α stage, then a loop over the rest.

        For the triple jump: RATTLE (γ1 h), then the loop over α-RATTLE (γ2 h) and
        RATTLE (γ1 h). Every stage after the first α stage is inside the loop, before
        its midpoint block, so that its position constraint precedes the midpoint
        assignment in program text. A failed midpoint iteration makes every remaining
        sub-step return the state the step started from.
        """
        composition = self._composition
        self._add_save_step_start(xstep="x", vstep="v", fstart="f")
        self._add_leading_substeps(composition)
        self._add_alpha_substeps_start(composition, "1 - delta(alpha)", fmid="f")
        self._add_composition_loop(composition)
        self._add_midpoint_end_step()

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

    def _massless_refusal(self, count: int, platform: str | None) -> str | None:
        if count and (self.energy_mode or self.alpha != 0.0):
            return (
                f"{type(self).__name__} with "
                f"{'the energy mode' if self.energy_mode else f'alpha={self.alpha}'} cannot integrate "
                f"this system: {count} particle(s) have zero mass (virtual sites). "
                "α ≠ 0 takes a force at the unconstrained midpoint of the step, where no OpenMM "
                "platform places virtual sites. With virtual sites use alpha=0 (RATTLE, or order=4 for "
                "a fourth-order composition of RATTLE steps) on CUDA, OpenCL or HIP after "
                "integrator.check_context(context), or "
                "openmm.VerletIntegrator."
            )
        return super()._massless_refusal(count, platform)

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
        if self.energy_mode:  # the user's choice: not changed for the system
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
        """2 (the α-RATTLE step), or the order of the composition at α = 0 (4, 6)."""
        return int(self.getGlobalVariableByName("order"))

    def __repr__(self) -> str:
        alpha = "'energy'" if self.energy_mode else self.alpha
        chosen = self.composition
        extra = ""
        if chosen is not None:
            extra = f", composition={chosen.name!r}"
            if chosen.alpha_stages != chosen.with_alpha_on("middle").alpha_stages:
                extra += f", alpha_stages={chosen.alpha_stages}"
        return f"{type(self).__name__}(timestep={self.timestep}, alpha={alpha}{extra})"

    def __getattr__(self, name: str) -> object:
        if name in _energy_mode_only_names():
            raise AttributeError(_energy_mode_only(name))
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __setattr__(self, name: str, value: object) -> None:
        if name in _energy_mode_only_names() and not self.energy_mode:
            raise AttributeError(_energy_mode_only(name))
        super().__setattr__(name, value)


def _order_and_composition(
    order: object, name: str | Composition | None, alpha_stages: str | tuple[int, ...] | None
) -> tuple[int, Composition | None]:
    """Return the order and the composition (None: one α-RATTLE step) that the options ask for."""
    chosen = requested_composition(order, name)
    if chosen is None:
        if alpha_stages is not None:
            raise InputError("alpha_stages applies to a composition; give order=4 or 6, or a composition.")
        return 2, None
    if alpha_stages is not None:
        chosen = chosen.with_alpha_on(alpha_stages)
    return chosen.order, chosen


def _is_energy_mode(alpha: float | str) -> bool:
    """Tell whether ``alpha`` asks for the energy mode; refuse any other string."""
    if isinstance(alpha, str) and alpha != "energy":
        raise InputError(f"alpha must be a number or 'energy', got {alpha!r}.")
    return isinstance(alpha, str)


def _refuse_energy_options(alpha: object, **given: bool) -> None:
    """Refuse energy-mode options given with a fixed α, where they would do nothing."""
    names = [name for name, was_given in given.items() if was_given]
    if names:
        raise InputError(
            f"{', '.join(names)}: option(s) of the energy mode, given with a fixed alpha={alpha!r}, where "
            "they do nothing. Pass alpha='energy' for the energy mode, or leave them out."
        )


def _energy_mode_only(name: str) -> str:
    return (
        f"{name} exists only in the energy-preserving mode; create the integrator with "
        "AlphaRattleIntegrator(timestep, alpha='energy')."
    )


@cache
def _energy_mode_only_names() -> frozenset[str]:
    """Return what the energy mode has and a fixed α has not: its public properties and methods."""
    from .energy_mode import AlphaRattleEnergyIntegrator

    return frozenset(
        name
        for cls in AlphaRattleEnergyIntegrator.__mro__
        if cls is not AlphaRattleIntegrator and not issubclass(AlphaRattleIntegrator, cls)
        for name in vars(cls)
        if not name.startswith("_") and name != "energy_mode"
    )
