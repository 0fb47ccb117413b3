"""The README's main job (``alphaprk compare``) from the shipped start state gives the README's numbers.

Marked slow (about 20 min on 2 cores): run with ``python -m pytest -m slow tests/test_main_job.py``.
The CPU platform sums forces in a thread-dependent order, so runs are not bitwise
repeatable and the chaotic trajectories part after a few hundred steps: the README states
its numbers to the precision checked here (RATTLE and `alpha4=0` 15 %, the energy mode
within a factor 2, its force evaluations per step to 0.5; RATTLE at h/k to 15 %, the gain
at equal cost within a factor 2; RATTLE + rescaling below 1/100 of RATTLE; the position
errors after 20 fs: RATTLE at h/k to 15 %, the energy mode within a factor 2 and above it,
`rattle4+rescale` within a factor 2 and 5× below RATTLE at h/5).
"""

import math
import re
from pathlib import Path

import pytest

from openmm_alphaprk.workflows import compare

README = Path(__file__).parents[1] / "README.md"


def _readme_numbers() -> dict[str, float]:
    text = " ".join(README.read_text(encoding="utf-8").split())
    match = re.search(
        r"RMS \|H − E_ref\| ([0-9.]+) kJ/mol for RATTLE, ([0-9.e-]+) for `rattle\+rescale`, ([0-9.e-]+) for "
        r"`rattle4\+rescale`, ([0-9.]+) for `energy4` at ([0-9.]+) force evaluations per step, ([0-9.]+) for "
        r"`alpha4=0`",
        text,
    )
    assert match, "the README's main-job sentence changed: update this test with it"
    rattle, rescale, rescale4, energy4, evaluations, composed = map(float, match.groups())
    positions = re.search(
        r"its position error after 20 fs is ([0-9.e-]+) nm against ([0-9.e-]+) for RATTLE at h/[0-9]+, "
        r"([0-9.]+)× higher",
        text,
    )
    assert positions, "the README's position-error sentence changed: update this test with it"
    equal_cost = re.search(r"and ([0-9.]+) for RATTLE at h/([0-9]+), so `energy4` is ([0-9.]+)× lower", text)
    assert equal_cost, "the README's equal-cost sentence changed: update this test with it"
    composed_positions = re.search(
        r"`rattle4\+rescale`'s is ([0-9.e-]+) nm against ([0-9.e-]+) for RATTLE at h/5, ([0-9.]+)× lower",
        text,
    )
    assert composed_positions, "the README's rattle4+rescale sentence changed: update this test with it"
    return {
        "rattle": rattle,
        "rattle+rescale": rescale,
        "rattle4+rescale": rescale4,
        "energy4": energy4,
        "evaluations": evaluations,
        "alpha4=0": composed,
        "rattle h/k": float(equal_cost.group(1)),
        "k": int(equal_cost.group(2)),
        "gain": float(equal_cost.group(3)),
        "energy4 position": float(positions.group(1)),
        "rattle h/k position": float(positions.group(2)),
        "position loss": float(positions.group(3)),
        "rattle4+rescale position": float(composed_positions.group(1)),
        "rattle h/5 position": float(composed_positions.group(2)),
        "rattle4+rescale position gain": float(composed_positions.group(3)),
    }


@pytest.mark.slow
def test_the_main_job_gives_the_readme_numbers(tmp_path):
    expected = _readme_numbers()
    result = compare(output=tmp_path / "main-job", plot=False, progress=False)
    by_name = {summary.integrator: summary for summary in result.summaries}
    assert by_name["rattle"].rms_residual == pytest.approx(expected["rattle"], rel=0.15)
    assert by_name["alpha4=0"].rms_residual == pytest.approx(expected["alpha4=0"], rel=0.15)
    assert expected["energy4"] / 2 <= by_name["energy4"].rms_residual <= 2 * expected["energy4"]
    evaluations = by_name["energy4"].force_evaluations_per_step
    assert evaluations == pytest.approx(expected["evaluations"], abs=0.5)
    k = expected["k"]
    assert by_name[f"rattle h/{k}"].rms_residual == pytest.approx(expected["rattle h/k"], rel=0.15)
    gain = by_name[f"rattle h/{k}"].rms_residual / by_name["energy4"].rms_residual
    assert expected["gain"] / 2 <= gain <= 2 * expected["gain"]
    assert by_name["rattle+rescale"].rms_residual <= by_name["rattle"].rms_residual / 100
    positions = {name: horizon.position_rms for name, horizon in result.accuracy.items()}
    assert positions[f"rattle h/{k}"] == pytest.approx(expected["rattle h/k position"], rel=0.15)
    energy4 = expected["energy4 position"]
    assert energy4 / 2 <= positions["energy4"] <= 2 * energy4
    assert positions["energy4"] > positions[f"rattle h/{k}"]  # the loss the README states
    assert by_name["rattle4+rescale"].rms_residual <= by_name["rattle"].rms_residual / 100
    composed = expected["rattle4+rescale position"]
    assert composed / 2 <= positions["rattle4+rescale"] <= 2 * composed
    assert positions["rattle h/5"] == pytest.approx(expected["rattle h/5 position"], rel=0.15)
    assert positions["rattle4+rescale"] < positions["rattle h/5"] / 5  # the gain the README states


def test_the_readme_main_job_sentence_is_self_consistent():
    """k is the energy mode's evaluations per step rounded up, the gain the ratio of the two RMS."""
    numbers = _readme_numbers()
    assert numbers["k"] == math.ceil(numbers["evaluations"])
    assert numbers["gain"] == pytest.approx(numbers["rattle h/k"] / numbers["energy4"], rel=0.05)
    assert numbers["energy4"] < numbers["alpha4=0"] < numbers["rattle"]
    assert numbers["rattle+rescale"] < numbers["rattle"] / 100
    assert numbers["rattle4+rescale"] < numbers["rattle"] / 100
    gain = numbers["rattle h/5 position"] / numbers["rattle4+rescale position"]
    assert numbers["rattle4+rescale position gain"] == pytest.approx(gain, rel=0.05)
    loss = numbers["energy4 position"] / numbers["rattle h/k position"]
    assert numbers["position loss"] == pytest.approx(loss, rel=0.05)
