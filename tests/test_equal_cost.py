"""The equal-cost comparison every table uses: k, the matching baseline, the gain and its wording."""

import math

import pytest

from openmm_alphaprk.equal_cost import equal_cost_baselines, equal_cost_divisor, gain, gain_text


def test_k_is_the_force_evaluations_per_step_rounded_up():
    assert [equal_cost_divisor(e) for e in (1.0, 1.0 + 1e-12, 1.2, 5.0, 7.78, 0.5)] == [1, 1, 2, 5, 8, 1]


def test_each_costlier_row_is_paired_with_the_baseline_of_its_k_where_that_ran():
    evaluations = {"rattle": 1.0, "alpha4=0": 5.0, "energy4": 7.78, "alpha6=0": 9.0}
    ran = {"rattle h/5", "rattle h/8"}
    pairs = equal_cost_baselines(evaluations, lambda k: f"rattle h/{k}", ran)
    assert pairs == {"alpha4=0": (5, "rattle h/5"), "energy4": (8, "rattle h/8")}


def test_the_gain_is_the_baselines_error_over_the_rows_and_says_which_side_wins():
    assert gain(3.0, 1.5) == 2.0
    assert gain(1.0, 4.0) == 0.25
    assert math.isnan(gain(1.0, 0.0)) and math.isnan(gain(float("nan"), 1.0))
    assert gain_text(gain(3.0, 1.5)) == "2x lower"
    assert gain_text(0.25) == "4x higher"
    assert gain_text(0.25, times="×", loss="**{}**") == "**4× higher**"
    assert gain_text(float("nan")) == "–"


@pytest.mark.parametrize("ratio", [0.999, 0.5, 1e-3])
def test_a_loss_is_never_said_as_a_gain_below_one(ratio):
    assert "higher" in gain_text(ratio) and "lower" not in gain_text(ratio)
