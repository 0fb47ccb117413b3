"""Parameter sweeps: a grid of NVE runs executed with ``dask.distributed``.

A sweep configuration (TOML) names one or more grids; each grid is the product
systems × integrators × step sizes × α × seeds, and every point (a *cell*) is an
independent :func:`~openmm_alphaprk.runs.run_nve` run in its own run directory under
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
    velocity_interval_fs = 4        # optional: trajectory.trr, positions and velocities, for VACF (0: none)
    controller_interval_fs = 20     # optional: energy mode's controller.csv rows (default: energy interval)
    checkpoint_seconds = 60         # optional: also checkpoint after this much wall time (s)
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
at least one. Integrator names are those of :mod:`openmm_alphaprk.runs.integrator_names`; an integrator
name containing ``{alpha}`` is expanded over ``alphas``, the others are not.

:mod:`.config` reads, checks and expands the configuration into cells; :mod:`.runner`
runs them and keeps the table.
"""

from .config import Cell, SweepConfig, SweepConfigError, load_config, parse_config
from .runner import (
    CELL_COLUMNS,
    ERROR_FILE,
    TABLE_FILE,
    SweepResult,
    cell_status,
    read_table,
    run_cell,
    run_sweep,
    write_table,
)

__all__ = [
    "CELL_COLUMNS",
    "ERROR_FILE",
    "TABLE_FILE",
    "Cell",
    "SweepConfig",
    "SweepConfigError",
    "SweepResult",
    "cell_status",
    "load_config",
    "parse_config",
    "read_table",
    "run_cell",
    "run_sweep",
    "write_table",
]
