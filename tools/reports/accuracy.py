r"""The tables of docs/accuracy.md from the JSON of ``alphaprk bench accuracy``.

Part of ``python -m tools.reports``, after the benchmark wrote
``docs/data/accuracy/accuracy_benchmark_SYSTEM.json``: it rewrites the generated blocks of
``docs/accuracy.md`` (the prose is left alone): per system the rows
(cost, energy error, position and velocity errors at each horizon), the equal-cost
verdicts of the energy mode, the equilibrium averages, and the momenta of the isolated
cluster; and draws ``docs/figures/accuracy_benchmark.png``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from openmm_alphaprk.equal_cost import equal_cost_divisor, gain_text
from openmm_alphaprk.workflows.plots import plot_accuracy
from tools.reports.markdown import markdown_table
from tools.reports.sources import parse_name, pick, provenance_line, source

DOCS = Path(__file__).resolve().parents[2] / "docs"
SYSTEMS = ("tip3p-2nm", "tip3p-3nm", "villin", "water-cluster")


def _sci(value: float) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{value:.2g}"


def rows_table(result: dict) -> str:
    """Cost, RMS(H − E_ref) and RMS position error at every horizon (velocity at the first and last)."""
    horizons = [h["time_fs"] for h in result["rows"][0]["horizons"]]
    header = ["row", "evals/step", "time/step ÷ RATTLE", "RMS(H − E_ref) kJ/mol"]
    header += [f"x err. {t:g} fs (nm)" for t in horizons]
    header += [f"v err. {horizons[0]:g} fs", f"v err. {horizons[-1]:g} fs (nm/ps)"]
    lines = []
    for row in result["rows"]:
        errors = {h["time_fs"]: h for h in row["horizons"]}
        ratio = row["time_ratio"]
        cells = [
            f"**{row['name']}**" if row["divisor"] == 1 else row["name"],
            f"{row['force_evaluations_per_step']:.2f}",
            f"{ratio:.2f}" if ratio is not None and math.isfinite(ratio) else "",
            _sci(row["rms_residual"]),
        ]
        cells += [_sci(errors[t]["position_rms"]) if t in errors else "–" for t in horizons]
        cells += [
            _sci(errors[t]["velocity_rms"]) if t in errors else "–" for t in (horizons[0], horizons[-1])
        ]
        lines.append(cells)
    floor = result["reference_convergence"]
    if floor:
        lines.append(
            ["reference h/64 − h/128", "", "", ""]
            + [_sci(h["position_rms"]) for h in floor]
            + [_sci(floor[0]["velocity_rms"]), _sci(floor[-1]["velocity_rms"])]
        )
    return markdown_table(header, lines)


#: Times (fs) at which the verdicts compare position errors: a short horizon and 100 fs.
VERDICT_TIMES = (10.0, 100.0)


def baselines(rows: list[dict], mine: dict) -> list[tuple[dict, str]]:
    """Return the rows a row of several force evaluations per step is weighed against, and why.

    RATTLE and RATTLE + rescaling at h/k, k its force evaluations per step rounded up
    (equal evaluations), and RATTLE at h/r, r its time per step over RATTLE's rounded up
    (equal wall time): found by the registry's name and divisor, in the order of ``rows``.
    """
    why: dict[tuple[str, int], list[str]] = {}
    k = equal_cost_divisor(mine["force_evaluations_per_step"])
    if k > 1:
        for name in ("rattle", "rattle+rescale"):
            why.setdefault((name, k), []).append("equal evaluations")
    ratio = mine.get("time_ratio")
    if ratio is not None and math.isfinite(ratio) and (r := equal_cost_divisor(ratio)) > 1:
        why.setdefault(("rattle", r), []).append("equal wall time")
    return [
        (row, "; ".join(why[parse_name(row["integrator"]), row["divisor"]]))
        for row in rows
        if (parse_name(row["integrator"]), row["divisor"]) in why
    ]


def verdicts(result: dict) -> str:
    """Compare the energy mode with RATTLE and RATTLE + rescaling at its k, and RATTLE at its wall time."""
    mode = pick(result["rows"], "energy4")
    mine = {h["time_fs"]: h["position_rms"] for h in mode["horizons"]}
    lines = []
    for row, why in baselines(result["rows"], mode):
        theirs = {h["time_fs"]: h["position_rms"] for h in row["horizons"]}
        cells = [row["name"], f"{why} (energy4)", _ratio(row["rms_residual"] / mode["rms_residual"])]
        cells += [_ratio(theirs[t] / mine[t]) if t in mine and t in theirs else "–" for t in VERDICT_TIMES]
        lines.append(cells)
    header = ["against", "why", "energy mode's RMS(H − E_ref)"]
    header += [f"its position error at {t:g} fs" for t in VERDICT_TIMES]
    return markdown_table(header, lines)


def _ratio(value: float) -> str:
    """Say how the energy mode's error compares, given the baseline's error over the energy mode's."""
    return gain_text(value, times="×", loss="**{}**")


def equilibrium_table(result: dict) -> str:
    """Each quantity's mean ± SE, and each row's difference from the reference with its verdict."""
    equilibrium = result.get("equilibrium") or {}
    if not equilibrium:
        return "(not measured for this system)"
    keys = list(next(iter(equilibrium.values())))
    titles = {
        "temperature_K": "T (K)",
        "potential_kJ_per_mol": "V (kJ/mol)",
        "rdf_peak_height": "O–O g(r) peak",
        "rdf_peak_position_nm": "peak position (nm)",
    }
    lines = []
    for name, averages in equilibrium.items():
        cells = [name]
        for key in keys:
            a = averages[key]
            text = f"{a['mean']:.5g} ± {a['standard_error']:.2g}"
            if a["difference"] is not None:
                verdict = "**resolved**" if a["resolved"] else "not resolved"
                text += f"; Δ {a['difference']:+.2g} ± {a['difference_standard_error']:.2g}, {verdict}"
            cells.append(text)
        lines.append(cells)
    return markdown_table(["row", *(titles.get(key, key) for key in keys)], lines)


def momentum_table(result: dict) -> str:
    """Largest change of P and L of every row (an isolated system)."""
    lines = []
    for row in result["rows"]:
        m = row["momentum_change"]
        if m:
            lines.append(
                [row["name"], f"{m['linear_amu_nm_per_ps']:.1e}", f"{m['angular_amu_nm2_per_ps']:.1e}"]
            )
    first = next(row["momentum_change"] for row in result["rows"] if row["momentum_change"])
    header = [
        "row",
        f"max \\|ΔP\\| (amu nm/ps; \\|P\\| = {first['linear_start']:.3g})",
        f"max \\|ΔL\\| (amu nm²/ps; \\|L\\| = {first['angular_start']:.3g})",
    ]
    return markdown_table(header, lines)


def _systems() -> dict[str, dict]:
    found = {}
    for system in SYSTEMS:
        path = DOCS / "data" / "accuracy" / f"accuracy_benchmark_{system}.json"
        if path.is_file():
            found[system] = json.loads(path.read_text(encoding="utf-8"))["systems"][system]
    return found


def render() -> dict[Path, dict[str, str]]:
    """docs/accuracy.md's generated blocks, by name."""
    tables = {}
    for system, result in _systems().items():
        tables[f"{system} header"] = provenance_line(
            [source(f"accuracy/accuracy_benchmark_{system}.json")], result["header"]
        )
        tables[f"{system} rows"] = rows_table(result)
        if system == "water-cluster":
            tables[f"{system} momenta"] = momentum_table(result)
            continue
        tables[f"{system} verdicts"] = verdicts(result)
        if result.get("equilibrium"):
            tables[f"{system} equilibrium"] = equilibrium_table(result)
    return {DOCS / "accuracy.md": tables}


def figures() -> None:
    """Draw docs/figures/accuracy_benchmark.png."""
    shown = {name: result for name, result in _systems().items() if name != "water-cluster"}
    plot_accuracy(shown, DOCS / "figures" / "accuracy_benchmark.png")
