r"""Regenerate every table and figure of docs/benchmarks.md from the MD benchmark sweep.

Run from the repository root::

    python docs/scripts/md_benchmark_report.py --run

``--run`` first runs (or completes) the sweep ``docs/sweeps/md_benchmark.toml`` with the
sweep runner (``alphaprk sweep``; finished cells are skipped), then analyses every run
directory with MDAnalysis (O–O RDF, diffusion coefficient, H velocity-autocorrelation
spectrum; cached per run in ``md_benchmark_analysis.json``), and writes

- ``docs/benchmarks.json``: every number of the page,
- ``docs/figures/benchmark_*.png``: the figures,
- the generated tables of ``docs/benchmarks.md`` (between ``<!-- generated: NAME -->``
  and ``<!-- end generated: NAME -->``; the prose around them is written by hand).

Without ``--run`` it reports on the cells finished so far.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "docs" / "sweeps" / "md_benchmark.toml"
PAGE = ROOT / "docs" / "benchmarks.md"
JSON_OUT = ROOT / "docs" / "benchmarks.json"
FIGURES = ROOT / "docs" / "figures"
ANALYSIS_FILE = "md_benchmark_analysis.json"
ANALYSIS_VERSION = 1

SYSTEMS = ("tip3p-2nm", "tip3p-3nm", "villin")
#: Rows of the energy table, in order: (integrator, step in fs).
ENERGY_ROWS = (
    ("rattle", 2.0),
    ("rattle", 1.0),
    ("rattle", 2 / 3),
    ("rattle", 0.5),
    ("verlet", 2.0),
    ("alpha=1/6", 2.0),
    ("alpha4=0", 2.0),
    ("energy", 2.0),
    ("energy4", 2.0),
)
REFERENCE = ("rattle", 0.5)  # small-step dynamics the others are compared with
LABELS = {
    "rattle": "RATTLE",
    "verlet": "VerletIntegrator",
    "alpha=1/6": "α-RATTLE α = 1/6",
    "alpha4=0": "α-RATTLE-4 α = 0",
    "energy": "α-RATTLE energy mode",
    "energy4": "α-RATTLE-4 energy mode",
}
WATER_O = "resname HOH and name O"
WATER_H = "resname HOH and name H1 H2"
RDF_RANGE = (0.0, 8.0)  # Å
RDF_BINS = 80
RDF_COMPARE = (2.4, 8.0)  # Å: where g(r) is compared (below 2.4 Å it is zero)
BANDS = {"translation": (0.0, 300.0), "libration": (300.0, 1100.0)}  # cm⁻¹
SPECTRUM_COMPARE = (0.0, 1200.0)  # cm⁻¹
#: A scan cell counts as stable if it finished and max|H − E_ref| per DOF stayed below this (kJ/mol).
STABLE_MAX_PER_DOF = 0.05


def label(integrator: str, step_fs: float) -> str:
    """Return a row label such as ``RATTLE 2/3 fs``."""
    step = "2/3" if abs(step_fs - 2 / 3) < 1e-9 else f"{step_fs:g}"
    return f"{LABELS.get(integrator, integrator)} {step} fs"


def load_rows(config) -> dict[tuple[str, str, float, str], dict]:
    """Return the rows of finished and failed cells, keyed by (system, integrator, step, seed).

    The rows are those of the sweep table, read from the run directories, so that a
    report can be made while the sweep still runs.
    """
    from openmm_alphaprk.sweep import cell_status

    rows = {}
    for cell in config.cells:
        row = cell_status(cell, config.output / cell.name)
        if row is not None:
            key = (row["system"], row["integrator"], round(float(row["timestep_fs"]), 6), str(row["seed"]))
            rows[key] = row
    if not rows:
        raise SystemExit(f"no finished cells under {config.output}: run with --run first.")
    return rows


def get(rows, system, integrator, step_fs, seed=""):
    """Return the row of a cell, or None."""
    return rows.get((system, integrator, round(step_fs, 6), seed))


def number(row: dict, key: str) -> float:
    """Return a float column of a row (NaN when empty or missing)."""
    value = row.get(key, "")
    return float(value) if value not in ("", None) else float("nan")


# ---------------------------------------------------------------- dynamics analyses


def analyse_run(directory: Path) -> dict:
    """O–O RDF, diffusion of water O and the water-H VACF spectrum of one run (cached in the run dir)."""
    cache = directory / ANALYSIS_FILE
    if cache.is_file():
        stored = json.loads(cache.read_text(encoding="utf-8"))
        if stored.get("version") == ANALYSIS_VERSION:
            return stored
    import MDAnalysis as mda

    from openmm_alphaprk.analysis import Diffusion, VelocityAutocorrelation, band_summary
    from openmm_alphaprk.analysis.structure import oxygen_rdf

    warnings.filterwarnings("ignore", category=DeprecationWarning)
    result: dict = {"version": ANALYSIS_VERSION}
    topology = str(directory / "topology.pdb")
    positions = mda.Universe(topology, str(directory / "trajectory.dcd"))
    rdf = oxygen_rdf(positions, select=WATER_O, nbins=RDF_BINS, r_max=RDF_RANGE[1])
    result["rdf_r"] = rdf.results.bins.tolist()
    result["rdf_g"] = rdf.results.rdf.tolist()
    msd = Diffusion(positions, select=WATER_O).run()
    result["diffusion"] = float(msd.results.diffusion_coefficient)
    # Error of D: the spread of D over 4 disjoint groups of molecules, / sqrt(4).
    oxygens = positions.select_atoms(WATER_O)
    groups = [oxygens[i::4] for i in range(4)]
    d_groups = [
        float(
            Diffusion(positions, select="index " + " ".join(map(str, g.indices)))
            .run()
            .results.diffusion_coefficient
        )
        for g in groups
    ]
    result["diffusion_error"] = float(np.std(d_groups, ddof=1) / np.sqrt(len(groups)))
    velocities_file = directory / "velocities.dcd"
    if velocities_file.is_file():
        velocities = mda.Universe(topology, str(velocities_file))
        vacf = VelocityAutocorrelation(velocities, select=WATER_H, max_lag=1.0).run()
        result["frequencies"] = vacf.results.frequencies.tolist()
        result["spectrum"] = vacf.results.spectrum.tolist()
        result["bands"] = {
            name: band_summary(vacf.results.frequencies, vacf.results.spectrum, low, high)
            for name, (low, high) in BANDS.items()
        }
    cache.write_text(json.dumps(result) + "\n", encoding="utf-8")
    return result


def compare_dynamics(run: dict, reference: dict) -> dict:
    """Differences of RDF, D and spectrum of a run from the reference run."""
    from openmm_alphaprk.analysis import spectrum_difference

    r = np.asarray(run["rdf_r"])
    window = (r >= RDF_COMPARE[0]) & (r <= RDF_COMPARE[1])
    g, g_ref = np.asarray(run["rdf_g"]), np.asarray(reference["rdf_g"])
    out = {
        "rdf_rms_difference": float(np.sqrt(np.mean((g[window] - g_ref[window]) ** 2))),
        "rdf_first_peak": float(g[window].max()),
        "diffusion": run["diffusion"],
        "diffusion_error": run["diffusion_error"],
        "diffusion_relative_difference": run["diffusion"] / reference["diffusion"] - 1.0,
    }
    if "spectrum" in run and "spectrum" in reference:
        out["spectrum_difference"] = spectrum_difference(
            np.asarray(run["frequencies"]),
            np.asarray(run["spectrum"]),
            np.asarray(reference["frequencies"]),
            np.asarray(reference["spectrum"]),
            *SPECTRUM_COMPARE,
        )
        out["libration_centroid"] = run["bands"]["libration"]["centroid"]
        out["libration_centroid_shift"] = (
            run["bands"]["libration"]["centroid"] - reference["bands"]["libration"]["centroid"]
        )
        out["libration_weight"] = run["bands"]["libration"]["weight"]
    return out


# ---------------------------------------------------------------- timing


def timing_table(system: str, steps: int = 30, rounds: int = 3) -> dict[str, dict]:
    """Time every integrator of the energy table on one system in interleaved rounds (this process).

    The sweep's cells ran one after another, each timing itself, while other work may have
    shared the machine; interleaving the integrators round by round puts such load on all
    of them alike, so the ratios to RATTLE 2 fs are the numbers to read. Median ms/step of
    ``rounds`` rounds of ``steps`` steps from the equilibrated start, CPU platform.
    """
    import openmm as mm

    from openmm_alphaprk.benchmarks.cost import interleaved_timing
    from openmm_alphaprk.integrator_specs import make_integrator
    from openmm_alphaprk.systems import prepare_system

    prepared = prepare_system(system, progress=False)
    platform = mm.Platform.getPlatformByName("CPU")
    runs = {}
    for integrator_name, step in ENERGY_ROWS:
        integrator = make_integrator(integrator_name, step / 1000.0, 1e-8)
        context = mm.Context(prepared.system, integrator, platform)
        context.setState(prepared.state)
        integrator.step(2)  # program analysis, first forces
        runs[label(integrator_name, step)] = (integrator, context, step)
    medians = interleaved_timing(
        {name: (integrator, 1) for name, (integrator, _context, _step) in runs.items()}, steps, rounds
    )
    baseline = medians[label("rattle", 2.0)]
    table = {}
    for name, (_integrator, _context, step) in runs.items():
        ms = medians[name]
        table[name] = {
            "ms_per_step": ms,
            "time_per_step_ratio": ms / baseline,
            "time_per_ps_ratio": ms / baseline * 2.0 / step,
            "ns_per_day": step * 1e-6 / (ms * 1e-3) * 86400.0,
        }
    return table


# ---------------------------------------------------------------- tables


def energy_table(rows, system: str, timing: dict[str, dict]) -> list[dict]:
    """Energy, cost and controller numbers of one system's main runs (start velocities)."""
    base = get(rows, system, "rattle", 2.0)
    if base is None or base["status"] != "ok":
        return []
    base_time = number(base, "wall_seconds") / number(base, "steps_this_call")
    out = []
    for integrator, step in ENERGY_ROWS:
        row = get(rows, system, integrator, step)
        if row is None:
            continue
        entry = {"label": label(integrator, step), "integrator": integrator, "timestep_fs": step}
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
                key.split(".", 1)[1]: number(row, key) for key in row if key.startswith("controller.")
            }
        out.append(entry)
    return out


def dynamics_table(rows, system: str) -> list[dict]:
    """Dynamics of every main run of a system against the small-step reference."""
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
        out.append({"label": label(integrator, step), **compare_dynamics(analysis, reference)})
    # independent starts (seeds): the statistical spread the differences are to be read against
    for seed in ("1", "2"):
        for integrator, step in (("rattle", 0.5), ("rattle", 2.0), ("energy4", 2.0)):
            row = get(rows, system, integrator, step, seed)
            if row is None or row["status"] != "ok":
                continue
            analysis = analyse_run(Path(row["run_dir"]))
            out.append(
                {"label": f"{label(integrator, step)}, seed {seed}", **compare_dynamics(analysis, reference)}
            )
    return out


def scan_table(rows, system: str) -> dict:
    """Step-size scan: per integrator and step, finished or not and max|H − E_ref| per DOF."""
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


# ---------------------------------------------------------------- markdown


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
    """Markdown table of energy error and cost."""
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
    """Markdown table of RDF, D and spectrum against the reference."""
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
    """Markdown table of the step-size scan."""
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


def replace_generated(page: str, name: str, content: str) -> str:
    """Replace the text between the markers of a generated block (the markers must exist)."""
    begin, end = f"<!-- generated: {name} -->\n", f"<!-- end generated: {name} -->"
    pattern = re.compile(re.escape(begin) + r"(.*?)" + re.escape(end), re.S)
    if not pattern.search(page):
        raise SystemExit(f"{PAGE} has no markers for the generated block {name!r}.")
    return pattern.sub(lambda _: begin + content.rstrip("\n") + "\n" + end, page)


# ---------------------------------------------------------------- figures


def _save(fig, name: str, rect: tuple[float, float, float, float] = (0, 0, 1, 1)) -> str:
    """Lay out, write and close a figure; return its path relative to docs/."""
    import matplotlib.pyplot as plt

    fig.tight_layout(rect=rect)
    fig.savefig(FIGURES / name, dpi=120)
    plt.close(fig)
    return f"figures/{name}"


def figures(rows, report: dict) -> list[str]:
    """Write the figures; return their paths relative to docs/."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from openmm_alphaprk import rundir

    written = []
    FIGURES.mkdir(parents=True, exist_ok=True)

    # 1. H − E_ref against time, one panel per system: RMS over 0.2 ps windows, log scale
    systems = [s for s in SYSTEMS if report["energy"].get(s)]
    fig, axes = plt.subplots(len(systems), 1, figsize=(8, 2.8 * len(systems)), squeeze=False)
    for ax, system in zip(axes[:, 0], systems):
        for integrator, step in ENERGY_ROWS:
            row = get(rows, system, integrator, step)
            if row is None or row["status"] != "ok" or integrator == "verlet":
                continue
            energies = rundir.read_energies(Path(row["run_dir"]) / rundir.ENERGIES_FILE)
            residual = energies[1:, 4] - energies[0, 4]
            window = 10  # samples of 20 fs
            n = residual.size // window * window
            rms = np.sqrt(np.mean(residual[:n].reshape(-1, window) ** 2, axis=1))
            times = energies[1 : n + 1, 1].reshape(-1, window).mean(axis=1)
            ax.plot(times, rms, lw=0.9, label=label(integrator, step))
        ax.set_yscale("log")
        ax.set_title(system)
        ax.set_ylabel("RMS(H − E_ref) per 0.2 ps (kJ/mol)")
    axes[-1, 0].set_xlabel("time (ps)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7)
    written.append(_save(fig, "benchmark_energy.png", rect=(0, 0.07, 1, 1)))

    # 2. accuracy against cost
    fig, axes = plt.subplots(1, len(systems), figsize=(4.2 * len(systems), 3.8), squeeze=False)
    for ax, system in zip(axes[0], systems):
        entries = [e for e in report["energy"][system] if "error" not in e and e["integrator"] != "verlet"]
        entries = [
            e | {"time_per_ps_ratio": e["timing"]["time_per_ps_ratio"]} for e in entries if e["timing"]
        ]
        if not entries:  # no timing yet (--no-timing on a first report)
            continue
        rattle = sorted(
            (e for e in entries if e["integrator"] == "rattle"), key=lambda e: e["time_per_ps_ratio"]
        )
        ax.plot(
            [e["time_per_ps_ratio"] for e in rattle],
            [e["rms_residual"] for e in rattle],
            "k.-",
            label="RATTLE 2, 1, 2/3, 1/2 fs",
        )
        for e in entries:
            if e["integrator"] != "rattle":
                ax.plot(e["time_per_ps_ratio"], e["rms_residual"], "o", label=e["label"])
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time per ps ÷ RATTLE 2 fs")
        ax.set_ylabel("RMS(H − E_ref) (kJ/mol)")
        ax.set_title(system)
    axes[0, 0].legend(fontsize=7)
    written.append(_save(fig, "benchmark_cost_accuracy.png"))

    # 3. RDF and spectra against the reference
    fig, axes = plt.subplots(2, len(systems), figsize=(4.2 * len(systems), 6.5), squeeze=False)
    for column, system in enumerate(systems):
        for integrator, step in ENERGY_ROWS:
            row = get(rows, system, integrator, step)
            if row is None or row["status"] != "ok":
                continue
            analysis = analyse_run(Path(row["run_dir"]))
            style = dict(lw=1.8, color="k") if (integrator, step) == REFERENCE else dict(lw=0.8)
            axes[0, column].plot(analysis["rdf_r"], analysis["rdf_g"], label=label(integrator, step), **style)
            if "spectrum" in analysis:
                axes[1, column].plot(analysis["frequencies"], analysis["spectrum"], **style)
        axes[0, column].set_xlabel("r (Å)")
        axes[0, column].set_ylabel("g_OO(r)")
        axes[0, column].set_title(system)
        axes[1, column].set_xlim(0, 1500)
        axes[1, column].set_xlabel("wavenumber (cm⁻¹)")
        axes[1, column].set_ylabel("water-H VACF spectrum")
    axes[0, 0].legend(fontsize=6)
    written.append(_save(fig, "benchmark_dynamics.png"))

    # 4. step-size scan
    scans = {s: report["scan"][s] for s in SYSTEMS if report["scan"].get(s)}
    if not scans:
        return written
    fig, axes = plt.subplots(1, len(scans), figsize=(4.5 * len(scans), 3.6), squeeze=False)
    for ax, (system, scan) in zip(axes[0], scans.items()):
        for integrator, cells in scan.items():
            steps = sorted((s for s in cells if s[0].isdigit()), key=float)
            ok = [
                (float(s), cells[s]["max_abs_residual_per_dof"]) for s in steps if cells[s]["status"] == "ok"
            ]
            failed = [float(s) for s in steps if cells[s]["status"] != "ok"]
            line = ax.plot(*zip(*ok), "o-", label=LABELS[integrator])[0] if ok else None
            if failed:
                ax.plot(failed, [1.0] * len(failed), "x", color=line.get_color() if line else "k", ms=9)
        ax.axhline(STABLE_MAX_PER_DOF, color="grey", ls=":", lw=1)
        ax.set_yscale("log")
        ax.set_xlabel("step (fs)")
        ax.set_ylabel("max|H − E_ref| per DOF (kJ/mol); × = failed")
        ax.set_title(system)
    axes[0, 0].legend(fontsize=7)
    written.append(_save(fig, "benchmark_step_scan.png"))
    return written


def main(argv: list[str] | None = None) -> int:
    """Run (optionally) the sweep, then write the JSON, the figures and the page's tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", action="store_true", help="run the sweep first (finished cells are skipped)")
    parser.add_argument("--workers", type=int, default=None, help="local dask workers for --run")
    parser.add_argument(
        "--no-timing", action="store_true", help="skip the interleaved timing (keep the JSON's last timings)"
    )
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from openmm_alphaprk.sweep import load_config, run_sweep

    config = load_config(CONFIG)
    if args.run:
        run_sweep(config, n_workers=args.workers)
    rows = load_rows(config)
    report = {"energy": {}, "dynamics": {}, "scan": {}, "timing": {}, "reference": label(*REFERENCE)}
    previous = (
        json.loads(JSON_OUT.read_text(encoding="utf-8")).get("timing", {}) if JSON_OUT.is_file() else {}
    )
    for system in SYSTEMS:
        if args.no_timing or get(rows, system, "rattle", 2.0) is None:
            report["timing"][system] = previous.get(system, {})
        else:
            print(f"timing {system} (interleaved rounds)", file=sys.stderr)
            report["timing"][system] = timing_table(system)
        report["energy"][system] = energy_table(rows, system, report["timing"][system])
        report["dynamics"][system] = dynamics_table(rows, system)
        report["scan"][system] = scan_table(rows, system)
    report["figures"] = figures(rows, report)
    import openmm

    report["environment"] = {
        "openmm": openmm.__version__,
        "platform": "CPU",
        "machine": "2-core development machine",
    }
    JSON_OUT.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")

    page = PAGE.read_text(encoding="utf-8")
    for system in SYSTEMS:
        if report["energy"][system]:
            page = replace_generated(
                page, f"energy {system}", energy_markdown(system, report["energy"][system])
            )
        if report["dynamics"][system]:
            page = replace_generated(
                page,
                f"dynamics {system}",
                dynamics_markdown(system, report["dynamics"][system], report["reference"]),
            )
        if report["scan"][system]:
            page = replace_generated(page, f"scan {system}", scan_markdown(system, report["scan"][system]))
    PAGE.write_text(page, encoding="utf-8")
    print(
        f"wrote {JSON_OUT.relative_to(ROOT)}, {len(report['figures'])} figures, "
        f"tables in {PAGE.relative_to(ROOT)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
