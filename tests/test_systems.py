"""Systems: definitions, cache keyed on content, every system with every integrator."""

from __future__ import annotations

import time

import numpy as np
import openmm.unit as unit
import pytest
from quick_systems import QUICK, quick_system

from openmm_alphaprk.integrators.names import IncompatibleSystemError
from openmm_alphaprk.runs import run_nve
from openmm_alphaprk.systems import (
    DefinitionError,
    UnknownSystemError,
    list_systems,
    load_definition,
    prepare_system,
)

INTEGRATORS = ("rattle", "alpha=1/6", "energy", "verlet")
EXPECTED = {"tip3p-2nm", "tip3p-3nm", "tip3p-4nm", "spce-3nm", "tip4pew-3nm", "water-cluster", "villin"}


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


def test_shipped_definitions_parse():
    assert EXPECTED <= set(list_systems())
    for name in list_systems():
        definition = load_definition(name)
        assert definition.description
        assert definition.equilibration["seed"] == 2024


def test_unknown_system_names_the_known_ones():
    with pytest.raises(UnknownSystemError, match="tip3p-3nm"):
        load_definition("tip5p-9nm")


def test_invalid_definition_is_explained():
    definition = load_definition("tip3p-2nm")
    with pytest.raises(DefinitionError, match="half the box"):
        definition.with_overrides({"build.cutoff_nm": 1.2})
    with pytest.raises(DefinitionError, match="must be 'build.<key>'"):
        definition.with_overrides({"seed": 1})


def test_cache_is_keyed_on_content(tmp_path):
    first = prepare_system("tip3p-2nm", cache_dir=tmp_path, overrides=QUICK)
    assert not first.from_cache and first.path.is_dir()
    start = time.perf_counter()
    again = prepare_system("tip3p-2nm", cache_dir=tmp_path, overrides=QUICK)
    assert again.from_cache and time.perf_counter() - start < 5
    np.testing.assert_array_equal(again.positions, first.positions)
    np.testing.assert_array_equal(again.velocities, first.velocities)
    # another protocol is another entry, never the stale one
    other = prepare_system("tip3p-2nm", cache_dir=tmp_path, overrides={**QUICK, "equilibration.seed": 7})
    assert not other.from_cache and other.key != first.key and other.path != first.path
    assert not np.array_equal(other.velocities, first.velocities)


def test_equilibrated_state_is_consistent(cache):
    prepared = quick_system("tip3p-2nm", cache)
    x, v = prepared.positions, prepared.velocities
    for k in range(prepared.system.getNumConstraints()):
        i, j, d = prepared.system.getConstraintParameters(k)
        r = x[j] - x[i]
        d = d.value_in_unit(unit.nanometers)
        assert abs(np.linalg.norm(r) - d) / d < 1e-7  # SETTLE's own geometry is ~3e-8 off nominal
        assert abs(np.dot(v[j] - v[i], r)) < 1e-8
    assert not any(type(f).__name__ == "CMMotionRemover" for f in prepared.system.getForces())


def test_cluster_is_isolated_and_at_rest(cache):
    prepared = quick_system("water-cluster", cache)
    assert not prepared.system.usesPeriodicBoundaryConditions()
    system = prepared.system
    m = np.array([system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(prepared.n_atoms)])
    x, v = prepared.positions, prepared.velocities
    centre = (m[:, None] * x).sum(0) / m.sum()
    momentum = (m[:, None] * v).sum(0)
    angular = (m[:, None] * np.cross(x - centre, v)).sum(0)
    assert np.abs(momentum).max() < 1e-6 and np.abs(angular).max() < 1e-6
    assert prepared.n_atoms > 150


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_system_runs_every_integrator(name, cache, tmp_path):
    prepared = quick_system(name, cache)
    for integrator in INTEGRATORS:
        output = tmp_path / integrator.replace("/", "_")
        if name.startswith("tip4pew") and integrator != "verlet":
            with pytest.raises(IncompatibleSystemError, match="virtual sites"):
                run_nve(prepared, integrator, output, steps=3, progress=False)
            assert not output.exists()  # refused before anything was written
            continue
        summary = run_nve(
            prepared,
            integrator,
            output,
            steps=3,
            energy_interval=1,
            trajectory_interval=1,
            checkpoint_interval=3,
            progress=False,
        )
        assert summary.steps == 3 and summary.n_atoms == prepared.n_atoms
        assert np.isfinite(summary.rms_residual) and summary.max_abs_residual < 50.0
        assert summary.max_relative_constraint_error < 1e-6
        if integrator in ("rattle", "verlet"):
            assert summary.force_evaluations_per_step == 1.0
        else:
            assert summary.force_evaluations_per_step > 1.0


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_full_protocol_builds(name, tmp_path):
    """The shipped protocols as they are (villin: about a minute on 2 cores)."""
    prepared = prepare_system(name, cache_dir=tmp_path)
    kinetic = prepared.state.getKineticEnergy().value_in_unit(unit.kilojoules_per_mole)
    potential = prepared.state.getPotentialEnergy().value_in_unit(unit.kilojoules_per_mole)
    assert kinetic > 0 and np.isfinite(potential) and potential < 0
