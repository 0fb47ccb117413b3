"""The invariants of a long OpenMM run: a reporter that records them, and their summary for the JSON.

:class:`InvariantReporter` records, every ``interval`` steps, the change of the
angular and linear momentum, their scales, the constraint errors and H;
:func:`long_run_entry` turns its rows into the numbers and series of one run.
"""

from __future__ import annotations

import numpy as np

from openmm_alphaprk import observables
from openmm_alphaprk.reference.step import Array


class InvariantReporter:
    """OpenMM reporter: change of L and P, scales, constraint errors and H every ``interval`` steps.

    The rows are kept in :attr:`rows`: the first is the start (step 0, no change, the
    scales and constraint errors, no energy), then one per report: step, |ΔL|, |ΔP|,
    Σm|x − x_cm||v|, Σm|v|, max relative constraint error, max |v·r|/|r|, H.

    Parameters
    ----------
    system
        The ``openmm.System`` (masses and constraints are read from it).
    start
        The start ``openmm.State`` (positions and velocities), against which L and P change.
    interval
        Steps between rows.
    """

    def __init__(self, system, start, interval: int) -> None:
        self.masses = observables.masses(system)
        self.pairs, self.lengths = observables.system_constraints(system)
        self.interval = interval
        x, v = self._arrays(start)
        self.l0, self.p0 = self._momenta(x, v)
        self.rows: list[list[float]] = [[0, 0.0, 0.0, *self._scales(x, v), *self._constraint_errors(x, v)]]

    @staticmethod
    def _arrays(state) -> tuple[Array, Array]:
        import openmm.unit as unit

        return (
            state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
            state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
        )

    def _momenta(self, x: Array, v: Array) -> tuple[Array, Array]:
        linear, angular = observables.momenta(self.masses, x, v)
        return angular, linear

    def _scales(self, x: Array, v: Array) -> tuple[float, float]:
        """Return Σ m|x − x_cm||v| (amu nm²/ps) and Σ m|v| (amu nm/ps): what L and P are sums of."""
        centre = self.masses @ x / self.masses.sum()
        speed = np.linalg.norm(v, axis=1)
        return (
            float(np.sum(self.masses * np.linalg.norm(x - centre, axis=1) * speed)),
            float(np.sum(self.masses * speed)),
        )

    def _constraint_errors(self, x: Array, v: Array) -> tuple[float, float]:
        return observables.constraint_errors(self.pairs, self.lengths, x, v)

    def describeNextReport(self, simulation) -> dict:
        """Ask for positions, velocities and energy every ``interval`` steps."""
        steps = self.interval - simulation.currentStep % self.interval
        return {"steps": steps, "periodic": None, "include": ["positions", "velocities", "energy"]}

    def _constructReportValues(self, simulation, state) -> list[float]:
        """Return a row: step, |ΔL|, |ΔP|, the scales, the constraint errors, H."""
        x, v = self._arrays(state)
        angular, linear = self._momenta(x, v)
        return [
            simulation.currentStep,
            float(np.linalg.norm(angular - self.l0)),
            float(np.linalg.norm(linear - self.p0)),
            *self._scales(x, v),
            *self._constraint_errors(x, v),
            observables.total_energy(state),
        ]

    def report(self, simulation, state) -> None:
        """Append a row: step, |ΔL|, |ΔP|, the scales, the constraint errors, H."""
        self.rows.append(self._constructReportValues(simulation, state))


def series(values: Array) -> list[float]:
    """Round to four significant digits: the series are for the figures, the tables use full precision."""
    return [float(f"{value:.4g}") for value in values]


def long_run_entry(reporter: InvariantReporter, e_ref: float, timestep_ps: float, extra: dict) -> dict:
    """Summarise a reporter's rows: series against time, their maxima, scales and H − E_ref.

    Parameters
    ----------
    reporter
        The reporter of the run.
    e_ref
        The reference energy (kJ/mol).
    timestep_ps
        The step, to turn steps into time.
    extra
        Entries put first (steps, force evaluations, ...).

    Returns
    -------
    dict
        One run's entry of ``long_runs`` in the JSON.
    """
    start, rows = reporter.rows[0], np.array(reporter.rows[1:], dtype=float)
    steps, dl, dp, scale_l, scale_p, c_pos, c_vel, energy = rows.T
    residual = energy - e_ref
    return {
        **extra,
        "time_ps": series(steps * timestep_ps),
        "angular_change": series(dl),
        "linear_change": series(dp),
        "constraint_error_change": series(c_pos - start[5]),
        "energy_residual": series(residual),
        "angular_scale": float(np.mean(scale_l)),
        "linear_scale": float(np.mean(scale_p)),
        "max_angular_change": float(dl.max()),
        "max_relative_angular_change": float(dl.max() / np.mean(scale_l)),
        "max_linear_change": float(dp.max()),
        "max_relative_linear_change": float(dp.max() / np.mean(scale_p)),
        "start_constraint_error": start[5],
        "max_constraint_error": float(c_pos.max()),
        "max_constraint_velocity_error": float(c_vel.max()),
        "rms_energy_residual": observables.rms(residual),
        "max_abs_energy_residual": float(np.max(np.abs(residual))),
    }
