"""The main job, ``alphaprk compare``: its preset, platform and verdict, and the README's copy of its output.

The README's and getting started's "main job" block is rendered from the JSON the main job
wrote (``docs/data/main_job/``, by ``python -m tools.reports.main_job``); the slow test runs
the main job again and checks it against that JSON. The CPU platform sums forces in a
thread-dependent order, so runs are not bitwise repeatable: RATTLE's and `alpha4=0`'s RMS
agree to 15 %, the energy mode's and the position errors within a factor 2.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_cli import alphaprk

from openmm_alphaprk.platforms import fastest_platform
from openmm_alphaprk.runs import RunSummary
from openmm_alphaprk.runs.accuracy import Horizon
from openmm_alphaprk.workflows.comparison import MAIN_JOB, compare, equal_cost_standings, verdict
from tools.reports import main_job
from tools.reports.markdown import stale_blocks

ROOT = Path(__file__).resolve().parents[1]
RECORDED = ROOT / "docs" / "data" / "main_job" / "comparison.json"


def _summary(name: str, rms: float, evaluations: float = 1.0) -> RunSummary:
    return RunSummary(
        system="box",
        integrator=name,
        n_atoms=3,
        degrees_of_freedom=6,
        timestep_fs=2.0,
        steps=10,
        simulated_ps=0.02,
        platform="CPU",
        e_ref=0.0,
        drift_per_dof=0.0,
        drift_per_dof_standard_error=0.0,
        drift_resolved=False,
        rms_residual=rms,
        max_abs_residual=rms,
        energy_samples=10,
        max_relative_constraint_error=0.0,
        max_constraint_velocity_error=0.0,
        ns_per_day=1.0,
        wall_seconds=1.0,
        steps_this_call=10,
        force_evaluations_per_step=evaluations,
        velocity_verlet=True,
    )


def _horizon(position: float) -> Horizon:
    return Horizon(steps=10, time_fs=20.0, position_rms=position, position_max=position,
                   velocity_rms=0.0, velocity_max=0.0)  # fmt: skip


def _recorded() -> tuple[list[RunSummary], dict[str, Horizon], dict]:
    data = json.loads(RECORDED.read_text(encoding="utf-8"))
    fields = set(RunSummary.__dataclass_fields__)
    summaries = [RunSummary(**{k: v for k, v in s.items() if k in fields}) for s in data["summaries"]]
    accuracy = {name: Horizon(**row) for name, row in data["accuracy"]["rows"].items()}
    return summaries, accuracy, data


# ---------------------------------------------------------------- the verdict
def test_the_verdict_names_the_row_that_holds_the_energy_and_tracks_the_positions_best():
    summaries = [
        _summary("rattle", 0.5),
        _summary("rattle+rescale", 1e-6),
        _summary("rattle4+rescale", 2e-6, 5.0),
        _summary("alpha4=0", 0.013, 5.0),
        _summary("energy4", 0.004, 8.4),
        _summary("rattle h/5", 0.025),
        _summary("rattle h/9", 0.015),
    ]
    accuracy = {
        "rattle": _horizon(8e-5),
        "rattle+rescale": _horizon(8e-5),
        "rattle4+rescale": _horizon(2e-7),
        "alpha4=0": _horizon(1.5e-7),  # closer, but it does not hold the energy
        "energy4": _horizon(1.4e-6),
        "rattle h/5": _horizon(3e-6),
        "rattle h/9": _horizon(1e-6),
    }
    said = verdict(summaries, accuracy)
    assert said.startswith("verdict: rattle4+rescale is best at equal cost")
    assert "positions 15x closer than RATTLE at h/5" in said
    assert (
        "the energy mode energy4: energy error 3.75x lower than RATTLE at h/9, positions 1.4x farther" in said
    )
    standings = {s.integrator: s for s in equal_cost_standings(summaries, accuracy)}
    assert standings["rattle+rescale"].baseline == "rattle" and standings["rattle+rescale"].holds_energy
    assert not standings["alpha4=0"].holds_energy  # 0.013 is not below RATTLE's 0.5 / 100


def test_without_positions_the_verdict_goes_by_the_energy_and_without_rattle_says_nothing():
    summaries = [_summary("rattle", 0.5), _summary("rattle+rescale", 1e-6), _summary("energy4", 0.004, 8.4)]
    assert verdict(summaries + [_summary("rattle h/9", 0.015)]).startswith("verdict: rattle+rescale is best")
    assert verdict(summaries[1:]) == ""


# ---------------------------------------------------------------- the platform
@pytest.mark.parametrize(
    "available, gpus, chosen",
    [
        (["Reference", "CPU", "OpenCL"], 0, "CPU"),  # pocl's CPU device: never chosen
        (["Reference", "CPU", "OpenCL"], 1, "OpenCL"),
        (["Reference", "CPU", "OpenCL", "HIP"], 1, "HIP"),
        (["Reference", "CPU", "OpenCL", "CUDA", "HIP"], 1, "CUDA"),
        (["Reference"], 0, "CPU"),
    ],
)
def test_the_fastest_platform_is_a_gpu_platform_else_cpu(available, gpus, chosen):
    name, reason = fastest_platform(available=available, opencl_gpus=gpus)
    assert name == chosen
    assert reason.startswith(chosen)


def test_this_machine_runs_the_main_job_on_the_cpu_platform():
    """CI and the development machines have no GPU; pocl's OpenCL must not be taken for one."""
    assert fastest_platform()[0] == "CPU"


# ---------------------------------------------------------------- the command
def test_the_main_job_runs_its_preset_on_the_fastest_platform_and_ends_with_its_verdict(tmp_path):
    result = alphaprk("compare", "--steps", "3", "--accuracy-steps", "1", "--no-plot", "-o", "job",
                      cwd=tmp_path, env_cache=tmp_path / "cache")  # fmt: skip
    data = json.loads((tmp_path / "job" / "comparison.json").read_text(encoding="utf-8"))
    rows = [summary["integrator"] for summary in data["summaries"]]
    assert data["system"] == MAIN_JOB.system
    assert rows[: len(MAIN_JOB.integrators)] == list(MAIN_JOB.integrators)
    assert {row for row in rows[len(MAIN_JOB.integrators) :]} >= {"rattle h/5"}
    assert {summary["steps"] for summary in data["summaries"][:5]} == {3}
    assert data["verdict"].startswith("verdict: ")
    lines = result.stdout.splitlines()
    assert data["verdict"] in lines
    assert any(line.startswith("platform CPU: no GPU platform usable here") for line in lines)


# ---------------------------------------------------------------- the pages
def test_the_readme_and_getting_started_show_the_main_jobs_recorded_output():
    assert stale_blocks(main_job.pages(), main_job.ROOT) == [], "run python -m tools.reports"
    block = main_job.render()
    _, _, data = _recorded()
    assert data["verdict"] in block
    for summary in data["summaries"]:
        assert f"`{summary['integrator']}`" in block


def test_the_recorded_main_job_is_the_preset_and_its_verdict_is_what_its_numbers_say():
    summaries, accuracy, data = _recorded()
    assert [s.integrator for s in summaries[: len(MAIN_JOB.integrators)]] == list(MAIN_JOB.integrators)
    assert {s.steps for s in summaries[: len(MAIN_JOB.integrators)]} == {MAIN_JOB.steps}
    assert data["system"] == MAIN_JOB.system
    assert verdict(summaries, accuracy) == data["verdict"]
    timing = json.loads((RECORDED.parent / "timing.json").read_text(encoding="utf-8"))
    assert len(timing["wall_seconds"]) >= 3 and max(timing["wall_seconds"]) <= 180, timing


@pytest.mark.slow
def test_the_main_job_gives_the_recorded_numbers(tmp_path):
    """About 1.5 min on 2 cores: the main job again, against its recorded JSON."""
    summaries, accuracy, _ = _recorded()
    expected = {s.integrator: s for s in summaries}
    result = compare(output=tmp_path / "main-job", plot=False, progress=False, steps=MAIN_JOB.steps)
    measured = {s.integrator: s for s in result.summaries}
    assert set(measured) == set(expected)
    for name in ("rattle", "alpha4=0", *[n for n in expected if n.startswith("rattle h/")]):
        assert measured[name].rms_residual == pytest.approx(expected[name].rms_residual, rel=0.15), name
    energy = expected["energy4"].rms_residual
    assert energy / 2 <= measured["energy4"].rms_residual <= 2 * energy
    for name in ("rattle+rescale", "rattle4+rescale"):  # round-off of the rescaled total: within 5x
        assert measured[name].rms_residual <= 5 * expected[name].rms_residual, name
    standings = {s.integrator: s for s in equal_cost_standings(result.summaries, result.accuracy)}
    recorded = {s.integrator: s for s in equal_cost_standings(summaries, accuracy)}
    # the verdict's claims, each with its margin (recorded: rattle4+rescale 14.7x closer than
    # RATTLE at h/5, the energy mode 1.04x; both rescaled rows hold the energy)
    assert result.verdict.startswith("verdict: rattle4+rescale is best at equal cost")
    composed = standings["rattle4+rescale"].position_gain
    assert (
        recorded["rattle4+rescale"].position_gain / 2
        <= composed
        <= 2 * recorded["rattle4+rescale"].position_gain
    )
    assert composed >= 5 and standings["energy4"].position_gain < composed / 3
    assert standings["rattle+rescale"].holds_energy and standings["rattle4+rescale"].holds_energy
