"""The energy mode's controller over the explicit family: ``AlphaRattleEnergyIntegrator(splitting=...)``.

The controller is the layer α-RATTLE's energy mode runs (:mod:`~.energy_controller`); the
base's trial is the two-stage splitting's step of the member α₀ + α from the step's start. With α
pinned it is that member's step for step (at 0 the splitting, at ¼ − α₀ RATTLE at h/2); a trial
costs two force evaluations, counted by OpenMM; the controller holds H at E_ref; and it is no name
of the grammar because it loses at equal force evaluations.
"""

from __future__ import annotations

import numpy as np
import openmm as mm
import pytest
from conftest import counting, make_context, path_on_the_water_cluster, positions_of, velocities_of

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    ControllerSettings,
    RattleIntegrator,
    RattleRescaleIntegrator,
    SplittingRattleIntegrator,
    restore_integrator,
)
from openmm_alphaprk.errors import InputError
from openmm_alphaprk.integrators.splittings import MINIMUM_ERROR2
from openmm_alphaprk.observables import total_energy
from openmm_alphaprk.reference import to_openmm_system, water_cluster

H = 0.002
ALPHA_ME = MINIMUM_ERROR2.alpha


def pinned(offset: float) -> AlphaRattleEnergyIntegrator:
    """The energy mode over ``me2`` with α held at ``offset`` and a tolerance every trial meets."""
    return AlphaRattleEnergyIntegrator(
        H,
        splitting="me2",
        controller=ControllerSettings(alpha_bounds=(offset, offset + 1e-12), energy_tolerance=1e9),
    )


def _pair(water_box, first, second):
    return [
        make_context(water_box.system, i, water_box.positions, water_box.velocities) for i in (first, second)
    ]


@pytest.mark.parametrize(
    ("offset", "same", "steps_each"),
    [
        (0.0, lambda: SplittingRattleIntegrator(H), 1),
        (0.25 - ALPHA_ME, lambda: RattleIntegrator(H / 2), 2),  # α = ¼: two RATTLE steps of h/2
        (0.4 - ALPHA_ME, lambda: SplittingRattleIntegrator(H, alpha=0.4), 1),
    ],
)
def test_a_pinned_alpha_is_the_members_step(water_box, offset, same, steps_each):
    energy, member = pinned(offset), same()
    contexts = _pair(water_box, energy, member)
    for _ in range(5):
        energy.step(1)
        member.step(steps_each)
        assert np.max(np.abs(positions_of(contexts[0]) - positions_of(contexts[1]))) < 1e-12
        assert np.max(np.abs(velocities_of(contexts[0]) - velocities_of(contexts[1]))) < 1e-9
    assert energy.trials == 1 and energy.force_evaluations == 10
    assert energy.alpha == pytest.approx(offset, abs=1e-11)


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_a_trial_costs_two_force_evaluations_counted_by_openmm(platform):
    """A PythonForce counts its calls: two per trial, the start's force kept, as the program counts."""
    problem, x0, v0 = water_cluster(3)
    system, calls = counting(to_openmm_system(problem))
    integrator = AlphaRattleEnergyIntegrator(
        H, splitting="me2", controller=ControllerSettings(energy_tolerance=1e-6, max_trials=4)
    )
    context = make_context(
        system, integrator, x0.reshape(-1, 3), v0.reshape(-1, 3), mm.Platform.getPlatformByName(platform)
    )
    integrator.step(1)  # the first step also evaluates the start (and E_ref)
    calls[0] = 0
    before = integrator.force_evaluations
    trials = 0
    for _ in range(6):
        integrator.step(1)
        trials += integrator.trials + integrator.getGlobalVariableByName("zero_trial")
    assert trials > 6  # the tolerance makes steps take more than one trial
    assert calls[0] == integrator.force_evaluations - before
    assert calls[0] >= 2 * trials
    assert context.getState(getEnergy=True).getPotentialEnergy() is not None


def test_the_controller_holds_the_energy_on_the_water_box(water_box):
    """Within the tolerance of the CPU platform's single-precision energy (0.005 kJ/mol on 774 atoms)."""
    integrator = AlphaRattleEnergyIntegrator(
        H, splitting="me2", controller=ControllerSettings(energy_tolerance=0.005)
    )
    context = make_context(water_box.system, integrator, water_box.positions, water_box.velocities)
    e_ref = total_energy(context)
    member = SplittingRattleIntegrator(H)
    plain = make_context(water_box.system, member, water_box.positions, water_box.velocities)
    held, free = [], []
    for _ in range(40):
        integrator.step(1)
        member.step(1)
        held.append(total_energy(context) - e_ref)
        free.append(total_energy(plain) - e_ref)
        low, high = integrator.alpha_bounds
        assert low <= integrator.alpha <= high
    totals = integrator.controller_totals()
    tolerance = integrator.energy_tolerance._value
    assert totals["fraction_within_tolerance"] >= 0.7, totals
    assert np.sqrt(np.mean(np.square(held))) < 2 * tolerance
    assert np.sqrt(np.mean(np.square(held))) < np.sqrt(np.mean(np.square(free))) / 3
    # H read in the program is the State's
    assert integrator.energy_residual._value == pytest.approx(held[-1], abs=1e-6)
    assert integrator.alpha_bounds == pytest.approx((-ALPHA_ME, 0.5 - ALPHA_ME))  # no negative kick


def test_it_loses_to_rescaled_rattle_and_the_rescaled_splitting_at_equal_evaluations():
    """Why the energy mode over a splitting is no name of the grammar (docs/energy_mode.md)."""
    error = path_on_the_water_cluster()
    energy_error, energy_cost = error(AlphaRattleEnergyIntegrator(H, splitting="me2"), 1)
    k = int(energy_cost)  # RATTLE at h/k costs no more than the energy mode (measured 3.6 per step)
    rattle_error, rattle_cost = error(RattleRescaleIntegrator(H / k), k)
    split_error, split_cost = error(RattleRescaleIntegrator(H, splitting="me2"), 1)
    assert rattle_cost <= energy_cost and split_cost < energy_cost
    assert rattle_error < energy_error / 2  # measured 2.7x closer
    assert split_error < energy_error  # the splitting it moves away from, rescaled: as close, cheaper


def test_it_is_restored_from_xml_with_its_splitting():
    integrator = AlphaRattleEnergyIntegrator(H, splitting="bcss2")
    plain = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(integrator))
    restored = restore_integrator(plain)
    assert isinstance(restored, AlphaRattleEnergyIntegrator)
    assert restored.splitting.name == "bcss2" and restored.composition is None
    assert (
        repr(restored)
        == repr(integrator)
        == "AlphaRattleEnergyIntegrator(timestep=0.002 ps, splitting='bcss2')"
    )


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"splitting": "me2", "order": 4}, "not both"),
        ({"splitting": "me3"}, "has 3 stages"),
        ({"splitting": "nonsense"}, "nonsense"),
    ],
)
def test_a_base_it_cannot_take_is_refused(options, message):
    with pytest.raises(InputError, match=message):
        AlphaRattleEnergyIntegrator(H, **options)


def test_the_measurement_script_runs_the_packages_energy_mode(tmp_path):
    """tools/scripts/splitting_energy_mode.py (docs/splitting.md's numbers) on the water cluster, 3 steps."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parent.parent / "tools" / "scripts" / "splitting_energy_mode.py"
    out = tmp_path / "out.json"
    arguments = [
        "--system",
        "water-cluster",
        "--steps",
        "3",
        "--horizons",
        "2",
        "--rows",
        "split-me",
        "rattle@2",
    ]
    subprocess.run(
        [sys.executable, str(script), *arguments, "--energy-modes", "1e-6:4", "--json", str(out)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    document = json.loads(out.read_text(encoding="utf-8"))
    rows = {row["row"]: row for row in document["rows"]}
    assert set(rows) == {"split-energy tol 1e-06, <= 4 trials", "split-me", "rattle at h/2"}
    energy = rows["split-energy tol 1e-06, <= 4 trials"]
    assert energy["evaluations"] >= 2 and energy["max_trials"] == 4 and len(energy["position_rms"]) == 1
    assert document["energy_mode"]["rows"]["split-energy tol 1e-06, <= 4 trials"]["steps"] == 3
    assert rows["rattle at h/2"]["evaluations"] == 2


def test_it_keeps_both_momenta_of_an_isolated_cluster():
    """Every step is a member's splitting step (or the splitting's own): P and L kept to round-off."""
    from openmm_alphaprk.observables import masses, momenta
    from openmm_alphaprk.systems import prepare_system

    water = prepare_system("water-cluster")
    integrator = AlphaRattleEnergyIntegrator(H, splitting="me2")
    context = mm.Context(water.system, integrator, mm.Platform.getPlatformByName("Reference"))
    context.setState(water.state)
    weights = masses(water.system)
    p0, l0 = momenta(weights, positions_of(context), velocities_of(context))
    alphas = set()
    for _ in range(20):
        integrator.step(1)
        alphas.add(integrator.alpha)
    p1, l1 = momenta(weights, positions_of(context), velocities_of(context))
    assert len(alphas) > 3  # the controller moved alpha (measured: seven members in 20 steps)
    assert np.abs(p1 - p0).max() < 1e-10
    assert np.abs(l1 - l0).max() < 1e-9 * max(1.0, float(np.abs(l0).max()))
