"""``alphaprk bench physics``: segments from independent starts, stress and order runs, and their report."""

import json

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest

from openmm_alphaprk.benchmarks import physics
from openmm_alphaprk.observables import masses
from openmm_alphaprk.runs import read_energies


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """Two starts, RATTLE and rattle+rescale at 2 fs beside the references, a stress and an order run."""
    out = tmp_path_factory.mktemp("physics")
    common = ["--output", str(out), "--no-progress", "--threads", "1"]
    segments = ["--starts", "2", "--spacing", "0.05", "--length", "0.5", "--timesteps", "2"]
    assert physics.main(["segments", *segments, "--rows", "rattle", "rattle+rescale", *common]) == 0
    assert (
        physics.main(["stress", "--rows", "rattle+rescale", "--timesteps", "4", "--time", "1.6", *common])
        == 0
    )
    assert (
        physics.main(["order", "--rows", "rattle", "--timesteps", "2", "1", "--length", "0.5", *common]) == 0
    )
    assert physics.main(["report", "--windows", "2", *common]) == 0
    return out, json.loads((out / "physics.json").read_text(encoding="utf-8"))


def test_the_starts_are_independent_langevin_states_and_each_setting_has_a_run_per_start(bench):
    out, data = bench
    starts = [mm.XmlSerializer.deserialize((out / "starts" / f"start_{i}.xml").read_text()) for i in range(2)]
    x = [s.getPositions(asNumpy=True).value_in_unit(unit.nanometers) for s in starts]
    assert np.abs(x[0] - x[1]).max() > 1e-3  # 0.05 ps of Langevin dynamics apart
    # on the constraints: projecting a start's velocities again leaves its kinetic energy as it is
    prepared = physics._prepared(physics._parser().parse_args(["segments"]))
    context = mm.Context(
        prepared.system, mm.VerletIntegrator(0.001), mm.Platform.getPlatformByName("Reference")
    )
    m = masses(prepared.system)[:, None]

    def kinetic() -> float:  # from the velocities (a Verlet State's kinetic energy is time-shifted)
        v = context.getState(getVelocities=True).getVelocities(asNumpy=True)._value
        return 0.5 * float((m * v**2).sum())

    for start in starts:
        context.setState(start)
        before = kinetic()
        context.applyVelocityConstraints(1e-12)
        after = kinetic()
        assert abs(before - after) < 1e-6, (before, after)  # Langevin's own velocities: about 2 kJ/mol
    for setting in ("rattle@0.5fs", "rattle@1fs", "rattle@2fs", "rattle+rescale@2fs"):
        for i in range(2):
            run = out / "segments" / setting / f"start_{i}"
            assert (run / "trajectory.trr").is_file() and (run / "summary.json").is_file()
            parameters = json.loads((run / "run.json").read_text())
            assert parameters["system_key"].endswith(f"-nvt{i}")
            assert parameters["velocity_interval"] * parameters["timestep_ps"] == pytest.approx(0.02)
    # one start, one E_ref: every row from start 1 begins at the same total energy
    e_ref = {read_energies(run / "energies.csv")[0, 4] for run in (out / "segments").glob("*/start_1")}
    assert max(e_ref) - min(e_ref) < 1e-3


def test_the_report_pairs_settings_by_start_and_holds_every_analysis(bench):
    out, data = bench
    assert data["system"] == "tip3p-2nm"
    paired = data["paired"]
    assert paired["rattle@0.5fs"]["temperature_difference_K"] == [0.0, 0.0]
    # the paired difference is the mean of the per-start differences of the runs' own means
    rows = {
        name: [
            read_energies(out / "segments" / name / f"start_{i}" / "energies.csv")[1:, 5].mean()
            for i in range(2)
        ]
        for name in ("rattle@0.5fs", "rattle+rescale@2fs")
    }
    expected = np.mean(np.array(rows["rattle+rescale@2fs"]) - np.array(rows["rattle@0.5fs"]))
    assert paired["rattle+rescale@2fs"]["temperature_difference_K"][0] == pytest.approx(expected)
    assert data["segments"]["equipartition"]["reference"]["label"] == "rattle h=0.5 fs"
    assert {s["integrator"] for s in data["transport"]["settings"]} == {"rattle", "rattle+rescale"}
    curve = data["curves"]["rattle@2fs"]
    assert 2.5 < max(curve["g"]) < 4 and len(curve["r_angstrom"]) == len(curve["g"])
    windows = data["stress"]["rattle+rescale@4fs"]["windows"]
    assert len(windows) == 2 and windows[1]["end_ps"] == pytest.approx(1.6, abs=0.03)
    assert 200 < windows[0]["temperatures"]["system"]["translational"]["temperature_K"] < 400
    assert data["order"]["order"]["rattle"]["kind"] == "order"


def test_a_second_call_resumes_instead_of_running_again(bench, capsys):
    out, _ = bench
    run = out / "segments" / "rattle@2fs" / "start_0"
    before = {name: (run / name).read_bytes() for name in ("summary.json", "trajectory.trr", "energies.csv")}
    segments = [
        "--starts",
        "2",
        "--spacing",
        "0.05",
        "--length",
        "0.5",
        "--timesteps",
        "2",
        "--rows",
        "rattle",
    ]
    assert physics.main(["segments", *segments, "--output", str(out), "--no-progress", "--threads", "1"]) == 0
    assert {name: (run / name).read_bytes() for name in before} == before  # the finished run is not redone


def test_the_report_of_a_cluster_in_vacuum_leaves_out_the_g_of_r_and_keeps_the_rest(tmp_path):
    """A system without a periodic box (the water cluster): no g(r), the scaling's statistics are there."""
    common = [
        "--output",
        str(tmp_path),
        "--no-progress",
        "--platform",
        "Reference",
        "--system",
        "water-cluster",
    ]
    segments = ["--starts", "2", "--spacing", "0.02", "--length", "0.4", "--timesteps", "2"]
    assert physics.main(["segments", *segments, "--rows", "rattle+rescale", *common]) == 0
    assert physics.main(["report", *common]) == 0
    data = json.loads((tmp_path / "physics.json").read_text(encoding="utf-8"))
    curve = data["curves"]["rattle+rescale@2fs"]
    assert "g" not in curve and len(curve["msd_angstrom2"]) == len(curve["lag_ps"]) > 1
    runs = data["segments"]["rescaling"]["runs"]
    assert len(runs) == 2 and all(r["rescalings"] == 200 for r in runs.values())
