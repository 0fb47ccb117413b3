"""E_ref, the energy an integrator holds: when it is taken, how it is reset, how it is read.

The integrators that hold the total energy at a reference value — α-RATTLE's energy mode
(:class:`~.energy_mode.AlphaRattleEnergyIntegrator`) and RATTLE with velocity rescaling
(:class:`~.rescale.RattleRescaleIntegrator`) — take E_ref by one rule, written once here:

E_ref is the total energy of the state at the first step, after
:meth:`_ReferenceEnergy.reset_reference_energy`, and after the user changed the state:
the positions or velocities at the start of a step differ from those the previous step
ended with *and* the total energy differs from the one it ended with (``end_energy``) by
more than max(tolerance, 1e-6 |E|). The energy test is what tells a user's change from the
common platform's reordering and re-wrapping of atoms every 250 steps, which moves
coordinates but not the energy. The energy mode's steps end by storing ``xend``, ``vend``
and ``end_energy``; the rescaling's store their end in x0, v0 (every N-th step's energy
only, with ``rescale_interval`` N > 1, whose call records its end once, after its last step).

A state can only be set between calls of ``step()``, so the comparison with the last
step's end (a sum over degrees of freedom: a device synchronisation on CUDA, OpenCL and
HIP) runs at the first step of each call: ``step()`` sets ``state_check`` and ``driven``
before the steps and clears ``driven`` after them. A copy of the program that no
``step()`` of this package drives (a plain ``CustomIntegrator`` deserialized from XML and
not given back its class by :func:`~.restore.restore_integrator`) has ``driven`` = 0 and
compares at every step.

NVE integrators: both leave out OpenMM's update-context-state step, and :meth:`check_context`
warns about the System's barostats and thermostats and about forces that are not smooth.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import openmm as mm
import openmm.unit as unit

from .. import platforms
from .._units import to_float
from ..nve import warn_if_state_changing, warn_if_velocities_off_constraints
from ..smooth_forces import warn_if_not_smooth
from .energy_settings import PROVISIONAL_ENERGY_TOLERANCE
from .variables import N_PARTICLES, REFERENCE_ENERGY

#: Relative energy change between steps below which a moved state counts as the same
#: state (the common platform's reordering), unless the energy tolerance is larger.
SAME_ENERGY = 1e-6


def energy_tolerance_setting(energy_tolerance: unit.Quantity | float | None) -> float | None:
    """Validate an ``energy_tolerance`` argument (kJ/mol); None is the automatic default."""
    if energy_tolerance is None:
        return None
    return to_float(energy_tolerance, unit.kilojoules_per_mole, "energy_tolerance", positive=True)


class _ReferenceEnergy:
    """What an integrator that holds E_ref has: its variables, the reference check, its API.

    Mixed into a :class:`~.pieces._StepProgram` subclass before it:
    ``class X(_ReferenceEnergy, SomeStepProgram)``. The subclass names what it is in
    :attr:`_holds_energy_as` (used in the warnings of :meth:`check_context`).
    """

    #: How the warnings name the integrator ("the energy-preserving mode" …).
    _holds_energy_as = "the energy-preserving mode"

    def _add_reference_energy_variables(self, energy_tolerance: float | None, end_state: bool = True) -> None:
        """Declare E_ref, its rule's state and the energy tolerance (None: automatic).

        ``end_state``: declare ``xend``, ``vend`` too, for a program whose steps record the
        state they end in there (one that records it in x0, v0 declares none).
        """
        automatic = energy_tolerance is None
        self.addGlobalVariable(
            "energy_tolerance", PROVISIONAL_ENERGY_TOLERANCE if automatic else energy_tolerance
        )
        self.addGlobalVariable("energy_tolerance_automatic", float(automatic))
        for name in (
            REFERENCE_ENERGY,
            "reference_set",
            "reference_resets",
            "state_moved",
            "start_energy",
            "end_energy",
            "retake",
            "kinetic_energy",
            "driven",
        ):
            self.addGlobalVariable(name, 0)
        self.addGlobalVariable("state_check", 1)
        for name in ("xend", "vend") if end_state else ():
            self.addPerDofVariable(name, 0)

    def _add_reference_check(
        self,
        on_retake: Sequence[tuple[str, str]] = (),
        on_moved: Callable[[], None] | None = None,
        previous: tuple[str, str] = ("xend", "vend"),
        carried_tolerance: str | None = None,
        after_energy: Callable[[], None] | None = None,
    ) -> None:
        """Take E_ref at the first step, after a reset, and after the user changed the state.

        A start state that differs from the end of the previous step (a sum over
        degrees of freedom, zero when nothing moved, taken at the first step of a
        ``step()`` call) opens the block; inside it the
        energy decides: the common platform's reordering and re-wrapping of atoms move
        coordinates but keep the energy. ``on_retake``: ``(variable, expression)``
        computations that run in the block after ``retake`` is set (the energy mode
        forgets its predictor there); ``on_moved`` adds computations at the block's start.
        ``previous``: the per-DOF variables that hold the last step's end (positions,
        velocities; :meth:`_add_end_state_record` writes them). ``carried_tolerance``: an
        expression (kJ/mol) added to the energy test's tolerance, for a program whose last
        step may have ended without reading its energy (``end_energy`` then carried).
        ``after_energy`` adds computations right after the energy read.

        The force at x0 must have been read (copied) before this block: with the
        energy read here as a step's first evaluation and ``f`` read after it, the
        forces were wrong on CUDA and NVIDIA's OpenCL, not on pocl or Reference (the
        measurement: docs/research/guide_measurements_2026-11-27.md).
        """
        self.beginIfBlock("state_check > 0.5")  # the first step of a step() call (module docstring)
        x_end, v_end = previous
        self._add_sum("state_moved", f"(x - {x_end})^2 + (v - {v_end})^2")
        self.addComputeGlobal("state_check", "1 - driven")
        self.endBlock()
        self.beginIfBlock("state_moved + 1 - reference_set > 0")
        if on_moved is not None:
            on_moved()
        self._add_sum("kinetic_energy", "0.5*m*v*v")
        self.addComputeGlobal("start_energy", "energy + kinetic_energy")
        if after_energy is not None:
            after_energy()
        self.addComputeGlobal(
            "retake",
            "max(1 - reference_set, step(abs(start_energy - end_energy) - same));"
            f"same = max(energy_tolerance, {SAME_ENERGY}*abs(end_energy))"
            + ("" if carried_tolerance is None else f" + {carried_tolerance}"),
        )
        self.addComputeGlobal("reference_energy", "select(retake, start_energy, reference_energy)")
        # H − E_ref at the step's start is end_energy − E_ref (zero after a retake)
        self.addComputeGlobal("end_energy", "select(retake, start_energy, end_energy)")
        for variable, expression in on_retake:
            self.addComputeGlobal(variable, expression)
        self.addComputeGlobal("reference_resets", "reference_resets + retake")
        self.addComputeGlobal("reference_set", "1")
        self.addComputeGlobal("state_moved", "0")
        self.endBlock()

    def _add_end_state_record(self, end_energy: str, into: tuple[str, str] | None = ("xend", "vend")) -> None:
        """Store the total energy the step ends with and the state it ends in (``into``: x, v).

        ``into`` None: the energy alone (a program that records the state elsewhere).
        """
        self.addComputeGlobal("end_energy", end_energy)
        if into is not None:
            self.addComputePerDof(into[0], "x")
            self.addComputePerDof(into[1], "v")

    # ---------------------------------------------------------------- what the user sets and reads
    def reset_reference_energy(self) -> None:
        """Take E_ref from the state at the start of the next step.

        The integrator also notices by itself when positions or velocities were set
        between steps; call this to be explicit, e.g. after changing parameters of a
        force (which changes the energy without changing the state).
        """
        self.setGlobalVariableByName("reference_set", 0)
        self._start_velocities_checked = False

    @property
    def reference_energy(self) -> unit.Quantity:
        """E_ref, the total energy the integrator holds (NaN before the first step)."""
        if not self.getGlobalVariableByName("reference_set") and not self.steps_taken:
            return float("nan") * unit.kilojoules_per_mole
        return self.getGlobalVariableByName(REFERENCE_ENERGY) * unit.kilojoules_per_mole

    @property
    def energy_tolerance(self) -> unit.Quantity:
        """The energy tolerance (kJ/mol): the energy mode's target |H − E_ref| per step.

        Also the test of a changed state: a state set between steps whose total energy is
        within max(tolerance, 1e-6 |E|) of the energy the last step ended with keeps E_ref.
        """
        return self.getGlobalVariableByName("energy_tolerance") * unit.kilojoules_per_mole

    @energy_tolerance.setter
    def energy_tolerance(self, value: unit.Quantity | float) -> None:
        tolerance = to_float(value, unit.kilojoules_per_mole, "energy_tolerance", positive=True)
        self.setGlobalVariableByName("energy_tolerance", tolerance)
        self.setGlobalVariableByName("energy_tolerance_automatic", 0)

    def _set_automatic_energy_tolerance(self, n_atoms: int, precision: str) -> None:
        """Set the default energy tolerance for the system and platform, unless the user chose one."""
        if self.getGlobalVariableByName("energy_tolerance_automatic"):
            tolerance = platforms.default_energy_tolerance(n_atoms, precision)
            self.setGlobalVariableByName("energy_tolerance", tolerance)

    def _check_system(self, context: mm.Context) -> None:
        """Set the default tolerance from the platform's precision, and give the System's warnings.

        The next ``step()`` looks at the start's velocities (:meth:`step`).
        """
        super()._check_system(context)
        self._start_velocities_checked = False
        system = context.getSystem()
        self._set_automatic_energy_tolerance(system.getNumParticles(), platforms.force_precision(context))
        warn_if_not_smooth(system, who=self._holds_energy_as)  # both point at the user's call
        warn_if_state_changing(system, who=self._holds_energy_as)

    def step(self, steps: int) -> None:
        """Advance by ``steps`` steps, comparing the start state with the last step's end at the first.

        The first call after :meth:`check_context` or :meth:`reset_reference_energy`, if E_ref is
        still to be taken, warns when the checked Context's velocities move along the
        constraints (:class:`~openmm_alphaprk.UnconstrainedVelocitiesWarning`).
        """
        if not getattr(self, "_start_velocities_checked", True):
            self._start_velocities_checked = True
            context = self._checked_context()
            if context is not None and not self.getGlobalVariableByName("reference_set"):
                warn_if_velocities_off_constraints(context, who=self._holds_energy_as, stacklevel=4)
        self.setGlobalVariableByName("state_check", 1)
        self.setGlobalVariableByName("driven", 1)
        try:
            super().step(steps)
        finally:
            self.setGlobalVariableByName("driven", 0)
            self.setGlobalVariableByName("state_check", 1)

    def _check_before_steps(self, context: mm.Context | None) -> None:
        super()._check_before_steps(context)
        if context is None:
            particles = int(self.getGlobalVariableByName(N_PARTICLES))
            self._set_automatic_energy_tolerance(particles, platforms.UNKNOWN_PRECISION)
