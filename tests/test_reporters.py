"""AlphaControllerReporter: constant memory, no State data, rows as samples, totals over every step."""

from __future__ import annotations

import tracemalloc

import numpy as np
import openmm as mm
import openmm.app as app
import pytest

from openmm_alphaprk import AlphaRattleEnergyIntegrator
from openmm_alphaprk.reference import to_openmm_system, water_cluster
from openmm_alphaprk.runs import reporters
from openmm_alphaprk.runs.reporters import (
    COLUMNS,
    EVERY_STEP,
    ROWS,
    AlphaControllerReporter,
    read_controller_csv,
    summarize_controller,
)

REFERENCE = mm.Platform.getPlatformByName("Reference")


def _simulation() -> app.Simulation:
    """Eight rigid TIP3P waters in vacuum, α-RATTLE's energy mode on the Reference platform: cheap steps."""
    problem, x0, v0 = water_cluster(8, spacing=0.3, seed=5)
    integrator = AlphaRattleEnergyIntegrator(0.002)
    simulation = app.Simulation(app.Topology(), to_openmm_system(problem), integrator, REFERENCE)
    simulation.context.setPositions(x0.reshape(-1, 3))
    simulation.context.setVelocities(v0.reshape(-1, 3))
    simulation.context.applyConstraints(1e-12)
    simulation.context.applyVelocityConstraints(1e-12)
    return simulation


def test_memory_does_not_grow_with_the_reports(tmp_path):
    """Every step reported (interval 1): what the reporter holds stays the same after 600 more rows."""
    simulation = _simulation()
    reporter = AlphaControllerReporter(str(tmp_path / "controller.csv"), 1)
    simulation.reporters.append(reporter)
    simulation.step(50)  # set up (file, header) and warmed up
    held = {name: len(value) for name, value in vars(reporter).items() if hasattr(value, "__len__")}
    tracemalloc.start()
    try:
        before = tracemalloc.take_snapshot()
        simulation.step(600)
        after = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    only_reporters = [tracemalloc.Filter(True, reporters.__file__)]
    growth = sum(
        stat.size_diff
        for stat in after.filter_traces(only_reporters).compare_to(
            before.filter_traces(only_reporters), "filename"
        )
    )
    assert growth < 10_000, f"{growth} bytes more held by reporters.py after 600 rows"
    assert {name: len(value) for name, value in vars(reporter).items() if hasattr(value, "__len__")} == held
    assert read_controller_csv(tmp_path / "controller.csv").shape == (650, len(COLUMNS))


def test_asks_for_no_state_data_and_reports_every_interval(tmp_path):
    simulation = _simulation()
    reporter = AlphaControllerReporter(str(tmp_path / "controller.csv"), 5)
    assert reporter.describeNextReport(simulation) == {"steps": 5, "periodic": None, "include": []}
    simulation.reporters.append(reporter)
    simulation.step(20)
    rows = read_controller_csv(tmp_path / "controller.csv")
    assert rows[:, 0].tolist() == [5, 10, 15, 20]
    assert rows[-1, 2] == simulation.integrator.alpha  # a row describes the step just taken


def test_summary_takes_every_step_from_the_integrator_and_alpha_from_the_rows(tmp_path, monkeypatch):
    simulation = _simulation()
    integrator = simulation.integrator
    reporter = AlphaControllerReporter(str(tmp_path / "controller.csv"), 5)
    simulation.reporters.append(reporter)
    simulation.step(40)
    rows = read_controller_csv(tmp_path / "controller.csv")
    totals = integrator.controller_totals()
    summary = reporter.summary()
    assert (summary.steps, summary.rows) == (40, 8)
    assert summary.fraction_fallen_back == totals["fraction_fallen_back"]
    assert summary.fraction_at_bound == totals["steps_at_bound"] / 40
    assert summary.force_evaluations_per_step == pytest.approx(integrator.force_evaluations_per_step)
    assert summary.alpha_percentiles["p50"] == pytest.approx(np.median(rows[:, 2]))
    if "rms_residual" not in totals:  # the integrator accumulates no residuals: RMS of the rows, said so
        assert summary.residuals_over == ROWS
        assert summary.rms_residual == pytest.approx(np.sqrt(np.mean(rows[:, 3] ** 2)))
    # with the integrator's own RMS and max over every step, those are used
    every = totals | {"rms_residual": 0.125, "max_abs_residual": 0.5}
    monkeypatch.setattr(AlphaRattleEnergyIntegrator, "controller_totals", lambda self: every)
    summary = reporter.summary()
    assert (summary.rms_residual, summary.max_abs_residual, summary.residuals_over) == (
        0.125,
        0.5,
        EVERY_STEP,
    )
    # without totals, the rows are all there is
    alone = summarize_controller(rows)
    assert (alone.steps, alone.residuals_over) == (8, ROWS)


def test_wrong_integrator_is_refused_at_the_first_report(tmp_path):
    problem, x0, _ = water_cluster(2, spacing=0.3, seed=5)
    simulation = app.Simulation(
        app.Topology(), to_openmm_system(problem), mm.VerletIntegrator(0.001), REFERENCE
    )
    simulation.context.setPositions(x0.reshape(-1, 3))
    simulation.reporters.append(AlphaControllerReporter(str(tmp_path / "x.csv")))
    with pytest.raises(TypeError, match="energy mode"):
        simulation.step(1)
    assert not (tmp_path / "x.csv").exists()
