"""docs/benchmarks.md's generated tables, from the MD benchmark's JSON file.

The benchmark is :mod:`openmm_alphaprk.benchmarks.md_sweep` (the sweep of
``docs/sweeps/md_benchmark.toml``, the analyses of its runs, the figures); run it as::

    python -m openmm_alphaprk.benchmarks.md_sweep docs/sweeps/md_benchmark.toml \
        --json docs/data/benchmarks/benchmarks.json --figures docs/figures [--run]

It writes ``docs/data/benchmarks/benchmarks.json``; ``python -m tools.reports`` renders and
checks the page's tables from it (:func:`render`).
"""

from __future__ import annotations

import json

import numpy as np

from openmm_alphaprk.benchmarks.md_sweep.results import LABELS, STABLE_MAX_PER_DOF, SYSTEMS
from tools.reports.markdown import read_blocks, replace_generated
from tools.reports.sources import DATA, DOCS

PAGE = DOCS / "benchmarks.md"
JSON_OUT = DATA / "benchmarks" / "benchmarks.json"


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


def render_page(page: str, report: dict) -> str:
    """Replace the generated blocks of the page's text ``page`` with the report's tables."""
    for system in SYSTEMS:
        if report["energy"][system]:
            page = replace_generated(
                page, f"energy {system}", energy_markdown(system, report["energy"][system]), PAGE
            )
        if report["dynamics"][system]:
            page = replace_generated(
                page,
                f"dynamics {system}",
                dynamics_markdown(system, report["dynamics"][system], report["reference"]),
                PAGE,
            )
        if report["scan"][system]:
            page = replace_generated(
                page, f"scan {system}", scan_markdown(system, report["scan"][system]), PAGE
            )
    return page


def render() -> dict:
    """docs/benchmarks.md's generated blocks from the benchmark's JSON file."""
    report = json.loads(JSON_OUT.read_text(encoding="utf-8"))
    return {PAGE: read_blocks(render_page(PAGE.read_text(encoding="utf-8"), report))}
