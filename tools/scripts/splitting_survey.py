"""The explicit α-family against RATTLE at equal force evaluations, from one start.

For each row: force evaluations per step, RMS(H − E_ref) over ``--steps`` steps (E_ref the
start's total energy), and the RMS position error per atom against RATTLE at h/64 (or
``--reference-divisor``) after
5 / 20 / 50 steps (``--horizons``). Rows: RATTLE at h, h/2 and h/3; the two-stage splittings
(α = ¼, BCSS, minimum error, and the last with the rescaling) and the three-stage ones (BCSS,
minimum error); with ``--rows`` also the order-4 rows at 10 force evaluations per step
(RATTLE at h/10, ``alpha4=0`` and ``rattle4+rescale`` at h/2, and Suzuki's five-stage
composition of the minimum-error member at h). CPU platform by
default. Prints a table; ``--json`` also writes it. Used for docs/splitting.md.

    python tools/scripts/splitting_survey.py --system tip3p-2nm --timestep 2 --json out.json
    python tools/scripts/splitting_survey.py --system villin --timestep 4 --hydrogen-mass 3

``--hydrogen-mass`` starts a solute (villin, dhfr) from its definition with the hydrogens
repartitioned, minimized and equilibrated again with the new masses (``villin-h3``).
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from functools import partial

import openmm as mm

from openmm_alphaprk import SplittingRattleIntegrator
from openmm_alphaprk.integrators.compositions import SUZUKI5
from openmm_alphaprk.integrators.splittings import MINIMUM_ERROR2, composed
from openmm_alphaprk.observables import rms
from openmm_alphaprk.runs.accuracy import horizon_errors, periodic_box, reference, run_trajectory
from openmm_alphaprk.runs.integrator_names import SubStepped, at_divisor
from openmm_alphaprk.systems import load_definition, prepare_system

HORIZONS = (5, 20, 50)
ROWS = (
    ("RATTLE at h", "rattle", 1),
    ("RATTLE at h/2", "rattle", 2),
    ("split=1/4", "split=1/4", 1),
    ("split-bcss", "split-bcss", 1),
    ("split-me", "split-me", 1),
    ("split-me+rescale", "split-me+rescale", 1),
    ("RATTLE at h/3", "rattle", 3),
    ("split3-bcss", "split3-bcss", 1),
    ("split3-me", "split3-me", 1),
)
#: Rows run only when ``--rows`` names them: order 4 at 10 force evaluations per step.
ORDER4_ROWS = (
    ("RATTLE at h/10", "rattle", 10),
    ("alpha4=0 at h/2", "alpha4=0", 2),
    ("rattle4+rescale at h/2", "rattle4+rescale", 2),
    ("me2 x suzuki5", "me2 x suzuki5", 1),
)
#: Rows of splittings that have no integrator name: Suzuki's five-stage composition of the
#: minimum-error member (order 4, 10 force evaluations per step), measured before it gets one.
COMPOSED = {
    "me2 x suzuki5": composed(MINIMUM_ERROR2, SUZUKI5.coefficients, "me2 x suzuki5", 4, SUZUKI5.source)
}


def row_integrator(name: str, h: float, divisor: int) -> SubStepped:
    """Return the row ``name`` at h/``divisor``: an integrator name, or a splitting of :data:`COMPOSED`."""
    if name in COMPOSED:
        return SubStepped(partial(SplittingRattleIntegrator, h / divisor, splitting=COMPOSED[name]), divisor)
    return at_divisor(name, h, divisor)


def row_entry(label: str, name: str, divisor: int, run, errors, started: float, **extra) -> dict:
    """Return a row of the survey's JSON: cost, RMS(H − E_ref), errors at the horizons, ``extra``."""
    return {
        "row": label,
        "integrator": name,
        "divisor": divisor,
        "evaluations": run.force_evaluations_per_step,
        "rms_residual": rms(run.residuals),
        "horizons": [e.steps for e in errors],
        "position_rms": [e.position_rms for e in errors],
        "velocity_rms": [e.velocity_rms for e in errors],
        "blew_up_at_step": run.blew_up_at_step,
        "seconds": time.perf_counter() - started,
        **extra,
    }


def parser() -> argparse.ArgumentParser:
    """Return the command line's parser."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument("--timestep", type=float, default=2.0, help="fs")
    parser.add_argument("--steps", type=int, default=500, help="steps of h for RMS(H - E_ref)")
    parser.add_argument("--horizons", type=int, nargs="+", default=list(HORIZONS), help="steps of h")
    parser.add_argument("--hydrogen-mass", type=float, help="repartition hydrogen masses (amu) in the start")
    parser.add_argument("--rows", nargs="+", help="labels of the rows to run (default: all)")
    parser.add_argument("--platform", default="CPU")
    parser.add_argument("--precision", choices=("single", "mixed", "double"), help="CUDA/OpenCL/HIP")
    parser.add_argument(
        "--reference-divisor", type=int, default=64, help="the reference: RATTLE at h/N (default 64)"
    )
    parser.add_argument("--json")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    horizons = sorted(args.horizons)
    if args.hydrogen_mass is None:
        prepared = prepare_system(args.system)
    else:
        prepared = prepare_system(load_definition(args.system).with_hydrogen_mass(args.hydrogen_mass))
    h = args.timestep / 1000.0
    box = periodic_box(prepared)
    started = time.perf_counter()
    properties = {"Precision": args.precision} if args.precision else {}
    run = partial(run_trajectory, prepared, platform=args.platform, properties=properties)
    ref = run(reference(h, args.reference_divisor), horizons, read_energy=False)
    print(
        f"reference RATTLE at h/{args.reference_divisor}: {time.perf_counter() - started:.0f} s", flush=True
    )
    rows = []
    chosen = [row for row in ROWS + ORDER4_ROWS if row[0] in args.rows] if args.rows else ROWS
    for label, name, divisor in chosen:
        started = time.perf_counter()
        result = run(row_integrator(name, h, divisor), [*horizons, args.steps])
        errors = horizon_errors(result, ref, box, args.timestep)
        rows.append(row_entry(label, name, divisor, result, errors, started))
        print(
            f"{label:16} evals {rows[-1]['evaluations']:5.2f} RMS {rows[-1]['rms_residual']:.3g}  x err "
            + " / ".join(f"{e.position_rms:.2g}" for e in errors)
            + (f"  blew up at step {result.blew_up_at_step}" if result.blew_up_at_step else ""),
            flush=True,
        )
    if args.json:
        survey = {
            "system": args.system,
            "timestep_fs": args.timestep,
            "hydrogen_mass_amu": args.hydrogen_mass,
            "start": f"{prepared.name} ({prepared.source})",
            "steps": args.steps,
            "horizons": horizons,
            "platform": args.platform,
            "precision": args.precision,
            "openmm": mm.__version__,
            "python": platform.python_version(),
            "reference": f"RATTLE at h/{args.reference_divisor}, constraint tolerance 1e-10",
            "rows": rows,
        }
        with open(args.json, "w") as handle:
            json.dump(survey, handle, indent=1)


if __name__ == "__main__":
    main()
