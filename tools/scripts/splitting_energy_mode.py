"""The energy mode over the explicit family against the rescaling, at equal force evaluations.

The energy mode is the package's (``AlphaRattleEnergyIntegrator(splitting="me2")``): each step
takes the two-stage member α₀ + α, α chosen inside the step program by the energy mode's
controller so that H(x1, v1) = E_ref; a trial costs two force evaluations. Its rows use the
tolerance ``TOL``·|E_ref| (E_ref the start's total energy) and at most ``TRIALS`` trials a step
(``--energy-modes TOL:TRIALS``). Beside them the other rows (``NAME`` or ``NAME@K``, the name
at h/K), all from one shipped start: per row the force evaluations per step, RMS(H − E_ref)
over ``--steps`` steps of h, and the RMS position error per atom against RATTLE at h/64 after
5 / 20 / 50 steps. CPU platform by default. Prints a table; ``--json`` also writes it (read by
docs/splitting.md's generator).

    python tools/scripts/splitting_energy_mode.py --system tip3p-2nm --timestep 2 --json out.json
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from functools import partial
from pathlib import Path

import openmm as mm

from openmm_alphaprk import AlphaRattleEnergyIntegrator, ControllerSettings, RattleIntegrator
from openmm_alphaprk.observables import total_energy
from openmm_alphaprk.runs.accuracy import (
    horizon_errors,
    periodic_box,
    reference,
    run_trajectory,
    start_context,
)
from openmm_alphaprk.runs.integrator_names import SubStepped, at_divisor
from openmm_alphaprk.systems import prepare_system


def print_row(entry: dict) -> None:
    """Print a row: cost, RMS(H − E_ref), position errors at the horizons."""
    errors = " / ".join(f"{e:.2g}" for e in entry["position_rms"])
    cost = f"evals {entry['evaluations']:5.2f} RMS {entry['rms_residual']:.3g}"
    print(f"{entry['row']:36} {cost}  x err {errors}", flush=True)


DEFAULT_ROWS = (
    "split-me",
    "split-me+rescale",
    *(f"split-me+rescale@{k}" for k in (2, 3, 4)),
    *(f"rattle+rescale@{k}" for k in (2, 4, 6, 8)),
    *(f"rattle@{k}" for k in (2, 4, 6, 8)),
    "rattle4+rescale",
)


def parse_rows(specs: list[str]) -> list[tuple[str, str, int]]:
    """``NAME@K`` → (label, name, K): ``split-me+rescale@2`` is split-me+rescale at h/2."""
    rows = []
    for spec in specs:
        name, _, k = spec.partition("@")
        divisor = int(k) if k else 1
        rows.append((name if divisor == 1 else f"{name} at h/{divisor}", name, divisor))
    return rows


def main(argv: list[str] | None = None) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))  # the survey beside this script
    from splitting_survey import HORIZONS, row_entry

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument("--timestep", type=float, default=2.0, help="fs")
    parser.add_argument("--steps", type=int, default=500, help="steps of h for RMS(H - E_ref)")
    parser.add_argument("--horizons", type=int, nargs="+", default=list(HORIZONS), help="steps of h")
    parser.add_argument("--rows", nargs="*", default=list(DEFAULT_ROWS), help="NAME or NAME@K (at h/K)")
    parser.add_argument(
        "--energy-modes",
        nargs="+",
        default=["1e-6:4", "1e-9:6"],
        help="TOL:TRIALS, |H - E_ref| <= TOL*|E_ref|",
    )
    parser.add_argument("--platform", default="CPU")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    horizons, runs = sorted(args.horizons), [*sorted(args.horizons), args.steps]
    prepared = prepare_system(args.system)
    h = args.timestep / 1000.0
    box = periodic_box(prepared)
    e_ref = total_energy(start_context(prepared, RattleIntegrator(h), args.platform))
    ref = run_trajectory(prepared, reference(h), horizons, platform=args.platform, read_energy=False)
    rows, summaries = [], {}
    for spec in args.energy_modes:
        tolerance, _, trials = spec.partition(":")
        settings = ControllerSettings(
            energy_tolerance=float(tolerance) * abs(e_ref), max_trials=int(trials or 4)
        )
        label = f"split-energy tol {float(tolerance):g}, <= {settings.max_trials} trials"
        started = time.perf_counter()
        make = partial(AlphaRattleEnergyIntegrator, h, splitting="me2", controller=settings)
        run = run_trajectory(prepared, SubStepped(make), runs, platform=args.platform)
        totals = summaries[label] = run.integrator.controller_totals()
        errors = horizon_errors(run, ref, box, args.timestep)
        extra = {
            "relative_tolerance": float(tolerance),
            "max_trials": settings.max_trials,
            "fraction_missed": totals["fraction_fallen_back"],
        }
        rows.append(row_entry(label, "split-energy", 1, run, errors, started, **extra))
        print_row(rows[-1])
    for label, name, divisor in parse_rows(args.rows):
        started = time.perf_counter()
        run = run_trajectory(prepared, at_divisor(name, h, divisor), runs, platform=args.platform)
        rows.append(
            row_entry(label, name, divisor, run, horizon_errors(run, ref, box, args.timestep), started)
        )
        print_row(rows[-1])
    if args.json:
        document = {
            "system": args.system,
            "timestep_fs": args.timestep,
            "steps": args.steps,
            "horizons": horizons,
            "platform": args.platform,
            "openmm": mm.__version__,
            "python": platform.python_version(),
            "reference": "RATTLE at h/64, constraint tolerance 1e-10",
            "energy_mode": {
                "method": "AlphaRattleEnergyIntegrator(splitting='me2'): the member alpha0 + alpha per step, "
                "alpha chosen by the energy mode's controller in the step program",
                "rows": summaries,
            },
            "rows": rows,
        }
        Path(args.json).write_text(json.dumps(document, indent=1), encoding="utf-8")


if __name__ == "__main__":
    main()
