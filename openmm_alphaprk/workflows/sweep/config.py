"""A sweep's configuration: read, checked and expanded into cells (see :mod:`..sweep`)."""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from ..._units import InputError
from ...runs import rundir
from ...runs.options import DEFAULTS, INTERVALS, NAMED_OPTIONS, OPTIONAL_INTERVALS, RunOptions

#: Keys of ``[run]`` (and of a grid): the run options, with times in fs instead of steps.
_RUN_KEYS = {"duration_ps"} | {f"{name}_fs" for name in INTERVALS} | set(NAMED_OPTIONS)
_GRID_KEYS = {"systems", "integrators", "timesteps_fs", "alphas", "seeds"} | _RUN_KEYS
_RUN_DEFAULTS: dict[str, Any] = {name: getattr(DEFAULTS, name) for name in NAMED_OPTIONS} | {
    "energy_interval_fs": 20.0,
    "trajectory_interval_fs": 100.0,
    "checkpoint_interval_fs": 1000.0,
    "velocity_interval_fs": None,
    "controller_interval_fs": None,
}


class SweepConfigError(InputError):
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
        Fields of :class:`~openmm_alphaprk.runs.RunOptions` besides these.
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

    def options(self, **execution: Any) -> RunOptions:
        """Return the cell's :class:`~openmm_alphaprk.runs.RunOptions`; ``execution``: cache_dir, progress."""
        return RunOptions(
            steps=self.steps,
            timestep=float(self.timestep_fs) / 1000.0,
            velocity_seed=self.seed,
            **self.kwargs(),
            **execution,
        )


@dataclass(frozen=True)
class SweepConfig:
    """A parsed sweep configuration: the cells, where they go and how they run.

    Attributes
    ----------
    cells : tuple of Cell
        Every run of the sweep, in the configuration's order, each once.
    output : pathlib.Path
        Folder of the run directories and the table (relative paths: from the
        configuration file's folder).
    n_workers : int, default 1
        Size of the ``LocalCluster`` (``[cluster] n_workers``).
    scheduler : str, optional
        Address of a running dask scheduler (``[cluster] scheduler``) instead.

    Examples
    --------
    Made by :func:`load_config` (or :func:`parse_config` from a dict): one grid of
    1 system × 2 integrators × 2 step sizes:

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
    >>> len(config.cells), config.output.name, config.n_workers, config.scheduler
    (4, 'sweep-out', 1, None)
    >>> cell = config.cells[-1]
    >>> cell.name, cell.integrator, cell.timestep_fs, cell.steps
    ('water-cluster__alpha=1_6__1fs__start', 'alpha=1/6', Fraction(1, 1), 20)
    >>> cell.options().energy_interval  # 4 fs at 1 fs
    4
    >>> folder.cleanup()
    """

    cells: tuple[Cell, ...]
    output: Path
    n_workers: int = 1
    scheduler: str | None = None


def load_config(path: str | os.PathLike) -> SweepConfig:
    """Read and check a sweep configuration file (TOML); see :mod:`openmm_alphaprk.workflows.sweep`.

    Parameters
    ----------
    path : str or os.PathLike
        The configuration file.

    Returns
    -------
    SweepConfig

    Raises
    ------
    SweepConfigError
        For a missing file, unknown keys, unknown systems or integrators, a step size
        that does not divide a duration or interval, and other bad entries.

    Examples
    --------
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
    >>> [cell.name for cell in config.cells]  # doctest: +NORMALIZE_WHITESPACE
    ['water-cluster__rattle__2fs__start', 'water-cluster__rattle__1fs__start',
     'water-cluster__alpha=1_6__2fs__start', 'water-cluster__alpha=1_6__1fs__start']
    >>> with open(path, "w") as file:
    ...     _ = file.write(CONFIG.replace("water-cluster", "tip3p-9nm"))
    >>> load_config(path)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.workflows.sweep.config.SweepConfigError: ...: unknown system 'tip3p-9nm'; ...
    >>> folder.cleanup()
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
    """Check a ``[[grid]]`` table and yield its cells (systems × integrators × steps × seeds)."""
    if not isinstance(grid, dict):
        raise SweepConfigError(f"{where}: must be a table.")
    unknown = set(grid) - _GRID_KEYS
    if unknown:
        raise SweepConfigError(f"{where}: unknown keys {sorted(unknown)}; allowed: {sorted(_GRID_KEYS)}.")
    for key in ("systems", "integrators", "timesteps_fs"):
        if not isinstance(grid.get(key), list) or not grid[key]:
            raise SweepConfigError(f"{where}: give `{key}` as a non-empty list.")
    systems = _systems(grid, where)
    integrators = _integrators(grid, where)
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
                kwargs = _run_kwargs(run, h, where)
                for seed in seeds:
                    yield Cell(system, integrator, h, seed, steps, tuple(sorted(kwargs.items())))


def _systems(grid: dict[str, Any], where: str) -> list[str]:
    """Return the grid's system names, each checked to be defined."""
    from ...systems import load_definition

    systems = [str(name) for name in grid["systems"]]
    for name in systems:
        try:
            load_definition(name)
        except KeyError as error:
            raise SweepConfigError(f"{where}: {error}") from error
    return systems


def _integrators(grid: dict[str, Any], where: str) -> list[str]:
    """Return the grid's integrator names, ``{alpha}`` filled with each of ``alphas``, each checked."""
    from ...runs.integrator_names import parse_integrator

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
    return integrators


def _run_kwargs(run: dict[str, Any], h: Fraction, where: str) -> dict[str, Any]:
    """Return the run options of a cell with step ``h``: times in fs become steps."""
    kwargs = {name: run[name] for name in NAMED_OPTIONS}
    kwargs["constraint_tolerance"] = float(run["constraint_tolerance"])
    for name in INTERVALS:
        time_fs = run[f"{name}_fs"]
        if name not in OPTIONAL_INTERVALS or time_fs:  # None or 0: no velocities; controller: energy interval
            kwargs[name] = _steps(time_fs, h, f"{where}: {name}_fs")
    return kwargs


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
