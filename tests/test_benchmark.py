"""The cost benchmark runs end to end and reports what it measured."""

import json

import pytest

from openmm_alphaprk.benchmarks.cost import main
from openmm_alphaprk.runs.integrator_names import label


def test_benchmark_command_prints_and_writes_the_table(tmp_path, capsys):
    out = tmp_path / "bench.json"
    args = "--box 1.6 --cutoff 0.7 --steps 3 --rounds 1 --energy-steps 3 --equilibration-steps 20"
    assert main([*args.split(), "--json", str(out)]) == 0
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
