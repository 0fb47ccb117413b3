"""The energy benchmark runs the package's systems in one run and reports ratios against RATTLE."""

import json
import math

import pytest

from openmm_alphaprk.benchmarks import energy as energy_benchmark
from openmm_alphaprk.benchmarks.energy import EnergyRow, main, ratios_to_rattle
from openmm_alphaprk.runs.integrator_names import label

RATTLE, T0, E4 = label("rattle"), label("alpha4=0"), label("energy4")


def _row(name: str, rms: float, evals: float) -> EnergyRow:
    return EnergyRow(name, 10, 0.0, rms, rms, evals)


def test_ratios_against_rattle_at_the_same_step_and_at_equal_cost():
    # 7.2 evaluations per step: RATTLE at h/8 is the equal-cost row (k rounded up)
    rows = [_row(RATTLE, 1.0, 1), _row(E4, 0.02, 7.2), _row(f"{RATTLE} h/8", 0.05, 8)]
    rows.append(_row(T0, 0.1, 3))
    ratios = ratios_to_rattle(rows)
    same_step_and_cost = {key: ratios[E4][key] for key in ("rms_vs_rattle", "rms_vs_rattle_equal_cost")}
    assert same_step_and_cost == pytest.approx({"rms_vs_rattle": 50.0, "rms_vs_rattle_equal_cost": 2.5})
    assert ratios[T0] == pytest.approx({"rms_vs_rattle": 10.0})  # 3 evaluations: no equal-cost row
    assert RATTLE not in ratios and f"{RATTLE} h/8" not in ratios


def test_a_package_system_runs_with_the_ratios_in_table_and_json(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ALPHAPRK_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "energy.json"
    args = ["--system", "water-cluster", "--time", "0.01", "--json", str(out)]
    assert main([*args, "--only", "energy4", "--fixed-alpha"]) == 0
    printed = capsys.readouterr().out
    assert "system water-cluster" in printed and "at equal cost" in printed
    result = json.loads(out.read_text(encoding="utf-8"))["water-cluster"]
    rows = {row["name"]: row for row in result["rows"]}
    k = math.ceil(rows[E4]["force_evaluations_per_step"])  # rounded up: RATTLE at h/k costs no less
    assert list(rows) == [RATTLE, E4, f"{RATTLE} h/{k}"]
    assert all(row["steps"] == 5 for row in rows.values())
    ratio = result["ratios"][E4]
    assert ratio["rms_vs_rattle"] == pytest.approx(rows[RATTLE]["rms_residual"] / rows[E4]["rms_residual"])
    assert ratio["rms_vs_rattle_equal_cost"] == pytest.approx(
        rows[f"{RATTLE} h/{k}"]["rms_residual"] / rows[E4]["rms_residual"]
    )


def test_energy_modes_are_compared_with_triple_jump_and_the_best_fixed_alpha():
    fixed = {label("alpha4=0.01"): 0.04, label("alpha4=0.02"): 0.3}
    rows = [_row(RATTLE, 1.0, 1), _row(E4, 0.02, 4.2), _row(T0, 0.1, 3)]
    rows += [_row(name, rms, 5) for name, rms in fixed.items()]
    rows.append(_row(label("alpha4=0.005"), 0.01, 5))
    rows[-1].blew_up_at_step = 3  # a row that blew up is never the best
    ratios = ratios_to_rattle(rows)
    assert ratios[E4]["rms_vs_alpha4_0"] == pytest.approx(5.0)
    assert ratios[E4]["best_fixed_alpha"] == label("alpha4=0.01")
    assert ratios[E4]["rms_vs_best_fixed_alpha"] == pytest.approx(2.0)
    assert "rms_vs_alpha4_0" not in ratios[T0]  # fixed-alpha rows are baselines, not compared


def test_the_fixed_alpha_scan_runs_in_the_same_run(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("ALPHAPRK_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "energy.json"
    args = ["--system", "water-cluster", "--time", "0.01", "--json", str(out), "--only", "energy4"]
    assert main([*args, "--fixed-alpha", "0.01"]) == 0
    printed = capsys.readouterr().out
    assert f"than {label('alpha4=0.01')} " in printed  # the energy mode against the best fixed alpha
    result = json.loads(out.read_text(encoding="utf-8"))["water-cluster"]
    names = [row["name"] for row in result["rows"]]
    assert label("alpha4=0.01") in names
    ratio = result["ratios"][E4]
    assert ratio["best_fixed_alpha"] == label("alpha4=0.01")
    rms = {row["name"]: row["rms_residual"] for row in result["rows"]}
    assert ratio["rms_vs_best_fixed_alpha"] == pytest.approx(rms[label("alpha4=0.01")] / rms[E4])


def test_a_system_named_twice_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["--system", "water-cluster", "water-cluster"])
    assert "named twice" in capsys.readouterr().err


def test_unknown_system_is_refused_before_any_work(capsys):
    with pytest.raises(SystemExit):
        main(["--system", "no-such-box"])
    assert "unknown system(s) ['no-such-box']" in capsys.readouterr().err
    assert energy_benchmark.list_systems()  # the message's list comes from the definitions
