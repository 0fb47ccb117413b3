"""The energy mode on the explicit α-family, as a measurement prototype, against the rescaling.

Each step chooses α* so that H(x1, v1) = E_ref (E_ref the start's total energy) for the
two-stage splitting kick((½−α)h) · drift(h/2) · kick(2αh) · drift(h/2) · kick((½−α)h):
a trial of an α is one whole step of the splitting from the step's start, two force
evaluations (F at the half-drift point x_½, which depends on α through the first kick, and
F at x1; F(x0) is the previous step's last and free). The step program
(:class:`AlphaGlobalSplitting`) is ``SplittingRattleIntegrator``'s, built from the same
pieces, with the kick coefficients written as expressions of a global ``alpha``; it keeps
the step's start (x0, v0, F(x0)) and the best trial so far (x1, v1, F(x1)) in per-DOF
variables, so a retry and a return to the best trial cost no force evaluation: the
prototype pays exactly the logical count, 2 per trial. The controller (:class:`EnergyModeController`,
Python) solves H(α) = E_ref by the secant method from α₀ = 0.3068 (the minimum-error
member) and α₁ = α₀ + δ, α kept in [0, ½] (kicks non-negative), at most ``max_trials``
trials; where no trial reaches the tolerance the step ends in the trial closest to E_ref
(counted).

The script measures it from a shipped start against the explicit member with the
rescaling, RATTLE (with and without the rescaling) and ``rattle4+rescale`` at equal force
evaluations: per row the force evaluations per step, RMS(H − E_ref) over ``--steps`` steps
of h, and the RMS position error per atom against RATTLE at h/64 after 5 / 20 / 50 steps.
CPU platform by default. Prints a table; ``--json`` also writes it.

    python tools/scripts/splitting_energy_mode.py --system tip3p-2nm --timestep 2 --json out.json

The wall-clock of a Python-driven controller is not a fair cost; the logical number of
force evaluations is a lower bound on any implementation's cost.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import openmm as mm
import openmm.unit as unit

from openmm_alphaprk.integrators.pieces import DEFAULT_CONSTRAINT_TOLERANCE, _StepProgram
from openmm_alphaprk.integrators.splittings import MINIMUM_ERROR2
from openmm_alphaprk.observables import rms, total_energy
from openmm_alphaprk.runs.accuracy import (
    Trajectory,
    horizon_errors,
    periodic_box,
    reference,
    run_trajectory,
    start_context,
)
from openmm_alphaprk.runs.integrator_names import at_divisor
from openmm_alphaprk.systems import prepare_system

#: The minimum-error member's α: the first trial of every step.
ALPHA_ME = MINIMUM_ERROR2.alpha
HORIZONS = (5, 20, 50)

#: The program's modes (global ``mode``): a new step from the current state, a retry of
#: the step from its saved start, a return to the best trial's saved end (no force).
NEW_STEP, RETRY, RESTORE_BEST = 0, 1, 2


class AlphaGlobalSplitting(_StepProgram):
    """The two-stage splitting with its kicks read from the global ``alpha``: one trial per ``step(1)``.

    Sub-steps (drift fraction, kick before / drift, kick after / drift): (½, 1−2α, 2α) and
    (½, 2α, 1−2α), as ``Splitting.substeps()`` gives for the two-stage set; the pieces are
    ``SplittingRattleIntegrator``'s. Globals: ``alpha``; ``mode`` (0: a new step from the
    current state, its start and F(x0) saved; 1: the step again from the saved start with
    the saved F(x0); 2: end in the best trial's state, no force); ``e_ref``; after a trial
    ``h_trial`` = U(x1) + K(v1) (the energy read with F(x1), a kinetic sum), and the best
    trial's |H − E_ref| in ``best_deviation``. Each trial counts two force evaluations in
    ``force_evaluations``. No update-context-state step: NVE, as the energy modes are.
    """

    _kind = 0

    def __init__(
        self,
        timestep: unit.Quantity | float,
        *,
        alpha: float = ALPHA_ME,
        constraint_tolerance: float = DEFAULT_CONSTRAINT_TOLERANCE,
    ) -> None:
        super().__init__(timestep, constraint_tolerance)
        for name, value in (
            ("alpha", alpha),
            ("mode", NEW_STEP),
            ("e_ref", 0.0),
            ("h_trial", 0.0),
            ("kinetic", 0.0),
            ("best_deviation", 0.0),
            ("best_alpha", 0.0),
            ("best_h", 0.0),
            ("use_best_force", 0.0),
        ):
            self.addGlobalVariable(name, value)
        for name in ("xs", "vs", "fs", "xb", "vb", "fb"):
            self.addPerDofVariable(name, 0)
        self._add_step(self._build_program, update_context_state=False)

    def _build_program(self) -> None:
        # a new step: the start and its force (the last step's F(x1), or the kept best trial's)
        self.beginIfBlock(f"mode < {NEW_STEP + 0.5}")
        self.beginIfBlock("use_best_force > 0.5")
        self.addComputePerDof("fs", "fb")
        self.endBlock()
        self.beginIfBlock("use_best_force < 0.5")
        self.addComputePerDof("fs", "f")
        self.endBlock()
        self.addComputeGlobal("use_best_force", "0")
        self.addComputePerDof("xs", "x")
        self.addComputePerDof("vs", "v")
        self.addComputeGlobal("best_deviation", "1e300")
        self.endBlock()
        # a retry: back to the start
        self.beginIfBlock(f"abs(mode - {RETRY}) < 0.5")
        self.addComputePerDof("x", "xs")
        self.addComputePerDof("v", "vs")
        self.addConstrainPositions()  # no move (xs is constrained); the next SHAKE projects along G(xs)
        self.endBlock()
        # one trial: the splitting's two sub-steps at the current alpha
        self.beginIfBlock(f"mode < {RETRY + 0.5}")
        self._add_save_step_start()
        self._add_position_solve("(1 - 2*alpha)*fs", "(0.5*dt)")
        self._add_velocity_update("(2*alpha)*f", "(0.5*dt)")
        self.addComputePerDof("x0", "x")
        self.addComputePerDof("v0", "v")
        self._add_position_solve("(2*alpha)*f", "(0.5*dt)")
        self._add_velocity_update("(1 - 2*alpha)*f", "(0.5*dt)")
        self._add_sum("kinetic", "0.5*m*v*v")
        self.addComputeGlobal("h_trial", "energy + kinetic")
        self.beginIfBlock("abs(h_trial - e_ref) < best_deviation")
        self.addComputeGlobal("best_deviation", "abs(h_trial - e_ref)")
        self.addComputeGlobal("best_alpha", "alpha")
        self.addComputeGlobal("best_h", "h_trial")
        self.addComputePerDof("xb", "x")
        self.addComputePerDof("vb", "v")
        self.addComputePerDof("fb", "f")
        self.endBlock()
        self._add_end_step()
        self.endBlock()
        # the best trial's end: its state and force kept, no evaluation
        self.beginIfBlock(f"mode > {RESTORE_BEST - 0.5}")
        self.addComputePerDof("x", "xb")
        self.addComputePerDof("v", "vb")
        self.addConstrainPositions()  # no move; the next step's SHAKE projects along G(xb)
        self.addComputeGlobal("use_best_force", "1")
        self.addComputeGlobal("h_trial", "best_h")
        self.addComputeGlobal("alpha", "best_alpha")
        self.endBlock()

    def trial(self, alpha: float, mode: int) -> float:
        """Take one trial at ``alpha`` (``mode`` NEW_STEP or RETRY); return its H (kJ/mol)."""
        self.setGlobalVariableByName("alpha", alpha)
        self.setGlobalVariableByName("mode", mode)
        self.step(1)
        return self.getGlobalVariableByName("h_trial")

    def restore_best(self) -> None:
        """End the step in the best trial's state (positions, velocities, force kept; no evaluation)."""
        self.setGlobalVariableByName("mode", RESTORE_BEST)
        self.step(1)


@dataclass
class EnergyModeController:
    """Choose α per step so that H(x1, v1) = E_ref: the secant method on α, in [0, ½].

    ``tolerance``: |H − E_ref| ≤ max(``relative_tolerance``·|E_ref|, ``absolute_tolerance``)
    ends the step. ``start``: "me" (every step from α = 0.3068) or "last" (from the last
    step's α*).
    """

    integrator: AlphaGlobalSplitting
    e_ref: float
    max_trials: int = 4
    relative_tolerance: float = 1e-6
    absolute_tolerance: float = 0.0
    delta: float = 0.02
    start: str = "me"
    bounds: tuple[float, float] = (0.0, 0.5)
    alphas: list[float] = field(default_factory=list)
    trials: list[int] = field(default_factory=list)
    missed: list[bool] = field(default_factory=list)
    restored: int = 0
    at_bound: int = 0

    def __post_init__(self) -> None:
        self.integrator.setGlobalVariableByName("e_ref", self.e_ref)

    @property
    def tolerance(self) -> float:
        return max(self.relative_tolerance * abs(self.e_ref), self.absolute_tolerance)

    def _clip(self, alpha: float) -> float:
        return min(max(alpha, self.bounds[0]), self.bounds[1])

    def step(self) -> float:
        """Take one controlled step; return its α*."""
        tol = self.tolerance
        a0 = ALPHA_ME if self.start == "me" or not self.alphas else self.alphas[-1]
        tried = [(a0, self.integrator.trial(a0, NEW_STEP) - self.e_ref)]
        done = abs(tried[0][1]) <= tol
        while not done and len(tried) < self.max_trials:
            (a_prev, r_prev), (a_last, r_last) = (tried[-2] if len(tried) > 1 else (None, None)), tried[-1]
            if a_prev is None or r_last == r_prev:
                a_next = a_last + self.delta if a_last + self.delta <= self.bounds[1] else a_last - self.delta
            else:
                a_next = a_last - r_last * (a_last - a_prev) / (r_last - r_prev)
            a_next = self._clip(a_next)
            if any(a_next == a for a, _ in tried):  # at a bound already tried: the root is beyond it
                self.at_bound += 1
                break
            tried.append((a_next, self.integrator.trial(a_next, RETRY) - self.e_ref))
            done = abs(tried[-1][1]) <= tol
        best = min(range(len(tried)), key=lambda i: abs(tried[i][1]))
        if best != len(tried) - 1:
            self.integrator.restore_best()
            self.restored += 1
        self.alphas.append(tried[best][0])
        self.trials.append(len(tried))
        self.missed.append(abs(tried[best][1]) > tol)
        return tried[best][0]

    def summary(self) -> dict:
        alphas = np.array(self.alphas)
        trials = np.array(self.trials)
        histogram, edges = np.histogram(alphas, bins=10, range=self.bounds)
        return {
            "steps": len(alphas),
            "tolerance_kj_per_mol": self.tolerance,
            "max_trials": self.max_trials,
            "delta": self.delta,
            "start": self.start,
            "mean_trials": float(trials.mean()),
            "trials_histogram": {str(k): int((trials == k).sum()) for k in range(1, self.max_trials + 1)},
            "fraction_missed": float(np.mean(self.missed)),
            "steps_ended_in_an_earlier_trial": self.restored,
            "steps_stopped_at_a_bound": self.at_bound,
            "alpha_quantiles": {
                q: float(np.quantile(alphas, float(q)))
                for q in ("0", "0.05", "0.25", "0.5", "0.75", "0.95", "1")
            },
            "alpha_mean": float(alphas.mean()),
            "alpha_histogram": {"edges": [float(e) for e in edges], "counts": [int(c) for c in histogram]},
            "fraction_at_bounds": float(np.mean((alphas <= self.bounds[0]) | (alphas >= self.bounds[1]))),
        }


def run_energy_mode(prepared, h: float, horizons, platform_name: str = "CPU", **options):
    """Run the energy mode from ``prepared``'s start: (Trajectory, controller, logical evaluations/step)."""
    integrator = AlphaGlobalSplitting(h)
    context = start_context(prepared, integrator, platform_name)
    e_ref = total_energy(context)
    controller = EnergyModeController(integrator, e_ref, **options)
    wanted, last = set(horizons), max(horizons)
    positions, velocities, residuals, in_program = {}, {}, [], []
    blew_up = None
    for step in range(1, last + 1):
        try:
            controller.step()
        except Exception:  # a failed step is the blow-up the caller reports
            blew_up = step
            break
        residuals.append(total_energy(context) - e_ref)
        in_program.append(integrator.getGlobalVariableByName("h_trial") - e_ref)
        if not math.isfinite(residuals[-1]):
            blew_up = step
            break
        if step in wanted:
            state = context.getState(getPositions=True, getVelocities=True)
            positions[step] = state.getPositions(asNumpy=True).value_in_unit(unit.nanometers)
            velocities[step] = state.getVelocities(asNumpy=True).value_in_unit(
                unit.nanometers / unit.picoseconds
            )
    steps_done = len(controller.trials)
    logical = 2.0 * sum(controller.trials) / max(steps_done, 1)
    counted = integrator.force_evaluations / max(steps_done, 1)
    trajectory = Trajectory(
        positions, velocities, np.array(residuals), logical, {}, blew_up, integrator, context
    )
    controller.in_program_residuals = np.array(in_program)
    return trajectory, controller, counted


def parse_rows(specs):
    """``NAME@K`` → (label, name, K): ``split-me+rescale@2`` is split-me+rescale at h/2."""
    rows = []
    for spec in specs:
        name, _, k = spec.partition("@")
        divisor = int(k) if k else 1
        rows.append((name if divisor == 1 else f"{name} at h/{divisor}", name, divisor))
    return rows


DEFAULT_ROWS = (
    "split-me",
    "split-me+rescale",
    "split-me+rescale@2",
    "split-me+rescale@3",
    "split-me+rescale@4",
    "rattle+rescale@2",
    "rattle+rescale@4",
    "rattle+rescale@6",
    "rattle+rescale@8",
    "rattle@2",
    "rattle@4",
    "rattle@6",
    "rattle@8",
    "rattle4+rescale",
)


def main(argv: list[str] | None = None) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))  # the survey beside this script
    from splitting_survey import print_row, row_entry

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument("--timestep", type=float, default=2.0, help="fs")
    parser.add_argument("--steps", type=int, default=500, help="steps of h for RMS(H - E_ref)")
    parser.add_argument("--horizons", type=int, nargs="+", default=list(HORIZONS), help="steps of h")
    parser.add_argument(
        "--rows",
        nargs="*",
        default=list(DEFAULT_ROWS),
        help="other rows, NAME or NAME@K (at h/K); the energy mode is always run",
    )
    parser.add_argument(
        "--energy-modes",
        nargs="+",
        default=["1e-6:4", "1e-9:6"],
        help="energy-mode rows, each RELATIVE_TOLERANCE:MAX_TRIALS (|H - E_ref| <= tol*|E_ref|)",
    )
    parser.add_argument(
        "--absolute-tolerance", type=float, default=0.0, help="kJ/mol, a floor of the tolerance"
    )
    parser.add_argument("--delta", type=float, default=0.02, help="alpha_1 - alpha_0")
    parser.add_argument("--start", choices=("me", "last"), default="me")
    parser.add_argument("--platform", default="CPU")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    horizons = sorted(args.horizons)
    prepared = prepare_system(args.system)
    h = args.timestep / 1000.0
    box = periodic_box(prepared)
    started = time.perf_counter()
    ref = run_trajectory(prepared, reference(h), horizons, platform=args.platform, read_energy=False)
    print(f"reference RATTLE at h/64: {time.perf_counter() - started:.0f} s", flush=True)
    rows, summaries = [], {}

    for spec in args.energy_modes:
        tolerance, _, trials = spec.partition(":")
        options = {
            "max_trials": int(trials or 4),
            "relative_tolerance": float(tolerance),
            "absolute_tolerance": args.absolute_tolerance,
            "delta": args.delta,
            "start": args.start,
        }
        label = f"split-energy tol {float(tolerance):g}, <= {options['max_trials']} trials"
        started = time.perf_counter()
        run, controller, counted = run_energy_mode(
            prepared, h, [*horizons, args.steps], args.platform, **options
        )
        summaries[label] = controller.summary()
        entry = row_entry(
            label,
            "split-energy",
            1,
            run,
            horizon_errors(run, ref, box, args.timestep),
            started,
            evaluations_counted_by_the_program=counted,
            rms_residual_read_in_the_program=rms(controller.in_program_residuals),
            relative_tolerance=float(tolerance),
            max_trials=options["max_trials"],
            mean_trials=summaries[label]["mean_trials"],
            fraction_missed=summaries[label]["fraction_missed"],
        )
        rows.append(entry)
        print_row(entry, 36)
        print(json.dumps(summaries[label]), flush=True)
    for label, name, divisor in parse_rows(args.rows):
        started = time.perf_counter()
        run = run_trajectory(
            prepared, at_divisor(name, h, divisor), [*horizons, args.steps], platform=args.platform
        )
        entry = row_entry(label, name, divisor, run, horizon_errors(run, ref, box, args.timestep), started)
        rows.append(entry)
        print_row(entry, 36)
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(
                {
                    "system": args.system,
                    "timestep_fs": args.timestep,
                    "steps": args.steps,
                    "horizons": horizons,
                    "platform": args.platform,
                    "openmm": mm.__version__,
                    "python": platform.python_version(),
                    "reference": "RATTLE at h/64, constraint tolerance 1e-10",
                    "energy_mode": {
                        "method": "two-stage splitting, alpha per step by the secant method on "
                        "H(alpha) = E_ref, alpha in [0, 1/2], from alpha_0 = 0.3068 (me2) and "
                        "alpha_0 + delta; the step ends in the trial closest to E_ref",
                        "evaluations": "logical: 2 per trial (F(x_1/2), F(x1)); F(x0) is the last "
                        "step's. The prototype keeps the start and the best trial in per-DOF variables and "
                        "pays the same count (evaluations_counted_by_the_program)",
                        "rows": summaries,
                    },
                    "rows": rows,
                },
                handle,
                indent=1,
            )


if __name__ == "__main__":
    main()
