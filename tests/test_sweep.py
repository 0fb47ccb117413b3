"""Sweep runner: grid expansion, a tiny sweep on dask with a failing cell, resume, scheduler, CLI."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest

from openmm_alphaprk.workflows.sweep import (
    ERROR_FILE,
    TABLE_FILE,
    SweepConfigError,
    load_config,
    parse_config,
    read_table,
    run_sweep,
)

#: The vacuum water cluster on the Reference platform: 20 steps per cell, a second or less.
TINY = {
    "output": "out",
    "run": {
        "duration_ps": 0.04,
        "platform": "Reference",
        "energy_interval_fs": 10,
        "trajectory_interval_fs": 20,
        "checkpoint_interval_fs": 20,
    },
    "grid": [
        {
            "systems": ["water-cluster"],
            "integrators": ["rattle", "alpha={alpha}"],
            "alphas": ["1/6"],
            "timesteps_fs": [2],
            "seeds": [1, 2],
        },
        # 40 fs is far beyond stability: this cell blows up at its first step.
        {"systems": ["water-cluster"], "integrators": ["rattle"], "timesteps_fs": [40], "duration_ps": 0.4},
    ],
}
FAILING = "water-cluster__rattle__40fs__start"


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


def test_grid_expansion():
    config = parse_config(
        {
            "output": "o",
            "run": {"duration_ps": 1, "energy_interval_fs": 20, "velocity_interval_fs": 4},
            "grid": [
                {
                    "systems": ["tip3p-2nm", "water-cluster"],
                    "integrators": ["rattle", "alpha={alpha}", "energy4"],
                    "alphas": ["1/6", 0.5],
                    "timesteps_fs": [2, "2/3"],
                    "seeds": [1, 2],
                },
                {"systems": ["tip3p-2nm"], "integrators": ["rattle"], "timesteps_fs": [2], "seeds": [1]},
            ],
        },
        base="/tmp/x",
    )
    # 2 systems x (rattle, alpha=1/6, alpha=1/2, energy4) x 2 steps x 2 seeds; the second grid repeats a cell
    assert len(config.cells) == 32
    assert config.output == Path("/tmp/x/o")
    assert {c.integrator for c in config.cells} == {"rattle", "alpha=1/6", "alpha=1/2", "energy4"}
    assert len({c.name for c in config.cells}) == 32
    cell = next(c for c in config.cells if c.timestep_fs == Fraction(2, 3) and c.integrator == "alpha=1/6")
    assert cell.steps == 1500 and cell.name.startswith("tip3p-2nm__alpha=1_6__2_3fs__seed")
    kwargs = cell.kwargs()
    assert kwargs["energy_interval"] == 30 and kwargs["velocity_interval"] == 6  # 20 fs, 4 fs of 2/3 fs
    two = next(c for c in config.cells if c.timestep_fs == 2)
    assert two.kwargs()["energy_interval"] == 10 and two.steps == 500
    assert "controller_interval" not in kwargs and kwargs["checkpoint_seconds"] == 60.0  # the defaults
    run = {"duration_ps": 1, "controller_interval_fs": 40, "checkpoint_seconds": 5}
    grid = [{"systems": ["water-cluster"], "integrators": ["energy4"], "timesteps_fs": ["2/3"]}]
    (cell,) = parse_config({"output": "o", "run": run, "grid": grid}, base="/tmp/x").cells
    assert cell.kwargs()["controller_interval"] == 60 and cell.kwargs()["checkpoint_seconds"] == 5


@pytest.mark.parametrize(
    "change, message",
    [
        (
            {"grid": [{"systems": ["no-such-box"], "integrators": ["rattle"], "timesteps_fs": [2]}]},
            "no-such-box",
        ),
        (
            {"grid": [{"systems": ["water-cluster"], "integrators": ["leapfrog"], "timesteps_fs": [2]}]},
            "leapfrog",
        ),
        (
            {"grid": [{"systems": ["water-cluster"], "integrators": ["alpha={alpha}"], "timesteps_fs": [2]}]},
            "alphas",
        ),
        (
            {"grid": [{"systems": ["water-cluster"], "integrators": ["rattle"], "timesteps_fs": [-2]}]},
            "positive",
        ),
        (
            {"grid": [{"systems": ["water-cluster"], "integrators": ["rattle"], "timesteps_fs": ["2fs"]}]},
            "2/3",
        ),
        (
            {
                "grid": [
                    {
                        "systems": ["water-cluster"],
                        "integrators": ["rattle"],
                        "timesteps_fs": [2],
                        "seeds": [1.5],
                    }
                ]
            },
            "seeds",
        ),
        (
            {"grid": [{"systems": ["water-cluster"], "integrators": ["rattle"], "timestep_fs": [2]}]},
            "timestep_fs",
        ),
        ({"grid": []}, "at least one"),
        ({"colour": "blue"}, "colour"),
        ({"cluster": {"n_workers": 0}}, "n_workers"),
        ({"output": None}, "output"),
    ],
)
def test_bad_configuration_is_refused_with_the_entry_named(change, message):
    data = json.loads(json.dumps(TINY)) | change
    if data.get("output") is None:
        del data["output"]
    with pytest.raises(SweepConfigError, match=message):
        parse_config(data)


def test_missing_or_broken_file(tmp_path):
    with pytest.raises(SweepConfigError, match="does not exist"):
        load_config(tmp_path / "none.toml")
    (tmp_path / "bad.toml").write_text("output = \n", encoding="utf-8")
    with pytest.raises(SweepConfigError, match="not valid TOML"):
        load_config(tmp_path / "bad.toml")


def test_tiny_sweep_records_the_failing_cell_and_resumes(tmp_path, cache):
    config = parse_config(TINY, base=tmp_path)
    seen = []
    first = run_sweep(
        config, processes=False, n_workers=2, cache_dir=cache, progress=False, on_row=seen.append
    )
    assert sorted(first.ran) == sorted(c.name for c in config.cells) and first.skipped == []
    assert first.failed == [FAILING] and len(seen) == 5
    rows = {row["cell"]: row for row in read_table(tmp_path / "out" / TABLE_FILE)}
    assert set(rows) == {c.name for c in config.cells}  # the failed cell is in the table, not dropped
    assert rows[FAILING]["status"] == "failed" and "NaN" in rows[FAILING]["error"]
    assert "NaN" in json.loads((tmp_path / "out" / FAILING / ERROR_FILE).read_text(encoding="utf-8"))["error"]
    ok = [row for name, row in rows.items() if name != FAILING]
    assert all(row["status"] == "ok" and int(float(row["steps"])) == 20 for row in ok)
    assert all(float(row["rms_residual"]) > 0 and float(row["force_evaluations_per_step"]) >= 1 for row in ok)
    # seeds give different starts; the same seed gives the same start for both integrators
    e_ref = {(row["integrator"], row["seed"]): float(row["e_ref"]) for row in ok}
    assert e_ref[("rattle", "1")] != e_ref[("rattle", "2")]
    assert e_ref[("rattle", "1")] == e_ref[("alpha=1/6", "1")]

    # a re-run skips finished and failed cells and leaves their files alone
    summary = tmp_path / "out" / "water-cluster__rattle__2fs__seed1" / "summary.json"
    stamp = summary.stat().st_mtime_ns
    again = run_sweep(config, processes=False, cache_dir=cache, progress=False)
    assert again.ran == [] and len(again.skipped) == 5 and again.failed == [FAILING]
    assert summary.stat().st_mtime_ns == stamp
    assert [row["cell"] for row in again.rows] == [c.name for c in config.cells]

    # an interrupted cell (no summary yet) runs again from its checkpoint; so do failed ones on request
    interrupted = tmp_path / "out" / "water-cluster__alpha=1_6__2fs__seed2"
    (interrupted / "summary.json").unlink()
    resumed = run_sweep(config, processes=False, cache_dir=cache, progress=False, retry_failed=True)
    assert sorted(resumed.ran) == sorted([interrupted.name, FAILING]) and resumed.failed == [FAILING]
    rows = {row["cell"]: row for row in read_table(tmp_path / "out" / TABLE_FILE)}
    assert rows[interrupted.name]["status"] == "ok" and rows[interrupted.name]["steps_this_call"] == "0"


def test_sweep_on_a_running_scheduler(tmp_path, cache):
    from dask.distributed import LocalCluster

    data = json.loads(json.dumps(TINY))
    data["grid"] = data["grid"][:1]
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        result = run_sweep(
            parse_config(data, base=tmp_path),
            scheduler=cluster.scheduler_address,
            cache_dir=cache,
            progress=False,
        )
    assert len(result.ran) == 4 and result.failed == []


def test_a_longer_run_is_not_taken_for_a_finished_cell(tmp_path):
    """A cell's folder holding a longer run is not reported as the cell (run_nve refuses it when run)."""
    from openmm_alphaprk.workflows.sweep import cell_status

    cell = parse_config(TINY, base=tmp_path).cells[0]
    folder = tmp_path / cell.name
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"steps": 2 * cell.steps}), encoding="utf-8")
    assert cell_status(cell, folder) is None
    (folder / "summary.json").write_text(json.dumps({"steps": cell.steps}), encoding="utf-8")
    assert cell_status(cell, folder)["status"] == "ok"


def test_cli_runs_a_sweep_through_the_installed_script(tmp_path, cache):
    config = tmp_path / "tiny.toml"
    config.write_text(
        'output = "cli-out"\n[run]\nduration_ps = 0.02\nplatform = "Reference"\nenergy_interval_fs = 10\n'
        "trajectory_interval_fs = 10\ncheckpoint_interval_fs = 10\n[cluster]\nn_workers = 1\n"
        '[[grid]]\nsystems = ["water-cluster"]\nintegrators = ["rattle", "energy"]\ntimesteps_fs = [2]\n',
        encoding="utf-8",
    )
    script = Path(sys.executable).parent / "alphaprk"
    env = os.environ | {"ALPHAPRK_CACHE_DIR": str(cache)}
    listed = subprocess.run(
        [script, "sweep", config, "--list"], capture_output=True, text=True, encoding="utf-8", env=env
    )
    assert listed.returncode == 0 and listed.stdout.count("to run") == 2
    done = subprocess.run(
        [script, "sweep", config, "--quiet"], capture_output=True, text=True, encoding="utf-8", env=env
    )
    assert done.returncode == 0, done.stderr
    assert "2 run now, 0 finished before, 0 failed" in done.stdout
    # the cell count once, not in both the start line and the result line
    again = subprocess.run(
        [script, "sweep", config], capture_output=True, text=True, encoding="utf-8", env=env
    )
    assert again.returncode == 0, again.stderr
    assert (again.stdout + again.stderr).count("2 cells") == 1
    assert "0 run now, 2 finished before, 0 failed" in again.stdout
    rows = read_table(tmp_path / "cli-out" / TABLE_FILE)
    energy = next(row for row in rows if row["integrator"] == "energy")
    assert energy["status"] == "ok" and float(energy["controller.force_evaluations_per_step"]) > 2
    bad = subprocess.run(
        [script, "sweep", tmp_path / "missing.toml"],
        capture_output=True,
        text=True,
        encoding="utf-8",
        env=env,
    )
    assert bad.returncode == 2 and "does not exist" in bad.stderr


def test_rattle_plus_rescale_is_a_sweep_integrator_with_its_own_folder():
    grid = [{"systems": ["water-cluster"], "integrators": ["rattle", "rattle+rescale"], "timesteps_fs": [2]}]
    cells = parse_config({"output": "o", "run": {"duration_ps": 0.1}, "grid": grid}).cells
    assert [c.integrator for c in cells] == ["rattle", "rattle+rescale"]
    assert len({c.name for c in cells}) == 2 and "rattle+rescale" in cells[1].name
