"""The cost benchmark runs end to end and reports what it measured."""

import json

import openmm.unit as unit
import pytest

from openmm_alphaprk.benchmarks import cost
from openmm_alphaprk.benchmarks.cost import main
from openmm_alphaprk.runs.integrator_names import label


def test_benchmark_command_prints_and_writes_the_table(tmp_path, capsys, monkeypatch, water_box):
    """The command on the tests' stored 1.8 nm box: it asks the builder for that box, which is not rebuilt.

    ``build_water_box`` itself is checked against that stored state bit for bit
    (test_systems, slow); its builder, ``prepare_system``, builds the named boxes.
    """
    asked = []

    def stored_box(box, **options):
        asked.append((box, options))
        return water_box

    monkeypatch.setattr(cost, "build_water_box", stored_box)
    out = tmp_path / "bench.json"
    args = "--box 1.8 --cutoff 0.8 --steps 3 --rounds 1 --energy-steps 3 --equilibration-steps 300"
    assert main([*args.split(), "--json", str(out)]) == 0
    assert asked == [(1.8, {"cutoff": 0.8, "equilibration_steps": 300, "platform": "CPU"})]
    printed = capsys.readouterr().out
    assert label("alpha=1/6") in printed and "time ratio" in printed
    rows = {row["name"]: row for row in json.loads(out.read_text(encoding="utf-8"))["rows"]}
    assert rows[label("rattle")]["force_evaluations_per_step"] == 1.0
    assert rows[label("alpha=0")]["force_evaluations_per_step"] == 1.0
    assert rows[label("alpha=1/2")]["force_evaluations_per_step"] > 2.0
    # α = 0 takes RATTLE's step: the same energies from the same start (to the CPU platform's round-off)
    assert rows[label("alpha=0")]["energy_rms"] == pytest.approx(
        rows[label("rattle")]["energy_rms"], rel=1e-3
    )
    assert rows[label("alpha=1/2")]["energy_rms"] != pytest.approx(
        rows[label("rattle")]["energy_rms"], rel=1e-3
    )


def test_cost_on_a_package_system_with_named_integrators(tmp_path, capsys):
    """``--system`` times from the system's shipped state; names give the rows in order; ns/day from ms."""
    out = tmp_path / "bench.json"
    args = "--system tip3p-2nm --steps 2 --rounds 1 --energy-steps 2 --timestep 1.5"
    assert (
        main([*args.split(), "--integrators", "rattle", "verlet", "rattle+rescale", "--json", str(out)]) == 0
    )
    printed = capsys.readouterr().out
    result = json.loads(out.read_text(encoding="utf-8"))
    header = result["header"]
    assert "system tip3p-2nm" in header and "774 atoms" in header and "platform CPU" in header
    assert "precision single" in header and header in printed and "ns/day" in printed
    assert result["system"] == "tip3p-2nm" and result["atoms"] == 774 and result["timestep_fs"] == 1.5
    rows = result["rows"]
    assert [row["name"] for row in rows] == [label("rattle"), label("verlet"), label("rattle+rescale")]
    assert rows[0]["time_ratio"] == 1.0  # the first name is the baseline
    for row in rows:
        expected = 86400 * 1.5e-6 / (row["ms_per_step"] / 1000)
        assert row["ns_per_day"] == pytest.approx(expected, rel=1e-9)
        assert f"{row['ns_per_day']:.2f}" in printed


def test_cost_integrator_names_expand_sets_and_refuse_unknown_names(capsys):
    assert cost.integrator_names(["core"]) == list(cost.CORE)
    assert cost.integrator_names(["verlet", "alpha4=0", "rattle4+rescale"]) == [
        "verlet",
        "alpha4=0",
        "rattle4+rescale",
    ]
    assert cost.integrator_names(["all"])[: len(cost.CORE)] == list(cost.CORE)
    with pytest.raises(ValueError, match="given twice"):
        cost.integrator_names(["core", "rattle"])
    with pytest.raises(SystemExit) as exit_info:
        main(["--system", "water-cluster", "--integrators", "rattle", "ratle"])
    assert exit_info.value.code == 2
    assert "unknown integrator 'ratle': no integrator family 'ratle'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--system", "tip3p-9nm"])
    assert "unknown system 'tip3p-9nm'; choose from" in capsys.readouterr().err


def test_ns_per_day():
    # 2 fs at 1 ms a step: 86,400 steps of 2 fs a day
    assert cost.ns_per_day(1.0, 0.002) == pytest.approx(172.8)
    assert cost.ns_per_day(0.0, 0.002) != cost.ns_per_day(0.0, 0.002)  # NaN


def test_cost_hydrogen_mass_repartitions_a_copy_of_the_system(capsys):
    """``--hydrogen-mass``: the start's System (a copy) gets it; water's hydrogens are left alone."""
    from openmm_alphaprk.systems import prepare_system

    args = cost._parser().parse_args(["--system", "water-cluster", "--hydrogen-mass", "3"])
    start, description = cost._start(args)
    assert (
        "hydrogen mass 3 amu" in description
        and "no hydrogen bonded to a heavy atom" in capsys.readouterr().err
    )
    assert start.system is not prepare_system("water-cluster").system
    assert start.system.getParticleMass(1).value_in_unit(unit.dalton) == pytest.approx(1.008, abs=1e-3)
    args = cost._parser().parse_args(["--system", "villin", "--hydrogen-mass", "3"])
    start, _ = cost._start(args)
    shipped = prepare_system("villin").system
    before = [shipped.getParticleMass(i).value_in_unit(unit.dalton) for i in range(shipped.getNumParticles())]
    after = [start.system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(len(before))]
    assert sum(after) == pytest.approx(sum(before)) and after.count(3.0) > 100 and before.count(3.0) == 0
    assert "hydrogen mass repartitioned" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--system", "water-cluster", "--hydrogen-mass", "5"])
    assert "outside 1-4 amu" in capsys.readouterr().err
