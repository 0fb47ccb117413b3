"""The figures of docs/validation.md (``docs/figures/validation_*.png``), drawn from the JSON data."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from openmm_alphaprk.benchmarks.validation.methods import FD_FLOOR


def _slope_label(label: str, order: float) -> str:
    return f"{label} (slope {order:.2f})"


def figure_convergence(data: dict, path: Path) -> None:
    """Plot the error against h, log-log, with fitted slopes: three panels."""
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
    """Plot the symplecticity defect against h (pendulum) and per method (3 waters)."""
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
    """Plot |α*| against h (reference) and histograms of α* on the 774-atom box (OpenMM)."""
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
    """Plot |ΔL|, |ΔP| (scaled), constraint error and H − E_ref against time (Reference solid, CPU dashed)."""
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


def write_figures(data: dict, folder: Path) -> None:
    """Draw the four figures into ``folder`` (created if missing) as ``validation_*.png``."""
    folder.mkdir(parents=True, exist_ok=True)
    figure_convergence(data, folder / "validation_convergence.png")
    figure_symplecticity(data, folder / "validation_symplecticity.png")
    figure_alpha_star(data, folder / "validation_alpha_star.png")
    figure_long_runs(data, folder / "validation_long_runs.png")
