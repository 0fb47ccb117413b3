"""Every named composition at α = 0 and in the energy mode (α on its middle stage), from one start.

For each: force evaluations per step, RMS(H − E_ref) over 200 steps and the RMS position
error per atom against RATTLE at h/64 after 5 / 20 / 50 / 200 steps (``--horizons``); RATTLE at h/k beside
them. Prints a table; ``--json`` also writes it. Used for docs/compositions.md.

    python -m openmm_alphaprk.benchmarks.compositions_survey --system tip3p-2nm --timestep 2
"""

from __future__ import annotations

import argparse
import json
import math
from functools import partial

import openmm.unit as unit

from openmm_alphaprk import AlphaRattleEnergyIntegrator, AlphaRattleIntegrator
from openmm_alphaprk.integrators.compositions import COMPOSITIONS
from openmm_alphaprk.observables import rms
from openmm_alphaprk.runs.accuracy import horizon_errors, periodic_box, reference, run_trajectory
from openmm_alphaprk.runs.integrator_names import SubStepped, at_divisor
from openmm_alphaprk.systems import prepare_system

HORIZONS = (5, 20, 50, 200)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument("--timestep", type=float, default=2.0, help="fs")
    parser.add_argument("--horizons", type=int, nargs="+", default=list(HORIZONS), help="steps of h")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    horizons = sorted(args.horizons)
    prepared = prepare_system(args.system)
    h = args.timestep / 1000.0
    box = periodic_box(prepared)
    ref = run_trajectory(prepared, reference(h), horizons, read_energy=False)
    rows = []

    def record(label: str, row: SubStepped) -> float:
        run = run_trajectory(prepared, row, horizons)
        errors = horizon_errors(run, ref, box, args.timestep)
        entry = {
            "row": label,
            "evaluations": run.force_evaluations_per_step,
            "rms_residual": rms(run.residuals),
            "position_rms": [e.position_rms for e in errors],
            "blew_up_at_step": run.blew_up_at_step,
        }
        rows.append(entry)
        print(
            f"{label:34} evals {entry['evaluations']:6.2f} RMS {entry['rms_residual']:.3g}  x err "
            + " / ".join(f"{e:.2g}" for e in entry["position_rms"])
            + (f"  blew up at step {run.blew_up_at_step}" if run.blew_up_at_step else ""),
            flush=True,
        )
        return entry["evaluations"]

    divisors = set()
    for chosen in COMPOSITIONS.values():
        for alpha in (0.0, "energy"):
            if alpha == "energy":
                make = partial(AlphaRattleEnergyIntegrator, h * unit.picoseconds, composition=chosen)
            else:
                make = partial(AlphaRattleIntegrator, h * unit.picoseconds, alpha=alpha, composition=chosen)
            evaluations = record(
                f"{chosen.name} {'α = 0' if alpha == 0.0 else 'energy mode'}", SubStepped(make)
            )
            if math.isfinite(evaluations):
                divisors.add(math.ceil(evaluations - 1e-9))
    for k in sorted(divisors):
        record(f"RATTLE h/{k}", at_divisor("rattle", h, k))
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(
                {"system": args.system, "timestep_fs": args.timestep, "horizons": horizons, "rows": rows},
                handle,
                indent=1,
            )


if __name__ == "__main__":
    main()
