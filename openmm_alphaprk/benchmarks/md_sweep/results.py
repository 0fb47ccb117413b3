"""The MD benchmark sweep's results: which rows the report shows, the finished cells.

The sweep's cells are read from their run directories (:func:`load_rows`), so that a
report can be made while the sweep still runs.
"""

from __future__ import annotations

from ...runs.integrator_names import label as integrator_label

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
#: The integrators the report shows, with their labels from the one vocabulary.
LABELS = {
    name: integrator_label(name)
    for name in ("rattle", "verlet", "alpha=1/6", "alpha4=0", "energy", "energy4")
}
#: A scan cell counts as stable if it finished and max|H − E_ref| per DOF stayed below this (kJ/mol).
STABLE_MAX_PER_DOF = 0.05


def run_label(integrator: str, step_fs: float) -> str:
    """Return a row label such as ``RATTLE 2/3 fs``."""
    step = "2/3" if abs(step_fs - 2 / 3) < 1e-9 else f"{step_fs:g}"
    return f"{LABELS.get(integrator, integrator)} {step} fs"


def load_rows(config) -> dict[tuple[str, str, float, str], dict]:
    """Return the rows of finished and failed cells, keyed by (system, integrator, step, seed).

    The rows are those of the sweep table, read from the run directories, so that a
    report can be made while the sweep still runs.
    """
    from openmm_alphaprk.workflows.sweep import cell_status

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
