"""Every integrator the grammar names, run the same way; a splitting added from data alone.

In openmmtools' manner: each registered form (:func:`example_names`) is made by name and
run from the shipped relaxed start of the water cluster; the run must stay finite, keep
the constraints and the linear momentum, count the force evaluations its program fixes,
and, for a rescaled row, hold H at E_ref.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest

from openmm_alphaprk import RattleRescaleIntegrator, restore_integrator
from openmm_alphaprk.integrators import counted_force_evaluations
from openmm_alphaprk.integrators.splittings import SPLITTINGS, Splitting
from openmm_alphaprk.runs.integrator_names import (
    FAMILIES,
    INTEGRATOR_HELP,
    LAYERS,
    Layer,
    example_names,
    label,
    make_integrator,
    parse_integrator,
    register_layer,
)
from openmm_alphaprk.systems import prepare_system

STEPS = 12


@pytest.fixture(scope="module")
def cluster():
    return prepare_system("water-cluster")


def _constraint_error(system: mm.System, x: np.ndarray) -> float:
    worst = 0.0
    for k in range(system.getNumConstraints()):
        i, j, d = system.getConstraintParameters(k)
        d = d.value_in_unit(unit.nanometers)
        worst = max(worst, abs(np.linalg.norm(x[i] - x[j]) - d) / d)
    return worst


@pytest.mark.parametrize("name", example_names())
def test_every_registered_integrator_runs_by_name(cluster, name):
    """stable from a relaxed start, constraints and momentum kept, its force evaluations counted."""
    spec = parse_integrator(name)
    assert parse_integrator(spec.name) == spec and label(spec)
    integrator = make_integrator(spec, 0.001)
    context = mm.Context(cluster.system, integrator, mm.Platform.getPlatformByName("CPU"))
    context.setState(cluster.state)
    if hasattr(integrator, "check_context"):
        integrator.check_context(context)
    masses = np.array(
        [
            cluster.system.getParticleMass(i).value_in_unit(unit.dalton)
            for i in range(context.getSystem().getNumParticles())
        ]
    )

    def read() -> tuple[np.ndarray, np.ndarray, float]:
        state = context.getState(getPositions=True, getVelocities=True, getEnergy=True)
        x = state.getPositions(asNumpy=True).value_in_unit(unit.nanometers)
        v = state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)
        energy = (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(
            unit.kilojoules_per_mole
        )
        return x, v, energy

    _, v0, e0 = read()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the energy mode's hold warnings are not what is tested here
        integrator.step(STEPS)
    x, v, energy = read()
    assert np.isfinite(x).all() and np.isfinite(energy)
    kinetic = 0.5 * float((masses[:, None] * v0**2).sum())
    assert abs(energy - e0) < 0.05 * kinetic, (name, energy - e0)
    assert _constraint_error(cluster.system, x) < 1e-6
    momentum_change = np.abs((masses[:, None] * (v - v0)).sum(axis=0)).max()
    assert momentum_change < 1e-4 * float((masses[:, None] * np.abs(v0)).sum()), name
    evaluations = counted_force_evaluations(integrator)
    if spec.force_evaluations is not None and evaluations is not None:
        assert evaluations == spec.force_evaluations * STEPS, (name, evaluations)
    if spec.kind == "rescale" and spec.rescale_interval == 1:
        assert abs(energy - integrator.reference_energy.value_in_unit(unit.kilojoules_per_mole)) < 1e-3


def test_every_family_and_named_set_is_in_the_help_and_the_examples():
    names = example_names()
    for word in FAMILIES:
        assert any(name.startswith(word) for name in names), word
        assert FAMILIES[word].form in INTEGRATOR_HELP
    for chosen in SPLITTINGS:
        assert f"split:{chosen}" in names and chosen in INTEGRATOR_HELP


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("split-me", "split:me2"),
        ("split3-bcss+rescale@10", "split:bcss3+rescale@10"),
        ("rattle4+rescale:triple-jump@10", "rattle4:triple-jump+rescale@10"),
        ("alpha4=0:triple-jump", "alpha4:triple-jump=0"),
        ("energy4:triple-jump", "energy4:triple-jump"),
    ],
)
def test_names_from_before_the_grammar_are_read_as_the_canonical_ones(old, new):
    assert parse_integrator(old) == parse_integrator(new) and parse_integrator(old).name == new


def test_a_digit_is_always_the_order():
    assert [
        parse_integrator(name).order for name in ("rattle4", "alpha6=0", "energy4", "rattle6+rescale")
    ] == [4, 6, 4, 6]
    for bad in ("split3:me3", "energy2", "rattle5"):
        with pytest.raises(ValueError, match="BASE"):
            parse_integrator(bad)


@pytest.fixture
def four_stage_splitting():
    """A four-stage splitting registered from data alone (RATTLE at h/4), removed afterwards."""
    added = SPLITTINGS.register(
        Splitting(
            "quarter",
            (0.125, 0.25, 0.25, 0.25, 0.125),
            (0.25, 0.25, 0.25, 0.25),
            2,
            "four RATTLE steps of h/4 (a test's own entry)",
            "RATTLE at h/4, four times",
        )
    )
    yield added
    del SPLITTINGS[added.name]


def test_a_splitting_added_as_data_runs_by_name_through_the_cli(four_stage_splitting, tmp_path, capsys):
    """one data entry, nothing else: the grammar, the label, the help's list and the CLI know it."""
    from openmm_alphaprk.cli import main

    assert label("split:quarter+rescale") == "RATTLE at h/4, four times + rescaling"
    assert parse_integrator("split:quarter").force_evaluations == 4
    code = main(
        [
            "run",
            "water-cluster",
            "split:quarter+rescale",
            "--steps",
            "8",
            "--timestep",
            "1fs",
            "--platform",
            "CPU",
            "-o",
            str(tmp_path / "q"),
            "--quiet",
            "--json",
        ]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["integrator"] == "split:quarter+rescale" and summary["steps"] == 8
    assert summary["force_evaluations_per_step"] == pytest.approx(4.0)


class UniformRescaleIntegrator(RattleRescaleIntegrator):
    """The base step, then every velocity scaled by one factor so that H = E_ref (no rigid motion kept)."""

    def _add_conservation_test(self) -> None:
        self.addComputeGlobal("translation", "0")
        self.addComputeGlobal("rotation", "0")

    def _check_system(self, context: mm.Context) -> None:
        super()._check_system(context)
        self.setGlobalVariableByName("translation", 0)
        self.setGlobalVariableByName("rotation", 0)


@pytest.fixture
def uniform_layer():
    """A way of holding the energy added as one class and one registration, removed afterwards."""
    layer = register_layer(
        Layer("uniform", UniformRescaleIntegrator, "uniform scaling", "every velocity scaled by one factor")
    )
    yield layer
    del LAYERS[layer.word]


def test_a_layer_added_as_one_class_runs_by_name_through_the_cli(uniform_layer, tmp_path, capsys):
    """one new layer class: the grammar, the label, every base and the CLI take it."""
    from openmm_alphaprk.cli import main

    assert (
        label("split:me2+uniform@5")
        == "splitting, minimum error (α = 0.3068) + uniform scaling every 5 steps"
    )
    made = make_integrator("rattle4+uniform", 0.001)
    assert isinstance(made, UniformRescaleIntegrator)
    xml = mm.XmlSerializer.serialize(made)  # restored by its class's own kind, no table of numbers
    assert isinstance(restore_integrator(mm.XmlSerializer.deserialize(xml)), UniformRescaleIntegrator)
    code = main(
        ["run", "water-cluster", "rattle+uniform", "--steps", "8", "--timestep", "1fs", "--platform", "CPU"]
        + ["--energy-interval", "2"]
        + ["-o", str(tmp_path / "u"), "--quiet", "--json"]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["integrator"] == "rattle+uniform" and summary["steps"] == 8
    assert summary["energy_samples"] >= 4 and summary["max_abs_residual"] < 1e-3  # H held at E_ref, kJ/mol
    assert summary["rescaling"]["rescalings"] == 8


@pytest.mark.parametrize("name", ["rattle", "alpha4=0.01", "energy", "rattle4+rescale", "split:me3"])
def test_programs_from_before_the_kinds_were_names_are_restored(name):
    """XML written when the kinds were the numbers 1-4 (the energy mode 2, told apart by E_ref)."""
    from openmm_alphaprk.integrators.variables import KIND_VARIABLE

    integrator = make_integrator(name, 0.002)
    old = {"RattleIntegrator": 1, "AlphaRattleIntegrator": 2, "AlphaRattleEnergyIntegrator": 2}
    old.update({"RattleRescaleIntegrator": 3, "SplittingRattleIntegrator": 4})
    integrator.setGlobalVariableByName(KIND_VARIABLE, old[type(integrator).__name__])
    restored = restore_integrator(mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(integrator)))
    assert type(restored) is type(integrator)
