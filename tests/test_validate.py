"""``alphaprk validate``: equipartition, order, rescaling and T/V against h with physical_validation.

The equipartition check must be able to fail: a dynamics that heats one group of
molecules (a Berendsen-like scaling of their velocities only) is flagged, RATTLE of the
same length is not.
"""

from __future__ import annotations

import json
import shutil
import sys

import MDAnalysis as mda
import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest

try:
    from openmm_alphaprk.analysis.equipartition import import_physical_validation

    import_physical_validation()
except ImportError:
    pytest.skip("physical_validation is not installed", allow_module_level=True)

from openmm_alphaprk import RattleIntegrator  # noqa: E402
from openmm_alphaprk._units import InputError  # noqa: E402
from openmm_alphaprk.analysis import (  # noqa: E402
    Equipartition,
    combine_segments,
    compare_settings,
    molecules_of,
)
from openmm_alphaprk.analysis.equipartition import MIN_FRAMES, flag_threshold  # noqa: E402
from openmm_alphaprk.runs import run_nve  # noqa: E402
from openmm_alphaprk.systems import prepare_system  # noqa: E402
from openmm_alphaprk.workflows.validate import validate  # noqa: E402

REFERENCE = mm.Platform.getPlatformByName("Reference")
KB = unit.MOLAR_GAS_CONSTANT_R.value_in_unit(unit.kilojoule_per_mole / unit.kelvin)


def biased_integrator(dt: float, mask: list[bool], dof: float, target_k: float, tau_ps: float):
    """Velocity Verlet with constraints, then a Berendsen-like scaling of the masked atoms' velocities only.

    The masked group's kinetic temperature is pulled towards ``target_k`` with time
    constant ``tau_ps``; the other atoms are left as velocity Verlet moves them.
    """
    integrator = mm.CustomIntegrator(dt)
    integrator.addPerDofVariable("mask", 0)
    integrator.addPerDofVariable("x1", 0)
    integrator.addGlobalVariable("kinetic", 0)
    integrator.addGlobalVariable("scale", 1)
    integrator.addUpdateContextState()
    integrator.addComputePerDof("v", "v + 0.5*dt*f/m")
    integrator.addComputePerDof("x", "x + dt*v")
    integrator.addComputePerDof("x1", "x")
    integrator.addConstrainPositions()
    integrator.addComputePerDof("v", "v + (x - x1)/dt")
    integrator.addComputePerDof("v", "v + 0.5*dt*f/m")
    integrator.addConstrainVelocities()
    integrator.addComputeSum("kinetic", "0.5*m*v*v*mask")
    integrator.addComputeGlobal("scale", f"sqrt(1 + {dt / tau_ps}*({target_k}/(2*kinetic/({dof}*{KB})) - 1))")
    integrator.addComputePerDof("v", "v*(1 + mask*(scale - 1))")  # whole rigid molecules: constraints kept
    integrator.setPerDofVariableByName("mask", [mm.Vec3(1, 1, 1) if m else mm.Vec3(0, 0, 0) for m in mask])
    return integrator


def write_segments(folder, prepared, integrator, segments: int, frames: int, every: int) -> list[str]:
    """Step ``integrator`` from the prepared state; write ``segments`` TRR files of ``frames`` frames each."""
    context = mm.Context(prepared.system, integrator, REFERENCE)
    context.setState(prepared.state)
    paths = []
    for k in range(segments):
        path = str(folder / f"segment{k}.trr")
        with mda.Writer(path, n_atoms=prepared.n_atoms) as writer:
            universe = mda.Universe.empty(prepared.n_atoms, trajectory=True, velocities=True)
            for _ in range(frames):
                integrator.step(every)
                state = context.getState(getPositions=True, getVelocities=True)
                universe.atoms.positions = state.getPositions(asNumpy=True).value_in_unit(unit.angstrom)
                universe.atoms.velocities = state.getVelocities(asNumpy=True).value_in_unit(
                    unit.angstrom / unit.picosecond
                )
                writer.write(universe.atoms)
        paths.append(path)
    return paths


def equipartition_of(paths, system, resnames) -> dict:
    """Combined partition temperatures of TRR segments (read back with MDAnalysis)."""
    temperatures = []
    for path in paths:
        universe = mda.Universe(path)
        check = Equipartition.from_system(universe, system, resnames=resnames).run()
        temperatures.append(check.results.temperatures)
    return combine_segments(temperatures)


@pytest.fixture(scope="module")
def heated_and_plain(tmp_path_factory):
    """Six segments (20 frames every 20 steps of 2 fs) of the biased dynamics and of RATTLE."""
    prepared = prepare_system("water-cluster", progress=False)
    molecules = molecules_of(prepared.system)
    heated = [k for k in range(len(molecules)) if k % 2 == 0]
    mask = np.zeros(prepared.n_atoms, dtype=bool)
    for k in heated:
        mask[molecules[k]] = True
    resnames = np.where(mask, "LIG", "HOH").tolist()  # the heated molecules are the "solute"
    folder = tmp_path_factory.mktemp("biased")
    biased = biased_integrator(0.002, mask.tolist(), 6.0 * len(heated), target_k=1000.0, tau_ps=0.02)
    biased_paths = write_segments(folder, prepared, biased, segments=6, frames=20, every=20)
    plain_folder = tmp_path_factory.mktemp("rattle")
    plain_paths = write_segments(
        plain_folder, prepared, RattleIntegrator(0.002), segments=6, frames=20, every=20
    )
    return (
        equipartition_of(biased_paths, prepared.system, resnames),
        equipartition_of(plain_paths, prepared.system, resnames),
    )


def test_equipartition_flags_a_heated_group_and_passes_rattle(heated_and_plain):
    biased, plain = heated_and_plain
    assert biased["segments"] == plain["segments"] == 6
    assert biased["error_source"] == "segments"
    threshold = flag_threshold(6)
    assert (
        biased["flag_threshold"]
        == plain["flag_threshold"]
        == pytest.approx(threshold)
        == pytest.approx(5.51, abs=0.01)
    )
    hot = biased["groups"]["solute"]["total"]
    cold = biased["groups"]["solvent"]["total"]
    # the heated molecules are far hotter than the system, by many standard errors; the rest colder
    assert hot["deviation_K"] > 100.0
    assert hot["deviation_in_errors"] > 3 * threshold
    assert cold["deviation_K"] < -100.0
    assert cold["deviation_in_errors"] < -3 * threshold
    assert hot["temperature_K"] - cold["temperature_K"] > 300.0
    # RATTLE of the same length: no partition of any group off by more than the threshold
    z = {
        (group, partition): values["deviation_in_errors"]
        for group, partitions in plain["groups"].items()
        for partition, values in partitions.items()
    }
    assert set(plain["groups"]) == {"system", "solute", "solvent", "half 1", "half 2"}
    assert max(abs(value) for value in z.values()) < threshold, z
    assert 200.0 < plain["groups"]["solute"]["total"]["temperature_K"] < 300.0
    # the heated group against RATTLE as the reference: off by many combined errors
    against = compare_settings(biased, plain)
    assert against["solute"]["total"]["in_errors"] > 3 * threshold
    assert abs(compare_settings(plain, plain)["system"]["total"]["difference_K"]) == 0.0


def test_partition_dofs_and_temperatures_add_up(heated_and_plain):
    _, plain = heated_and_plain
    system = plain["groups"]["system"]
    # 74 rigid waters, cluster in vacuum: 6 per molecule, 3 translations and 3 rotations not thermal
    assert system["total"]["dof"] == pytest.approx(438.0)
    assert system["translational"]["dof"] + system["rotational"]["dof"] == pytest.approx(438.0)
    assert "internal" not in system  # rigid water has none
    # the DOF-weighted partition temperatures make up the total's
    weighted = sum(system[k]["temperature_K"] * system[k]["dof"] for k in ("translational", "rotational"))
    assert weighted / 438.0 == pytest.approx(system["total"]["temperature_K"], rel=1e-12)
    # segment by segment: every partition from the same frames (2<K>/(N k_B)), so they add up exactly
    for i, total in enumerate(system["total"]["segment_temperatures_K"]):
        parts = sum(
            system[k]["segment_temperatures_K"][i] * system[k]["dof"] for k in ("translational", "rotational")
        )
        assert parts / 438.0 == pytest.approx(total, rel=1e-12)
    halves = plain["groups"]["half 1"]["total"]["dof"] + plain["groups"]["half 2"]["total"]["dof"]
    assert halves == pytest.approx(438.0)


# ----------------------------------------------------------------------------- run directories


def _run(folder, name, integrator, timestep, steps, seed, interval):
    path = folder / name
    run_nve(
        "water-cluster",
        integrator,
        path,
        steps=steps,
        timestep=timestep,
        energy_interval=10,
        velocity_interval=interval,
        velocity_seed=seed,
        platform="Reference",
        progress=False,
    )
    return path


@pytest.fixture(scope="module")
def run_dirs(tmp_path_factory):
    """0.6 ps runs of the water cluster: RATTLE at 2 fs (two segments) and 1 fs, + rescaling at both."""
    folder = tmp_path_factory.mktemp("runs")
    return {
        "rattle2a": _run(folder, "rattle2a", "rattle", 0.002, 300, 1, 10),
        "rattle2b": _run(folder, "rattle2b", "rattle", 0.002, 300, 2, 10),
        "rattle1": _run(folder, "rattle1", "rattle", 0.001, 600, 1, 20),
        "rescale2": _run(folder, "rescale2", "rattle+rescale", 0.002, 300, 1, 10),
        "rescale1": _run(folder, "rescale1", "rattle+rescale", 0.001, 600, 1, 20),
    }


@pytest.fixture(scope="module")
def validation(run_dirs):
    runs = [run_dirs[k] for k in ("rattle2a", "rattle2b", "rattle1", "rescale2", "rescale1")]
    return validate(runs, reference=[run_dirs["rattle1"]])


def test_validate_groups_settings_and_compares_with_the_reference(validation):
    labels = [s["label"] for s in validation.settings]
    assert labels == ["rattle h=2 fs", "rattle h=1 fs", "rattle+rescale h=2 fs", "rattle+rescale h=1 fs"]
    assert validation.system == "water-cluster"
    eq = validation.equipartition["settings"]
    assert eq["rattle h=2 fs"]["segments"] == 2 and eq["rattle h=2 fs"]["error_source"] == "segments"
    assert eq["rattle h=1 fs"]["error_source"] == "physical_validation"
    total = eq["rattle h=2 fs"]["groups"]["system"]["total"]
    assert 200.0 < total["temperature_K"] < 300.0 and total["standard_error_K"] > 0
    # the reference is rattle h=1 fs itself: its own difference is exactly zero
    assert eq["rattle h=1 fs"]["against_reference"]["system"]["total"]["difference_K"] == 0.0
    ref = eq["rattle+rescale h=2 fs"]["against_reference"]["system"]["rotational"]
    assert ref["error_K"] > 0 and np.isfinite(ref["in_errors"])
    assert any("one segment" in note for note in validation.notes)


def test_validate_order_rescaling_and_temperature_against_h(validation, run_dirs):
    order = validation.order["rattle"]
    assert order["timestep_fs"] == [2.0, 1.0]
    assert 1.5 < order["fitted_order"] < 2.8  # RATTLE: second order
    assert 0.0 <= order["physical_validation_max_deviation"] < 0.6
    rescaled = validation.order["rattle+rescale"]
    assert rescaled["kind"] == "rescaled"
    assert all(row["at_round_off"] and row["relative"] < 1e-12 for row in rescaled["rows"])
    runs = validation.rescaling["runs"]
    assert set(runs) == {str(run_dirs["rescale2"]), str(run_dirs["rescale1"])}
    assert runs[str(run_dirs["rescale2"])]["rescalings"] == 300
    fit = validation.rescaling["fits"]["rattle+rescale"]
    assert 2.0 < fit["power_of_h"]["rms_scale_change"] < 4.0  # s - 1 per step: h^3 after RATTLE
    assert fit["expected_power"] == {"mean_scale_change": 3, "rms_scale_change": 3, "added_energy_per_ns": 2}
    limit = validation.temperature_vs_h["limit"]
    assert limit["from"] == ["rattle h=1 fs", "rattle h=2 fs"]
    assert 200.0 < limit["temperature_K"][0] < 300.0 and limit["temperature_K"][1] > 0
    for row in validation.temperature_vs_h["rows"]:
        assert np.isfinite(row["temperature_K_from_limit_in_errors"])
    text = validation.text()
    assert "(a) equipartition" in text and "(d) mean kinetic temperature (K)" in text


def test_validate_command_writes_validation_json(run_dirs, tmp_path, capsys):
    from openmm_alphaprk.cli import main

    output = tmp_path / "validation.json"
    status = main(["validate", str(run_dirs["rattle1"]), "-o", str(output), "--quiet"])
    printed = capsys.readouterr().out
    assert status == 0
    stored = json.loads(output.read_text())
    assert stored["settings"][0]["label"] == "rattle h=1 fs"
    assert "one step size only" in printed and "no h -> 0 limit" in printed  # what it cannot compute
    assert "no --reference given" in printed


# ----------------------------------------------------------------------------- bad input


def test_refuses_a_run_without_trr(tmp_path, run_dirs, capsys):
    from openmm_alphaprk.cli import main

    copy = tmp_path / "no_trr"
    shutil.copytree(run_dirs["rattle1"], copy)
    (copy / "trajectory.trr").unlink()
    with pytest.raises(InputError, match=r"--velocity-interval N"):
        validate([copy])
    assert main(["validate", str(copy), "-o", str(tmp_path / "v.json")]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "no trajectory.trr" in error


def test_refuses_too_few_frames_naming_the_length_needed(tmp_path):
    path = _run(tmp_path, "short", "rattle", 0.002, 50, 1, 10)  # 5 or 6 frames
    with pytest.raises(
        InputError, match=rf"at least {MIN_FRAMES}: a run of at least {MIN_FRAMES * 10} steps"
    ):
        validate([path])


def test_refuses_runs_of_different_systems_naming_them(tmp_path, run_dirs):
    other = tmp_path / "box"
    run_nve(
        "tip3p-2nm",
        "rattle",
        other,
        steps=10,
        velocity_interval=5,
        platform="CPU",
        cpu_threads=1,
        progress=False,
    )
    with pytest.raises(InputError, match=r"different systems.*water-cluster.*tip3p-2nm"):
        validate([run_dirs["rattle1"]], reference=[other])


def test_missing_physical_validation_is_one_line_naming_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "physical_validation", None)
    from openmm_alphaprk.analysis.equipartition import import_physical_validation

    with pytest.raises(ImportError, match=r'pip install "openmm-alphaprk\[validate\]"'):
        import_physical_validation()


def test_equipartition_refuses_too_few_frames_and_no_velocities():
    prepared = prepare_system("water-cluster", progress=False)
    positions = prepared.state.getPositions(asNumpy=True).value_in_unit(unit.angstrom)
    universe = mda.Universe.empty(prepared.n_atoms, trajectory=True)
    from MDAnalysis.coordinates.memory import MemoryReader

    velocities = np.ones_like(positions)
    universe.load_new(np.array([positions] * 5), velocities=np.array([velocities] * 5), format=MemoryReader)
    with pytest.raises(InputError, match=rf"5 frames .* at least {MIN_FRAMES}"):
        Equipartition.from_system(universe, prepared.system, resnames=["HOH"] * prepared.n_atoms).run()
    universe.load_new(np.array([positions] * MIN_FRAMES), format=MemoryReader)
    with pytest.raises(InputError, match="no velocities"):
        Equipartition.from_system(universe, prepared.system, resnames=["HOH"] * prepared.n_atoms).run()


def test_two_workers_give_the_same_temperatures(run_dirs):
    serial = validate([run_dirs["rattle1"]]).equipartition["settings"]["rattle h=1 fs"]["groups"]
    parallel = validate([run_dirs["rattle1"]], workers=2).equipartition["settings"]["rattle h=1 fs"]["groups"]
    assert parallel == serial
    assert parallel["system"]["total"]["temperature_K"] > 100.0
