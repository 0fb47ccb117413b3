"""The MD benchmark's tables: their numbers from the sweep's rows, and their Markdown.

:func:`energy_table`, :func:`dynamics_table` and :func:`scan_table` gather the
numbers of one system (what ``docs/data/benchmarks/benchmarks.json`` holds);
:func:`energy_markdown`, :func:`dynamics_markdown` and :func:`scan_markdown` render
them as the generated blocks of ``docs/benchmarks.md``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tools.reports.md_benchmark_analysis import analyse_run, compare_dynamics
from tools.reports.md_benchmark_results import (
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


def fmt(value: float, digits: int = 3) -> str:
    """Format a number for a table cell."""
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "—"
    if value == 0:
        return "0"
    if abs(value) >= 1000 or abs(value) < 1e-3:
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def energy_markdown(system: str, entries: list[dict]) -> str:
    """Render the Markdown table of energy error and cost."""
    first = entries[0]
    lines = [
        f"**{system}**: {first.get('n_atoms', '?')} atoms, {first.get('degrees_of_freedom', '?')} DOF, "
        f"{fmt(first.get('simulated_ps', float('nan')))} ps per run, from the same equilibrated start.",
        "",
        "| integrator | evals/step | time/step ÷ RATTLE 2 fs | time/ps ÷ RATTLE 2 fs | ns/day | sweep ns/day "
        "| RMS(H − E_ref) kJ/mol | max | drift kJ/mol/ns/DOF | α* p5/p50/p95 | within tol. | at bound |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for e in entries:
        if "error" in e:
            lines.append(f"| {e['label']} | failed: {e['error'][:80]} |" + " |" * 10)
            continue
        c = e.get("controller", {})
        alpha = (
            f"{c['alpha_percentiles.p5']:.2f}/{c['alpha_percentiles.p50']:.2f}/{c['alpha_percentiles.p95']:.2f}"
            if "alpha_percentiles.p50" in c
            else "—"
        )
        within = f"{100 * c['fraction_within_tolerance']:.0f} %" if "fraction_within_tolerance" in c else "—"
        bound = f"{100 * c['fraction_at_bound']:.1f} %" if "fraction_at_bound" in c else "—"
        t = {
            "time_per_step_ratio": float("nan"),
            "time_per_ps_ratio": float("nan"),
            "ns_per_day": float("nan"),
        }
        t |= e["timing"]
        lines.append(
            f"| {e['label']} | {e['force_evaluations_per_step']:.2f} | {t['time_per_step_ratio']:.2f} | "
            f"{t['time_per_ps_ratio']:.2f} | {t['ns_per_day']:.3g} | {e['sweep_ns_per_day']:.3g} | "
            f"{fmt(e['rms_residual'])} | "
            f"{fmt(e['max_abs_residual'])} | {fmt(e['drift_per_dof'], 2)} | {alpha} | {within} | {bound} |"
        )
    return "\n".join(lines)


def dynamics_markdown(system: str, entries: list[dict], reference_label: str) -> str:
    """Render the Markdown table of RDF, D and spectrum against the reference."""
    lines = [
        f"**{system}** against {reference_label} (start velocities):",
        "",
        "| run | RMS Δg(r), 2.4–8 Å | g(r) first peak | D (1e-5 cm²/s) | ΔD vs reference | spectrum distance "
        "0–1200 cm⁻¹ | libration centroid (cm⁻¹) | shift |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for e in entries:
        lines.append(
            f"| {e['label']} | {e['rdf_rms_difference']:.3f} | {e['rdf_first_peak']:.2f} | "
            f"{e['diffusion']:.2f} ± {e['diffusion_error']:.2f} | "
            f"{100 * e['diffusion_relative_difference']:+.0f} % | "
            f"{fmt(e.get('spectrum_difference', float('nan')))} | "
            f"{fmt(e.get('libration_centroid', float('nan')), 4)} | "
            f"{e.get('libration_centroid_shift', float('nan')):+.1f} |"
        )
    return "\n".join(lines)


def scan_markdown(system: str, scan: dict) -> str:
    """Render the Markdown table of the step-size scan."""
    steps = sorted({s for cells in scan.values() for s in cells if s[0].isdigit()}, key=float)
    lines = [
        f"**{system}**: max|H − E_ref| per DOF (kJ/mol) over the run; ✗ = the run failed (NaN or failed "
        "midpoint iteration); stable = finished with max|H − E_ref| per DOF < "
        f"{STABLE_MAX_PER_DOF} kJ/mol.",
        "",
        "| integrator | " + " | ".join(f"{s} fs" for s in steps) + " | largest stable step |",
        "| --- |" + " --- |" * (len(steps) + 1),
    ]
    for integrator, cells in scan.items():
        row = []
        for s in steps:
            cell = cells.get(s)
            if cell is None:
                row.append("")
            elif cell["status"] != "ok":
                row.append("✗")
            else:
                mark = "" if cell["stable"] else " (unstable)"
                row.append(f"{cell['max_abs_residual_per_dof']:.1e}{mark}")
        largest = cells["largest_stable_fs"]
        limit = "none" if largest is None else f"{largest:g} fs"
        if largest is not None and largest == cells["scanned_to_fs"]:
            limit = f"≥ {largest:g} fs (scan end)"
        if sum(1 for s in cells if s[0].isdigit()) == 1:
            limit = "not scanned"
        lines.append(f"| {LABELS[integrator]} | " + " | ".join(row) + f" | {limit} |")
    return "\n".join(lines)
