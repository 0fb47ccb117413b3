"""Energy benchmark: the energy-preserving mode against RATTLE from the same start.

Every integrator runs NVE from the same equilibrated TIP3P state, on the same
platform and step, in the same process. After every step the total energy is read
from the context (``State`` potential + kinetic energy, on-step velocities) and
compared with the starting energy E_ref. Reported per integrator: drift (linear fit,
kJ/mol/ns per degree of freedom), RMS and max of H − E_ref, for the energy mode the
α* percentiles and the fractions of steps within tolerance / fallen back / at a
bound, force evaluations per step, and ms/step as a ratio to RATTLE from separate,
interleaved timing rounds without energy read-out.

Run ``python -m openmm_alphaprk.energy_benchmark --help`` for the options.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
import openmm as mm
import openmm.unit as unit
from tqdm import tqdm

from .integrators import AlphaRattleIntegrator, RattleIntegrator
from .waterbox import WaterBox, build_water_box


@dataclass
class EnergyRow:
    """One integrator's measurements (energies in kJ/mol)."""

    name: str
    steps: int
    drift_per_dof: float  # kJ/mol/ns per degree of freedom, linear fit
    rms_residual: float
    max_abs_residual: float
    force_evaluations_per_step: float
    ms_per_step: float = float("nan")
    time_ratio: float = float("nan")
    alpha_percentiles: dict[str, float] = field(default_factory=dict)
    fraction_within_tolerance: float = float("nan")
    fraction_fallen_back: float = float("nan")
    fraction_at_bound: float = float("nan")
    blew_up_at_step: int | None = None


def default_integrators(timestep: float) -> dict[str, Callable[[], mm.Integrator]]:
    """RATTLE (the baseline), the energy mode, and the energy mode with tight α bounds."""
    return {
        "RATTLE": lambda: RattleIntegrator(timestep),
        "energy [-1,3]": lambda: AlphaRattleIntegrator(timestep, alpha="energy"),
        "energy [0,1]": lambda: AlphaRattleIntegrator(timestep, alpha="energy", alpha_bounds=(0.0, 1.0)),
    }


def degrees_of_freedom(system: mm.System) -> int:
    """3 N − constraints − 3 if the system removes centre-of-mass motion (massive particles only)."""
    massive = sum(
        system.getParticleMass(i).value_in_unit(unit.dalton) > 0 for i in range(system.getNumParticles())
    )
    removes_cm = any(isinstance(system.getForce(i), mm.CMMotionRemover) for i in range(system.getNumForces()))
    return 3 * massive - system.getNumConstraints() - (3 if removes_cm else 0)


def drift_per_dof(times_ps: np.ndarray, residuals: np.ndarray, dof: int) -> float:
    """Slope of a least-squares line through H(t), in kJ/mol/ns per degree of freedom."""
    slope_per_ps = np.polyfit(times_ps, residuals, 1)[0]
    return float(slope_per_ps * 1000.0 / dof)


def _context(box: WaterBox, integrator: mm.Integrator, platform: mm.Platform) -> mm.Context:
    context = mm.Context(box.system, integrator, platform)
    context.setPositions(box.positions)
    context.setVelocities(box.velocities)
    return context


def _total_energy(context: mm.Context) -> float:
    state = context.getState(getEnergy=True)
    return (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(unit.kilojoules_per_mole)


def run_energy_benchmark(
    box: WaterBox,
    integrators: dict[str, Callable[[], mm.Integrator]],
    *,
    platform: str = "CPU",
    steps: int = 10_000,
    timing_steps: int = 100,
    timing_rounds: int = 3,
    progress: bool = True,
) -> tuple[list[EnergyRow], dict[str, np.ndarray]]:
    """Run each integrator for ``steps`` steps from the same state; time them after.

    Returns
    -------
    rows
        One :class:`EnergyRow` per integrator, in order; the first is the baseline
        of the time ratios.
    residuals
        H − E_ref after every step, by integrator name (for plots).
    """
    plat = mm.Platform.getPlatformByName(platform)
    dof = degrees_of_freedom(box.system)
    timestep_ps = None
    rows, traces, runs = [], {}, {}
    for name, make in integrators.items():
        integrator = make()
        context = _context(box, integrator, plat)
        timestep_ps = integrator.getStepSize().value_in_unit(unit.picoseconds)
        e_ref = _total_energy(context)
        residuals = np.full(steps, np.nan)
        alphas = np.full(steps, np.nan)
        blew_up = None
        energy_mode = getattr(integrator, "energy_mode", False)
        for i in tqdm(range(steps), desc=name, disable=not progress, mininterval=2.0, file=sys.stderr):
            try:
                integrator.step(1)
            except Exception:  # a failed step is the blow-up we report, not a crash of the benchmark
                blew_up = i
                break
            residuals[i] = _total_energy(context) - e_ref
            if energy_mode:
                alphas[i] = integrator.alpha
            if not np.isfinite(residuals[i]) or abs(residuals[i]) > 1e6:
                blew_up = i
                break
        done = np.isfinite(residuals)
        times = (np.arange(steps) + 1) * timestep_ps
        row = EnergyRow(
            name=name,
            steps=int(done.sum()),
            drift_per_dof=drift_per_dof(times[done], residuals[done], dof),
            rms_residual=float(np.sqrt(np.mean(residuals[done] ** 2))),
            max_abs_residual=float(np.max(np.abs(residuals[done]))),
            force_evaluations_per_step=integrator.force_evaluations_per_step,
            blew_up_at_step=blew_up,
        )
        if energy_mode:
            totals = integrator.controller_totals()
            row.alpha_percentiles = {
                f"p{p}": float(v)
                for p, v in zip(
                    (1, 5, 25, 50, 75, 95, 99), np.nanpercentile(alphas, (1, 5, 25, 50, 75, 95, 99))
                )
            }
            row.fraction_within_tolerance = totals["fraction_within_tolerance"]
            row.fraction_fallen_back = totals["fraction_fallen_back"]
            row.fraction_at_bound = totals["steps_at_bound"] / totals["steps"]
        rows.append(row)
        traces[name] = residuals
        runs[name] = integrator, context
    times_ms: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(timing_rounds):
        for name, (integrator, _) in runs.items():
            if rows[list(runs).index(name)].blew_up_at_step is not None:
                continue
            start = time.perf_counter()
            integrator.step(timing_steps)
            times_ms[name].append((time.perf_counter() - start) / timing_steps * 1e3)
    baseline = statistics.median(times_ms[rows[0].name]) if times_ms[rows[0].name] else float("nan")
    for row in rows:
        if times_ms[row.name]:
            row.ms_per_step = statistics.median(times_ms[row.name])
            row.time_ratio = row.ms_per_step / baseline
    return rows, traces


def format_table(rows: Sequence[EnergyRow], header: str = "") -> str:
    """Format the rows as a plain-text table."""
    lines = [header] if header else []
    lines.append(
        f"{'integrator':<16} {'steps':>6} {'drift/dof':>10} {'RMS(H-Eref)':>11} {'max|H-Eref|':>11} "
        f"{'evals/step':>10} {'time ratio':>10} {'within tol':>10} {'fell back':>9} {'at bound':>8}  "
        "alpha* p5/p50/p95"
    )
    for row in rows:
        alpha = (
            "/".join(f"{row.alpha_percentiles[k]:.2f}" for k in ("p5", "p50", "p95"))
            if row.alpha_percentiles
            else "-"
        )
        lines.append(
            f"{row.name:<16} {row.steps:>6} {row.drift_per_dof:>10.2e} {row.rms_residual:>11.4f} "
            f"{row.max_abs_residual:>11.4f} {row.force_evaluations_per_step:>10.2f} {row.time_ratio:>10.2f} "
            f"{row.fraction_within_tolerance:>10.3f} {row.fraction_fallen_back:>9.3f} "
            f"{row.fraction_at_bound:>8.3f}  "
            f"{alpha}"
            + (f"  BLEW UP at step {row.blew_up_at_step}" if row.blew_up_at_step is not None else "")
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(
        prog="python -m openmm_alphaprk.energy_benchmark",
        description=(
            "Energy drift and fluctuation of α-RATTLE's energy mode against RATTLE (TIP3P box, PME, NVE)."
        ),
    )
    parser.add_argument(
        "--box", type=float, default=3.0, help="cubic box edge in nm (default 3.0: ~2,600 atoms)"
    )
    parser.add_argument(
        "--cutoff", type=float, default=0.9, help="PME direct-space cutoff in nm (default 0.9)"
    )
    parser.add_argument("--timestep", type=float, default=2.0, help="step size in fs (default 2)")
    parser.add_argument("--platform", default="CPU", help="OpenMM platform (default CPU)")
    parser.add_argument(
        "--time", type=float, default=20.0, help="simulated time per integrator in ps (default 20)"
    )
    parser.add_argument(
        "--only",
        nargs="*",
        default=None,
        help="run only these integrators (names as in the table; RATTLE always)",
    )
    parser.add_argument(
        "--equilibration-steps", type=int, default=1000, help="2 fs Langevin steps first (default 1000)"
    )
    parser.add_argument(
        "--seed", type=int, default=2024, help="random seed of the equilibration (default 2024)"
    )
    parser.add_argument("--json", help="also write the rows to this JSON file")
    parser.add_argument(
        "--traces", help="also write H - E_ref per step of every integrator to this .npz file"
    )
    args = parser.parse_args(argv)
    if min(args.box, args.timestep, args.time) <= 0:
        parser.error("--box, --timestep and --time must be positive")
    timestep = args.timestep / 1000.0
    integrators = default_integrators(timestep)
    if args.only:
        unknown = set(args.only) - set(integrators)
        if unknown:
            parser.error(f"unknown integrator(s) {sorted(unknown)}; choose from {list(integrators)}")
        integrators = {k: v for k, v in integrators.items() if k == "RATTLE" or k in args.only}
    print(f"building a {args.box} nm TIP3P box ...", file=sys.stderr, flush=True)
    box = build_water_box(
        args.box,
        cutoff=args.cutoff,
        equilibration_steps=args.equilibration_steps,
        seed=args.seed,
        platform=args.platform,
    )
    steps = int(round(args.time / args.timestep * 1000.0))
    rows, traces = run_energy_benchmark(box, integrators, platform=args.platform, steps=steps)
    header = (
        f"TIP3P box {args.box} nm, {box.n_atoms} atoms, {degrees_of_freedom(box.system)} DOF, PME cutoff "
        f"{args.cutoff} nm, {args.timestep} fs, {args.time} ps NVE, platform {args.platform}; drift in "
        "kJ/mol/ns per DOF (linear fit); energies in kJ/mol; time ratio against RATTLE (median of 3 x 100 "
        "timed steps)"
    )
    print(format_table(rows, header))
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"header": header, "rows": [asdict(row) for row in rows]}, handle, indent=2)
    if args.traces:
        np.savez_compressed(args.traces, timestep_ps=timestep, **traces)
    return 0


if __name__ == "__main__":
    sys.exit(main())
