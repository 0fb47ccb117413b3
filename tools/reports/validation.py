r"""docs/validation.md: run :mod:`openmm_alphaprk.benchmarks.validation`, draw and tabulate it.

Run from the repository root::

    python -m tools.reports.validation           # run it, rewrite the JSON, figures and tables
    python -m tools.reports.validation --quick   # smaller runs into a scratch folder (1 minute)

The experiment is the package's; this writes its JSON to ``docs/data/validation/``, the
figures ``docs/figures/validation_*.png`` and the page's tables (:func:`render_tables`, also
checked by ``python -m tools.reports --check``). ``--quick`` writes to a scratch folder
unless paths are given, so that it never overwrites the page's numbers.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from openmm_alphaprk.benchmarks.validation import compute, dump_json
from openmm_alphaprk.benchmarks.validation.methods import FD_FLOOR
from tools.reports.markdown import Column, series, table, update_page
from tools.reports.sources import DATA, DOCS, provenance_line, source

#: The validation's data, under docs/data/.
JSON = "validation/validation.json"


# ------------------------------------------------------------------ the tables
def sci(value: float, digits: int = 2) -> str:
    """Format in scientific notation, ``digits`` after the point, no leading zeros in the exponent."""
    if value == 0:
        return "0"
    return f"{value:.{digits}e}".replace("e-0", "e-").replace("e+0", "e")


def _or_dash(key: str, show: Callable) -> Callable:
    """Return a cell showing ``show(row[key])``, or "—" where the row has nothing under ``key``."""
    return lambda r: "—" if r.get(key) is None else show(r[key])


def render_tables(data: dict) -> dict[str, str]:
    """Render the Markdown tables of the page from the JSON data (the page must hold exactly these)."""
    conv, sym = data["convergence"], data["symplecticity"]
    period, spring, water = conv["pendulum_period"], conv["spring_pendulum"], conv["water_cluster"]
    box = data["alpha_star_openmm"]["runs"]
    long_runs = data["long_runs"]
    run = (
        f"the numerical validation, run as `{data['command']}` (today "
        f"`python -m openmm_alphaprk.benchmarks.validation`); {data['machine']}"
    )
    method = Column("method", "{label}")
    plain = [period["methods"][k] for k in ("alpha=0", "alpha=1", "energy", "alpha4=0", "energy4")]
    plain_columns = [
        method,
        *series([f"max \\|H − H₀\\|, h = T/{n}" for n in period["counts"]], "max_energy_error", sci),
        Column("steps without root", _or_dash("fraction_of_steps_without_root", "{:.0%}".format)),
    ]
    orders = [
        {**s, "p": period["methods"][k], "w": water["methods"][k]} for k, s in spring["methods"].items()
    ]
    orders_columns = [
        method,
        Column("plain pendulum, period error", "{p[fitted_order]:.2f}"),
        Column(
            "max difference from α = 0 (same order)",
            lambda r: sci(r["p"]["max_difference_from_alpha_zero"], 1),
        ),
        Column("spring pendulum", "{fitted_order:.2f}"),
        Column(f"spring pendulum: error / RATTLE's at h = {spring['h'][1]:g}", "{error_over_rattle[1]:.2g}"),
        Column("3 waters: fitted", "{w[fitted_order]:.2f}"),
        Column("3 waters: finest pair", lambda r: f"{r['w']['local_orders'][-1]:.2f}"),
        Column(
            f"3 waters: error / RATTLE's at h = {water['h'][1] * 1000:g} fs", "{w[error_over_rattle][1]:.2g}"
        ),
    ]
    water_columns = [method, *series([f"h = {h * 1000:g} fs" for h in water["h"]], "errors", sci)]
    pendulum = sym["spring_pendulum"]
    defects = [{**e, "water": sym["water_cluster"]["methods"][k]} for k, e in pendulum["methods"].items()]
    defect_columns = [
        method,
        *series([f"pendulum h = {h:g}" for h in pendulum["h"]], "defects", lambda d: sci(d, 1)),
        Column(
            "slope (above 1e-7)",
            lambda r: "floor" if r["fitted_order"] is None else f"{r['fitted_order']:.1f}",
        ),
        Column("3 waters, 10 × 2 fs", lambda r: sci(r["water"]["defect"], 1)),
    ]
    alpha_star = [
        {
            "problem": problem,
            "mode": entry["label"],
            "h": f"{h * scale:g}{unit}",
            **{key: values[i] for key, values in entry["alpha_star"].items()},
        }
        for problem, study, scale, unit in (
            ("spring pendulum", spring, 1.0, ""),
            ("3 waters", water, 1000.0, " fs"),
        )
        for entry in (study["methods"]["energy"], study["methods"]["energy4"])
        for i, h in enumerate(study["h"])
    ]
    alpha_star_columns = [
        Column("problem", "{problem}"),
        Column("mode", "{mode}"),
        Column("h", "{h}"),
        Column("median \\|α*\\|", "{median_abs:.3g}"),
        Column("90th pct \\|α*\\|", "{p90_abs:.3g}"),
        Column("max \\|α*\\|", "{max_abs:.3g}"),
        Column("steps without root", "{fraction_at_bound:.0%}"),
    ]
    percentiles = ("p1", "p5", "p25", "p50", "p75", "p95", "p99")
    box_alpha_columns = [
        Column("integrator", "{name}"),
        *(Column(p, f"{{alpha_percentiles[{p}]:.3g}}") for p in percentiles),
        Column("median \\|α*\\|", "{median_abs_alpha:.3g}"),
        Column("steps at a bound", "{controller[fraction_at_bound]:.1%}"),
        Column("steps not within 0.01 kJ/mol", "{controller[fraction_fallen_back]:.0%}"),
    ]
    rattle_rms = box["rattle"]["rms_residual"]
    box_columns = [
        Column("integrator", "{name}"),
        Column("h (fs)", "{timestep_fs:.3g}"),
        Column("force evaluations per 2 fs", "{force_evaluations_per_2fs:.2f}"),
        Column("RMS H − E_ref (kJ/mol)", "{rms_residual:.3g}"),
        Column("max \\|H − E_ref\\|", "{max_abs_residual:.3g}"),
        Column("RATTLE's RMS / this RMS", lambda r: f"{rattle_rms / r['rms_residual']:.3g}"),
    ]
    long_rows = [
        {"platform": platform, "name": name, **run}
        for platform, block in long_runs["platforms"].items()
        for name, run in block["runs"].items()
    ]
    long_columns = [
        Column("platform", "{platform}"),
        Column("integrator", "{name}"),
        Column("ps", lambda r: f"{r['steps'] * long_runs['timestep_fs'] / 1000:g}"),
        Column("max \\|ΔL\\| (amu nm²/ps)", lambda r: sci(r["max_angular_change"])),
        Column("/ Σm\\|x\\|\\|v\\|", lambda r: sci(r["max_relative_angular_change"])),
        Column("max \\|ΔP\\| / Σm\\|v\\|", lambda r: sci(r["max_relative_linear_change"])),
        Column(
            "constraint error: start → max",
            lambda r: f"{sci(r['start_constraint_error'])} → {sci(r['max_constraint_error'])}",
        ),
        Column("max \\|v·r\\|/\\|r\\| (nm/ps)", lambda r: sci(r["max_constraint_velocity_error"], 1)),
        Column("RMS H − E_ref (kJ/mol)", "{rms_energy_residual:.3g}"),
        Column("max \\|H − E_ref\\|", "{max_abs_energy_residual:.3g}"),
        Column("force evaluations / step", "{force_evaluations_per_step:.2f}"),
    ]
    return {
        "provenance": provenance_line([source(JSON)], run),
        "headline": render_headline(data),
        "plain_pendulum_energy": table(plain, plain_columns),
        "orders": table(orders, orders_columns),
        "water_errors": table(water["methods"].values(), water_columns),
        "symplecticity": table(defects, defect_columns),
        "alpha_star_h": table(alpha_star, alpha_star_columns),
        "alpha_star_box": table([{"name": n, **box[n]} for n in ("energy", "energy4")], box_alpha_columns),
        "box_energy": table([{"name": n, **run} for n, run in box.items()], box_columns),
        "long_runs": table(long_rows, long_columns),
    }


def render() -> dict[Path, dict[str, str]]:
    """docs/validation.md's tables, from the validation's data."""
    return {DOCS / "validation.md": render_tables(json.loads((DATA / JSON).read_text(encoding="utf-8")))}


def render_headline(data: dict) -> str:
    """Render the summary table: one row per integrator, one column per property."""
    defects = data["symplecticity"]["water_cluster"]["methods"]
    box = data["alpha_star_openmm"]["runs"]
    cluster = data["long_runs"]["platforms"]["Reference"]["runs"]
    openmm_names = {"alpha=0": "rattle", "alpha=1/6": "alpha=1/6", "energy": "energy", "energy4": "energy4"}
    box_names = {"alpha=0": "rattle", "alpha4=0": "alpha4=0", "energy": "energy", "energy4": "energy4"}
    rows = [
        {
            **data["convergence"]["water_cluster"]["methods"][key],
            "defect": defects.get(key, {}).get("defect"),
            "box": box.get(box_names.get(key, "")),
            "cluster": cluster.get(openmm_names.get(key, "")),
        }
        for key in ("alpha=0", "alpha=1/6", "alpha=1", "energy", "alpha4=0", "energy4")
    ]
    columns = [
        Column("integrator", "{label}"),
        Column("order (3 waters)", "{fitted_order:.2f}"),
        Column("error vs RATTLE, 3 waters, 2 fs", "{error_over_rattle[1]:.2g}×"),
        Column("symplecticity defect, 3 waters", _or_dash("defect", lambda d: sci(d, 1))),
        Column(
            "median \\|α*\\| (exact), 3 waters, 2 fs",
            _or_dash("alpha_star", lambda s: f"{s['median_abs'][1]:.2g}"),
        ),
        Column(
            "RMS H − E_ref, 774-atom box, 2 fs (kJ/mol)", _or_dash("box", "{rms_residual:.2g}".format_map)
        ),
        Column(
            "force evaluations / step (box)", _or_dash("box", "{force_evaluations_per_step:.1f}".format_map)
        ),
        Column(
            "max \\|ΔL\\| / Σm\\|x\\|\\|v\\|, 222-atom cluster (Reference)",
            _or_dash("cluster", lambda c: sci(c["max_relative_angular_change"], 1)),
        ),
    ]
    return table(rows, columns)


# ------------------------------------------------------------------ the figures
def _log_axes(ax, hs, xlabel: str, ylabel: str, title: str, legend: float) -> None:
    """Label a log-log plot against h, one tick per step size."""
    ax.set_xticks(hs, [f"{h:.3g}" for h in hs])
    ax.minorticks_off()
    ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
    ax.legend(fontsize=legend)


def figure_convergence(plt, data: dict):
    """Plot the error against h, log-log, with fitted slopes: three panels."""
    conv = data["convergence"]
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    panels = [
        (conv["pendulum_period"], 1.0, "h", "state error after one exact period", "Plain pendulum (κ = 0)"),
        (conv["spring_pendulum"], 1.0, "h", "state error at t = 2", "Pendulum with a spring (κ = 2)"),
        (conv["water_cluster"], 1000.0, "h (fs)", "RMS position error at 0.2 ps (nm)", "3 rigid waters"),
    ]
    for ax, (study, scale, *labels) in zip(axes, panels):
        hs = np.array(study["h"]) * scale
        for entry in study["methods"].values():
            label = f"{entry['label']} (slope {entry['fitted_order']:.2f})"
            ax.loglog(hs, entry["errors"], "s--" if entry["order"] == 4 else "o-", ms=4, label=label)
        _log_axes(ax, hs, *labels, legend=6.5)
    return fig


def figure_symplecticity(plt, data: dict):
    """Plot the symplecticity defect against h (pendulum) and per method (3 waters)."""
    sym = data["symplecticity"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5))
    hs = sym["spring_pendulum"]["h"]
    for key, entry in sym["spring_pendulum"]["methods"].items():
        style = "s--" if "4" in key else ("x:" if "one-pass" in key else "o-")
        left.loglog(hs, entry["defects"], style, ms=5, label=entry["label"])
    left.axhline(FD_FLOOR, color="k", lw=0.8, ls="--", label="finite-difference floor (slopes fitted above)")
    left.set_xticks(hs, [f"{h:g}" for h in hs])
    left.minorticks_off()
    left.set(xlabel="h", ylabel="relative change of ω over t = 0.4")
    left.set_title("Pendulum with a spring: symplecticity defect")
    left.legend(fontsize=7)
    methods = sym["water_cluster"]["methods"].values()
    right.barh(range(len(methods)), [entry["defect"] for entry in methods], log=True)
    right.set_yticks(range(len(methods)), [entry["label"] for entry in methods], fontsize=8)
    right.invert_yaxis()
    right.axvline(FD_FLOOR, color="k", lw=0.8, ls="--")
    right.set(xlabel="relative change of ω over 10 steps of 2 fs", title="3 rigid waters")
    return fig


def figure_alpha_star(plt, data: dict):
    """Plot |α*| against h (reference) and histograms of α* on the 774-atom box (OpenMM)."""
    conv = data["convergence"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    panels = [
        (conv["spring_pendulum"], 1.0, "h", "Pendulum with a spring: exact α* per step"),
        (conv["water_cluster"], 1000.0, "h (fs)", "3 rigid waters: exact α* per step"),
    ]
    for ax, (study, scale, xlabel, title) in zip(axes[0], panels):
        hs = np.array(study["h"]) * scale
        for key, color in (("energy", "C0"), ("energy4", "C3")):
            stats, label = study["methods"][key]["alpha_star"], study["methods"][key]["label"]
            ax.loglog(hs, stats["median_abs"], "o-", color=color, label=f"{label}: median |α*|")
            ax.loglog(hs, stats["max_abs"], "^:", color=color, label=f"{label}: max |α*|")
        guide = np.array(study["methods"]["energy4"]["alpha_star"]["median_abs"][0]) * (hs / hs[0]) ** 2
        ax.loglog(hs, guide, "k--", lw=0.8, label="∝ h²")
        _log_axes(ax, hs, xlabel, "|α*|", title, legend=7)
    box = data["alpha_star_openmm"]
    for ax, name in zip(axes[1], ("energy", "energy4")):
        alphas = np.array(box["runs"][name]["alpha"])
        ax.hist(alphas, bins=60, color="C0" if name == "energy" else "C3")
        ax.set(xlabel="α used by the OpenMM controller", ylabel="steps")
        ax.set_title(f"{name}: tip3p-2nm (774 atoms, PME), 2 fs, {alphas.size} steps, CPU")
    return fig


def figure_long_runs(plt, data: dict):
    """Plot |ΔL|, |ΔP| (scaled), constraint error and H − E_ref against time (Reference solid, CPU dashed)."""
    runs = data["long_runs"]
    fig, axes = plt.subplots(2, 2, figsize=(13, 9), sharex=True)
    names = ("rattle", "alpha=1/6", "energy", "energy4", "energy, midpoint 1e-12 nm")
    colors = {name: f"C{i}" for i, name in enumerate(names)}
    for platform_name, block in runs["platforms"].items():
        reference = platform_name == "Reference"
        for name, run in block["runs"].items():
            t = np.array(run["time_ps"])
            kw = {
                "color": colors[name],
                "ls": "-" if reference else "--",
                "lw": 0.8,
                "label": f"{name} ({platform_name})",
            }
            angular = np.array(run["angular_change"]) / run["angular_scale"]
            axes[0, 0].semilogy(t, np.maximum(angular, 1e-18), **kw)
            axes[0, 1].semilogy(
                t, np.maximum(np.array(run["linear_change"]) / run["linear_scale"], 1e-18), **kw
            )
            change = np.abs(np.array(run["constraint_error_change"]))
            dots = {"color": kw["color"], "marker": "." if reference else "x"}
            axes[1, 0].semilogy(t, np.maximum(change, 1e-18), ls="none", ms=2, **dots)
            if reference:
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
    return fig


def write_figures(data: dict, folder: Path) -> None:
    """Draw the four figures (each ``figure_*`` returns its own) into ``folder`` as ``validation_*.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    for name, draw in (
        ("convergence", figure_convergence),
        ("symplecticity", figure_symplecticity),
        ("alpha_star", figure_alpha_star),
        ("long_runs", figure_long_runs),
    ):
        fig = draw(plt, data)
        fig.tight_layout()
        fig.savefig(folder / f"validation_{name}.png", dpi=110)
        plt.close(fig)


# ------------------------------------------------------------------ the command
def main(argv: list[str] | None = None) -> int:
    """Run the validation (or read its JSON), write the JSON, the figures and the page's tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small runs, to check the report")
    parser.add_argument("--json", type=Path, help="the JSON (default docs/data/validation/validation.json)")
    parser.add_argument("--figures", type=Path, help="figure folder (default docs/figures)")
    parser.add_argument(
        "--page", type=Path, help="page whose tables are rewritten (default docs/validation.md)"
    )
    parser.add_argument(
        "--workdir", type=Path, help="run directories of the OpenMM runs (default: temporary)"
    )
    parser.add_argument("--from-json", action="store_true", help="run nothing: draw and tabulate the JSON")
    args = parser.parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="alphaprk-validation-"))
    default = not args.quick
    json_path = args.json or (DATA / JSON if default else scratch / "v.json")
    figures = args.figures or (DOCS / "figures" if default else scratch / "figures")
    page = args.page or (DOCS / "validation.md" if default else None)
    if args.from_json:
        data = json.loads(json_path.read_text(encoding="utf-8"))
    else:
        data = compute(args.quick, args.workdir or scratch / "runs")
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(dump_json(data), encoding="utf-8")
    write_figures(data, figures)
    if page is not None and (missing := update_page(page, render_tables(data))):
        print(f"{page} has no place for the tables {', '.join(missing)}", file=sys.stderr)
    print(f"JSON: {json_path}\nfigures: {figures}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
