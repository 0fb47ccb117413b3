"""The OpenMM runs of the validation: α* on the 774-atom box and the long runs on the water cluster.

Both go through the driver (``run_nve``) with its default settings; the long runs
record their invariants with :class:`~.reporter.InvariantReporter`.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from openmm_alphaprk import observables

from .reporter import InvariantReporter, long_run_entry, series

#: Runs on ``tip3p-2nm``: name in the JSON, integrator, substeps per 2 fs. The last two cost
#: what the energy modes cost (6 force evaluations per 2 fs), at a smaller step.
BOX_RUNS = (
    ("rattle", "rattle", 1),
    ("alpha4=0", "alpha4=0", 1),
    ("energy", "energy", 1),
    ("energy4", "energy4", 1),
    ("rattle, h = 1/3 fs", "rattle", 6),
    ("alpha4=0, h = 1 fs", "alpha4=0", 2),
)
#: The integrators of the long runs through the driver.
LONG_RUN_INTEGRATORS = ("rattle", "alpha=1/6", "energy", "energy4")


def _box_run(workdir: Path, key: str, name: str, substeps: int, steps: int) -> dict:
    """Run one integrator of :data:`BOX_RUNS` on ``tip3p-2nm``; return its entry."""
    from openmm_alphaprk.runs import read_controller_csv, run_nve

    outdir = workdir / f"tip3p-2nm-{key.replace('/', '_').replace(' ', '').replace(',', '_')}"
    summary = run_nve(
        "tip3p-2nm",
        name,
        outdir,
        steps=steps * substeps,
        timestep=0.002 / substeps,
        platform="CPU",
        energy_interval=10 * substeps,
        trajectory_interval=steps * substeps,
        checkpoint_interval=steps * substeps,
        controller_interval=1,  # α* of every step
        progress=False,
    )
    entry = {
        "integrator": name,
        "timestep_fs": 2.0 / substeps,
        "steps": steps * substeps,
        "n_atoms": summary.n_atoms,
        "rms_residual": summary.rms_residual,
        "max_abs_residual": summary.max_abs_residual,
        "force_evaluations_per_step": summary.force_evaluations_per_step,
        "force_evaluations_per_2fs": summary.force_evaluations_per_step * substeps,
        "wall_seconds": summary.wall_seconds,
    }
    if name.startswith("energy"):
        alphas = read_controller_csv(outdir / "controller.csv")[:, 2]
        entry["alpha"] = series(alphas)
        entry["alpha_percentiles"] = observables.alpha_percentiles(alphas)
        entry["median_abs_alpha"] = float(np.median(np.abs(alphas)))
        entry["max_abs_alpha"] = float(np.max(np.abs(alphas)))
        entry["controller"] = summary.controller
    return entry


def openmm_alpha_star(workdir: Path, steps: int) -> dict:
    """Run the energy modes on ``tip3p-2nm`` (CPU, 2 fs): α* from controller.csv, H − E_ref of every run.

    Every run covers ``steps`` × 2 fs and records H every 20 fs; RATTLE and the triple
    jump also run at the energy modes' cost (6 force evaluations per 2 fs).
    """
    result: dict = {
        "system": "tip3p-2nm",
        "platform": "CPU",
        "simulated_ps": steps * 0.002,
        "energy_sampling_fs": 20.0,
        "runs": {},
    }
    for key, name, substeps in BOX_RUNS:
        result["runs"][key] = _box_run(workdir, key, name, substeps, steps)
    return result


def _driver_run(prepared, workdir: Path, platform_name: str, name: str, n_steps: int, interval: int) -> dict:
    """Run ``name`` on the water cluster through the driver with an :class:`InvariantReporter`."""
    from openmm_alphaprk.runs import run_nve

    reporter = InvariantReporter(prepared.system, prepared.state, interval)
    outdir = workdir / f"cluster-{platform_name}-{name.replace('/', '_')}"
    summary = run_nve(
        prepared,
        name,
        outdir,
        steps=n_steps,
        timestep=0.002,
        platform=platform_name,
        energy_interval=interval,
        trajectory_interval=n_steps,
        checkpoint_interval=n_steps,
        progress=False,
        extra_reporters=[reporter],
    )
    return long_run_entry(
        reporter,
        summary.e_ref,
        0.002,
        {
            "steps": n_steps,
            "force_evaluations_per_step": summary.force_evaluations_per_step,
            "wall_seconds": summary.wall_seconds,
            "drift_per_dof_kj_mol_ns": summary.drift_per_dof,
            "summary_momentum_change": summary.momentum_change,
        },
    )


def _tight_midpoint_run(prepared, n_steps: int, interval: int) -> dict:
    """Run the order-2 energy mode directly on Reference, the midpoint iterated to 1e-12 nm."""
    import openmm as mm
    import openmm.app as app

    from openmm_alphaprk import AlphaRattleEnergyIntegrator

    integrator = AlphaRattleEnergyIntegrator(0.002, constraint_tolerance=1e-8, midpoint_tolerance=1e-12)
    simulation = app.Simulation(
        prepared.topology, prepared.system, integrator, mm.Platform.getPlatformByName("Reference")
    )
    integrator.check_context(simulation.context)  # the tolerance for double precision
    simulation.context.setState(prepared.state)
    reporter = InvariantReporter(prepared.system, prepared.state, interval)
    simulation.reporters.append(reporter)
    e_ref = observables.total_energy(simulation.context)
    started = time.perf_counter()
    simulation.step(n_steps)
    return long_run_entry(
        reporter,
        e_ref,
        0.002,
        {
            "steps": n_steps,
            "force_evaluations_per_step": integrator.force_evaluations_per_step,
            "wall_seconds": time.perf_counter() - started,
        },
    )


def long_runs(workdir: Path, steps: dict[str, int], interval: int) -> dict:
    """Run rattle, alpha=1/6, energy and energy4 on ``water-cluster`` (driver; Reference and CPU).

    A fifth run (Reference) drives the order-2 energy mode directly with the midpoint
    iterated to 1e-12 nm instead of its default 1e-7 nm.
    """
    from openmm_alphaprk.systems import prepare_system

    prepared = prepare_system("water-cluster")
    result: dict = {
        "system": "water-cluster",
        "n_atoms": prepared.n_atoms,
        "timestep_fs": 2.0,
        "constraint_tolerance": 1e-8,
        "report_interval": interval,
        "platforms": {},
    }
    for platform_name, n_steps in steps.items():
        runs = {
            name: _driver_run(prepared, workdir, platform_name, name, n_steps, interval)
            for name in LONG_RUN_INTEGRATORS
        }
        result["platforms"][platform_name] = {"steps": n_steps, "runs": runs}
    result["platforms"]["Reference"]["runs"]["energy, midpoint 1e-12 nm"] = _tight_midpoint_run(
        prepared, steps["Reference"], interval
    )
    return result
