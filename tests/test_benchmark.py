"""The cost benchmark runs end to end and reports what it measured."""

import json

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
