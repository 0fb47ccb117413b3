"""Trajectory accuracy against a small-step reference: the measurement, the benchmark and its command line."""

import json

import numpy as np
import pytest

from openmm_alphaprk.benchmarks.accuracy import (
    equilibrium_averages,
    format_accuracy_table,
    run_accuracy_benchmark,
)
from openmm_alphaprk.cli import main
from openmm_alphaprk.observables import convergence_order
from openmm_alphaprk.runs.accuracy import (
    horizon_errors,
    periodic_box,
    reference,
    run_trajectory,
    with_rigid_motion,
)
from openmm_alphaprk.runs.integrator_names import at_divisor
from openmm_alphaprk.systems import prepare_system

H = 0.002


@pytest.fixture(scope="module")
def cluster():
    """The shipped water cluster, spinning and moving as a whole (no box: P and L are invariants)."""
    return with_rigid_motion(prepare_system("water-cluster"), (0.3, -0.2, 0.1), (0.4, 0.7, -0.5))


def test_the_reference_has_no_error_against_itself(cluster):
    """Reference platform: the same program from the same start repeats itself bit for bit."""
    runs = [
        run_trajectory(cluster, reference(H, 8), [2, 5], platform="Reference", read_energy=False)
        for _ in range(2)
    ]
    errors = horizon_errors(runs[0], runs[1], periodic_box(cluster), 2.0)
    assert [e.steps for e in errors] == [2, 5]
    for error in errors:
        assert error.position_rms == error.position_max == error.velocity_rms == error.velocity_max == 0.0


def test_rattles_error_shrinks_as_h_squared(cluster):
    """After 10 fs, RATTLE at h, h/2, h/4 against RATTLE at h/64 (Reference platform).

    Measured: order 2.00 (errors 4.6e-5, 1.2e-5, 2.9e-6 nm); the reference's own difference
    from h/128 is below 1/50 of the smallest.
    """
    reference_run = run_trajectory(cluster, reference(H), [5], platform="Reference", read_energy=False)
    finer = run_trajectory(cluster, reference(H, 128), [5], platform="Reference", read_energy=False)
    errors = []
    for divisor in (1, 2, 4):
        run = run_trajectory(cluster, at_divisor("rattle", H, divisor), [5], platform="Reference")
        errors.append(horizon_errors(run, reference_run, None, 2.0)[0].position_rms)
    order = convergence_order(np.array([1.0, 0.5, 0.25]) * H, np.array(errors))
    assert order == pytest.approx(2.0, abs=0.1), errors
    floor = horizon_errors(reference_run, finer, None, 2.0)[0].position_rms
    assert floor < errors[-1] / 50, (floor, errors)


def test_the_benchmark_adds_equal_cost_rows_and_states_every_error(cluster):
    rows_seen = []
    result = run_accuracy_benchmark(
        cluster,
        ["rattle", "rattle+rescale", "alpha4=0:triple-jump"],
        horizons=[2, 5],
        platform="Reference",
        timing_rounds=1,
        timing_steps=3,
        progress=False,
        on_row=rows_seen.append,
    )
    by_name = {row.name: row for row in result.rows}
    assert [row.name for row in rows_seen] == [row.name for row in result.rows]
    # triple jump: 3 evaluations per step → RATTLE and RATTLE + rescaling at h/3
    assert (
        by_name["RATTLE h/3"].divisor == 3
        and "equal evaluations (alpha4:triple-jump=0)" in by_name["RATTLE h/3"].role
    )
    assert by_name["RATTLE + rescaling h/3"].force_evaluations_per_step == pytest.approx(3.0)
    assert by_name["α-RATTLE-4 (triple-jump) α = 0"].force_evaluations_per_step == pytest.approx(3.0)
    assert by_name["RATTLE + rescaling"].rms_residual < 1e-9 < by_name["RATTLE"].rms_residual
    rattle, triple = by_name["RATTLE"].horizons, by_name["α-RATTLE-4 (triple-jump) α = 0"].horizons
    assert all(t.position_rms < r.position_rms / 3 for r, t in zip(rattle, triple))  # fourth order
    for row in result.rows:
        assert [h.steps for h in row.horizons] == [2, 5]
        assert row.momentum_change["angular_amu_nm2_per_ps"] < 1e-8 * row.momentum_change["angular_start"]
    assert all(
        f.position_rms < by_name["RATTLE h/3"].horizons[i].position_rms / 10
        for i, f in enumerate(result.reference_convergence)
    )
    table = format_accuracy_table(result)
    assert "reference h/64 vs h/128" in table and "RATTLE + rescaling h/3" in table


def test_equilibrium_averages_say_whether_a_difference_is_resolved(water_box):
    averages = equilibrium_averages(
        water_box, [("RATTLE", at_divisor("rattle", H))], 0.2, H, blocks=2, progress=False
    )
    reference, rattle = averages["RATTLE h/4 (reference)"], averages["RATTLE"]
    assert 250 < reference["temperature_K"]["mean"] < 350
    assert 0.26 < reference["rdf_peak_position_nm"]["mean"] < 0.30
    assert reference["temperature_K"]["resolved"] is None
    for key, average in rattle.items():
        assert average["difference"] == pytest.approx(average["mean"] - reference[key]["mean"])
        assert average["resolved"] == (abs(average["difference"]) > 2 * average["difference_standard_error"])


def test_the_command_writes_json_and_figure_and_skips_finished_systems(tmp_path, capsys):
    out, figure = tmp_path / "accuracy.json", tmp_path / "accuracy.png"
    argv = [
        "bench",
        "accuracy",
        "--system",
        "water-cluster",
        "--integrators",
        "rattle",
        "rattle+rescale",
        "--horizons",
        "2",
        "4",
        "--timing-rounds",
        "1",
        "--json",
        str(out),
        "--figure",
        str(figure),
    ]
    assert main(argv) == 0
    result = json.loads(out.read_text())
    rows = result["systems"]["water-cluster"]["rows"]
    assert [row["name"] for row in rows[:2]] == ["RATTLE", "RATTLE + rescaling"]
    # taking the rigid rotation out costs a small cluster several RATTLE steps: RATTLE at h/r joins
    assert all(row["role"].startswith("equal wall time (rattle+rescale)") for row in rows[2:])
    assert figure.stat().st_size > 10_000
    assert "RATTLE + rescaling" in capsys.readouterr().out
    assert main(argv) == 0  # the same settings: the finished system is not run again
    assert "done in" in capsys.readouterr().err
    written = out.read_text()
    with pytest.raises(SystemExit):  # other settings: the results are not overwritten
        main([*argv[:-4], "--timestep", "1", *argv[-4:]])
    assert "other settings" in capsys.readouterr().err
    assert out.read_text() == written
