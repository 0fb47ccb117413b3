"""The MD benchmark's figures (``benchmark_*.png``), from the sweep's runs and the report.

:func:`figures` draws them all into a folder; each ``figure_*`` function draws one and
returns its path as ``FOLDER_NAME/FILE`` (the page beside the folder links it so).
Matplotlib is imported when they are drawn.
"""

from __future__ import annotations

from pathlib import Path

from openmm_alphaprk.observables import rms

from .analysis import analyse_run
from .results import (
    ENERGY_ROWS,
    LABELS,
    REFERENCE,
    STABLE_MAX_PER_DOF,
    SYSTEMS,
    get,
    run_label,
)


def _save(fig, folder: Path, name: str, rect: tuple[float, float, float, float] = (0, 0, 1, 1)) -> str:
    """Lay out, write and close a figure; return ``FOLDER_NAME/name``."""
    import matplotlib.pyplot as plt

    fig.tight_layout(rect=rect)
    fig.savefig(folder / name, dpi=120)
    plt.close(fig)
    return f"{folder.name}/{name}"


def figure_energy(rows, systems: list[str], folder: Path) -> str:
    """Plot H − E_ref against time, one panel per system: RMS over 0.2 ps windows, log scale."""
    import matplotlib.pyplot as plt

    from openmm_alphaprk.runs import rundir

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
            block_rms = rms(residual[:n].reshape(-1, window), axis=1)
            times = energies[1 : n + 1, 1].reshape(-1, window).mean(axis=1)
            ax.plot(times, block_rms, lw=0.9, label=run_label(integrator, step))
        ax.set_yscale("log")
        ax.set_title(system)
        ax.set_ylabel("RMS(H − E_ref) per 0.2 ps (kJ/mol)")
    axes[-1, 0].set_xlabel("time (ps)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7)
    return _save(fig, folder, "benchmark_energy.png", rect=(0, 0.07, 1, 1))


def figure_cost_accuracy(report: dict, systems: list[str], folder: Path) -> str:
    """Plot the accuracy (RMS of H − E_ref) against the cost (time per ps), one panel per system."""
    import matplotlib.pyplot as plt

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
    return _save(fig, folder, "benchmark_cost_accuracy.png")


def figure_dynamics(rows, systems: list[str], folder: Path) -> str:
    """Plot the O–O RDF and the water-H spectrum of every main run, the reference in black."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(systems), figsize=(4.2 * len(systems), 6.5), squeeze=False)
    for column, system in enumerate(systems):
        for integrator, step in ENERGY_ROWS:
            row = get(rows, system, integrator, step)
            if row is None or row["status"] != "ok":
                continue
            analysis = analyse_run(Path(row["run_dir"]))
            style = dict(lw=1.8, color="k") if (integrator, step) == REFERENCE else dict(lw=0.8)
            name = run_label(integrator, step)
            axes[0, column].plot(analysis["rdf_r"], analysis["rdf_g"], label=name, **style)
            if "spectrum" in analysis:
                axes[1, column].plot(analysis["frequencies"], analysis["spectrum"], **style)
        axes[0, column].set_xlabel("r (Å)")
        axes[0, column].set_ylabel("g_OO(r)")
        axes[0, column].set_title(system)
        axes[1, column].set_xlim(0, 1500)
        axes[1, column].set_xlabel("wavenumber (cm⁻¹)")
        axes[1, column].set_ylabel("water-H VACF spectrum")
    axes[0, 0].legend(fontsize=6)
    return _save(fig, folder, "benchmark_dynamics.png")


def figure_step_scan(scans: dict[str, dict], folder: Path) -> str:
    """Plot max|H − E_ref| per DOF against the step of every scanned integrator; × marks a failed run."""
    import matplotlib.pyplot as plt

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
    return _save(fig, folder, "benchmark_step_scan.png")


def figures(rows, report: dict, folder: Path) -> list[str]:
    """Write the figures into ``folder``; return their paths as ``FOLDER_NAME/FILE``."""
    import matplotlib

    matplotlib.use("Agg")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    systems = [s for s in SYSTEMS if report["energy"].get(s)]
    written = [
        figure_energy(rows, systems, folder),
        figure_cost_accuracy(report, systems, folder),
        figure_dynamics(rows, systems, folder),
    ]
    scans = {s: report["scan"][s] for s in SYSTEMS if report["scan"].get(s)}
    if scans:
        written.append(figure_step_scan(scans, folder))
    return written
