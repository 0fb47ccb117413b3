"""OpenMM reporters of a run: the α* controller's diagnostics (CSV) and velocities (DCD).

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

from ..integrators import AlphaRattleIntegrator, restore_integrator
from ..integrators.controller import (
    ALPHA,
    ALPHA_AT_BOUND,
    FELL_BACK,
    MIDPOINT_CHANGE,
    REFERENCE_ENERGY,
    RESIDUAL,
    STEP_FORCE_EVALUATIONS,
    TRIALS,
)
from ..observables import alpha_percentiles

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
    """Write the α* controller's per-step diagnostics to a CSV file as the run goes.

    Follows the OpenMM reporter protocol (``describeNextReport``/``report``), so it
    is added to ``Simulation.reporters`` like ``StateDataReporter``. The file is
    opened on the first report and flushed after every row, so an interrupted run
    leaves a readable file. With ``reportInterval=1`` (the default) every step is
    recorded; with a larger interval each row describes the step just taken.

    Parameters
    ----------
    file
        A path, or an open text file.
    reportInterval
        Steps between rows.
    append
        Append to an existing file instead of overwriting it (for a resumed run);
        the header is then not written again.

    Raises
    ------
    ValueError
        From ``report``, if the residual is not finite (fail fast on NaN).
    """

    def __init__(
        self, file: str | os.PathLike | io.TextIOBase, reportInterval: int = 1, append: bool = False
    ):
        if isinstance(reportInterval, bool) or int(reportInterval) != reportInterval or reportInterval < 1:
            raise ValueError(f"reportInterval must be a positive integer, got {reportInterval!r}.")
        self._interval = int(reportInterval)
        self._file_argument = file
        self._append = append
        self._out: io.TextIOBase | None = None
        self._writer = None
        self._owns_file = False
        self.rows: list[tuple[float, ...]] = []

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        """Return the steps until the next report; this reporter needs no state data."""
        steps = self._interval - simulation.currentStep % self._interval
        return {"steps": steps, "periodic": None, "include": []}

    def report(self, simulation: app.Simulation, state) -> None:
        """Append one row for the step just taken."""
        row = self._constructReportValues(simulation, state)
        if self._out is None:
            self._open()
        self.rows.append(row)
        self._writer.writerow(row)
        self._out.flush()
        self._checkForErrors(row)

    def _constructHeaders(self) -> list[str]:
        """Return the CSV header: :data:`COLUMNS`."""
        return list(COLUMNS)

    def _constructReportValues(self, simulation: app.Simulation, state) -> tuple:
        """Return the row of the step just taken, read from the integrator's global variables."""
        integrator = restore_integrator(simulation.integrator)
        if not isinstance(integrator, AlphaRattleIntegrator) or not integrator.energy_mode:
            raise TypeError(
                "AlphaControllerReporter needs an AlphaRattleIntegrator in the energy mode "
                "(alpha='energy'); use openmm.app.StateDataReporter for other integrators."
            )
        get = integrator.getGlobalVariableByName
        return (
            simulation.currentStep,
            state.getTime()._value
            if state is not None
            else simulation.currentStep * integrator.getStepSize()._value,
            get(ALPHA),
            get(RESIDUAL),
            get(REFERENCE_ENERGY),
            int(get(TRIALS)),
            int(get(STEP_FORCE_EVALUATIONS)),
            int(get(FELL_BACK)),
            int(get(ALPHA_AT_BOUND)),
            get(MIDPOINT_CHANGE),
        )

    @staticmethod
    def _checkForErrors(row: tuple) -> None:
        """Fail fast when the residual is not finite."""
        if not math.isfinite(row[3]):
            raise ValueError(
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
        """Summary statistics of the rows recorded by this reporter object."""
        return summarize_controller(np.array(self.rows, dtype=float), energy_tolerance)

    def __del__(self) -> None:
        if self._owns_file and self._out is not None:
            self._out.close()


@dataclass(frozen=True)
class ControllerSummary:
    """Statistics of the α* controller over a run (kJ/mol for energies)."""

    steps: int
    alpha_percentiles: dict[str, float]
    rms_residual: float
    max_abs_residual: float
    fraction_within_tolerance: float
    fraction_fallen_back: float
    fraction_at_bound: float
    force_evaluations_per_step: float

    def as_dict(self) -> dict:
        """Plain-dict form (for JSON)."""
        return dict(self.__dict__)


def read_controller_csv(path: str | os.PathLike) -> np.ndarray:
    """Read a file written by :class:`AlphaControllerReporter` into an array (rows × columns)."""
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.shape[1] != len(COLUMNS):
        raise ValueError(
            f"{path} has {data.shape[1]} columns, expected {len(COLUMNS)} ({', '.join(COLUMNS)})."
        )
    return data


def summarize_controller(rows: np.ndarray, energy_tolerance: float | None = None) -> ControllerSummary:
    """α percentiles, residual statistics and fractions from controller rows.

    Parameters
    ----------
    rows
        Array with the columns of :data:`COLUMNS` (from the reporter, or
        :func:`read_controller_csv`).
    energy_tolerance
        If given (kJ/mol), "within tolerance" is |H − E_ref| ≤ this; otherwise the
        integrator's own verdict per step (``fell back`` column) is used.
    """
    rows = np.asarray(rows, dtype=float)
    if rows.ndim != 2 or rows.shape[0] == 0:
        raise ValueError("No controller rows to summarize: run at least one step with the reporter attached.")
    alpha, residual = rows[:, 2], rows[:, 3]
    within = np.abs(residual) <= energy_tolerance if energy_tolerance is not None else rows[:, 7] == 0
    return ControllerSummary(
        steps=int(rows.shape[0]),
        alpha_percentiles=alpha_percentiles(alpha),
        rms_residual=float(np.sqrt(np.mean(residual**2))),
        max_abs_residual=float(np.max(np.abs(residual))),
        fraction_within_tolerance=float(np.mean(within)),
        fraction_fallen_back=float(np.mean(rows[:, 7])),
        fraction_at_bound=float(np.mean(rows[:, 8])),
        force_evaluations_per_step=float(np.mean(rows[:, 6])),
    )


class VelocityDCDReporter:
    """Write atom velocities to a DCD file as the run goes (for velocity autocorrelations).

    OpenMM's ``DCDReporter`` writes positions only. This reporter writes each frame's
    velocities through OpenMM's own ``app.DCDFile`` in place of positions; the file then
    holds **velocities in Å/ps** where a DCD holds coordinates in Å, and MDAnalysis reads
    them back as ``Universe(topology, file).atoms.positions`` (see
    :class:`~openmm_alphaprk.analysis.VelocityAutocorrelation`, ``source="positions"``).
    Frames are written at steps that are multiples of ``reportInterval``, as by
    ``DCDReporter``, and the file is flushed after each.

    Parameters
    ----------
    file
        Path of the DCD file.
    reportInterval
        Steps between frames.
    append
        Append to an existing file written by this reporter (for a resumed run).

    Raises
    ------
    ValueError
        From ``report``, if a velocity is not finite (fail fast on NaN).
    """

    def __init__(self, file: str | os.PathLike, reportInterval: int, append: bool = False):
        if isinstance(reportInterval, bool) or int(reportInterval) != reportInterval or reportInterval < 1:
            raise ValueError(f"reportInterval must be a positive integer, got {reportInterval!r}.")
        self._path = os.fspath(file)
        self._interval = int(reportInterval)
        self._append = append
        self._handle = None
        self._dcd = None

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        steps = self._interval - simulation.currentStep % self._interval
        return {"steps": steps, "periodic": None, "include": ["velocities"]}

    def report(self, simulation: app.Simulation, state) -> None:
        """Write one frame: the State's velocities."""
        velocities = self._constructReportValues(simulation, state)
        if self._dcd is None:
            self._open(simulation)
        # Velocities (nm/ps) typed as nm: DCDFile stores them ×10, i.e. in Å/ps.
        self._dcd.writeModel(unit.Quantity(velocities, unit.nanometers))
        self._handle.flush()

    @staticmethod
    def _constructReportValues(simulation: app.Simulation, state) -> np.ndarray:
        """Return the State's velocities in nm/ps, checked to be finite."""
        velocities = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
        if not np.all(np.isfinite(velocities)):
            raise ValueError(
                f"non-finite velocity at step {simulation.currentStep}: the simulation has blown up; "
                "use a smaller step size."
            )
        return velocities

    def _open(self, simulation: app.Simulation) -> None:
        """Open the file and write the DCD header (or take over the header of the file appended to)."""
        self._handle = open(self._path, "r+b" if self._append else "wb")
        self._dcd = app.DCDFile(
            self._handle,
            simulation.topology,
            simulation.integrator.getStepSize(),
            simulation.currentStep,
            self._interval,
            self._append,
        )

    def __del__(self):
        if self._handle is not None:
            self._handle.close()
