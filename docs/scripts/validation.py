r"""Numerical validation of the α-RATTLE family: every number and figure of docs/validation.md.

Run from the repository root::

    python docs/scripts/validation.py            # the full page (about 10 minutes on 2 cores)
    python docs/scripts/validation.py --quick    # smaller runs, to check the script (about 1 minute)

It computes

1. convergence orders on the plain pendulum (error after one exact period), on the
   pendulum with a spring and on a cluster of three rigid waters (error at a fixed
   time against a fine-step reference), with the NumPy reference;
2. symplecticity defects of fixed α, the energy modes and the one-pass variant;
3. α* against h for both energy modes (NumPy reference), and α* distributions of
   the OpenMM energy modes on the 774-atom ``tip3p-2nm`` box;
4. long OpenMM runs on the 222-atom ``water-cluster`` (Reference and CPU platforms):
   angular and linear momentum, constraints and H − E_ref against time.

It writes ``docs/validation.json`` (all numbers), ``docs/figures/validation_*.png``,
rewrites the generated tables of ``docs/validation.md`` (between ``<!-- table: NAME -->``
and ``<!-- end table -->``; the prose is left alone) and prints the tables. OpenMM
runs use one CPU thread. ``--quick`` writes to a scratch directory unless paths
are given, so that it never overwrites the page's numbers.
"""

from __future__ import annotations

import argparse
import json
import platform as python_platform
import re
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from openmm_alphaprk import observables
from openmm_alphaprk.reference import (
    alpha_rattle4_step,
    alpha_rattle_step,
    energy_preserving_step,
    integrate,
    planar_pendulum,
    planar_pendulum_period,
    planar_pendulum_start,
    symplecticity_defect,
    water_cluster,
)
from openmm_alphaprk.reference.step import Array, ConstrainedProblem

DOCS = Path(__file__).resolve().parents[1]
COMMAND = "python docs/scripts/validation.py"
#: α of the fixed-α study (issue 6).
ALPHAS = (0.0, 1 / 6, 1 / 3, 1 / 2, 1.0)
#: Bounds of the reference energy mode's exact (Brent) root search, design doc §4.
REFERENCE_BOUNDS = (-1.0, 3.0)
#: The reference's default midpoint tolerance (1e-15) can be below what the fixed-point
#: iteration reaches when SHAKE converges to 1e-14 (seen at α = 3 on the pendulum); the
#: energy modes' trials use this one.
ENERGY_MIDPOINT_TOLERANCE = 1e-14
#: Symplecticity defects below this are the finite-difference floor of the test (ε = 1e-6 and the
#: solver tolerances, accumulated over the steps); slopes are fitted above it.
FD_FLOOR = 1e-7


# ----------------------------------------------------------------------- methods
@dataclass(frozen=True)
class Method:
    """One integrator of the study: a fixed α, or an energy mode (α* per step).

    Parameters
    ----------
    key
        Name in the JSON (``alpha=1/6``, ``energy``, ``alpha4=0``, ``energy4``, ...).
    label
        Name in tables and figures.
    order
        2 (α-RATTLE) or 4 (α-RATTLE-4).
    alpha
        The fixed α, or None for the energy mode.
    one_pass
        Take the midpoint force at the RATTLE-predicted midpoint only (not symplectic).
    """

    key: str
    label: str
    order: int
    alpha: float | None
    one_pass: bool = False

    @property
    def step(self) -> Callable[..., tuple[Array, Array, Array]]:
        return alpha_rattle_step if self.order == 2 else alpha_rattle4_step

    @property
    def energy_mode(self) -> bool:
        return self.alpha is None


def _fraction(alpha: float) -> str:
    return str(Fraction(alpha).limit_denominator(12))


def fixed(alpha: float, order: int = 2, one_pass: bool = False) -> Method:
    """Return a fixed-α method (``alpha=1/6``, ``alpha4=0.3``, ``one-pass alpha=1``)."""
    text = _fraction(alpha)
    key = f"alpha{'4' if order == 4 else ''}={text}"
    if order == 2:
        label = "RATTLE (α = 0)" if alpha == 0 else f"α = {text}"
    else:
        label = f"α-RATTLE-4, α = {text}"
    if one_pass:
        key, label = f"one-pass {key}", f"{label}, one pass"
    return Method(key, label, order, alpha, one_pass)


ENERGY = Method("energy", "energy mode (order 2)", 2, None)
ENERGY4 = Method("energy4", "energy mode, α-RATTLE-4", 4, None)
CONVERGENCE_METHODS = (*(fixed(a) for a in ALPHAS), ENERGY, fixed(0.0, 4), fixed(0.3, 4), ENERGY4)


def run_method(
    method: Method, problem: ConstrainedProblem, x0: Array, v0: Array, h: float, n_steps: int
) -> tuple[Array, Array, Array | None, Array]:
    """``n_steps`` steps of ``method``.

    Returns
    -------
    x, v
        The final state.
    alphas
        α* of every step (energy modes), else None.
    energies
        H after every step, shape (n_steps,).
    """
    x, v = np.array(x0, dtype=float), np.array(v0, dtype=float)
    e_ref = problem.energy(x, v)
    f = problem.force(x)
    alphas = np.empty(n_steps) if method.energy_mode else None
    energies = np.empty(n_steps)
    for i in range(n_steps):
        if method.energy_mode:
            x, v, f, alphas[i] = energy_preserving_step(
                method.step,
                problem,
                x,
                v,
                h,
                e_ref,
                f0=f,
                bounds=REFERENCE_BOUNDS,
                midpoint_tolerance=ENERGY_MIDPOINT_TOLERANCE,
            )
        else:
            x, v, f = method.step(problem, x, v, h, method.alpha, f0=f, one_pass=method.one_pass)
        energies[i] = problem.energy(x, v)
    return x, v, alphas, energies


def fitted_order(hs: Array, errors: Array) -> float:
    """Least-squares slope of log(error) against log(h)."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


def local_orders(errors: Array) -> list[float]:
    """log2 of the error ratio per halving of h (h listed from large to small)."""
    errors = np.asarray(errors)
    return [float(v) for v in np.log2(errors[:-1] / errors[1:])]


def alpha_statistics(alphas: Array) -> dict:
    """max, median and 90th percentile of |α*|, and the fraction of steps at a bound of the search."""
    magnitude = np.abs(alphas)
    at_bound = np.isclose(alphas, REFERENCE_BOUNDS[0]) | np.isclose(alphas, REFERENCE_BOUNDS[1])
    return {
        "max_abs": float(magnitude.max()),
        "median_abs": float(np.median(magnitude)),
        "p90_abs": float(np.percentile(magnitude, 90)),
        "fraction_at_bound": float(np.mean(at_bound)),
    }


# ------------------------------------------------------------------- 1. convergence
def pendulum_period_study(counts: list[int]) -> dict:
    """Plain pendulum (constant gravity), θ₀ = π/2: error of the state after one exact period.

    The force does not depend on position, so every α gives RATTLE's map (and every
    α-RATTLE-4 the triple jump's): the difference of each method's end state from
    RATTLE's is recorded as the check, with the energy error and how often the
    energy mode's root search found no root (α* at a bound).
    """
    theta0 = np.pi / 2
    period = planar_pendulum_period(theta0)
    problem = planar_pendulum(kappa=0.0)
    x0, v0 = planar_pendulum_start(theta0)
    e0 = problem.energy(x0, v0)
    hs = period / np.array(counts)
    result: dict = {"theta0": theta0, "period": period, "counts": counts, "h": hs.tolist(), "methods": {}}
    ends = {}
    for method in CONVERGENCE_METHODS:
        errors, ends[method.key], energy_errors, at_bound = [], [], [], []
        for n in counts:
            x, v, alphas, energies = run_method(method, problem, x0, v0, period / n, n)
            errors.append(float(np.linalg.norm(np.concatenate([x - x0, v - v0]))))
            ends[method.key].append(np.concatenate([x, v]))
            energy_errors.append(float(np.max(np.abs(energies - e0))))
            if alphas is not None:
                at_bound.append(alpha_statistics(alphas)["fraction_at_bound"])
        base = "alpha=0" if method.order == 2 else "alpha4=0"
        entry = {
            "label": method.label,
            "order": method.order,
            "errors": errors,
            "fitted_order": fitted_order(hs, np.array(errors)),
            "local_orders": local_orders(errors),
            "max_energy_error": energy_errors,
            "max_difference_from_alpha_zero": float(
                max(np.max(np.abs(a - b)) for a, b in zip(ends[method.key], ends[base]))
            ),
        }
        if at_bound:
            entry["fraction_of_steps_without_root"] = float(np.mean(at_bound))
        result["methods"][method.key] = entry
    return result


def fixed_time_study(
    problem: ConstrainedProblem,
    x0: Array,
    v0: Array,
    t_end: float,
    counts: list[int],
    reference_steps: int,
    error: Callable[[Array, Array], float],
    description: dict,
) -> dict:
    """Error at ``t_end`` against α-RATTLE-4 (α = 0) with ``reference_steps`` steps, for every method."""
    x_ref, v_ref = integrate(
        problem, x0, v0, t_end / reference_steps, reference_steps, 0.0, step=alpha_rattle4_step
    )
    x_check, v_check = integrate(
        problem, x0, v0, 2 * t_end / reference_steps, reference_steps // 2, 0.0, step=alpha_rattle4_step
    )
    hs = t_end / np.array(counts)
    result: dict = {
        **description,
        "t_end": t_end,
        "counts": counts,
        "h": hs.tolist(),
        "reference_steps": reference_steps,
        "reference_error_estimate": error(x_check - x_ref, v_check - v_ref) / 15.0,
        "methods": {},
    }
    rattle_errors = None
    for method in CONVERGENCE_METHODS:
        errors, stats = [], []
        for n in counts:
            x, v, alphas, _ = run_method(method, problem, x0, v0, t_end / n, n)
            errors.append(error(x - x_ref, v - v_ref))
            if alphas is not None:
                stats.append(alpha_statistics(alphas))
        if method.key == "alpha=0":
            rattle_errors = np.array(errors)
        entry = {
            "label": method.label,
            "order": method.order,
            "errors": errors,
            "fitted_order": fitted_order(hs, np.array(errors)),
            "local_orders": local_orders(errors),
            "error_over_rattle": (np.array(errors) / rattle_errors).tolist(),
        }
        if stats:
            entry["alpha_star"] = {k: [s[k] for s in stats] for k in stats[0]}
        result["methods"][method.key] = entry
    return result


def convergence(quick: bool) -> dict:
    """Run the three convergence studies."""
    period_counts = [40, 80, 160] if quick else [40, 80, 160, 320, 640]
    pendulum_counts = [20, 40, 80] if quick else [20, 40, 80, 160, 320]
    water_counts = [50, 100, 200] if quick else [50, 100, 200, 400]
    spring = planar_pendulum(kappa=2.0)
    xs, vs = planar_pendulum_start(1.0)
    waters, xw, vw = water_cluster(3, seed=0)
    return {
        "pendulum_period": pendulum_period_study(period_counts),
        "spring_pendulum": fixed_time_study(
            spring,
            xs,
            vs,
            2.0,
            pendulum_counts,
            1024 if quick else 4096,
            lambda dx, dv: float(np.linalg.norm(np.concatenate([dx, dv]))),
            {
                "problem": "planar pendulum with a horizontal spring, kappa = 2, theta0 = 1",
                "error": "|(x, v)|",
            },
        ),
        "water_cluster": fixed_time_study(
            waters,
            xw,
            vw,
            0.2,
            water_counts,
            2000 if quick else 8000,
            lambda dx, dv: float(np.sqrt(np.mean(dx**2))),
            {
                "problem": "3 rigid TIP3P waters in vacuum (reference.water_cluster(3, seed=0)), 300 K",
                "error": "RMS position error (nm)",
                "units": "h in ps",
            },
        ),
    }


# -------------------------------------------------------------- 2. symplecticity
def symplecticity_methods() -> list[Method]:
    """List fixed α (iterated midpoint), the one-pass variant, and both energy modes."""
    return [
        fixed(0.0),
        fixed(1 / 6),
        fixed(0.5),
        fixed(1.0),
        fixed(0.5, one_pass=True),
        fixed(1.0, one_pass=True),
        ENERGY,
        fixed(0.3, 4),
        fixed(0.3, 4, one_pass=True),
        ENERGY4,
    ]


def _flow(method: Method, problem: ConstrainedProblem, h: float, n: int) -> Callable[[Array, Array], tuple]:
    def step_map(x: Array, v: Array) -> tuple[Array, Array]:
        x1, v1, _, _ = run_method(method, problem, x, v, h, n)
        return x1, v1

    return step_map


def symplecticity(quick: bool) -> dict:
    """Defect of the symplectic form on the pendulum with a spring (against h) and on 3 waters (2 fs)."""
    spring = planar_pendulum(kappa=2.0)
    xs, vs = planar_pendulum_start(1.0)
    t_end = 0.4
    hs = [0.2, 0.1, 0.05] if quick else [0.2, 0.1, 0.05, 0.025]
    pendulum: dict = {
        "problem": "planar pendulum with a spring, kappa = 2, theta0 = 1",
        "t_end": t_end,
        "h": hs,
        "tangent_vectors": 2,
        "epsilon": 1e-6,
        "methods": {},
    }
    for method in symplecticity_methods():
        defects = [
            symplecticity_defect(spring, _flow(method, spring, h, round(t_end / h)), xs, vs, 2) for h in hs
        ]
        above = np.array(defects) > FD_FLOOR
        pendulum["methods"][method.key] = {
            "label": method.label,
            "defects": defects,
            "fitted_order": (
                fitted_order(np.array(hs)[above], np.array(defects)[above]) if above.sum() >= 2 else None
            ),
            "points_above_floor": int(above.sum()),
        }
    waters, xw, vw = water_cluster(3, seed=0)
    water: dict = {
        "problem": "3 rigid TIP3P waters in vacuum, h = 2 fs",
        "h": 0.002,
        "steps": 10,
        "tangent_vectors": 4,
        "epsilon": 1e-6,
        "methods": {},
    }
    for method in symplecticity_methods():
        water["methods"][method.key] = {
            "label": method.label,
            "defect": symplecticity_defect(waters, _flow(method, waters, 0.002, 10), xw, vw, 4),
        }
    return {"spring_pendulum": pendulum, "water_cluster": water}


# ------------------------------------------------------------------ 3. α* (OpenMM)
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


def openmm_alpha_star(workdir: Path, steps: int) -> dict:
    """Run the energy modes on ``tip3p-2nm`` (CPU, 2 fs): α* from controller.csv, H − E_ref of every run.

    Every run covers ``steps`` × 2 fs and records H every 20 fs; RATTLE and the triple
    jump also run at the energy modes' cost (6 force evaluations per 2 fs).
    """
    from openmm_alphaprk.driver import run_nve
    from openmm_alphaprk.reporters import read_controller_csv

    result: dict = {
        "system": "tip3p-2nm",
        "platform": "CPU",
        "simulated_ps": steps * 0.002,
        "energy_sampling_fs": 20.0,
        "runs": {},
    }
    for key, name, substeps in BOX_RUNS:
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
            rows = read_controller_csv(outdir / "controller.csv")
            alphas = rows[:, 2]
            entry["alpha"] = _series(alphas)
            entry["alpha_percentiles"] = observables.alpha_percentiles(alphas)
            entry["median_abs_alpha"] = float(np.median(np.abs(alphas)))
            entry["max_abs_alpha"] = float(np.max(np.abs(alphas)))
            entry["controller"] = summary.controller
        result["runs"][key] = entry
    return result


# -------------------------------------------------------------- 4. long runs (OpenMM)
class InvariantReporter:
    """OpenMM reporter: change of L and P, scales, constraint errors and H every ``interval`` steps.

    Parameters
    ----------
    system
        The ``openmm.System`` (masses and constraints are read from it).
    start
        The start ``openmm.State`` (positions and velocities), against which L and P change.
    interval
        Steps between rows.
    """

    def __init__(self, system, start, interval: int) -> None:
        self.masses = observables.masses(system)
        self.pairs, self.lengths = observables.system_constraints(system)
        self.interval = interval
        x, v = self._arrays(start)
        self.l0, self.p0 = self._momenta(x, v)
        self.rows: list[list[float]] = [[0, 0.0, 0.0, *self._scales(x, v), *self._constraint_errors(x, v)]]

    @staticmethod
    def _arrays(state) -> tuple[Array, Array]:
        import openmm.unit as unit

        return (
            state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
            state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
        )

    def _momenta(self, x: Array, v: Array) -> tuple[Array, Array]:
        linear, angular = observables.momenta(self.masses, x, v)
        return angular, linear

    def _scales(self, x: Array, v: Array) -> tuple[float, float]:
        """Σ m|x − x_cm||v| (amu nm²/ps) and Σ m|v| (amu nm/ps): what L and P are sums of."""
        centre = self.masses @ x / self.masses.sum()
        speed = np.linalg.norm(v, axis=1)
        return (
            float(np.sum(self.masses * np.linalg.norm(x - centre, axis=1) * speed)),
            float(np.sum(self.masses * speed)),
        )

    def _constraint_errors(self, x: Array, v: Array) -> tuple[float, float]:
        return observables.constraint_errors(self.pairs, self.lengths, x, v)

    def describeNextReport(self, simulation) -> dict:
        """Positions, velocities and energy every ``interval`` steps."""
        steps = self.interval - simulation.currentStep % self.interval
        return {"steps": steps, "periodic": None, "include": ["positions", "velocities", "energy"]}

    def report(self, simulation, state) -> None:
        """Append a row: step, |ΔL|, |ΔP|, the scales, the constraint errors, H."""
        import openmm.unit as unit

        x, v = self._arrays(state)
        angular, linear = self._momenta(x, v)
        energy = (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(
            unit.kilojoules_per_mole
        )
        self.rows.append(
            [
                simulation.currentStep,
                float(np.linalg.norm(angular - self.l0)),
                float(np.linalg.norm(linear - self.p0)),
                *self._scales(x, v),
                *self._constraint_errors(x, v),
                energy,
            ]
        )


def _series(values: Array) -> list[float]:
    """Four significant digits: the series are for the figures, the tables use full precision."""
    return [float(f"{value:.4g}") for value in values]


def _long_run_entry(reporter: InvariantReporter, e_ref: float, timestep_ps: float, extra: dict) -> dict:
    start, rows = reporter.rows[0], np.array(reporter.rows[1:], dtype=float)
    steps, dl, dp, scale_l, scale_p, c_pos, c_vel, energy = rows.T
    residual = energy - e_ref
    return {
        **extra,
        "time_ps": _series(steps * timestep_ps),
        "angular_change": _series(dl),
        "linear_change": _series(dp),
        "constraint_error_change": _series(c_pos - start[5]),
        "energy_residual": _series(residual),
        "angular_scale": float(np.mean(scale_l)),
        "linear_scale": float(np.mean(scale_p)),
        "max_angular_change": float(dl.max()),
        "max_relative_angular_change": float(dl.max() / np.mean(scale_l)),
        "max_linear_change": float(dp.max()),
        "max_relative_linear_change": float(dp.max() / np.mean(scale_p)),
        "start_constraint_error": start[5],
        "max_constraint_error": float(c_pos.max()),
        "max_constraint_velocity_error": float(c_vel.max()),
        "rms_energy_residual": float(np.sqrt(np.mean(residual**2))),
        "max_abs_energy_residual": float(np.max(np.abs(residual))),
    }


def long_runs(workdir: Path, steps: dict[str, int], interval: int) -> dict:
    """rattle, alpha=1/6, energy and energy4 on ``water-cluster`` through the driver, on Reference and CPU.

    A fifth run (Reference) drives the order-2 energy mode directly with the midpoint
    iterated to 1e-12 nm instead of its default 1e-7 nm.
    """
    import openmm as mm
    import openmm.app as app
    import openmm.unit as unit

    from openmm_alphaprk import AlphaRattleIntegrator
    from openmm_alphaprk.driver import run_nve
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
        runs = {}
        for name in ("rattle", "alpha=1/6", "energy", "energy4"):
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
            runs[name] = _long_run_entry(
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
        result["platforms"][platform_name] = {"steps": n_steps, "runs": runs}
    n_steps = steps["Reference"]
    integrator = AlphaRattleIntegrator(0.002, "energy", constraint_tolerance=1e-8, midpoint_tolerance=1e-12)
    simulation = app.Simulation(
        prepared.topology, prepared.system, integrator, mm.Platform.getPlatformByName("Reference")
    )
    simulation.context.setState(prepared.state)
    reporter = InvariantReporter(prepared.system, prepared.state, interval)
    simulation.reporters.append(reporter)
    start = simulation.context.getState(getEnergy=True)
    e_ref = (start.getPotentialEnergy() + start.getKineticEnergy()).value_in_unit(unit.kilojoules_per_mole)
    started = time.perf_counter()
    simulation.step(n_steps)
    result["platforms"]["Reference"]["runs"]["energy, midpoint 1e-12 nm"] = _long_run_entry(
        reporter,
        e_ref,
        0.002,
        {
            "steps": n_steps,
            "force_evaluations_per_step": integrator.force_evaluations_per_step,
            "wall_seconds": time.perf_counter() - started,
        },
    )
    return result


# ------------------------------------------------------------------------ tables
def _e(value: float, digits: int = 2) -> str:
    if value == 0:
        return "0"
    return f"{value:.{digits}e}".replace("e-0", "e-").replace("e+0", "e")


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _table(header: list[str], rows: list[list[str]]) -> str:
    return "\n".join([_row(header), _row(["---"] * len(header)), *(_row(r) for r in rows)])


def render_tables(data: dict) -> dict[str, str]:
    """Markdown tables of the page, from the JSON data (the page must hold exactly these)."""
    tables = {"headline": render_headline(data)}
    conv = data["convergence"]
    period, spring, water = conv["pendulum_period"], conv["spring_pendulum"], conv["water_cluster"]
    rows = []
    for key in ("alpha=0", "alpha=1", "energy", "alpha4=0", "energy4"):
        entry = period["methods"][key]
        rows.append(
            [
                entry["label"],
                *(_e(e) for e in entry["max_energy_error"]),
                f"{entry['fraction_of_steps_without_root']:.0%}"
                if "fraction_of_steps_without_root" in entry
                else "—",
            ]
        )
    tables["plain_pendulum_energy"] = _table(
        ["method", *(f"max \\|H − H₀\\|, h = T/{n}" for n in period["counts"]), "steps without root"], rows
    )
    rows = []
    for key, entry in spring["methods"].items():
        p, w = period["methods"][key], water["methods"][key]
        rows.append(
            [
                entry["label"],
                f"{p['fitted_order']:.2f}",
                _e(p["max_difference_from_alpha_zero"], 1),
                f"{entry['fitted_order']:.2f}",
                f"{entry['error_over_rattle'][1]:.2g}",
                f"{w['fitted_order']:.2f}",
                f"{w['local_orders'][-1]:.2f}",
                f"{w['error_over_rattle'][1]:.2g}",
            ]
        )
    tables["orders"] = _table(
        [
            "method",
            "plain pendulum, period error",
            "max difference from α = 0 (same order)",
            "spring pendulum",
            f"spring pendulum: error / RATTLE's at h = {spring['h'][1]:g}",
            "3 waters: fitted",
            "3 waters: finest pair",
            f"3 waters: error / RATTLE's at h = {water['h'][1] * 1000:g} fs",
        ],
        rows,
    )
    rows = []
    for entry in water["methods"].values():
        rows.append([entry["label"], *(_e(e) for e in entry["errors"])])
    tables["water_errors"] = _table(
        ["method", *(f"h = {h * 1000:g} fs" for h in water["h"])],
        rows,
    )
    sym = data["symplecticity"]
    rows = []
    for key, entry in sym["spring_pendulum"]["methods"].items():
        rows.append(
            [
                entry["label"],
                *(_e(d, 1) for d in entry["defects"]),
                "floor" if entry["fitted_order"] is None else f"{entry['fitted_order']:.1f}",
                _e(sym["water_cluster"]["methods"][key]["defect"], 1),
            ]
        )
    tables["symplecticity"] = _table(
        [
            "method",
            *(f"pendulum h = {h:g}" for h in sym["spring_pendulum"]["h"]),
            "slope (above 1e-7)",
            "3 waters, 10 × 2 fs",
        ],
        rows,
    )
    rows = []
    for problem, unit_scale, unit in ((spring, 1.0, ""), (water, 1000.0, " fs")):
        for key in ("energy", "energy4"):
            stats = problem["methods"][key]["alpha_star"]
            for i, h in enumerate(problem["h"]):
                rows.append(
                    [
                        "spring pendulum" if problem is spring else "3 waters",
                        problem["methods"][key]["label"],
                        f"{h * unit_scale:g}{unit}",
                        f"{stats['median_abs'][i]:.3g}",
                        f"{stats['p90_abs'][i]:.3g}",
                        f"{stats['max_abs'][i]:.3g}",
                        f"{stats['fraction_at_bound'][i]:.0%}",
                    ]
                )
    tables["alpha_star_h"] = _table(
        [
            "problem",
            "mode",
            "h",
            "median \\|α*\\|",
            "90th pct \\|α*\\|",
            "max \\|α*\\|",
            "steps without root",
        ],
        rows,
    )
    box = data["alpha_star_openmm"]
    rows = []
    for name in ("energy", "energy4"):
        run = box["runs"][name]
        pct = run["alpha_percentiles"]
        ctl = run["controller"]
        rows.append(
            [
                name,
                *(f"{pct[k]:.3g}" for k in ("p1", "p5", "p25", "p50", "p75", "p95", "p99")),
                f"{run['median_abs_alpha']:.3g}",
                f"{ctl['fraction_at_bound']:.1%}",
                f"{ctl['fraction_fallen_back']:.0%}",
            ]
        )
    tables["alpha_star_box"] = _table(
        [
            "integrator",
            "p1",
            "p5",
            "p25",
            "p50",
            "p75",
            "p95",
            "p99",
            "median \\|α*\\|",
            "steps at a bound",
            "steps not within 0.01 kJ/mol",
        ],
        rows,
    )
    rattle_rms = box["runs"]["rattle"]["rms_residual"]
    rows = [
        [
            key,
            f"{run['timestep_fs']:.3g}",
            f"{run['force_evaluations_per_2fs']:.2f}",
            f"{run['rms_residual']:.3g}",
            f"{run['max_abs_residual']:.3g}",
            f"{rattle_rms / run['rms_residual']:.3g}",
        ]
        for key, run in box["runs"].items()
    ]
    tables["box_energy"] = _table(
        [
            "integrator",
            "h (fs)",
            "force evaluations per 2 fs",
            "RMS H − E_ref (kJ/mol)",
            "max \\|H − E_ref\\|",
            "RATTLE's RMS / this RMS",
        ],
        rows,
    )
    runs = data["long_runs"]
    rows = []
    for platform_name, block in runs["platforms"].items():
        for name, run in block["runs"].items():
            rows.append(
                [
                    platform_name,
                    name,
                    f"{run['steps'] * runs['timestep_fs'] / 1000:g}",
                    _e(run["max_angular_change"]),
                    _e(run["max_relative_angular_change"]),
                    _e(run["max_relative_linear_change"]),
                    f"{_e(run['start_constraint_error'])} → {_e(run['max_constraint_error'])}",
                    _e(run["max_constraint_velocity_error"], 1),
                    f"{run['rms_energy_residual']:.3g}",
                    f"{run['max_abs_energy_residual']:.3g}",
                    f"{run['force_evaluations_per_step']:.2f}",
                ]
            )
    tables["long_runs"] = _table(
        [
            "platform",
            "integrator",
            "ps",
            "max \\|ΔL\\| (amu nm²/ps)",
            "/ Σm\\|x\\|\\|v\\|",
            "max \\|ΔP\\| / Σm\\|v\\|",
            "constraint error: start → max",
            "max \\|v·r\\|/\\|r\\| (nm/ps)",
            "RMS H − E_ref (kJ/mol)",
            "max \\|H − E_ref\\|",
            "force evaluations / step",
        ],
        rows,
    )
    return tables


def render_headline(data: dict) -> str:
    """Render the summary table: one row per integrator, one column per property."""
    water = data["convergence"]["water_cluster"]["methods"]
    defects = data["symplecticity"]["water_cluster"]["methods"]
    box = data["alpha_star_openmm"]["runs"]
    cluster = data["long_runs"]["platforms"]["Reference"]["runs"]
    openmm_names = {"alpha=0": "rattle", "alpha=1/6": "alpha=1/6", "energy": "energy", "energy4": "energy4"}
    box_names = {"alpha=0": "rattle", "alpha4=0": "alpha4=0", "energy": "energy", "energy4": "energy4"}
    rows = []
    for key in ("alpha=0", "alpha=1/6", "alpha=1", "energy", "alpha4=0", "energy4"):
        entry = water[key]
        stats = entry.get("alpha_star")
        defect = defects.get(key, {}).get("defect")
        cluster_run = cluster.get(openmm_names.get(key, ""), None)
        box_run = box.get(box_names.get(key, ""), None)
        rows.append(
            [
                entry["label"],
                f"{entry['fitted_order']:.2f}",
                f"{entry['error_over_rattle'][1]:.2g}×",
                _e(defect, 1) if defect is not None else "—",
                f"{stats['median_abs'][1]:.2g}" if stats else "—",
                f"{box_run['rms_residual']:.2g}" if box_run else "—",
                f"{box_run['force_evaluations_per_step']:.1f}" if box_run else "—",
                _e(cluster_run["max_relative_angular_change"], 1) if cluster_run else "—",
            ]
        )
    return _table(
        [
            "integrator",
            "order (3 waters)",
            "error vs RATTLE, 3 waters, 2 fs",
            "symplecticity defect, 3 waters",
            "median \\|α*\\| (exact), 3 waters, 2 fs",
            "RMS H − E_ref, 774-atom box, 2 fs (kJ/mol)",
            "force evaluations / step (box)",
            "max \\|ΔL\\| / Σm\\|x\\|\\|v\\|, 222-atom cluster (Reference)",
        ],
        rows,
    )


#: A generated table: its marker, then anything but another marker, then the end marker.
TABLE_PATTERN = re.compile(r"<!-- table: (\w+) -->\n((?:(?!<!-- ).)*?)<!-- end table -->", re.S)


def update_page(page: Path, tables: dict[str, str]) -> list[str]:
    """Replace the generated tables in ``page``; return the names of tables the page lacks."""
    text = page.read_text(encoding="utf-8")
    found = set()

    def replace(match: re.Match) -> str:
        name = match.group(1)
        if name not in tables:
            return match.group(0)
        found.add(name)
        return f"<!-- table: {name} -->\n{tables[name]}\n<!-- end table -->"

    page.write_text(TABLE_PATTERN.sub(replace, text), encoding="utf-8")
    return sorted(set(tables) - found)


def page_tables(page: Path) -> dict[str, str]:
    """Return the generated tables as they stand in ``page``."""
    return {
        m.group(1): m.group(2).rstrip("\n") for m in TABLE_PATTERN.finditer(page.read_text(encoding="utf-8"))
    }


# ----------------------------------------------------------------------- figures
def _slope_label(label: str, order: float) -> str:
    return f"{label} (slope {order:.2f})"


def figure_convergence(data: dict, path: Path) -> None:
    """Error against h, log-log, with fitted slopes: three panels."""
    conv = data["convergence"]
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    panels = [
        (conv["pendulum_period"], 1.0, "h", "state error after one exact period", "Plain pendulum (κ = 0)"),
        (conv["spring_pendulum"], 1.0, "h", "state error at t = 2", "Pendulum with a spring (κ = 2)"),
        (conv["water_cluster"], 1000.0, "h (fs)", "RMS position error at 0.2 ps (nm)", "3 rigid waters"),
    ]
    for ax, (study, scale, xlabel, ylabel, title) in zip(axes, panels):
        hs = np.array(study["h"]) * scale
        for entry in study["methods"].values():
            style = "s--" if entry["order"] == 4 else "o-"
            ax.loglog(
                hs, entry["errors"], style, ms=4, label=_slope_label(entry["label"], entry["fitted_order"])
            )
        ax.set_xticks(hs, [f"{h:.3g}" for h in hs])
        ax.minorticks_off()
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.legend(fontsize=6.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_symplecticity(data: dict, path: Path) -> None:
    """Defect against h (pendulum) and per method (3 waters)."""
    sym = data["symplecticity"]
    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    hs = sym["spring_pendulum"]["h"]
    for key, entry in sym["spring_pendulum"]["methods"].items():
        style = "s--" if "4" in key else ("x:" if "one-pass" in key else "o-")
        axes[0].loglog(hs, entry["defects"], style, ms=5, label=entry["label"])
    axes[0].axhline(
        FD_FLOOR, color="k", lw=0.8, ls="--", label="finite-difference floor (slopes fitted above)"
    )
    axes[0].set_xticks(hs, [f"{h:g}" for h in hs])
    axes[0].minorticks_off()
    axes[0].set_xlabel("h")
    axes[0].set_ylabel("relative change of ω over t = 0.4")
    axes[0].set_title("Pendulum with a spring: symplecticity defect")
    axes[0].legend(fontsize=7)
    methods = sym["water_cluster"]["methods"]
    labels = [entry["label"] for entry in methods.values()]
    axes[1].barh(range(len(labels)), [entry["defect"] for entry in methods.values()], log=True)
    axes[1].set_yticks(range(len(labels)), labels, fontsize=8)
    axes[1].invert_yaxis()
    axes[1].axvline(FD_FLOOR, color="k", lw=0.8, ls="--")
    axes[1].set_xlabel("relative change of ω over 10 steps of 2 fs")
    axes[1].set_title("3 rigid waters")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_alpha_star(data: dict, path: Path) -> None:
    """|α*| against h (reference) and histograms of α* on the 774-atom box (OpenMM)."""
    conv = data["convergence"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    for ax, (study, scale, xlabel, title) in zip(
        axes[0],
        [
            (conv["spring_pendulum"], 1.0, "h", "Pendulum with a spring: exact α* per step"),
            (conv["water_cluster"], 1000.0, "h (fs)", "3 rigid waters: exact α* per step"),
        ],
    ):
        hs = np.array(study["h"]) * scale
        for key, color in (("energy", "C0"), ("energy4", "C3")):
            stats = study["methods"][key]["alpha_star"]
            label = study["methods"][key]["label"]
            ax.loglog(hs, stats["median_abs"], "o-", color=color, label=f"{label}: median |α*|")
            ax.loglog(hs, stats["max_abs"], "^:", color=color, label=f"{label}: max |α*|")
        guide = np.array(study["methods"]["energy4"]["alpha_star"]["median_abs"][0]) * (hs / hs[0]) ** 2
        ax.loglog(hs, guide, "k--", lw=0.8, label="∝ h²")
        ax.set_xticks(hs, [f"{h:.3g}" for h in hs])
        ax.minorticks_off()
        ax.set_xlabel(xlabel)
        ax.set_ylabel("|α*|")
        ax.set_title(title)
        ax.legend(fontsize=7)
    box = data["alpha_star_openmm"]
    for ax, name in zip(axes[1], ("energy", "energy4")):
        alphas = np.array(box["runs"][name]["alpha"])
        ax.hist(alphas, bins=60, color="C0" if name == "energy" else "C3")
        ax.set_xlabel("α used by the OpenMM controller")
        ax.set_ylabel("steps")
        ax.set_title(f"{name}: tip3p-2nm (774 atoms, PME), 2 fs, {alphas.size} steps, CPU")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_long_runs(data: dict, path: Path) -> None:
    """|ΔL|/scale, |ΔP|/scale, constraint error and H − E_ref against time (Reference solid, CPU dashed)."""
    runs = data["long_runs"]
    fig, axes = plt.subplots(2, 2, figsize=(13, 9), sharex=True)
    colors = {
        "rattle": "C0",
        "alpha=1/6": "C1",
        "energy": "C2",
        "energy4": "C3",
        "energy, midpoint 1e-12 nm": "C4",
    }
    for platform_name, block in runs["platforms"].items():
        style = "-" if platform_name == "Reference" else "--"
        for name, run in block["runs"].items():
            t = np.array(run["time_ps"])
            kw = {"color": colors[name], "ls": style, "lw": 0.8, "label": f"{name} ({platform_name})"}
            axes[0, 0].semilogy(
                t, np.maximum(np.array(run["angular_change"]) / run["angular_scale"], 1e-18), **kw
            )
            axes[0, 1].semilogy(
                t, np.maximum(np.array(run["linear_change"]) / run["linear_scale"], 1e-18), **kw
            )
            change = np.abs(np.array(run["constraint_error_change"]))
            dots = {"color": kw["color"], "marker": "." if platform_name == "Reference" else "x"}
            axes[1, 0].semilogy(t, np.maximum(change, 1e-18), ls="none", ms=2, **dots)
            if platform_name == "Reference":
                axes[1, 1].plot(t, run["energy_residual"], **{**kw, "lw": 0.5})
    axes[0, 0].set_ylabel("|L(t) − L(0)| / Σ m|x − x_cm||v|")
    axes[0, 1].set_ylabel("|P(t) − P(0)| / Σ m|v|")
    axes[1, 0].set_ylabel("|max relative constraint error − its start value| (0 drawn at 1e-18)")
    axes[1, 0].set_title("constraints (SETTLE's geometry is 3e-8 off the nominal lengths)", fontsize=9)
    axes[1, 1].set_ylabel("H − E_ref (kJ/mol), Reference platform")
    for ax in axes[1]:
        ax.set_xlabel("time (ps)")
    axes[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"water-cluster ({runs['n_atoms']} atoms, vacuum, no cutoff), 2 fs, driver defaults")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -------------------------------------------------------------------------- main
def dump_json(data: dict) -> str:
    """Indented JSON with every list of plain numbers on one line."""
    text = json.dumps(data, indent=1)
    numbers = re.compile(r"\[\s*([-0-9.eE+]+(?:,\s*[-0-9.eE+]+)*)\s*\]")
    return numbers.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text) + "\n"


def compute(quick: bool, workdir: Path) -> dict:
    """Run every study; return the page's data (what ``docs/validation.json`` holds)."""
    import openmm as mm

    mm.Platform.getPlatformByName("CPU").setPropertyDefaultValue("Threads", "1")
    started = time.perf_counter()
    timings: dict[str, float] = {}

    def timed(name: str, function: Callable[[], dict]) -> dict:
        t0 = time.perf_counter()
        value = function()
        timings[name] = time.perf_counter() - t0
        print(f"[{timings[name]:6.1f} s] {name}", file=sys.stderr, flush=True)
        return value

    data: dict = {
        "command": COMMAND + (" --quick" if quick else ""),
        "quick": quick,
        "versions": {
            "python": python_platform.python_version(),
            "numpy": np.__version__,
            "openmm": mm.__version__,
        },
        "machine": f"{python_platform.machine()}, OpenMM runs on 1 CPU thread",
    }
    data["convergence"] = timed("convergence", lambda: convergence(quick))
    data["symplecticity"] = timed("symplecticity", lambda: symplecticity(quick))
    data["alpha_star_openmm"] = timed(
        "alpha* on tip3p-2nm", lambda: openmm_alpha_star(workdir, 100 if quick else 1000)
    )
    long_steps = {"Reference": 500, "CPU": 500} if quick else {"Reference": 20000, "CPU": 20000}
    data["long_runs"] = timed("long runs", lambda: long_runs(workdir, long_steps, 20 if quick else 50))
    data["timings_seconds"] = {**timings, "total": time.perf_counter() - started}
    print(f"total {data['timings_seconds']['total']:.0f} s", file=sys.stderr)
    return data


def main(argv: list[str] | None = None) -> int:
    """Compute everything, write the JSON, the figures and the page's tables; print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small runs, to check the script")
    parser.add_argument("--json", type=Path, help="output JSON (default docs/validation.json)")
    parser.add_argument("--figures", type=Path, help="figure folder (default docs/figures)")
    parser.add_argument(
        "--page", type=Path, help="page whose tables are rewritten (default docs/validation.md)"
    )
    parser.add_argument(
        "--workdir", type=Path, help="run directories of the OpenMM runs (default: temporary)"
    )
    parser.add_argument(
        "--from-json",
        action="store_true",
        help="compute nothing: redraw the figures and rewrite the tables from the existing JSON",
    )
    args = parser.parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="alphaprk-validation-"))
    if args.quick:
        json_path = args.json or scratch / "validation.json"
        figures = args.figures or scratch / "figures"
        page = args.page
    else:
        json_path = args.json or DOCS / "validation.json"
        figures = args.figures or DOCS / "figures"
        page = args.page or DOCS / "validation.md"
    if args.from_json:
        data = json.loads(json_path.read_text(encoding="utf-8"))
    else:
        data = compute(args.quick, args.workdir or scratch / "runs")
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(dump_json(data), encoding="utf-8")
    figures.mkdir(parents=True, exist_ok=True)
    figure_convergence(data, figures / "validation_convergence.png")
    figure_symplecticity(data, figures / "validation_symplecticity.png")
    figure_alpha_star(data, figures / "validation_alpha_star.png")
    figure_long_runs(data, figures / "validation_long_runs.png")
    tables = render_tables(data)
    for name, table in tables.items():
        print(f"\n## {name}\n{table}")
    if page is not None:
        missing = update_page(page, tables)
        if missing:
            print(f"\n{page} has no place for the tables {', '.join(missing)}", file=sys.stderr)
    print(f"\nJSON: {json_path}\nfigures: {figures}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
