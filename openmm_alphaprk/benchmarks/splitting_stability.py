"""The largest stable step of RATTLE and the explicit α-family, from one start.

For each integrator (``--integrators``, names of the command line) the runs go from the
system's start for a simulated time T (``--time``, ps) at steps h of a coarse grid
(``--grid``, fs) in increasing order until the first unstable one, then bisect between
the last stable and the first unstable step until they are ``--resolution`` fs apart. A
run is stable (:func:`classify`) when it reaches T with no OpenMM exception, every total
energy read is finite, and max |H − E_ref| per degree of freedom stays at or below
``--threshold-kt`` kT (E_ref the start's total energy, kT at ``--temperature``). H is read
every ``--every`` steps and at the end; a run stops at its first failure. Beside each
integrator: the linear stability limit ωh_max of its splitting on the harmonic
oscillator (:meth:`~openmm_alphaprk.integrators.splittings.Splitting.stability_limit`)
and the largest stable step it predicts from RATTLE's measured one, RATTLE's h times
ωh_max / 2. CPU platform by default. Prints a table; ``--json`` also writes it.

    python -m openmm_alphaprk.benchmarks.splitting_stability --system tip3p-2nm --json out.json
    python -m openmm_alphaprk.benchmarks.splitting_stability --system villin --hydrogen-mass 3 --time 1
"""

from __future__ import annotations

import argparse
import math
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
import openmm as mm

from openmm_alphaprk.integrators.splittings import Splitting, splitting, two_stage
from openmm_alphaprk.observables import BOLTZMANN, degrees_of_freedom, rms, total_energy
from openmm_alphaprk.runs.accuracy import start_context
from openmm_alphaprk.runs.integrator_names import at_divisor, parse_integrator
from openmm_alphaprk.systems import PreparedSystem, load_definition, prepare_system

INTEGRATORS = ("rattle", "split=1/4", "split-me", "split-bcss", "split3-me", "split3-bcss")
GRID = tuple(float(h) for h in (*range(1, 13), 14, 16, 18, 20, 24, 28, 32))
#: Velocity Verlet (RATTLE) as a one-stage splitting: kick(h/2) drift(h) kick(h/2).
VERLET = Splitting("verlet", (0.5, 0.5), (1.0,), 2, "velocity Verlet")


@dataclass
class Verdict:
    """Whether a run is stable, why not, max |H − E_ref| per degree of freedom and RMS(H − E_ref) (kJ/mol)."""

    stable: bool
    reason: str
    max_per_dof: float
    rms_residual: float


def classify(
    residuals: Sequence[float],
    dof: int,
    threshold_per_dof: float,
    *,
    failure: str | None = None,
    steps_done: int | None = None,
    steps_wanted: int | None = None,
) -> Verdict:
    """Return the verdict on a run from its H − E_ref samples: the one rule of the scan.

    Parameters
    ----------
    residuals : sequence of float
        H − E_ref (kJ/mol) at the samples read, in order.
    dof : int
        Degrees of freedom of the System.
    threshold_per_dof : float
        The largest max |H − E_ref| / ``dof`` (kJ/mol) of a stable run.
    failure : str, optional
        Why the run stopped early (an OpenMM exception's message); a run with one is unstable.
    steps_done, steps_wanted : int, optional
        Steps the run took and was to take; a run that stopped short is unstable.

    Returns
    -------
    Verdict
        Stable when there is no failure, the run took every step, it read at least one
        energy, every energy is finite and max |H − E_ref| / dof ≤ ``threshold_per_dof``.

    Examples
    --------
    >>> classify([0.1, -0.2], dof=10, threshold_per_dof=0.25).stable
    True
    >>> classify([0.1, float("nan")], dof=10, threshold_per_dof=0.25).reason
    'non-finite energy at sample 2'
    """
    values = np.asarray(list(residuals), dtype=float)
    finite = values[np.isfinite(values)]
    largest = float(np.abs(finite).max()) / dof if finite.size else math.nan
    spread = rms(finite)
    if failure is not None:
        return Verdict(False, failure, largest, spread)
    if values.size == 0:
        return Verdict(False, "no energy read", largest, spread)
    if finite.size < values.size:
        first = int(np.flatnonzero(~np.isfinite(values))[0]) + 1
        return Verdict(False, f"non-finite energy at sample {first}", largest, spread)
    if steps_done is not None and steps_wanted is not None and steps_done < steps_wanted:
        return Verdict(False, f"stopped at step {steps_done} of {steps_wanted}", largest, spread)
    if not largest <= threshold_per_dof:
        return Verdict(
            False, f"max |H - E_ref|/DOF {largest:.3g} > {threshold_per_dof:.3g} kJ/mol", largest, spread
        )
    return Verdict(True, "stable", largest, spread)


def splitting_of(name: str) -> Splitting:
    """Return the splitting an integrator name of the scan runs (velocity Verlet for ``rattle``)."""
    if name == "rattle":
        return VERLET
    spec = parse_integrator(name)
    if spec.family.word == "split" and spec.splitting is not None:
        return splitting(spec.splitting)
    if spec.family.word == "split" and spec.alpha is not None:
        return two_stage(spec.alpha, name)
    raise ValueError(f"no splitting for integrator {name!r}")


def run_once(
    prepared: PreparedSystem,
    name: str,
    h_fs: float,
    time_ps: float,
    every: int,
    threshold_per_dof: float,
    dof: int,
    platform_name: str,
) -> dict:
    """Run ``name`` at ``h_fs`` from the start for ``time_ps``; return the row of the JSON for it."""
    steps = max(1, math.ceil(time_ps * 1000.0 / h_fs - 1e-9))
    started = time.perf_counter()
    integrator = at_divisor(name, h_fs / 1000.0, 1).make()
    context = start_context(prepared, integrator, platform_name)
    e_ref = total_energy(context)
    residuals: list[float] = []
    failure, done = None, 0
    for step in range(1, steps + 1):
        try:
            integrator.step(1)
        except Exception as error:  # a constraint failure or NaN coordinates: the blow-up
            failure = f"blew up at step {step}: {str(error).splitlines()[0][:80]}"
            break
        done = step
        if step % every == 0 or step == steps:
            try:
                residuals.append(total_energy(context) - e_ref)
            except Exception as error:
                failure = f"blew up at step {step}: {str(error).splitlines()[0][:80]}"
                break
            value = residuals[-1]
            if not math.isfinite(value):
                failure = f"non-finite energy at step {step}"
                break
            if abs(value) / dof > threshold_per_dof:
                failure = f"|H - E_ref|/DOF {abs(value) / dof:.3g} > {threshold_per_dof:.3g} at step {step}"
                break
    verdict = classify(
        residuals, dof, threshold_per_dof, failure=failure, steps_done=done, steps_wanted=steps
    )
    del context, integrator
    return {
        "h_fs": h_fs,
        "steps": steps,
        "steps_done": done,
        **asdict(verdict),
        "seconds": time.perf_counter() - started,
    }


def scan(
    run: Callable[[float], dict], grid: Sequence[float], resolution: float
) -> tuple[list[dict], float | None, float | None]:
    """Scan ``grid`` upward to the first unstable step, then bisect to ``resolution``.

    ``run(h)`` returns a row with ``stable``. Returns the rows in the order run, the largest
    stable step below the first unstable one (None if the smallest is unstable) and the
    smallest unstable step (None if every step of the grid is stable).
    """
    rows, good, bad = [], None, None
    for h in sorted(grid):
        rows.append(run(h))
        if rows[-1]["stable"]:
            good = h
        else:
            bad = h
            break
    if bad is not None and good is not None:
        while bad - good > resolution + 1e-9:
            middle = round(0.5 * (good + bad) / (resolution / 2)) * (resolution / 2)
            if not good < middle < bad:
                break
            rows.append(run(middle))
            if rows[-1]["stable"]:
                good = middle
            else:
                bad = middle
    return rows, good, bad


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument(
        "--hydrogen-mass", type=float, help="hydrogen mass (amu): the definition's repartitioned start"
    )
    parser.add_argument("--integrators", nargs="+", default=list(INTEGRATORS))
    parser.add_argument("--time", type=float, default=2.0, help="simulated time T of each run (ps)")
    parser.add_argument("--grid", type=float, nargs="+", default=list(GRID), help="coarse steps (fs)")
    parser.add_argument("--resolution", type=float, default=0.25, help="bisect to this gap (fs)")
    parser.add_argument("--every", type=int, default=10, help="read H every this many steps")
    parser.add_argument("--threshold-kt", type=float, default=0.1, help="max |H - E_ref|/DOF in kT")
    parser.add_argument("--temperature", type=float, default=300.0, help="K, for kT")
    parser.add_argument("--platform", default="CPU")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    definition = load_definition(args.system)
    if args.hydrogen_mass is not None:
        definition = definition.with_hydrogen_mass(args.hydrogen_mass)
    prepared = prepare_system(definition)
    dof = degrees_of_freedom(prepared.system)
    threshold = args.threshold_kt * BOLTZMANN * args.temperature
    print(
        f"{definition.name}: {prepared.system.getNumParticles()} particles, {dof} DOF, T = {args.time} ps, "
        f"threshold {threshold:.4g} kJ/mol/DOF, start {prepared.source}",
        flush=True,
    )
    results = []
    for name in args.integrators:
        chosen = splitting_of(name)

        def run(h: float, name: str = name) -> dict:
            row = run_once(prepared, name, h, args.time, args.every, threshold, dof, args.platform)
            print(
                f"  {name:12} h {h:6.3f} fs  {'stable  ' if row['stable'] else 'UNSTABLE'}  "
                f"max|dH|/DOF {row['max_per_dof']:.3g}  RMS {row['rms_residual']:.3g}  "
                f"{row['seconds']:.0f} s  {'' if row['stable'] else row['reason']}",
                flush=True,
            )
            return row

        runs, good, bad = scan(run, args.grid, args.resolution)
        results.append(
            {
                "integrator": name,
                "splitting": chosen.name,
                "evaluations": chosen.stages,
                "linear_limit": chosen.stability_limit(),
                "largest_stable_fs": good,
                "smallest_unstable_fs": bad,
                "runs": sorted(runs, key=lambda r: r["h_fs"]),
            }
        )
    rattle = next((r["largest_stable_fs"] for r in results if r["integrator"] == "rattle"), None)
    print(f"\n{definition.name}, T = {args.time} ps, largest stable h (fs); predicted: RATTLE's h x ωh_max/2")
    heads = ("integrator", "evals", "stable h", "unstable", "h/evals", "ωh_max", "predicted")
    print(f"{heads[0]:12} " + " ".join(f"{head:>9}" for head in heads[1:]))
    for entry in results:
        good, k = entry["largest_stable_fs"], entry["evaluations"]
        predicted = rattle * entry["linear_limit"] / 2.0 if rattle is not None else None
        entry["predicted_fs"] = predicted
        entry["ratio_to_rattle"] = good / rattle if good is not None and rattle else None
        print(
            f"{entry['integrator']:12} {k:9d} {_fs(good):>9} {_fs(entry['smallest_unstable_fs']):>9} "
            f"{_fs(good / k if good is not None else None):>9} {entry['linear_limit']:9.4f} "
            f"{_fs(predicted):>9}"
        )
    document = {
        "system": definition.name,
        "particles": prepared.system.getNumParticles(),
        "dof": dof,
        "start": prepared.source,
        "time_ps": args.time,
        "every": args.every,
        "threshold_kt": args.threshold_kt,
        "temperature_k": args.temperature,
        "threshold_kj_per_mol_per_dof": threshold,
        "resolution_fs": args.resolution,
        "grid_fs": sorted(args.grid),
        "platform": args.platform,
        "openmm": mm.__version__,
        "python": platform.python_version(),
        "rule": "stable: T reached, no exception, every H read finite, max|H - E_ref|/DOF <= threshold",
        "integrators": results,
    }
    if args.json:
        import json

        with open(args.json, "w") as handle:
            json.dump(document, handle, indent=1)
    return document


def _fs(value: float | None) -> str:
    return "-" if value is None else f"{value:.3g}"


if __name__ == "__main__":
    main()
