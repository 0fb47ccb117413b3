"""The energy mode on the explicit α-family (tools/scripts/splitting_energy_mode.py), a measurement prototype.

Its step program is ``SplittingRattleIntegrator``'s with the kicks read from a global
``alpha``: at the minimum-error α it is that integrator step for step, at α = ¼ RATTLE at
h/2; a retry from the saved start is the same trial again; a trial costs two force
evaluations and a return to the best trial none; the controller holds H at E_ref.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import openmm as mm
import pytest
from conftest import counting, make_context, positions_of, velocities_of

from openmm_alphaprk import RattleIntegrator, SplittingRattleIntegrator
from openmm_alphaprk.observables import total_energy
from openmm_alphaprk.reference import to_openmm_system, water_cluster

SCRIPT = Path(__file__).resolve().parent.parent / "tools" / "scripts" / "splitting_energy_mode.py"


@pytest.fixture(scope="module")
def prototype():
    spec = importlib.util.spec_from_file_location("splitting_energy_mode", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    return module


def _pair(water_box, first, second):
    return [
        make_context(water_box.system, i, water_box.positions, water_box.velocities) for i in (first, second)
    ]


def test_the_minimum_error_alpha_is_split_me_step_for_step(prototype, water_box):
    assert prototype.ALPHA_ME == 0.3068166724962164
    trial = prototype.AlphaGlobalSplitting(0.002)
    split = SplittingRattleIntegrator(0.002)
    contexts = _pair(water_box, trial, split)
    for _ in range(5):
        trial.trial(prototype.ALPHA_ME, prototype.NEW_STEP)
        split.step(1)
        assert np.max(np.abs(positions_of(contexts[0]) - positions_of(contexts[1]))) < 1e-12
        assert np.max(np.abs(velocities_of(contexts[0]) - velocities_of(contexts[1]))) < 1e-9
    assert trial.force_evaluations == split.force_evaluations == 10


def test_alpha_a_quarter_is_rattle_at_half_the_step(prototype, water_box):
    trial = prototype.AlphaGlobalSplitting(0.002)
    rattle = RattleIntegrator(0.001)
    contexts = _pair(water_box, trial, rattle)
    for _ in range(5):
        trial.trial(0.25, prototype.NEW_STEP)
        rattle.step(2)
        assert np.max(np.abs(positions_of(contexts[0]) - positions_of(contexts[1]))) < 1e-12
        assert np.max(np.abs(velocities_of(contexts[0]) - velocities_of(contexts[1]))) < 1e-9


def test_a_retry_is_the_trial_from_the_step_start_and_the_best_trial_is_kept(prototype, water_box):
    """A retry at α is the step at α from the saved start; a return to the best trial ends where it ended."""
    trial = prototype.AlphaGlobalSplitting(0.002)
    fresh = SplittingRattleIntegrator(0.002, alpha=0.4)
    contexts = _pair(water_box, trial, fresh)
    h_me = trial.trial(prototype.ALPHA_ME, prototype.NEW_STEP)
    x_me, v_me = positions_of(contexts[0]), velocities_of(contexts[0])
    h_04 = trial.trial(0.4, prototype.RETRY)
    fresh.step(1)
    assert np.max(np.abs(positions_of(contexts[0]) - positions_of(contexts[1]))) < 1e-12
    assert h_04 == pytest.approx(total_energy(contexts[1]), abs=1e-7)
    assert h_04 != pytest.approx(h_me, abs=1e-6)
    assert total_energy(contexts[0]) == pytest.approx(h_04, abs=1e-7)  # H read in the program is the State's
    # aim E_ref at the first trial: the return to the best one lands on its state
    trial.setGlobalVariableByName("e_ref", h_me)
    trial.trial(prototype.ALPHA_ME, prototype.RETRY)
    trial.trial(0.4, prototype.RETRY)
    trial.restore_best()
    assert np.max(np.abs(positions_of(contexts[0]) - x_me)) < 1e-12
    assert np.max(np.abs(velocities_of(contexts[0]) - v_me)) < 1e-9
    assert trial.getGlobalVariableByName("alpha") == prototype.ALPHA_ME


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_a_trial_costs_two_force_evaluations_and_the_return_to_the_best_none(prototype, platform):
    """Counted by OpenMM (a PythonForce that counts its calls): the start's force is kept, not recomputed."""
    problem, x0, v0 = water_cluster(3)
    system, calls = counting(to_openmm_system(problem))
    trial = prototype.AlphaGlobalSplitting(0.002)
    context = make_context(
        system, trial, x0.reshape(-1, 3), v0.reshape(-1, 3), mm.Platform.getPlatformByName(platform)
    )
    trial.trial(prototype.ALPHA_ME, prototype.NEW_STEP)  # the first step also evaluates the start
    calls[0] = 0
    before = trial.force_evaluations
    trial.setGlobalVariableByName("e_ref", 1e9)  # every trial is the best so far: no return needed
    for _ in range(3):  # three steps of one trial, a fourth of two, a fifth of three ending in its first
        trial.trial(0.30, prototype.NEW_STEP)
    trial.trial(0.31, prototype.RETRY)
    trial.trial(0.20, prototype.NEW_STEP)
    trial.setGlobalVariableByName("e_ref", trial.getGlobalVariableByName("h_trial"))
    trial.trial(0.25, prototype.RETRY)
    trial.trial(0.35, prototype.RETRY)
    trial.restore_best()
    trial.trial(0.30, prototype.NEW_STEP)  # starts from the kept best trial's force
    assert calls[0] == 2 * 8  # eight trials
    assert trial.force_evaluations - before == 2 * 8
    assert context.getState(getPositions=True).getPositions() is not None


def test_the_controller_holds_the_energy_within_its_tolerance_on_the_water_box(prototype, water_box):
    trial = prototype.AlphaGlobalSplitting(0.002)
    context = make_context(water_box.system, trial, water_box.positions, water_box.velocities)
    e_ref = total_energy(context)
    controller = prototype.EnergyModeController(trial, e_ref, max_trials=6, relative_tolerance=1e-7)
    for _ in range(5):
        alpha = controller.step()
        assert 0.0 <= alpha <= 0.5
        residual = total_energy(context) - e_ref
        if controller.missed[-1]:  # no root found: the fallback is counted, and is the best trial
            assert abs(residual) > controller.tolerance
        else:
            assert abs(residual) <= controller.tolerance
    summary = controller.summary()
    assert summary["fraction_missed"] == 0.0  # on this box the root is there every step
    assert summary["steps"] == 5 and 1 <= summary["mean_trials"] <= 6
    assert trial.force_evaluations == 2 * sum(controller.trials) + 0  # 2 per trial, nothing else
    # H read in the program is the State's
    assert trial.getGlobalVariableByName("h_trial") == pytest.approx(total_energy(context), abs=1e-7)


def test_the_controller_counts_a_step_whose_root_is_out_of_reach(prototype, water_box):
    """E_ref far off: every trial misses; the step ends in the closest trial, at a bound, counted."""
    trial = prototype.AlphaGlobalSplitting(0.002)
    context = make_context(water_box.system, trial, water_box.positions, water_box.velocities)
    e_ref = total_energy(context) + 100.0
    controller = prototype.EnergyModeController(trial, e_ref, max_trials=4)
    controller.step()
    assert controller.missed == [True]
    best = min(abs(controller.alphas[0] - bound) for bound in (0.0, 0.5))
    assert best == 0.0
    assert abs(total_energy(context) - e_ref) == pytest.approx(
        trial.getGlobalVariableByName("best_deviation")
    )
