"""Running a sweep's cells on dask and keeping its table (see :mod:`..sweep`)."""

from __future__ import annotations

import csv
import json
import os
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .config import Cell, SweepConfig, load_config

#: Name of the collected table in the sweep's output folder.
TABLE_FILE = "sweep.csv"
#: Written into a cell's run directory when its run failed.
ERROR_FILE = "error.json"
#: The first columns of the table; the summary's fields follow.
CELL_COLUMNS = ("cell", "system", "integrator", "timestep_fs", "seed", "steps", "status", "error", "run_dir")


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


def run_cell(cell: Cell, directory: str | os.PathLike, cache_dir: str | None = None) -> dict[str, Any]:
    """Run one cell (on a dask worker); return its table row. Never raises for a failed run.

    A failed run's error is written to ``error.json`` in the run directory and returned
    in the row (``status = "failed"``); whatever the run wrote stays.
    """
    from ...runs import run_nve

    directory = Path(directory)
    row = _cell_row(cell, directory)
    (directory / ERROR_FILE).unlink(missing_ok=True)
    try:
        summary = run_nve(
            cell.system, cell.integrator, directory, cell.options(cache_dir=cache_dir, progress=False)
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
        if summary.get("steps", 0) == cell.steps:  # a longer run is refused by run_nve, not reported
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
    config : SweepConfig or str or os.PathLike
        A :class:`SweepConfig` or the path of a TOML configuration.
    output : str or os.PathLike, optional
        Output folder (default: the configuration's ``output``).
    scheduler : str, optional
        Address of a running dask scheduler (``tcp://host:8786``; default: the
        configuration's). Without one, a ``LocalCluster`` is started for this sweep.
    n_workers : int, optional
        Workers of the ``LocalCluster`` (default: the configuration's, else 1). Each
        worker runs one cell at a time; on the CPU platform give each run
        ``cpu_threads`` so that workers × threads ≤ cores.
    processes : bool, default True
        The ``LocalCluster``'s workers are processes (False: threads in this process).
    retry_failed : bool, default False
        Run cells again that failed in an earlier call (default: keep their error).
    cache_dir : str or os.PathLike, optional
        Cache of prepared systems (see :func:`~openmm_alphaprk.systems.prepare_system`).
    progress : bool, default True
        Print one line per finished cell on stderr.
    on_row : callable, optional
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

    Examples
    --------
    Four 20 fs runs of the water cluster on one worker thread (about a second); a
    second call finds them finished:

    >>> import os, tempfile
    >>> from openmm_alphaprk.workflows import load_config
    >>> CONFIG = '''
    ... output = "sweep-out"
    ... [run]
    ... duration_ps = 0.02
    ... platform = "Reference"
    ... energy_interval_fs = 4
    ... [[grid]]
    ... systems = ["water-cluster"]
    ... integrators = ["rattle", "alpha={alpha}"]
    ... timesteps_fs = [2, 1]
    ... alphas = ["1/6"]
    ... '''
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = os.path.join(folder.name, "sweep.toml")
    >>> with open(path, "w") as file:
    ...     _ = file.write(CONFIG)
    >>> config = load_config(path)
    >>> from openmm_alphaprk.workflows import run_sweep
    >>> result = run_sweep(config, processes=False, progress=False)
    >>> result.table.name, len(result.ran), result.failed
    ('sweep.csv', 4, [])
    >>> for row in result.rows:  # in the configuration's order
    ...     print(row["integrator"], row["timestep_fs"], row["steps"], row["status"])
    rattle 2.0 10 ok
    rattle 1.0 20 ok
    alpha=1/6 2.0 10 ok
    alpha=1/6 1.0 20 ok
    >>> again = run_sweep(config, processes=False, progress=False)
    >>> again.ran, len(again.skipped)
    ([], 4)
    >>> folder.cleanup()
    """
    if not isinstance(config, SweepConfig):
        config = load_config(config)
    dask = _dask()
    root = Path(output) if output is not None else config.output
    root.mkdir(parents=True, exist_ok=True)
    sweep = _Sweep(config, root, None if cache_dir is None else str(cache_dir), progress, on_row)
    pending = sweep.collect_finished(retry_failed)
    if pending:
        _prepare_systems({cell.system for cell in pending}, sweep.cache, progress)
        sweep.run(pending, dask, scheduler or config.scheduler, n_workers or config.n_workers, processes)
    sweep.result.rows = sweep.ordered()
    return sweep.result


def _dask() -> tuple:
    """Return dask.distributed's Client, LocalCluster and as_completed, or say how to install it."""
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError as error:  # pragma: no cover - the test extra installs it
        raise ImportError(
            "sweeps need dask.distributed: pip install 'openmm-alphaprk[sweep]' (or 'dask[distributed]')."
        ) from error
    return Client, LocalCluster, as_completed


class _Sweep:
    """The state of one :func:`run_sweep` call: the rows so far, the table, the result."""

    def __init__(self, config: SweepConfig, root: Path, cache: str | None, progress: bool, on_row) -> None:
        self.config, self.root, self.cache, self.progress, self.on_row = config, root, cache, progress, on_row
        self.table = root / TABLE_FILE
        self.rows: dict[str, dict[str, Any]] = {}
        self.result = SweepResult(table=self.table, rows=[])

    def ordered(self) -> list[dict[str, Any]]:
        """Return the rows in the configuration's order of cells."""
        return [self.rows[cell.name] for cell in self.config.cells if cell.name in self.rows]

    def collect_finished(self, retry_failed: bool) -> list[Cell]:
        """Take the rows of finished (and failed) cells, write the table; return the cells to run."""
        pending: list[Cell] = []
        for cell in self.config.cells:
            row = cell_status(cell, self.root / cell.name)
            if row is None or (retry_failed and row["status"] == "failed"):
                pending.append(cell)
                continue
            self.rows[cell.name] = row
            self.result.skipped.append(cell.name)
            if row["status"] == "failed":
                self.result.failed.append(cell.name)
        write_table(self.table, self.ordered())
        if self.progress:
            print(
                f"sweep: {len(pending)} to run, {len(self.result.skipped)} finished before", file=sys.stderr
            )
        return pending

    def run(
        self, pending: list[Cell], dask: tuple, address: str | None, workers: int, processes: bool
    ) -> None:
        """Run the pending cells on the scheduler at ``address``, else on a local cluster of ``workers``."""
        client_class, cluster_class, as_completed = dask
        cluster = (
            None
            if address
            else cluster_class(
                n_workers=workers, threads_per_worker=1, processes=processes, dashboard_address=":0"
            )
        )
        started = time.perf_counter()
        try:
            with client_class(address or cluster) as client:
                futures = {
                    client.submit(
                        run_cell,
                        cell,
                        str(self.root / cell.name),
                        self.cache,
                        pure=False,
                        key=f"cell-{cell.name}",
                    ): cell
                    for cell in pending
                }
                for future in as_completed(futures):
                    self._record(futures[future], future.result(), len(pending), started)
        finally:
            if cluster is not None:
                cluster.close()

    def _record(self, cell: Cell, row: dict[str, Any], pending: int, started: float) -> None:
        """Keep a finished cell's row, rewrite the table and report it."""
        self.rows[cell.name] = row
        self.result.ran.append(cell.name)
        if row["status"] == "failed":
            self.result.failed.append(cell.name)
        write_table(self.table, self.ordered())
        if self.on_row is not None:
            self.on_row(row)
        if self.progress:
            print(
                f"[{len(self.result.ran)}/{pending}, {time.perf_counter() - started:.0f} s] {cell.name}: "
                f"{row['status']}{' - ' + row['error'] if row['error'] else ''}",
                file=sys.stderr,
            )


def _prepare_systems(names: set[str], cache_dir: str | None, progress: bool) -> None:
    """Build (or find cached) each system once, before the workers start, so they never race to build it."""
    from ...systems import prepare_system

    for name in sorted(names):
        prepare_system(name, cache_dir=cache_dir, progress=progress)
