"""Convergence orders of the α-RATTLE family on the NumPy reference.

The plain pendulum is measured by the error after one exact period; the pendulum
with a spring and a cluster of three rigid waters by the error at a fixed time
against a fine-step α-RATTLE-4 reference.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from openmm_alphaprk.observables import convergence_order as fitted_order
from openmm_alphaprk.reference import (
    alpha_rattle4_step,
    integrate,
    planar_pendulum,
    planar_pendulum_period,
    planar_pendulum_start,
    water_cluster,
)
from openmm_alphaprk.reference.step import Array, ConstrainedProblem

from .methods import (
    CONVERGENCE_METHODS,
    alpha_statistics,
    local_orders,
    run_method,
)


def pendulum_period_study(counts: list[int]) -> dict:
    """Measure the plain pendulum (constant gravity), θ₀ = π/2: error of the state after one exact period.

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
            **_order_entry(method, hs, errors),
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
    """Measure every method's error at ``t_end`` against α-RATTLE-4 (α = 0) with ``reference_steps`` steps."""
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
            **_order_entry(method, hs, errors),
            "error_over_rattle": (np.array(errors) / rattle_errors).tolist(),
        }
        if stats:
            entry["alpha_star"] = {k: [s[k] for s in stats] for k in stats[0]}
        result["methods"][method.key] = entry
    return result


def _order_entry(method, hs: np.ndarray, errors: list[float]) -> dict:
    """Return what every convergence study records of a method: label, order, errors, fitted orders."""
    return {
        "label": method.label,
        "order": method.order,
        "errors": errors,
        "fitted_order": fitted_order(hs, np.array(errors)),
        "local_orders": local_orders(errors),
    }


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
