r"""The tables of docs/compositions.md from the JSON of ``alphaprk bench accuracy``.

Part of ``python -m tools.reports``, after the benchmarks wrote
``docs/data/compositions/compositions_accuracy_{2fs,4fs}*.json`` (one or more files per
step): it rewrites the generated blocks of ``docs/compositions.md`` (the prose is left alone): per
system and step the rows (cost, energy error, position errors at each horizon) and, for
every row of more than one force evaluation per step, its verdicts at equal cost: against
RATTLE and RATTLE + rescaling at h/k (k its evaluations per step rounded up) and against
RATTLE at the h/r of equal CPU wall time; and draws
``docs/figures/compositions_accuracy_{2fs,4fs}.png`` (position error against time).
"""

from __future__ import annotations

import json
from pathlib import Path

from openmm_alphaprk.equal_cost import gain_text
from openmm_alphaprk.workflows.plots import plot_accuracy
from tools.reports.accuracy import baselines, rows_table
from tools.reports.markdown import markdown_table
from tools.reports.sources import pick, provenance_line, source

DOCS = Path(__file__).resolve().parents[2] / "docs"
STEPS = ("2fs", "4fs")
#: The rows weighed at equal cost, by their command-line names.
WEIGHED = ("alpha4=0", "rattle4+rescale", "energy4", "alpha6=0", "rattle6+rescale", "alpha4=0:triple-jump")


def _ratio(value: float) -> str:
    """Say the baseline's error over the row's: '3.1× lower' (the row wins) or '**2× higher**'."""
    return gain_text(value, times="×", loss="**{}**")


def verdicts(result: dict) -> str:
    """For each weighed row, each baseline of its cost: energy and position error ratios at every horizon."""
    horizons = [h["time_fs"] for h in result["rows"][0]["horizons"]]
    lines = []
    for name in WEIGHED:
        try:
            mine_row = pick(result["rows"], name)
        except LookupError:
            continue
        mine = {h["time_fs"]: h["position_rms"] for h in mine_row["horizons"]}
        for row, why in baselines(result["rows"], mine_row):
            theirs = {h["time_fs"]: h["position_rms"] for h in row["horizons"]}
            cells = [mine_row["name"], f"{mine_row['force_evaluations_per_step']:.2f}", row["name"], why]
            cells.append(_ratio(row["rms_residual"] / mine_row["rms_residual"]))
            cells += [_ratio(theirs[t] / mine[t]) if t in mine and t in theirs else "–" for t in horizons]
            lines.append(cells)
    header = ["row", "evals/step", "against", "why", "row's RMS(H − E_ref)"]
    header += [f"row's x err. {t:g} fs" for t in horizons]
    return markdown_table(header, lines)


def _results(step: str) -> dict[str, dict]:
    """Return the results of each system at ``step``, each with the data file it came from (``path``)."""
    results = {}
    for path in sorted((DOCS / "data" / "compositions").glob(f"compositions_accuracy_{step}*.json")):
        found = json.loads(path.read_text(encoding="utf-8"))["systems"]
        results.update(
            {system: {**result, "path": f"compositions/{path.name}"} for system, result in found.items()}
        )
    return results


def render() -> dict[Path, dict[str, str]]:
    """docs/compositions.md's generated blocks, by name."""
    tables = {}
    for step in STEPS:
        for system, result in _results(step).items():
            tables[f"{system} {step} header"] = provenance_line([source(result["path"])], result["header"])
            tables[f"{system} {step} rows"] = rows_table(result)
            tables[f"{system} {step} verdicts"] = verdicts(result)
    return {DOCS / "compositions.md": tables}


def figures() -> None:
    """Draw docs/figures/compositions_accuracy_{2fs,4fs}.png."""
    for step in STEPS:
        if results := _results(step):
            plot_accuracy(results, DOCS / "figures" / f"compositions_accuracy_{step}.png")
