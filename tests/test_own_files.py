"""A user's own system files (PDB + force field, OpenMM XML; AMBER/CHARMM/GROMACS in test_own_formats).

Made here from the shipped boxes: a PDB written by OpenMM, a serialized System and State.
"""

from __future__ import annotations

import warnings

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
import pytest
from quick_systems import QUICK

from openmm_alphaprk import AlphaRattleEnergyIntegrator
from openmm_alphaprk.cli import main
from openmm_alphaprk.nve import LargeStepWarning, StateChangingForceWarning, step_size_problem
from openmm_alphaprk.runs import run_nve
from openmm_alphaprk.smooth_forces import NonSmoothForcesWarning
from openmm_alphaprk.systems import DefinitionError, load_definition, prepare_system
from openmm_alphaprk.systems.files import FileOptions, file_definition, repartition_hydrogen_mass

TIP3P = ("amber14/tip3p.xml",)
VILLIN_PDB = str(__import__("pathlib").Path(app.__file__).parent / "data" / "test.pdb")
COMPARE = [
    "--steps",
    "6",
    "--energy-interval",
    "2",
    "--no-plot",
    "--accuracy-steps",
    "0",
    "--no-equal-cost",
    "--quiet",
]


@pytest.fixture(scope="module")
def water_files(tmp_path_factory):
    """tip3p-2nm as files: a PDB with its box, and a serialized System, State and topology."""
    folder = tmp_path_factory.mktemp("own-files")
    prepared = prepare_system("tip3p-2nm")
    with open(folder / "water.pdb", "w") as handle:
        app.PDBFile.writeFile(prepared.topology, prepared.state.getPositions(), handle)
    (folder / "water.xml").write_text(mm.XmlSerializer.serialize(prepared.system), encoding="utf-8")
    (folder / "state.xml").write_text(mm.XmlSerializer.serialize(prepared.state), encoding="utf-8")
    with open(folder / "boxless.pdb", "w") as handle:
        topology = app.Topology()
        chain = topology.addChain()
        for residue in list(prepared.topology.residues())[:3]:
            new = topology.addResidue(residue.name, chain)
            for atom in residue.atoms():
                topology.addAtom(atom.name, atom.element, new)
        app.PDBFile.writeFile(topology, prepared.state.getPositions()[:9], handle)
    return folder, prepared


def test_a_pdb_with_force_fields_is_made_ready_for_nve_and_says_what_changed(water_files, tmp_path, capsys):
    folder, prepared = water_files
    status = main(["compare", str(folder / "water.pdb"), "--forcefield", *TIP3P, "-i", "rattle",
                   "-o", str(tmp_path / "out"), *COMPARE])  # fmt: skip
    out = capsys.readouterr().out
    assert status == 0
    changes = out.split("integrator")[0]
    assert f"water: {prepared.n_atoms} atoms from {folder / 'water.pdb'}; made ready for NVE" in changes
    assert (
        "NonbondedForce (force 1): no switching function → switching from 0.8 nm (cutoff 0.9 nm)" in changes
    )
    assert "Ewald error tolerance 0.0005 → 1e-05" in changes
    assert "CMMotionRemover (force" in changes and "removed" in changes
    # the same System as the shipped box, which was built ready: forces, masses, constraints
    ours = prepare_system(file_definition(folder / "water.pdb", FileOptions(forcefield=TIP3P)))
    assert [type(f).__name__ for f in ours.system.getForces()] == [
        type(f).__name__ for f in prepared.system.getForces()
    ]
    assert ours.system.getNumConstraints() == prepared.system.getNumConstraints()
    (ours_nb,) = [f for f in ours.system.getForces() if isinstance(f, mm.NonbondedForce)]
    assert ours_nb.getUseSwitchingFunction() and ours_nb.getEwaldErrorTolerance() == 1e-5
    assert (tmp_path / "out" / "rattle" / "topology.pdb").is_file()


def test_as_is_keeps_the_system_and_the_energy_mode_warns(water_files, tmp_path):
    folder, _ = water_files
    definition = file_definition(folder / "water.pdb", FileOptions(forcefield=TIP3P, as_is=True))
    prepared = prepare_system(definition, cache_dir=tmp_path / "cache")
    assert prepared.changes == ()
    assert any(isinstance(f, mm.CMMotionRemover) for f in prepared.system.getForces())
    with (
        pytest.warns(NonSmoothForcesWarning, match="switching"),
        pytest.warns(StateChangingForceWarning, match="CMMotionRemover"),
    ):
        run_nve(prepared, "energy4", tmp_path / "run", steps=2, progress=False)


def test_files_are_cached_under_their_content_and_velocities_are_seeded(water_files, tmp_path):
    folder, _ = water_files
    pdb = tmp_path / "copy.pdb"
    pdb.write_bytes((folder / "water.pdb").read_bytes())
    options = FileOptions(forcefield=TIP3P, seed=5)
    first = prepare_system(file_definition(pdb, options), cache_dir=tmp_path / "cache")
    again = prepare_system(file_definition(pdb, options), cache_dir=tmp_path / "cache")
    assert (first.source, again.source) == ("built", "cache") and again.changes == first.changes
    assert np.array_equal(first.velocities, again.velocities)
    other_seed = prepare_system(file_definition(pdb, FileOptions(forcefield=TIP3P, seed=6)), use_cache=False)
    assert not np.allclose(other_seed.velocities, first.velocities)
    temperature = (first.velocities**2 * _masses(first.system)[:, None]).sum() / (
        first.system.getNumParticles() * 3 - first.system.getNumConstraints()
    )
    assert temperature / unit.MOLAR_GAS_CONSTANT_R.value_in_unit(unit.kilojoule_per_mole / unit.kelvin) == (
        pytest.approx(300, rel=0.15)
    )
    pdb.write_text(
        pdb.read_text().replace("HETATM    1  O", "HETATM    1  O").replace(" 1.00  0.00", " 1.00  0.01")
    )
    changed = prepare_system(file_definition(pdb, options), cache_dir=tmp_path / "cache")
    assert changed.source == "built" and changed.key != first.key  # new content, new key


def test_a_serialized_system_runs_with_its_state_and_a_made_up_topology(water_files, tmp_path):
    folder, prepared = water_files
    definition = file_definition(folder / "water.xml", FileOptions(state=str(folder / "state.xml")))
    ours = prepare_system(definition, use_cache=False)
    # the State's velocities, not drawn ones (through the CPU platform's single-precision storage)
    assert np.allclose(ours.velocities, prepared.velocities, rtol=0, atol=1e-6)
    assert ours.changes == ()  # the shipped box was built ready for NVE: nothing to change
    elements = {atom.element.symbol for atom in ours.topology.atoms()}
    assert elements == {"O", "H"}
    summary = run_nve(ours, "rattle", tmp_path / "run", steps=4, energy_interval=2, progress=False)
    assert summary.steps == 4 and (tmp_path / "run" / "topology.pdb").is_file()


def test_hydrogen_mass_repartitioning_in_place_matches_openmms_and_keeps_the_total(tmp_path):
    pdb = app.PDBFile(VILLIN_PDB)
    forcefield = app.ForceField("amber14-all.xml", "amber14/tip3p.xml")
    kwargs = {"nonbondedMethod": app.PME, "constraints": app.HBonds, "rigidWater": True}
    openmms = forcefield.createSystem(pdb.topology, hydrogenMass=3 * unit.amu, **kwargs)
    ours = forcefield.createSystem(pdb.topology, **kwargs)
    before = _masses(ours)
    changes = repartition_hydrogen_mass(ours, 3.0)  # bonds from the constraints and bond terms
    assert np.allclose(_masses(ours), _masses(openmms), atol=1e-12)
    assert _masses(ours).sum() == pytest.approx(before.sum(), rel=1e-14)
    assert changes == [
        "hydrogen mass repartitioned: 293 hydrogens set to 3 amu, taken from their heavy atoms"
    ]
    assert step_size_problem(ours, 0.004) is None and "293 hydrogen(s) of 1.01 amu" in step_size_problem(
        forcefield.createSystem(pdb.topology, **kwargs), 0.004
    )


def test_hydrogen_mass_of_a_reader_and_of_a_serialized_system_alike(water_files, tmp_path):
    folder, _ = water_files
    (tmp_path / "villin.xml").write_text(
        mm.XmlSerializer.serialize(
            app.ForceField("amber14-all.xml", "amber14/tip3p.xml").createSystem(
                app.PDBFile(VILLIN_PDB).topology, nonbondedMethod=app.PME, constraints=app.HBonds
            )
        ),
        encoding="utf-8",
    )
    pdb = app.PDBFile(VILLIN_PDB)
    state = _state(pdb.positions, pdb.topology.getPeriodicBoxVectors())
    (tmp_path / "villin_state.xml").write_text(mm.XmlSerializer.serialize(state), encoding="utf-8")
    options = {"hydrogen_mass_amu": 3.0}
    read = load_definition_files(
        VILLIN_PDB, FileOptions(forcefield=("amber14-all.xml", "amber14/tip3p.xml"), **options)
    )
    serialized = load_definition_files(
        tmp_path / "villin.xml",
        FileOptions(state=str(tmp_path / "villin_state.xml"), topology=VILLIN_PDB, **options),
    )
    assert np.allclose(_masses(read.system), _masses(serialized.system))
    assert any("293 hydrogens set to 3 amu" in change for change in serialized.changes)


def test_a_large_step_without_repartitioned_hydrogens_warns_and_names_the_fix(tmp_path):
    definition = file_definition(VILLIN_PDB, FileOptions(forcefield=("amber14-all.xml", "amber14/tip3p.xml")))
    prepared = prepare_system(definition, use_cache=False)
    with pytest.warns(LargeStepWarning, match=r"--hydrogen-mass 3"):
        run_nve(prepared, "rattle", tmp_path / "run", steps=1, timestep=0.004, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", LargeStepWarning)
        run_nve(prepared, "rattle", tmp_path / "run2", steps=1, timestep=0.002, progress=False)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["water.pdb"], "needs force-field XMLs; give --forcefield"),
        (
            ["boxless.pdb", "--forcefield", *TIP3P],
            "has no periodic box, and PME needs one; give the box edges in nm with --box",
        ),
        (["water.xml"], "no state file for water.xml; give --state STATE.xml"),
        (["water.xml", "--state", "missing.xml"], "state file .*missing.xml not found"),
        (["water.prmtop"], "system file .*water.prmtop not found"),
        (["tip3p-2nm", "--forcefield", *TIP3P], "--forcefield apply to a system given as files"),
        (["water.xml", "--state", "state.xml", "--constraints", "none"], "keeps its own constraints"),
        (["water.pdb", "--forcefield", *TIP3P, "--hydrogen-mass", "9"], "outside 1–4 amu"),
        (["tip3p-2nm", "--hydrogen-mass", "3"], "is water only: rigid water's hydrogens are not"),
        (["villin", "--hydrogen-mass", "3", "--temperature", "310"], "does not apply to 'villin'"),
    ],
)
def test_file_errors_name_the_problem_and_the_fix_before_any_step(
    water_files, tmp_path, capsys, args, message
):
    folder, _ = water_files
    (tmp_path / "water.prmtop").unlink(missing_ok=True)
    argv = [
        "run",
        *[str(folder / a) if a.endswith((".pdb", ".xml")) and a != "missing.xml" else a for a in args],
    ]
    argv = [a if a != "water.prmtop" else str(tmp_path / a) for a in argv]
    argv.insert(2, "rattle")
    status = main([*argv, "-o", str(tmp_path / "out"), "--steps", "2", "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and "Traceback" not in err
    assert __import__("re").search(message, err), err
    assert not (tmp_path / "out").exists()


def test_files_that_disagree_in_atom_count_are_refused(water_files, tmp_path):
    folder, prepared = water_files
    positions = prepared.state.getPositions(asNumpy=True)[:-3]
    (tmp_path / "short.xml").write_text(
        mm.XmlSerializer.serialize(_state(positions, prepared.state.getPeriodicBoxVectors())),
        encoding="utf-8",
    )
    definition = file_definition(folder / "water.xml", FileOptions(state=str(tmp_path / "short.xml")))
    with pytest.raises(
        DefinitionError, match="the files disagree: the System has 774 particles, the coordinates 771"
    ):
        prepare_system(definition, use_cache=False)


def test_a_library_call_takes_a_file_path_like_a_name(water_files, tmp_path):
    folder, _ = water_files
    with pytest.raises(DefinitionError, match="give --state"):
        load_definition(str(folder / "water.xml"))
    with pytest.raises(DefinitionError, match="give --state"):
        run_nve(str(folder / "water.xml"), "rattle", tmp_path / "run", steps=1, progress=False)
    assert not (tmp_path / "run").exists()
    toml = tmp_path / "mine.toml"
    toml.write_text(
        '[build]\nkind = "openmm_xml"\nfiles = { system = "water.xml", state = "state.xml" }\n'
        "[equilibration]\nseed = 1\ntemperature_K = 300.0\nminimize_tolerance_kJ_per_mol_nm = 10.0\n"
        "minimize_max_iterations = 0\nlangevin_steps = 0\nlangevin_timestep_fs = 2.0\n"
        'langevin_friction_per_ps = 1.0\nplatform = "CPU"\n',
        encoding="utf-8",
    )
    for name in ("water.xml", "state.xml"):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
    summary = run_nve(str(toml), "rattle", tmp_path / "run", steps=2, energy_interval=1, progress=False)
    assert summary.steps == 2 and summary.system == "mine"


def test_an_energy_mode_step_on_user_files_matches_one_on_the_same_system_built_here(water_files):
    """The System read from files is the one OpenMM's ForceField makes: one energy-mode step agrees."""
    folder, prepared = water_files
    ours = prepare_system(
        file_definition(folder / "water.pdb", FileOptions(forcefield=TIP3P)), use_cache=False
    )
    results = []
    for system in (prepared.system, ours.system):
        integrator = AlphaRattleEnergyIntegrator(0.002, order=4)
        context = mm.Context(system, integrator, mm.Platform.getPlatformByName("Reference"))
        context.setPeriodicBoxVectors(*prepared.state.getPeriodicBoxVectors())
        context.setPositions(prepared.state.getPositions())
        context.setVelocities(prepared.state.getVelocities())
        integrator.step(2)
        results.append(
            context.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(unit.nanometers)
        )
    assert np.max(np.abs(results[0] - results[1])) < 1e-9


def load_definition_files(path, options):
    from openmm_alphaprk.systems.files import load_files

    return load_files(file_definition(path, options))


def _state(positions, box) -> mm.State:
    system = mm.System()
    for _ in range(len(positions)):
        system.addParticle(1.0)
    context = mm.Context(system, mm.VerletIntegrator(0.001), mm.Platform.getPlatformByName("Reference"))
    context.setPeriodicBoxVectors(*box)
    context.setPositions(positions)
    return context.getState(getPositions=True, getVelocities=True)


def _masses(system: mm.System) -> np.ndarray:
    return np.array(
        [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    )


def test_tip4pew_files_get_the_virtual_site_refusal_for_the_energy_mode_with_exit_status_2(tmp_path):
    """Through the installed script: the process's exit status and a message without a traceback."""
    import subprocess
    import sys
    from pathlib import Path

    forcefield = app.ForceField("amber14/tip4pew.xml")
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, model="tip4pew", boxSize=mm.Vec3(2.0, 2.0, 2.0) * unit.nanometers)
    with open(tmp_path / "tip4pew.pdb", "w") as handle:
        app.PDBFile.writeFile(modeller.topology, modeller.positions, handle)
    script = Path(sys.executable).with_name("alphaprk")
    result = subprocess.run(
        [str(script), "run", "tip4pew.pdb", "energy4", "--forcefield", "amber14/tip4pew.xml", "--steps", "2"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        encoding="utf-8",
        timeout=300,
        env={**__import__("os").environ, "ALPHAPRK_CACHE_DIR": str(tmp_path / "cache")},
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert "integrator 'energy4' cannot run 'tip4pew.pdb'" in result.stderr
    assert "massless particle(s)" in result.stderr and "alphaprk run tip4pew.pdb verlet" in result.stderr
    assert not list(tmp_path.glob("alphaprk-run-*"))


def test_equilibrate_runs_a_seeded_langevin_first_and_caches_the_start(water_files, tmp_path):
    """The option's protocol: at most 500 minimization steps, then 0.02 ps of Langevin (10 steps).

    The builds here minimize at most 10 steps (``QUICK``; the protocol is otherwise the
    option's): 500 on this box took 13 s on two cores, most of this test's time.
    """
    folder, prepared = water_files
    options = FileOptions(forcefield=TIP3P, equilibrate_ps=0.02, seed=3)
    definition = file_definition(folder / "water.pdb", options)
    assert definition.equilibration["langevin_steps"] == QUICK["equilibration.langevin_steps"] == 10
    assert definition.equilibration["minimize_max_iterations"] == 500
    first = prepare_system(definition, cache_dir=tmp_path / "cache", overrides=QUICK)
    again = prepare_system(
        file_definition(folder / "water.pdb", options), cache_dir=tmp_path / "cache", overrides=QUICK
    )
    assert (first.source, again.source) == ("built", "cache")
    assert np.array_equal(first.positions, again.positions)
    assert np.abs(first.positions - prepared.positions).max() > 1e-3  # moved by minimization and dynamics
    plain = prepare_system(
        file_definition(folder / "water.pdb", FileOptions(forcefield=TIP3P)), use_cache=False
    )
    assert first.key != plain.key


def test_a_start_that_blows_up_gets_the_start_blow_up_message(water_files, tmp_path):
    folder, prepared = water_files
    text = (folder / "water.pdb").read_text().splitlines()
    atoms = [i for i, line in enumerate(text) if line.startswith(("ATOM", "HETATM"))]
    first, second = text[atoms[0]], text[atoms[3]]  # the first two oxygens: 0.05 nm apart
    x = float(first[30:38]) + 0.5
    text[atoms[3]] = second[:30] + f"{x:8.3f}" + first[38:54] + second[54:]
    (tmp_path / "clash.pdb").write_text("\n".join(text) + "\n")
    text[atoms[3]] = second[:30] + first[30:54] + second[54:]  # on top of each other
    (tmp_path / "overlap.pdb").write_text("\n".join(text) + "\n")
    with pytest.raises(DefinitionError, match="non-finite energy .* atoms on top of each other"):
        prepare_system(
            file_definition(tmp_path / "overlap.pdb", FileOptions(forcefield=TIP3P)), use_cache=False
        )
    from openmm_alphaprk.runs import RunFailedError

    with pytest.raises(RunFailedError, match=r"blew up in its first 100 steps.*unminimized start"):
        run_nve(
            prepare_system(
                file_definition(tmp_path / "clash.pdb", FileOptions(forcefield=TIP3P)), use_cache=False
            ),
            "rattle",
            tmp_path / "run",
            steps=100,
            energy_interval=10,
            progress=False,
        )


def test_a_named_solute_with_a_hydrogen_mass_is_prepared_from_its_repartitioned_definition():
    """``--hydrogen-mass 3`` with villin: its definition with 3 amu hydrogens (nothing built here)."""
    import argparse

    from openmm_alphaprk.systems.arguments import add_file_arguments, system_to_prepare

    parser = argparse.ArgumentParser()
    add_file_arguments(parser)
    definition = system_to_prepare("villin", parser.parse_args(["--hydrogen-mass", "3"]))
    assert definition.name == "villin-h3" and definition.build["hydrogen_mass_amu"] == 3.0
    assert system_to_prepare("villin", parser.parse_args([])) == "villin"
