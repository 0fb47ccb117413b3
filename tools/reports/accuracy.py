r"""The tables of docs/accuracy.md and docs/compositions.md from the JSON of ``alphaprk bench accuracy``.

Part of ``python -m tools.reports``: per system (and, on compositions.md, per step) the rows
(cost, energy error, position and velocity errors at each horizon) and the verdicts at equal
cost against RATTLE and RATTLE + rescaling at h/k (k the row's evaluations per step rounded
up) and RATTLE at the h/r of equal wall time; on accuracy.md also the equilibrium averages
and the momenta of the isolated cluster. ``--figures`` draws the position errors against time.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from openmm_alphaprk.equal_cost import equal_cost_divisor, gain_text
from openmm_alphaprk.workflows.plots import plot_accuracy
from tools.reports.markdown import markdown_table
from tools.reports.sources import DATA, DOCS, parse_name, pick, provenance_line, source

SYSTEMS = ("tip3p-2nm", "tip3p-3nm", "villin", "water-cluster")
#: The steps of compositions.md, each with one or more files ``compositions_accuracy_{step}*.json``.
STEPS = ("2fs", "4fs")
#: The rows compositions.md weighs at equal cost, by their command-line names.
WEIGHED = ("alpha4=0", "rattle4+rescale", "energy4", "alpha6=0", "rattle6+rescale", "alpha4=0:triple-jump")
#: Times (fs) at which accuracy.md's verdicts compare position errors: a short horizon and 100 fs.
VERDICT_TIMES = (10.0, 100.0)


def _sci(value: float) -> str:
    """Two significant digits, "–" for no or no finite value."""
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
        name = f"**{row['name']}**" if row["divisor"] == 1 else row["name"]
        ratio = f"{ratio:.2f}" if ratio is not None and math.isfinite(ratio) else ""
        cells = [name, f"{row['force_evaluations_per_step']:.2f}", ratio, _sci(row["rms_residual"])]
        for key, times in (("position_rms", horizons), ("velocity_rms", (horizons[0], horizons[-1]))):
            cells += [_sci(errors[t][key]) if t in errors else "–" for t in times]
        lines.append(cells)
    floor = result["reference_convergence"]
    if floor:
        lines.append(
            ["reference h/64 − h/128", "", "", ""]
            + [_sci(h["position_rms"]) for h in floor]
            + [_sci(floor[0]["velocity_rms"]), _sci(floor[-1]["velocity_rms"])]
        )
    return markdown_table(header, lines)


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


def _ratio(value: float) -> str:
    """Say the baseline's error over the row's: '3.1× lower' (the row wins) or '**2× higher**'."""
    return gain_text(value, times="×", loss="**{}**")


def weighed(result: dict, names: tuple[str, ...], times) -> list[tuple[dict, dict, str, list[str]]]:
    """Return each row of ``names`` with each baseline of its cost, why, and the error ratios.

    The ratios: the baseline's RMS(H − E_ref) over the row's, then its position error over the
    row's at each of ``times`` (fs).
    """
    found = []
    for name in names:
        try:
            mine = pick(result["rows"], name)
        except LookupError:
            continue
        errors = {h["time_fs"]: h["position_rms"] for h in mine["horizons"]}
        for row, why in baselines(result["rows"], mine):
            theirs = {h["time_fs"]: h["position_rms"] for h in row["horizons"]}
            ratios = [_ratio(row["rms_residual"] / mine["rms_residual"])]
            ratios += [_ratio(theirs[t] / errors[t]) if t in errors and t in theirs else "–" for t in times]
            found.append((mine, row, why, ratios))
    return found


def verdicts(result: dict) -> str:
    """Compare the energy mode with RATTLE and RATTLE + rescaling at its k, and RATTLE at its wall time."""
    lines = [
        [row["name"], f"{why} (energy4)", *r]
        for _, row, why, r in weighed(result, ("energy4",), VERDICT_TIMES)
    ]
    header = ["against", "why", "energy mode's RMS(H − E_ref)"]
    return markdown_table(header + [f"its position error at {t:g} fs" for t in VERDICT_TIMES], lines)


def composition_verdicts(result: dict) -> str:
    """For each weighed row, each baseline of its cost: energy and position error ratios at every horizon."""
    horizons = [h["time_fs"] for h in result["rows"][0]["horizons"]]
    lines = [
        [mine["name"], f"{mine['force_evaluations_per_step']:.2f}", row["name"], why, *ratios]
        for mine, row, why, ratios in weighed(result, WEIGHED, horizons)
    ]
    header = ["row", "evals/step", "against", "why", "row's RMS(H − E_ref)"]
    return markdown_table(header + [f"row's x err. {t:g} fs" for t in horizons], lines)


def equilibrium_table(result: dict) -> str:
    """Each quantity's mean ± SE, and each row's difference from the reference with its verdict."""
    equilibrium = result["equilibrium"]
    keys = list(next(iter(equilibrium.values())))
    titles = {
        "temperature_K": "T (K)",
        "potential_kJ_per_mol": "V (kJ/mol)",
        "rdf_peak_height": "O–O g(r) peak",
        "rdf_peak_position_nm": "peak position (nm)",
    }

    def cell(a: dict) -> str:
        text = f"{a['mean']:.5g} ± {a['standard_error']:.2g}"
        if a["difference"] is None:
            return text
        verdict = "**resolved**" if a["resolved"] else "not resolved"
        return text + f"; Δ {a['difference']:+.2g} ± {a['difference_standard_error']:.2g}, {verdict}"

    lines = [[name, *(cell(averages[key]) for key in keys)] for name, averages in equilibrium.items()]
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


def _results(pattern: str) -> dict[str, dict]:
    """Return the results of each system in the files ``pattern`` matches, each with its file (``path``)."""
    results = {}
    for path in sorted(DATA.glob(pattern)):
        found = json.loads(path.read_text(encoding="utf-8"))["systems"]
        name = path.relative_to(DATA).as_posix()
        results.update({system: {**result, "path": name} for system, result in found.items()})
    return results


def render() -> dict[Path, dict[str, str]]:
    """docs/accuracy.md's and docs/compositions.md's generated blocks, by page and name."""
    tables = {}
    for system, result in _results("accuracy/accuracy_benchmark_*.json").items():
        tables[f"{system} header"] = provenance_line([source(result["path"])], result["header"])
        tables[f"{system} rows"] = rows_table(result)
        if system == "water-cluster":
            tables[f"{system} momenta"] = momentum_table(result)
            continue
        tables[f"{system} verdicts"] = verdicts(result)
        if result.get("equilibrium"):
            tables[f"{system} equilibrium"] = equilibrium_table(result)
    compositions = {}
    for step in STEPS:
        for system, result in _results(f"compositions/compositions_accuracy_{step}*.json").items():
            compositions[f"{system} {step} header"] = provenance_line(
                [source(result["path"])], result["header"]
            )
            compositions[f"{system} {step} rows"] = rows_table(result)
            compositions[f"{system} {step} verdicts"] = composition_verdicts(result)
    return {DOCS / "accuracy.md": tables, DOCS / "compositions.md": compositions}


def figures() -> None:
    """Draw docs/figures/accuracy_benchmark.png and compositions_accuracy_{2fs,4fs}.png."""
    shown = _results("accuracy/accuracy_benchmark_*.json")
    shown = {system: shown[system] for system in SYSTEMS if system != "water-cluster"}
    plot_accuracy(shown, DOCS / "figures" / "accuracy_benchmark.png")
    for step in STEPS:
        plot_accuracy(
            _results(f"compositions/compositions_accuracy_{step}*.json"),
            DOCS / "figures" / f"compositions_accuracy_{step}.png",
        )
