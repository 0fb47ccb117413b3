"""The explicit α-family against RATTLE at equal force evaluations, from one start.

For each row: force evaluations per step, RMS(H − E_ref) over ``--steps`` steps (E_ref the
start's total energy), and the RMS position error per atom against RATTLE at h/64 after
5 / 20 / 50 steps (``--horizons``). Rows: RATTLE at h, h/2 and h/3; the two-stage splittings
(α = ¼, BCSS, minimum error) and the three-stage ones (BCSS, minimum error). CPU platform by
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

import openmm as mm

from openmm_alphaprk.observables import rms
from openmm_alphaprk.runs.accuracy import horizon_errors, periodic_box, reference, run_trajectory
from openmm_alphaprk.runs.integrator_names import at_divisor
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
    ref = run_trajectory(
        prepared, reference(h), horizons, platform=args.platform, properties=properties, read_energy=False
    )
    print(f"reference RATTLE at h/64: {time.perf_counter() - started:.0f} s", flush=True)
    rows = []
    for label, name, divisor in ROWS:
        if args.rows and label not in args.rows:
            continue
        started = time.perf_counter()
        run = run_trajectory(
            prepared,
            at_divisor(name, h, divisor),
            [*horizons, args.steps],
            platform=args.platform,
            properties=properties,
        )
        errors = horizon_errors(run, ref, box, args.timestep)
        entry = {
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
        }
        rows.append(entry)
        print(
            f"{label:16} evals {entry['evaluations']:5.2f} RMS {entry['rms_residual']:.3g}  x err "
            + " / ".join(f"{e:.2g}" for e in entry["position_rms"])
            + (f"  blew up at step {run.blew_up_at_step}" if run.blew_up_at_step else ""),
            flush=True,
        )
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(
                {
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
                    "reference": "RATTLE at h/64, constraint tolerance 1e-10",
                    "rows": rows,
                },
                handle,
                indent=1,
            )


if __name__ == "__main__":
    main()
