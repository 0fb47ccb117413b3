"""alphaprk bench long: rows from one start, resumable, measured from what the run directories hold."""

from __future__ import annotations

import json

import numpy as np
import pytest

from openmm_alphaprk._units import InputError
from openmm_alphaprk.benchmarks import long
from openmm_alphaprk.observables import block_drift, fit_drift, residual_windows
from openmm_alphaprk.runs import read_energies, run_nve

ROWS = ["verlet", "rattle", "rattle+rescale", "alpha4=0"]


def _main(tmp_path, cache, *extra):
    argv = ["--system", "water-cluster", "--platform", "Reference", "--integrators", *ROWS]
    argv += ["--energy-interval", "5", "--blocks", "3", "--window", "0.02", "--output", str(tmp_path / "out")]
    argv += ["--no-progress", *extra]
    return long.main(argv)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ALPHAPRK_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_rows_run_their_lengths_from_one_start_and_are_measured_from_their_files(tmp_path, cache, capsys):
    assert _main(tmp_path, cache, "--time", "0.08", "--time-multi", "0.04") == 0
    result = json.loads((tmp_path / "out" / "long.json").read_text(encoding="utf-8"))
    rows = {row["integrator"]: row for row in result["water-cluster"]["rows"]}
    assert list(rows) == ROWS
    # one-evaluation rows run --time (40 steps of 2 fs), the composition --time-multi (20 steps)
    assert [rows[n]["steps"] for n in ROWS] == [40, 40, 40, 20]
    assert all(row["complete"] and row["samples"] == row["steps"] // 5 for row in rows.values())
    # the same start: every row's first energy row is the same state
    folder = tmp_path / "out" / "water-cluster"
    starts = {n: read_energies(folder / n / "energies.csv")[0, 2] for n in ROWS}
    assert len({round(value, 6) for value in starts.values()}) == 1
    # measured from the files: RMS |H - E_ref| of RATTLE equals the energies' own
    energies = read_energies(folder / "rattle" / "energies.csv")
    residual = energies[1:, 4] - energies[0, 4]
    assert rows["rattle"]["rms_residual"] == pytest.approx(np.sqrt(np.mean(residual**2)), rel=1e-12)
    assert rows["rattle"]["max_abs_residual"] == pytest.approx(np.max(np.abs(residual)), rel=1e-12)
    assert rows["rattle+rescale"]["rms_residual"] < 1e-6 < rows["rattle"]["rms_residual"]
    # the carried momentum against the state's, at the row's last step (the cluster's P is zero)
    assert rows["rattle+rescale"]["carried_momentum_error"] < 1e-6
    assert np.isnan(rows["rattle"]["carried_momentum_error"])
    assert rows["verlet"]["time_ratio_to_verlet"] == 1.0
    for row in rows.values():  # ns/day from ms/step and the 2 fs step
        assert row["ns_per_day"] == pytest.approx(
            0.002 * 1e-3 * 86400 / (row["ms_per_step"] * 1e-3), rel=1e-9
        )
        assert len(row["windows"]["rms"]) >= 2 and row["worst_window_rms"] == max(row["windows"]["rms"])
    table = (folder / "table.txt").read_text(encoding="utf-8")
    assert "drift/DOF kJ/mol/ns" in table and "ns/day" in table and "RATTLE + rescaling" in table
    assert "water-cluster" in capsys.readouterr().out


def test_a_longer_time_extends_the_runs_and_report_only_reads(tmp_path, cache):
    assert _main(tmp_path, cache, "--time", "0.04", "--time-multi", "0.02") == 0
    folder = tmp_path / "out" / "water-cluster"
    before = read_energies(folder / "rattle" / "energies.csv")
    assert _main(tmp_path, cache, "--time", "0.08", "--time-multi", "0.02") == 0
    after = read_energies(folder / "rattle" / "energies.csv")
    assert after[-1, 0] == 40 and before[-1, 0] == 20
    np.testing.assert_array_equal(after[: len(before)], before)  # extended, not run again
    timing = json.loads((folder / "rattle" / long.TIMING_FILE).read_text(encoding="utf-8"))
    assert [call["steps"] for call in timing] == [20, 20]
    # --report runs nothing: the files stay as they are, the rows are the same
    stamp = {n: (folder / n / "energies.csv").stat().st_mtime_ns for n in ROWS}
    result_before = json.loads((tmp_path / "out" / "long.json").read_text(encoding="utf-8"))
    assert _main(tmp_path, cache, "--time", "0.08", "--time-multi", "0.02", "--report") == 0
    assert stamp == {n: (folder / n / "energies.csv").stat().st_mtime_ns for n in ROWS}
    result_after = json.loads((tmp_path / "out" / "long.json").read_text(encoding="utf-8"))
    assert result_after["water-cluster"]["rows"] == result_before["water-cluster"]["rows"]


def test_a_row_that_stopped_short_is_reported_as_such(tmp_path, cache):
    folder = tmp_path / "water-cluster"
    run_nve(
        "water-cluster",
        "rattle",
        folder / "rattle",
        steps=20,
        energy_interval=5,
        platform="Reference",
        progress=False,
    )
    rows, traces = long.analyse_rows(
        "water-cluster",
        ["rattle", "rattle+rescale"],
        folder,
        444,
        {"rattle": 40, "rattle+rescale": 40},
        timestep_ps=0.002,
        window_ps=0.02,
        blocks=3,
    )
    assert [row.integrator for row in rows] == ["rattle"]  # a row never started has no line
    assert rows[0].steps == 20 and not rows[0].complete and rows[0].simulated_ps == pytest.approx(0.04)
    assert "(stopped)" in long.format_long_table(rows)
    assert set(traces) == {"rattle"}


def test_block_drift_finds_a_drift_under_correlated_noise_with_an_honest_error():
    """A known slope under AR(1) noise, 200 seeds: the SE matches the slopes' spread, few miss by 3 SE."""
    from scipy.signal import lfilter

    t = np.arange(2000.0) * 0.1  # 200 ps
    slopes, errors = [], []
    for seed in range(200):
        noise = lfilter([1.0], [1.0, -0.95], np.random.default_rng(seed).normal(0.0, 0.05, t.size))
        fit = block_drift(t, 0.003 * t + noise, blocks=10)  # 3 kJ/mol/ns under ~20-sample correlation
        slopes.append(fit.slope)
        errors.append(fit.standard_error)
    slopes, errors = np.array(slopes), np.array(errors)
    assert abs(slopes.mean() - 3.0) < 3 * slopes.std() / np.sqrt(slopes.size)  # unbiased
    assert 0.7 < np.median(errors) / slopes.std() < 1.4  # the error is the slope's true spread
    assert np.mean(np.abs(slopes - 3.0) > 3 * errors) < 0.05  # t with 8 dof: ~1.7 % beyond 3 SE


def test_block_drift_and_the_least_squares_fit_agree_without_noise():
    t = np.linspace(0.0, 100.0, 1001)
    values = -0.5 + 0.01 * t
    assert block_drift(t, values, 10).slope == pytest.approx(fit_drift(t, values).slope, rel=1e-9)
    assert block_drift(t, values, 10).slope == pytest.approx(10.0, rel=1e-9)  # kJ/mol/ns


@pytest.mark.parametrize(
    "times, values, blocks",
    [
        ([0.0, 1.0], [0.0, 1.0], 3),
        (np.arange(10.0), np.arange(10.0), 2),
        ([0, 1, 2, 3], [0, 1, np.nan, 3], 3),
    ],
)
def test_block_drift_refuses_what_it_cannot_fit(times, values, blocks):
    with pytest.raises(InputError):
        block_drift(times, values, blocks)


def test_residual_windows_match_a_direct_count():
    t = np.arange(0.0, 30.01, 0.5)  # 0 .. 30 ps
    y = np.sin(t)
    windows = residual_windows(t, y, 10.0)
    assert windows.starts_ps.tolist() == [0.0, 10.0, 20.0]
    for k, start in enumerate(windows.starts_ps):
        inside = (t > start) & (t <= start + 10.0)
        assert windows.samples[k] == inside.sum() == 20
        assert windows.rms[k] == pytest.approx(np.sqrt(np.mean(y[inside] ** 2)))
        assert windows.max_abs[k] == pytest.approx(np.max(np.abs(y[inside])))
    # OpenMM's accumulated time: 200.00000000022 ps is the end of the 20th window, not a 21st
    drifted = np.arange(0, 2001) * 0.1 * (1 + 1e-10)
    assert residual_windows(drifted, np.ones_like(drifted), 10.0).samples.tolist() == [100] * 20
    with pytest.raises(InputError, match="window_ps"):
        residual_windows(t, y, 0.0)


def test_bad_arguments_are_refused_before_any_run(tmp_path, cache, capsys):
    with pytest.raises(SystemExit):
        _main(tmp_path, cache, "--integrators", "rattle", "nonsense")
    with pytest.raises(SystemExit):
        _main(tmp_path, cache, "--time", "-1")
    assert not (tmp_path / "out" / "water-cluster").exists()
    assert "nonsense" in capsys.readouterr().err


def test_a_row_rescaling_every_nth_step_gets_its_drift_at_the_rescaling_steps(tmp_path, cache):
    """@10 sampled every 5 steps: H at the rows on rescaling steps is E_ref, the rows between are RATTLE's.

    The drift over the rescaling steps alone is at round-off; the drift over every row carries
    RATTLE's excursions between rescalings (the check can fail: those rows are far from E_ref).
    """
    argv = ["--system", "water-cluster", "--platform", "Reference", "--integrators", "rattle+rescale@10"]
    argv += ["--energy-interval", "5", "--blocks", "3", "--time", "0.12", "--output", str(tmp_path / "out")]
    assert long.main([*argv, "--no-progress"]) == 0
    result = json.loads((tmp_path / "out" / "long.json").read_text(encoding="utf-8"))
    (row,) = result["water-cluster"]["rows"]
    assert row["samples"] == 12 and row["rescaling_samples"] == 6
    energies = read_energies(tmp_path / "out" / "water-cluster" / "rattle+rescale_10" / "energies.csv")
    residual = energies[1:, 4] - energies[0, 4]
    assert np.abs(residual[1::2]).max() < 1e-8 < np.abs(residual[::2]).max()
    assert abs(row["drift_at_rescaling_per_dof"]) < 1e-6 and row["drift_at_rescaling_standard_error"] < 1e-6
    assert row["rms_residual"] > 1e3 * max(np.abs(residual[1::2]).max(), 1e-12)
    table = (tmp_path / "out" / "water-cluster" / "table.txt").read_text(encoding="utf-8")
    assert "at its rescaling steps alone (6 energy rows)" in table
