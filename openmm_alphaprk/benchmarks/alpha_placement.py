"""Where α goes on a composition: the energy mode and a fixed α with α on each stage, from one start.

For each placement: RMS(H − E_ref), force evaluations per step, the median |α*| (energy
mode) and the RMS position error per atom against RATTLE at h/64 after 5 / 20 / 50 steps
(``--horizons``).
Prints a table; ``--json`` also writes it. Used for docs/compositions.md.

    python -m openmm_alphaprk.benchmarks.alpha_placement --system tip3p-2nm --timestep 2
"""

from __future__ import annotations

import argparse
import json
from functools import partial

import openmm.unit as unit

from openmm_alphaprk import AlphaRattleEnergyIntegrator, AlphaRattleIntegrator
from openmm_alphaprk.observables import rms
from openmm_alphaprk.runs.accuracy import horizon_errors, periodic_box, reference, run_trajectory
from openmm_alphaprk.runs.integrator_names import SubStepped
from openmm_alphaprk.systems import prepare_system


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument("--timestep", type=float, default=2.0, help="fs")
    parser.add_argument("--composition", default="suzuki5")
    parser.add_argument("--fixed-alpha", type=float, default=0.02)
    parser.add_argument("--horizons", type=int, nargs="+", default=[5, 20, 50], help="steps of h")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    prepared = prepare_system(args.system)
    h = args.timestep / 1000.0
    horizons = sorted(args.horizons)
    box = periodic_box(prepared)
    ref = run_trajectory(prepared, reference(h), horizons, read_energy=False)
    from openmm_alphaprk.integrators.compositions import composition

    chosen = composition(args.composition)
    placements = [(k,) for k in range(1, (chosen.stages + 1) // 2 + 1)] + ["all"]
    rows = []
    for alpha in ("energy", 0.0, args.fixed_alpha):
        for stages in placements if alpha != 0.0 else ["middle"]:
            if alpha == "energy" and stages == "all":
                continue
            settings = {"composition": chosen, "alpha_stages": stages, "max_midpoint_iterations": 100}
            if alpha == "energy":
                make = partial(AlphaRattleEnergyIntegrator, h * unit.picoseconds, **settings)
            else:
                make = partial(AlphaRattleIntegrator, h * unit.picoseconds, alpha=alpha, **settings)
            run = run_trajectory(prepared, SubStepped(make), horizons)
            errors = horizon_errors(run, ref, box, args.timestep)
            integrator = run.integrator
            row = {
                "alpha": alpha,
                "stages": stages if isinstance(stages, str) else list(stages),
                "evaluations": run.force_evaluations_per_step,
                "rms_residual": rms(run.residuals),
                "position_rms": [e.position_rms for e in errors],
            }
            if alpha == "energy":
                row["alpha_bounds"] = integrator.alpha_bounds
                row["final_alpha"] = integrator.alpha
                row["fraction_fallen_back"] = integrator.controller_totals()["fraction_fallen_back"]
            rows.append(row)
            print(
                f"alpha={alpha!s:7} stages={row['stages']!s:16} evals {row['evaluations']:5.2f} "
                f"RMS {row['rms_residual']:.3g}  x err "
                + " / ".join(f"{e:.2g}" for e in row["position_rms"])
                + (f"  fell back {row['fraction_fallen_back']:.2f}" if alpha == "energy" else ""),
                flush=True,
            )
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(
                {"system": args.system, "timestep_fs": args.timestep, "horizons": horizons, "rows": rows},
                handle,
                indent=1,
            )


if __name__ == "__main__":
    main()
