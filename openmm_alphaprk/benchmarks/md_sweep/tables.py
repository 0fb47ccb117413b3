"""The MD benchmark's tables: the numbers of one system gathered from the sweep's rows.

:func:`energy_table`, :func:`dynamics_table` and :func:`scan_table` return what the
benchmark's JSON file holds per system.
"""

from __future__ import annotations

from pathlib import Path

from .analysis import analyse_run, compare_dynamics
from .results import (
    ENERGY_ROWS,
    LABELS,
    REFERENCE,
    STABLE_MAX_PER_DOF,
    get,
    number,
    run_label,
)


def energy_table(rows, system: str, timing: dict[str, dict]) -> list[dict]:
    """Return the energy, cost and controller numbers of one system's main runs (start velocities)."""
    base = get(rows, system, "rattle", 2.0)
    if base is None or base["status"] != "ok":
        return []
    base_time = number(base, "wall_seconds") / number(base, "steps_this_call")
    out = []
    for integrator, step in ENERGY_ROWS:
        row = get(rows, system, integrator, step)
        if row is None:
            continue
        entry = {"label": run_label(integrator, step), "integrator": integrator, "timestep_fs": step}
        if row["status"] != "ok":
            entry["error"] = row["error"]
            out.append(entry)
            continue
        per_step = number(row, "wall_seconds") / number(row, "steps_this_call")
        entry |= {
            "force_evaluations_per_step": number(row, "force_evaluations_per_step"),
            "timing": timing.get(entry["label"], {}),
            "sweep_time_per_step_ratio": per_step / base_time,
            "sweep_ns_per_day": number(row, "ns_per_day"),
            "rms_residual": number(row, "rms_residual"),
            "max_abs_residual": number(row, "max_abs_residual"),
            "drift_per_dof": number(row, "drift_per_dof"),
            "max_relative_constraint_error": number(row, "max_relative_constraint_error"),
            "simulated_ps": number(row, "simulated_ps"),
            "degrees_of_freedom": int(number(row, "degrees_of_freedom")),
            "n_atoms": int(number(row, "n_atoms")),
        }
        if integrator.startswith("energy"):
            entry["controller"] = {
                key.split(".", 1)[1]: number(row, key)
                for key in row
                if key.startswith("controller.") and key != "controller.residuals_over"  # the one text field
            }
        out.append(entry)
    return out


def dynamics_table(rows, system: str) -> list[dict]:
    """Compare the dynamics of every main run of a system with the small-step reference."""
    reference_row = get(rows, system, *REFERENCE)
    if reference_row is None or reference_row["status"] != "ok":
        return []
    reference = analyse_run(Path(reference_row["run_dir"]))
    out = []
    for integrator, step in ENERGY_ROWS:
        row = get(rows, system, integrator, step)
        if row is None or row["status"] != "ok":
            continue
        analysis = analyse_run(Path(row["run_dir"]))
        out.append({"label": run_label(integrator, step), **compare_dynamics(analysis, reference)})
    # independent starts (seeds): the statistical spread the differences are to be read against
    for seed in ("1", "2"):
        for integrator, step in (("rattle", 0.5), ("rattle", 2.0), ("energy4", 2.0)):
            row = get(rows, system, integrator, step, seed)
            if row is None or row["status"] != "ok":
                continue
            analysis = analyse_run(Path(row["run_dir"]))
            name = f"{run_label(integrator, step)}, seed {seed}"
            out.append({"label": name, **compare_dynamics(analysis, reference)})
    return out


def scan_table(rows, system: str) -> dict:
    """Return the step-size scan: per integrator and step, finished or not and max|H − E_ref| per DOF."""
    scan: dict[str, dict] = {}
    for (sys_name, integrator, step, seed), row in sorted(rows.items()):
        if sys_name != system or seed != "" or step < 2.0:  # the smaller RATTLE steps are not scan cells
            continue
        if integrator not in LABELS:
            continue
        cell = {"status": row["status"]}
        if row["status"] == "ok":
            dof = number(row, "degrees_of_freedom")
            cell["max_abs_residual_per_dof"] = number(row, "max_abs_residual") / dof
            cell["rms_residual_per_dof"] = number(row, "rms_residual") / dof
            cell["stable"] = bool(cell["max_abs_residual_per_dof"] < STABLE_MAX_PER_DOF)
            cell["simulated_ps"] = number(row, "simulated_ps")
        else:
            cell["stable"] = False
            cell["error"] = row["error"][:160]
        scan.setdefault(integrator, {})[f"{step:g}"] = cell
    if not any(float(step) > 2.0 for cells in scan.values() for step in cells):
        return {}  # no scan cells for this system
    for cells in scan.values():
        steps = sorted(cells, key=float)
        largest = None
        for step in steps:  # the largest step below which every scanned step was stable
            if not cells[step]["stable"]:
                break
            largest = float(step)
        cells["largest_stable_fs"] = largest
        cells["scanned_to_fs"] = float(steps[-1])
    return scan
