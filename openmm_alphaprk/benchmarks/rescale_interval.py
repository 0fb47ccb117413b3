"""RATTLE + rescaling every N-th step (``rattle+rescale@N``): its step time and its energy, beside RATTLE.

Research script behind docs/integrators.md ("Rescaling every N-th step") and
docs/data/platforms/rescale_interval_cpu.json. In one run, on one platform:

- the step time of ``rattle+rescale@N`` for each N against RATTLE's, on each box
  (:func:`openmm_alphaprk.benchmarks.cost.run_benchmark`: interleaved rounds, median);
- over ``--ps`` of the first box, from its shipped state, with the energy read after
  every step: RMS(H − E_ref) and the linear-fit drift per ns per degree of freedom
  (:func:`openmm_alphaprk.observables.energy_drift`) over every step and over the
  rescaling steps alone (every N-th), and the largest |H − E_ref|.

Usage: ``python -m openmm_alphaprk.benchmarks.rescale_interval --out
docs/data/platforms/rescale_interval_cpu.json``
(defaults: CPU platform, tip3p-2nm and tip3p-3nm, N = 1, 10, 100, 5 rounds x 300 steps, 20 ps),
then ``... --cpu-time-only --out <the same file>`` adds the step costs as single-thread CPU
time (:func:`single_thread_cpu_times`), which a shared machine's load disturbs far less.
"""

from __future__ import annotations

import argparse
import json
import platform as host
import time

import numpy as np
import openmm as mm

from openmm_alphaprk.benchmarks.cost import cost_benchmark_integrators, run_benchmark
from openmm_alphaprk.observables import degrees_of_freedom, energy_drift, total_energy
from openmm_alphaprk.runs.integrator_names import label, make_integrator
from openmm_alphaprk.systems import prepare_system

TIMESTEP_PS = 0.002


def _names(intervals: list[int]) -> list[str]:
    return ["rattle", *(f"rattle+rescale@{n}" if n > 1 else "rattle+rescale" for n in intervals)]


def step_times(box_name: str, intervals: list[int], platform: str, rounds: int, steps: int) -> dict:
    """Median ms/step of RATTLE and each ``rattle+rescale@N``, with the ratio to RATTLE's."""
    box = prepare_system(box_name)
    rows = run_benchmark(
        box,
        cost_benchmark_integrators(TIMESTEP_PS, _names(intervals)),
        platform=platform,
        steps=steps,
        rounds=rounds,
        energy_steps=20,
        progress=False,
    )
    return {
        "atoms": box.system.getNumParticles(),
        "rows": [
            {
                "name": row.name,
                "ms_per_step": row.ms_per_step,
                "ratio_to_rattle": row.time_ratio,
                "host_syncs_per_step": row.host_syncs_per_step,
            }
            for row in rows
        ],
    }


def single_thread_cpu_times(box_name: str, intervals: list[int], rounds: int, steps: int) -> dict:
    """Median CPU time per step (``time.process_time``, CPU platform with one thread), interleaved rounds.

    Process time of one thread is what the step costs, not what the other processes on a
    shared machine leave of the cores: the wall-clock rows of :func:`step_times` vary with
    the load, these far less.
    """
    box = prepare_system(box_name)
    platform = mm.Platform.getPlatformByName("CPU")
    runs = {}
    for name in _names(intervals):
        integrator = make_integrator(name, TIMESTEP_PS)
        context = mm.Context(box.system, integrator, platform, {"Threads": "1"})
        context.setState(box.state)
        if hasattr(integrator, "check_context"):
            integrator.check_context(context)
        integrator.step(5)
        runs[name] = (integrator, context, [])
    for _ in range(rounds):
        for integrator, _context, times in runs.values():
            start = time.process_time()
            integrator.step(steps)
            times.append((time.process_time() - start) / steps * 1e3)
    baseline = float(np.median(runs["rattle"][2]))
    return {
        "rows": [
            {
                "name": label(name),
                "cpu_ms_per_step": float(np.median(times)),
                "ratio_to_rattle": float(np.median(times)) / baseline,
            }
            for name, (_integrator, _context, times) in runs.items()
        ]
    }


def energy_trace(box_name: str, name: str, platform: str, picoseconds: float) -> dict:
    """H − E_ref after every step over ``picoseconds`` from the box's shipped state."""
    box = prepare_system(box_name)
    integrator = make_integrator(name, TIMESTEP_PS)
    context = mm.Context(box.system, integrator, mm.Platform.getPlatformByName(platform))
    context.setState(box.state)
    if hasattr(integrator, "check_context"):
        integrator.check_context(context)
    steps = round(picoseconds / TIMESTEP_PS)
    totals = np.empty(steps + 1)
    totals[0] = total_energy(context)
    start = time.perf_counter()
    for i in range(1, steps + 1):
        integrator.step(1)
        totals[i] = total_energy(context)
    wall = time.perf_counter() - start
    times = np.arange(steps + 1) * TIMESTEP_PS
    dof = degrees_of_freedom(box.system)
    every = energy_drift(times, totals, dof)
    interval = getattr(integrator, "rescale_interval", 1)
    at_rescaling = energy_drift(times[::interval], totals[::interval], dof)
    return {
        "name": name,
        "label": label(name),
        "steps": steps,
        "degrees_of_freedom": dof,
        "e_ref": float(totals[0]),
        "rms_residual": every.rms_residual,
        "max_abs_residual": every.max_abs_residual,
        "drift_kj_per_mol_per_ns": every.drift_kj_per_mol_per_ns,
        "drift_per_dof": every.drift_per_dof,
        "drift_per_dof_standard_error": every.drift_per_dof_standard_error,
        "at_rescaling_steps": {
            "samples": at_rescaling.samples,
            "rms_residual": at_rescaling.rms_residual,
            "max_abs_residual": at_rescaling.max_abs_residual,
            "drift_per_dof": at_rescaling.drift_per_dof,
        },
        "wall_s_with_energy_reads": wall,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--platform", default="CPU")
    parser.add_argument("--boxes", nargs="+", default=["tip3p-2nm", "tip3p-3nm"])
    parser.add_argument("--intervals", nargs="+", type=int, default=[1, 10, 100])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--ps", type=float, default=20.0)
    parser.add_argument("--skip-energy", action="store_true")
    parser.add_argument("--skip-cost", action="store_true", help="no wall-clock step times")
    parser.add_argument(
        "--cpu-time-only",
        action="store_true",
        help="add single-thread CPU times per step to the JSON in --out (which must exist)",
    )
    parser.add_argument("--note", help="a sentence kept in the JSON (e.g. what else ran on the machine)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    if args.cpu_time_only:
        with open(args.out) as handle:
            result = json.load(handle)
        result["single_thread_cpu_time"] = {
            box_name: single_thread_cpu_times(box_name, args.intervals, args.rounds, args.steps)
            for box_name in args.boxes
        }
        result["rounds_single_thread_cpu_time"] = args.rounds
        result["steps_per_round_single_thread_cpu_time"] = args.steps
        if args.note:
            result["note"] = args.note
        for box_name, rows in result["single_thread_cpu_time"].items():
            print(box_name, json.dumps(rows), flush=True)
        with open(args.out, "w") as handle:
            json.dump(result, handle, indent=1)
            handle.write("\n")
        return 0
    result = {
        "platform": args.platform,
        "openmm": mm.Platform.getOpenMMVersion(),
        "machine": host.node(),
        "timestep_ps": TIMESTEP_PS,
        "rounds": args.rounds,
        "steps_per_round": args.steps,
        "step_time": {},
        "energy": {},
    }
    if args.note:
        result["note"] = args.note
    for box_name in [] if args.skip_cost else args.boxes:
        result["step_time"][box_name] = step_times(
            box_name, args.intervals, args.platform, args.rounds, args.steps
        )
        print(json.dumps(result["step_time"][box_name]), flush=True)
    if not args.skip_energy:
        box_name = args.boxes[0]
        result["energy"] = {
            "box": box_name,
            "picoseconds": args.ps,
            "runs": [energy_trace(box_name, name, args.platform, args.ps) for name in _names(args.intervals)],
        }
        for run in result["energy"]["runs"]:
            print(json.dumps(run), flush=True)
    with open(args.out, "w") as handle:
        json.dump(result, handle, indent=1)
        handle.write("\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
