"""The stability scan of the explicit α-family: its rule, its bisection, the linear limits, the script.

``python -m openmm_alphaprk.benchmarks.splitting_stability`` finds the largest stable step of RATTLE and the
splittings on a system; :meth:`Splitting.stability_limit` is the harmonic oscillator's
linear stability limit ωh_max that predicts the ratio of those steps.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from openmm_alphaprk.integrators.splittings import SPLITTINGS, Splitting, splitting, two_stage

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script():
    """The stability scan (``python -m openmm_alphaprk.benchmarks.splitting_stability``)."""
    from openmm_alphaprk.benchmarks import splitting_stability

    return splitting_stability


# --- the classification rule -------------------------------------------------------------


def test_small_finite_residuals_are_stable(script):
    verdict = script.classify([0.0, 1.0, -2.0, 0.5], dof=100, threshold_per_dof=0.25)
    assert verdict.stable and verdict.reason == "stable"
    assert verdict.max_per_dof == pytest.approx(0.02)
    assert verdict.rms_residual == pytest.approx(math.sqrt((0 + 1 + 4 + 0.25) / 4))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_energy_is_unstable(script, bad):
    verdict = script.classify([0.1, 0.2, bad], dof=100, threshold_per_dof=0.25)
    assert not verdict.stable and "non-finite" in verdict.reason
    assert verdict.max_per_dof == pytest.approx(0.002)  # from the finite samples


def test_over_the_threshold_is_unstable(script):
    # 26 kJ/mol over 100 DOF is 0.26 > 0.25; 25 is at the threshold, still stable
    assert not script.classify([1.0, -26.0], dof=100, threshold_per_dof=0.25).stable
    assert script.classify([1.0, -25.0], dof=100, threshold_per_dof=0.25).stable


def test_an_exception_or_a_short_run_is_unstable(script):
    failed = script.classify([0.1], dof=100, threshold_per_dof=0.25, failure="blew up at step 7: Constraint")
    assert not failed.stable and failed.reason.startswith("blew up at step 7")
    short = script.classify([0.1], dof=100, threshold_per_dof=0.25, steps_done=5, steps_wanted=10)
    assert not short.stable
    assert not script.classify([], dof=100, threshold_per_dof=0.25).stable
    assert script.classify([0.1], dof=100, threshold_per_dof=0.25, steps_done=10, steps_wanted=10).stable


def test_scan_brackets_the_edge_to_the_resolution(script):
    asked = []

    def run(h):
        asked.append(h)
        return {"h_fs": h, "stable": h <= 5.3}

    rows, good, bad = script.scan(run, [2.0, 4.0, 6.0, 8.0], 0.25)
    assert (good, bad) == (5.25, 5.5)
    assert asked[:3] == [2.0, 4.0, 6.0] and 8.0 not in asked  # stops at the first unstable step
    assert len(rows) == len(asked)
    assert script.scan(run, [6.0, 8.0], 0.25)[1:] == (None, 6.0)
    assert script.scan(run, [1.0, 2.0], 0.25)[1:] == (2.0, None)


# --- the linear stability limit ----------------------------------------------------------


def _brute_force_limit(chosen: Splitting, step: float = 1e-4) -> float:
    """The first ωh on a grid where an eigenvalue of the step's matrix leaves the unit circle."""
    z = np.arange(step, 2.0 * chosen.stages + 1.0, step)
    m = np.broadcast_to(np.eye(2), (z.size, 2, 2)).copy()
    for j, b in enumerate(chosen.kicks):
        kick = np.broadcast_to(np.eye(2), (z.size, 2, 2)).copy()
        kick[:, 1, 0] = -b * z
        m = kick @ m
        if j < chosen.stages:
            drift = np.broadcast_to(np.eye(2), (z.size, 2, 2)).copy()
            drift[:, 0, 1] = chosen.drifts[j] * z
            m = drift @ m
    largest = np.abs(np.linalg.eigvals(m)).max(axis=1)
    return float(z[np.argmax(largest > 1.0 + 1e-6)])


def test_verlet_and_its_repetitions_have_the_exact_limits(script):
    assert script.VERLET.stability_limit() == pytest.approx(2.0, abs=1e-9)
    assert two_stage(0.0).stability_limit() == pytest.approx(2.0, abs=1e-9)  # kicks (½, 0, ½): Verlet at h
    assert splitting("rattle/2").stability_limit() == pytest.approx(4.0, abs=1e-9)
    assert splitting("rattle/3").stability_limit() == pytest.approx(6.0, abs=1e-9)


@pytest.mark.parametrize("name", sorted(SPLITTINGS))
def test_stability_limit_matches_the_eigenvalues(name):
    chosen = splitting(name)
    assert chosen.stability_limit() == pytest.approx(_brute_force_limit(chosen), abs=2e-4)


def test_the_optimized_sets_are_less_stable_than_verlet_steps():
    # per force evaluation below Verlet's 2; BCSS's sets (made for large steps) above the minimum-error ones
    me2, bcss2 = splitting("me2").stability_limit(), splitting("bcss2").stability_limit()
    me3, bcss3 = splitting("me3").stability_limit(), splitting("bcss3").stability_limit()
    assert me2 == pytest.approx(2.5531, abs=1e-4) and bcss2 == pytest.approx(2.6342, abs=1e-4)
    assert me3 == pytest.approx(4.5838, abs=1e-4) and bcss3 == pytest.approx(4.6618, abs=1e-4)
    assert me2 < bcss2 < 4.0 and me3 < bcss3 < 6.0


def test_a_touching_point_does_not_end_the_interval():
    # two Verlet steps of h/2 at ωh = 2√2: tr M = −2 with M = −I, and stable on both sides
    rattle2 = splitting("rattle/2")
    assert _brute_force_limit(rattle2) > 2.0 * math.sqrt(2.0) + 0.1
    assert rattle2.stability_limit() > 2.0 * math.sqrt(2.0) + 0.1


# --- the script, on the small water box --------------------------------------------------


def test_main_writes_the_scan(script, tmp_path):
    out = tmp_path / "stability.json"
    document = script.main(
        [
            "--system", "tip3p-2nm", "--integrators", "rattle", "split-me", "--time", "0.06",
            "--grid", "2", "60", "--every", "5", "--resolution", "100", "--json", str(out),
        ]
    )  # fmt: skip
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data == json.loads(json.dumps(document))
    assert data["system"] == "tip3p-2nm" and data["dof"] > 0
    assert data["threshold_kj_per_mol_per_dof"] == pytest.approx(0.1 * 0.0083144626 * 300.0, rel=1e-6)
    rows = {entry["integrator"]: entry for entry in data["integrators"]}
    assert set(rows) == {"rattle", "split-me"}
    assert rows["rattle"]["evaluations"] == 1 and rows["split-me"]["evaluations"] == 2
    assert rows["split-me"]["linear_limit"] == pytest.approx(2.5531, abs=1e-4)
    for entry in rows.values():
        first, second = entry["runs"]
        assert first["h_fs"] == 2 and first["stable"] and first["steps_done"] == first["steps"] == 30
        assert 0 <= first["max_per_dof"] < data["threshold_kj_per_mol_per_dof"]
        assert second["h_fs"] == 60 and not second["stable"] and second["reason"] != "stable"
        assert entry["largest_stable_fs"] == 2 and entry["smallest_unstable_fs"] == 60
    assert rows["split-me"]["predicted_fs"] == pytest.approx(2 * 2.5531 / 2, abs=1e-3)
