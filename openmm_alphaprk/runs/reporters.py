"""OpenMM reporters of a run: the α* controller's diagnostics (CSV), positions with velocities (TRR).

Both follow OpenMM's reporter protocol (``describeNextReport``/``report``) and build
their header and each report's values in separate methods, as OpenMM's own reporters do.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass

import numpy as np
import openmm.app as app
import openmm.unit as unit

from .._units import InputError, InputTypeError
from ..integrators import AlphaRattleEnergyIntegrator, restore_integrator
from ..integrators.variables import (
    ALPHA,
    ALPHA_AT_BOUND,
    FELL_BACK,
    MIDPOINT_CHANGE,
    REFERENCE_ENERGY,
    RESIDUAL,
    STEP_FORCE_EVALUATIONS,
    TRIALS,
)
from ..observables import alpha_percentiles, rms

#: Columns written by :class:`AlphaControllerReporter`, with their units.
COLUMNS = (
    "step",
    "time (ps)",
    "alpha",
    "H - E_ref (kJ/mol)",
    "E_ref (kJ/mol)",
    "trials",
    "force evaluations",
    "fell back",
    "alpha at bound",
    "midpoint change (nm)",
)


class AlphaControllerReporter:
    """Write the α* controller's diagnostics of sampled steps to a CSV file as the run goes.

    Follows the OpenMM reporter protocol (``describeNextReport``/``report``), so it
    is added to ``Simulation.reporters`` like ``StateDataReporter``. Every
    ``reportInterval`` steps it writes one row describing the step just taken (α*,
    H − E_ref, trials, force evaluations, fallback, …), read from the integrator's
    global variables; it asks OpenMM for no State data. Set-up (the integrator check,
    the file and its header) happens at the first report. Each row is flushed as it is
    written, so an interrupted run leaves a readable file, and no row is kept in memory.

    The rows are samples. Statistics over every step (fractions fallen back and at a
    bound, force evaluations per step, and, where the integrator accumulates them, RMS
    and max |H − E_ref|) come from ``integrator.controller_totals()``; :meth:`summary`
    combines both. ``reportInterval=1`` records every step but makes ``Simulation``
    take one step at a time with a ``getState`` after each (a host synchronization per
    step on a GPU); the driver uses the energy interval.

    Parameters
    ----------
    file : str or os.PathLike or io.TextIOBase
        A path, or an open text file.
    reportInterval : int, default 1
        Steps between rows.
    append : bool, default False
        Append to an existing file instead of overwriting it (for a resumed run);
        the header is then not written again.

    Raises
    ------
    TypeError
        From ``report``, if the simulation's integrator is not an
        :class:`~openmm_alphaprk.AlphaRattleEnergyIntegrator` (the energy mode).
    ValueError
        From ``report``, if the residual is not finite (fail fast on NaN).

    Examples
    --------
    The energy mode (``energy4``) on the shipped water cluster, a row every 2 steps:

    >>> import io, openmm, openmm.app as app, openmm.unit as unit
    >>> from openmm_alphaprk import AlphaRattleEnergyIntegrator
    >>> from openmm_alphaprk.runs import AlphaControllerReporter
    >>> from openmm_alphaprk.systems import prepare_system
    >>> water = prepare_system("water-cluster")
    >>> integrator = AlphaRattleEnergyIntegrator(2 * unit.femtoseconds, order=4)
    >>> platform = openmm.Platform.getPlatformByName("Reference")
    >>> simulation = app.Simulation(water.topology, water.system, integrator, platform)
    >>> simulation.context.setState(water.state)
    >>> integrator.check_context(simulation.context)
    >>> rows = io.StringIO()
    >>> simulation.reporters.append(AlphaControllerReporter(rows, reportInterval=2))
    >>> simulation.step(4)
    >>> lines = rows.getvalue().splitlines()
    >>> lines[0].split(",")[:4]  # the header: COLUMNS
    ['step', 'time (ps)', 'alpha', 'H - E_ref (kJ/mol)']
    >>> [line.split(",")[0] for line in lines[1:]]  # the steps of the rows
    ['2', '4']
    """

    def __init__(
        self, file: str | os.PathLike | io.TextIOBase, reportInterval: int = 1, append: bool = False
    ):
        if isinstance(reportInterval, bool) or int(reportInterval) != reportInterval or reportInterval < 1:
            raise InputError(f"reportInterval must be a positive integer, got {reportInterval!r}.")
        self._interval = int(reportInterval)
        self._file_argument = file
        self._append = append
        self._out: io.TextIOBase | None = None
        self._writer = None
        self._owns_file = False
        self._integrator: AlphaRattleEnergyIntegrator | None = None
        self._variables: tuple[int, ...] = ()

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        """Return the steps until the next row; no State data is asked for (the row is read from globals)."""
        steps = self._interval - simulation.currentStep % self._interval
        return {"steps": steps, "periodic": None, "include": []}

    def report(self, simulation: app.Simulation, state) -> None:
        """Write one row for the step just taken (set up the file at the first report)."""
        if self._out is None:
            self._initialize(simulation)
        row = self._constructReportValues(simulation, state)
        self._writer.writerow(row)
        self._out.flush()
        self._checkForErrors(row)

    def _initialize(self, simulation: app.Simulation) -> None:
        """Check the integrator, find its variables, open the file and write the header."""
        try:
            integrator = restore_integrator(simulation.integrator)
        except TypeError:  # not one of this package's integrators
            integrator = simulation.integrator
        if not isinstance(integrator, AlphaRattleEnergyIntegrator):
            raise InputTypeError(
                "AlphaControllerReporter needs an AlphaRattleEnergyIntegrator (the energy mode); "
                "use openmm.app.StateDataReporter for other integrators."
            )
        names = [integrator.getGlobalVariableName(i) for i in range(integrator.getNumGlobalVariables())]
        self._integrator = integrator
        self._variables = tuple(names.index(name) for name in _VARIABLES)
        self._open()

    def _constructHeaders(self) -> list[str]:
        """Return the CSV header: :data:`COLUMNS`."""
        return list(COLUMNS)

    def _constructReportValues(self, simulation: app.Simulation, state) -> tuple:
        """Return the row of the step just taken, read from the integrator's global variables."""
        get = self._integrator.getGlobalVariable
        alpha, residual, reference, trials, evaluations, fell_back, at_bound, change = (
            get(i) for i in self._variables
        )
        step = simulation.currentStep
        time = state.getTime()._value if state is not None else step * self._integrator.getStepSize()._value
        return (
            step,
            time,
            alpha,
            residual,
            reference,
            int(trials),
            int(evaluations),
            int(fell_back),
            int(at_bound),
            change,
        )

    @staticmethod
    def _checkForErrors(row: tuple) -> None:
        """Fail fast when the residual is not finite."""
        if not math.isfinite(row[3]):
            raise InputError(
                f"Energy residual is {row[3]} at step {row[0]}: the simulation has become unstable. "
                "Reduce the timestep or check the starting structure."
            )

    def _open(self) -> None:
        if isinstance(self._file_argument, (str, os.PathLike)):
            exists = os.path.exists(self._file_argument) and os.path.getsize(self._file_argument) > 0
            self._out = open(  # noqa: SIM115
                self._file_argument, "a" if self._append else "w", newline="", encoding="utf-8"
            )
            self._owns_file = True
            write_header = not (self._append and exists)
        else:
            self._out = self._file_argument
            write_header = not self._append
        self._writer = csv.writer(self._out)
        if write_header:
            self._writer.writerow(self._constructHeaders())

    def summary(self, energy_tolerance: float | None = None) -> ControllerSummary:
        """Summarize the file written and the integrator's totals (see :func:`summarize_controller`).

        Raises
        ------
        ValueError
            Before the first report, or when the reporter writes to an open file
            object instead of a path (the rows are not kept; read them back yourself).
        """
        if self._integrator is None:
            raise InputError("no report yet: run at least one step with the reporter attached.")
        if not isinstance(self._file_argument, (str, os.PathLike)):
            raise InputError(
                "this reporter writes to a file object and keeps no rows; summarize with "
                "summarize_controller(read_controller_csv(path), totals=integrator.controller_totals())."
            )
        rows = read_controller_csv(self._file_argument)
        return summarize_controller(rows, energy_tolerance, self._integrator.controller_totals())

    def __del__(self) -> None:
        if self._owns_file and self._out is not None:
            self._out.close()


#: The integrator's global variables of a row, in the order of :data:`COLUMNS` after step and time.
_VARIABLES = (
    ALPHA,
    RESIDUAL,
    REFERENCE_ENERGY,
    TRIALS,
    STEP_FORCE_EVALUATIONS,
    FELL_BACK,
    ALPHA_AT_BOUND,
    MIDPOINT_CHANGE,
)

#: ``residuals_over`` of a :class:`ControllerSummary` whose RMS and max cover every step.
EVERY_STEP = "every step"
#: ``residuals_over`` of a :class:`ControllerSummary` whose RMS and max cover the CSV rows only.
ROWS = "controller.csv rows"


@dataclass(frozen=True)
class ControllerSummary:
    """Statistics of the α* controller over a run (energies in kJ/mol).

    Attributes
    ----------
    steps : int
        Steps the statistics cover: the integrator's steps when its totals are given,
        else the number of rows.
    rows : int
        Rows of ``controller.csv`` (sampled steps) summarized.
    alpha_percentiles : dict of str to float
        α* percentiles over the rows (``{"p1": …, "p99": …}``).
    rms_residual, max_abs_residual : float
        RMS and max |H − E_ref| (E_ref: the integrator's reference energy, the start
        state's total energy) over every step when the integrator accumulates them,
        else over the rows; ``residuals_over`` says which.
    residuals_over : str
        :data:`EVERY_STEP` or :data:`ROWS`: what ``rms_residual`` and
        ``max_abs_residual`` cover.
    fraction_within_tolerance : float
        Steps that ended with |H − E_ref| ≤ the energy tolerance.
    fraction_fallen_back : float
        Steps that ended with |H − E_ref| above the energy tolerance: no α trial reached it
        within the bounds and ``max_trials``; the step is then the α = 0 step of its base,
        unless an α trial ended closer to E_ref.
    fraction_at_bound : float
        Steps whose α* sat at a bound of ``alpha_bounds``.
    force_evaluations_per_step : float
        Mean force evaluations per step.

    Examples
    --------
    Made by :func:`summarize_controller` (here from two hand-written rows) and
    :meth:`AlphaControllerReporter.summary`:

    >>> import numpy as np
    >>> from openmm_alphaprk.runs import summarize_controller
    >>> rows = np.array([
    ...     # step, time, alpha, H - E_ref, E_ref, trials, evaluations, fell back, at bound, change
    ...     [2, 0.004, 0.01, 2e-5, -2274.5, 2, 6, 0, 0, 1e-9],
    ...     [4, 0.008, 0.03, -4e-5, -2274.5, 3, 7, 0, 0, 1e-9],
    ... ])
    >>> summary = summarize_controller(rows)
    >>> summary.steps, summary.residuals_over, summary.force_evaluations_per_step
    (2, 'controller.csv rows', 6.5)
    >>> round(summary.alpha_percentiles["p50"], 6), round(summary.rms_residual, 8)
    (0.02, 3.162e-05)
    >>> sorted(summary.as_dict())[:3]
    ['alpha_percentiles', 'force_evaluations_per_step', 'fraction_at_bound']
    """

    steps: int
    rows: int
    alpha_percentiles: dict[str, float]
    rms_residual: float
    max_abs_residual: float
    residuals_over: str
    fraction_within_tolerance: float
    fraction_fallen_back: float
    fraction_at_bound: float
    force_evaluations_per_step: float

    def as_dict(self) -> dict:
        """Plain-dict form (for JSON)."""
        return dict(self.__dict__)


def read_controller_csv(path: str | os.PathLike) -> np.ndarray:
    """Read a file written by :class:`AlphaControllerReporter` into an array (rows × columns).

    Parameters
    ----------
    path : str or os.PathLike
        The CSV file (``controller.csv`` of a run directory of the energy mode).

    Returns
    -------
    numpy.ndarray
        One row per report, the columns of :data:`COLUMNS`.

    Raises
    ------
    ValueError
        If the file does not have the columns of :data:`COLUMNS`.

    Examples
    --------
    The ``controller.csv`` of an ``energy4`` run:

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import read_controller_csv, run_nve
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     _ = run_nve("water-cluster", "energy4", run, steps=8, energy_interval=2,
    ...                 platform="Reference", progress=False)
    ...     rows = read_controller_csv(os.path.join(run, "controller.csv"))
    >>> rows.shape  # a row every energy interval, 10 columns
    (4, 10)
    >>> rows[:, 0]  # the steps
    array([2., 4., 6., 8.])
    """
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.shape[1] != len(COLUMNS):
        raise InputError(
            f"{path} has {data.shape[1]} columns, expected {len(COLUMNS)} ({', '.join(COLUMNS)})."
        )
    return data


def summarize_controller(
    rows: np.ndarray, energy_tolerance: float | None = None, totals: dict | None = None
) -> ControllerSummary:
    """α* percentiles, residual statistics and fractions from controller rows and the integrator's totals.

    Parameters
    ----------
    rows : numpy.ndarray
        Array with the columns of :data:`COLUMNS` (from :func:`read_controller_csv`).
    energy_tolerance : float, optional
        If given (kJ/mol), "within tolerance" is |H − E_ref| ≤ this over the rows;
        otherwise the integrator's verdict (its totals, or the rows' ``fell back`` column).
    totals : dict, optional
        ``integrator.controller_totals()``: counts over every step. The fractions and
        force evaluations per step are taken from it, and RMS and max |H − E_ref| when
        it has ``rms_residual`` and ``max_abs_residual``; without it, everything comes
        from the rows.

    Returns
    -------
    ControllerSummary

    Raises
    ------
    ValueError
        If there are no rows.

    Examples
    --------
    Two hand-written rows, the tolerance given:

    >>> import numpy as np
    >>> from openmm_alphaprk.runs import summarize_controller
    >>> rows = np.array([
    ...     # step, time, alpha, H - E_ref, E_ref, trials, evaluations, fell back, at bound, change
    ...     [2, 0.004, 0.01, 2e-5, -2274.5, 2, 6, 0, 0, 1e-9],
    ...     [4, 0.008, 0.03, -4e-5, -2274.5, 3, 7, 0, 0, 1e-9],
    ... ])
    >>> summary = summarize_controller(rows, energy_tolerance=3e-5)
    >>> summary.fraction_within_tolerance, summary.max_abs_residual
    (0.5, 4e-05)
    """
    rows = np.asarray(rows, dtype=float)
    if rows.ndim != 2 or rows.shape[0] == 0:
        raise InputError("No controller rows to summarize: run at least one step with the reporter attached.")
    alpha, residual = rows[:, 2], rows[:, 3]
    if energy_tolerance is not None:
        within = float(np.mean(np.abs(residual) <= energy_tolerance))
    elif totals:
        within = float(totals["fraction_within_tolerance"])
    else:
        within = float(np.mean(rows[:, 7] == 0))
    every_step = bool(totals) and "rms_residual" in totals and "max_abs_residual" in totals
    steps = int(totals["steps"]) if totals else int(rows.shape[0])
    return ControllerSummary(
        steps=steps,
        rows=int(rows.shape[0]),
        alpha_percentiles=alpha_percentiles(alpha),
        rms_residual=float(totals["rms_residual"]) if every_step else rms(residual),
        max_abs_residual=float(totals["max_abs_residual"]) if every_step else float(np.max(np.abs(residual))),
        residuals_over=EVERY_STEP if every_step else ROWS,
        fraction_within_tolerance=within,
        fraction_fallen_back=float(totals["fraction_fallen_back"]) if totals else float(np.mean(rows[:, 7])),
        fraction_at_bound=float(totals["fraction_at_bound"]) if totals else float(np.mean(rows[:, 8])),
        force_evaluations_per_step=float(totals["force_evaluations_per_step"])
        if totals
        else float(np.mean(rows[:, 6])),
    )


class TRRReporter:
    """Write positions, velocities and the box to a GROMACS TRR file as the run goes.

    OpenMM has no reporter of velocities. This one follows OpenMM's reporter protocol
    (``describeNextReport``/``report``) and writes each frame with MDAnalysis' own TRR
    writer (``MDAnalysis.lib.formats.libmdaxdr.TRRFile``): positions in nm, velocities
    in nm/ps, the box, the step and the time (ps), in single precision, as GROMACS writes
    them. MDAnalysis, GROMACS, MDTraj and ``physical_validation`` read it
    (``MDAnalysis.Universe(topology, file)``: ``atoms.positions`` in Å,
    ``atoms.velocities`` in Å/ps). Positions are not wrapped into the box (as the run
    driver's DCD), so displacements can be read from them. Frames are written at steps
    that are multiples of ``reportInterval``, as by ``DCDReporter``. A TRR file is a
    sequence of self-contained frames: each is written whole to a scratch file beside
    the file (the writer opens only new files) and appended to it in one write, then
    flushed, so an interrupted run leaves every complete frame readable and
    :func:`~openmm_alphaprk.runs.rundir.truncate_trr` cuts a partial one off.

    Parameters
    ----------
    file : str or os.PathLike
        Path of the TRR file.
    reportInterval : int
        Steps between frames.
    append : bool, default False
        Append to an existing file (for a resumed run) instead of starting a new one.

    Raises
    ------
    ValueError
        From ``report``, if a position or velocity is not finite (fail fast on NaN).

    Examples
    --------
    Positions and velocities of the shipped water cluster every 2 steps, read back with
    MDAnalysis:

    >>> import os, tempfile, MDAnalysis, openmm, openmm.app as app, openmm.unit as unit
    >>> from openmm_alphaprk import RattleIntegrator
    >>> from openmm_alphaprk.runs import TRRReporter
    >>> from openmm_alphaprk.systems import prepare_system
    >>> water = prepare_system("water-cluster")
    >>> platform = openmm.Platform.getPlatformByName("Reference")
    >>> simulation = app.Simulation(water.topology, water.system, RattleIntegrator(0.002), platform)
    >>> simulation.context.setState(water.state)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "trajectory.trr")
    ...     simulation.reporters.append(TRRReporter(path, 2))
    ...     simulation.step(4)
    ...     with open(os.path.join(folder, "topology.pdb"), "w") as pdb:
    ...         app.PDBFile.writeFile(water.topology, water.state.getPositions(), pdb)
    ...     universe = MDAnalysis.Universe(os.path.join(folder, "topology.pdb"), path)
    ...     frames = universe.trajectory.n_frames
    ...     last = universe.trajectory[-1].velocities / 10  # Å/ps → nm/ps
    ...     step, time = universe.trajectory.ts.data["step"], universe.trajectory.time
    >>> state = simulation.context.getState(getVelocities=True)
    >>> velocities = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
    >>> frames, step, round(time, 6), bool(abs(last - velocities).max() < 1e-5)  # stored as float32
    (2, 4, 0.008, True)
    """

    def __init__(self, file: str | os.PathLike, reportInterval: int, append: bool = False):
        if isinstance(reportInterval, bool) or int(reportInterval) != reportInterval or reportInterval < 1:
            raise InputError(f"reportInterval must be a positive integer, got {reportInterval!r}.")
        self._path = os.fspath(file)
        self._scratch = self._path + ".frame"
        self._interval = int(reportInterval)
        self._append = append
        self._handle = None

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        steps = self._interval - simulation.currentStep % self._interval
        return {"steps": steps, "periodic": False, "include": ["positions", "velocities"]}

    def report(self, simulation: app.Simulation, state) -> None:
        """Write one frame: the State's positions, velocities and box."""
        from MDAnalysis.lib.formats.libmdaxdr import (
            TRRFile,
        )  # not at import: the CLI starts without MDAnalysis

        positions, velocities, box = self._constructReportValues(simulation, state)
        if self._handle is None:
            self._handle = open(self._path, "ab" if self._append else "wb")
        with TRRFile(self._scratch, "w") as frame:
            frame.write(
                positions,
                velocities,
                None,
                box,
                simulation.currentStep,
                state.getTime().value_in_unit(unit.picoseconds),
                0.0,
                len(positions),
            )
        with open(self._scratch, "rb") as frame:
            self._handle.write(frame.read())
        self._handle.flush()

    @staticmethod
    def _constructReportValues(
        simulation: app.Simulation, state
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return positions (nm), velocities (nm/ps) and box vectors (nm, 3 × 3), checked to be finite."""
        positions = state.getPositions(asNumpy=True).value_in_unit(unit.nanometers)
        velocities = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(velocities))):
            raise InputError(
                f"non-finite position or velocity at step {simulation.currentStep}: the simulation has "
                "blown up; use a smaller step size."
            )
        box = state.getPeriodicBoxVectors(asNumpy=True).value_in_unit(unit.nanometers)
        return positions, velocities, np.asarray(box, dtype=float)

    def __del__(self):
        if self._handle is not None:
            self._handle.close()
        if os.path.exists(self._scratch):
            os.remove(self._scratch)
