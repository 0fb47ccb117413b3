"""Parameter sweeps: a grid of NVE runs executed with ``dask.distributed``.

A sweep configuration (TOML) names one or more grids; each grid is the product
systems × integrators × step sizes × α × seeds, and every point (a *cell*) is an
independent :func:`~openmm_alphaprk.driver.run_nve` run in its own run directory under
the sweep's output folder. :func:`run_sweep` submits the cells to a dask cluster (a
``LocalCluster`` by default, an existing scheduler when its address is given) and
collects their summaries into one CSV table, rewritten after every finished cell.

A cell that fails (a blow-up, a bad setting) is recorded with its error (an
``error.json`` in its directory and a ``failed`` row in the table), never dropped. A
re-run of the same sweep skips finished cells (``summary.json`` present for the
requested length), skips failed cells unless ``retry_failed``, and resumes interrupted
ones from their last checkpoint.

Configuration::

    output = "sweep-out"            # folder of the run directories and sweep.csv
                                    # (relative to the configuration file)
    [run]
    duration_ps = 10.0
    platform = "CPU"
    energy_interval_fs = 20         # times, converted to steps for each step size
    trajectory_interval_fs = 100
    checkpoint_interval_fs = 1000
    velocity_interval_fs = 4        # optional: velocities.dcd for VACF spectra (0: none)
    cpu_threads = 1                 # optional: threads per run on the CPU platform

    [cluster]                       # optional
    n_workers = 2                   # LocalCluster size (default 1)
    scheduler = "tcp://host:8786"   # optional: use a running scheduler instead

    [[grid]]
    systems = ["tip3p-2nm"]
    integrators = ["rattle", "alpha={alpha}", "energy"]
    timesteps_fs = [2, "2/3"]       # numbers or fractions
    alphas = ["1/6", 0.5]           # fill "{alpha}" in integrator names (optional)
    seeds = [1, 2]                  # optional: new Maxwell-Boltzmann velocities per seed
    duration_ps = 2.0               # optional: any [run] key, for this grid only

Times (duration, intervals) become the nearest whole number of steps of each step size,
at least one. Integrator names are those of :mod:`openmm_alphaprk.integrators.names`; an integrator
name containing ``{alpha}`` is expanded over ``alphas``, the others are not.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from . import rundir

#: Name of the collected table in the sweep's output folder.
TABLE_FILE = "sweep.csv"
#: Written into a cell's run directory when its run failed.
ERROR_FILE = "error.json"
#: The first columns of the table; the summary's fields follow.
CELL_COLUMNS = ("cell", "system", "integrator", "timestep_fs", "seed", "steps", "status", "error", "run_dir")

_RUN_KEYS = {
    "duration_ps",
    "platform",
    "precision",
    "energy_interval_fs",
    "trajectory_interval_fs",
    "checkpoint_interval_fs",
    "velocity_interval_fs",
    "cpu_threads",
    "constraint_tolerance",
}
_GRID_KEYS = {"systems", "integrators", "timesteps_fs", "alphas", "seeds"} | _RUN_KEYS
_RUN_DEFAULTS: dict[str, Any] = {
    "platform": "CPU",
    "precision": None,
    "energy_interval_fs": 20.0,
    "trajectory_interval_fs": 100.0,
    "checkpoint_interval_fs": 1000.0,
    "velocity_interval_fs": None,
    "cpu_threads": None,
    "constraint_tolerance": 1e-8,
}


class SweepConfigError(ValueError):
    """Raised for a sweep configuration that cannot be run; the message names the entry."""


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a point of a grid.

    Attributes
    ----------
    system, integrator
        Names as ``alphaprk run`` takes them.
    timestep_fs
        Step size in fs, exact (``Fraction``) so that 2/3 fs stays 2/3 fs.
    seed
        Velocity seed, or None for the prepared state's velocities.
    steps
        Number of steps (duration / step size).
    run_kwargs
        Keyword arguments of :func:`~openmm_alphaprk.driver.run_nve` besides these.
    """

    system: str
    integrator: str
    timestep_fs: Fraction
    seed: int | None
    steps: int
    run_kwargs: tuple[tuple[str, Any], ...] = ()

    @property
    def name(self) -> str:
        """Folder name of the cell's run directory (file-system safe, unique in a sweep)."""
        step = _format_fs(self.timestep_fs).replace("/", "_")
        seed = "start" if self.seed is None else f"seed{self.seed}"
        integrator = rundir.folder_name(self.integrator)
        return f"{self.system}__{integrator}__{step}fs__{seed}"

    def kwargs(self) -> dict[str, Any]:
        return dict(self.run_kwargs)


@dataclass
class SweepResult:
    """What :func:`run_sweep` returns.

    Attributes
    ----------
    table
        Path of the CSV table.
    rows
        One dict per cell (the table's rows).
    ran, skipped, failed
        Names of cells run in this call, skipped as finished (or failed before), and
        failed (in this call or before).
    """

    table: Path
    rows: list[dict[str, Any]]
    ran: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class SweepConfig:
    """A parsed sweep configuration: the cells, where they go and how they run."""

    cells: tuple[Cell, ...]
    output: Path
    n_workers: int = 1
    scheduler: str | None = None


def load_config(path: str | os.PathLike) -> SweepConfig:
    """Read and check a sweep configuration file (TOML); see the module docstring.

    Raises
    ------
    SweepConfigError
        For a missing file, unknown keys, unknown systems or integrators, a step size
        that does not divide a duration or interval, and other bad entries.
    """
    path = Path(path)
    if not path.is_file():
        raise SweepConfigError(f"sweep configuration {path} does not exist.")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as error:
        raise SweepConfigError(f"{path} is not valid TOML: {error}") from error
    return parse_config(data, base=path.parent, source=str(path))


def parse_config(data: dict[str, Any], base: str | os.PathLike = ".", source: str = "sweep") -> SweepConfig:
    """Check a configuration given as a dict (the TOML's content) and expand its grids."""
    unknown = set(data) - {"output", "run", "cluster", "grid"}
    if unknown:
        raise SweepConfigError(
            f"{source}: unknown top-level keys {sorted(unknown)}; allowed: output, run, cluster, grid."
        )
    if "output" not in data:
        raise SweepConfigError(f"{source}: give `output`, the folder for the runs and the table.")
    run = dict(_RUN_DEFAULTS) | _table(data, "run", _RUN_KEYS, source)
    cluster = _table(data, "cluster", {"n_workers", "scheduler"}, source)
    grids = data.get("grid")
    if not isinstance(grids, list) or not grids:
        raise SweepConfigError(f"{source}: give at least one [[grid]] table.")
    cells: dict[str, Cell] = {}
    for number, grid in enumerate(grids, 1):
        for cell in _expand_grid(grid, run, f"{source} [[grid]] #{number}"):
            cells.setdefault(cell.name, cell)
    n_workers = cluster.get("n_workers", 1)
    if isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1:
        raise SweepConfigError(f"{source}: cluster.n_workers must be a positive integer, got {n_workers!r}.")
    return SweepConfig(
        cells=tuple(cells.values()),
        output=Path(base) / str(data["output"]),
        n_workers=n_workers,
        scheduler=cluster.get("scheduler"),
    )


def _table(data: dict, name: str, allowed: set[str], source: str) -> dict[str, Any]:
    table = data.get(name, {})
    if not isinstance(table, dict):
        raise SweepConfigError(f"{source}: [{name}] must be a table.")
    unknown = set(table) - allowed
    if unknown:
        raise SweepConfigError(
            f"{source}: unknown keys in [{name}]: {sorted(unknown)}; allowed: {sorted(allowed)}."
        )
    return dict(table)


def _expand_grid(grid: dict[str, Any], run: dict[str, Any], where: str) -> Iterable[Cell]:
    from .integrators.names import parse_integrator
    from .systems import load_definition

    if not isinstance(grid, dict):
        raise SweepConfigError(f"{where}: must be a table.")
    unknown = set(grid) - _GRID_KEYS
    if unknown:
        raise SweepConfigError(f"{where}: unknown keys {sorted(unknown)}; allowed: {sorted(_GRID_KEYS)}.")
    for key in ("systems", "integrators", "timesteps_fs"):
        if not isinstance(grid.get(key), list) or not grid[key]:
            raise SweepConfigError(f"{where}: give `{key}` as a non-empty list.")
    systems = [str(name) for name in grid["systems"]]
    for name in systems:
        try:
            load_definition(name)
        except KeyError as error:
            raise SweepConfigError(f"{where}: {error}") from error
    alphas = [str(_fraction(a, f"{where} alphas")) for a in grid.get("alphas", [])]
    integrators: list[str] = []
    for template in grid["integrators"]:
        template = str(template)
        if "{alpha}" in template:
            if not alphas:
                raise SweepConfigError(f"{where}: integrator {template!r} needs `alphas`.")
            integrators.extend(template.replace("{alpha}", a) for a in alphas)
        else:
            integrators.append(template)
    for name in integrators:
        try:
            parse_integrator(name)
        except (KeyError, ValueError) as error:
            raise SweepConfigError(f"{where}: {error}") from error
    steps_fs = [_fraction(h, f"{where} timesteps_fs") for h in grid["timesteps_fs"]]
    if any(h <= 0 for h in steps_fs):
        raise SweepConfigError(f"{where}: step sizes must be positive, got {grid['timesteps_fs']}.")
    seeds = grid.get("seeds", [None])
    if not isinstance(seeds, list) or any(
        s is not None and (isinstance(s, bool) or not isinstance(s, int)) for s in seeds
    ):
        raise SweepConfigError(f"{where}: seeds must be a list of integers, got {seeds!r}.")
    run = run | {key: value for key, value in grid.items() if key in _RUN_KEYS}
    duration = run.get("duration_ps")
    if duration is None:
        raise SweepConfigError(f"{where}: give duration_ps (in [run] or in the grid).")
    duration_fs = _fraction(duration, f"{where} duration_ps") * 1000
    for system in systems:
        for integrator in integrators:
            for h in steps_fs:
                steps = _steps(duration_fs, h, f"{where}: duration_ps = {duration}")
                kwargs = {
                    "platform": run["platform"],
                    "precision": run["precision"],
                    "constraint_tolerance": float(run["constraint_tolerance"]),
                    "energy_interval": _steps(run["energy_interval_fs"], h, f"{where}: energy_interval_fs"),
                    "trajectory_interval": _steps(
                        run["trajectory_interval_fs"], h, f"{where}: trajectory_interval_fs"
                    ),
                    "checkpoint_interval": _steps(
                        run["checkpoint_interval_fs"], h, f"{where}: checkpoint_interval_fs"
                    ),
                    "cpu_threads": run["cpu_threads"],
                }
                if run["velocity_interval_fs"]:  # None or 0: no velocities file
                    kwargs["velocity_interval"] = _steps(
                        run["velocity_interval_fs"], h, f"{where}: velocity_interval_fs"
                    )
                for seed in seeds:
                    yield Cell(system, integrator, h, seed, steps, tuple(sorted(kwargs.items())))


def _fraction(value: Any, what: str) -> Fraction:
    """Return a number or a fraction string (``"2/3"``) as an exact Fraction."""
    if isinstance(value, bool):
        raise SweepConfigError(f"{what}: expected a number, got {value!r}.")
    try:
        if isinstance(value, float):
            if not math.isfinite(value):
                raise ValueError
            return Fraction(str(value))
        return Fraction(value)
    except (ValueError, TypeError, ZeroDivisionError):
        raise SweepConfigError(
            f"{what}: expected a number or a fraction like '2/3', got {value!r}."
        ) from None


def _steps(time_fs: Any, h: Fraction, what: str) -> int:
    """Return a time as the nearest whole number of steps of size ``h``, at least one."""
    time_fs = _fraction(time_fs, what)
    if time_fs <= 0:
        raise SweepConfigError(f"{what} must be positive, got {float(time_fs):g}.")
    return max(1, round(time_fs / h))


def _format_fs(h: Fraction) -> str:
    """Write a step size as a decimal where it has a finite one (2, 2.5, 0.5), else as p/q (2/3)."""
    if h.denominator == 1:
        return str(h.numerator)
    for digits in range(1, 7):
        scaled = h * 10**digits
        if scaled.denominator == 1:
            return f"{float(h):.{digits}f}"
    return str(h)


def run_cell(cell: Cell, directory: str | os.PathLike, cache_dir: str | None = None) -> dict[str, Any]:
    """Run one cell (on a dask worker); return its table row. Never raises for a failed run.

    A failed run's error is written to ``error.json`` in the run directory and returned
    in the row (``status = "failed"``); whatever the run wrote stays.
    """
    from .driver import run_nve

    directory = Path(directory)
    row = _cell_row(cell, directory)
    (directory / ERROR_FILE).unlink(missing_ok=True)
    try:
        summary = run_nve(
            cell.system,
            cell.integrator,
            directory,
            steps=cell.steps,
            timestep=float(cell.timestep_fs) / 1000.0,
            velocity_seed=cell.seed,
            cache_dir=cache_dir,
            progress=False,
            **cell.kwargs(),
        )
    except Exception as error:  # noqa: BLE001 - a failed cell is data, not a crash of the sweep
        message = f"{type(error).__name__}: {error}"
        directory.mkdir(parents=True, exist_ok=True)
        (directory / ERROR_FILE).write_text(
            json.dumps({"error": message, "traceback": traceback.format_exc()}, indent=2) + "\n"
        )
        return row | {"status": "failed", "error": message}
    return row | {"status": "ok"} | _flatten(summary.as_dict())


def _cell_row(cell: Cell, directory: Path) -> dict[str, Any]:
    return {
        "cell": cell.name,
        "system": cell.system,
        "integrator": cell.integrator,
        "timestep_fs": float(cell.timestep_fs),
        "seed": "" if cell.seed is None else cell.seed,
        "steps": cell.steps,
        "status": "",
        "error": "",
        "run_dir": str(directory),
    }


def _flatten(summary: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Summary fields as table columns: nested dicts become ``name.key`` columns, lists are joined."""
    flat: dict[str, Any] = {}
    for key, value in summary.items():
        if not prefix and key in ("system", "integrator", "steps"):
            continue
        if isinstance(value, dict):
            flat |= _flatten(value, f"{prefix}{key}.")
        elif isinstance(value, list):
            flat[prefix + key] = " | ".join(map(str, value))
        else:
            flat[prefix + key] = value
    return flat


def cell_status(cell: Cell, directory: Path) -> dict[str, Any] | None:
    """Return the row of a finished or failed cell from its directory, None if it still has to run."""
    summary_file = directory / "summary.json"
    if summary_file.is_file():
        summary = json.loads(summary_file.read_text(encoding="utf-8"))
        if summary.get("steps", 0) >= cell.steps:
            return _cell_row(cell, directory) | {"status": "ok"} | _flatten(summary)
    error_file = directory / ERROR_FILE
    if error_file.is_file():
        error = json.loads(error_file.read_text(encoding="utf-8")).get("error", "unknown error")
        return _cell_row(cell, directory) | {"status": "failed", "error": error}
    return None


def write_table(path: Path, rows: list[dict[str, Any]]) -> None:
    """Write the rows as CSV (cell columns first, then every summary column seen), atomically."""
    columns = list(CELL_COLUMNS)
    for row in rows:
        columns.extend(key for key in row if key not in columns)
    temporary = path.with_suffix(".csv.tmp")
    with open(temporary, "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, restval="")
        writer.writeheader()
        writer.writerows(rows)
    os.replace(temporary, path)


def read_table(path: str | os.PathLike) -> list[dict[str, str]]:
    """Rows of a sweep table (all values as strings)."""
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def run_sweep(
    config: SweepConfig | str | os.PathLike,
    *,
    output: str | os.PathLike | None = None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    processes: bool = True,
    retry_failed: bool = False,
    cache_dir: str | os.PathLike | None = None,
    progress: bool = True,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> SweepResult:
    """Run every cell of a sweep that has not finished, on a dask cluster; collect the table.

    Parameters
    ----------
    config
        A :class:`SweepConfig` or the path of a TOML configuration.
    output
        Output folder (default: the configuration's ``output``).
    scheduler
        Address of a running dask scheduler (``tcp://host:8786``); default: the
        configuration's, else a ``LocalCluster`` started for this sweep.
    n_workers
        Workers of the local cluster (default: the configuration's, else 1). Each worker
        runs one cell at a time; on the CPU platform give each run ``cpu_threads``
        so that workers × threads ≤ cores.
    processes
        Local cluster of processes (default) or of threads in this process.
    retry_failed
        Run cells again that failed in an earlier call (default: keep their error).
    cache_dir
        Cache of prepared systems (see :func:`~openmm_alphaprk.systems.prepare_system`).
    progress
        Print one line per finished cell on stderr.
    on_row
        Called with each row as it arrives (for tests and live reports).

    Returns
    -------
    SweepResult
        The table's path and rows, and which cells ran, were skipped or failed.

    Raises
    ------
    ImportError
        If ``dask.distributed`` is not installed (``pip install "openmm-alphaprk[sweep]"``).
    SweepConfigError
        For a bad configuration, before anything runs.
    """
    if not isinstance(config, SweepConfig):
        config = load_config(config)
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError as error:  # pragma: no cover - the test extra installs it
        raise ImportError(
            "sweeps need dask.distributed: pip install 'openmm-alphaprk[sweep]' (or 'dask[distributed]')."
        ) from error
    root = Path(output) if output is not None else config.output
    root.mkdir(parents=True, exist_ok=True)
    table = root / TABLE_FILE
    cache = None if cache_dir is None else str(cache_dir)

    rows: dict[str, dict[str, Any]] = {}
    pending: list[Cell] = []
    result = SweepResult(table=table, rows=[])
    for cell in config.cells:
        row = cell_status(cell, root / cell.name)
        if row is None or (retry_failed and row["status"] == "failed"):
            pending.append(cell)
            continue
        rows[cell.name] = row
        result.skipped.append(cell.name)
        if row["status"] == "failed":
            result.failed.append(cell.name)
    write_table(table, _ordered(config, rows))
    if progress:
        print(
            f"sweep: {len(config.cells)} cells, {len(result.skipped)} finished before, {len(pending)} to run "
            f"-> {table}",
            file=sys.stderr,
        )
    if pending:
        _prepare_systems({cell.system for cell in pending}, cache, progress)
        address = scheduler or config.scheduler
        workers = n_workers or config.n_workers
        cluster = (
            None
            if address
            else LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=processes, dashboard_address=":0"
            )
        )
        started = time.perf_counter()
        try:
            with Client(address or cluster) as client:
                futures = {
                    client.submit(
                        run_cell, cell, str(root / cell.name), cache, pure=False, key=f"cell-{cell.name}"
                    ): cell
                    for cell in pending
                }
                for future in as_completed(futures):
                    cell = futures[future]
                    row = future.result()
                    rows[cell.name] = row
                    result.ran.append(cell.name)
                    if row["status"] == "failed":
                        result.failed.append(cell.name)
                    write_table(table, _ordered(config, rows))
                    if on_row is not None:
                        on_row(row)
                    if progress:
                        done = len(result.ran)
                        print(
                            f"[{done}/{len(pending)}, {time.perf_counter() - started:.0f} s] {cell.name}: "
                            f"{row['status']}{' - ' + row['error'] if row['error'] else ''}",
                            file=sys.stderr,
                        )
        finally:
            if cluster is not None:
                cluster.close()
    result.rows = _ordered(config, rows)
    return result


def _ordered(config: SweepConfig, rows: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    return [rows[cell.name] for cell in config.cells if cell.name in rows]


def _prepare_systems(names: set[str], cache_dir: str | None, progress: bool) -> None:
    """Build (or find cached) each system once, before the workers start, so they never race to build it."""
    from .systems import prepare_system

    for name in sorted(names):
        prepare_system(name, cache_dir=cache_dir, progress=progress)
