"""The generated tables of docs/validation.md, rendered from docs/data/validation/validation.json."""

from __future__ import annotations

from tools.reports.markdown import markdown_table as _table
from tools.reports.sources import provenance_line, source


def _e(value: float, digits: int = 2) -> str:
    """Format in scientific notation, ``digits`` after the point, no leading zeros in the exponent."""
    if value == 0:
        return "0"
    return f"{value:.{digits}e}".replace("e-0", "e-").replace("e+0", "e")


def render_tables(data: dict) -> dict[str, str]:
    """Render the Markdown tables of the page from the JSON data (the page must hold exactly these)."""
    run = (
        f"the numerical validation, run as `{data['command']}` (today "
        f"`python -m openmm_alphaprk.benchmarks.validation`); {data['machine']}"
    )
    return {
        "provenance": provenance_line([source("validation/validation.json")], run),
        "headline": render_headline(data),
        "plain_pendulum_energy": _plain_pendulum_energy(data),
        "orders": _orders(data),
        "water_errors": _water_errors(data),
        "symplecticity": _symplecticity(data),
        "alpha_star_h": _alpha_star_h(data),
        "alpha_star_box": _alpha_star_box(data),
        "box_energy": _box_energy(data),
        "long_runs": _long_runs(data),
    }


def _plain_pendulum_energy(data: dict) -> str:
    """Render ``plain_pendulum_energy``: max |H − H₀| per step size on the plain pendulum."""
    period = data["convergence"]["pendulum_period"]
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
    return _table(
        ["method", *(f"max \\|H − H₀\\|, h = T/{n}" for n in period["counts"]), "steps without root"], rows
    )


def _orders(data: dict) -> str:
    """Render ``orders``: fitted orders and error ratios to RATTLE on the three problems."""
    conv = data["convergence"]
    period, spring, water = conv["pendulum_period"], conv["spring_pendulum"], conv["water_cluster"]
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
    return _table(
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


def _water_errors(data: dict) -> str:
    """Render ``water_errors``: the RMS position error on 3 waters per method and step."""
    water = data["convergence"]["water_cluster"]
    rows = []
    for entry in water["methods"].values():
        rows.append([entry["label"], *(_e(e) for e in entry["errors"])])
    return _table(
        ["method", *(f"h = {h * 1000:g} fs" for h in water["h"])],
        rows,
    )


def _symplecticity(data: dict) -> str:
    """Render ``symplecticity``: the defects per method, their slope, and on 3 waters."""
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
    return _table(
        [
            "method",
            *(f"pendulum h = {h:g}" for h in sym["spring_pendulum"]["h"]),
            "slope (above 1e-7)",
            "3 waters, 10 × 2 fs",
        ],
        rows,
    )


def _alpha_star_h(data: dict) -> str:
    """Render ``alpha_star_h``: exact |α*| against h for both energy modes."""
    conv = data["convergence"]
    spring, water = conv["spring_pendulum"], conv["water_cluster"]
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
    return _table(
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


def _alpha_star_box(data: dict) -> str:
    """Render ``alpha_star_box``: percentiles of the controller's α on the 774-atom box."""
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
    return _table(
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


def _box_energy(data: dict) -> str:
    """Render ``box_energy``: H − E_ref and cost of every run on the 774-atom box."""
    box = data["alpha_star_openmm"]
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
    return _table(
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


def _long_runs(data: dict) -> str:
    """Render ``long_runs``: the invariants of the long runs on the water cluster."""
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
    return _table(
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
