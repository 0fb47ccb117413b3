"""run_nve and compare: α = 0 is RATTLE, resume = uninterrupted, run directories, errors."""

from __future__ import annotations

import json
import math

import numpy as np
import openmm.unit as unit
import pytest
from quick_systems import StopAt, quick_system

from openmm_alphaprk.nve import LargeStepWarning
from openmm_alphaprk.runs import RunFailedError, RunInterrupted, run_nve, rundir
from openmm_alphaprk.runs.integrator_names import UnknownIntegratorError, make_integrator, parse_integrator
from openmm_alphaprk.runs.rundir import RunDirectoryError
from openmm_alphaprk.systems import UnknownSystemError
from openmm_alphaprk.workflows import compare
from openmm_alphaprk.workflows.comparison import format_comparison_table, gain_line

REFERENCE_RUN = dict(
    platform="Reference", energy_interval=2, trajectory_interval=4, checkpoint_interval=10, progress=False
)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


@pytest.fixture(scope="module")
def box(cache):
    """tip3p-2nm (774 atoms), briefly equilibrated; the runs use the Reference platform."""
    return quick_system("tip3p-2nm", cache)


@pytest.fixture(scope="module")
def cluster(cache):
    """The vacuum water cluster (222 atoms, no cutoff): cheap on the Reference platform."""
    return quick_system("water-cluster", cache)


def test_integrator_names():
    assert parse_integrator("alpha=1/6").alpha == pytest.approx(1 / 6)
    assert parse_integrator(" Alpha = 0.5 ").alpha == 0.5
    assert parse_integrator("RATTLE").kind == "rattle"
    assert (parse_integrator("energy4").kind, parse_integrator("energy4").order) == ("energy", 4)
    assert (parse_integrator("alpha4=0").alpha, parse_integrator("alpha4=0").order) == (0.0, 4)
    assert make_integrator("energy4", 0.002).order == 4
    assert make_integrator("alpha4=1/10", 0.002).alpha == pytest.approx(0.1)
    for bad in ("alpha=", "alpha=x", "alpha=1/0", "leapfrog", "alpha=nan", "alpha5=1", "energy2"):
        listed = r"Names are BASE\[:SET\]\[=alpha\]\[\+rescale\[@N\]\]: rattle\[4\|6\]"
        with pytest.raises(UnknownIntegratorError, match=listed):
            parse_integrator(bad)


def test_alpha_zero_gives_rattle_energies(box, tmp_path):
    rattle = run_nve(box, "rattle", tmp_path / "rattle", steps=20, **REFERENCE_RUN)
    alpha0 = run_nve(box, "alpha=0", tmp_path / "alpha0", steps=20, **REFERENCE_RUN)
    a = rundir.read_energies(tmp_path / "rattle" / rundir.ENERGIES_FILE)
    b = rundir.read_energies(tmp_path / "alpha0" / rundir.ENERGIES_FILE)
    assert a.shape == b.shape == (11, 6)
    np.testing.assert_allclose(b[:, 2:5], a[:, 2:5], rtol=0, atol=1e-9)
    assert np.ptp(a[:, 4]) > 1e-3  # the energies do move: the comparison is not of constants
    assert alpha0.rms_residual == pytest.approx(rattle.rms_residual, abs=1e-9)


@pytest.mark.parametrize(
    "system, integrator, extra, stop, resumes_from",
    [
        # raised after the step's reports: the files are complete, so step 17 is checkpointed
        ("box", "rattle", {}, StopAt(17), 17),
        # raised before the reports of step 16: no checkpoint of it; the last one (step 10) stays
        ("cluster", "energy", {}, StopAt(16, "before"), 10),
        # Ctrl-C (SIGINT) at step 13 takes effect at the end of the energy interval, step 14
        ("cluster", "rattle", {"velocity_interval": 3, "velocity_seed": 11}, StopAt(13, "signal"), 14),
        # Ctrl-C before the first step-count checkpoint (step 1000) is not lost: it resumes from 14
        ("cluster", "energy", {"checkpoint_interval": 1000}, StopAt(13, "signal"), 14),
        # SIGTERM (kill, timeout, a batch scheduler's time limit) is deferred the same way
        ("cluster", "rattle", {}, StopAt(13, "sigterm"), 14),
        # incomplete output and no checkpoint yet: the run starts again from step 0
        ("cluster", "rattle", {}, StopAt(6, "before"), None),
    ],
)
def test_interrupted_run_resumes_to_the_uninterrupted_result(
    request, tmp_path, system, integrator, extra, stop, resumes_from, ctrl_c_raises
):
    """On the Reference platform (deterministic); the energy mode keeps E_ref over the restart."""
    prepared = request.getfixturevalue(system)
    options = REFERENCE_RUN | extra
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    run_nve(prepared, integrator, whole, steps=30, **options)
    with pytest.raises(RunInterrupted) as interrupted:
        run_nve(prepared, integrator, parts, steps=30, extra_reporters=[stop], **options)
    assert isinstance(interrupted.value, KeyboardInterrupt)
    assert interrupted.value.checkpoint_step == resumes_from
    message = str(interrupted.value)
    assert message.startswith(f"run in {parts} interrupted at step ")
    if resumes_from is None:
        assert message.endswith("no checkpoint yet: the same command starts it again from step 0."), message
        assert not (parts / rundir.CHECKPOINT_FILE).exists()
    else:
        assert message.endswith(
            f"resumes it from step {resumes_from}"
            + ("." if stop.how != "before" else ", its last checkpoint.")
        ), message
    assert not (parts / rundir.SUMMARY_FILE).exists()
    # what the interrupted run left is readable
    assert rundir.read_energies(parts / rundir.ENERGIES_FILE)[-1, 0] <= stop.step + 1
    summary = run_nve(prepared, integrator, parts, steps=30, **options)
    assert summary.steps == 30 and summary.steps_this_call == 30 - (resumes_from or 0)
    if "velocity_interval" in extra:  # trajectory.trr cut back to the checkpoint, then continued
        assert (parts / rundir.TRR_FILE).read_bytes() == (whole / rundir.TRR_FILE).read_bytes()
        v_parts = rundir.open_universe(parts, rundir.TRR_FILE)
        assert len(v_parts.trajectory) == 10
        assert [ts.data["step"] for ts in v_parts.trajectory] == list(range(3, 31, 3))
    for name in (rundir.ENERGIES_FILE, rundir.CONTROLLER_FILE):
        if (whole / name).exists():
            assert (parts / name).read_text(encoding="utf-8") == (whole / name).read_text(encoding="utf-8")
    u_whole = rundir.open_universe(whole)
    u_parts = rundir.open_universe(parts)
    assert len(u_parts.trajectory) == len(u_whole.trajectory) == 7
    np.testing.assert_array_equal(u_parts.trajectory.timeseries(), u_whole.trajectory.timeseries())
    final = json.loads((whole / rundir.SUMMARY_FILE).read_text(encoding="utf-8"))
    assert summary.e_ref == final["e_ref"] and summary.rms_residual == final["rms_residual"]
    assert summary.drift_per_dof == final["drift_per_dof"]
    assert summary.force_evaluations_per_step == final["force_evaluations_per_step"]
    assert summary.controller == final["controller"]


def test_checkpoints_are_also_written_by_wall_time(cluster, tmp_path):
    """checkpoint_seconds: a checkpoint at the end of an energy interval once that much time has passed."""
    failing = dict(steps=30, extra_reporters=[_FailAt(17)], **REFERENCE_RUN | {"checkpoint_interval": 1000})
    with pytest.raises(RunFailedError, match="no checkpoint was written"):
        run_nve(cluster, "rattle", tmp_path / "steps only", **failing)
    with pytest.raises(RunFailedError, match=r"the last checkpoint, .*, is of step 16\.$"):
        run_nve(cluster, "rattle", tmp_path / "by time", checkpoint_seconds=1e-6, **failing)


class _FailAt:
    """A reporter that fails (ValueError, as a NaN does) at a step."""

    def __init__(self, step: int):
        self.step = step

    def describeNextReport(self, simulation) -> dict:
        remaining = self.step - simulation.currentStep
        return {"steps": remaining if remaining > 0 else 10**9, "periodic": None, "include": []}

    def report(self, simulation, state) -> None:
        raise ValueError("stopped by the test")


def test_finished_run_is_reported_and_can_be_extended(box, tmp_path):
    first = run_nve(box, "rattle", tmp_path, steps=10, **REFERENCE_RUN)
    again = run_nve(box, "rattle", tmp_path, steps=10, **REFERENCE_RUN)
    assert again == first
    # the same step given as a Quantity in fs is the same run
    longer = run_nve(box, "rattle", tmp_path, steps=20, timestep=2 * unit.femtoseconds, **REFERENCE_RUN)
    assert longer.steps == 20 and longer.steps_this_call == 10
    assert rundir.read_energies(tmp_path / rundir.ENERGIES_FILE)[:, 0].tolist() == list(range(0, 21, 2))


def test_directory_with_a_different_run_is_refused(box, tmp_path):
    run_nve(box, "rattle", tmp_path, steps=4, **REFERENCE_RUN)
    before = (tmp_path / rundir.ENERGIES_FILE).read_text(encoding="utf-8")
    with pytest.raises(RunDirectoryError, match=r"different run \(integrator: stored 'rattle', requested"):
        run_nve(box, "energy", tmp_path, steps=4, **REFERENCE_RUN)
    with pytest.raises(RunDirectoryError, match="timestep_ps"):
        run_nve(box, "rattle", tmp_path, steps=4, **{**REFERENCE_RUN}, timestep=0.001)
    assert (tmp_path / rundir.ENERGIES_FILE).read_text(encoding="utf-8") == before
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine", encoding="utf-8")
    with pytest.raises(RunDirectoryError, match="not a run directory"):
        run_nve(box, "rattle", tmp_path / "other", steps=4, **REFERENCE_RUN)


def test_bad_input_is_refused_before_work(box, tmp_path):
    out = tmp_path / "run"
    with pytest.raises(TypeError, match="cannot be converted to picosecond"):
        run_nve(box, "rattle", out, timestep=2 * unit.nanometers)
    with pytest.raises(ValueError, match="timestep must be positive"):
        run_nve(box, "rattle", out, timestep=-0.002)
    with pytest.raises(ValueError, match="steps must be a positive integer"):
        run_nve(box, "rattle", out, steps=0)
    with pytest.raises(ValueError, match="finite"):
        run_nve(box, "rattle", out, timestep=float("nan"))
    with pytest.raises(ValueError, match="no precision setting"):
        run_nve(box, "rattle", out, precision="double")
    with pytest.raises(ValueError, match="unknown OpenMM platform 'GPU'"):
        run_nve(box, "rattle", out, platform="GPU")
    with pytest.raises(UnknownSystemError, match="unknown system 'tip9p'"):
        run_nve("tip9p", "rattle", out)
    assert not out.exists()
    # a Quantity in other units is converted
    summary = run_nve(box, "rattle", out, steps=2, timestep=1 * unit.femtoseconds, **REFERENCE_RUN)
    assert summary.timestep_fs == pytest.approx(1.0)


def test_blow_up_stops_with_a_clear_error_and_keeps_the_output(box, tmp_path):
    with (
        pytest.raises(RunFailedError, match="output up to then is kept"),
        pytest.warns(LargeStepWarning, match="a 50 fs step is above about 4.5 fs"),
    ):
        run_nve(box, "verlet", tmp_path, steps=200, timestep=0.05, energy_interval=1, progress=False)
    assert rundir.read_energies(tmp_path / rundir.ENERGIES_FILE).shape[0] >= 1


def test_blow_up_says_where_it_stopped_and_whether_a_checkpoint_exists(box, tmp_path):
    """no "near step", no checkpoint claimed that was never written."""
    import re

    import openmm as mm
    import openmm.app as app

    blow_up = dict(steps=200, timestep=0.05, energy_interval=1, progress=False)
    with pytest.raises(RunFailedError) as none, pytest.warns(LargeStepWarning):
        run_nve(box, "verlet", tmp_path / "none", **blow_up)
    message = str(none.value)
    assert re.search(r"stopped at step \d+ of 200 with VerletIntegrator", message), message
    assert "near step" not in message and "last checkpoint" not in message
    assert message.endswith("no checkpoint was written.")
    assert not (tmp_path / "none" / rundir.CHECKPOINT_FILE).exists()
    # a checkpoint every step: the message names the step of the one on disk
    with pytest.raises(RunFailedError) as some, pytest.warns(LargeStepWarning):
        run_nve(
            box, "verlet", tmp_path / "some", **blow_up | {"energy_interval": 3, "checkpoint_interval": 1}
        )
    found = re.search(r"the last checkpoint, (.+), is of step (\d+)\.$", str(some.value))
    assert found, str(some.value)
    assert found.group(1) == str(tmp_path / "some" / rundir.CHECKPOINT_FILE)
    simulation = app.Simulation(
        box.topology, box.system, mm.VerletIntegrator(0.05), mm.Platform.getPlatformByName("CPU")
    )
    simulation.loadCheckpoint(found.group(1))
    assert simulation.currentStep == int(found.group(2))


def test_longer_run_is_refused_not_reported_as_shorter(cluster, tmp_path):
    """a folder holding a longer run is refused (run_nve and compare), never cut or mislabelled."""
    run_nve(cluster, "rattle", tmp_path / "run", steps=20, **REFERENCE_RUN)
    summary = (tmp_path / "run" / rundir.SUMMARY_FILE).read_text(encoding="utf-8")
    with pytest.raises(RunDirectoryError, match="holds a run of 20 steps, longer than the 10 asked for"):
        run_nve(cluster, "rattle", tmp_path / "run", steps=10, **REFERENCE_RUN)
    assert (tmp_path / "run" / rundir.SUMMARY_FILE).read_text(encoding="utf-8") == summary
    assert json.loads((tmp_path / "run" / rundir.PARAMETERS_FILE).read_text(encoding="utf-8"))["steps"] == 20
    compare(cluster, ["rattle"], tmp_path / "cmp", steps=20, plot=False, **REFERENCE_RUN)
    with pytest.raises(RunDirectoryError, match="holds a run of 20 steps.*--steps 20"):
        compare(cluster, ["rattle"], tmp_path / "cmp", steps=10, plot=False, **REFERENCE_RUN)
    # interrupted after its checkpoint at step 10: asking for 5 steps is refused, 30 resumes
    with pytest.raises(KeyboardInterrupt):
        stop = StopAt(16, "before")
        run_nve(cluster, "rattle", tmp_path / "cut", steps=30, extra_reporters=[stop], **REFERENCE_RUN)
    with pytest.raises(RunDirectoryError, match="holds a run of 10 steps, longer than the 5 asked for"):
        run_nve(cluster, "rattle", tmp_path / "cut", steps=5, **REFERENCE_RUN)
    assert run_nve(cluster, "rattle", tmp_path / "cut", steps=30, **REFERENCE_RUN).steps == 30


def test_run_without_a_trajectory_frame_yet_is_extended(cluster, tmp_path):
    """A finished run shorter than one trajectory interval (empty DCD) is extended, not refused."""
    run = dict(REFERENCE_RUN, trajectory_interval=20)
    run_nve(cluster, "rattle", tmp_path, steps=8, **run)
    assert (tmp_path / rundir.TRAJECTORY_FILE).stat().st_size == 0
    assert run_nve(cluster, "rattle", tmp_path, steps=44, **run).steps == 44
    universe = rundir.open_universe(tmp_path)
    assert len(universe.trajectory) == 2 and universe.trajectory.dt == pytest.approx(0.04, rel=1e-6)


def test_reading_a_run_directory_raises_no_deprecation_warning(cluster, tmp_path):
    """the package's DCD reading (open_universe, analyze_run), DeprecationWarnings as errors."""
    import warnings

    from openmm_alphaprk.workflows import analyze_run

    summary = run_nve(cluster, "rattle", tmp_path, steps=16, velocity_interval=4, **REFERENCE_RUN)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        assert len(rundir.open_universe(tmp_path).trajectory) == 4
        assert len(rundir.open_universe(tmp_path, rundir.TRR_FILE).trajectory) == 4
        result = analyze_run(tmp_path, plot=False)
    constraints = result["constraints"]
    assert "float32" in constraints["note"] and "full-precision final state" in constraints["note"]
    assert constraints["run_summary_max_relative_constraint_error"] == summary.max_relative_constraint_error


def test_periodic_box_reports_no_momentum_invariants(box, tmp_path):
    assert run_nve(box, "rattle", tmp_path, steps=2, **REFERENCE_RUN).momentum_change == {}


def test_compare_table_figure_and_json(box, tmp_path):
    result = compare(
        box,
        ["rattle", "alpha=1/6", "verlet"],
        tmp_path,
        steps=6,
        energy_interval=2,
        progress=False,
        equal_cost=False,
        accuracy_steps=2,
    )
    assert [s.integrator for s in result.summaries] == ["rattle", "alpha=1/6", "verlet"]
    assert "drift/DOF" in result.table and "kJ/mol/ns" in result.table and "leapfrog" in result.table
    assert set(result.accuracy) == {"rattle", "alpha=1/6"}  # not verlet: leapfrog velocities
    assert result.figure.is_file() and result.figure.stat().st_size > 1000
    data = json.loads((tmp_path / "comparison.json").read_text(encoding="utf-8"))
    assert len(data["summaries"]) == 3 and (tmp_path / "alpha=1_6" / "summary.json").is_file()
    with pytest.raises(ValueError, match="repeated"):
        compare(box, ["rattle", "RATTLE"], tmp_path / "x", steps=2, progress=False)


def test_isolated_cluster_keeps_momenta(cluster, tmp_path):
    """Vacuum cluster, no cutoff: P and L are invariants of every member of the family."""
    for integrator in ("rattle", "alpha=0.5"):
        summary = run_nve(cluster, integrator, tmp_path / integrator, steps=40, **REFERENCE_RUN)
        assert summary.momentum_change["linear_amu_nm_per_ps"] < 1e-9
        assert summary.momentum_change["angular_amu_nm2_per_ps"] < 1e-8


def test_velocities_file_and_seeded_start(cluster, tmp_path):
    """trajectory.trr holds the State's positions and velocities; a seed draws new, constrained velocities."""
    import openmm as mm

    from openmm_alphaprk.observables import system_constraint_errors as constraint_errors

    run = dict(REFERENCE_RUN, steps=12, velocity_interval=4)
    first = run_nve(cluster, "rattle", tmp_path / "a", velocity_seed=3, **run)
    again = run_nve(cluster, "rattle", tmp_path / "b", velocity_seed=3, **run)
    other = run_nve(cluster, "rattle", tmp_path / "c", velocity_seed=4, **run)
    plain = run_nve(cluster, "rattle", tmp_path / "d", **run)
    assert first.e_ref == again.e_ref and first.e_ref != other.e_ref and first.e_ref != plain.e_ref
    start = mm.XmlSerializer.deserialize(
        (tmp_path / "a" / rundir.START_STATE_FILE).read_text(encoding="utf-8")
    )
    v0 = start.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
    x0 = start.getPositions(asNumpy=True).value_in_unit(unit.nanometers)
    assert constraint_errors(cluster.system, x0, v0)[1] < 1e-6  # constrained components removed
    kinetic = 0.5 * sum(
        cluster.system.getParticleMass(i).value_in_unit(unit.dalton) * float(v0[i] @ v0[i])
        for i in range(len(v0))
    )
    dof = 3 * len(v0) - cluster.system.getNumConstraints()
    assert (
        200
        < 2 * kinetic / (dof * unit.MOLAR_GAS_CONSTANT_R.value_in_unit(unit.kilojoule_per_mole / unit.kelvin))
        < 400
    )
    # momenta are compared with the seeded start, not with the prepared state's velocities
    assert first.momentum_change["linear_amu_nm_per_ps"] < 1e-9
    assert not (tmp_path / "d" / rundir.START_STATE_FILE).exists()
    u = rundir.open_universe(tmp_path / "a", rundir.TRR_FILE)
    assert len(u.trajectory) == 3 and u.trajectory.dt == pytest.approx(0.008, rel=1e-6)
    u.trajectory[-1]  # the last frame (step 12) is the last checkpoint's state, in Å and Å/ps
    assert u.trajectory.ts.data["step"] == 12 and u.trajectory.time == pytest.approx(0.024)
    np.testing.assert_allclose(
        u.atoms.velocities / 10.0, _final_velocities(cluster, tmp_path / "a"), atol=1e-5
    )
    positions = rundir.open_universe(tmp_path / "a")  # the DCD's last frame: the same positions
    positions.trajectory[-1]
    np.testing.assert_allclose(u.atoms.positions, positions.atoms.positions, atol=1e-3)


def _final_velocities(prepared, directory):
    """Velocities (nm/ps) of the run's last checkpoint, read through an OpenMM Simulation."""
    import openmm as mm
    import openmm.app as app

    integrator = make_integrator("rattle", 0.002)
    platform = mm.Platform.getPlatformByName("Reference")
    simulation = app.Simulation(prepared.topology, prepared.system, integrator, platform)
    simulation.loadCheckpoint(str(directory / rundir.CHECKPOINT_FILE))
    state = simulation.context.getState(getVelocities=True)
    return state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)


def test_compare_states_one_rms_and_one_drift_in_table_json_and_figure(cluster, tmp_path, monkeypatch):
    """The same numbers, printed the same way, in the table, each summary.json and the figure."""
    pytest.importorskip("matplotlib")
    from openmm_alphaprk.observables import drift_text
    from openmm_alphaprk.runs.integrator_names import label
    from openmm_alphaprk.workflows import plots

    built = []
    build = plots.build_energy_residual_figure
    monkeypatch.setattr(
        plots, "build_energy_residual_figure", lambda *a, **k: built.append(build(*a, **k)) or built[-1]
    )
    result = compare(cluster, ["rattle", "energy"], tmp_path, steps=60, **REFERENCE_RUN)
    (figure,) = built
    legends = [
        text.get_text() for ax in figure.axes if ax.get_legend() for text in ax.get_legend().get_texts()
    ]
    rows = {line.split()[0]: line for line in result.table.splitlines()[3:5]}
    for name in ("rattle", "energy"):
        stored = json.loads((tmp_path / name / rundir.SUMMARY_FILE).read_text(encoding="utf-8"))
        rms = f"{stored['rms_residual']:.3g}"
        drift = (stored["drift_per_dof"], stored["drift_per_dof_standard_error"])
        assert f" {drift_text(*drift)} " in rows[name] and f" {rms} " in rows[name], rows[name]
        assert f"{label(name)}: RMS {rms} kJ/mol" in legends, legends
        assert f"drift/DOF {drift_text(*drift, 'kJ/mol/ns')}" in legends, legends
    assert "E_ref = total energy of the start state" in result.table
    assert "fell back = the step ended with |H - E_ref| above the energy tolerance" in result.table


def test_a_run_too_short_to_resolve_its_drift_says_so(cluster, tmp_path):
    result = compare(cluster, ["rattle"], tmp_path, steps=8, plot=False, **REFERENCE_RUN)
    (summary,) = result.summaries
    assert (
        not summary.drift_resolved and abs(summary.drift_per_dof) < 2 * summary.drift_per_dof_standard_error
    )
    row = result.table.splitlines()[3]
    assert f"not resolved (±{summary.drift_per_dof_standard_error:.2g})" in row, row
    assert f"{summary.drift_per_dof:+.3g}" not in row


def test_energy_mode_summary_uses_the_integrators_totals_over_every_step(cluster, tmp_path, monkeypatch):
    """controller.csv rows are samples (every energy interval); fractions and, when the integrator
    accumulates them, RMS and max |H - E_ref| cover every step."""
    from openmm_alphaprk import AlphaRattleEnergyIntegrator
    from openmm_alphaprk.runs.reporters import EVERY_STEP, ROWS

    summary = run_nve(
        cluster, "energy", tmp_path / "plain", steps=20, **REFERENCE_RUN | {"energy_interval": 5}
    )
    rows = np.loadtxt(tmp_path / "plain" / rundir.CONTROLLER_FILE, delimiter=",", skiprows=1)
    assert rows[:, 0].tolist() == [5, 10, 15, 20]  # the default: the energy interval, no single-stepping
    assert (summary.controller["steps"], summary.controller["rows"]) == (20, 4)
    totals = AlphaRattleEnergyIntegrator.controller_totals
    if summary.controller["residuals_over"] == ROWS:
        assert "RMS |H - E_ref|" not in format_comparison_table([summary]).split("energy (energy mode)")[1]
    every = {"rms_residual": 0.0123, "max_abs_residual": 0.0456}
    monkeypatch.setattr(AlphaRattleEnergyIntegrator, "controller_totals", lambda self: totals(self) | every)
    summary = run_nve(
        cluster, "energy", tmp_path / "every", steps=20, **REFERENCE_RUN | {"energy_interval": 5}
    )
    c = summary.controller
    assert (c["rms_residual"], c["max_abs_residual"], c["residuals_over"]) == (0.0123, 0.0456, EVERY_STEP)
    assert "energy (energy mode), over all 20 steps: RMS |H - E_ref| 0.0123 kJ/mol, max 0.0456 kJ/mol" in (
        " ".join(format_comparison_table([summary]).split())
    )


def test_a_finished_run_with_an_older_summary_is_summarized_again(cluster, tmp_path):
    """A summary.json without the newer fields (the drift's standard error) is rewritten, not returned."""
    first = run_nve(cluster, "energy", tmp_path, steps=20, **REFERENCE_RUN)
    path = tmp_path / rundir.SUMMARY_FILE
    old = json.loads(path.read_text(encoding="utf-8"))
    for key in ("drift_per_dof_standard_error", "drift_resolved"):
        del old[key]
    del old["controller"]["residuals_over"]
    path.write_text(json.dumps(old), encoding="utf-8")
    again = run_nve(cluster, "energy", tmp_path, steps=20, **REFERENCE_RUN)
    assert again == first  # the same numbers, from the same files and final checkpoint
    assert json.loads(path.read_text(encoding="utf-8")) == first.as_dict()


def test_compare_runs_rattle_at_h_over_k_and_states_the_gain_at_equal_cost(cluster, tmp_path):
    """RATTLE at h/k, k = ⌈the energy mode's evaluations per step⌉, over the same simulated time."""
    result = compare(cluster, ["rattle", "energy4"], tmp_path / "cmp", steps=20, plot=False, **REFERENCE_RUN)
    rattle, energy, *extra = result.summaries
    k = math.ceil(energy.force_evaluations_per_step)
    (equal_cost,) = extra
    assert equal_cost.integrator == f"rattle h/{k}"
    assert equal_cost.steps == 20 * k and equal_cost.simulated_ps == pytest.approx(energy.simulated_ps)
    assert equal_cost.timestep_fs == pytest.approx(rattle.timestep_fs / k)
    assert equal_cost.energy_samples == energy.energy_samples  # read at the same simulated times
    stored = json.loads((tmp_path / "cmp" / "comparison.json").read_text(encoding="utf-8"))
    (gain,) = stored["equal_cost"]
    assert gain["k"] == k and gain["rattle_row"] == equal_cost.integrator
    assert gain["gain"] == pytest.approx(equal_cost.rms_residual / energy.rms_residual)
    assert f"{gain['gain']:.3g}x lower" in result.table
    assert f"rattle h/{k}" in result.table.splitlines()[5]
    # a finished h/k run is reported like the others: a second call runs nothing new
    again = compare(cluster, ["rattle", "energy4"], tmp_path / "cmp", steps=20, plot=False, **REFERENCE_RUN)
    assert again.summaries == result.summaries


def test_an_interrupted_comparison_resumes_and_a_foreign_folder_is_refused(cluster, tmp_path):
    """A comparison stopped before comparison.json was written resumes in the same folder."""
    output = tmp_path / "cmp"
    first = compare(cluster, ["rattle", "energy"], output, steps=8, plot=False, **REFERENCE_RUN)
    # what an interruption during the h/k run leaves: the listed runs, an h/k folder, no comparison files
    (output / "comparison.json").unlink()
    (output / "table.txt").unlink()
    (hk,) = [path for path in output.iterdir() if path.name.startswith("rattle_h")]
    for path in hk.iterdir():
        path.unlink()
    again = compare(cluster, ["rattle", "energy"], output, steps=8, plot=False, **REFERENCE_RUN)
    assert again.summaries[:2] == first.summaries[:2]  # the finished runs are read back, not rerun
    timing = {"wall_seconds", "ns_per_day"}
    rerun, before = (
        {key: value for key, value in summary.as_dict().items() if key not in timing}
        for summary in (again.summaries[2], first.summaries[2])
    )
    assert rerun == before  # the h/k run, rerun from its start, reaches the same numbers
    assert (output / "comparison.json").is_file()
    foreign = tmp_path / "foreign"
    (foreign / "rattle").mkdir(parents=True)
    (foreign / "rattle" / "notes.txt").write_text("not a run", encoding="utf-8")
    with pytest.raises(RunDirectoryError, match="not a comparison directory"):
        compare(cluster, ["rattle"], foreign, steps=8, plot=False, **REFERENCE_RUN)
    (tmp_path / "stray.txt").write_text("x", encoding="utf-8")
    with pytest.raises(RunDirectoryError, match="not a comparison directory"):
        compare(cluster, ["rattle"], tmp_path, steps=8, plot=False, **REFERENCE_RUN)


def test_compare_without_equal_cost_runs_only_the_listed_integrators(cluster, tmp_path):
    result = compare(
        cluster, ["rattle", "energy4"], tmp_path, steps=6, plot=False, equal_cost=False, **REFERENCE_RUN
    )
    assert [s.integrator for s in result.summaries] == ["rattle", "energy4"]
    assert "at equal cost" not in result.table


def test_the_equal_cost_line_says_a_loss_as_a_loss():
    """A ratio below 1 is RATTLE at h/k doing better: the line says "higher", never "0.85x lower"."""
    gain = {"integrator": "energy4", "rms_residual": 0.0938, "rattle_row": "rattle h/10", "k": 10}
    assert gain_line(gain | {"rattle_rms_residual": 0.0798, "gain": 0.0798 / 0.0938}).endswith(
        "0.0798: 1.18x higher: no gain at equal cost"
    )
    better = gain | {"rattle_rms_residual": 0.3752, "gain": 0.3752 / 0.0938}
    assert gain_line(better).endswith("0.375: 4x lower")


def test_a_trr_frame_cut_off_by_an_interruption_is_removed_on_resume(cluster, tmp_path):
    """truncate_trr keeps whole frames only: a partial last frame and frames past the checkpoint go."""
    run_nve(cluster, "rattle", tmp_path, steps=12, velocity_interval=2, **REFERENCE_RUN)
    path = tmp_path / rundir.TRR_FILE
    whole = path.read_bytes()
    frame = len(whole) // 6
    assert len(whole) == 6 * frame
    path.write_bytes(whole + whole[: frame // 2])  # half a frame, as a kill during a write leaves it
    assert rundir.truncate_trr(path, 100) == 6 and path.read_bytes() == whole
    assert rundir.truncate_trr(path, 4) == 4 and path.read_bytes() == whole[: 4 * frame]
    steps = [ts.data["step"] for ts in rundir.open_universe(tmp_path, rundir.TRR_FILE).trajectory]
    assert steps == [2, 4, 6, 8]
    path.write_bytes(b"not a trr file")
    with pytest.raises(rundir.RunDirectoryError, match="move it away"):
        rundir.truncate_trr(path, 1)
