"""docs/benchmarks.md's generated tables, from the MD benchmark's JSON file.

The benchmark is :mod:`openmm_alphaprk.benchmarks.md_sweep` (the sweep of
``docs/sweeps/md_benchmark.toml``, the analyses of its runs, the figures); run it as::

    python -m openmm_alphaprk.benchmarks.md_sweep docs/sweeps/md_benchmark.toml \
        --json docs/data/benchmarks/benchmarks.json --figures docs/figures [--run]

It writes ``docs/data/benchmarks/benchmarks.json``; ``python -m tools.reports`` renders the
page's tables from it (:func:`render`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from openmm_alphaprk.benchmarks.md_sweep.results import LABELS, STABLE_MAX_PER_DOF, SYSTEMS
from tools.reports.markdown import Column, table
from tools.reports.sources import DATA, DOCS, provenance_line, source

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


def _controller(title: str, key: str, show: Callable[[dict], str] | str) -> Column:
    """Return a column of the controller's ``key``, written by ``show`` as a column's cell; "—" without it."""
    column = Column(title, show)
    return Column(title, lambda e: column.text(e) if key in e.get("controller", {}) else "—")


#: The energy table's columns (a failed run: its label and error, the other cells empty).
ENERGY_COLUMNS = [
    Column("integrator", "{label}"),
    Column("evals/step", "{force_evaluations_per_step:.2f}"),
    Column("time/step ÷ RATTLE 2 fs", "{timing[time_per_step_ratio]:.2f}"),
    Column("time/ps ÷ RATTLE 2 fs", "{timing[time_per_ps_ratio]:.2f}"),
    Column("ns/day", "{timing[ns_per_day]:.3g}"),
    Column("sweep ns/day", "{sweep_ns_per_day:.3g}"),
    Column("RMS(H − E_ref) kJ/mol", lambda e: fmt(e["rms_residual"])),
    Column("max", lambda e: fmt(e["max_abs_residual"])),
    Column("drift kJ/mol/ns/DOF", lambda e: fmt(e["drift_per_dof"], 2)),
    _controller(
        "α* p5/p50/p95",
        "alpha_percentiles.p50",
        "/".join(f"{{controller[alpha_percentiles.{p}]:.2f}}" for p in ("p5", "p50", "p95")),
    ),
    _controller(
        "within tol.",
        "fraction_within_tolerance",
        lambda e: f"{100 * e['controller']['fraction_within_tolerance']:.0f} %",
    ),
    _controller(
        "at bound", "fraction_at_bound", lambda e: f"{100 * e['controller']['fraction_at_bound']:.1f} %"
    ),
]


def energy_markdown(system: str, entries: list[dict]) -> str:
    """Render the Markdown table of energy error and cost (a failed run: its label and error)."""
    first = entries[0]
    caption = (
        f"**{system}**: {first.get('n_atoms', '?')} atoms, {first.get('degrees_of_freedom', '?')} DOF, "
        f"{fmt(first.get('simulated_ps', float('nan')))} ps per run, from the same equilibrated start."
    )

    def cells(e: dict) -> list[str]:
        if "error" in e:
            return [e["label"], f"failed: {e['error'][:80]}"] + [""] * (len(ENERGY_COLUMNS) - 2)
        return [c.text(e) for c in ENERGY_COLUMNS]

    columns = [Column(c.title, lambda r, i=i: r[i]) for i, c in enumerate(ENERGY_COLUMNS)]
    return table(map(cells, entries), columns, caption)


DYNAMICS_COLUMNS = [
    Column("run", lambda e: e["label"]),
    Column("RMS Δg(r), 2.4–8 Å", lambda e: f"{e['rdf_rms_difference']:.3f}"),
    Column("g(r) first peak", lambda e: f"{e['rdf_first_peak']:.2f}"),
    Column("D (1e-5 cm²/s)", lambda e: f"{e['diffusion']:.2f} ± {e['diffusion_error']:.2f}"),
    Column("ΔD vs reference", lambda e: f"{100 * e['diffusion_relative_difference']:+.0f} %"),
    Column("spectrum distance 0–1200 cm⁻¹", lambda e: fmt(e.get("spectrum_difference", float("nan")))),
    Column("libration centroid (cm⁻¹)", lambda e: fmt(e.get("libration_centroid", float("nan")), 4)),
    Column("shift", lambda e: f"{e.get('libration_centroid_shift', float('nan')):+.1f}"),
]


def dynamics_markdown(system: str, entries: list[dict], reference_label: str) -> str:
    """Render the Markdown table of RDF, D and spectrum against the reference."""
    return table(entries, DYNAMICS_COLUMNS, f"**{system}** against {reference_label} (start velocities):")


def _scan_cell(cell: dict | None) -> str:
    """Write a scan cell: max|H − E_ref| per DOF, marked if unstable; ✗ for a failed run."""
    if cell is None:
        return ""
    if cell["status"] != "ok":
        return "✗"
    return f"{cell['max_abs_residual_per_dof']:.1e}" + ("" if cell["stable"] else " (unstable)")


def _largest(cells: dict) -> str:
    """Write the largest stable step of a scanned integrator."""
    largest = cells["largest_stable_fs"]
    if sum(1 for s in cells if s[0].isdigit()) == 1:
        return "not scanned"
    if largest is not None and largest == cells["scanned_to_fs"]:
        return f"≥ {largest:g} fs (scan end)"
    return "none" if largest is None else f"{largest:g} fs"


def scan_markdown(system: str, scan: dict) -> str:
    """Render the Markdown table of the step-size scan."""
    steps = sorted({s for cells in scan.values() for s in cells if s[0].isdigit()}, key=float)
    columns = [
        Column("integrator", lambda r: LABELS[r[0]]),
        *(Column(f"{s} fs", lambda r, s=s: _scan_cell(r[1].get(s))) for s in steps),
        Column("largest stable step", lambda r: _largest(r[1])),
    ]
    caption = (
        f"**{system}**: max|H − E_ref| per DOF (kJ/mol) over the run; ✗ = the run failed (NaN or failed "
        "midpoint iteration); stable = finished with max|H − E_ref| per DOF < "
        f"{STABLE_MAX_PER_DOF} kJ/mol."
    )
    return table(scan.items(), columns, caption)


def blocks(report: dict) -> dict[str, str]:
    """Return the page's generated blocks from the benchmark's report, by name."""
    environment = report["environment"]
    run = (
        "the MD benchmark (today `python -m openmm_alphaprk.benchmarks.md_sweep`) over the sweep "
        "`docs/sweeps/md_benchmark.toml`, "
        f"{environment['platform']} platform, OpenMM {environment['openmm']}"
    )
    found = {"provenance": provenance_line([source("benchmarks/benchmarks.json")], run)}
    for system in SYSTEMS:
        energy, dynamics, scan = (report[part][system] for part in ("energy", "dynamics", "scan"))
        if energy:
            found[f"energy {system}"] = energy_markdown(system, energy)
        if dynamics:
            found[f"dynamics {system}"] = dynamics_markdown(system, dynamics, report["reference"])
        if scan:
            found[f"scan {system}"] = scan_markdown(system, scan)
    return found


def render() -> dict[Path, dict[str, str]]:
    """docs/benchmarks.md's generated blocks from the benchmark's JSON file."""
    return {PAGE: blocks(json.loads(JSON_OUT.read_text(encoding="utf-8")))}
