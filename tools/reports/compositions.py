r"""The tables of docs/compositions.md from the JSON of ``alphaprk bench accuracy``.

Run from the repository root, after the benchmarks wrote
``docs/data/compositions/compositions_accuracy_2fs*.json`` and
``docs/data/compositions/compositions_accuracy_4fs*.json`` (one or more files per step)::

    python -m tools.reports.compositions

It rewrites the generated blocks of ``docs/compositions.md`` (the prose is left alone): per
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
from openmm_alphaprk.runs.integrator_names import label
from openmm_alphaprk.workflows.plots import plot_accuracy
from tools.reports.accuracy import rows_table
from tools.reports.markdown import markdown_table, update_page

DOCS = Path(__file__).resolve().parents[2] / "docs"
STEPS = ("2fs", "4fs")
#: The rows weighed at equal cost, by their command-line names.
WEIGHED = ("alpha4=0", "rattle4+rescale", "energy4", "alpha6=0", "rattle6+rescale", "alpha4=0:triple-jump")


def _ratio(value: float) -> str:
    """Say the baseline's error over the row's: '3.1× lower' (the row wins) or '**2× higher**'."""
    return gain_text(value, times="×", loss="**{}**")


def verdicts(result: dict) -> str:
    """For each weighed row, each baseline of its cost: energy and position error ratios at every horizon."""
    by_name = {row["name"]: row for row in result["rows"]}
    horizons = [h["time_fs"] for h in result["rows"][0]["horizons"]]
    lines = []
    for name in WEIGHED:
        mine_row = by_name.get(label(name))
        if mine_row is None:
            continue
        mine = {h["time_fs"]: h["position_rms"] for h in mine_row["horizons"]}
        for row in result["rows"]:
            if f"({name})" not in row["role"]:
                continue
            theirs = {h["time_fs"]: h["position_rms"] for h in row["horizons"]}
            why = "; ".join(part.split(" (")[0] for part in row["role"].split("; ") if f"({name})" in part)
            cells = [label(name), f"{mine_row['force_evaluations_per_step']:.2f}", row["name"], why]
            cells.append(_ratio(row["rms_residual"] / mine_row["rms_residual"]))
            cells += [_ratio(theirs[t] / mine[t]) if t in mine and t in theirs else "–" for t in horizons]
            lines.append(cells)
    header = ["row", "evals/step", "against", "why", "row's RMS(H − E_ref)"]
    header += [f"row's x err. {t:g} fs" for t in horizons]
    return markdown_table(header, lines)


def main() -> None:
    tables = {}
    for step in STEPS:
        results = {}
        for path in sorted((DOCS / "data" / "compositions").glob(f"compositions_accuracy_{step}*.json")):
            results.update(json.loads(path.read_text(encoding="utf-8"))["systems"])
        for system, result in results.items():
            tables[f"{system} {step} header"] = result["header"]
            tables[f"{system} {step} rows"] = rows_table(result)
            tables[f"{system} {step} verdicts"] = verdicts(result)
        if results:
            plot_accuracy(results, DOCS / "figures" / f"compositions_accuracy_{step}.png")
    missing = update_page(DOCS / "compositions.md", tables)
    if missing:
        raise SystemExit(f"docs/compositions.md has no block for {missing}")
    print("\n\n".join(f"{name}\n{text}" for name, text in tables.items()))


if __name__ == "__main__":
    main()
